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
    /// Pixels compared: finite in both images.
    pub compared: usize,
}

/// Linear RGB pixels of an EXR or PNG file, with its size.
pub fn read_image(path: &Path) -> Result<(u32, u32, Vec<Vec3>)> {
    let ext = path.extension().and_then(|e| e.to_str()).map(str::to_ascii_lowercase);
    match ext.as_deref() {
        Some("exr") => read_exr(path),
        Some("png") => {
            crate::scene::input::open_regular(path)?;
            let unreadable =
                |e: &dyn std::fmt::Display| Error::Input { path: path.into(), msg: format!("not a readable PNG: {e}") };
            // The header's size passes the film's limits before anything is decoded: a
            // 31 kB 1-bit PNG decoded to 3.7 GB.
            let reader = image::ImageReader::open(path).map_err(|e| Error::io(path, e))?;
            let reader = reader.with_guessed_format().map_err(|e| Error::io(path, e))?;
            let (w, h) = reader.into_dimensions().map_err(|e| unreadable(&e))?;
            crate::film::check_size(w, h).map_err(|e| Error::Input {
                path: path.into(),
                msg: format!("not a readable PNG: its header claims {w}x{h} pixels ({e})"),
            })?;
            let img = image::open(path).map_err(|e| unreadable(&e))?.to_rgb8();
            let linear = |c: u8| {
                let x = c as f32 / 255.0;
                if x <= 0.04045 { x / 12.92 } else { ((x + 0.055) / 1.055).powf(2.4) }
            };
            let px = img.pixels().map(|p| Vec3::new(linear(p[0]), linear(p[1]), linear(p[2]))).collect();
            Ok((img.width(), img.height(), px))
        }
        _ => Err(Error::Input { path: path.into(), msg: "unknown image type: use .exr or .png".into() }),
    }
}

/// Checks a gate's RMSE limit (`--fail-above`): finite and not negative.
pub fn check_limit(limit: f64) -> Result<()> {
    if limit.is_finite() && limit >= 0.0 {
        Ok(())
    } else {
        Err(Error::BadSetting(format!("--fail-above must be a finite RMSE of 0 or more, not {limit}")))
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
    // With no pixel finite in both, every figure is undefined (NaN: `null` in JSON).
    let undefined = r.is_empty();
    let figure = |x: f64| if undefined { f64::NAN } else { x };
    let mean = |v: &[Vec3]| {
        let s: DVec3 = v.iter().map(|p| p.as_dvec3()).sum();
        (s / v.len().max(1) as f64).to_array().map(figure)
    };
    Ok(Diff {
        width: w,
        height: h,
        mean_reference: mean(&r),
        mean_test: mean(&t),
        rmse: figure(rmse(&t, &r)),
        relmse: figure(relmse_eps(&t, &r, epsilon)),
        epsilon,
        max_abs: figure(
            r.iter().zip(&t).map(|(a, b)| (a.as_dvec3() - b.as_dvec3()).abs().max_element()).fold(0.0, f64::max),
        ),
        differing_pixels: r.iter().zip(&t).filter(|(a, b)| a != b).count(),
        non_finite,
        compared: r.len(),
    })
}

impl Diff {
    /// Whether the test image fails a gate of RMSE `limit` (`--fail-above`): its RMSE
    /// is above `limit`, or it has a NaN or infinite pixel (a render that produced one
    /// is broken whatever its other pixels say; `ignore_nonfinite` lets it pass on its
    /// finite pixels), or no pixel could be compared. A limit that is negative,
    /// infinite or NaN is an error: such a gate could never fail.
    pub fn fails(&self, limit: f64, ignore_nonfinite: bool) -> Result<bool> {
        check_limit(limit)?;
        let broken = self.non_finite.1 > 0 && !ignore_nonfinite;
        // A NaN RMSE fails the gate: `!(rmse <= limit)` is true for it.
        #[allow(clippy::neg_cmp_op_on_partial_ord)]
        let above = !(self.rmse <= limit);
        Ok(above || broken || self.compared == 0)
    }

    /// One JSON object; figures that are not finite (an RMSE of no pixels) are `null`.
    pub fn to_json(&self) -> String {
        let n = |x: f64| if x.is_finite() { format!("{x:e}") } else { "null".into() };
        let a = |v: [f64; 3]| format!("[{},{},{}]", n(v[0]), n(v[1]), n(v[2]));
        format!(
            "{{\"width\":{},\"height\":{},\"mean_reference\":{},\"mean_test\":{},\"rmse\":{},\"relmse\":{},\"epsilon\":{},\"max_abs\":{},\"differing_pixels\":{},\"non_finite_reference\":{},\"non_finite_test\":{},\"compared_pixels\":{}}}",
            self.width,
            self.height,
            a(self.mean_reference),
            a(self.mean_test),
            n(self.rmse),
            n(self.relmse),
            n(self.epsilon),
            n(self.max_abs),
            self.differing_pixels,
            self.non_finite.0,
            self.non_finite.1,
            self.compared
        )
    }
}
