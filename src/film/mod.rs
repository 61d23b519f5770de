//! The film: f32 RGB sums with a pass count, a guard that keeps NaN and Inf out, and
//! image output. Files are written to a temporary name beside the target and renamed
//! into place, so a failed or interrupted run never leaves a truncated image.
//!
//! PNG tone map: `exposure · x`, clamped to `[0, 1]`, then the sRGB transfer curve,
//! rounded to 8 bits. EXR: linear f32 RGB (ZIP compression), no tone map.

use crate::error::{Error, Result};
use crate::filter::prepared::PreparedFilter;
use crate::filter::{Filter, FilterMode, pixel_offset};
use glam::{Vec2, Vec3};
use std::path::{Path, PathBuf};

#[derive(Clone, Debug)]
/// Accumulated radiance of a progressive render, per pixel, and its output as PNG or EXR.
pub struct Film {
    /// Width, pixels.
    pub width: u32,
    /// Height, pixels.
    pub height: u32,
    /// Per pixel: sum of the radiance estimates of all passes (with
    /// [`FilterMode::Splat`], of the filter-weighted estimates splatted onto it).
    pub sum: Vec<Vec3>,
    /// Per pixel, [`FilterMode::Splat`] only: the summed filter weights `sum` is divided
    /// by (empty otherwise).
    pub weight: Vec<f32>,
    /// Per pixel: sum of contributions splatted by light paths (light tracing, BDPT's
    /// camera connections), normalised so that it too is divided by `passes`: the
    /// finished passes' (a pass's splats are added to it when the pass ends).
    pub splat: Vec<Vec3>,
    /// Per pixel: sum of the squares of each pass's estimate (its own estimate plus
    /// that pass's splats), for the per-pixel sample variance.
    pub sum_sq: Vec<Vec3>,
    /// Per pixel: the splats of the pass in progress (added to `splat` and folded into
    /// `sum_sq` when the pass ends: each splat touches one buffer).
    pass_splat: Vec<Vec3>,
    /// Number of passes (samples per pixel) accumulated.
    pub passes: u32,
    /// Estimates rejected because they were NaN, infinite or negative.
    pub rejected: u64,
    /// The reconstruction filter splats are spread with (camera samples apply it when
    /// they are drawn: [`Filter::sample`]).
    pub filter: Filter,
    /// How camera samples are reconstructed: with [`FilterMode::Splat`] the film places
    /// each pass's samples itself ([`pixel_offset`] under `seed`).
    pub mode: FilterMode,
    /// The render's seed (for [`FilterMode::Splat`]).
    pub seed: u64,
    /// `filter` with its stepped values tabulated (remade when `filter` has changed).
    prepared: PreparedFilter,
    /// [`FilterMode::Splat`]'s per-sample weights of one band of rows, kept from pass
    /// to pass (every entry a pass reads, it writes first).
    band_weights: Vec<f32>,
}

/// Ends a pass at one pixel: the pass's pending splats join the running total `splat`,
/// and the pass's estimate there (its own estimate `own` plus those splats) adds its
/// square to `sum_sq` (every way a pass ends goes through here).
#[inline]
fn close_pass(own: Vec3, pending: &mut Vec3, splat: &mut Vec3, sum_sq: &mut Vec3) {
    let p = std::mem::take(pending);
    *splat += p;
    let x = own + p;
    *sum_sq += x * x;
}

/// Rows per band when splats are added in parallel ([`Film::add_splats`]).
const SPLAT_BAND: u32 = 16;
/// Fewest splats added in parallel.
const PARALLEL_SPLATS: usize = 1 << 14;

/// Largest image accepted: 16384 pixels a side and 2^26 pixels (64 Mpx) in all.
pub const MAX_SIDE: u32 = 16_384;
/// Most pixels an image may have.
pub const MAX_PIXELS: u64 = 1 << 26;

/// Checks an image size before anything is allocated.
pub fn check_size(width: u32, height: u32) -> Result<()> {
    let bad = |why| Err(Error::BadImageSize { width, height, why });
    if width == 0 || height == 0 {
        return bad("width and height must be at least 1");
    }
    if width > MAX_SIDE || height > MAX_SIDE {
        return bad("a side is longer than 16384 pixels");
    }
    if width as u64 * height as u64 > MAX_PIXELS {
        return bad("more than 2^26 (67 million) pixels");
    }
    Ok(())
}

impl Film {
    /// An empty film (the size is checked first).
    pub fn new(width: u32, height: u32) -> Result<Film> {
        check_size(width, height)?;
        let n = (width * height) as usize;
        let zeros = || vec![Vec3::ZERO; n];
        Ok(Film {
            width,
            height,
            sum: zeros(),
            splat: zeros(),
            sum_sq: zeros(),
            pass_splat: zeros(),
            passes: 0,
            rejected: 0,
            filter: Filter::Box,
            mode: FilterMode::Sample,
            seed: 0,
            weight: Vec::new(),
            prepared: Filter::Box.prepared(),
            band_weights: Vec::new(),
        })
    }

    /// The film's filter, tabulated.
    fn prepared_filter(&mut self) -> PreparedFilter {
        if self.prepared.filter() != self.filter {
            self.prepared = self.filter.prepared();
        }
        self.prepared
    }

    /// A film whose camera samples follow `filter` in `mode` under `seed`.
    pub fn with_filter(mut self, filter: Filter, mode: FilterMode, seed: u64) -> Film {
        (self.filter, self.mode, self.seed) = (filter, mode, seed);
        self.weight = match mode {
            FilterMode::Splat => vec![0.0; self.sum.len()],
            FilterMode::Sample => Vec::new(),
        };
        self
    }

    /// Bytes of the film's buffers.
    pub fn memory_bytes(&self) -> usize {
        (self.sum.len() + self.splat.len() + self.sum_sq.len() + self.pass_splat.len()) * size_of::<Vec3>()
            + (self.weight.len() + self.band_weights.len()) * size_of::<f32>()
    }

    /// Pixels.
    pub fn pixel_count(&self) -> usize {
        self.sum.len()
    }

    /// Adds pass number `pass`: one estimate per pixel, in pixel order, for the camera
    /// sample [`Filter::camera_sample`] placed. Non-finite or negative estimates count
    /// as zero and are counted in `rejected`.
    pub fn add_pass(&mut self, pass: u32, estimates: &[Vec3]) {
        assert_eq!(estimates.len(), self.sum.len(), "one estimate per pixel");
        let mut valid = |e: Vec3| {
            if e.is_finite() && e.min_element() >= 0.0 {
                e
            } else {
                self.rejected += 1;
                Vec3::ZERO
            }
        };
        match self.mode {
            FilterMode::Sample => {
                let splats = self.splat.iter_mut().zip(&mut self.pass_splat);
                for ((s, q), (&e, (splat, p))) in
                    self.sum.iter_mut().zip(&mut self.sum_sq).zip(estimates.iter().zip(splats))
                {
                    let e = valid(e);
                    *s += e;
                    close_pass(e, p, splat, q);
                }
            }
            FilterMode::Splat => {
                let clean: Vec<Vec3> = estimates.iter().map(|&e| valid(e)).collect();
                self.splat_pass(pass, &clean);
            }
        }
        self.passes += 1;
    }

    /// [`FilterMode::Splat`]: every pixel gathers the camera samples of this pass whose
    /// filter reaches it, weighted, in a fixed order (the same sums at any thread count).
    /// Works in bands of rows so that the per-sample weights stay a small buffer.
    fn splat_pass(&mut self, pass: u32, estimates: &[Vec3]) {
        use rayon::prelude::*;
        let (w, h) = (self.width as usize, self.height as usize);
        let (filter, seed) = (self.prepared_filter(), self.seed);
        let k = self.filter.splat_reach() as usize;
        let n = 2 * k + 1;
        const BAND: usize = 32;
        let mut weights = std::mem::take(&mut self.band_weights);
        weights.resize((BAND + 2 * k) * w * 2 * n, 0.0);
        for y0 in (0..h).step_by(BAND) {
            let y1 = (y0 + BAND).min(h);
            // Sample rows that reach the band, and their per-axis weights.
            let (r0, r1) = (y0.saturating_sub(k), (y1 + k).min(h));
            weights[..(r1 - r0) * w * 2 * n].par_chunks_mut(w * 2 * n).enumerate().for_each(|(row, out)| {
                let qy = r0 + row;
                for (qx, out) in out.chunks_exact_mut(2 * n).enumerate() {
                    let q = (qy * w + qx) as u32;
                    let p = Vec2::new(qx as f32, qy as f32) + pixel_offset(seed, q, pass);
                    let (wx, wy) = out.split_at_mut(n);
                    filter.splat_weights(p, wx, wy);
                }
            });
            let weights = &weights;
            let rows = self.sum[y0 * w..y1 * w]
                .par_chunks_mut(w)
                .zip(self.weight[y0 * w..y1 * w].par_chunks_mut(w))
                .zip(self.sum_sq[y0 * w..y1 * w].par_chunks_mut(w))
                .zip(self.pass_splat[y0 * w..y1 * w].par_chunks_mut(w))
                .zip(self.splat[y0 * w..y1 * w].par_chunks_mut(w));
            rows.enumerate().for_each(|(row, ((((sum, weight), sum_sq), pass_splat), splat))| {
                let y = y0 + row;
                for x in 0..w {
                    let (mut num, mut den) = (Vec3::ZERO, 0.0f32);
                    for qy in y.saturating_sub(k)..(y + k + 1).min(h) {
                        for qx in x.saturating_sub(k)..(x + k + 1).min(w) {
                            let base = ((qy - r0) * w + qx) * 2 * n;
                            // Sample q's weight for pixel (x, y): index k + (x − qx).
                            let wt = weights[base + k + x - qx] * weights[base + n + k + y - qy];
                            num += estimates[qy * w + qx] * wt;
                            den += wt;
                        }
                    }
                    sum[x] += num;
                    weight[x] += den;
                    let own = if den > 0.0 { num / den } else { Vec3::ZERO };
                    close_pass(own, &mut pass_splat[x], &mut splat[x], &mut sum_sq[x]);
                }
            });
        }
        self.band_weights = weights;
    }

    /// Adds splatted contributions `(film position in pixels, value)` in the order given
    /// (so that the result does not depend on thread scheduling), spread over the pixels
    /// the film's filter covers. Non-finite or negative values are dropped and counted.
    /// Call once or more per pass, before [`Film::end_pass`].
    ///
    /// Many splats are added by bands of rows in parallel: each band takes, in the
    /// order given, the splats whose filter reaches it, so every pixel adds its
    /// contributions in the same order as one thread would (the same sums, bit for bit).
    pub fn add_splats(&mut self, splats: impl IntoIterator<Item = (Vec2, Vec3)>) {
        use rayon::prelude::*;
        let (w, h, filter) = (self.width, self.height, self.prepared_filter());
        let valid = |&(p, v): &(Vec2, Vec3)| v.is_finite() && v.min_element() >= 0.0 && p.is_finite();
        let splats: Vec<(Vec2, Vec3)> = splats.into_iter().collect();
        let n_bands = h.div_ceil(SPLAT_BAND) as usize;
        if splats.len() < PARALLEL_SPLATS || n_bands < 2 || rayon::current_num_threads() < 2 {
            for s @ (p, v) in splats {
                if valid(&s) {
                    filter.splat_rows(p, (w, h), 0..h, |i, wt| self.pass_splat[i as usize] += v * wt);
                } else {
                    self.rejected += 1;
                }
            }
            return;
        }
        // The bands each splat's filter reaches (its rows k above and below its own),
        // listed per band in the given order: per chunk of splats, then chunk after chunk.
        let k = self.filter.splat_reach() as f32;
        let band_of = |y: f32| ((y.max(0.0) as u32).min(h - 1) / SPLAT_BAND) as usize;
        let chunk = splats.len().div_ceil(4 * rayon::current_num_threads());
        let lists: Vec<(Vec<Vec<u32>>, u64)> = splats
            .par_chunks(chunk)
            .enumerate()
            .map(|(c, part)| {
                let (mut bands, mut rejected) = (vec![Vec::new(); n_bands], 0);
                for (j, s) in part.iter().enumerate() {
                    if !valid(s) {
                        rejected += 1;
                        continue;
                    }
                    let y = s.0.y.floor();
                    for band in &mut bands[band_of(y - k)..=band_of(y + k)] {
                        band.push((c * chunk + j) as u32);
                    }
                }
                (bands, rejected)
            })
            .collect();
        self.rejected += lists.iter().map(|l| l.1).sum::<u64>();
        let band_pixels = (SPLAT_BAND * w) as usize;
        self.pass_splat.par_chunks_mut(band_pixels).enumerate().for_each(|(b, out)| {
            let rows = b as u32 * SPLAT_BAND..((b as u32 + 1) * SPLAT_BAND).min(h);
            let first = b * band_pixels;
            for &i in lists.iter().flat_map(|l| &l.0[b]) {
                let (p, v) = splats[i as usize];
                filter.splat_rows(p, (w, h), rows.clone(), |i, wt| out[i as usize - first] += v * wt);
            }
        });
    }

    /// Ends a pass that added only splats.
    pub fn end_pass(&mut self) {
        for ((q, p), s) in self.sum_sq.iter_mut().zip(&mut self.pass_splat).zip(&mut self.splat) {
            close_pass(Vec3::ZERO, p, s, q);
        }
        self.passes += 1;
    }

    /// Per-pixel sample variance of the passes' estimates (unbiased: divided by
    /// `passes − 1`; NaN, undefined, before the second pass). The variance of the mean is this
    /// divided by `passes`. With [`FilterMode::Splat`] a pass's estimate is that pass's
    /// own weighted average (plus its splats), taken about the film's mean: close to,
    /// not exactly, the variance of the ratio the film reports. It assumes independent
    /// passes: passes that share a light pass (`samples_per_iteration` above 1, see
    /// [`crate::render::Iterations`]) are correlated, and the command line refuses
    /// `--aov variance` for them.
    pub fn variance(&self) -> Vec<Vec3> {
        let n = self.passes as f64;
        if self.passes < 2 {
            return vec![Vec3::NAN; self.sum.len()];
        }
        let mean = self.mean();
        (0..mean.len())
            .map(|i| {
                let mean = mean[i].as_dvec3();
                let v = (self.sum_sq[i].as_dvec3() - mean * mean * n) / (n - 1.0);
                v.max(glam::DVec3::ZERO).as_vec3()
            })
            .collect()
    }

    /// The mean estimate per pixel.
    pub fn mean(&self) -> Vec<Vec3> {
        let inv = if self.passes > 0 { 1.0 / self.passes as f32 } else { 0.0 };
        match self.mode {
            FilterMode::Sample => (0..self.sum.len()).map(|i| (self.sum[i] + self.splats(i)) * inv).collect(),
            FilterMode::Splat => (0..self.sum.len())
                .map(|i| {
                    let own = if self.weight[i] > 0.0 { self.sum[i] / self.weight[i] } else { Vec3::ZERO };
                    own + self.splats(i) * inv
                })
                .collect(),
        }
    }

    /// Pixel `i`'s splats so far: the finished passes' and the pass in progress's.
    fn splats(&self, i: usize) -> Vec3 {
        self.splat[i] + self.pass_splat[i]
    }

    /// Mean of all pixels' means (per channel).
    pub fn image_mean(&self) -> Vec3 {
        let m = self.mean();
        let acc: glam::DVec3 = m.iter().map(|v| v.as_dvec3()).sum();
        (acc / m.len().max(1) as f64).as_vec3()
    }

    /// Writes `path` as PNG or EXR, chosen by its extension.
    pub fn write(&self, path: &Path, exposure: f32) -> Result<()> {
        self.write_with(path, exposure, &[])
    }

    /// As [`Film::write`]; an EXR also carries `metadata` as text attributes named
    /// `warpray.KEY` in its header (read back with [`read_exr_metadata`]).
    pub fn write_with(&self, path: &Path, exposure: f32, metadata: &[(&str, String)]) -> Result<()> {
        let ext = path.extension().and_then(|e| e.to_str()).map(str::to_ascii_lowercase);
        match ext.as_deref() {
            Some("png") => self.write_png(path, exposure),
            Some("exr") => self.write_exr_with(path, metadata),
            _ => Err(Error::Output { path: path.into(), msg: "unknown image type: use .png or .exr".into() }),
        }
    }

    /// sRGB 8-bit PNG of the mean, scaled by `exposure` and clamped.
    pub fn write_png(&self, path: &Path, exposure: f32) -> Result<()> {
        let bytes: Vec<u8> = self.mean().iter().flat_map(|c| (*c * exposure).to_array().map(encode_srgb8)).collect();
        atomic_write(path, |tmp| {
            image::save_buffer_with_format(
                tmp,
                &bytes,
                self.width,
                self.height,
                image::ColorType::Rgb8,
                image::ImageFormat::Png,
            )
            .map_err(|e| e.to_string())
        })
    }

    /// Linear f32 EXR of the mean.
    pub fn write_exr(&self, path: &Path) -> Result<()> {
        self.write_exr_with(path, &[])
    }

    /// Linear EXR with `metadata` as `warpray.KEY` text attributes (characters outside
    /// Latin-1, which EXR text cannot hold, become `?`).
    pub fn write_exr_with(&self, path: &Path, metadata: &[(&str, String)]) -> Result<()> {
        self.write_exr_aovs(path, metadata, &[])
    }

    /// As [`Film::write_exr_with`], with extra channels beside R, G, B: `(name, one value
    /// per pixel)`, named as tev and pbrt-v4 group them (`Albedo.R`, `N.X`, `Z`,
    /// `Variance.G`; see [`crate::aov`]). Every channel must have one value per pixel.
    pub fn write_exr_aovs(&self, path: &Path, metadata: &[(&str, String)], aovs: &[(String, Vec<f32>)]) -> Result<()> {
        use exr::prelude::*;
        let (w, h) = (self.width as usize, self.height as usize);
        if let Some((name, _)) = aovs.iter().find(|(_, v)| v.len() != w * h) {
            let msg = format!("channel {name} does not have one value per pixel");
            return Err(crate::error::Error::Output { path: path.into(), msg });
        }
        let mut attributes = LayerAttributes::named("rgb");
        for (key, value) in metadata {
            let text = |s: &str| {
                let latin1: String = s.chars().map(|c| if (c as u32) < 256 { c } else { '?' }).collect();
                Text::new_or_panic(latin1)
            };
            attributes.other.insert(text(&format!("warpray.{key}")), AttributeValue::Text(text(value)));
        }
        let mean = self.mean();
        let mut list: SmallVec<[AnyChannel<FlatSamples>; 4]> = SmallVec::new();
        for (i, name) in ["R", "G", "B"].into_iter().enumerate() {
            list.push(AnyChannel::new(name, FlatSamples::F32(mean.iter().map(|c| c[i]).collect())));
        }
        for (name, values) in aovs {
            list.push(AnyChannel::new(name.as_str(), FlatSamples::F32(values.clone())));
        }
        atomic_write(path, |tmp| {
            let layer = Layer::new((w, h), attributes, Encoding::SMALL_LOSSLESS, AnyChannels::sort(list));
            Image::from_layer(layer).write().to_file(tmp).map_err(|e| e.to_string())
        })
    }
}

/// The `warpray.KEY` text attributes of an EXR's first layer, as (KEY, value), sorted
/// by key.
pub fn read_exr_metadata(path: &Path) -> Result<Vec<(String, String)>> {
    crate::scene::input::open_regular(path)?;
    let meta = exr::meta::MetaData::read_from_file(path, false)
        .map_err(|e| Error::Input { path: path.into(), msg: format!("not a readable EXR: {e}") })?;
    let mut out: Vec<(String, String)> = meta
        .headers
        .first()
        .map(|h| {
            h.own_attributes
                .other
                .iter()
                .filter_map(|(k, v)| {
                    let key = k.to_string();
                    let key = key.strip_prefix("warpray.")?.to_string();
                    match v {
                        exr::meta::attribute::AttributeValue::Text(t) => Some((key, t.to_string())),
                        _ => None,
                    }
                })
                .collect()
        })
        .unwrap_or_default();
    out.sort();
    Ok(out)
}

/// Rec. 709 luminance of a linear RGB colour.
#[inline]
pub fn luminance(c: Vec3) -> f32 {
    c.dot(Vec3::new(0.2126, 0.7152, 0.0722))
}

/// sRGB transfer curve, clamped, to 8 bits.
pub fn encode_srgb8(linear: f32) -> u8 {
    let x = if linear.is_nan() { 0.0 } else { linear.clamp(0.0, 1.0) };
    let s = if x <= 0.003_130_8 { 12.92 * x } else { 1.055 * x.powf(1.0 / 2.4) - 0.055 };
    (s * 255.0 + 0.5) as u8
}

/// Writes through `write` to a temporary file beside `path`, then renames it into place.
/// On failure the temporary file is removed and `path` is untouched.
pub fn atomic_write(path: &Path, write: impl FnOnce(&Path) -> std::result::Result<(), String>) -> Result<()> {
    let name = path.file_name().ok_or_else(|| Error::Output { path: path.into(), msg: "not a file name".into() })?;
    let ext = path.extension().map(|e| e.to_string_lossy().into_owned()).unwrap_or_default();
    // Keep the extension last: the encoders pick their format from it.
    let tmp: PathBuf = path.with_file_name(format!(".{}.{}.tmp.{ext}", name.to_string_lossy(), std::process::id()));
    let result = write(&tmp).and_then(|()| std::fs::rename(&tmp, path).map_err(|e| e.to_string()));
    if let Err(msg) = result {
        let _ = std::fs::remove_file(&tmp);
        return Err(Error::Output { path: path.into(), msg });
    }
    Ok(())
}

#[cfg(test)]
mod tests;
