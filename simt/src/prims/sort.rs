//! Stable LSD radix sort by key, 8 bits a pass, as kernels: a per-block digit histogram,
//! an exclusive scan of the digit-major count table, and a stable scatter in which each
//! warp ranks its lanes by digit with ballots (the `match_any` idiom) and the block's
//! warps are ordered by a per-digit scan in shared memory.
//!
//! Keys that carry a segment id in their high bits sort segment by segment, which is
//! how PDACRT runs a segmented sort; [`sort_by_key_bits`] limits the passes to the bits
//! in use.

pub use super::radix_key::RadixKey;
use super::{BLOCK, ITEMS, TILE};
use crate::device::{Device, LaunchConfig};
use crate::memory::{DeviceBuffer, DeviceCopy};
use crate::prims::scan::exclusive_scan;

const RADIX: usize = 256;
const WARPS: usize = BLOCK as usize / 32;

/// Sorts `keys` ascending, moving `values` with them; equal keys keep their order.
///
/// ```
/// let dev = simt::Device::default();
/// let mut keys = dev.alloc_from(&[3u32, 1, 2, 1]);
/// let mut vals = dev.alloc_from(&[30u32, 10, 20, 11]);
/// simt::sort_by_key(&dev, &mut keys, &mut vals);
/// assert_eq!(keys.as_slice(), &[1, 1, 2, 3]);
/// assert_eq!(vals.as_slice(), &[10, 11, 20, 30]); // stable: 10 before 11
/// ```
pub fn sort_by_key<K: RadixKey, V: DeviceCopy>(dev: &Device, keys: &mut DeviceBuffer<K>, values: &mut DeviceBuffer<V>) {
    sort_by_key_bits(dev, keys, values, 0, K::BITS)
}

/// [`sort_by_key`] on key bits `begin_bit..end_bit` only (higher and lower bits are
/// ignored for ordering); fewer bits, fewer passes.
pub fn sort_by_key_bits<K: RadixKey, V: DeviceCopy>(
    dev: &Device,
    keys: &mut DeviceBuffer<K>,
    values: &mut DeviceBuffer<V>,
    begin_bit: u32,
    end_bit: u32,
) {
    assert_eq!(keys.len(), values.len(), "one value per key");
    assert!(begin_bit <= end_bit && end_bit <= K::BITS, "bit range {begin_bit}..{end_bit} of a {}-bit key", K::BITS);
    let n = keys.len();
    if n <= 1 || begin_bit == end_bit {
        return;
    }
    if !dev.measuring() {
        let bytes = n * std::mem::size_of::<(K, V)>();
        return dev.host("simt::sort_by_key [cpu]", n, || {
            dev.with_pool(bytes, |pool| {
                super::native::sort_by_key_bits(keys.as_mut_slice(), values.as_mut_slice(), begin_bit, end_bit, pool)
            })
        });
    }
    let mut keys_tmp = dev.alloc_vec(keys.as_slice().to_vec());
    let mut vals_tmp = dev.alloc_vec(values.as_slice().to_vec());
    let mut shift = begin_bit;
    while shift < end_bit {
        let width = (end_bit - shift).min(8);
        radix_pass(dev, keys, values, &mut keys_tmp, &mut vals_tmp, shift, width);
        std::mem::swap(keys, &mut keys_tmp);
        std::mem::swap(values, &mut vals_tmp);
        shift += width;
    }
}

fn radix_pass<K: RadixKey, V: DeviceCopy>(
    dev: &Device,
    keys_in: &DeviceBuffer<K>,
    vals_in: &DeviceBuffer<V>,
    keys_out: &mut DeviceBuffer<K>,
    vals_out: &mut DeviceBuffer<V>,
    shift: u32,
    width: u32,
) {
    let n = keys_in.len();
    let grid = n.div_ceil(TILE);
    let mut counts = dev.alloc::<u32>(grid * RADIX);
    {
        let (kin, cnt) = (keys_in.view(), counts.view_mut());
        let cfg = LaunchConfig { grid: grid as u32, block: BLOCK, shared_bytes: RADIX * 4, regions: &[], registers: 0 };
        dev.launch("simt::radix_histogram", cfg, |blk| {
            let base = blk.block_idx() as usize * TILE;
            let hist = blk.shared::<u32>(RADIX);
            blk.for_each_thread(|t| {
                for k in 0..ITEMS {
                    let i = base + k * BLOCK as usize + t.thread_idx() as usize;
                    if i < n {
                        let d = t.load(&kin, i).digit(shift, width);
                        t.atomic_add_shared(hist, d as usize, 1);
                    }
                }
            });
            blk.sync_threads();
            blk.for_each_thread(|t| {
                let d = t.thread_idx() as usize;
                t.store(&cnt, d * grid + t.block_idx() as usize, t.load_shared(hist, d));
            });
        })
        .expect("radix launch shape is valid");
    }
    let mut offsets = dev.alloc::<u32>(grid * RADIX);
    exclusive_scan(dev, &counts, &mut offsets, 0, 0, |a, b| a + b);
    drop(counts);

    let (kin, vin, offs) = (keys_in.view(), vals_in.view(), offsets.view());
    let (kout, vout) = (keys_out.view_mut(), vals_out.view_mut());
    let shared = (RADIX + 2 * WARPS * RADIX) * 4;
    let cfg = LaunchConfig { grid: grid as u32, block: BLOCK, shared_bytes: shared, regions: &[], registers: 0 };
    dev.launch("simt::radix_scatter", cfg, |blk| {
        let b = blk.block_idx() as usize;
        let base = b * TILE;
        let run = blk.shared::<u32>(RADIX);
        let warp_cnt = blk.shared::<u32>(WARPS * RADIX);
        let warp_base = blk.shared::<u32>(WARPS * RADIX);
        let r_digit = blk.local::<u32>(0);
        let r_rank = blk.local::<u32>(0);
        let r_valid = blk.local::<u32>(0);
        blk.for_each_thread(|t| {
            let d = t.thread_idx() as usize;
            t.store_shared(run, d, t.load(&offs, d * grid + b));
        });
        blk.sync_threads();
        // Rounds of BLOCK elements, in index order, keep the scatter stable.
        for k in 0..ITEMS {
            let round = base + k * BLOCK as usize;
            blk.for_each_warp(|w| {
                let first = round + w.warp_idx() as usize * 32;
                let mut digit = [0u32; 32];
                let mut valid = [false; 32];
                w.for_each_lane(|t| {
                    let i = first + t.lane_id() as usize;
                    if i < n {
                        digit[t.lane_id() as usize] = t.load(&kin, i).digit(shift, width);
                        valid[t.lane_id() as usize] = true;
                    }
                });
                // Lanes with the same digit ("peers"), from one ballot per digit bit.
                let mut peers = [w.ballot(&valid); 32];
                for bit in 0..width {
                    let set: [bool; 32] = std::array::from_fn(|l| digit[l] >> bit & 1 == 1);
                    let mask = w.ballot(&set);
                    for l in 0..32 {
                        peers[l] &= if set[l] { mask } else { !mask };
                    }
                }
                w.for_each_lane(|t| {
                    let l = t.lane_id() as usize;
                    t.set(r_valid, valid[l] as u32);
                    if !valid[l] {
                        return;
                    }
                    let below = peers[l] & ((1u32 << l) - 1);
                    t.set(r_digit, digit[l]);
                    t.set(r_rank, below.count_ones());
                    if below == 0 {
                        // The lowest lane of each digit reports the warp's count.
                        t.store_shared(
                            warp_cnt,
                            t.warp_id() as usize * RADIX + digit[l] as usize,
                            peers[l].count_ones(),
                        );
                    }
                });
            });
            blk.sync_threads();
            // Thread d orders the warps' counts of digit d.
            blk.for_each_thread(|t| {
                let d = t.thread_idx() as usize;
                let mut acc = t.load_shared(run, d);
                for w in 0..WARPS {
                    let c = t.load_shared(warp_cnt, w * RADIX + d);
                    t.store_shared(warp_base, w * RADIX + d, acc);
                    t.store_shared(warp_cnt, w * RADIX + d, 0);
                    acc += c;
                }
                t.store_shared(run, d, acc);
            });
            blk.sync_threads();
            blk.for_each_thread(|t| {
                if t.get(r_valid) == 0 {
                    return;
                }
                let i = round + t.thread_idx() as usize;
                let d = t.get(r_digit) as usize;
                let pos = (t.load_shared(warp_base, t.warp_id() as usize * RADIX + d) + t.get(r_rank)) as usize;
                t.store(&kout, pos, t.load(&kin, i));
                t.store(&vout, pos, t.load(&vin, i));
            });
            blk.sync_threads();
        }
    })
    .expect("radix launch shape is valid");
}
