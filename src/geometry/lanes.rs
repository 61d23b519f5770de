//! Layouts for the casters' SIMD lanes (SSE, part of x86-64's baseline, so no
//! run-time dispatch is needed): [`RaySlab`], a ray packed for box tests, [`Boxes4`],
//! four boxes tested at once, and [`Triangles4`], the watertight triangle test on four
//! triangles at once.
//!
//! Every lane runs the scalar test's operations in the scalar test's order — the shear
//! as glam's three-term dot product `(x·x' + y·y') + z·z'`, the edge functions, the
//! determinant and the distance — and IEEE arithmetic is the same per lane as in
//! scalar code (Rust never contracts to FMA), so each lane's answer is bit for bit
//! the scalar [`triangle_test`]'s. A lane whose edge function is exactly zero takes
//! the scalar test itself (its double-precision tie-break).

use super::lane_ops::{slab, watertight};
use super::{Aabb, Ray, RayShear, SLAB_WIDEN, inv_dir, triangle_test};
use glam::{Vec3, Vec3A, Vec4};

/// A ray packed for repeated slab tests: origin with `t_min`, and reciprocal direction
/// with `t_max`, in one 32-byte record (half a cache line, two SIMD registers). DACRT
/// tests every ray of a node against each child's box; with this record a test reads
/// one line instead of three arrays.
#[derive(Clone, Copy, Debug, PartialEq)]
#[repr(C, align(32))]
pub struct RaySlab {
    origin_t_min: Vec4,
    inv_t_max: Vec4,
}

impl RaySlab {
    /// The record of a ray.
    #[inline]
    pub fn new(ray: &Ray) -> RaySlab {
        RaySlab { origin_t_min: ray.origin.extend(ray.t_min), inv_t_max: inv_dir(ray.dir).extend(ray.t_max) }
    }

    /// The records as floats, eight a ray in the record's order (origin x, y, z,
    /// `t_min`, reciprocal direction x, y, z, `t_max`): what a gather reads lane by lane.
    pub(crate) fn floats(slabs: &[RaySlab]) -> &[f32] {
        const _: () = assert!(std::mem::size_of::<RaySlab>() == 8 * std::mem::size_of::<f32>());
        // SAFETY: a record is `repr(C)`, two `Vec4`s of four `f32`s each and no padding
        // (asserted above), so the slice's memory is `8 · len` initialised floats.
        unsafe { std::slice::from_raw_parts(slabs.as_ptr().cast::<f32>(), slabs.len() * 8) }
    }

    /// The ray's `t_max`.
    #[inline]
    pub fn t_max(&self) -> f32 {
        self.inv_t_max.w
    }

    /// The reciprocal direction.
    #[inline]
    pub fn inv_dir(&self) -> Vec3 {
        self.inv_t_max.truncate()
    }

    /// Whether the ray, cut to `(t_min, t_far)`, enters the box: exactly
    /// [`Aabb::intersect`]'s answer, computed on three lanes at once when no direction
    /// component is zero (and by `intersect` itself when one is).
    #[inline]
    pub fn enters(&self, b: &Aabb, t_far: f32) -> bool {
        let o = Vec3A::from_vec4(self.origin_t_min);
        let inv = Vec3A::from_vec4(self.inv_t_max);
        if !inv.is_finite() {
            return b.intersect(o.into(), inv.into(), self.origin_t_min.w, t_far).is_some();
        }
        // Per axis as `intersect` computes it; the order of the max/min reductions
        // does not change their values (no NaN can arise with finite reciprocals).
        let t0 = (Vec3A::from(b.min) - o) * inv;
        let t1 = (Vec3A::from(b.max) - o) * inv;
        let near = t0.min(t1).max_element().max(self.origin_t_min.w);
        let far = (t0.max(t1).min_element() * SLAB_WIDEN).min(t_far);
        near <= far
    }
}

/// Four boxes in structure-of-arrays form (a wide BVH node's children): `min[axis]`
/// and `max[axis]` hold that coordinate of the four boxes. Unused lanes are masked off
/// by the caller.
#[derive(Clone, Copy, Debug)]
pub struct Boxes4 {
    min: [Vec4; 3],
    max: [Vec4; 3],
}

impl Boxes4 {
    /// Up to four boxes (at least one); lanes past the slice's end repeat box 0.
    pub fn new(boxes: &[Aabb]) -> Boxes4 {
        debug_assert!(!boxes.is_empty() && boxes.len() <= 4);
        let b = |k: usize| &boxes[if k < boxes.len() { k } else { 0 }];
        let lanes = |corner: fn(&Aabb) -> Vec3, a: usize| Vec4::from_array([0, 1, 2, 3].map(|k| corner(b(k))[a]));
        Boxes4 { min: [0, 1, 2].map(|a| lanes(|b| b.min, a)), max: [0, 1, 2].map(|a| lanes(|b| b.max, a)) }
    }

    /// Box `k`.
    pub fn get(&self, k: usize) -> Aabb {
        Aabb {
            min: Vec3::new(self.min[0][k], self.min[1][k], self.min[2][k]),
            max: Vec3::new(self.max[0][k], self.max[1][k], self.max[2][k]),
        }
    }

    /// Which of the four boxes, each grown by `grow` on every side, the ray cut to
    /// `(t_min, t_far)` enters (bit `k` for box `k`), and the entry distances: lane by
    /// lane exactly [`Aabb::intersect`]'s answer for the grown box (the same operations
    /// as [`RaySlab::enters`]; a ray with a zero direction component takes `intersect`
    /// itself, box by box).
    #[inline]
    pub fn enters(&self, ray: &RaySlab, t_far: f32, grow: f32) -> (u32, Vec4) {
        let inv = ray.inv_t_max;
        if !Vec3A::from_vec4(inv).is_finite() {
            return self.enters_by_position(ray, t_far, grow);
        }
        let (o, s) = (ray.origin_t_min, Vec4::splat);
        slab(self.min, self.max, [s(o.x), s(o.y), s(o.z)], [s(inv.x), s(inv.y), s(inv.z)], s(grow), s(o.w), s(t_far))
    }

    #[cold]
    fn enters_by_position(&self, ray: &RaySlab, t_far: f32, grow: f32) -> (u32, Vec4) {
        let (mut mask, mut near) = (0, [f32::INFINITY; 4]);
        for (k, n) in near.iter_mut().enumerate() {
            let o = ray.origin_t_min;
            let b = self.get(k);
            let grown = Aabb { min: b.min - grow, max: b.max + grow };
            if let Some((t, _)) = grown.intersect(o.truncate(), ray.inv_dir(), o.w, t_far) {
                mask |= 1 << k;
                *n = t;
            }
        }
        (mask, Vec4::from_array(near))
    }
}

/// Four triangles in structure-of-arrays form: `p[corner][axis]` holds that
/// coordinate of the four triangles' corner. Unused lanes repeat lane 0.
#[derive(Clone, Copy, Debug)]
pub struct Triangles4 {
    p: [[Vec4; 3]; 3],
}

impl Triangles4 {
    /// A block of four triangles with all corners at the origin (hit by nothing).
    pub const EMPTY: Triangles4 = Triangles4 { p: [[Vec4::ZERO; 3]; 3] };

    /// The block of up to four triangles (at least one).
    #[inline]
    pub fn new(tris: &[[Vec3; 3]]) -> Triangles4 {
        debug_assert!(!tris.is_empty() && tris.len() <= 4);
        let t = |k: usize| &tris[if k < tris.len() { k } else { 0 }];
        Triangles4 { p: [0, 1, 2].map(|c| [0, 1, 2].map(|a| Vec4::from_array([0, 1, 2, 3].map(|k| t(k)[c][a])))) }
    }

    /// Triangle `k`'s corners.
    #[inline(always)]
    pub(crate) fn triangle(&self, k: usize) -> [Vec3; 3] {
        let c = |i: usize| Vec3::new(self.p[i][0][k], self.p[i][1][k], self.p[i][2][k]);
        [c(0), c(1), c(2)]
    }

    /// The scalar test's answer for each lane: bit `k` of [`Hits4::mask`] set for a
    /// hit with `t_min < t < t_max`, at `(t[k], u[k], v[k])`.
    #[inline]
    pub fn test(&self, origin: Vec3, shear: &RayShear, t_min: f32, t_max: f32) -> Hits4 {
        let s = Vec4::splat;
        let row = |r: Vec3A| [s(r.x), s(r.y), s(r.z)];
        let rows = [row(shear.rx), row(shear.ry), row(shear.rz)];
        let h = watertight(&self.p, [s(origin.x), s(origin.y), s(origin.z)], &rows, s(t_min), s(t_max));
        let on_edge = h.on_edge;
        let mut hits = Hits4 { mask: h.mask, t: h.t.to_array(), u: h.u.to_array(), v: h.v.to_array() };
        if on_edge != 0 {
            self.on_edge(&mut hits, on_edge, origin, shear, t_min, t_max);
        }
        hits
    }

    /// Lanes with an edge function exactly zero: the scalar test (its double-precision
    /// tie-break) decides them.
    #[cold]
    #[inline(never)]
    fn on_edge(&self, hits: &mut Hits4, lanes: u32, origin: Vec3, shear: &RayShear, t_min: f32, t_max: f32) {
        for k in (0..4).filter(|k| lanes >> k & 1 == 1) {
            if let (_, Some((t, u, v))) = triangle_test(origin, shear, self.triangle(k), t_min, t_max) {
                hits.mask |= 1 << k;
                (hits.t[k], hits.u[k], hits.v[k]) = (t, u, v);
            }
        }
    }
}

/// What [`Triangles4::test`] found: a hit mask (bit `k` for lane `k`) and each lane's
/// distance and barycentrics (meaningful where the bit is set).
#[derive(Clone, Copy, Debug)]
pub struct Hits4 {
    /// Bit `k` set when lane `k` is hit.
    pub mask: u32,
    /// Distances.
    pub t: [f32; 4],
    /// Barycentric weights of the second corner.
    pub u: [f32; 4],
    /// Barycentric weights of the third corner.
    pub v: [f32; 4],
}

impl Hits4 {
    /// Lane `k`'s hit, if any.
    #[inline]
    pub fn get(&self, k: usize) -> Option<(f32, f32, f32)> {
        (self.mask >> k & 1 == 1).then(|| (self.t[k], self.u[k], self.v[k]))
    }

    /// The hit lanes among the first `len` (a block of fewer than four triangles
    /// repeats one in its other lanes, which must not count).
    #[inline(always)]
    fn lanes(&self, len: usize) -> u32 {
        self.mask & ((1 << len) - 1)
    }

    /// The lane of the closest hit among the first `len`, where lane `k` is triangle
    /// `ids[k]`: the smallest distance, and of equal distances the smallest id
    /// ([`closer`](super::closer), the rule of every caster's leaf). `None` when none of
    /// them is hit.
    #[inline(always)]
    pub fn closest(&self, len: usize, ids: &[u32]) -> Option<usize> {
        let mut mask = self.lanes(len);
        if mask == 0 {
            return None;
        }
        let mut best = mask.trailing_zeros() as usize;
        mask &= mask - 1;
        while mask != 0 {
            let k = mask.trailing_zeros() as usize;
            if super::closer((self.t[k], ids[k]), (self.t[best], ids[best])) {
                best = k;
            }
            mask &= mask - 1;
        }
        Some(best)
    }

    /// The first hit lane among the first `len` (any-hit queries stop there).
    #[inline(always)]
    pub fn first(&self, len: usize) -> Option<usize> {
        let mask = self.lanes(len);
        (mask != 0).then(|| mask.trailing_zeros() as usize)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sampling::Rng;

    #[test]
    fn packed_slab_test_answers_as_the_box_test() {
        // Coordinates on a coarse grid, so that origins on faces, rays along faces,
        // zero direction components and exact ties at `t_far` all occur.
        let mut r = Rng::for_sample(11, 0, 0);
        let mut grid = || (r.uniform() * 8.0).floor() * 0.25 - 1.0;
        let (mut agree, mut entered) = (0, 0);
        for _ in 0..200_000 {
            let (a, b) = (Vec3::new(grid(), grid(), grid()), Vec3::new(grid(), grid(), grid()));
            let bx = Aabb { min: a.min(b), max: a.max(b) };
            let o = Vec3::new(grid(), grid(), grid());
            let d = Vec3::new(grid(), grid(), grid());
            if d == Vec3::ZERO {
                continue;
            }
            let ray = Ray { origin: o, dir: d, t_min: grid().max(0.0), t_max: grid() * 4.0 + 4.0 };
            let t_far = [ray.t_max, grid() + 1.0][agree % 2];
            let want = bx.intersect(o, inv_dir(d), ray.t_min, t_far).is_some();
            assert_eq!(RaySlab::new(&ray).enters(&bx, t_far), want, "{ray:?} {bx:?} t_far {t_far}");
            agree += 1;
            entered += want as usize;
        }
        // Both answers occur often (the check is not one-sided).
        assert!(entered > agree / 10 && entered < agree * 9 / 10, "{entered} of {agree}");
    }

    #[test]
    fn four_box_lanes_answer_as_the_box_test() {
        // The grid of the packed slab test: origins on faces, zero components, ties.
        let mut r = Rng::for_sample(12, 0, 0);
        let mut grid = || (r.uniform() * 8.0).floor() * 0.25 - 1.0;
        let (mut lanes, mut entered) = (0, 0);
        for trial in 0..50_000 {
            let boxes: Vec<Aabb> = (0..1 + trial % 4)
                .map(|_| {
                    let (a, b) = (Vec3::new(grid(), grid(), grid()), Vec3::new(grid(), grid(), grid()));
                    Aabb { min: a.min(b), max: a.max(b) }
                })
                .collect();
            let d = Vec3::new(grid(), grid(), grid());
            if d == Vec3::ZERO {
                continue;
            }
            let ray = Ray { origin: Vec3::new(grid(), grid(), grid()), dir: d, t_min: grid().max(0.0), t_max: 8.0 };
            let t_far = [ray.t_max, grid() + 1.0][trial % 2];
            let grow = [0.0, 0.125][trial % 3 / 2];
            let (mask, near) = Boxes4::new(&boxes).enters(&RaySlab::new(&ray), t_far, grow);
            for (k, b) in boxes.iter().enumerate() {
                let grown = Aabb { min: b.min - grow, max: b.max + grow };
                let want = grown.intersect(ray.origin, inv_dir(d), ray.t_min, t_far);
                assert_eq!(mask >> k & 1 == 1, want.is_some(), "{ray:?} {b:?} t_far {t_far}");
                if let Some((t, _)) = want {
                    assert_eq!(near[k].to_bits(), t.to_bits(), "entry distance of {b:?} for {ray:?}");
                }
                lanes += 1;
                entered += want.is_some() as usize;
            }
        }
        assert!(entered > lanes / 10 && entered < lanes * 9 / 10, "{entered} of {lanes}");
    }

    #[test]
    fn every_lane_answers_as_the_scalar_test_bit_for_bit() {
        // Corners on a coarse grid (shared edges, vertices on the ray, zero edge
        // functions, degenerate triangles) and random ones.
        let mut r = Rng::for_sample(3, 0, 0);
        let (mut hits, mut n) = (0, 0);
        for trial in 0..40_000 {
            let mut point = |coarse: bool| {
                let v = Vec3::new(r.uniform(), r.uniform(), r.uniform()) * 4.0 - 2.0;
                if coarse { (v * 2.0).round() * 0.5 } else { v }
            };
            let coarse = trial % 2 == 0;
            let tris: Vec<[Vec3; 3]> =
                (0..1 + trial % 4).map(|_| [point(coarse), point(coarse), point(coarse)]).collect();
            let origin = point(coarse) + Vec3::Z * 3.0;
            let dir = (point(coarse) - origin).normalize_or(Vec3::X);
            let shear = RayShear::new(dir);
            let t_max = if trial % 3 == 0 { 2.5 } else { f32::INFINITY };
            let got = Triangles4::new(&tris).test(origin, &shear, 0.0, t_max);
            let got: Vec<_> = (0..4).map(|k| got.get(k)).collect();
            for (k, t) in tris.iter().enumerate() {
                let want = triangle_test(origin, &shear, *t, 0.0, t_max).1;
                let bits = |h: Option<(f32, f32, f32)>| h.map(|(t, u, v)| (t.to_bits(), u.to_bits(), v.to_bits()));
                assert_eq!(bits(got[k]), bits(want), "trial {trial} lane {k}: {t:?} from {origin} along {dir}");
                hits += want.is_some() as usize;
                n += 1;
            }
        }
        assert!(hits > n / 20 && hits < n / 2, "{hits} hits of {n}");
    }

    /// The lane a leaf keeps is the closest hit, ties to the smaller id whatever the
    /// lane order, among the lanes of the list only; any-hit takes the first.
    #[test]
    fn a_block_keeps_the_closest_hit_and_ignores_lanes_past_the_list() {
        let hits = Hits4 { mask: 0b1111, t: [2.0, 1.0, 1.0, 0.5], u: [0.0; 4], v: [0.0; 4] };
        // Lanes 1 and 2 tie at t = 1; lane 2's triangle has the smaller id.
        assert_eq!(hits.closest(3, &[7, 9, 4, 1]), Some(2));
        assert_eq!(hits.closest(3, &[7, 4, 9, 1]), Some(1));
        // Lane 3 (t = 0.5) is past a list of three: it does not count until the list has four.
        assert_eq!(hits.closest(4, &[7, 9, 4, 1]), Some(3));
        assert_eq!(hits.first(3), Some(0));
        let none = Hits4 { mask: 0b1000, ..hits };
        assert_eq!((none.closest(3, &[7, 9, 4, 1]), none.first(3)), (None, None));
        assert_eq!((none.closest(4, &[7, 9, 4, 1]), none.first(4)), (Some(3), Some(3)));
    }
}
