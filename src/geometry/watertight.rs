//! The watertight ray/triangle test of Woop, Benthin and Wald (JCGT 2013): the
//! per-ray shear ([`RayShear`]) and the test itself, which every caster's leaf runs
//! (the SIMD lanes of [`super::lanes`] run it operation for operation).

use glam::{Vec3, Vec3A};

/// Per-ray constants of the watertight test: the permutation that makes the dominant
/// direction axis `z`, and the shear that maps the ray onto `+z`.
#[derive(Clone, Copy, Debug)]
pub struct RayShear {
    /// The permutation and shear as three rows: `x' = rx · v`, `y' = ry · v`,
    /// `z' = rz · v` for a vertex `v` relative to the ray origin. Each row has one or
    /// two non-zero entries, so the products are those of the permuted form exactly
    /// (the zero terms add exactly), with no per-triangle indexing.
    pub(super) rx: Vec3A,
    pub(super) ry: Vec3A,
    pub(super) rz: Vec3A,
}

impl RayShear {
    #[inline]
    /// The shear of a ray direction.
    pub fn new(dir: Vec3) -> RayShear {
        // The dominant axis (ties to the lower axis), by arithmetic on the comparisons
        // rather than branches: path-traced rays point every way, and branches on
        // their directions were mispredicted ray after ray.
        let a = dir.abs();
        let x_wins = (a.x >= a.y) & (a.x >= a.z);
        let kz = (!x_wins) as usize * (1 + (a.y < a.z) as usize);
        let d = dir.to_array();
        let (next, after) = ([1, 2, 0][kz], [2, 0, 1][kz]);
        // Keep the winding of the sheared triangle when the dominant axis points backwards.
        let (kx, ky) = if d[kz] < 0.0 { (after, next) } else { (next, after) };
        let (sx, sy, sz) = (d[kx] / d[kz], d[ky] / d[kz], 1.0 / d[kz]);
        // Rows built on lanes (a lane equal to its axis index), not by storing into an
        // array at computed indices: the stores then the vector load stalled the store
        // buffer on every ray.
        let lane = |k: usize| Vec3A::new(0.0, 1.0, 2.0).cmpeq(Vec3A::splat(k as f32));
        let (x, y, z) = (lane(kx), lane(ky), lane(kz));
        let entry = |m, v: f32, rest: Vec3A| Vec3A::select(m, Vec3A::splat(v), rest);
        RayShear {
            rx: entry(x, 1.0, entry(z, -sx, Vec3A::ZERO)),
            ry: entry(y, 1.0, entry(z, -sy, Vec3A::ZERO)),
            rz: entry(z, sz, Vec3A::ZERO),
        }
    }

    /// The rows `rx`, `ry`, `rz`.
    #[inline(always)]
    pub(crate) fn rows(&self) -> [Vec3A; 3] {
        [self.rx, self.ry, self.rz]
    }

    /// A vertex relative to the ray origin in ray-aligned axes: sheared `(x, y)` and
    /// the scaled `z`.
    #[inline(always)]
    fn apply(&self, v: Vec3A) -> (f32, f32, f32) {
        (self.rx.dot(v), self.ry.dot(v), self.rz.dot(v))
    }
}

/// Watertight ray/triangle intersection (two-sided). Returns `(t, u, v)` with `u`, `v`
/// the barycentric weights of `p1` and `p2`, for `t_min < t < t_max`.
#[inline]
pub fn intersect_triangle(
    origin: Vec3,
    shear: &RayShear,
    p0: Vec3,
    p1: Vec3,
    p2: Vec3,
    t_min: f32,
    t_max: f32,
) -> Option<(f32, f32, f32)> {
    triangle_test(origin, shear, [p0, p1, p2], t_min, t_max).1
}

/// [`intersect_triangle`], also telling whether the ray's line passed the edge test.
/// Past it, a GPU's lanes run the determinant and distance code, few lanes at a time
/// (PDACRT's brute-force kernel counts that path apart).
#[inline(always)]
pub(crate) fn triangle_test(
    origin: Vec3,
    shear: &RayShear,
    [p0, p1, p2]: [Vec3; 3],
    t_min: f32,
    t_max: f32,
) -> (bool, Option<(f32, f32, f32)>) {
    let o = Vec3A::from(origin);
    let (ax, ay, az) = shear.apply(Vec3A::from(p0) - o);
    let (bx, by, bz) = shear.apply(Vec3A::from(p1) - o);
    let (cx, cy, cz) = shear.apply(Vec3A::from(p2) - o);

    // Edge functions; each is the signed area opposite one vertex.
    let mut e0 = cx * by - cy * bx;
    let mut e1 = ax * cy - ay * cx;
    let mut e2 = bx * ay - by * ax;
    // Non-short-circuit `|`/`&`: one well-predicted branch instead of several random ones.
    if (e0 == 0.0) | (e1 == 0.0) | (e2 == 0.0) {
        // Exactly on an edge in single precision: decide in double precision so that
        // neighbouring triangles agree on which side the ray passes.
        let (ax, ay, bx, by, cx, cy) = (ax as f64, ay as f64, bx as f64, by as f64, cx as f64, cy as f64);
        e0 = (cx * by - cy * bx) as f32;
        e1 = (ax * cy - ay * cx) as f32;
        e2 = (bx * ay - by * ax) as f32;
    }
    if ((e0 < 0.0) | (e1 < 0.0) | (e2 < 0.0)) & ((e0 > 0.0) | (e1 > 0.0) | (e2 > 0.0)) {
        return (false, None);
    }
    let det = e0 + e1 + e2;
    if det == 0.0 || !det.is_finite() {
        return (true, None);
    }
    let t_scaled = e0 * az + e1 * bz + e2 * cz;
    let inv_det = 1.0 / det;
    let t = t_scaled * inv_det;
    if !(t > t_min && t < t_max) {
        return (true, None);
    }
    (true, Some((t, e1 * inv_det, e2 * inv_det)))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The shear's rows, as the permuted test defines them: `x' = v[kx] - sx·v[kz]`,
    /// `y' = v[ky] - sy·v[kz]`, `z' = sz·v[kz]`, with exact zeros elsewhere (one bit
    /// pattern for every direction, signed zeros included).
    #[test]
    fn shear_rows_hold_the_permuted_form_bit_for_bit() {
        let mut r = crate::sampling::Rng::for_sample(5, 0, 0);
        for trial in 0..20_000 {
            let mut c = || if trial % 4 == 0 { (r.uniform() * 4.0).floor() - 2.0 } else { r.uniform() * 2.0 - 1.0 };
            let d = Vec3::new(c(), c(), c());
            if d == Vec3::ZERO {
                continue;
            }
            let a = d.abs();
            let kz = if a.x >= a.y && a.x >= a.z {
                0
            } else if a.y >= a.z {
                1
            } else {
                2
            };
            let (mut kx, mut ky) = ((kz + 1) % 3, (kz + 2) % 3);
            if d[kz] < 0.0 {
                std::mem::swap(&mut kx, &mut ky);
            }
            let mut want = [[0.0f32; 3]; 3];
            (want[0][kx], want[0][kz]) = (1.0, -(d[kx] / d[kz]));
            (want[1][ky], want[1][kz]) = (1.0, -(d[ky] / d[kz]));
            want[2][kz] = 1.0 / d[kz];
            let s = RayShear::new(d);
            let bits = |v: [f32; 3]| v.map(f32::to_bits);
            let got = [s.rx, s.ry, s.rz].map(|v| bits(v.to_array()));
            assert_eq!(got, want.map(bits), "direction {d}");
        }
    }
}
