//! The machine's fixed sizes that the executor, the meter and the statistics share, on
//! a floor below all three: warp width, regions and paths a kernel may name, the
//! register file, the memory sector, and the retry loop of a 64-bit shared atomic.

/// Threads in a warp.
pub const WARP_SIZE: u32 = 32;
/// Regions a kernel may name for SIMD accounting.
pub const MAX_REGIONS: usize = 8;
/// Paths (branch arms) per region.
pub const MAX_PATHS: usize = 8;
/// Per-thread register file, in 32-bit words (CUDA allows 255 registers; 64 words
/// keep the emulator's per-block scratch small).
pub const REGISTER_WORDS_PER_THREAD: usize = 64;
/// Bytes in one memory sector.
pub const SECTOR_BYTES: u64 = 32;
/// Sectors of a 128-byte cache line.
pub const SECTORS_PER_LINE: u64 = 4;
/// Instructions in one trip of the retry loop that a 64-bit shared `atomicAdd` compiles
/// to on sm_90, which has no 64-bit shared add (nvcc 13.0, `cuobjdump -sass`): the load
/// (`LDS.64`), the 64-bit add (`IADD3`, `IMAD.X`), the swap (`ATOMS.CAST.SPIN.64`), the
/// 64-bit test of its result (two `ISETP`) and the branch back.
pub const RETRY_TRIP_INSTRUCTIONS: u64 = 7;
/// One in `2^FOOTPRINT_SAMPLE_BITS` sectors (chosen by a hash of the address) is kept
/// to estimate how many distinct sectors a measured launch touches (its footprint),
/// as SHARDS (Waldspurger et al., FAST 2015) samples addresses for reuse distances.
pub const FOOTPRINT_SAMPLE_BITS: u32 = 4;

/// The multiplier of the sampling hash (Fibonacci hashing: 2^64 over the golden ratio).
pub const FOOTPRINT_HASH: u64 = 0x9e37_79b9_7f4a_7c15;

/// Whether `sector` is one of the sampled ones: the top bits of its hash are zero.
#[inline]
pub fn footprint_sampled(sector: u64) -> bool {
    sector.wrapping_mul(FOOTPRINT_HASH) >> (64 - FOOTPRINT_SAMPLE_BITS) == 0
}

/// The bit that marks a model address as host memory read by shared code
/// (`ambient::read!`): its place derives from a host address, which changes from run
/// to run, so its sectors are counted one by one rather than sampled by their hash.
pub const HOST_ADDRESS_BIT: u64 = 1 << 63;

/// Whether `sector` lies in host memory read by shared code (see [`HOST_ADDRESS_BIT`]).
#[inline]
pub fn host_sector(sector: u64) -> bool {
    sector & (HOST_ADDRESS_BIT / SECTOR_BYTES) != 0
}

/// How many sectors one kept sector stands for in a footprint: a sampled one
/// `2^FOOTPRINT_SAMPLE_BITS`, a host one (kept whenever touched) one.
#[inline]
pub fn footprint_weight(sector: u64) -> u64 {
    if host_sector(sector) { 1 } else { 1 << FOOTPRINT_SAMPLE_BITS }
}
