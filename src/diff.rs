//! Comparing two images (`warpray diff REF TEST`): per-channel means, RMSE, relMSE and
//! the largest difference, on linear RGB. EXRs are read as they are; PNGs are decoded
//! from sRGB to linear first, so a PNG and an EXR of one render compare sensibly
//! (up to the PNG's clamping and 8-bit rounding).

use crate::converge::{read_exr, relmse_eps, rmse};
use crate::error::{Error, Result};
use glam::{DVec3, Vec3};
use std::path::Path;

/// The relMSE offset used unless told otherwise: `(x − r)² / (r² + ε)`.
pub const DEFAULT_EPSILON: f64 = 0.01;

/// What `warpray diff` reports.
#[derive(Clone, Debug, PartialEq)]
pub struct Diff {
    /// Image width.
    pub width: u32,
    /// Image height.
    pub height: u32,
    /// Mean of each channel, reference then test.
    pub mean_reference: [f64; 3],
    /// Mean of each channel of the test image.
    pub mean_test: [f64; 3],
    /// Root-mean-square difference over all channels.
    pub rmse: f64,
    /// Relative MSE: mean of `(x − r)² / (r² + ε)`.
    pub relmse: f64,
    /// The ε of the relMSE.
    pub epsilon: f64,
    /// Largest absolute difference of any channel of any pixel.
    pub max_abs: f64,
    /// Pixels that differ at all.
    pub differing_pixels: usize,
    /// Pixels with a NaN or infinite channel (reference, test); they are left out of
    /// every figure.
    pub non_finite: (usize, usize),
}

/// Linear RGB pixels of an EXR or PNG file, with its size.
pub fn read_image(path: &Path) -> Result<(u32, u32, Vec<Vec3>)> {
    let ext = path.extension().and_then(|e| e.to_str()).map(str::to_ascii_lowercase);
    match ext.as_deref() {
        Some("exr") => read_exr(path),
        Some("png") => {
            crate::scene::input::open_regular(path)?;
            let img = image::open(path)
                .map_err(|e| Error::Output { path: path.into(), msg: format!("not a readable PNG: {e}") })?
                .to_rgb8();
            let linear = |c: u8| {
                let x = c as f32 / 255.0;
                if x <= 0.04045 { x / 12.92 } else { ((x + 0.055) / 1.055).powf(2.4) }
            };
            let px = img.pixels().map(|p| Vec3::new(linear(p[0]), linear(p[1]), linear(p[2]))).collect();
            Ok((img.width(), img.height(), px))
        }
        _ => Err(Error::Output { path: path.into(), msg: "unknown image type: use .exr or .png".into() }),
    }
}

/// Compares `test` against `reference` (same size) with relMSE offset `epsilon`.
pub fn diff(reference: &Path, test: &Path, epsilon: f64) -> Result<Diff> {
    if !(epsilon > 0.0 && epsilon.is_finite()) {
        return Err(Error::BadSetting(format!("--epsilon must be positive and finite, not {epsilon}")));
    }
    let (w, h, r) = read_image(reference)?;
    let (tw, th, t) = read_image(test)?;
    if (w, h) != (tw, th) {
        return Err(Error::BadSetting(format!(
            "{} is {w}x{h} but {} is {tw}x{th}: only images of one size compare",
            reference.display(),
            test.display()
        )));
    }
    let finite = |p: &Vec3| p.is_finite();
    let non_finite = (r.iter().filter(|p| !finite(p)).count(), t.iter().filter(|p| !finite(p)).count());
    let (r, t): (Vec<Vec3>, Vec<Vec3>) = r.into_iter().zip(t).filter(|(a, b)| finite(a) && finite(b)).unzip();
    let mean = |v: &[Vec3]| {
        let s: DVec3 = v.iter().map(|p| p.as_dvec3()).sum();
        (s / v.len().max(1) as f64).to_array()
    };
    Ok(Diff {
        width: w,
        height: h,
        mean_reference: mean(&r),
        mean_test: mean(&t),
        rmse: rmse(&t, &r),
        relmse: relmse_eps(&t, &r, epsilon),
        epsilon,
        max_abs: r.iter().zip(&t).map(|(a, b)| (*a - *b).abs().max_element() as f64).fold(0.0, f64::max),
        differing_pixels: r.iter().zip(&t).filter(|(a, b)| a != b).count(),
        non_finite,
    })
}

impl Diff {
    /// One JSON object.
    pub fn to_json(&self) -> String {
        let a = |v: [f64; 3]| format!("[{:e},{:e},{:e}]", v[0], v[1], v[2]);
        format!(
            "{{\"width\":{},\"height\":{},\"mean_reference\":{},\"mean_test\":{},\"rmse\":{:e},\"relmse\":{:e},\"epsilon\":{:e},\"max_abs\":{:e},\"differing_pixels\":{},\"non_finite_reference\":{},\"non_finite_test\":{}}}",
            self.width,
            self.height,
            a(self.mean_reference),
            a(self.mean_test),
            self.rmse,
            self.relmse,
            self.epsilon,
            self.max_abs,
            self.differing_pixels,
            self.non_finite.0,
            self.non_finite.1
        )
    }
}
