//! Microfacet pieces: the GGX (Trowbridge–Reitz) distribution with visible-normal
//! sampling (Heitz 2018), Fresnel terms, and the rough conductor and rough dielectric
//! BSDFs (Walter et al. 2007) built from them. Directions are local (`+z` = normal).

use super::sample::TransportMode;
use crate::cost::declare;
use crate::cost::{BRANCH, CROSS, DIV, DOT, NORMALIZE, NORMALIZE_OR_ZERO, SIN_COS, SQRT, V3, V3_DIV};
use glam::{Vec2, Vec3};
use std::f32::consts::PI;

/// The part of the code this module's declared arithmetic counts as ([`crate::cost::Part`]).
const COST_PART: crate::cost::Part = crate::cost::Part::Microfacet;

/// GGX microfacet distribution of roughness `alpha`.
#[derive(Clone, Copy, Debug)]
pub struct Ggx {
    /// GGX roughness α (width of the slope distribution).
    pub alpha: f32,
}

impl Ggx {
    /// Microfacet normal distribution D(ωm).
    #[inline]
    #[track_caller]
    pub fn d(&self, wm: Vec3) -> f32 {
        let _inlined = crate::cost::scope();
        declare!(BRANCH);
        if wm.z <= 0.0 {
            return 0.0;
        }
        declare!(7 + DIV);
        let a2 = self.alpha * self.alpha;
        let c2 = wm.z * wm.z;
        let denom = c2 * (a2 - 1.0) + 1.0;
        a2 / (PI * denom * denom)
    }

    #[inline]
    #[track_caller]
    fn lambda(&self, w: Vec3) -> f32 {
        let _inlined = crate::cost::scope();
        declare!(1 + BRANCH);
        let c2 = w.z * w.z;
        if c2 == 0.0 {
            return f32::INFINITY;
        }
        declare!(7 + DIV + SQRT);
        let tan2 = ((1.0 - c2) / c2).max(0.0);
        0.5 * ((1.0 + self.alpha * self.alpha * tan2).sqrt() - 1.0)
    }

    /// Smith masking G1(ω).
    #[inline]
    #[track_caller]
    pub fn g1(&self, w: Vec3) -> f32 {
        let _inlined = crate::cost::scope();
        g1_of(self.lambda(w))
    }

    /// Height-correlated masking-shadowing G2(ωo, ωi).
    #[inline]
    #[track_caller]
    pub fn g2(&self, wo: Vec3, wi: Vec3) -> f32 {
        let _inlined = crate::cost::scope();
        let lambda_o = self.lambda(wo);
        self.g2_with(lambda_o, wi)
    }

    /// G2 with Λ(ωo) already known.
    #[inline]
    #[track_caller]
    fn g2_with(&self, lambda_o: f32, wi: Vec3) -> f32 {
        let _inlined = crate::cost::scope();
        declare!(2 + DIV);
        1.0 / (1.0 + lambda_o + self.lambda(wi))
    }

    /// Density of visible normal `wm` seen from `wo` (`wo.z > 0`).
    #[inline]
    #[track_caller]
    pub fn visible_pdf(&self, wo: Vec3, wm: Vec3) -> f32 {
        let _inlined = crate::cost::scope();
        let lambda_o = self.lambda(wo);
        visible_pdf_with(lambda_o, self.d(wm), wo, wm)
    }

    /// Samples a visible normal seen from `wo` (`wo.z > 0`).
    #[inline]
    #[track_caller]
    pub fn sample_visible(&self, wo: Vec3, u: Vec2) -> Vec3 {
        let _inlined = crate::cost::scope();
        // Stretch, the tangent frame (one square root and a vector division), the disk
        // sample (two square roots, sine and cosine), the projection (a square root),
        // unstretch: two normalisations.
        declare!(2 * NORMALIZE + CROSS + 4 * SQRT + V3_DIV + 2 * SIN_COS + 45);
        let a = self.alpha;
        let vh = Vec3::new(a * wo.x, a * wo.y, wo.z).normalize();
        let len2 = vh.x * vh.x + vh.y * vh.y;
        let t1 = if len2 > 0.0 { Vec3::new(-vh.y, vh.x, 0.0) / len2.sqrt() } else { Vec3::X };
        let t2 = vh.cross(t1);
        let r = u.x.sqrt();
        let phi = 2.0 * PI * u.y;
        let p1 = r * phi.cos();
        let s = 0.5 * (1.0 + vh.z);
        let p2 = (1.0 - s) * (1.0 - p1 * p1).max(0.0).sqrt() + s * r * phi.sin();
        let nh = t1 * p1 + t2 * p2 + vh * (1.0 - p1 * p1 - p2 * p2).max(0.0).sqrt();
        Vec3::new(a * nh.x, a * nh.y, nh.z.max(1e-6)).normalize()
    }

    /// Reflection lobe `D G F / (4 cos_o cos_i)` without `F`, and its sampling density,
    /// for directions on the `+z` side.
    #[inline]
    #[track_caller]
    pub fn reflection(&self, wo: Vec3, wi: Vec3) -> Option<(f32, f32, Vec3)> {
        let _inlined = crate::cost::scope();
        declare!(2 * BRANCH);
        if wo.z <= 0.0 || wi.z <= 0.0 {
            return None;
        }
        declare!(V3 + NORMALIZE_OR_ZERO + 4);
        let wm = (wo + wi).normalize_or_zero();
        if wm == Vec3::ZERO {
            return None;
        }
        declare!(4 + DIV + DOT + 1 + DIV);
        let (d, lambda_o) = (self.d(wm), self.lambda(wo));
        let value = d * self.g2_with(lambda_o, wi) / (4.0 * wo.z * wi.z);
        let pdf = visible_pdf_with(lambda_o, d, wo, wm) / (4.0 * wo.dot(wm));
        Some((value, pdf, wm))
    }
}

/// G1 from Λ.
#[inline]
fn g1_of(lambda: f32) -> f32 {
    declare!(1 + DIV);
    1.0 / (1.0 + lambda)
}

/// The visible-normal density with Λ(ωo) and D(ωm) already known. A lobe's value and
/// density both need D(ωm) and Λ(ωo); they are computed once, as the compiled twin
/// computes them (nvcc keeps one of each after inlining), and the results are the same
/// to the bit.
#[inline]
#[track_caller]
fn visible_pdf_with(lambda_o: f32, d: f32, wo: Vec3, wm: Vec3) -> f32 {
    let _inlined = crate::cost::scope();
    declare!(DOT + 3 + DIV);
    g1_of(lambda_o) * wo.dot(wm).max(0.0) * d / wo.z
}

/// Unpolarised Fresnel reflectance of a dielectric interface; `eta = η_t / η_i`.
#[inline]
#[track_caller]
pub fn fresnel_dielectric(cos_i: f32, eta: f32) -> f32 {
    let _inlined = crate::cost::scope();
    declare!(5 + DIV + BRANCH);
    let cos_i = cos_i.clamp(0.0, 1.0);
    let sin2_t = (1.0 - cos_i * cos_i) / (eta * eta);
    if sin2_t >= 1.0 {
        return 1.0;
    }
    declare!(10 + SQRT + 2 * DIV);
    let cos_t = (1.0 - sin2_t).sqrt();
    let r_par = (eta * cos_i - cos_t) / (eta * cos_i + cos_t);
    let r_perp = (cos_i - eta * cos_t) / (cos_i + eta * cos_t);
    0.5 * (r_par * r_par + r_perp * r_perp)
}

/// Fresnel reflectance of a conductor with complex index `eta + i k`, per channel.
#[inline]
#[track_caller]
pub fn fresnel_conductor(cos_i: f32, eta: Vec3, k: Vec3) -> Vec3 {
    let _inlined = crate::cost::scope();
    // Per channel: 29 operations, two square roots and two divisions.
    declare!(4 + 3 * (29 + 2 * SQRT + 2 * DIV));
    let c = cos_i.clamp(0.0, 1.0);
    let (c2, s2) = (c * c, 1.0 - c * c);
    let f = |eta: f32, k: f32| {
        let t0 = eta * eta - k * k - s2;
        let a2b2 = (t0 * t0 + 4.0 * eta * eta * k * k).max(0.0).sqrt();
        let t1 = a2b2 + c2;
        let a = (0.5 * (a2b2 + t0)).max(0.0).sqrt();
        let t2 = 2.0 * c * a;
        let rs = (t1 - t2) / (t1 + t2);
        let t3 = c2 * a2b2 + s2 * s2;
        let t4 = t2 * s2;
        let rp = rs * (t3 - t4) / (t3 + t4);
        (0.5 * (rp + rs)).clamp(0.0, 1.0)
    };
    Vec3::new(f(eta.x, k.x), f(eta.y, k.y), f(eta.z, k.z))
}

/// Refracts `w` (pointing away from the interface, on the `+z` side) through an
/// interface of relative index `eta = η_t / η_i` about normal `n` (on `w`'s side).
/// `None` on total internal reflection.
#[inline]
#[track_caller]
pub fn refract(w: Vec3, n: Vec3, eta: f32) -> Option<Vec3> {
    let _inlined = crate::cost::scope();
    declare!(DOT + 4 + DIV + BRANCH);
    let cos_i = n.dot(w);
    let sin2_t = (1.0 - cos_i * cos_i).max(0.0) / (eta * eta);
    if sin2_t >= 1.0 {
        return None;
    }
    declare!(1 + SQRT + V3_DIV + DIV + 1 + 2 * V3);
    let cos_t = (1.0 - sin2_t).sqrt();
    Some(-w / eta + n * (cos_i / eta - cos_t))
}

/// Rough dielectric for `wo.z > 0`: value and density of `wi` on either side.
/// `eta` is the index below the surface over the index above it.
#[inline]
#[track_caller]
pub fn rough_dielectric(ggx: Ggx, eta: f32, wo: Vec3, wi: Vec3, mode: TransportMode) -> (f32, f32) {
    let _inlined = crate::cost::scope();
    declare!(2 * BRANCH);
    let (cos_o, cos_i) = (wo.z, wi.z);
    if cos_o <= 0.0 || cos_i == 0.0 {
        return (0.0, 0.0);
    }
    declare!(BRANCH + 2 * V3 + DOT + 1);
    let reflect = cos_i > 0.0;
    let etap = if reflect { 1.0 } else { eta };
    let wm = wi * etap + wo;
    if wm.length_squared() == 0.0 {
        return (0.0, 0.0);
    }
    declare!(NORMALIZE + BRANCH + 3 + 2 * DOT + 4);
    let wm = wm.normalize();
    let wm = if wm.z < 0.0 { -wm } else { wm };
    // Microfacets seen from behind contribute nothing.
    if wm.dot(wi) * cos_i < 0.0 || wm.dot(wo) * cos_o < 0.0 {
        return (0.0, 0.0);
    }
    declare!(DOT);
    let fr = fresnel_dielectric(wo.dot(wm), eta);
    let (d, lambda_o) = (ggx.d(wm), ggx.lambda(wo));
    let vis = visible_pdf_with(lambda_o, d, wo, wm);
    if reflect {
        declare!(5 + DIV + DOT + 3 + DIV);
        let value = d * ggx.g2_with(lambda_o, wi) * fr / (4.0 * cos_o * cos_i);
        let pdf = vis / (4.0 * wo.dot(wm)) * fr;
        (value, pdf)
    } else {
        declare!(4 * DOT + 13 + 3 * DIV + BRANCH);
        let denom = wi.dot(wm) + wo.dot(wm) / etap;
        let denom2 = denom * denom;
        let mut value =
            d * (1.0 - fr) * ggx.g2_with(lambda_o, wi) * (wi.dot(wm) * wo.dot(wm) / (cos_i * cos_o * denom2)).abs();
        if mode == TransportMode::Radiance {
            declare!(1 + DIV);
            value /= etap * etap;
        }
        let pdf = vis * (wi.dot(wm).abs() / denom2) * (1.0 - fr);
        (value, pdf)
    }
}

/// Samples the rough dielectric for `wo.z > 0` (see [`rough_dielectric`]).
#[inline]
#[track_caller]
pub fn sample_rough_dielectric(ggx: Ggx, eta: f32, wo: Vec3, u_lobe: f32, u: Vec2) -> Option<Vec3> {
    let _inlined = crate::cost::scope();
    let wm = ggx.sample_visible(wo, u);
    declare!(DOT + BRANCH);
    let fr = fresnel_dielectric(wo.dot(wm), eta);
    if u_lobe < fr {
        declare!(DOT + 1 + 2 * V3 + BRANCH);
        let wi = 2.0 * wo.dot(wm) * wm - wo;
        (wi.z > 0.0).then_some(wi)
    } else {
        let wi = refract(wo, wm, eta)?;
        declare!(BRANCH);
        (wi.z < 0.0).then_some(wi)
    }
}
