//! SIMD lanes of the BVH4's ray packets on x86-64 (`cast::bvh4::packet`): [`F8`], eight
//! rays on one AVX register, and [`F16`], sixteen on one AVX-512 register, each a
//! [`Lanes`] for the box and triangle tests of [`lane_ops`](super::lane_ops) and a
//! [`Packed`] for what the traversal needs beyond them.
//!
//! Their operations are the CPU's vector instructions, so they may run only in code
//! compiled for that extension, on a CPU that has it: the packets check once, at run
//! time, and call the traversal through a function compiled for it.

use super::lane_ops::Lanes;

/// A [`Lanes`] type a packet of rays is held in: as many rays as lanes.
pub(crate) trait Packed: Lanes {
    /// Lanes (rays) of a packet: at most 32, the bits of a `u32` mask.
    const WIDTH: usize;
    /// The lanes as an array.
    type Array: Copy + Default + std::ops::IndexMut<usize, Output = f32>;
    fn from_array(v: Self::Array) -> Self;
    fn to_array(self) -> Self::Array;
    /// The smallest lane where bit `k` of `bits` is set for lane `k` (∞ where none is).
    fn min_where(self, bits: u32) -> f32;
}

/// Eight `f32` lanes: one AVX register.
#[derive(Clone, Copy, Debug)]
#[repr(transparent)]
pub(crate) struct F8(std::arch::x86_64::__m256);

/// The mask of [`F8`]: all ones or all zeros per lane.
#[derive(Clone, Copy, Debug)]
#[repr(transparent)]
pub(crate) struct M8(std::arch::x86_64::__m256);

mod avx {
    // SAFETY (every `unsafe` below): AVX intrinsics, reached only from code compiled
    // for AVX2 after a run-time check that the CPU has it (see `F8`).
    use super::{F8, M8, Packed};
    use crate::geometry::lane_ops::Lanes;
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

    impl Packed for F8 {
        const WIDTH: usize = 8;
        type Array = [f32; 8];
        #[inline(always)]
        fn from_array(v: [f32; 8]) -> F8 {
            F8(unsafe { _mm256_loadu_ps(v.as_ptr()) })
        }
        #[inline(always)]
        fn to_array(self) -> [f32; 8] {
            let mut v = [0.0; 8];
            unsafe { _mm256_storeu_ps(v.as_mut_ptr(), self.0) };
            v
        }
        #[inline(always)]
        fn min_where(self, bits: u32) -> f32 {
            let lane = unsafe { _mm256_setr_epi32(1, 2, 4, 8, 16, 32, 64, 128) };
            let set = unsafe { _mm256_cmpeq_epi32(_mm256_and_si256(_mm256_set1_epi32(bits as i32), lane), lane) };
            let v = unsafe { _mm256_blendv_ps(_mm256_set1_ps(f32::INFINITY), self.0, _mm256_castsi256_ps(set)) };
            let m = unsafe { _mm_min_ps(_mm256_castps256_ps128(v), _mm256_extractf128_ps::<1>(v)) };
            let m = unsafe { _mm_min_ps(m, _mm_movehl_ps(m, m)) };
            let m = unsafe { _mm_min_ss(m, _mm_shuffle_ps::<1>(m, m)) };
            unsafe { _mm_cvtss_f32(m) }
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

/// Sixteen `f32` lanes: one AVX-512 register.
#[derive(Clone, Copy, Debug)]
#[repr(transparent)]
pub(crate) struct F16(std::arch::x86_64::__m512);

/// The mask of [`F16`]: a bit per lane.
#[derive(Clone, Copy, Debug)]
#[repr(transparent)]
pub(crate) struct M16(u16);

mod avx512 {
    // SAFETY (every `unsafe` below): AVX-512F intrinsics, reached only from code
    // compiled for AVX-512F after a run-time check that the CPU has it (see the module).
    use super::{F16, M16, Packed};
    use crate::geometry::lane_ops::Lanes;
    use std::arch::x86_64::*;
    use std::ops::{Add, BitAnd, BitOr, Div, Mul, Sub};

    macro_rules! lanewise {
        ($tr:ident, $f:ident, $op:ident) => {
            impl $tr for F16 {
                type Output = F16;
                #[inline(always)]
                fn $f(self, o: F16) -> F16 {
                    F16(unsafe { $op(self.0, o.0) })
                }
            }
        };
    }
    lanewise!(Add, add, _mm512_add_ps);
    lanewise!(Sub, sub, _mm512_sub_ps);
    lanewise!(Mul, mul, _mm512_mul_ps);
    lanewise!(Div, div, _mm512_div_ps);

    impl BitAnd for M16 {
        type Output = M16;
        #[inline(always)]
        fn bitand(self, o: M16) -> M16 {
            M16(self.0 & o.0)
        }
    }

    impl BitOr for M16 {
        type Output = M16;
        #[inline(always)]
        fn bitor(self, o: M16) -> M16 {
            M16(self.0 | o.0)
        }
    }

    impl Packed for F16 {
        const WIDTH: usize = 16;
        type Array = [f32; 16];
        #[inline(always)]
        fn from_array(v: [f32; 16]) -> F16 {
            F16(unsafe { _mm512_loadu_ps(v.as_ptr()) })
        }
        #[inline(always)]
        fn to_array(self) -> [f32; 16] {
            let mut v = [0.0; 16];
            unsafe { _mm512_storeu_ps(v.as_mut_ptr(), self.0) };
            v
        }
        #[inline(always)]
        fn min_where(self, bits: u32) -> f32 {
            unsafe { _mm512_reduce_min_ps(_mm512_mask_blend_ps(bits as u16, _mm512_set1_ps(f32::INFINITY), self.0)) }
        }
    }

    impl Lanes for F16 {
        type Mask = M16;
        #[inline(always)]
        fn splat(v: f32) -> Self {
            F16(unsafe { _mm512_set1_ps(v) })
        }
        // `a < b ? a : b` as SSE's `minps`: AVX-512's `vminps` returns the second
        // operand for NaNs and signed zeros just as `minps` does.
        #[inline(always)]
        fn min(self, o: Self) -> Self {
            F16(unsafe { _mm512_min_ps(self.0, o.0) })
        }
        #[inline(always)]
        fn max(self, o: Self) -> Self {
            F16(unsafe { _mm512_max_ps(self.0, o.0) })
        }
        #[inline(always)]
        fn abs(self) -> Self {
            F16(unsafe { _mm512_abs_ps(self.0) })
        }
        #[inline(always)]
        fn lt(self, o: Self) -> M16 {
            M16(unsafe { _mm512_cmp_ps_mask::<_CMP_LT_OQ>(self.0, o.0) })
        }
        #[inline(always)]
        fn le(self, o: Self) -> M16 {
            M16(unsafe { _mm512_cmp_ps_mask::<_CMP_LE_OQ>(self.0, o.0) })
        }
        #[inline(always)]
        fn gt(self, o: Self) -> M16 {
            M16(unsafe { _mm512_cmp_ps_mask::<_CMP_GT_OQ>(self.0, o.0) })
        }
        #[inline(always)]
        fn eq(self, o: Self) -> M16 {
            M16(unsafe { _mm512_cmp_ps_mask::<_CMP_EQ_OQ>(self.0, o.0) })
        }
        #[inline(always)]
        fn ne(self, o: Self) -> M16 {
            M16(unsafe { _mm512_cmp_ps_mask::<_CMP_NEQ_UQ>(self.0, o.0) })
        }
        #[inline(always)]
        fn bits(m: M16) -> u32 {
            m.0 as u32
        }
    }
}
