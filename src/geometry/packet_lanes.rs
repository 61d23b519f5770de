//! Wide SIMD lanes on x86-64: [`F8`], eight `f32` on one AVX register, and [`F16`],
//! sixteen on one AVX-512 register, each a [`Lanes`] for the box and triangle tests of
//! [`lane_ops`](super::lane_ops) and a [`Packed`] for what the casters need beyond them.
//! The BVH4's ray packets (`cast::bvh4::packet`) hold a ray per lane; DACRT's ray
//! partitions and leaves (`cast::dacrt::lanes`) a ray or a triangle per lane.
//!
//! Their operations are the CPU's vector instructions, so they may run only in code
//! compiled for that extension, on a CPU that has it: a caster asks [`Width`] once, at
//! run time, and calls its loop through a function compiled for that width.

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
    /// Lane `k` = `f(k)`, the values set from registers (no round trip through memory,
    /// whose scalar stores a vector load would wait for).
    fn from_fn(f: impl FnMut(usize) -> f32) -> Self;
    /// Records of `N` floats (at most 8), lane `k` holding record `ids[k]` of `base`
    /// (floats `N · ids[k] ..`): element `c < N` of the answer is every lane's field
    /// `c` (the others are zero). Each record is one 32-byte load (masked to `N` floats,
    /// so nothing past the record is read) and the loads are transposed in registers,
    /// which costs less than `N` gathers. `ids` holds at least `WIDTH` entries; a record
    /// outside `base` panics, as indexing does.
    fn records<const N: usize>(base: &[f32], ids: &[u32]) -> [Self; 8];
}

/// Four lanes on SSE, which every x86-64 CPU has: the loops written over [`Packed`]
/// run on it where the CPU has no wider lanes.
impl Packed for glam::Vec4 {
    const WIDTH: usize = 4;
    type Array = [f32; 4];
    #[inline(always)]
    fn from_array(v: [f32; 4]) -> glam::Vec4 {
        glam::Vec4::from_array(v)
    }
    #[inline(always)]
    fn to_array(self) -> [f32; 4] {
        glam::Vec4::to_array(&self)
    }
    #[inline(always)]
    fn min_where(self, bits: u32) -> f32 {
        (0..4).filter(|k| bits >> k & 1 == 1).map(|k| self[k]).fold(f32::INFINITY, f32::min)
    }
    #[inline(always)]
    fn from_fn(mut f: impl FnMut(usize) -> f32) -> glam::Vec4 {
        glam::Vec4::new(f(0), f(1), f(2), f(3))
    }
    #[inline(always)]
    fn records<const N: usize>(base: &[f32], ids: &[u32]) -> [glam::Vec4; 8] {
        let r: [&[f32]; 4] = std::array::from_fn(|k| &base[ids[k] as usize * N..][..N]);
        std::array::from_fn(
            |c| if c < N { glam::Vec4::new(r[0][c], r[1][c], r[2][c], r[3][c]) } else { glam::Vec4::ZERO },
        )
    }
}

/// A vector extension the wide lanes run on, and so how many lanes they have.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Width {
    /// Sixteen lanes on AVX-512F.
    Avx512,
    /// Eight lanes on AVX2.
    Avx2,
}

impl Width {
    /// Every width, widest first.
    pub(crate) const ALL: [Width; 2] = [Width::Avx512, Width::Avx2];

    /// Lanes of this width (rays a BVH4 packet holds).
    pub(crate) fn rays(self) -> usize {
        match self {
            Width::Avx512 => F16::WIDTH,
            Width::Avx2 => F8::WIDTH,
        }
    }

    /// Whether this CPU has the extension (checked once per width).
    pub(crate) fn supported(self) -> bool {
        use std::sync::OnceLock;
        static AVX512: OnceLock<bool> = OnceLock::new();
        static AVX2: OnceLock<bool> = OnceLock::new();
        match self {
            Width::Avx512 => *AVX512.get_or_init(|| std::arch::is_x86_feature_detected!("avx512f")),
            Width::Avx2 => *AVX2.get_or_init(|| std::arch::is_x86_feature_detected!("avx2")),
        }
    }

    /// The widest width this CPU has (`None` on a CPU with neither: SSE only).
    pub(crate) fn widest() -> Option<Width> {
        Width::ALL.into_iter().find(|w| w.supported())
    }

    /// Of `loops`, one loop compiled for each width in the order of [`Width::ALL`], the
    /// one for this width. Panics where the CPU lacks the extension, so the loop
    /// returned is safe to call on this CPU.
    pub(crate) fn pick<F: Copy>(self, loops: [F; 2]) -> F {
        assert!(self.supported(), "{self:?} lanes on a CPU without them");
        match self {
            Width::Avx512 => loops[0],
            Width::Avx2 => loops[1],
        }
    }
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
    /// Eight records of `N` floats (`base[N · ids[k] ..]`, one 32-byte load each, masked
    /// to `N` floats), transposed: element `c` holds field `c` of the eight records,
    /// record `k` in lane `k` (unpack pairs of rows, shuffle pairs of pairs, then swap
    /// 128-bit halves).
    #[inline(always)]
    pub(super) fn transpose8<const N: usize>(base: &[f32], ids: &[u32]) -> [__m256; 8] {
        const { assert!(N >= 1 && N <= 8) };
        // SAFETY: each load reads the `N` floats of a record inside `base` (the slice
        // below is bounds-checked); a masked load does not touch masked-off lanes.
        let mask =
            unsafe { _mm256_cmpgt_epi32(_mm256_set1_epi32(N as i32), _mm256_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7)) };
        let row = |k: usize| row::<N>(base, ids[k], mask);
        let r = [row(0), row(1), row(2), row(3), row(4), row(5), row(6), row(7)];
        unsafe {
            let t = [
                _mm256_unpacklo_ps(r[0], r[1]),
                _mm256_unpackhi_ps(r[0], r[1]),
                _mm256_unpacklo_ps(r[2], r[3]),
                _mm256_unpackhi_ps(r[2], r[3]),
                _mm256_unpacklo_ps(r[4], r[5]),
                _mm256_unpackhi_ps(r[4], r[5]),
                _mm256_unpacklo_ps(r[6], r[7]),
                _mm256_unpackhi_ps(r[6], r[7]),
            ];
            // Fields 0 and 4, 1 and 5, 2 and 6, 3 and 7 of rows 0-3 (s[0..4]) and 4-7 (s[4..8]).
            let s = [
                _mm256_shuffle_ps::<0x44>(t[0], t[2]),
                _mm256_shuffle_ps::<0xEE>(t[0], t[2]),
                _mm256_shuffle_ps::<0x44>(t[1], t[3]),
                _mm256_shuffle_ps::<0xEE>(t[1], t[3]),
                _mm256_shuffle_ps::<0x44>(t[4], t[6]),
                _mm256_shuffle_ps::<0xEE>(t[4], t[6]),
                _mm256_shuffle_ps::<0x44>(t[5], t[7]),
                _mm256_shuffle_ps::<0xEE>(t[5], t[7]),
            ];
            [
                _mm256_permute2f128_ps::<0x20>(s[0], s[4]),
                _mm256_permute2f128_ps::<0x20>(s[1], s[5]),
                _mm256_permute2f128_ps::<0x20>(s[2], s[6]),
                _mm256_permute2f128_ps::<0x20>(s[3], s[7]),
                _mm256_permute2f128_ps::<0x31>(s[0], s[4]),
                _mm256_permute2f128_ps::<0x31>(s[1], s[5]),
                _mm256_permute2f128_ps::<0x31>(s[2], s[6]),
                _mm256_permute2f128_ps::<0x31>(s[3], s[7]),
            ]
        }
    }

    /// Record `id` of `N` floats, one (masked) load. A helper, not a closure, so that
    /// it is inlined into the loops compiled for AVX2.
    #[inline(always)]
    fn row<const N: usize>(base: &[f32], id: u32, mask: __m256i) -> __m256 {
        let r = &base[id as usize * N..][..N];
        // SAFETY: see `transpose8`.
        unsafe { if N == 8 { _mm256_loadu_ps(r.as_ptr()) } else { _mm256_maskload_ps(r.as_ptr(), mask) } }
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
        #[inline(always)]
        fn from_fn(mut f: impl FnMut(usize) -> f32) -> F8 {
            let v = [f(0), f(1), f(2), f(3), f(4), f(5), f(6), f(7)];
            F8(unsafe { _mm256_setr_ps(v[0], v[1], v[2], v[3], v[4], v[5], v[6], v[7]) })
        }
        #[inline(always)]
        fn records<const N: usize>(base: &[f32], ids: &[u32]) -> [F8; 8] {
            let c = transpose8::<N>(base, &ids[..8]);
            [F8(c[0]), F8(c[1]), F8(c[2]), F8(c[3]), F8(c[4]), F8(c[5]), F8(c[6]), F8(c[7])]
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
        fn select(m: M8, a: Self, b: Self) -> Self {
            F8(unsafe { _mm256_blendv_ps(b.0, a.0, m.0) })
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
        #[inline(always)]
        fn from_fn(mut f: impl FnMut(usize) -> f32) -> F16 {
            let v: [f32; 16] = std::array::from_fn(&mut f);
            F16(unsafe {
                _mm512_setr_ps(
                    v[0], v[1], v[2], v[3], v[4], v[5], v[6], v[7], v[8], v[9], v[10], v[11], v[12], v[13], v[14],
                    v[15],
                )
            })
        }
        #[inline(always)]
        fn records<const N: usize>(base: &[f32], ids: &[u32]) -> [F16; 8] {
            let (lo, hi) =
                (super::avx::transpose8::<N>(base, &ids[..8]), super::avx::transpose8::<N>(base, &ids[8..16]));
            [
                join(lo[0], hi[0]),
                join(lo[1], hi[1]),
                join(lo[2], hi[2]),
                join(lo[3], hi[3]),
                join(lo[4], hi[4]),
                join(lo[5], hi[5]),
                join(lo[6], hi[6]),
                join(lo[7], hi[7]),
            ]
        }
    }

    /// Two 256-bit halves as one register (AVX-512F).
    #[inline(always)]
    fn join(lo: __m256, hi: __m256) -> F16 {
        F16(unsafe {
            _mm512_castpd_ps(_mm512_insertf64x4::<1>(
                _mm512_castpd256_pd512(_mm256_castps_pd(lo)),
                _mm256_castps_pd(hi),
            ))
        })
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
        fn select(m: M16, a: Self, b: Self) -> Self {
            F16(unsafe { _mm512_mask_blend_ps(m.0, b.0, a.0) })
        }
        #[inline(always)]
        fn bits(m: M16) -> u32 {
            m.0 as u32
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every lane's fields of `records::<N>`, read out on the lanes' own extension.
    fn fields<L: Packed, const N: usize>(base: &[f32], ids: &[u32]) -> Vec<Vec<f32>> {
        L::records::<N>(base, ids).iter().map(|v| (0..L::WIDTH).map(|k| v.to_array()[k]).collect()).collect()
    }

    #[target_feature(enable = "avx2")]
    fn fields_avx2<const N: usize>(base: &[f32], ids: &[u32]) -> Vec<Vec<f32>> {
        fields::<F8, N>(base, ids)
    }

    #[target_feature(enable = "avx512f")]
    fn fields_avx512<const N: usize>(base: &[f32], ids: &[u32]) -> Vec<Vec<f32>> {
        fields::<F16, N>(base, ids)
    }

    /// Field `c` of lane `k` is float `c` of record `ids[k]` (zero past the record),
    /// for records of 6 and 8 floats, on SSE and every wider width this CPU has.
    fn check<const N: usize>() {
        let base: Vec<f32> = (0..40 * N).map(|i| i as f32 * 0.5 - 3.0).collect();
        // Records in a scattered order, the slice's last record (39) among them: a
        // 6-float record there must not be read past.
        let ids = [39, 0, 17, 5, 38, 22, 9, 30, 1, 14, 27, 33, 2, 11, 25, 39];
        let mut got = vec![("SSE", fields::<glam::Vec4, N>(&base, &ids))];
        if Width::Avx2.supported() {
            // SAFETY: the CPU has AVX2.
            got.push(("AVX2", unsafe { fields_avx2::<N>(&base, &ids) }));
        }
        if Width::Avx512.supported() {
            // SAFETY: the CPU has AVX-512F.
            got.push(("AVX-512", unsafe { fields_avx512::<N>(&base, &ids) }));
        } else {
            eprintln!("WARNING: this CPU has no AVX-512: the 16-lane transpose is not checked here");
        }
        for (name, f) in got {
            for (c, lanes) in f.iter().enumerate() {
                for (k, &v) in lanes.iter().enumerate() {
                    let want = if c < N { base[ids[k] as usize * N + c] } else { 0.0 };
                    assert_eq!(v, want, "{name}, records of {N}: field {c}, lane {k}");
                }
            }
        }
    }

    #[test]
    fn records_load_each_lanes_record_field_by_field() {
        check::<8>();
        check::<6>();
    }
}
