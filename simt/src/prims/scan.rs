//! Scans and reductions over an associative operator with an identity, as kernels.
//! A scan is one pass, as CUB's is: each block scans a tile in CUB's shape (striped
//! loads into shared memory, a sequential scan per thread, a shuffle scan
//! across lanes, a scan across warps), learns the total of the tiles before it by a
//! decoupled look-back ([`super::look_back`]) and writes its elements out; a small launch
//! clears the tiles' status words first. A reduction reduces tiles, then the tiles'
//! totals.

use super::look_back::TileStatus;
use super::{BLOCK, ITEMS, TILE};
use crate::device::{Device, LaunchConfig};
use crate::exec::{Local, Shared, Warp};
use crate::memory::{DeviceBuffer, DeviceCopy};

/// The identity map of the plain scans (a named function, so the recursion over
/// block totals instantiates one type).
fn same<T>(x: T) -> T {
    x
}

/// Inclusive scan of the warp's 32 values (Hillis–Steele with `shfl_up`).
pub(super) fn warp_inclusive_scan<T: Copy>(w: &Warp, v: &mut [T; 32], op: impl Fn(T, T) -> T) {
    let mut d = 1;
    while d < 32 {
        let up = w.shfl_up(v, d);
        for lane in d as usize..32 {
            v[lane] = op(up[lane], v[lane]);
        }
        d *= 2;
    }
}

/// The warp step of a block's exclusive sum of one count a lane: each lane's sum of the
/// counts of the lanes before it into `r_exclusive`, the warp's total into
/// `warp_sums[warp]` (the selection's kept counts, the sort's digit counts).
pub(super) fn warp_exclusive_sum(w: &mut Warp, counts: [u32; 32], r_exclusive: Local<u32>, warp_sums: Shared<u32>) {
    let mut v = counts;
    warp_inclusive_scan(w, &mut v, |a, b| a + b);
    w.for_each_lane(|t| {
        let l = t.lane_id() as usize;
        t.set(r_exclusive, v[l] - counts[l]);
        if l == 31 {
            t.store_shared(warp_sums, t.warp_id() as usize, v[31]);
        }
    });
}

/// Threads of a scan block and elements a thread scans: CUB's sm_90 tunings for
/// primitive values of 1, 2, 4 and 8 bytes (4-byte sums: tiles of 128 × 24), its default
/// policy for others, 128 threads of 15 four-byte elements' worth (PDACRT's scans of
/// three-word counts: 128 × 5). A value's size stands for CUB's test of a primitive
/// type and operator: the scans here of 1 to 8 bytes are sums of integers.
fn scan_shape<T>() -> (u32, usize) {
    match std::mem::size_of::<T>() {
        1 => (192, 22),
        2 => (512, 12),
        4 => (128, 24),
        8 => (224, 24),
        size => (128, (60 / size.max(1)).clamp(1, 15)),
    }
}

/// Scans `input` (mapped) into `output` in one launch, one tile per block; with `init`,
/// exclusively, starting from it.
fn scan_tiles<I, T, M, F>(
    dev: &Device,
    input: &DeviceBuffer<I>,
    map: M,
    output: &mut DeviceBuffer<T>,
    init: Option<T>,
    identity: T,
    op: F,
) where
    I: DeviceCopy,
    T: DeviceCopy,
    M: Fn(I) -> T + Sync + Copy,
    F: Fn(T, T) -> T + Sync + Copy,
{
    let n = input.len();
    let (threads, items) = scan_shape::<T>();
    let tile_len = threads as usize * items;
    let blocks = n.div_ceil(tile_len);
    let exclusive = init.is_some();
    let mut status = TileStatus::new(dev, blocks, 1, identity, Some("simt::scan_init"));
    let (inp, out, status) = (input.view(), output.view_mut(), status.views());
    let shared = (tile_len + threads as usize + 32 + 1) * std::mem::size_of::<T>();
    let cfg = LaunchConfig {
        grid: blocks as u32,
        block: threads,
        shared_bytes: shared,
        regions: &[],
        registers: 0,
        code_bytes: 0,
    };
    dev.launch_in_order("simt::scan_tiles", cfg, |blk| {
        let b = blk.block_idx() as usize;
        let base = b * tile_len;
        let valid = (n - base).min(tile_len);
        let tile = blk.shared::<T>(tile_len);
        let sums = blk.shared::<T>(threads as usize);
        let warp_sums = blk.shared::<T>(32);
        let block_prefix = blk.shared::<T>(1);
        // Coalesced striped loads into shared memory, issued together (CUB's BlockLoad).
        blk.for_each_thread(|t| {
            let _together = t.loads_together();
            for k in 0..items {
                let j = k * threads as usize + t.thread_idx() as usize;
                let v = if j < valid { map(t.load(&inp, base + j)) } else { identity };
                t.store_shared(tile, j, v);
            }
        });
        blk.sync_threads();
        // Each thread scans its `items` consecutive elements (inclusive, in place).
        blk.for_each_thread(|t| {
            let start = t.thread_idx() as usize * items;
            let mut acc = identity;
            for j in start..start + items {
                acc = op(acc, t.load_shared(tile, j));
                t.store_shared(tile, j, acc);
            }
            t.store_shared(sums, t.thread_idx() as usize, acc);
        });
        blk.sync_threads();
        // Inclusive scan of thread totals within each warp (Hillis–Steele with shfl_up).
        blk.for_each_warp(|w| {
            let first = w.warp_idx() as usize * 32;
            let mut v = [identity; 32];
            w.for_each_lane(|t| v[t.lane_id() as usize] = t.load_shared(sums, first + t.lane_id() as usize));
            warp_inclusive_scan(w, &mut v, op);
            w.for_each_lane(|t| {
                t.store_shared(sums, first + t.lane_id() as usize, v[t.lane_id() as usize]);
                if t.lane_id() == 31 {
                    t.store_shared(warp_sums, t.warp_id() as usize, v[31]);
                }
            });
        });
        blk.sync_threads();
        // Exclusive scan of the warp totals (one a warp) by thread 0, then its look-back
        // for the total of the tiles before this one.
        let warps = blk.warp_count() as usize;
        blk.for_each_thread(|t| {
            if t.thread_idx() == 0 {
                let mut acc = identity;
                for w in 0..warps {
                    let s = t.load_shared(warp_sums, w);
                    t.store_shared(warp_sums, w, acc);
                    acc = op(acc, s);
                }
                let before = status.look_back(t, b, 0, acc, identity, op);
                t.store_shared(block_prefix, 0, init.map_or(before, |f| op(f, before)));
            }
        });
        blk.sync_threads();
        // Apply the thread's prefix to its elements; write out striped (coalesced).
        blk.for_each_thread(|t| {
            let ti = t.thread_idx() as usize;
            let warp_prefix = t.load_shared(warp_sums, t.warp_id() as usize);
            let lane_prefix = if t.lane_id() == 0 { identity } else { t.load_shared(sums, ti - 1) };
            let prefix = op(t.load_shared(block_prefix, 0), op(warp_prefix, lane_prefix));
            let start = ti * items;
            let mut prev = prefix;
            for j in start..start + items {
                let inc = op(prefix, t.load_shared(tile, j));
                t.store_shared(tile, j, if exclusive { prev } else { inc });
                prev = inc;
            }
        });
        blk.sync_threads();
        blk.for_each_thread(|t| {
            for k in 0..items {
                let j = k * threads as usize + t.thread_idx() as usize;
                if j < valid {
                    t.store(&out, base + j, t.load_shared(tile, j));
                }
            }
        });
    })
    .expect("scan launch shape is valid");
}

fn scan<I, T, M, F>(
    dev: &Device,
    input: &DeviceBuffer<I>,
    map: M,
    output: &mut DeviceBuffer<T>,
    init: Option<T>,
    identity: T,
    op: F,
) where
    I: DeviceCopy,
    T: DeviceCopy,
    M: Fn(I) -> T + Sync + Copy,
    F: Fn(T, T) -> T + Sync + Copy,
{
    assert_eq!(input.len(), output.len(), "scan output must match its input");
    if input.is_empty() {
        return;
    }
    if !dev.measuring() {
        return dev.host("simt::scan [cpu]", input.len(), || {
            super::native::scan(input.as_slice(), map, output.as_mut_slice(), init, identity, op)
        });
    }
    scan_tiles(dev, input, map, output, init, identity, op);
}

/// `output[i] = input[0] ⊕ … ⊕ input[i]`. `identity` must be neutral for `op`
/// (0 for `+`, `u32::MAX` for `min`); `op` must be associative.
///
/// ```
/// let dev = simt::Device::default();
/// let input = dev.alloc_from(&[1u32, 0, 2, 2, 1, 3]);
/// let mut out = dev.alloc::<u32>(6);
/// simt::inclusive_scan(&dev, &input, &mut out, 0, |a, b| a + b);
/// assert_eq!(out.as_slice(), &[1, 1, 3, 5, 6, 9]);
/// ```
pub fn inclusive_scan<T, F>(dev: &Device, input: &DeviceBuffer<T>, output: &mut DeviceBuffer<T>, identity: T, op: F)
where
    T: DeviceCopy,
    F: Fn(T, T) -> T + Sync + Copy,
{
    scan(dev, input, same, output, None, identity, op)
}

/// `output[0] = init`, `output[i] = init ⊕ input[0] ⊕ … ⊕ input[i-1]`.
///
/// ```
/// let dev = simt::Device::default();
/// let input = dev.alloc_from(&[1u32, 0, 2, 2, 1, 3]);
/// let mut out = dev.alloc::<u32>(6);
/// simt::exclusive_scan(&dev, &input, &mut out, 4, 0, |a, b| a + b);
/// assert_eq!(out.as_slice(), &[4, 5, 5, 7, 9, 10]);
/// ```
pub fn exclusive_scan<T, F>(
    dev: &Device,
    input: &DeviceBuffer<T>,
    output: &mut DeviceBuffer<T>,
    init: T,
    identity: T,
    op: F,
) where
    T: DeviceCopy,
    F: Fn(T, T) -> T + Sync + Copy,
{
    scan(dev, input, same, output, Some(init), identity, op)
}

/// [`exclusive_scan`] of `map(input[i])` without storing the mapped values (Thrust's
/// `transform_exclusive_scan`): `output[0] = init`, `output[i] = init ⊕ map(input[0]) ⊕
/// … ⊕ map(input[i-1])`.
///
/// ```
/// let dev = simt::Device::default();
/// let input = dev.alloc_from(&[3u32, 0, 2, 3]);
/// let mut out = dev.alloc::<u32>(4);
/// simt::transform_exclusive_scan(&dev, &input, &mut out, |x| (x == 3) as u32, 0, 0, |a, b| a + b);
/// assert_eq!(out.as_slice(), &[0, 1, 1, 1]);
/// ```
pub fn transform_exclusive_scan<I, T, M, F>(
    dev: &Device,
    input: &DeviceBuffer<I>,
    output: &mut DeviceBuffer<T>,
    map: M,
    init: T,
    identity: T,
    op: F,
) where
    I: DeviceCopy,
    T: DeviceCopy,
    M: Fn(I) -> T + Sync + Copy,
    F: Fn(T, T) -> T + Sync + Copy,
{
    scan(dev, input, map, output, Some(init), identity, op)
}

/// `init ⊕ input[0] ⊕ … ⊕ input[n-1]`, reduced block by block on the device.
///
/// ```
/// let dev = simt::Device::default();
/// let input = dev.alloc_from(&[3u32, 9, 1, 7]);
/// assert_eq!(simt::reduce(&dev, &input, 0, 0, |a, b| a + b), 20);
/// assert_eq!(simt::reduce(&dev, &input, u32::MAX, u32::MAX, |a, b| a.min(b)), 1);
/// ```
pub fn reduce<T, F>(dev: &Device, input: &DeviceBuffer<T>, init: T, identity: T, op: F) -> T
where
    T: DeviceCopy,
    F: Fn(T, T) -> T + Sync + Copy,
{
    transform_reduce(dev, input, same, init, identity, op)
}

/// `init ⊕ map(input[0]) ⊕ … ⊕ map(input[n-1])` without storing the mapped values
/// (Thrust's `transform_reduce`; CUB's reduce over a transform iterator): the first
/// pass reads the inputs themselves.
///
/// ```
/// let dev = simt::Device::default();
/// let input = dev.alloc_from(&[[3u32, 1], [9, 2], [1, 5]]);
/// assert_eq!(simt::transform_reduce(&dev, &input, |p: [u32; 2]| p[0] * p[1], 0, 0, |a, b| a + b), 26);
/// ```
pub fn transform_reduce<I, T, M, F>(dev: &Device, input: &DeviceBuffer<I>, map: M, init: T, identity: T, op: F) -> T
where
    I: DeviceCopy,
    T: DeviceCopy,
    M: Fn(I) -> T + Sync + Copy,
    F: Fn(T, T) -> T + Sync + Copy,
{
    let n = input.len();
    if n == 0 {
        return init;
    }
    if !dev.measuring() {
        return dev.host("simt::reduce [cpu]", n, || super::native::reduce(input.as_slice(), map, init, identity, op));
    }
    let blocks = n.div_ceil(TILE);
    let mut partial = dev.alloc_filled(blocks, identity);
    let (inp, part) = (input.view(), partial.view_mut());
    let cfg = LaunchConfig {
        grid: blocks as u32,
        block: BLOCK,
        shared_bytes: 32 * std::mem::size_of::<T>(),
        regions: &[],
        registers: 0,
        code_bytes: 0,
    };
    dev.launch("simt::reduce_tiles", cfg, |blk| {
        let base = blk.block_idx() as usize * TILE;
        let warp_sums = blk.shared::<T>(32);
        blk.for_each_warp(|w| {
            let mut v = [identity; 32];
            w.for_each_lane(|t| {
                // Each thread folds ITEMS consecutive elements (a blocked arrangement keeps
                // operand order, so `op` need not commute), loaded together as CUB's
                // unrolled tile loads are.
                let _together = t.loads_together();
                let mut acc = identity;
                for k in 0..ITEMS {
                    let i = base + t.thread_idx() as usize * ITEMS + k;
                    if i < n {
                        acc = op(acc, map(t.load(&inp, i)));
                    }
                }
                v[t.lane_id() as usize] = acc;
            });
            // Pairwise tree of neighbours (lane l with l + d for l a multiple of 2d):
            // operands stay in lane order, so `op` need not commute.
            let mut d = 1;
            while d < 32 {
                let down = w.shfl_down(&v, d);
                for lane in (0..32).step_by(2 * d as usize) {
                    if lane + d < w.lane_count() {
                        v[lane as usize] = op(v[lane as usize], down[lane as usize]);
                    }
                }
                d *= 2;
            }
            w.for_each_lane(|t| {
                if t.lane_id() == 0 {
                    t.store_shared(warp_sums, t.warp_id() as usize, v[0]);
                }
            });
        });
        blk.sync_threads();
        let warps = blk.warp_count() as usize;
        blk.for_each_thread(|t| {
            if t.thread_idx() == 0 {
                let mut acc = identity;
                for w in 0..warps {
                    acc = op(acc, t.load_shared(warp_sums, w));
                }
                t.store(&part, t.block_idx() as usize, acc);
            }
        });
    })
    .expect("reduce launch shape is valid");
    if blocks == 1 { op(init, partial.as_slice()[0]) } else { reduce(dev, &partial, init, identity, op) }
}
