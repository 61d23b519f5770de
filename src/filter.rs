//! Pixel reconstruction filters: a pixel's value is the film's radiance weighted by the
//! filter centred on the pixel, `I_q = ∫ h(x − c_q) L(x) dx` with `∫ h = 1`.
//!
//! Camera samples use filter importance sampling (as pbrt-v4 does): the sample's offset
//! from the pixel centre is drawn from (roughly) the filter's shape and the estimate is
//! multiplied by `h / pdf`, so the film stays a plain per-pixel average. Contributions
//! splatted by light paths at a film position go to every pixel whose filter covers it,
//! weighted by `h`. Both routes estimate the same `I_q`.
//!
//! - [`Filter::Box`]: the unit square (radius 0.5). Offsets are uniform in the pixel,
//!   weight 1, splats go to the one pixel they land in — warpray's behaviour before
//!   filters existed, number for number.
//! - [`Filter::Gaussian`]: Mitsuba 3's and pbrt-v4's default, a Gaussian minus its value
//!   at the radius (so it reaches zero there), separable in x and y. Mitsuba's defaults
//!   are σ = 0.5 pixels and radius 4σ; pbrt-v4's are σ = 0.5, radius 1.5. Offsets are
//!   drawn from the Gaussian restricted to the disk around the square support (Box–Muller
//!   with its radial CDF inverted over `[0, r√2]`) and weighted by `h / pdf`; offsets in
//!   the disk's corners beyond the square have weight 0 (at most 1 − 2/π of them, when
//!   σ is wide against r). σ lies in [0.01, 16 r]: outside it the filter is a delta or a
//!   flat tent that f32 cannot weigh.
//!
//! How camera samples meet the filter is a [`FilterMode`]: drawn from it and weighted
//! (`Sample`, above; pbrt-v4's way, unbiased, each pixel's noise its own), or placed
//! uniformly in their pixel and spread over every pixel the filter covers, each pixel
//! dividing by the weights it received (`Splat`; Mitsuba 3's and pbrt-v3's way, a ratio
//! estimator: consistent, biased by O(1/spp), and its neighbouring pixels share
//! samples, so each is less noisy). With the box filter the two are the same estimator.
//! Light-path splats (light tracing, BDPT's camera connections) are weighted by `h` and
//! divided by the pass count in both modes; under `Splat` the camera samples of a pixel
//! within the filter's radius of the image edge are normalised by the weight that
//! reached it, so there a bidirectional image mixes two border treatments (Mitsuba's
//! light tracer does the same); interior pixels are unaffected.

use crate::sampling::Rng;
use glam::Vec2;
use std::f32::consts::TAU;

pub(crate) mod prepared;

/// A pixel reconstruction filter.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub enum Filter {
    /// Box of radius 0.5 (one pixel).
    #[default]
    Box,
    /// Truncated Gaussian `exp(−x²/2σ²) − exp(−r²/2σ²)` per axis.
    Gaussian {
        /// Standard deviation σ, pixels.
        stddev: f32,
        /// Radius r where the filter reaches zero, pixels.
        radius: f32,
        /// `∫_{−r}^{r}` of the 1-D filter, computed once by [`Filter::gaussian`].
        integral: f32,
        /// `exp(−r²/2σ²)`, the value subtracted so the filter reaches zero at `r`.
        bias: f32,
        /// 0: the function itself. `n > 0`: evaluated as Mitsuba 3's film evaluates its
        /// filters, from a table of `n` values over `[0, r)`, each the filter at the
        /// start of its step (so the steps lie above the curve: a slightly wider
        /// filter, whose weighted averages have about 6 % less variance at Mitsuba's
        /// σ = 0.5, r = 2, n = 31).
        steps: u32,
    },
}

/// Largest Gaussian radius accepted (pixels): a splat touches (2r)² pixels.
pub const MAX_RADIUS: f32 = 16.0;
/// Smallest Gaussian σ accepted (pixels): narrower, the filter's weights overflow f32.
pub const MIN_STDDEV: f32 = 0.01;
/// Largest σ accepted, as a multiple of the radius: wider, the truncated Gaussian is a
/// tent whose values differ from its value at the radius by less than f32 resolves.
pub const MAX_STDDEV_PER_RADIUS: f32 = 16.0;
/// Steps of the table from which Mitsuba 3's film evaluates reconstruction filters
/// (`MI_FILTER_RESOLUTION`).
pub const MITSUBA_FILTER_STEPS: u32 = 31;

impl Filter {
    /// A Gaussian of standard deviation `stddev` reaching zero at `radius` (both in
    /// pixels). Errors name the bad value.
    pub fn gaussian(stddev: f32, radius: f32) -> Result<Filter, String> {
        Filter::gaussian_in_steps(stddev, radius, 0)
    }

    /// The Gaussian as Mitsuba 3's film evaluates it: σ = `stddev`, cut off at 4σ, from
    /// its table of 31 steps (`MI_FILTER_RESOLUTION`).
    pub fn mitsuba(stddev: f32) -> Result<Filter, String> {
        Filter::gaussian_in_steps(stddev, 4.0 * stddev, MITSUBA_FILTER_STEPS)
    }

    fn gaussian_in_steps(stddev: f32, radius: f32, steps: u32) -> Result<Filter, String> {
        if !(stddev > 0.0 && stddev.is_finite()) {
            return Err(format!("Gaussian filter stddev {stddev} must be positive and finite"));
        }
        if !(0.5..=MAX_RADIUS).contains(&radius) {
            return Err(format!("filter radius {radius} must lie in [0.5, {MAX_RADIUS}] pixels"));
        }
        if !(MIN_STDDEV..=MAX_STDDEV_PER_RADIUS * radius).contains(&stddev) {
            return Err(format!(
                "Gaussian filter stddev {stddev} must lie in [{MIN_STDDEV}, {MAX_STDDEV_PER_RADIUS} × radius = {}] pixels",
                MAX_STDDEV_PER_RADIUS * radius
            ));
        }
        let bias = (-(radius * radius) / (2.0 * stddev * stddev)).exp();
        let integral = if steps == 0 {
            // Simpson's rule in f64; the 1-D integrand is smooth on [−r, r].
            let (s, r) = (stddev as f64, radius as f64);
            let bias = (-r * r / (2.0 * s * s)).exp();
            let n = 4096;
            let h = 2.0 * r / n as f64;
            let f = |x: f64| ((-x * x / (2.0 * s * s)).exp() - bias).max(0.0);
            let mut sum = f(-r) + f(r);
            for i in 1..n {
                sum += f(-r + i as f64 * h) * if i % 2 == 1 { 4.0 } else { 2.0 };
            }
            sum * h / 3.0
        } else {
            // Both halves of the steps, each `r / n` wide.
            let width = radius as f64 / steps as f64;
            2.0 * (0..steps).map(|i| gauss(step_start(radius, steps, i), stddev, bias) as f64 * width).sum::<f64>()
        };
        Ok(Filter::Gaussian { stddev, radius, integral: integral as f32, bias, steps })
    }

    /// Mitsuba 3's default Gaussian as its film evaluates it: σ = 0.5, radius 2, 31
    /// steps.
    pub fn mitsuba_gaussian() -> Filter {
        Filter::mitsuba(0.5).expect("valid constants")
    }

    /// Half-width of the filter's support, pixels.
    pub fn radius(&self) -> f32 {
        match *self {
            Filter::Box => 0.5,
            Filter::Gaussian { radius, .. } => radius,
        }
    }

    /// How far outside the image (pixels) a film position can still reach a pixel:
    /// 0 for the box, `radius − 0.5` for wider filters.
    pub fn margin(&self) -> f32 {
        self.radius() - 0.5
    }

    /// The normalised 1-D filter at offset `x` (pixels): integrates to 1.
    #[inline]
    fn eval_1d(&self, x: f32) -> f32 {
        match *self {
            Filter::Box => {
                if x.abs() <= 0.5 {
                    1.0
                } else {
                    0.0
                }
            }
            Filter::Gaussian { stddev, radius, integral, bias, steps } => {
                if x.abs() >= radius {
                    return 0.0;
                }
                // A stepped filter takes the value at the start of the step |x| is in
                // (Mitsuba's index: the integer part of |x| · n / r).
                if steps > 0 {
                    return step_value(stddev, radius, integral, bias, steps, step_of(x, radius, steps));
                }
                gauss(x, stddev, bias) / integral
            }
        }
    }

    /// The normalised 2-D filter at offset `d` from a pixel centre.
    #[inline]
    pub fn eval(&self, d: Vec2) -> f32 {
        self.eval_1d(d.x) * self.eval_1d(d.y)
    }

    /// A camera sample's film position in pixel `(x, y)` from `u` in `[0,1)²`, and the
    /// weight `h / pdf` its estimate is multiplied by.
    #[inline]
    pub fn sample(&self, x: u32, y: u32, u: Vec2) -> (Vec2, f32) {
        let corner = Vec2::new(x as f32, y as f32);
        match *self {
            Filter::Box => (corner + u, 1.0),
            Filter::Gaussian { stddev, radius, .. } => {
                // Box–Muller restricted to the disk of radius r√2 that holds the square
                // support: the radial CDF 1 − exp(−ρ²/2σ²) inverted over that disk. (An
                // unrestricted draw landed outside the support, weight 0, for most
                // samples when σ is wide against r: black pixels and fireflies.)
                let s2 = 2.0 * stddev * stddev;
                let mass = -(-(2.0 * radius * radius) / s2).exp_m1();
                let rho = (-s2 * (-u.x * mass).ln_1p()).sqrt();
                let (sin, cos) = (TAU * u.y).sin_cos();
                let d = Vec2::new(rho * cos, rho * sin);
                let pdf = (-d.length_squared() / s2).exp() / (std::f32::consts::PI * s2 * mass);
                let w = if pdf > 0.0 { self.eval(d) / pdf } else { 0.0 };
                (corner + Vec2::splat(0.5) + d, w)
            }
        }
    }

    /// The pixels a contribution at film position `p` reaches, with their weights,
    /// passed to `add(pixel index, weight)`; nothing outside the `width × height` image.
    pub fn splat(&self, p: Vec2, width: u32, height: u32, add: impl FnMut(u32, f32)) {
        let centres = |p, first, out: &mut [f32]| centres_each(|x| self.eval_1d(x), p, first, out);
        splat_with(*self, centres, p, (width, height), 0..height, add)
    }
}

/// [`Filter::splat`] with the 1-D filter's values at pixel centres given by
/// `centres(p, first, out)`: into `out[j]`, the value at offset `p − (first + j + 0.5)`
/// (the filter's own or its table's, or the exact Gaussian's recurrence:
/// [`PreparedFilter`]).
#[inline]
fn splat_with(
    filter: Filter,
    centres: impl Fn(f32, i64, &mut [f32]),
    p: Vec2,
    (width, height): (u32, u32),
    rows: std::ops::Range<u32>,
    mut add: impl FnMut(u32, f32),
) {
    match filter {
        Filter::Box => {
            if p.x >= 0.0 && p.y >= 0.0 && p.x <= width as f32 && p.y <= height as f32 {
                let x = (p.x as u32).min(width - 1);
                let y = (p.y as u32).min(height - 1);
                if rows.contains(&y) {
                    add(y * width + x, 1.0);
                }
            }
        }
        Filter::Gaussian { radius, .. } => {
            // Pixel centres c = i + 0.5 with |p − c| < r.
            let lo = |v: f32| (v - radius - 0.5).ceil().max(0.0) as i64;
            let hi = |v: f32, n: u32| ((v + radius - 0.5).floor() as i64).min(n as i64 - 1);
            // The column and row weights once each, not once per pixel. At most
            // 2·MAX_RADIUS + 1 of each. The rows' weights are those of every row the
            // filter reaches, whichever of them `rows` keeps, so that a row's weight
            // does not depend on the band it is added in.
            let (x0, x1, y0, y1) = (lo(p.x), hi(p.x, width), lo(p.y), hi(p.y, height));
            if x1 < x0 || y1 < y0 {
                return;
            }
            let (mut wx, mut wy) = ([0.0f32; 2 * MAX_RADIUS as usize + 2], [0.0f32; 2 * MAX_RADIUS as usize + 2]);
            let (wx, wy) = (&mut wx[..(x1 - x0 + 1) as usize], &mut wy[..(y1 - y0 + 1) as usize]);
            centres(p.x, x0, wx);
            centres(p.y, y0, wy);
            let kept = |&(y, _): &(i64, &f32)| y >= rows.start as i64 && y < rows.end as i64;
            for (y, &w_y) in (y0..=y1).zip(wy.iter()).filter(kept) {
                if w_y <= 0.0 {
                    continue;
                }
                for (x, &w_x) in (x0..=x1).zip(wx.iter()) {
                    let w = w_y * w_x;
                    if w > 0.0 {
                        add(y as u32 * width + x as u32, w);
                    }
                }
            }
        }
    }
}

/// The 1-D filter `eval_1d`'s values at pixel centres `first + j + 0.5`, offsets from
/// `p`, into `out`: [`splat_with`]'s `centres`, value by value.
#[inline]
fn centres_each(eval_1d: impl Fn(f32) -> f32, p: f32, first: i64, out: &mut [f32]) {
    for (j, o) in out.iter_mut().enumerate() {
        *o = eval_1d(p - ((first + j as i64) as f32 + 0.5));
    }
}

/// Where step `i` of a Gaussian in `steps` steps over `[0, radius)` begins:
/// `radius · i / steps`, as Mitsuba computes its table's positions.
#[inline]
fn step_start(radius: f32, steps: u32, i: u32) -> f32 {
    radius * i as f32 / steps as f32
}

/// The step of a stepped filter that offset `x` (|x| < radius) falls in: Mitsuba's
/// index, the integer part of |x| · n / r (at most `steps`, by rounding).
#[inline]
fn step_of(x: f32, radius: f32, steps: u32) -> u32 {
    (x.abs() * (steps as f32 / radius)) as u32
}

/// The normalised value of step `i` of a stepped Gaussian: the filter at the step's
/// start.
#[inline]
fn step_value(stddev: f32, radius: f32, integral: f32, bias: f32, steps: u32, i: u32) -> f32 {
    gauss(step_start(radius, steps, i), stddev, bias) / integral
}

/// The truncated Gaussian before its normalisation: `exp(−x²/2σ²) − bias`, at least 0.
#[inline]
fn gauss(x: f32, stddev: f32, bias: f32) -> f32 {
    ((-(x * x) / (2.0 * stddev * stddev)).exp() - bias).max(0.0)
}

/// How camera samples are reconstructed into pixels (see the module docs).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum FilterMode {
    /// Filter importance sampling: offsets drawn from the filter, weight `h / pdf`,
    /// each sample belongs to its own pixel (pbrt-v4).
    #[default]
    Sample,
    /// Uniform offsets in the pixel, each sample splatted with weight `h` to every pixel
    /// the filter covers; a pixel is its weighted sum over its summed weights (Mitsuba 3).
    Splat,
}

impl std::str::FromStr for FilterMode {
    type Err = String;
    fn from_str(s: &str) -> Result<FilterMode, String> {
        match s {
            "sample" => Ok(FilterMode::Sample),
            "splat" => Ok(FilterMode::Splat),
            _ => Err(format!("unknown filter mode '{s}' (sample, splat)")),
        }
    }
}

impl FilterMode {
    /// Its name on the command line and in scene files.
    pub fn name(self) -> &'static str {
        match self {
            FilterMode::Sample => "sample",
            FilterMode::Splat => "splat",
        }
    }
}

/// The uniform `[0,1)²` number that places camera sample `pass` of `pixel` (under
/// `seed`) on the film: its own stream, so the film can recompute it when it splats
/// (`Film::add_pass`) without the integrator handing positions over.
#[inline]
pub fn pixel_offset(seed: u64, pixel: u32, pass: u32) -> Vec2 {
    Rng::for_sample(seed, pixel as u64, pass as u64).derive(0x6669_6c6d).uniform2()
}

impl Filter {
    /// Camera sample `pass` of pixel `(x, y)` under `mode`: its film position and the
    /// weight its estimate is multiplied by.
    #[inline]
    pub fn camera_sample(&self, mode: FilterMode, seed: u64, (x, y): (u32, u32), width: u32, pass: u32) -> (Vec2, f32) {
        let u = pixel_offset(seed, y * width + x, pass);
        match mode {
            FilterMode::Sample => self.sample(x, y, u),
            FilterMode::Splat => (Vec2::new(x as f32, y as f32) + u, 1.0),
        }
    }

    /// How many pixels beyond its own a camera sample can reach along each axis.
    #[inline]
    pub(crate) fn splat_reach(&self) -> u32 {
        (self.radius() + 0.5).ceil() as u32 - 1
    }
}

impl std::str::FromStr for Filter {
    type Err = String;
    /// `box`, `gaussian` (Mitsuba's σ = 0.5, radius 2) or `gaussian:σ:radius`.
    fn from_str(s: &str) -> Result<Filter, String> {
        let mut parts = s.split(':');
        match parts.next() {
            Some("box") if parts.next().is_none() => Ok(Filter::Box),
            Some("gaussian") => {
                let nums: Vec<&str> = parts.collect();
                match nums.as_slice() {
                    [] => Ok(Filter::mitsuba_gaussian()),
                    [s, r] => {
                        let p = |v: &str| v.parse::<f32>().map_err(|_| format!("'{v}' is not a number"));
                        Filter::gaussian(p(s)?, p(r)?)
                    }
                    _ => Err("expected gaussian or gaussian:STDDEV:RADIUS".into()),
                }
            }
            _ => Err(format!("unknown filter '{s}' (box, gaussian, gaussian:STDDEV:RADIUS)")),
        }
    }
}

#[cfg(test)]
mod tests;
