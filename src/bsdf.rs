//! Scattering: `f`, `pdf` and `sample_f` for every [`Material`], in a local frame whose
//! `+z` is the geometric normal (the winding's side). Directions point away from the
//! surface. Opaque materials are two-sided: they are evaluated as if `wo` were on the
//! `+z` side. Glass uses the normal's side to tell entering from leaving.
//!
//! The GGX (Trowbridge–Reitz) lobe samples visible normals (Heitz 2018).

use crate::scene::Material;
use glam::{Vec2, Vec3};
use std::f32::consts::{FRAC_1_PI, PI};

/// Whether a path carries radiance (from the camera) or importance (from a light).
/// Refraction scales radiance by 1/η² but not importance (Veach 1997, ch. 5).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum TransportMode {
    Radiance,
    Importance,
}

/// A sampled direction. `weight = f · |cos θi| / pdf`; for delta lobes `f` and `pdf`
/// are the discrete probability and matching value, so the same identity holds.
#[derive(Clone, Copy, Debug)]
pub struct BsdfSample {
    pub wi: Vec3,
    pub f: Vec3,
    pub pdf: f32,
    pub weight: Vec3,
    pub delta: bool,
}

#[inline]
fn luminance(c: Vec3) -> f32 {
    c.dot(Vec3::new(0.2126, 0.7152, 0.0722))
}

/// Flips both directions so that `wo` lies on `+z` (two-sided opaque surfaces).
#[inline]
fn upper(wo: Vec3, wi: Vec3) -> (Vec3, Vec3) {
    if wo.z < 0.0 { (wo * Vec3::new(1.0, 1.0, -1.0), wi * Vec3::new(1.0, 1.0, -1.0)) } else { (wo, wi) }
}

#[inline]
fn reflect_z(w: Vec3) -> Vec3 {
    Vec3::new(-w.x, -w.y, w.z)
}

/// Unpolarised Fresnel reflectance of a dielectric interface; `eta = η_t / η_i`.
pub fn fresnel_dielectric(cos_i: f32, eta: f32) -> f32 {
    let cos_i = cos_i.clamp(0.0, 1.0);
    let sin2_t = (1.0 - cos_i * cos_i) / (eta * eta);
    if sin2_t >= 1.0 {
        return 1.0;
    }
    let cos_t = (1.0 - sin2_t).sqrt();
    let r_par = (eta * cos_i - cos_t) / (eta * cos_i + cos_t);
    let r_perp = (cos_i - eta * cos_t) / (cos_i + eta * cos_t);
    0.5 * (r_par * r_par + r_perp * r_perp)
}

/// GGX microfacet distribution of roughness `alpha`.
#[derive(Clone, Copy, Debug)]
pub struct Ggx {
    pub alpha: f32,
}

impl Ggx {
    pub fn d(&self, wm: Vec3) -> f32 {
        if wm.z <= 0.0 {
            return 0.0;
        }
        let a2 = self.alpha * self.alpha;
        let c2 = wm.z * wm.z;
        let denom = c2 * (a2 - 1.0) + 1.0;
        a2 / (PI * denom * denom)
    }

    fn lambda(&self, w: Vec3) -> f32 {
        let c2 = w.z * w.z;
        if c2 == 0.0 {
            return f32::INFINITY;
        }
        let tan2 = ((1.0 - c2) / c2).max(0.0);
        0.5 * ((1.0 + self.alpha * self.alpha * tan2).sqrt() - 1.0)
    }

    pub fn g1(&self, w: Vec3) -> f32 {
        1.0 / (1.0 + self.lambda(w))
    }

    pub fn g2(&self, wo: Vec3, wi: Vec3) -> f32 {
        1.0 / (1.0 + self.lambda(wo) + self.lambda(wi))
    }

    /// Density of visible normal `wm` as seen from `wo` (`wo.z > 0`).
    pub fn visible_pdf(&self, wo: Vec3, wm: Vec3) -> f32 {
        self.g1(wo) * wo.dot(wm).max(0.0) * self.d(wm) / wo.z
    }

    /// Samples a visible normal from `wo` (`wo.z > 0`).
    pub fn sample_visible(&self, wo: Vec3, u: Vec2) -> Vec3 {
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
}

impl Material {
    /// Probability of choosing the specular lobe of a glossy material.
    fn specular_weight(diffuse: Vec3, specular: Vec3) -> f32 {
        let (d, s) = (luminance(diffuse), luminance(specular));
        if d + s > 0.0 { s / (d + s) } else { 0.0 }
    }

    /// The BSDF value for the pair (non-delta part only; 0 for mirror and glass).
    pub fn f(&self, wo: Vec3, wi: Vec3, _mode: TransportMode) -> Vec3 {
        let (wo, wi) = upper(wo, wi);
        if wi.z <= 0.0 || wo.z <= 0.0 {
            return Vec3::ZERO;
        }
        match *self {
            Material::Diffuse { albedo } => albedo * FRAC_1_PI,
            Material::Glossy { diffuse, specular, roughness } => {
                let ggx = Ggx { alpha: roughness };
                let wm = (wo + wi).normalize();
                diffuse * FRAC_1_PI + specular * (ggx.d(wm) * ggx.g2(wo, wi) / (4.0 * wo.z * wi.z))
            }
            Material::Mirror { .. } | Material::Glass { .. } => Vec3::ZERO,
        }
    }

    /// Solid-angle density with which [`Material::sample_f`] picks `wi` (non-delta part).
    pub fn pdf(&self, wo: Vec3, wi: Vec3) -> f32 {
        let (wo, wi) = upper(wo, wi);
        if wi.z <= 0.0 || wo.z <= 0.0 {
            return 0.0;
        }
        match *self {
            Material::Diffuse { .. } => wi.z * FRAC_1_PI,
            Material::Glossy { diffuse, specular, roughness } => {
                let ws = Self::specular_weight(diffuse, specular);
                let ggx = Ggx { alpha: roughness };
                let wm = (wo + wi).normalize();
                (1.0 - ws) * wi.z * FRAC_1_PI + ws * ggx.visible_pdf(wo, wm) / (4.0 * wo.dot(wm))
            }
            Material::Mirror { .. } | Material::Glass { .. } => 0.0,
        }
    }

    /// Samples an incident direction for `wo`. `u_lobe` picks a lobe, `u` the direction.
    pub fn sample_f(&self, wo: Vec3, u_lobe: f32, u: Vec2, mode: TransportMode) -> Option<BsdfSample> {
        if wo.z == 0.0 {
            return None;
        }
        let side = if wo.z < 0.0 { -1.0 } else { 1.0 };
        let to_side = |w: Vec3| Vec3::new(w.x, w.y, w.z * side);
        match *self {
            Material::Diffuse { .. } | Material::Glossy { .. } => {
                let wo_up = to_side(wo);
                let wi_up = match *self {
                    Material::Glossy { diffuse, specular, roughness }
                        if u_lobe < Self::specular_weight(diffuse, specular) =>
                    {
                        let wm = Ggx { alpha: roughness }.sample_visible(wo_up, u);
                        wo_up.reflect(wm) * -1.0
                    }
                    _ => crate::sampling::cosine_hemisphere(u),
                };
                if wi_up.z <= 0.0 {
                    return None;
                }
                let wi = to_side(wi_up);
                let f = self.f(wo, wi, mode);
                let pdf = self.pdf(wo, wi);
                if pdf <= 0.0 {
                    return None;
                }
                Some(BsdfSample { wi, f, pdf, weight: f * wi_up.z / pdf, delta: false })
            }
            Material::Mirror { reflectance } => {
                let wi = reflect_z(wo);
                Some(BsdfSample { wi, f: reflectance / wi.z.abs(), pdf: 1.0, weight: reflectance, delta: true })
            }
            Material::Glass { ior, tint } => {
                let entering = wo.z > 0.0;
                let eta = if entering { ior } else { 1.0 / ior };
                let fr = fresnel_dielectric(wo.z.abs(), eta);
                if u_lobe < fr {
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
