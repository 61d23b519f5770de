//! Scattering: `f`, `pdf` and `sample_f` for every [`Material`], in a local frame whose
//! `+z` is the geometric normal (the winding's side). Directions point away from the
//! surface. Opaque materials are two-sided: they are evaluated as if `wo` were on the
//! `+z` side. Dielectrics use the normal's side to tell entering from leaving.
//!
//! `f` and `pdf` cover the continuous part only; delta lobes (mirror, smooth glass,
//! smooth conductor, smooth coats) are reached through `sample_f` alone, with
//! `delta = true`.

pub mod layered;
pub mod microfacet;
pub mod plastic;
mod sample;

use crate::cost::{BRANCH, DIV, DOT, LUMINANCE, SQRT, V3, V3_DIV};
use crate::cost::{declare, reads};
use crate::film::luminance;
use crate::sampling::Frame;
use crate::scene::Material;
use glam::{Vec2, Vec3};
use layered::SMOOTH;
use microfacet::{Ggx, fresnel_conductor, fresnel_dielectric, rough_dielectric, sample_rough_dielectric};
pub use sample::{BsdfSample, TransportMode};
use std::f32::consts::FRAC_1_PI;

/// The part of the code this module's declared arithmetic counts as ([`crate::cost::Part`]).
const COST_PART: crate::cost::Part = crate::cost::Part::Bsdf;

/// Flips both directions so that `wo` lies on `+z` (two-sided opaque surfaces).
#[inline]
fn upper(wo: Vec3, wi: Vec3) -> (Vec3, Vec3) {
    if wo.z < 0.0 { (flip(wo), flip(wi)) } else { (wo, wi) }
}

#[inline]
fn flip(w: Vec3) -> Vec3 {
    Vec3::new(w.x, w.y, -w.z)
}

#[inline]
fn reflect_z(w: Vec3) -> Vec3 {
    Vec3::new(-w.x, -w.y, w.z)
}

#[inline]
#[track_caller]
fn continuous(wi: Vec3, f: Vec3, pdf: f32) -> Option<BsdfSample> {
    let _inlined = crate::cost::scope();
    declare!(2 * BRANCH + 1 + V3 + V3_DIV);
    (pdf > 0.0 && wi.z != 0.0).then(|| BsdfSample { wi, f, pdf, weight: f * wi.z.abs() / pdf, delta: false })
}

impl Material {
    /// Probability of choosing the specular lobe of a glossy material.
    #[inline]
    #[track_caller]
    fn specular_weight(diffuse: Vec3, specular: Vec3) -> f32 {
        let _inlined = crate::cost::scope();
        declare!(2 * LUMINANCE + 1 + BRANCH + DIV);
        let (d, s) = (luminance(diffuse), luminance(specular));
        if d + s > 0.0 { s / (d + s) } else { 0.0 }
    }

    /// True for interfaces between two media (glass, rough glass), which scatter on
    /// both sides whatever the scene says about sidedness.
    pub fn is_dielectric(&self) -> bool {
        reads!(self, 1);
        matches!(self, Material::Glass { .. } | Material::RoughGlass { .. })
    }

    /// The relative index a scattering from `wo` to `wi` crosses: the interior's over
    /// the exterior's for a refraction into a dielectric, its inverse out of one, 1 for
    /// every reflection (Mitsuba's `BSDFSample3f::eta`).
    #[inline]
    pub fn eta(&self, wo: Vec3, wi: Vec3) -> f32 {
        reads!(self, 1);
        match *self {
            Material::Glass { ior, .. } | Material::RoughGlass { ior, .. } if wo.z * wi.z < 0.0 => {
                reads!(self, 1);
                if wo.z > 0.0 { ior } else { 1.0 / ior }
            }
            _ => 1.0,
        }
    }

    /// True when the material scatters only into discrete directions (no light
    /// sampling is possible at such a vertex).
    pub fn is_delta(&self) -> bool {
        reads!(self, 1);
        match *self {
            Material::Mirror { .. } | Material::Glass { .. } => true,
            Material::Conductor { roughness, .. } | Material::RoughGlass { roughness, .. } => {
                reads!(self, 1);
                roughness < SMOOTH
            }
            Material::Layered(ref l) => l.is_delta(),
            Material::Diffuse { .. } | Material::Glossy { .. } | Material::Plastic(_) => false,
        }
    }

    /// `wo` and `wi`, unit directions in world space at a surface of unit normal `n`,
    /// in the shading frame, as [`Material::f`] and [`Material::pdf`] take them. A Lambertian lobe reads nothing of them but their
    /// cosines, so for it the frame is not built and the tangential parts are left zero:
    /// the cosines are [`Frame::to_local`]'s own, bit for bit (its `z` is the dot product
    /// with `n`), and so are `f` and `pdf`. While a kernel's lane is counted
    /// ([`crate::cost::counting`]) the frame is always built, as the CUDA twins build it.
    #[inline(always)]
    #[track_caller]
    pub(crate) fn local_pair(&self, n: Vec3, wo: Vec3, wi: Vec3) -> (Vec3, Vec3) {
        if matches!(self, Material::Diffuse { .. }) && !crate::cost::counting() {
            return (Vec3::new(0.0, 0.0, wo.dot(n)), Vec3::new(0.0, 0.0, wi.dot(n)));
        }
        let frame = Frame::from_normal(n);
        (frame.to_local(wo), frame.to_local(wi))
    }

    /// The BSDF value for the pair (continuous part only).
    #[inline(always)]
    #[track_caller]
    pub fn f(&self, wo: Vec3, wi: Vec3, mode: TransportMode) -> Vec3 {
        let _inlined = crate::cost::scope();
        declare!(BRANCH, reads(self, 1));
        if let Material::RoughGlass { ior, roughness, tint } = *self {
            declare!(BRANCH, reads(self, 1));
            if roughness < SMOOTH {
                return Vec3::ZERO;
            }
            declare!(2 * BRANCH + 5 + DIV + V3, reads(self, 4));
            let (wo_u, wi_u, eta) = if wo.z < 0.0 { (flip(wo), flip(wi), 1.0 / ior) } else { (wo, wi, ior) };
            let (v, _) = rough_dielectric(Ggx { alpha: roughness }, eta, wo_u, wi_u, mode);
            return if wo.z * wi.z < 0.0 { tint * v } else { Vec3::splat(v) };
        }
        declare!(3 * BRANCH + 2);
        let (wo, wi) = upper(wo, wi);
        if wi.z <= 0.0 || wo.z <= 0.0 {
            return Vec3::ZERO;
        }
        declare!(BRANCH);
        match *self {
            Material::Diffuse { albedo } => {
                declare!(V3, reads(self, 3));
                albedo * FRAC_1_PI
            }
            Material::Glossy { diffuse, specular, roughness } => {
                let spec = Ggx { alpha: roughness }.reflection(wo, wi).map_or(0.0, |(v, _, _)| v);
                declare!(3 * V3, reads(self, 7));
                diffuse * FRAC_1_PI + specular * spec
            }
            Material::Conductor { eta, k, roughness } if roughness >= SMOOTH => {
                Ggx { alpha: roughness }.reflection(wo, wi).map_or(Vec3::ZERO, |(v, _, wm)| {
                    declare!(DOT + V3, reads(self, 7));
                    fresnel_conductor(wo.dot(wm), eta, k) * v
                })
            }
            Material::Layered(ref l) => l.f(wo, wi),
            Material::Plastic(p) => p.f(wo, wi),
            _ => Vec3::ZERO,
        }
    }

    /// Solid-angle density with which [`Material::sample_f`] picks `wi` (continuous part).
    #[inline(always)]
    #[track_caller]
    pub fn pdf(&self, wo: Vec3, wi: Vec3) -> f32 {
        let _inlined = crate::cost::scope();
        declare!(BRANCH, reads(self, 1));
        if let Material::RoughGlass { ior, roughness, .. } = *self {
            declare!(BRANCH, reads(self, 1));
            if roughness < SMOOTH {
                return 0.0;
            }
            declare!(BRANCH + 4 + DIV, reads(self, 1));
            let (wo_u, wi_u, eta) = if wo.z < 0.0 { (flip(wo), flip(wi), 1.0 / ior) } else { (wo, wi, ior) };
            return rough_dielectric(Ggx { alpha: roughness }, eta, wo_u, wi_u, TransportMode::Radiance).1;
        }
        declare!(3 * BRANCH + 2);
        let (wo, wi) = upper(wo, wi);
        if wi.z <= 0.0 || wo.z <= 0.0 {
            return 0.0;
        }
        declare!(BRANCH);
        match *self {
            Material::Diffuse { .. } => {
                declare!(1);
                wi.z * FRAC_1_PI
            }
            Material::Glossy { diffuse, specular, roughness } => {
                let ws = Self::specular_weight(diffuse, specular);
                let spec = Ggx { alpha: roughness }.reflection(wo, wi).map_or(0.0, |(_, p, _)| p);
                declare!(5, reads(self, 7));
                (1.0 - ws) * wi.z * FRAC_1_PI + ws * spec
            }
            Material::Conductor { roughness, .. } if roughness >= SMOOTH => {
                reads!(self, 1);
                Ggx { alpha: roughness }.reflection(wo, wi).map_or(0.0, |(_, p, _)| p)
            }
            Material::Layered(ref l) => l.pdf(wo, wi),
            Material::Plastic(p) => p.pdf(wo, wi),
            _ => 0.0,
        }
    }

    /// Samples an incident direction for `wo`. `u_lobe` picks a lobe, `u` the direction.
    #[inline]
    #[track_caller]
    pub fn sample_f(&self, wo: Vec3, u_lobe: f32, u: Vec2, mode: TransportMode) -> Option<BsdfSample> {
        self.sample_f_inlined(wo, u_lobe, u, mode)
    }

    /// [`Material::sample_f`], always inlined: for a caller that knows the material's
    /// kind, so that only its arm is left (the path tracer's lanes of diffuse hits,
    /// whose loop the compiler then runs on SIMD lanes).
    #[inline(always)]
    #[track_caller]
    pub(crate) fn sample_f_inlined(&self, wo: Vec3, u_lobe: f32, u: Vec2, mode: TransportMode) -> Option<BsdfSample> {
        let _inlined = crate::cost::scope();
        declare!(BRANCH);
        if wo.z == 0.0 {
            return None;
        }
        declare!(2 * BRANCH + 1, reads(self, 1));
        let side = if wo.z < 0.0 { -1.0 } else { 1.0 };
        let to_side = |w: Vec3| Vec3::new(w.x, w.y, w.z * side);
        let wo_up = to_side(wo);
        match *self {
            Material::Diffuse { .. } | Material::Glossy { .. } => {
                let wi_up = match *self {
                    Material::Glossy { diffuse, specular, roughness } => {
                        reads!(self, 7);
                        if u_lobe < Self::specular_weight(diffuse, specular) {
                            let wm = Ggx { alpha: roughness }.sample_visible(wo_up, u);
                            declare!(DOT + 1 + 2 * V3);
                            2.0 * wo_up.dot(wm) * wm - wo_up
                        } else {
                            crate::sampling::cosine_hemisphere(u)
                        }
                    }
                    _ => crate::sampling::cosine_hemisphere(u),
                };
                declare!(BRANCH);
                if wi_up.z <= 0.0 {
                    return None;
                }
                declare!(1);
                let wi = to_side(wi_up);
                continuous(wi, self.f(wo, wi, mode), self.pdf(wo, wi))
            }
            Material::Conductor { eta, k, roughness } => {
                declare!(BRANCH, reads(self, 1));
                if roughness < SMOOTH {
                    let wi = reflect_z(wo);
                    let fr = fresnel_conductor(wo_up.z, eta, k);
                    declare!(1 + V3_DIV, reads(self, 6));
                    return Some(BsdfSample { wi, f: fr / wi.z.abs(), pdf: 1.0, weight: fr, delta: true });
                }
                let wm = Ggx { alpha: roughness }.sample_visible(wo_up, u);
                declare!(DOT + 1 + 2 * V3 + BRANCH);
                let wi_up = 2.0 * wo_up.dot(wm) * wm - wo_up;
                if wi_up.z <= 0.0 {
                    return None;
                }
                declare!(1);
                let wi = to_side(wi_up);
                continuous(wi, self.f(wo, wi, mode), self.pdf(wo, wi))
            }
            Material::Layered(ref l) => {
                let s = l.sample(wo_up, u_lobe, u, mode)?;
                declare!(1);
                Some(BsdfSample { wi: to_side(s.wi), ..s })
            }
            Material::Plastic(p) => {
                let s = p.sample(wo_up, u_lobe, u)?;
                Some(BsdfSample { wi: to_side(s.wi), ..s })
            }
            Material::Mirror { reflectance } => {
                declare!(1 + V3_DIV, reads(self, 3));
                let wi = reflect_z(wo);
                Some(BsdfSample { wi, f: reflectance / wi.z.abs(), pdf: 1.0, weight: reflectance, delta: true })
            }
            Material::RoughGlass { ior, roughness, .. } if roughness >= SMOOTH => {
                declare!(BRANCH + DIV, reads(self, 2));
                let eta = if wo.z > 0.0 { ior } else { 1.0 / ior };
                let wi_up = sample_rough_dielectric(Ggx { alpha: roughness }, eta, wo_up, u_lobe, u)?;
                declare!(1);
                let wi = to_side(wi_up);
                continuous(wi, self.f(wo, wi, mode), self.pdf(wo, wi))
            }
            Material::Glass { ior, tint } | Material::RoughGlass { ior, tint, .. } => {
                declare!(2 * BRANCH + DIV + 1, reads(self, 1));
                let entering = wo.z > 0.0;
                let eta = if entering { ior } else { 1.0 / ior };
                let fr = fresnel_dielectric(wo.z.abs(), eta);
                if u_lobe < fr {
                    declare!(2 + DIV);
                    let wi = reflect_z(wo);
                    return Some(BsdfSample {
                        wi,
                        f: Vec3::splat(fr / wi.z.abs()),
                        pdf: fr,
                        weight: Vec3::ONE,
                        delta: true,
                    });
                }
                // Refraction about the normal on wo's side.
                declare!(12 + 4 * DIV + SQRT + BRANCH + 2 * V3, reads(self, 3));
                let cos_i = wo.z.abs();
                let sin2_t = (1.0 - cos_i * cos_i) / (eta * eta);
                let cos_t = (1.0 - sin2_t).max(0.0).sqrt();
                let wi = Vec3::new(-wo.x / eta, -wo.y / eta, -side * cos_t);
                let scale = if mode == TransportMode::Radiance { 1.0 / (eta * eta) } else { 1.0 };
                let ft = tint * ((1.0 - fr) * scale / cos_t.max(1e-12));
                Some(BsdfSample { wi, f: ft, pdf: 1.0 - fr, weight: tint * scale, delta: true })
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sampling::{Rng, uniform_sphere};
    use crate::scene::Plastic;

    /// `local_pair` gives every material's `f` and `pdf` what the shading frame gives,
    /// bit for bit, for random normals and directions on both sides: the Lambertian
    /// shortcut (only the cosines) must not reach a lobe that reads more of the
    /// directions, and must give the frame's own cosines.
    #[test]
    fn local_pairs_give_the_frames_values_bit_for_bit() {
        let materials = [
            Material::Diffuse { albedo: Vec3::new(0.8, 0.5, 0.2) },
            Material::Glossy { diffuse: Vec3::splat(0.4), specular: Vec3::splat(0.5), roughness: 0.3 },
            Material::Conductor { eta: Vec3::splat(0.2), k: Vec3::splat(3.0), roughness: 0.3 },
            Material::RoughGlass { ior: 1.5, roughness: 0.3, tint: Vec3::ONE },
            Material::Plastic(Plastic::new(Vec3::new(0.2, 0.4, 0.7), Vec3::ONE, 1.49, 0.0, false)),
            Material::Plastic(Plastic::new(Vec3::new(0.7, 0.3, 0.1), Vec3::ONE, 1.6, 0.25, true)),
        ];
        let mut rng = Rng::for_sample(3, 0, 0);
        let mut nonzero = 0;
        for m in &materials {
            for _ in 0..2000 {
                let (n, wo, wi) =
                    (uniform_sphere(rng.uniform2()), uniform_sphere(rng.uniform2()), uniform_sphere(rng.uniform2()));
                let frame = Frame::from_normal(n);
                let (lo, li) = (frame.to_local(wo), frame.to_local(wi));
                let (po, pi) = m.local_pair(n, wo, wi);
                if matches!(m, Material::Diffuse { .. }) {
                    assert_eq!((po.x, po.y, pi.x, pi.y), (0.0, 0.0, 0.0, 0.0), "the shortcut was not taken");
                }
                let bits = |v: Vec3| v.to_array().map(f32::to_bits);
                for mode in [TransportMode::Radiance, TransportMode::Importance] {
                    assert_eq!(bits(m.f(po, pi, mode)), bits(m.f(lo, li, mode)), "{m:?}: f at {n}, {wo}, {wi}");
                }
                assert_eq!(m.pdf(po, pi).to_bits(), m.pdf(lo, li).to_bits(), "{m:?}: pdf at {n}, {wo}, {wi}");
                nonzero += (m.pdf(lo, li) > 0.0) as u32;
            }
        }
        assert!(nonzero > 4000, "only {nonzero} pairs with a density");
    }

    /// Inside a measured kernel (with the feature `model-arithmetic`) a Lambertian pair
    /// is worked out through the frame, as the CUDA twins do: each lane declares the
    /// frame and its two changes of basis, and the shortcut declares nothing.
    #[cfg(feature = "model-arithmetic")]
    #[test]
    fn a_counted_lane_builds_the_frame_as_the_cuda_twins_do() {
        use crate::cost::{FRAME, Part, TO_LOCAL};
        const PARTS: [&str; 6] = [
            Part::ALL[0].name(),
            Part::ALL[1].name(),
            Part::ALL[2].name(),
            Part::ALL[3].name(),
            Part::ALL[4].name(),
            Part::ALL[5].name(),
        ];
        let dev = simt::Device::new(simt::DeviceConfig { measure: true, ..Default::default() });
        let m = Material::Diffuse { albedo: Vec3::splat(0.5) };
        let (n, wo, wi) = (Vec3::new(0.0, 0.6, 0.8), Vec3::new(0.3, 0.1, 0.9).normalize(), Vec3::Z);
        let rec = dev.for_each_in("bsdf::local_pair", &PARTS, 32, |t, _| {
            t.ambient(0, || std::hint::black_box(m.local_pair(n, wo, wi)));
        });
        let all = rec.all_regions();
        assert_eq!((all.issued, all.active), ((FRAME + 2 * TO_LOCAL) as u64, 32 * (FRAME + 2 * TO_LOCAL) as u64));
    }
}
