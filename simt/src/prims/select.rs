//! Element-wise primitives: fill, sequence, gather, scatter, copy_if (stream
//! compaction) and reduce_by_key (a segmented scan on head flags).

use super::look_back::TileStatus;
use super::scan::{inclusive_scan, warp_exclusive_sum};
use crate::device::{Device, LaunchConfig};
use crate::memory::{DeviceBuffer, DeviceCopy, Global, GlobalMut, Readable};
use std::cell::Cell;

/// Sets every element to `value`.
pub fn fill<T: DeviceCopy>(dev: &Device, buf: &mut DeviceBuffer<T>, value: T) {
    let out = buf.view_mut();
    dev.for_each("simt::fill", out.len(), |t, i| t.store(&out, i, value));
}

/// `buf[i] = start + i · step` (wrapping).
///
/// ```
/// let dev = simt::Device::default();
/// let mut b = dev.alloc::<u32>(4);
/// simt::sequence(&dev, &mut b, 10, 5);
/// assert_eq!(b.as_slice(), &[10, 15, 20, 25]);
/// ```
pub fn sequence(dev: &Device, buf: &mut DeviceBuffer<u32>, start: u32, step: u32) {
    let out = buf.view_mut();
    dev.for_each("simt::sequence", out.len(), |t, i| t.store(&out, i, start.wrapping_add(step.wrapping_mul(i as u32))));
}

/// `output[i] = input[map[i]]`.
///
/// ```
/// let dev = simt::Device::default();
/// let input = dev.alloc_from(&[10u32, 20, 30]);
/// let map = dev.alloc_from(&[2u32, 0, 0]);
/// let mut out = dev.alloc::<u32>(3);
/// simt::gather(&dev, &map, &input, &mut out);
/// assert_eq!(out.as_slice(), &[30, 10, 10]);
/// ```
pub fn gather<T: DeviceCopy>(
    dev: &Device,
    map: &DeviceBuffer<u32>,
    input: &DeviceBuffer<T>,
    output: &mut DeviceBuffer<T>,
) {
    assert_eq!(map.len(), output.len(), "gather: one map entry per output");
    let inp = input.view();
    dev.transform("simt::gather", &map.view(), output, |t, _, m| t.load(&inp, m as usize));
}

/// `output[map[i]] = input[i]` (map entries should be distinct).
///
/// ```
/// let dev = simt::Device::default();
/// let input = dev.alloc_from(&[10u32, 20, 30]);
/// let map = dev.alloc_from(&[2u32, 0, 1]);
/// let mut out = dev.alloc::<u32>(3);
/// simt::scatter(&dev, &input, &map, &mut out);
/// assert_eq!(out.as_slice(), &[20, 30, 10]);
/// ```
pub fn scatter<T: DeviceCopy>(
    dev: &Device,
    input: &DeviceBuffer<T>,
    map: &DeviceBuffer<u32>,
    output: &mut DeviceBuffer<T>,
) {
    assert_eq!(map.len(), input.len(), "scatter: one map entry per input");
    let (m, inp, out) = (map.view(), input.view(), output.view_mut());
    dev.for_each("simt::scatter", m.len(), |t, i| t.store(&out, t.load(&m, i) as usize, t.load(&inp, i)));
}

/// Copies the elements whose `stencil` entry satisfies `pred`, in order, to the front
/// of `output`; returns how many. `output` must be as long as `input`.
pub fn copy_if_stencil<T, S, P>(
    dev: &Device,
    input: &DeviceBuffer<T>,
    stencil: &DeviceBuffer<S>,
    output: &mut DeviceBuffer<T>,
    pred: P,
) -> usize
where
    T: DeviceCopy,
    S: DeviceCopy,
    P: Fn(S) -> bool + Sync,
{
    let n = input.len();
    assert_eq!(stencil.len(), n, "copy_if: one stencil entry per input");
    assert!(output.len() >= n, "copy_if: output shorter than input");
    if n == 0 {
        return 0;
    }
    if !dev.measuring() {
        return dev.host("simt::copy_if [cpu]", n, || {
            super::native::copy_if_stencil(input.as_slice(), stencil.as_slice(), output.as_mut_slice(), pred)
        });
    }
    select_tiles(dev, (input.view(), stencil.view(), output.view_mut()), pred, StencilLoads::OneByOne)
}

/// Copies the elements whose flag is non-zero, in order, to the front of `output`;
/// returns how many (CUB's `DeviceSelect::Flagged` over an array of flags). The same
/// selection as [`copy_if_stencil`] with the predicate `flag != 0`, but a thread loads
/// its flags as it loads its elements, all together: CUB's direct blocked load of a
/// plain array, whose loads nvcc issues back to back, where a predicate computed from
/// each stencil record (a transform iterator over rays, as PDACRT's twin has it) is
/// loaded and tested one element after another.
///
/// ```
/// let dev = simt::Device::default();
/// let input = dev.alloc_from(&[1u32, 4, 7, 8, 3]);
/// let flags = dev.alloc_from(&[0u32, 1, 0, 2, 0]);
/// let mut out = dev.alloc::<u32>(5);
/// let n = simt::copy_flagged(&dev, &input, &flags, &mut out);
/// assert_eq!(&out.as_slice()[..n], &[4, 8]);
/// ```
pub fn copy_flagged<T: DeviceCopy>(
    dev: &Device,
    input: &DeviceBuffer<T>,
    flags: &DeviceBuffer<u32>,
    output: &mut DeviceBuffer<T>,
) -> usize {
    let n = input.len();
    assert_eq!(flags.len(), n, "copy_flagged: one flag per input");
    assert!(output.len() >= n, "copy_flagged: output shorter than input");
    if n == 0 {
        return 0;
    }
    let keep = |f: u32| f != 0;
    if !dev.measuring() {
        return dev.host("simt::copy_if [cpu]", n, || {
            super::native::copy_if_stencil(input.as_slice(), flags.as_slice(), output.as_mut_slice(), keep)
        });
    }
    select_tiles(dev, (input.view(), flags.view(), output.view_mut()), keep, StencilLoads::Together)
}

/// How a selection's threads load their stencil values.
#[derive(Clone, Copy, PartialEq)]
enum StencilLoads {
    /// All of a thread's at once, as its elements (a plain array of flags).
    Together,
    /// Each element's loaded and tested before the next (a predicate over records).
    OneByOne,
}

/// Threads of a selection block and elements a thread selects: CUB's `DeviceSelect::Flagged`
/// tunings on sm_90 for 1-, 2-, 4- and 8-byte elements (the twins select 4-byte ray and
/// path indices: 384 × 15), its default policy for other sizes.
fn select_shape<T>() -> (u32, usize) {
    match std::mem::size_of::<T>() {
        1 | 2 => (448, 20),
        4 => (384, 15),
        8 => (384, 11),
        size => (128, (40 / size.max(1)).clamp(1, 10)),
    }
}

/// [`copy_if_stencil`] as CUB's single pass: a launch clears the tiles' status words
/// (`DeviceCompactInitKernel`); then each block loads its tile (each thread its own
/// consecutive elements together, then their stencil values one by one), counts what `pred`
/// keeps, scans the counts across the block, learns the count kept before the tile by a
/// decoupled look-back and writes the kept elements out: through shared memory, in
/// order and coalesced, when the tile keeps more than one element a thread, else each
/// thread its own. The last block writes the total.
fn select_tiles<T: DeviceCopy, S: DeviceCopy>(
    dev: &Device,
    (inp, st, out): (Global<'_, T>, Global<'_, S>, GlobalMut<'_, T>),
    pred: impl Fn(S) -> bool + Sync,
    stencil_loads: StencilLoads,
) -> usize {
    let n = inp.len();
    let (select_threads, items) = select_shape::<T>();
    let (threads, tile_len) = (select_threads as usize, select_threads as usize * items);
    let tiles = n.div_ceil(tile_len);
    let mut count = dev.alloc::<u32>(1);
    let mut status = TileStatus::new(dev, tiles, 1, 0u32, Some("simt::select_init"));
    let status = status.views();
    let total = count.view_mut();
    let warps = threads / 32;
    let shared = tile_len * std::mem::size_of::<T>() + (warps + 1) * 4;
    let cfg = LaunchConfig {
        grid: tiles as u32,
        block: select_threads,
        shared_bytes: shared,
        regions: &[],
        registers: 0,
        code_bytes: 0,
    };
    dev.launch_in_order("simt::select_sweep", cfg, |blk| {
        let b = blk.block_idx() as usize;
        let base = b * tile_len;
        let valid = (n - base).min(tile_len);
        let exchange = blk.shared::<T>(tile_len);
        let warp_sums = blk.shared::<u32>(warps);
        let tile_before = blk.shared::<u32>(1);
        let r_kept = blk.local::<u32>(0);
        let r_before = blk.local::<u32>(0);
        // Each thread's consecutive elements, loaded together (CUB's direct blocked
        // loads), then its stencil values: a plain array's together too, records one
        // element at a time, each loaded and tested before the next (as PDACRT's twin's
        // SASS has it: the rays' words in dependent groups, ray after ray); `r_kept`
        // marks the ones `pred` keeps.
        blk.for_each_thread(|t| {
            let mine = (t.thread_idx() as usize * items).min(valid)..((t.thread_idx() as usize + 1) * items).min(valid);
            {
                let _together = t.loads_together();
                mine.clone().for_each(|i| {
                    t.load(&inp, base + i);
                });
            }
            let mut kept = 0u32;
            let all_at_once = (stencil_loads == StencilLoads::Together).then(|| t.loads_together());
            for (k, i) in mine.enumerate() {
                let _one = all_at_once.is_none().then(|| t.loads_together());
                kept |= (pred(t.load(&st, base + i)) as u32) << k;
            }
            drop(all_at_once);
            t.set(r_kept, kept);
        });
        blk.sync_threads();
        // Exclusive sum of the threads' counts: within each warp by shuffles, then the
        // warps' totals by thread 0, whose look-back adds the tiles before.
        blk.for_each_warp(|w| {
            let mut counts = [0u32; 32];
            w.for_each_lane(|t| counts[t.lane_id() as usize] = t.get(r_kept).count_ones());
            warp_exclusive_sum(w, counts, r_before, warp_sums);
        });
        blk.sync_threads();
        // Block-uniform: the tile's count (CUB's block scan gives it to every thread).
        let tile_kept = Cell::new(0u32);
        blk.for_each_thread(|t| {
            if t.thread_idx() == 0 {
                let mut acc = 0;
                for w in 0..warps {
                    let s = t.load_shared(warp_sums, w);
                    t.store_shared(warp_sums, w, acc);
                    acc += s;
                }
                let before = status.look_back(t, b, 0, acc, 0, |a, c| a + c);
                t.store_shared(tile_before, 0, before);
                tile_kept.set(acc);
                if b + 1 == tiles {
                    t.store(&total, 0, before + acc);
                }
            }
        });
        blk.sync_threads();
        let two_phase = tile_kept.get() > select_threads;
        // Each kept element's place; its value is the one loaded above (held in registers
        // on a GPU, read again here unmeasured).
        blk.for_each_thread(|t| {
            let before = t.load_shared(tile_before, 0) as usize;
            let mut at = (t.load_shared(warp_sums, t.warp_id() as usize) + t.get(r_before)) as usize;
            let kept = t.get(r_kept);
            for k in 0..items {
                if kept >> k & 1 == 1 {
                    let v = inp.read(base + t.thread_idx() as usize * items + k);
                    if two_phase {
                        t.store_shared(exchange, at, v);
                    } else {
                        t.store(&out, before + at, v);
                    }
                    at += 1;
                }
            }
        });
        if two_phase {
            // The tile's kept elements, in order, out of shared memory: coalesced stores.
            blk.sync_threads();
            blk.for_each_thread(|t| {
                let before = t.load_shared(tile_before, 0) as usize;
                let mut j = t.thread_idx() as usize;
                while j < tile_kept.get() as usize {
                    t.store(&out, before + j, t.load_shared(exchange, j));
                    j += threads;
                }
            });
        }
    })
    .expect("selection launch shape is valid");
    count.as_slice()[0] as usize
}

/// Copies the elements satisfying `pred`, in order, to the front of `output`;
/// returns how many (Thrust's `copy_if`, with a count for the end iterator).
///
/// ```
/// let dev = simt::Device::default();
/// let input = dev.alloc_from(&[1u32, 4, 7, 8, 3]);
/// let mut out = dev.alloc::<u32>(5);
/// let n = simt::copy_if(&dev, &input, &mut out, |x| x % 2 == 0);
/// assert_eq!(&out.as_slice()[..n], &[4, 8]);
/// ```
pub fn copy_if<T, P>(dev: &Device, input: &DeviceBuffer<T>, output: &mut DeviceBuffer<T>, pred: P) -> usize
where
    T: DeviceCopy,
    P: Fn(T) -> bool + Sync,
{
    copy_if_stencil(dev, input, input, output, pred)
}

/// A value with a segment-head flag, for segmented scans (packed to 4-byte alignment so
/// it has no padding for any `DeviceCopy` value).
#[derive(Clone, Copy, Debug, Default)]
#[repr(C, packed(4))]
pub struct Flagged<V> {
    /// Nonzero when the value is selected.
    pub flag: u32,
    /// The value.
    pub value: V,
}
unsafe impl<V: DeviceCopy> DeviceCopy for Flagged<V> {}

/// For each run of equal consecutive keys, writes the key and the reduction of its
/// values; returns the number of runs. Outputs must be as long as the inputs.
///
/// ```
/// let dev = simt::Device::default();
/// let keys = dev.alloc_from(&[1u32, 1, 3, 3, 3, 1]);
/// let vals = dev.alloc_from(&[9u32, 1, 2, 2, 2, 5]);
/// let (mut ok, mut ov) = (dev.alloc::<u32>(6), dev.alloc::<u32>(6));
/// let n = simt::reduce_by_key(&dev, &keys, &vals, &mut ok, &mut ov, 0, |a, b| a + b);
/// assert_eq!((&ok.as_slice()[..n], &ov.as_slice()[..n]), (&[1, 3, 1][..], &[10, 6, 5][..]));
/// ```
pub fn reduce_by_key<K, V, F>(
    dev: &Device,
    keys: &DeviceBuffer<K>,
    values: &DeviceBuffer<V>,
    out_keys: &mut DeviceBuffer<K>,
    out_values: &mut DeviceBuffer<V>,
    identity: V,
    op: F,
) -> usize
where
    K: DeviceCopy + PartialEq,
    V: DeviceCopy,
    F: Fn(V, V) -> V + Sync + Copy,
{
    let n = keys.len();
    assert_eq!(values.len(), n, "reduce_by_key: one value per key");
    assert!(out_keys.len() >= n && out_values.len() >= n, "reduce_by_key: outputs shorter than inputs");
    if n == 0 {
        return 0;
    }
    if !dev.measuring() {
        return dev.host("simt::reduce_by_key [cpu]", n, || {
            super::native::reduce_by_key(
                keys.as_slice(),
                values.as_slice(),
                out_keys.as_mut_slice(),
                out_values.as_mut_slice(),
                op,
            )
        });
    }
    let mut heads = dev.alloc::<u32>(n);
    let mut pairs = dev.alloc_filled(n, Flagged { flag: 0, value: identity });
    {
        let (k, v, h, p) = (keys.view(), values.view(), heads.view_mut(), pairs.view_mut());
        dev.for_each("simt::rbk_heads", n, |t, i| {
            let head = i == 0 || t.load(&k, i) != t.load(&k, i - 1);
            t.store(&h, i, head as u32);
            t.store(&p, i, Flagged { flag: head as u32, value: t.load(&v, i) });
        });
    }
    // Segmented inclusive scan: a head restarts the running value.
    let mut scanned = dev.alloc_filled(n, Flagged { flag: 0, value: identity });
    inclusive_scan(
        dev,
        &pairs,
        &mut scanned,
        Flagged { flag: 0, value: identity },
        move |a: Flagged<V>, b: Flagged<V>| {
            if b.flag != 0 { b } else { Flagged { flag: a.flag, value: op(a.value, b.value) } }
        },
    );
    drop(pairs);
    let mut seg = dev.alloc::<u32>(n);
    inclusive_scan(dev, &heads, &mut seg, 0, |a, b| a + b);
    let count = seg.as_slice()[n - 1] as usize;
    let (k, h, s, sc) = (keys.view(), heads.view(), seg.view(), scanned.view());
    let (ok, ov) = (out_keys.view_mut(), out_values.view_mut());
    dev.for_each("simt::rbk_scatter", n, |t, i| {
        let tail = i == n - 1 || t.load(&h, i + 1) != 0;
        if tail {
            let o = t.load(&s, i) as usize - 1;
            t.store(&ok, o, t.load(&k, i));
            t.store(&ov, o, t.load(&sc, i).value);
        }
    });
    count
}
