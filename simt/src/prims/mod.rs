//! Thrust/CUB-style primitives written as kernels on the emulator. Each has a plain
//! sequential twin in [`crate::seq`] that the tests use as the oracle. With measurement
//! off, scans, reductions, `copy_if`, `reduce_by_key` and the sorts run their CPU
//! backend (`native`) instead of the kernels, as Thrust's CPU backends do; their
//! records are named `simt::<primitive> [cpu]`.

mod look_back;
pub(crate) mod native;
pub mod queue;
mod radix_key;
pub mod scan;
pub mod select;
pub mod sort;

/// Threads per block in the primitives' kernels (also the radix, 256 digits).
pub const BLOCK: u32 = 256;
/// Elements per thread in tiled kernels.
pub const ITEMS: usize = 8;
/// Elements per block in tiled kernels.
pub const TILE: usize = BLOCK as usize * ITEMS;
