#![warn(missing_docs)]
//! # simt
//!
//! A SIMT (GPU) machine emulated on rayon, measured the way a GPU profiler would
//! measure it. It knows nothing about rays.
//!
//! * **Launches**: [`Device::launch`] runs a grid of blocks in parallel; a block runs its
//!   threads warp by warp (32 lanes) in phases separated by barriers, with shared memory
//!   of a declared size (a launch asking for more than the device has is refused).
//! * **Memory**: typed [`DeviceBuffer`]s with current/peak accounting; kernels read and
//!   write through views, with atomics (including a 64-bit `atomic_min` for packed
//!   closest-hit keys).
//! * **Measurement** (switchable): per named kernel, launches and time always; SIMD
//!   efficiency (active lanes per issued warp step), warp-wide memory requests and the
//!   32-byte sectors they touch when [`Device::set_measure`] is on. Code a kernel shares
//!   with host code declares its arithmetic through the kernel's ambient lane
//!   ([`ambient`]: [`Thread::ambient`], [`declare!`](crate::declare!), [`scope`]).
//! * **Primitives** with Thrust names, written as kernels: [`inclusive_scan`],
//!   [`exclusive_scan`], [`transform_exclusive_scan`], [`reduce`], [`transform_reduce`], [`reduce_by_key`], [`sort_by_key`] (stable radix),
//!   [`copy_if`], [`gather`], [`scatter`], [`fill`], [`sequence`], and [`WorkQueue`].
//!   Each has a sequential twin in [`seq`].
//!
//! ## CUDA to simt
//!
//! | CUDA | simt |
//! |---|---|
//! | `kernel<<<grid, block, shmem>>>(args)` | `dev.launch("name", LaunchConfig { grid, block, shared_bytes, .. }, \|blk\| ..)` |
//! | one thread per element | `dev.for_each("name", n, \|t, i\| ..)` |
//! | `thrust::transform(x, x + n, y, y, op)` (each thread owns `y[i]`) | `dev.transform("name", &x, &mut y, \|t, i, x\| ..)`, `dev.transform_in_place("name", &x, &mut y, \|t, i, x, y\| ..)` |
//! | `threadIdx.x`, `blockIdx.x`, `blockDim.x`, `gridDim.x` | `t.thread_idx()`, `t.block_idx()`, `t.block_dim()`, `t.grid_dim()` |
//! | code between barriers | `blk.for_each_thread(\|t\| ..)` (one phase) |
//! | `__syncthreads()` | `blk.sync_threads()` (between phases) |
//! | `__shared__ T a[n]` | `let a = blk.shared::<T>(n)`; `t.load_shared(a, i)`, `t.store_shared(a, i, v)` |
//! | a register kept across a barrier | `let r = blk.local(init)`; `t.get(r)`, `t.set(r, v)` |
//! | `cudaMalloc` + `cudaMemcpy` | `dev.alloc_from(&host)`, `buf.as_slice()` |
//! | `p[i]`, `p[i] = v` | `t.load(&view, i)`, `t.store(&view, i, v)` |
//! | `atomicAdd`, `atomicMin`, `atomicMax`, `atomicCAS` | `t.atomic_add`, `t.atomic_min`, `t.atomic_max`, `t.atomic_cas` (`_u64` forms too) |
//! | the same with the old value unused (`RED` in SASS) | `t.red_add`, `t.red_min`, `t.red_max` (`_u64` forms too) |
//! | `laneid`, `warpid` | `t.lane_id()`, `t.warp_id()` |
//! | `__ballot_sync`, `__any_sync`, `__all_sync` | `w.ballot(&pred)`, `w.any(&pred)`, `w.all(&pred)` in `blk.for_each_warp(\|w\| ..)` |
//! | `__shfl_down_sync`, `__shfl_up_sync`, `__shfl_xor_sync`, `__shfl_sync` | `w.shfl_down(&v, d)`, `w.shfl_up`, `w.shfl_xor`, `w.shfl` on `[T; 32]` lane arrays |
//! | `thrust::exclusive_scan(first, last, out, init, op)` | `simt::exclusive_scan(&dev, &input, &mut out, init, identity, op)` |
//! | `thrust::sort_by_key` | `simt::sort_by_key(&dev, &mut keys, &mut values)` |
//! | `copy_if` returning an end iterator | `copy_if` returning a count |
//!
//! ## Example
//!
//! The program below is `simt/examples/block_sum.rs`: a block-wide sum with shared
//! memory, a barrier and warp shuffles, launched and measured.
//!
#![doc = concat!("```rust\n", include_str!("../examples/block_sum.rs"), "\n```")]

pub mod ambient;
mod device;
mod exec;
mod launch;
mod limits;
mod memory;
pub mod meter;
pub mod prims;
mod records;
mod runs;
pub mod seq;
pub mod stats;
pub mod timing;
mod transform;

pub use ambient::{Scope, scope};
pub use device::{Device, DeviceConfig, LaunchConfig, LaunchError, MAX_BLOCK_DIM, MemoryStats};
pub use exec::{Block, Local, Place, Shared, Thread, Together, Unrolled, Warp};
pub use limits::{MAX_PATHS, MAX_REGIONS, REGISTER_WORDS_PER_THREAD, RETRY_TRIP_INSTRUCTIONS, SECTOR_BYTES, WARP_SIZE};
pub use memory::{DeviceBuffer, DeviceCopy, Global, GlobalMut, Readable, prefetch_host};
pub use meter::{Race, Traffic, WarpChain};
pub use prims::queue::{QueuePusher, WorkQueue};
pub use prims::scan::{exclusive_scan, inclusive_scan, reduce, transform_exclusive_scan, transform_reduce};
pub use prims::select::{
    Flagged, copy_flagged, copy_if, copy_if_stencil, fill, gather, reduce_by_key, scatter, sequence,
};
pub use prims::sort::{RadixKey, sort_by_key, sort_by_key_bits};
pub use records::{records_from_tsv, records_to_tsv};
pub use stats::{KernelSummary, LaunchRecord, RegionStats};
pub use timing::{GpuProfile, Prediction};
