//! Layered materials: up to two dielectric coats over a base (Lambertian or conductor),
//! evaluated layer by layer and sampled layer by layer.
//!
//! **Model.** Each coat is an interface of index `ior` over a thin absorbing film.
//! Light either reflects at the coat (a smooth, delta reflection, or a GGX lobe when the
//! coat is rough, weighted by the Fresnel factor of the microfacet) or refracts into the
//! film, is attenuated by `exp(-absorption · (1/cos θo' + 1/cos θi'))`, scatters off what
//! lies below (the next coat or the base) at the refracted directions, and refracts
//! out. With `F` the Fresnel reflectance of the macro surface:
//!
//! `f(wo, wi) = f_coat(wo, wi) + (1 − F(θo)) (1 − F(θi)) · A · f_below(wo', wi') / η²`
//!
//! (refraction compresses solid angle by `cos θi / (η² cos θi')`, which turns the
//! radiance factor η² into the 1/η² above). The expression is symmetric in `wo`, `wi`,
//! so it serves radiance and importance alike.
//!
//! **Sampling** picks the coat with probability `F(θo)`, else refracts `wo` into the
//! film and samples the layer below, refracting its direction back out. The density
//! is the same mixture (the lower layer's density times the solid-angle Jacobian), so
//! `f`, `pdf` and `sample_f` agree exactly and the chi-square test applies.
//!
//! **Energy.** Light reflected back down at the underside of a coat, and light that
//! would leave the film beyond the critical angle, is dropped: the model only ever
//! loses energy relative to the physical stack (never gains). A white Lambertian under a
//! clear coat of index 1.5 reflects 43 % at normal incidence (4 % at the coat, the rest
//! the light that leaves the film on its first try; `examples/layered_albedo.rs`), where
//! the full multiple-scattering solution would reflect nearly all of it; coloured coats
//! and bases darken further.

use super::microfacet::{Ggx, fresnel_conductor, fresnel_dielectric};
use super::sample::{BsdfSample, TransportMode};
use crate::cost::{BRANCH, DIV, DOT, EXP, SQRT, V3, V3_DIV};
use crate::cost::{declare, reads};
use crate::sampling::cosine_hemisphere;
use glam::{Vec2, Vec3};
use std::f32::consts::FRAC_1_PI;

/// The part of the code this module's declared arithmetic counts as ([`crate::cost::Part`]).
const COST_PART: crate::cost::Part = crate::cost::Part::Bsdf;

/// Roughness below which a lobe is treated as perfectly smooth (a delta lobe).
pub const SMOOTH: f32 = 1e-3;

/// One dielectric coat over a thin absorbing film.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Coat {
    /// Index of refraction of the coat.
    pub ior: f32,
    /// GGX α of the coat's surface; below [`SMOOTH`] the coat is a perfect interface.
    pub roughness: f32,
    /// Optical depth of the film along its normal, per channel (0: clear).
    pub absorption: Vec3,
}

/// What lies under the coats.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum LayerBase {
    /// A Lambertian base.
    Diffuse {
        /// Reflectance.
        albedo: Vec3,
    },
    /// A GGX conductor base.
    Conductor {
        /// Real part of the refractive index, per channel.
        eta: Vec3,
        /// Imaginary part (absorption), per channel.
        k: Vec3,
        /// GGX roughness α.
        roughness: f32,
    },
}

/// Up to two coats (`coats[0]` on top) over a base.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Layered {
    /// The coats, outermost first (only the first `coat_count` are used).
    pub coats: [Coat; 2],
    /// Coats in use (1 or 2).
    pub coat_count: u32,
    /// What lies under the coats.
    pub base: LayerBase,
}

impl Layered {
    /// The coats in use, outermost first.
    pub fn coats(&self) -> &[Coat] {
        reads!(&self.coat_count, 1);
        &self.coats[..self.coat_count.min(2) as usize]
    }

    /// No continuous lobe anywhere (smooth coats over a smooth conductor).
    pub fn is_delta(&self) -> bool {
        self.coats().iter().all(|c| {
            reads!(&c.roughness, 1);
            c.roughness < SMOOTH
        }) && {
            reads!(&self.base, 2);
            matches!(self.base, LayerBase::Conductor { roughness, .. } if roughness < SMOOTH)
        }
    }

    /// Value of the continuous part, both directions on `+z`.
    #[inline]
    #[track_caller]
    pub fn f(&self, wo: Vec3, wi: Vec3) -> Vec3 {
        let _inlined = crate::cost::scope();
        f_stack(self.coats(), &self.base, wo, wi)
    }

    /// Density of the continuous part, both directions on `+z`.
    #[inline]
    #[track_caller]
    pub fn pdf(&self, wo: Vec3, wi: Vec3) -> f32 {
        let _inlined = crate::cost::scope();
        pdf_stack(self.coats(), &self.base, wo, wi)
    }

    /// Samples `wi` for `wo` on `+z`.
    #[inline]
    #[track_caller]
    pub fn sample(&self, wo: Vec3, u_lobe: f32, u: Vec2, mode: TransportMode) -> Option<BsdfSample> {
        let _inlined = crate::cost::scope();
        let s = sample_stack(self.coats(), &self.base, wo, u_lobe, u)?;
        if s.delta {
            return Some(s);
        }
        // Continuous samples report the whole stack's value and density, so every lobe
        // that could have produced this direction is accounted for.
        let _ = mode;
        let f = self.f(wo, s.wi);
        let pdf = self.pdf(wo, s.wi);
        declare!(BRANCH + 1 + V3 + V3_DIV);
        (pdf > 0.0).then(|| BsdfSample { wi: s.wi, f, pdf, weight: f * s.wi.z / pdf, delta: false })
    }
}

/// `w` (on `+z`, outside a coat of index `ior`) carried into the film, still pointing up.
#[inline]
#[track_caller]
fn into_film(w: Vec3, ior: f32) -> Vec3 {
    let _inlined = crate::cost::scope();
    declare!(2 * DIV + 5 + SQRT);
    let t = Vec2::new(w.x, w.y) / ior;
    Vec3::new(t.x, t.y, (1.0 - t.length_squared()).max(0.0).sqrt())
}

/// The reverse of [`into_film`]; `None` beyond the critical angle.
#[inline]
#[track_caller]
fn out_of_film(w: Vec3, ior: f32) -> Option<Vec3> {
    let _inlined = crate::cost::scope();
    declare!(5 + BRANCH + SQRT);
    let t = Vec2::new(w.x, w.y) * ior;
    let s2 = t.length_squared();
    (s2 < 1.0).then(|| Vec3::new(t.x, t.y, (1.0 - s2).sqrt()))
}

#[inline]
#[track_caller]
fn attenuation(c: &Coat, wo: Vec3, wi: Vec3) -> Vec3 {
    let _inlined = crate::cost::scope();
    declare!(2 * DIV + 3 + 2 * V3 + 3 * EXP, reads(&c.absorption, 3));
    (-c.absorption * (1.0 / wo.z.max(1e-6) + 1.0 / wi.z.max(1e-6))).exp()
}

#[inline]
#[track_caller]
fn base_f(b: &LayerBase, wo: Vec3, wi: Vec3) -> Vec3 {
    let _inlined = crate::cost::scope();
    declare!(2 * BRANCH, reads(b, 1));
    match *b {
        LayerBase::Diffuse { albedo } => {
            declare!(V3, reads(b, 3));
            albedo * FRAC_1_PI
        }
        LayerBase::Conductor { eta, k, roughness } if roughness >= SMOOTH => {
            reads!(b, 1);
            let ggx = Ggx { alpha: roughness };
            ggx.reflection(wo, wi).map_or(Vec3::ZERO, |(v, _, wm)| {
                declare!(DOT + V3, reads(b, 6));
                fresnel_conductor(wo.dot(wm), eta, k) * v
            })
        }
        LayerBase::Conductor { .. } => Vec3::ZERO,
    }
}

#[inline]
#[track_caller]
fn base_pdf(b: &LayerBase, wo: Vec3, wi: Vec3) -> f32 {
    let _inlined = crate::cost::scope();
    declare!(2 * BRANCH, reads(b, 1));
    match *b {
        LayerBase::Diffuse { .. } => {
            declare!(1);
            wi.z * FRAC_1_PI
        }
        LayerBase::Conductor { roughness, .. } if roughness >= SMOOTH => {
            reads!(b, 1);
            Ggx { alpha: roughness }.reflection(wo, wi).map_or(0.0, |(_, p, _)| p)
        }
        LayerBase::Conductor { .. } => 0.0,
    }
}

#[inline]
#[track_caller]
fn base_sample(b: &LayerBase, wo: Vec3, u: Vec2) -> Option<BsdfSample> {
    let _inlined = crate::cost::scope();
    declare!(2 * BRANCH, reads(b, 2));
    match *b {
        LayerBase::Diffuse { albedo } => {
            let wi = cosine_hemisphere(u);
            declare!(1 + BRANCH + V3, reads(b, 3));
            let pdf = wi.z * FRAC_1_PI;
            (pdf > 0.0).then(|| BsdfSample { wi, f: albedo * FRAC_1_PI, pdf, weight: albedo, delta: false })
        }
        LayerBase::Conductor { eta, k, roughness } if roughness >= SMOOTH => {
            let ggx = Ggx { alpha: roughness };
            let wm = ggx.sample_visible(wo, u);
            declare!(DOT + 1 + 2 * V3);
            let wi = 2.0 * wo.dot(wm) * wm - wo;
            let (v, pdf, _) = ggx.reflection(wo, wi)?;
            declare!(DOT + V3 + BRANCH + 2 * V3 + V3_DIV, reads(b, 6));
            let f = fresnel_conductor(wo.dot(wm), eta, k) * v;
            (pdf > 0.0).then(|| BsdfSample { wi, f, pdf, weight: f * wi.z / pdf, delta: false })
        }
        LayerBase::Conductor { eta, k, .. } => {
            let wi = Vec3::new(-wo.x, -wo.y, wo.z);
            let fr = fresnel_conductor(wo.z, eta, k);
            declare!(V3_DIV, reads(b, 6));
            Some(BsdfSample { wi, f: fr / wi.z, pdf: 1.0, weight: fr, delta: true })
        }
    }
}

fn f_stack(coats: &[Coat], base: &LayerBase, wo: Vec3, wi: Vec3) -> Vec3 {
    declare!(3 * BRANCH);
    if wo.z <= 0.0 || wi.z <= 0.0 {
        return Vec3::ZERO;
    }
    let Some((c, rest)) = coats.split_first() else {
        return base_f(base, wo, wi);
    };
    declare!(BRANCH, reads(c, 2));
    let top = if c.roughness >= SMOOTH {
        Ggx { alpha: c.roughness }.reflection(wo, wi).map_or(0.0, |(v, _, wm)| {
            declare!(DOT + 1);
            v * fresnel_dielectric(wo.dot(wm), c.ior)
        })
    } else {
        0.0
    };
    declare!(6 + DIV + 2 * V3 + 3);
    let (wo2, wi2) = (into_film(wo, c.ior), into_film(wi, c.ior));
    let trans = (1.0 - fresnel_dielectric(wo.z, c.ior)) * (1.0 - fresnel_dielectric(wi.z, c.ior)) / (c.ior * c.ior);
    Vec3::splat(top) + attenuation(c, wo2, wi2) * f_stack(rest, base, wo2, wi2) * trans
}

fn pdf_stack(coats: &[Coat], base: &LayerBase, wo: Vec3, wi: Vec3) -> f32 {
    declare!(3 * BRANCH);
    if wo.z <= 0.0 || wi.z <= 0.0 {
        return 0.0;
    }
    let Some((c, rest)) = coats.split_first() else {
        return base_pdf(base, wo, wi);
    };
    declare!(BRANCH + 8 + DIV, reads(c, 2));
    let p_coat = fresnel_dielectric(wo.z, c.ior);
    let top = if c.roughness >= SMOOTH {
        Ggx { alpha: c.roughness }.reflection(wo, wi).map_or(0.0, |(_, p, _)| p)
    } else {
        0.0
    };
    let (wo2, wi2) = (into_film(wo, c.ior), into_film(wi, c.ior));
    let jacobian = wi.z / (c.ior * c.ior * wi2.z.max(1e-9));
    p_coat * top + (1.0 - p_coat) * pdf_stack(rest, base, wo2, wi2) * jacobian
}

/// Samples a direction through the stack. Continuous samples carry only `wi` reliably
/// (the caller re-evaluates the stack); delta samples carry their full weight.
fn sample_stack(coats: &[Coat], base: &LayerBase, wo: Vec3, u_lobe: f32, u: Vec2) -> Option<BsdfSample> {
    declare!(BRANCH);
    let Some((c, rest)) = coats.split_first() else {
        return base_sample(base, wo, u);
    };
    declare!(BRANCH, reads(c, 1));
    let p_coat = fresnel_dielectric(wo.z, c.ior);
    if u_lobe < p_coat {
        declare!(BRANCH, reads(c, 1));
        return if c.roughness >= SMOOTH {
            let wm = Ggx { alpha: c.roughness }.sample_visible(wo, u);
            declare!(DOT + 1 + 2 * V3 + BRANCH);
            let wi = 2.0 * wo.dot(wm) * wm - wo;
            (wi.z > 0.0).then_some(BsdfSample { wi, f: Vec3::ZERO, pdf: 0.0, weight: Vec3::ZERO, delta: false })
        } else {
            declare!(DIV);
            let wi = Vec3::new(-wo.x, -wo.y, wo.z);
            Some(BsdfSample { wi, f: Vec3::splat(p_coat / wi.z), pdf: p_coat, weight: Vec3::ONE, delta: true })
        };
    }
    declare!(4 + DIV);
    let u_lobe = ((u_lobe - p_coat) / (1.0 - p_coat)).clamp(0.0, 1.0 - f32::EPSILON);
    let wo2 = into_film(wo, c.ior);
    let s = sample_stack(rest, base, wo2, u_lobe, u)?;
    declare!(BRANCH);
    if s.wi.z <= 0.0 {
        return None;
    }
    let wi = out_of_film(s.wi, c.ior)?;
    declare!(BRANCH);
    if !s.delta {
        return Some(BsdfSample { wi, ..s });
    }
    // A delta path through the film: its weight composes layer by layer (see module docs).
    declare!(3 * V3 + 2 + V3 + V3_DIV);
    let weight = s.weight * attenuation(c, wo2, s.wi) * (1.0 - fresnel_dielectric(wi.z, c.ior));
    let pdf = (1.0 - p_coat) * s.pdf;
    Some(BsdfSample { wi, f: weight * pdf / wi.z, pdf, weight, delta: true })
}
