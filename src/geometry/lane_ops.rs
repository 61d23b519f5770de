//! The box and triangle tests written once over SIMD lanes ([`Lanes`]), whatever the
//! lanes hold: four boxes or triangles against one ray (`Vec4`, [`super::lanes`]'s
//! [`Boxes4`](super::lanes::Boxes4) and [`Triangles4`](super::lanes::Triangles4)), or
//! one box or triangle against eight rays (`F8`, the BVH4's ray packets on x86-64). A value
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
    fn bits(m: Self::Mask) -> u32 {
        m.bitmask()
    }
}

/// Lanes of a packet of rays.
pub(crate) const PACKET: usize = 8;

/// Eight `f32` lanes: one AVX register. Its operations are AVX instructions, so they
/// may run only in code compiled for AVX2 on a CPU that has it (the BVH4's packets
/// check once, `cast::bvh4::packet::available`).
#[cfg(target_arch = "x86_64")]
#[derive(Clone, Copy, Debug)]
#[repr(transparent)]
pub(crate) struct F8(std::arch::x86_64::__m256);

/// The mask of [`F8`]: all ones or all zeros per lane.
#[cfg(target_arch = "x86_64")]
#[derive(Clone, Copy, Debug)]
#[repr(transparent)]
pub(crate) struct M8(std::arch::x86_64::__m256);

#[cfg(target_arch = "x86_64")]
mod avx {
    // SAFETY (every `unsafe` below): AVX intrinsics, reached only from code compiled
    // for AVX2 after a run-time check that the CPU has it (see `F8`).
    use super::{F8, Lanes, M8, PACKET};
    use std::arch::x86_64::*;
    use std::ops::{Add, BitAnd, BitOr, Div, Mul, Sub};

    macro_rules! lanewise {
        ($tr:ident, $f:ident, $op:ident, $t:ident) => {
            impl $tr for $t {
                type Output = $t;
                #[inline(always)]
                fn $f(self, o: $t) -> $t {
                    $t(unsafe { $op(self.0, o.0) })
                }
            }
        };
    }
    lanewise!(Add, add, _mm256_add_ps, F8);
    lanewise!(Sub, sub, _mm256_sub_ps, F8);
    lanewise!(Mul, mul, _mm256_mul_ps, F8);
    lanewise!(Div, div, _mm256_div_ps, F8);
    lanewise!(BitAnd, bitand, _mm256_and_ps, M8);
    lanewise!(BitOr, bitor, _mm256_or_ps, M8);

    impl F8 {
        /// The lanes.
        #[inline(always)]
        pub(crate) fn from_array(v: [f32; PACKET]) -> F8 {
            F8(unsafe { _mm256_loadu_ps(v.as_ptr()) })
        }

        /// The lanes as an array.
        #[inline(always)]
        pub(crate) fn to_array(self) -> [f32; PACKET] {
            let mut v = [0.0; PACKET];
            unsafe { _mm256_storeu_ps(v.as_mut_ptr(), self.0) };
            v
        }

        /// The smallest lane where `mask` is set (∞ where none is).
        #[inline(always)]
        pub(crate) fn min_where(self, mask: M8) -> f32 {
            let v = unsafe { _mm256_blendv_ps(_mm256_set1_ps(f32::INFINITY), self.0, mask.0) };
            let m = unsafe { _mm_min_ps(_mm256_castps256_ps128(v), _mm256_extractf128_ps::<1>(v)) };
            let m = unsafe { _mm_min_ps(m, _mm_movehl_ps(m, m)) };
            let m = unsafe { _mm_min_ss(m, _mm_shuffle_ps::<1>(m, m)) };
            unsafe { _mm_cvtss_f32(m) }
        }
    }

    impl M8 {
        /// The mask of the set bits of `bits` (bit `k` for lane `k`).
        #[inline(always)]
        pub(crate) fn from_bits(bits: u32) -> M8 {
            let lane = unsafe { _mm256_setr_epi32(1, 2, 4, 8, 16, 32, 64, 128) };
            let set = unsafe { _mm256_and_si256(_mm256_set1_epi32(bits as i32), lane) };
            M8(unsafe { _mm256_castsi256_ps(_mm256_cmpeq_epi32(set, lane)) })
        }
    }

    impl Lanes for F8 {
        type Mask = M8;
        #[inline(always)]
        fn splat(v: f32) -> Self {
            F8(unsafe { _mm256_set1_ps(v) })
        }
        #[inline(always)]
        fn min(self, o: Self) -> Self {
            F8(unsafe { _mm256_min_ps(self.0, o.0) })
        }
        #[inline(always)]
        fn max(self, o: Self) -> Self {
            F8(unsafe { _mm256_max_ps(self.0, o.0) })
        }
        #[inline(always)]
        fn abs(self) -> Self {
            F8(unsafe { _mm256_andnot_ps(_mm256_set1_ps(-0.0), self.0) })
        }
        #[inline(always)]
        fn lt(self, o: Self) -> M8 {
            M8(unsafe { _mm256_cmp_ps::<_CMP_LT_OQ>(self.0, o.0) })
        }
        #[inline(always)]
        fn le(self, o: Self) -> M8 {
            M8(unsafe { _mm256_cmp_ps::<_CMP_LE_OQ>(self.0, o.0) })
        }
        #[inline(always)]
        fn gt(self, o: Self) -> M8 {
            M8(unsafe { _mm256_cmp_ps::<_CMP_GT_OQ>(self.0, o.0) })
        }
        #[inline(always)]
        fn eq(self, o: Self) -> M8 {
            M8(unsafe { _mm256_cmp_ps::<_CMP_EQ_OQ>(self.0, o.0) })
        }
        #[inline(always)]
        fn ne(self, o: Self) -> M8 {
            M8(unsafe { _mm256_cmp_ps::<_CMP_NEQ_UQ>(self.0, o.0) })
        }
        #[inline(always)]
        fn bits(m: M8) -> u32 {
            unsafe { _mm256_movemask_ps(m.0) as u32 }
        }
    }
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
