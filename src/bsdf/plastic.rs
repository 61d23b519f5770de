//! Mitsuba 3's `plastic` and `roughplastic`: a Lambertian base under a smooth or GGX
//! dielectric coat, with the light trapped inside the coat accounted for in closed
//! form rather than simulated. The XML loader maps those plugins here, so that a scene
//! written for Mitsuba gives Mitsuba's image; warpray's own coats (`layered.rs`) stay
//! what TOML scenes and the CIS paper's materials use.
//!
//! With η the coat's relative index, F(cos) the dielectric Fresnel reflectance, ρ the
//! base's albedo, directions in the local frame (`+z` the normal) and both above it:
//!
//! * **Smooth** (`plastic`): a delta reflection of weight `specular · F(cos_o)`, and a
//!   diffuse lobe `f = ρ' / π · (1 − F(cos_o)) (1 − F(cos_i)) / η²`.
//! * **Rough** (`roughplastic`, GGX α): the microfacet reflection
//!   `f = specular · F(wo·h) D(h) G1(wo, h) G1(wi, h) / (4 cos_o cos_i)` (Smith's
//!   separable masking, as Mitsuba's), plus the diffuse lobe with `1 − F(cos)` replaced
//!   by the rough coat's directional transmittance T(cos), tabulated at 64 cosines
//!   and interpolated linearly.
//! * ρ' = ρ / (1 − R_int), the internal reflections summed as a geometric series;
//!   with `nonlinear`, ρ / (1 − ρ R_int), which shifts colours as a real coat does.
//!   R_int is the coat's diffuse reflectance seen from inside: the Egan–Hilgeman /
//!   d'Eon–Irving fit of F_dr(1/η) for the smooth coat; for the rough coat
//!   2 ∫ R(μ; 1/η) μ dμ, with R the rough coat's directional albedo seen from inside,
//!   averaged over the same 64 cosines.
//!
//! Sampling follows Mitsuba: the specular lobe is chosen with probability
//! `F·w / (F·w + (1 − F)(1 − w))`, where `w = s̄ / (ρ̄ + s̄)` (channel means) and F is
//! F(cos_o) (smooth) or 1 − T(cos_o) (rough); the specular direction from visible
//! normals, the diffuse one cosine-weighted. The rough lobe's density is the mixture
//! of both.
//!
//! The tables are integrals (directional albedo and transmittance of the rough coat
//! under its visible normals) computed here with a 32 × 32 (128 × 128 seen from
//! inside) Gauss–Legendre rule over the visible-normal sample square, as Mitsuba does;
//! the square is mapped to normals by warpray's own visible-normal sampler, so the
//! tables agree with Mitsuba's to the quadrature's error, not to the bit.

use super::microfacet::{Ggx, fresnel_dielectric};
use super::sample::BsdfSample;
use glam::{Vec2, Vec3};
use std::f32::consts::FRAC_1_PI;
use std::sync::Mutex;

/// Cosines at which the rough coat's transmittance is tabulated (Mitsuba's
/// `MI_ROUGH_TRANSMITTANCE_RES`).
pub const TABLE_SIZE: usize = 64;

/// Mitsuba's plastic (see the module docs). Build it with [`Plastic::new`], which
/// computes what the lobes need from the parameters.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Plastic {
    /// Albedo of the Lambertian base (ρ).
    pub diffuse: Vec3,
    /// Scale of the coat's specular reflection (1 for a physical coat).
    pub specular: Vec3,
    /// Relative index of the coat (interior over exterior).
    pub eta: f32,
    /// GGX α of the coat; 0 for the smooth `plastic`.
    pub roughness: f32,
    /// Whether the internal reflections tint the base (Mitsuba's `nonlinear`).
    pub nonlinear: bool,
    /// Probability weight of the specular lobe, `s̄ / (ρ̄ + s̄)`.
    specular_weight: f32,
    /// R_int: the coat's diffuse reflectance seen from inside.
    internal: f32,
    /// The rough coat's transmittance at `TABLE_SIZE` cosines from 0 to 1 (shared by
    /// every plastic with the same η and α).
    transmittance: Option<&'static [f32; TABLE_SIZE]>,
}

/// Coats below this α are smooth (as for warpray's other rough lobes).
const SMOOTH: f32 = super::layered::SMOOTH;

impl Plastic {
    /// A plastic of base albedo `diffuse`, specular scale `specular`, relative index
    /// `eta` (> 0, ≠ 1), GGX α `roughness` (0: smooth) and Mitsuba's `nonlinear` flag.
    pub fn new(diffuse: Vec3, specular: Vec3, eta: f32, roughness: f32, nonlinear: bool) -> Plastic {
        let (d_mean, s_mean) = (diffuse.element_sum() / 3.0, specular.element_sum() / 3.0);
        let specular_weight = if d_mean + s_mean > 0.0 { s_mean / (d_mean + s_mean) } else { 0.0 };
        let (internal, transmittance) = if roughness < SMOOTH {
            (fresnel_diffuse_reflectance(1.0 / eta), None)
        } else {
            let t = tables(eta, roughness);
            (t.1, Some(t.0))
        };
        Plastic { diffuse, specular, eta, roughness, nonlinear, specular_weight, internal, transmittance }
    }

    /// The coat's reflectance at `cos` for lobe selection: F(cos) for a smooth coat,
    /// 1 − T(cos) for a rough one.
    fn coat_reflectance(&self, cos: f32) -> f32 {
        1.0 - self.transmitted(cos)
    }

    fn transmitted(&self, cos: f32) -> f32 {
        match self.transmittance {
            None => 1.0 - fresnel_dielectric(cos, self.eta),
            Some(t) => lerp_table(t, cos),
        }
    }

    /// Probability of sampling the specular lobe for outgoing cosine `cos_o`.
    fn specular_probability(&self, cos_o: f32) -> f32 {
        let f = self.coat_reflectance(cos_o);
        let (s, d) = (f * self.specular_weight, (1.0 - f) * (1.0 - self.specular_weight));
        if s + d > 0.0 { s / (s + d) } else { 0.0 }
    }

    /// The diffuse lobe's value (both directions above the surface).
    fn diffuse_f(&self, wo: Vec3, wi: Vec3) -> Vec3 {
        let base = if self.nonlinear {
            self.diffuse / (Vec3::ONE - self.diffuse * self.internal)
        } else {
            self.diffuse / (1.0 - self.internal)
        };
        base * (FRAC_1_PI / (self.eta * self.eta) * self.transmitted(wo.z) * self.transmitted(wi.z))
    }

    /// The rough coat's reflection and its visible-normal density (`None` when the
    /// half vector is degenerate).
    fn glossy(&self, wo: Vec3, wi: Vec3) -> Option<(Vec3, f32)> {
        let wm = (wo + wi).normalize_or_zero();
        if wm == Vec3::ZERO {
            return None;
        }
        let ggx = Ggx { alpha: self.roughness };
        let d = ggx.d(wm);
        let (g_o, g_i) = (masking(ggx, wo, wm), masking(ggx, wi, wm));
        let fr = fresnel_dielectric(wo.dot(wm), self.eta);
        let value = self.specular * (fr * d * g_o * g_i / (4.0 * wo.z * wi.z));
        Some((value, d * g_o / (4.0 * wo.z)))
    }

    /// `f` for directions on the `+z` side (the caller makes the pair two-sided).
    pub fn f(&self, wo: Vec3, wi: Vec3) -> Vec3 {
        if wo.z <= 0.0 || wi.z <= 0.0 {
            return Vec3::ZERO;
        }
        let diffuse = self.diffuse_f(wo, wi);
        match self.transmittance {
            None => diffuse,
            Some(_) => diffuse + self.glossy(wo, wi).map_or(Vec3::ZERO, |g| g.0),
        }
    }

    /// The density with which [`Plastic::sample`] picks `wi` (continuous part).
    pub fn pdf(&self, wo: Vec3, wi: Vec3) -> f32 {
        if wo.z <= 0.0 || wi.z <= 0.0 {
            return 0.0;
        }
        let p_spec = self.specular_probability(wo.z);
        let diffuse = (1.0 - p_spec) * wi.z * FRAC_1_PI;
        match self.transmittance {
            None => diffuse,
            Some(_) => diffuse + p_spec * self.glossy(wo, wi).map_or(0.0, |g| g.1),
        }
    }

    /// Samples `wi` for `wo` on the `+z` side: the specular lobe with probability
    /// [`Plastic::specular_probability`], else the diffuse one.
    pub fn sample(&self, wo: Vec3, u_lobe: f32, u: Vec2) -> Option<BsdfSample> {
        if wo.z <= 0.0 {
            return None;
        }
        let p_spec = self.specular_probability(wo.z);
        let specular = u_lobe < p_spec;
        if specular && self.transmittance.is_none() {
            let wi = Vec3::new(-wo.x, -wo.y, wo.z);
            let weight = self.specular * (fresnel_dielectric(wo.z, self.eta) / p_spec);
            return Some(BsdfSample { wi, f: weight * p_spec / wi.z, pdf: p_spec, weight, delta: true });
        }
        let wi = if specular {
            let wm = Ggx { alpha: self.roughness }.sample_visible(wo, u);
            2.0 * wo.dot(wm) * wm - wo
        } else {
            crate::sampling::cosine_hemisphere(u)
        };
        let (f, pdf) = (self.f(wo, wi), self.pdf(wo, wi));
        (pdf > 0.0 && wi.z > 0.0).then(|| BsdfSample { wi, f, pdf, weight: f * wi.z / pdf, delta: false })
    }
}

/// Smith's G1 for GGX with Mitsuba's orientation rule: zero where `w` sees the back
/// of the microfacet.
fn masking(ggx: Ggx, w: Vec3, wm: Vec3) -> f32 {
    if w.dot(wm) * w.z <= 0.0 { 0.0 } else { ggx.g1(w) }
}

/// Mitsuba's fit of the diffuse Fresnel reflectance F_dr(η): Egan and Hilgeman (1973)
/// below η = 1, d'Eon and Irving (2011) above.
pub fn fresnel_diffuse_reflectance(eta: f32) -> f32 {
    if eta < 1.0 {
        0.0636 / eta + eta * (eta * -1.4399 + 0.7099) + 0.6681
    } else {
        let x = 1.0 / eta;
        [0.919317, -3.4793, 6.75335, -7.80989, 4.98554, -1.36881].iter().rev().fold(0.0, |acc, c| acc * x + c)
    }
}

/// Linear interpolation in a table over cosines 0..=1 (Mitsuba's `lerp_gather`).
fn lerp_table(t: &[f32; TABLE_SIZE], cos: f32) -> f32 {
    let x = cos.clamp(0.0, 1.0) * (TABLE_SIZE - 1) as f32;
    let i = (x as usize).min(TABLE_SIZE - 2);
    let w = x - i as f32;
    t[i] * (1.0 - w) + t[i + 1] * w
}

/// The cosines of the tables: 0 to 1 in `TABLE_SIZE` steps, the first raised to 1e-6.
fn table_cosine(k: usize) -> f32 {
    (k as f32 / (TABLE_SIZE - 1) as f32).max(1e-6)
}

/// Gauss–Legendre nodes and weights on [−1, 1] (Newton's method on P_n, in f64).
fn gauss_legendre(n: usize) -> Vec<(f64, f64)> {
    (0..n)
        .map(|i| {
            let mut x = (std::f64::consts::PI * (i as f64 + 0.75) / (n as f64 + 0.5)).cos();
            let mut dp = 0.0;
            for _ in 0..100 {
                let (mut p0, mut p1) = (1.0, x);
                for k in 2..=n {
                    let k = k as f64;
                    (p0, p1) = (p1, ((2.0 * k - 1.0) * x * p1 - (k - 1.0) * p0) / k);
                }
                dp = n as f64 * (x * p1 - p0) / (x * x - 1.0);
                let dx = p1 / dp;
                x -= dx;
                if dx.abs() < 1e-15 {
                    break;
                }
            }
            (x, 2.0 / ((1.0 - x * x) * dp * dp))
        })
        .collect()
}

/// The coat's directional albedo (`reflect`) or transmittance at incidence `wi` for
/// relative index `eta`: the mean over visible normals of F·G1(reflected) or
/// (1 − F)·G1(refracted), by a product Gauss–Legendre rule on the sample square.
fn coat_integral(ggx: Ggx, rule: &[(f64, f64)], wi: Vec3, eta: f32, reflect: bool) -> f32 {
    let mut sum = 0.0f64;
    for &(x, wx) in rule {
        for &(y, wy) in rule {
            let u = Vec2::new((0.5 * x + 0.5) as f32, (0.5 * y + 0.5) as f32);
            let wm = ggx.sample_visible(wi, u);
            let c = wi.dot(wm);
            let fr = fresnel_dielectric(c, eta);
            let value = if reflect {
                let wo = 2.0 * c * wm - wi;
                if wo.z <= 0.0 { 0.0 } else { fr * masking(ggx, wo, wm) }
            } else {
                // Refraction through the microfacet (total internal reflection: F = 1).
                let sin2_t = (1.0 - c * c) / (eta * eta);
                if sin2_t >= 1.0 {
                    0.0
                } else {
                    let cos_t = (1.0 - sin2_t).sqrt();
                    let wo = (c / eta - cos_t) * wm - wi / eta;
                    if wo.z * wi.z >= 0.0 { 0.0 } else { (1.0 - fr) * masking(ggx, wo, wm) }
                }
            };
            sum += value as f64 * wx * wy;
        }
    }
    (sum * 0.25) as f32
}

/// The rough coat's transmittance table and internal reflectance for (η, α), computed
/// once per pair and kept for the process (a scene holds few distinct pairs).
fn tables(eta: f32, alpha: f32) -> (&'static [f32; TABLE_SIZE], f32) {
    type Entry = (u32, u32, &'static [f32; TABLE_SIZE], f32);
    static TABLES: Mutex<Vec<Entry>> = Mutex::new(Vec::new());
    let key = (eta.to_bits(), alpha.to_bits());
    let mut known = TABLES.lock().unwrap_or_else(|e| e.into_inner());
    if let Some(&(_, _, t, r)) = known.iter().find(|e| (e.0, e.1) == key) {
        return (t, r);
    }
    let ggx = Ggx { alpha };
    let incidence = |k: usize| {
        let mu = table_cosine(k);
        Vec3::new((1.0 - mu * mu).sqrt(), 0.0, mu)
    };
    // Mitsuba's rule sizes: 32 points a side for η > 1, 128 for η < 1.
    let rule = |eta: f32| gauss_legendre(if eta > 1.0 { 32 } else { 128 });
    let (outside, inside) = (rule(eta), rule(1.0 / eta));
    let mut t = [0.0; TABLE_SIZE];
    for (k, v) in t.iter_mut().enumerate() {
        *v = coat_integral(ggx, &outside, incidence(k), eta, false);
    }
    let internal = 2.0
        * (0..TABLE_SIZE)
            .map(|k| coat_integral(ggx, &inside, incidence(k), 1.0 / eta, true) * table_cosine(k))
            .sum::<f32>()
        / TABLE_SIZE as f32;
    let t: &'static [f32; TABLE_SIZE] = Box::leak(Box::new(t));
    known.push((key.0, key.1, t, internal));
    (t, internal)
}
