//! The box and triangle tests written once over SIMD lanes ([`Lanes`]), whatever the
//! lanes hold: four boxes or triangles against one ray (`Vec4`, [`super::lanes`]'s
//! [`Boxes4`](super::lanes::Boxes4) and [`Triangles4`](super::lanes::Triangles4)), or
//! one box or triangle against 8 or 16 rays (`super::packet_lanes`, the BVH4's ray
//! packets on x86-64). A value
//! the same for every lane is a splat.
//!
//! Each lane runs the scalar test's operations in the scalar test's order (the shear
//! as `(x·x' + y·y') + z·z'`, the edge functions, the determinant, the distance, the
//! slab's widened exit), and minima and maxima as SSE's `minps`/`maxps` (`a < b ? a :
//! b`), so each lane's answer is bit for bit the scalar one.

use super::SLAB_WIDEN;
use std::ops::{Add, BitAnd, BitOr, Div, Mul, Sub};

/// A vector of `f32` lanes with the operations the tests need.
pub(crate) trait Lanes:
    Copy + Add<Output = Self> + Sub<Output = Self> + Mul<Output = Self> + Div<Output = Self>
{
    /// A lane mask.
    type Mask: Copy + BitAnd<Output = Self::Mask> + BitOr<Output = Self::Mask>;
    fn splat(v: f32) -> Self;
    /// `a < b ? a : b` per lane (SSE's `minps`).
    fn min(self, o: Self) -> Self;
    /// `a > b ? a : b` per lane (SSE's `maxps`).
    fn max(self, o: Self) -> Self;
    fn abs(self) -> Self;
    fn lt(self, o: Self) -> Self::Mask;
    fn le(self, o: Self) -> Self::Mask;
    fn gt(self, o: Self) -> Self::Mask;
    fn eq(self, o: Self) -> Self::Mask;
    fn ne(self, o: Self) -> Self::Mask;
    /// `a` in the lanes where `m` is true, `b` in the others.
    fn select(m: Self::Mask, a: Self, b: Self) -> Self;
    /// Bit `k` set for a true lane `k`.
    fn bits(m: Self::Mask) -> u32;
}

impl Lanes for glam::Vec4 {
    type Mask = glam::BVec4A;
    #[inline(always)]
    fn splat(v: f32) -> Self {
        glam::Vec4::splat(v)
    }
    #[inline(always)]
    fn min(self, o: Self) -> Self {
        glam::Vec4::min(self, o)
    }
    #[inline(always)]
    fn max(self, o: Self) -> Self {
        glam::Vec4::max(self, o)
    }
    #[inline(always)]
    fn abs(self) -> Self {
        glam::Vec4::abs(self)
    }
    #[inline(always)]
    fn lt(self, o: Self) -> Self::Mask {
        self.cmplt(o)
    }
    #[inline(always)]
    fn le(self, o: Self) -> Self::Mask {
        self.cmple(o)
    }
    #[inline(always)]
    fn gt(self, o: Self) -> Self::Mask {
        self.cmpgt(o)
    }
    #[inline(always)]
    fn eq(self, o: Self) -> Self::Mask {
        self.cmpeq(o)
    }
    #[inline(always)]
    fn ne(self, o: Self) -> Self::Mask {
        self.cmpne(o)
    }
    #[inline(always)]
    fn select(m: Self::Mask, a: Self, b: Self) -> Self {
        glam::Vec4::select(m, a, b)
    }
    #[inline(always)]
    fn bits(m: Self::Mask) -> u32 {
        m.bitmask()
    }
}

/// A point's coordinates, each on every lane.
#[inline(always)]
pub(crate) fn splat3<L: Lanes>(v: glam::Vec3) -> [L; 3] {
    [L::splat(v.x), L::splat(v.y), L::splat(v.z)]
}

/// The mask bits of the first `len` lanes.
#[inline(always)]
pub(crate) fn first_lanes(len: usize) -> u32 {
    if len >= 32 { u32::MAX } else { (1 << len) - 1 }
}

/// The slab test, lane by lane: whether a ray (origin `o`, reciprocal direction `inv`,
/// all finite), cut to `(t_min, t_far)`, enters the box `min..max` grown by `grow` on
/// every side, and where it enters. The widening of exits is `intersect`'s
/// ([`SLAB_WIDEN`]); widening the axes' minimum gives the value of widening each axis,
/// since rounding a product is monotone.
#[inline(always)]
pub(crate) fn slab<L: Lanes>(
    min: [L; 3],
    max: [L; 3],
    o: [L; 3],
    inv: [L; 3],
    grow: L,
    t_min: L,
    t_far: L,
) -> (u32, L) {
    // Helper functions here and below, not closures: the AVX lanes' operations are
    // inlined only into code compiled for AVX2, and a closure is not inlined with
    // certainty where it is used.
    #[inline(always)]
    fn axis<L: Lanes>(min: L, max: L, o: L, inv: L, grow: L) -> (L, L) {
        let (t0, t1) = ((min - grow - o) * inv, (max + grow - o) * inv);
        (t0.min(t1), t0.max(t1))
    }
    let (n0, f0) = axis(min[0], max[0], o[0], inv[0], grow);
    let (n1, f1) = axis(min[1], max[1], o[1], inv[1], grow);
    let (n2, f2) = axis(min[2], max[2], o[2], inv[2], grow);
    let near = n0.max(n1).max(n2).max(t_min);
    let far = (f0.min(f1).min(f2) * L::splat(SLAB_WIDEN)).min(t_far);
    (L::bits(near.le(far)), near)
}

/// What [`watertight`] found, per lane: the hit lanes (with `t_min < t < t_max`), the
/// lanes with an edge function exactly zero (which the scalar test, with its
/// double-precision tie-break, must decide), and each lane's distance and barycentric
/// weights of the second and third corners.
#[derive(Clone, Copy, Debug)]
pub(crate) struct LaneHits<L> {
    pub mask: u32,
    pub on_edge: u32,
    pub t: L,
    pub u: L,
    pub v: L,
}

/// The watertight test (Woop, Benthin and Wald 2013), lane by lane: triangle corners
/// `p[corner][axis]`, ray origins `o`, and each ray's shear rows `rows[row][axis]`
/// (`RayShear`'s `rx`, `ry`, `rz`).
#[inline(always)]
pub(crate) fn watertight<L: Lanes>(p: &[[L; 3]; 3], o: [L; 3], rows: &[[L; 3]; 3], t_min: L, t_max: L) -> LaneHits<L> {
    // A corner relative to the origin, sheared: `RayShear::apply`, lane-wise.
    #[inline(always)]
    fn corner<L: Lanes>(p: &[L; 3], o: [L; 3], rows: &[[L; 3]; 3]) -> (L, L, L) {
        let (x, y, z) = (p[0] - o[0], p[1] - o[1], p[2] - o[2]);
        let [r0, r1, r2] = rows;
        ((r0[0] * x + r0[1] * y) + r0[2] * z, (r1[0] * x + r1[1] * y) + r1[2] * z, (r2[0] * x + r2[1] * y) + r2[2] * z)
    }
    let (ax, ay, az) = corner(&p[0], o, rows);
    let (bx, by, bz) = corner(&p[1], o, rows);
    let (cx, cy, cz) = corner(&p[2], o, rows);
    let e0 = cx * by - cy * bx;
    let e1 = ax * cy - ay * cx;
    let e2 = bx * ay - by * ax;
    let det = e0 + e1 + e2;
    let t_scaled = e0 * az + e1 * bz + e2 * cz;
    let inv_det = L::splat(1.0) / det;
    let t = t_scaled * inv_det;
    let zero = L::splat(0.0);
    let on_edge = L::bits(e0.eq(zero) | e1.eq(zero) | e2.eq(zero));
    let outside = L::bits((e0.lt(zero) | e1.lt(zero) | e2.lt(zero)) & (e0.gt(zero) | e1.gt(zero) | e2.gt(zero)));
    let valid = det.ne(zero) & det.abs().lt(L::splat(f32::INFINITY));
    let within = t.gt(t_min) & t.lt(t_max);
    LaneHits { mask: L::bits(valid & within) & !outside & !on_edge, on_edge, t, u: e1 * inv_det, v: e2 * inv_det }
}
