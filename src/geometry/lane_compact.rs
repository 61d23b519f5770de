//! The write step of a partition on wide lanes: of a block of ids, those whose lane
//! bit is set, in order, stored at a list's end with a few vector instructions instead
//! of a store and an add per id (AVX-512's `vpcompressd`; on AVX2 a lane permutation
//! looked up by the block's 8-bit mask). [`compact`] picks the one for a lane type;
//! on SSE it stores the ids one at a time, with the same result.

use super::packet_lanes::Packed;
use std::arch::x86_64::*;

/// `dst[at..]` gets the ids of `block` (`L::WIDTH` of them) whose bit in `bits` is set,
/// in order; returns how many. `dst[at..at + L::WIDTH]` must exist: past the count it
/// may be overwritten.
#[inline(always)]
pub(crate) fn compact<L: Packed>(block: &[u32], bits: u32, dst: &mut [u32], at: usize) -> usize {
    match L::WIDTH {
        // SAFETY: only `F16` has 16 lanes and `F8` 8, and their values exist only in
        // code compiled for AVX-512F or AVX2 that runs after a check that the CPU has
        // it (`Width::pick`), which is where this is inlined.
        16 => unsafe { compact16(block, bits, dst, at) },
        8 => unsafe { compact8(block, bits, dst, at) },
        w => {
            let mut n = at;
            for (k, &id) in block[..w].iter().enumerate() {
                dst[n] = id;
                n += (bits >> k & 1) as usize;
            }
            n - at
        }
    }
}

/// For each 8-bit mask, the lanes whose bit is set, in order, a byte each (the rest
/// zero): the permutation that moves them to the front.
static FRONT8: [u64; 256] = {
    let mut table = [0u64; 256];
    let mut mask = 0;
    while mask < 256 {
        let (mut lane, mut at) = (0, 0);
        while lane < 8 {
            if mask >> lane & 1 == 1 {
                table[mask] |= (lane as u64) << (8 * at);
                at += 1;
            }
            lane += 1;
        }
        mask += 1;
    }
    table
};

/// `dst[at..]` gets the ids of `block[..8]` whose bit in `bits` is set, in order;
/// returns how many. Writes all of `dst[at..at + 8]` (past the count, other ids).
///
/// # Safety
/// The CPU has AVX2 (the caller is compiled for it after a run-time check).
#[inline(always)]
pub(crate) unsafe fn compact8(block: &[u32], bits: u32, dst: &mut [u32], at: usize) -> usize {
    let (block, dst) = (&block[..8], &mut dst[at..at + 8]);
    // SAFETY: AVX2 (the caller's contract); both slices hold 8 ids (checked above).
    unsafe {
        let order = _mm256_cvtepu8_epi32(_mm_cvtsi64_si128(FRONT8[(bits & 0xff) as usize] as i64));
        let ids = _mm256_loadu_si256(block.as_ptr().cast());
        _mm256_storeu_si256(dst.as_mut_ptr().cast(), _mm256_permutevar8x32_epi32(ids, order));
    }
    (bits & 0xff).count_ones() as usize
}

/// `dst[at..]` gets the ids of `block[..16]` whose bit in `bits` is set, in order;
/// returns how many. Writes all of `dst[at..at + 16]` (past the count, zeros).
///
/// # Safety
/// The CPU has AVX-512F (the caller is compiled for it after a run-time check).
#[inline(always)]
pub(crate) unsafe fn compact16(block: &[u32], bits: u32, dst: &mut [u32], at: usize) -> usize {
    let (block, dst) = (&block[..16], &mut dst[at..at + 16]);
    // SAFETY: AVX-512F (the caller's contract); both slices hold 16 ids (checked above).
    // The compress goes to a register and a whole store (`vpcompressd` straight to
    // memory is slow on some CPUs).
    unsafe {
        let ids = _mm512_loadu_si512(block.as_ptr().cast());
        _mm512_storeu_si512(dst.as_mut_ptr().cast(), _mm512_maskz_compress_epi32(bits as u16, ids));
    }
    (bits & 0xffff).count_ones() as usize
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The ids of `block` whose bit is set, in order, as a loop writes them.
    fn expected(block: &[u32], bits: u32) -> Vec<u32> {
        block.iter().enumerate().filter(|(k, _)| bits >> k & 1 == 1).map(|(_, &id)| id).collect()
    }

    #[target_feature(enable = "avx2")]
    fn run8(block: &[u32], bits: u32, dst: &mut [u32], at: usize) -> usize {
        unsafe { compact8(block, bits, dst, at) }
    }

    #[target_feature(enable = "avx512f")]
    fn run16(block: &[u32], bits: u32, dst: &mut [u32], at: usize) -> usize {
        unsafe { compact16(block, bits, dst, at) }
    }

    /// Every 8-bit mask on AVX2, and every 16-bit mask on AVX-512, stores exactly the
    /// kept ids in order at the given place and leaves what lies before it alone.
    #[test]
    fn compaction_keeps_the_set_lanes_in_order() {
        let block: Vec<u32> = (0..16).map(|k| 1000 + 7 * k).collect();
        let mut ran = Vec::new();
        for (width, supported) in [(8, is_x86_feature_detected!("avx2")), (16, is_x86_feature_detected!("avx512f"))] {
            if !supported {
                eprintln!("WARNING: this CPU lacks the extension of the {width}-lane compaction; it was not run");
                continue;
            }
            for bits in 0..1u32 << width {
                let mut dst = vec![u32::MAX; 3 + width];
                // SAFETY: each wrapper is compiled for its extension, which the CPU has.
                let n = if width == 8 {
                    unsafe { run8(&block, bits, &mut dst, 3) }
                } else {
                    unsafe { run16(&block, bits, &mut dst, 3) }
                };
                assert_eq!(dst[3..3 + n], expected(&block[..width], bits)[..], "{width} lanes, mask {bits:#x}");
                assert_eq!(dst[..3], [u32::MAX; 3], "{width} lanes, mask {bits:#x}: before the place");
            }
            ran.push(width);
        }
        assert!(!ran.is_empty() || !is_x86_feature_detected!("avx2"));
    }
}
