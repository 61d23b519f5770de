//! Deterministic random numbers and the warps that turn them into directions.
//!
//! Random numbers are a hash of (seed, stream, index): a path's stream is derived from
//! its pixel and sample index, never from a thread or a queue position, so an image
//! depends only on the seed, whatever the thread count or scheduling.

use glam::{Vec2, Vec3};
use std::f32::consts::{FRAC_1_PI, PI};

/// The part of the code this module's declared arithmetic counts as ([`crate::cost::Part`]).
const COST_PART: crate::cost::Part = crate::cost::Part::Sampling;

/// 64-bit finaliser (splitmix64 / Stafford variant 13): a bijective, well-mixed hash.
#[inline]
pub fn mix64(mut z: u64) -> u64 {
    z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
    z ^ (z >> 31)
}

/// A counter-based stream of uniform numbers. Cheap to create, `Copy`, and the same
/// key always yields the same sequence.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[repr(C)]
pub struct Rng {
    key: u64,
    counter: u64,
}

impl Rng {
    /// The stream for one (pixel, sample) pair under `seed`.
    pub fn for_sample(seed: u64, pixel: u64, sample: u64) -> Rng {
        let key =
            mix64(mix64(seed ^ 0x5157_4d3c_8a2b_9e11).wrapping_add(pixel) ^ mix64(sample.wrapping_add(0x9e37_79b9)));
        Rng { key, counter: 0 }
    }

    /// An independent stream derived from this one's key (e.g. per bounce or per purpose).
    pub fn derive(&self, tag: u64) -> Rng {
        Rng { key: mix64(self.key ^ mix64(tag.wrapping_add(0xd1b5_4a32_d192_ed03))), counter: 0 }
    }

    /// Numbers drawn from the stream so far (a GPU twin that took another branch draws
    /// another count).
    pub fn counter(&self) -> u64 {
        self.counter
    }

    #[inline]
    /// The next 64 random bits.
    pub fn next_u64(&mut self) -> u64 {
        self.counter += 1;
        mix64(self.key.wrapping_add(self.counter.wrapping_mul(0x9e37_79b9_7f4a_7c15)))
    }

    /// Uniform in `[0, 1)`, with 24 bits of precision.
    #[inline]
    #[track_caller]
    pub fn uniform(&mut self) -> f32 {
        let _inlined = crate::cost::scope();
        crate::cost::declare!(crate::cost::RNG);
        (self.next_u64() >> 40) as f32 * (1.0 / (1u64 << 24) as f32)
    }

    #[inline]
    /// Two uniform numbers in `[0, 1)`.
    pub fn uniform2(&mut self) -> Vec2 {
        Vec2::new(self.uniform(), self.uniform())
    }
}

// SAFETY: two u64 fields, #[repr(C)], no padding; any bit pattern is a valid state.
unsafe impl simt::DeviceCopy for Rng {}

impl Default for Rng {
    fn default() -> Self {
        Rng::for_sample(0, 0, 0)
    }
}

/// An orthonormal basis around a unit normal (Duff et al. 2017).
#[derive(Clone, Copy, Debug)]
pub struct Frame {
    /// First tangent.
    pub s: Vec3,
    /// Second tangent.
    pub t: Vec3,
    /// Normal (the local `z` axis).
    pub n: Vec3,
}

impl Frame {
    /// An orthonormal frame around unit normal `n`.
    #[inline]
    #[track_caller]
    pub fn from_normal(n: Vec3) -> Frame {
        let _inlined = crate::cost::scope();
        crate::cost::declare!(crate::cost::FRAME);
        let sign = 1.0f32.copysign(n.z);
        let a = -1.0 / (sign + n.z);
        let b = n.x * n.y * a;
        let s = Vec3::new(1.0 + sign * n.x * n.x * a, sign * b, -sign * n.x);
        let t = Vec3::new(b, sign + n.y * n.y * a, -n.y);
        Frame { s, t, n }
    }
    #[inline]
    /// World direction to local coordinates.
    #[track_caller]
    pub fn to_local(&self, v: Vec3) -> Vec3 {
        let _inlined = crate::cost::scope();
        crate::cost::declare!(crate::cost::TO_LOCAL);
        Vec3::new(v.dot(self.s), v.dot(self.t), v.dot(self.n))
    }
    #[inline]
    /// Local direction to world coordinates.
    #[track_caller]
    pub fn to_world(&self, v: Vec3) -> Vec3 {
        let _inlined = crate::cost::scope();
        crate::cost::declare!(crate::cost::TO_WORLD);
        self.s * v.x + self.t * v.y + self.n * v.z
    }
}

/// Cosine-weighted direction on the +z hemisphere; pdf = cos θ / π.
#[inline]
#[track_caller]
pub fn cosine_hemisphere(u: Vec2) -> Vec3 {
    let _inlined = crate::cost::scope();
    let d = concentric_disk(u);
    crate::cost::declare!(6 + crate::cost::SQRT);
    Vec3::new(d.x, d.y, (1.0 - d.length_squared()).max(0.0).sqrt())
}

/// Density of [`cosine_hemisphere`] for a direction with this cosine.
pub fn cosine_hemisphere_pdf(cos_theta: f32) -> f32 {
    cos_theta.max(0.0) * FRAC_1_PI
}

/// Uniform point on a triangle, as barycentric weights of corners 1 and 2 (Heitz 2019's
/// low-distortion split would do too; this is the classic square-root warp).
#[inline]
pub fn uniform_triangle(u: Vec2) -> (f32, f32) {
    let su = u.x.sqrt();
    (su * (1.0 - u.y), su * u.y)
}

/// Uniform direction on the unit sphere; pdf = 1 / 4π.
pub fn uniform_sphere(u: Vec2) -> Vec3 {
    let z = 1.0 - 2.0 * u.x;
    let r = (1.0 - z * z).max(0.0).sqrt();
    let phi = 2.0 * PI * u.y;
    Vec3::new(r * phi.cos(), r * phi.sin(), z)
}

/// Power heuristic (β = 2) for two strategies with `nf` and `ng` samples.
#[inline(always)]
pub fn power_heuristic(pf: f32, pg: f32) -> f32 {
    let (f, g) = (pf * pf, pg * pg);
    if f == 0.0 && g == 0.0 {
        0.0
    } else if f.is_infinite() {
        1.0
    } else {
        f / (f + g)
    }
}

/// Shirley–Chiu concentric map from the unit square to the unit disk. The point's
/// angle is π/4 · t or π/2 − π/4 · t with t in [−1, 1], so its sine and cosine are those
/// of an angle in [−π/4, π/4] ([`sin_cos_quarter`]), taken in one order or the other.
#[inline]
#[track_caller]
pub fn concentric_disk(u: Vec2) -> Vec2 {
    let _inlined = crate::cost::scope();
    use crate::cost::{BRANCH, DIV, SIN_COS_QUARTER};
    crate::cost::declare!(4 + 2 * BRANCH);
    let o = 2.0 * u - Vec2::ONE;
    if o == Vec2::ZERO {
        return Vec2::ZERO;
    }
    // The comparison, the ratio and its angle, the two polynomials, the scaling.
    crate::cost::declare!(2 + BRANCH + DIV + 1 + SIN_COS_QUARTER + 2);
    if o.x.abs() > o.y.abs() {
        let (sin, cos) = sin_cos_quarter(std::f32::consts::FRAC_PI_4 * (o.y / o.x));
        Vec2::new(cos, sin) * o.x
    } else {
        // At π/2 − t: the cosine is t's sine and the sine its cosine.
        let (sin, cos) = sin_cos_quarter(std::f32::consts::FRAC_PI_4 * (o.x / o.y));
        Vec2::new(sin, cos) * o.y
    }
}

/// Sine and cosine of `x` in [−π/4, π/4] as polynomials in x² (the single-precision
/// minimax coefficients of Cephes's `sinf` and `cosf` for that interval; within 6e-8 of
/// the exact values, `tests::sin_cos_quarter_is_within_float_rounding`): no range
/// reduction and no library call. The CUDA twins evaluate the same polynomials in the
/// same order (`cuda/cis_device.cuh`).
#[inline(always)]
pub(crate) fn sin_cos_quarter(x: f32) -> (f32, f32) {
    let z = x * x;
    let sin = ((-1.951_529_6e-4 * z + 8.332_161e-3) * z - 1.666_665_5e-1) * z * x + x;
    let cos = ((2.443_315_7e-5 * z - 1.388_731_6e-3) * z + 4.166_664_6e-2) * z * z - 0.5 * z + 1.0;
    (sin, cos)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The polynomials against double-precision sine and cosine over the whole quarter
    /// interval (ends included), and the concentric map against its trigonometric form.
    /// The largest errors measured: 4.4e-8 (sine) and 5.7e-8 (cosine), under half an ulp
    /// of 1. The x³ coefficient × 1.01 is caught (an error of 8.1e-4), and so is the x²
    /// coefficient of the cosine × 1.01 (3.1e-3).
    #[test]
    fn sin_cos_quarter_is_within_float_rounding() {
        let n = 200_000;
        let (mut worst_sin, mut worst_cos) = (0.0f64, 0.0f64);
        for i in 0..=n {
            let x = -std::f32::consts::FRAC_PI_4 + std::f32::consts::FRAC_PI_2 * (i as f32 / n as f32);
            let (s, c) = sin_cos_quarter(x);
            worst_sin = worst_sin.max((s as f64 - (x as f64).sin()).abs());
            worst_cos = worst_cos.max((c as f64 - (x as f64).cos()).abs());
        }
        assert!(worst_sin < 1e-7 && worst_cos < 1e-7, "sine {worst_sin:e}, cosine {worst_cos:e}");

        let mut rng = Rng::for_sample(5, 0, 0);
        for _ in 0..100_000 {
            let u = rng.uniform2();
            let o = 2.0 * u.as_dvec2() - glam::DVec2::ONE;
            let (r, theta) = if o.x.abs() > o.y.abs() {
                (o.x, std::f64::consts::FRAC_PI_4 * (o.y / o.x))
            } else {
                (o.y, std::f64::consts::FRAC_PI_2 - std::f64::consts::FRAC_PI_4 * (o.x / o.y))
            };
            let d = concentric_disk(u).as_dvec2();
            let exact = glam::DVec2::new(theta.cos(), theta.sin()) * r;
            assert!((d - exact).length() < 5e-7, "{u}: {d} against {exact}");
        }
    }
}
