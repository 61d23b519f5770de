//! Reference optics for the BSDF tests, written out from the textbook formulas in
//! `f64` and sharing no code with `warpray::bsdf`: Fresnel for dielectrics (Snell's law,
//! total internal reflection) and conductors (complex index), the GGX distribution
//! (Walter et al. 2007) with Smith's height-correlated masking (Heitz 2014), and small
//! vector helpers.

use std::f64::consts::PI;
use warpray::glam::Vec3;

/// Unpolarised Fresnel reflectance for light arriving at `cos_i` in a medium of index
/// `n_i` at an interface to index `n_t` (1 beyond the critical angle).
pub(crate) fn fresnel(cos_i: f64, n_i: f64, n_t: f64) -> f64 {
    let sin_t = n_i / n_t * (1.0 - cos_i * cos_i).max(0.0).sqrt();
    if sin_t >= 1.0 {
        return 1.0;
    }
    let cos_t = (1.0 - sin_t * sin_t).sqrt();
    let rs = (n_i * cos_i - n_t * cos_t) / (n_i * cos_i + n_t * cos_t);
    let rp = (n_i * cos_t - n_t * cos_i) / (n_i * cos_t + n_t * cos_i);
    0.5 * (rs * rs + rp * rp)
}

/// A complex number, for the conductor's Fresnel equations.
#[derive(Clone, Copy)]
pub(crate) struct C(pub(crate) f64, pub(crate) f64);

impl C {
    pub(crate) fn add(self, o: C) -> C {
        C(self.0 + o.0, self.1 + o.1)
    }
    pub(crate) fn sub(self, o: C) -> C {
        C(self.0 - o.0, self.1 - o.1)
    }
    pub(crate) fn mul(self, o: C) -> C {
        C(self.0 * o.0 - self.1 * o.1, self.0 * o.1 + self.1 * o.0)
    }
    pub(crate) fn div(self, o: C) -> C {
        let d = o.0 * o.0 + o.1 * o.1;
        C((self.0 * o.0 + self.1 * o.1) / d, (self.1 * o.0 - self.0 * o.1) / d)
    }
    pub(crate) fn sqrt(self) -> C {
        let r = (self.0 * self.0 + self.1 * self.1).sqrt();
        let re = (0.5 * (r + self.0)).max(0.0).sqrt();
        let im = (0.5 * (r - self.0)).max(0.0).sqrt().copysign(self.1);
        C(re, im)
    }
    pub(crate) fn norm2(self) -> f64 {
        self.0 * self.0 + self.1 * self.1
    }
}

/// Unpolarised reflectance of a conductor of complex index `n + ik` seen from air.
pub(crate) fn fresnel_conductor(cos_i: f64, n: f64, k: f64) -> f64 {
    let (eta, c) = (C(n, k), C(cos_i, 0.0));
    let sin2 = C(1.0 - cos_i * cos_i, 0.0);
    let cos_t = C(1.0, 0.0).sub(sin2.div(eta.mul(eta))).sqrt();
    let rs = c.sub(eta.mul(cos_t)).div(c.add(eta.mul(cos_t)));
    let rp = eta.mul(c).sub(cos_t).div(eta.mul(c).add(cos_t));
    0.5 * (rs.norm2() + rp.norm2())
}

/// GGX (Trowbridge–Reitz) normal distribution, Walter et al. 2007, eq. 33.
pub(crate) fn ggx_d(alpha: f64, cos_m: f64) -> f64 {
    if cos_m <= 0.0 {
        return 0.0;
    }
    let (c2, a2) = (cos_m * cos_m, alpha * alpha);
    let tan2 = (1.0 - c2) / c2;
    a2 / (PI * c2 * c2 * (a2 + tan2).powi(2))
}

/// Smith's Λ for GGX (Heitz 2014, eq. 72).
pub(crate) fn ggx_lambda(alpha: f64, cos: f64) -> f64 {
    let c2 = cos * cos;
    let tan2 = (1.0 - c2) / c2;
    0.5 * ((1.0 + alpha * alpha * tan2).sqrt() - 1.0)
}

/// Height-correlated masking-shadowing (Heitz 2014, eq. 99).
pub(crate) fn ggx_g2(alpha: f64, cos_o: f64, cos_i: f64) -> f64 {
    1.0 / (1.0 + ggx_lambda(alpha, cos_o.abs()) + ggx_lambda(alpha, cos_i.abs()))
}

pub(crate) fn v(w: Vec3) -> [f64; 3] {
    [w.x as f64, w.y as f64, w.z as f64]
}

pub(crate) fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

pub(crate) fn normalize(a: [f64; 3]) -> [f64; 3] {
    let l = dot(a, a).sqrt();
    [a[0] / l, a[1] / l, a[2] / l]
}

/// The microfacet reflection value `D G2 / (4 cos_o cos_i)` (without Fresnel) and the
/// half vector's cosine with `wo`.
pub(crate) fn microfacet_reflection(alpha: f64, wo: Vec3, wi: Vec3) -> (f64, f64) {
    let (o, i) = (v(wo), v(wi));
    let m = normalize([o[0] + i[0], o[1] + i[1], o[2] + i[2]]);
    (ggx_d(alpha, m[2]) * ggx_g2(alpha, o[2], i[2]) / (4.0 * o[2] * i[2]), dot(o, m))
}

/// Direction at polar angle `theta` and azimuth `phi`.
pub(crate) fn dir(theta: f64, phi: f64) -> Vec3 {
    Vec3::new((theta.sin() * phi.cos()) as f32, (theta.sin() * phi.sin()) as f32, theta.cos() as f32)
}

/// Pairs of directions on the upper side, spread over polar angles and azimuths.
pub(crate) fn upper_pairs() -> Vec<(Vec3, Vec3)> {
    let mut out = Vec::new();
    for &to in &[0.1, 0.5, 0.9, 1.2] {
        for &ti in &[0.05, 0.4, 0.8, 1.3] {
            for &phi in &[0.0, 1.0, 2.5, PI] {
                out.push((dir(to, 0.3), dir(ti, 0.3 + phi)));
            }
        }
    }
    out
}

pub(crate) fn close(got: f64, want: f64, rel: f64) -> bool {
    (got - want).abs() <= rel * want.abs() + 1e-6
}
