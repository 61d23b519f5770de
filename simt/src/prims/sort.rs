//! Stable LSD radix sort by key, 8 bits a pass, as CUB's onesweep sort runs it (Adinets
//! and Merrill, "Onesweep: A Faster Least Significant Digit Radix Sort for GPUs", 2022):
//! one launch counts every pass's digits, one scans the counts of each pass, and each
//! pass is one launch that ranks a tile's keys by digit, learns how many keys of each
//! digit the tiles before it hold by a decoupled look-back ([`super::look_back`], one
//! per digit), and scatters the tile. Ranking is stable: each warp ranks its lanes by
//! digit with ballots (the `match_any` idiom) and the block's warps are ordered by a
//! per-digit scan in shared memory.
//!
//! Keys that carry a segment id in their high bits sort segment by segment, which is
//! how PDACRT runs a segmented sort; [`sort_by_key_bits`] limits the passes to the bits
//! in use.

use super::look_back::TileStatus;
pub use super::radix_key::RadixKey;
use super::scan::warp_exclusive_sum;
use super::{BLOCK, ITEMS, TILE};
use crate::device::{Device, LaunchConfig};
use crate::memory::{DeviceBuffer, DeviceCopy};

const RADIX: usize = 256;
/// Threads of a onesweep block and keys a thread ranks: CUB's onesweep shape on sm_90
/// for 4-byte keys (its launches in the GPU BVH's builds: 384 threads, 6,528 keys a
/// tile), so the emulated passes have the GPU's tiles.
const SWEEP_THREADS: u32 = 384;
const SWEEP_ITEMS: usize = 17;
const SWEEP_TILE: usize = SWEEP_THREADS as usize * SWEEP_ITEMS;
const SWEEP_WARPS: usize = SWEEP_THREADS as usize / 32;
/// Warp instructions of CUB's ranking per key a lane ranks that the emulated ranking
/// does not count as operations of its own: the bit tests and mask updates around its
/// eight ballots, the digit's extraction, the rank's population count and the shared
/// addresses (declared work, region `rank`). CUB's onesweep kernel for 4-byte keys is
/// unrolled and every warp runs all of it: 1,558 warp instructions a warp (Nsight's
/// per-instruction counts, `docs/measured/ncu-executed-sass-cub-onesweep-bunny-h100.csv.gz`),
/// against 705 the emulated pass counts without this; (1,558 − 705) / 17 keys.
const RANK_KEY_INSTRUCTIONS: u32 = 50;

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
    let passes: Vec<(u32, u32)> =
        (begin_bit..end_bit).step_by(8).map(|shift| (shift, (end_bit - shift).min(8))).collect();
    let offsets = digit_offsets(dev, keys, &passes);
    let mut keys_tmp = dev.alloc_vec(keys.as_slice().to_vec());
    let mut vals_tmp = dev.alloc_vec(values.as_slice().to_vec());
    for (p, &(shift, width)) in passes.iter().enumerate() {
        onesweep_pass(dev, keys, values, &mut keys_tmp, &mut vals_tmp, &offsets, p, shift, width);
        std::mem::swap(keys, &mut keys_tmp);
        std::mem::swap(values, &mut vals_tmp);
    }
}

/// Where each digit's keys start in each pass's output: every pass's digit counts in
/// one launch (CUB's histogram kernel), then an exclusive scan of each pass's counts,
/// one block a pass (CUB's exclusive-sum kernel). `RADIX` values a pass.
fn digit_offsets<K: RadixKey>(dev: &Device, keys: &DeviceBuffer<K>, passes: &[(u32, u32)]) -> DeviceBuffer<u32> {
    let n = keys.len();
    let mut counts = dev.alloc::<u32>(passes.len() * RADIX);
    {
        let (kin, cnt) = (keys.view(), counts.view_mut());
        let shared = passes.len() * RADIX * 4;
        let cfg = LaunchConfig {
            grid: n.div_ceil(TILE) as u32,
            block: BLOCK,
            shared_bytes: shared,
            regions: &[],
            registers: 0,
            code_bytes: 0,
        };
        dev.launch("simt::radix_histogram", cfg, |blk| {
            let base = blk.block_idx() as usize * TILE;
            let hist = blk.shared::<u32>(passes.len() * RADIX);
            blk.for_each_thread(|t| {
                let mut mine = [K::default(); ITEMS];
                {
                    let _together = t.loads_together();
                    for (k, key) in mine.iter_mut().enumerate() {
                        let i = base + k * BLOCK as usize + t.thread_idx() as usize;
                        if i < n {
                            *key = t.load(&kin, i);
                        }
                    }
                }
                for (k, key) in mine.iter().enumerate() {
                    if base + k * BLOCK as usize + (t.thread_idx() as usize) < n {
                        for (p, &(shift, width)) in passes.iter().enumerate() {
                            t.atomic_add_shared(hist, p * RADIX + key.digit(shift, width) as usize, 1);
                        }
                    }
                }
            });
            blk.sync_threads();
            blk.for_each_thread(|t| {
                let d = t.thread_idx() as usize;
                for p in 0..passes.len() {
                    let c = t.load_shared(hist, p * RADIX + d);
                    if c > 0 {
                        // The old value is not used: a `RED`, not waited for.
                        t.red_add(&cnt, p * RADIX + d, c);
                    }
                }
            });
        })
        .expect("radix launch shape is valid");
    }
    let mut offsets = dev.alloc::<u32>(passes.len() * RADIX);
    let (cnt, offs) = (counts.view(), offsets.view_mut());
    let cfg = LaunchConfig {
        grid: passes.len() as u32,
        block: RADIX as u32,
        shared_bytes: 32 * 4,
        regions: &[],
        registers: 0,
        code_bytes: 0,
    };
    dev.launch("simt::radix_exclusive_sum", cfg, |blk| {
        let p = blk.block_idx() as usize;
        let warp_sums = blk.shared::<u32>(32);
        let r_exclusive = blk.local::<u32>(0);
        blk.for_each_warp(|w| {
            let first = p * RADIX + w.warp_idx() as usize * 32;
            let mut v = [0u32; 32];
            w.for_each_lane(|t| v[t.lane_id() as usize] = t.load(&cnt, first + t.lane_id() as usize));
            warp_exclusive_sum(w, v, r_exclusive, warp_sums);
        });
        blk.sync_threads();
        blk.for_each_thread(|t| {
            let d = t.thread_idx() as usize;
            let before: u32 = (0..t.warp_id() as usize).map(|w| t.load_shared(warp_sums, w)).sum();
            t.store(&offs, p * RADIX + d, before + t.get(r_exclusive));
        });
    })
    .expect("radix launch shape is valid");
    offsets
}

/// One pass of the sort on digit `shift..shift + width` (pass `pass` of `offsets`).
#[allow(clippy::too_many_arguments)]
fn onesweep_pass<K: RadixKey, V: DeviceCopy>(
    dev: &Device,
    keys_in: &DeviceBuffer<K>,
    vals_in: &DeviceBuffer<V>,
    keys_out: &mut DeviceBuffer<K>,
    vals_out: &mut DeviceBuffer<V>,
    offsets: &DeviceBuffer<u32>,
    pass: usize,
    shift: u32,
    width: u32,
) {
    let n = keys_in.len();
    let grid = n.div_ceil(SWEEP_TILE);
    let mut status = TileStatus::new(dev, grid, RADIX, 0u32, None);
    let status = status.views();
    let (kin, vin, offs) = (keys_in.view(), vals_in.view(), offsets.view());
    let (kout, vout) = (keys_out.view_mut(), vals_out.view_mut());
    let shared = (2 * RADIX + 2 * SWEEP_WARPS * RADIX) * 4;
    let cfg = LaunchConfig {
        grid: grid as u32,
        block: SWEEP_THREADS,
        shared_bytes: shared,
        regions: &["rank"],
        registers: 0,
        code_bytes: 0,
    };
    dev.launch_in_order("simt::radix_onesweep", cfg, |blk| {
        let b = blk.block_idx() as usize;
        let base = b * SWEEP_TILE;
        let run = blk.shared::<u32>(RADIX);
        let start = blk.shared::<u32>(RADIX);
        let warp_cnt = blk.shared::<u32>(SWEEP_WARPS * RADIX);
        let warp_base = blk.shared::<u32>(SWEEP_WARPS * RADIX);
        let r_keys = blk.local::<[K; SWEEP_ITEMS]>([K::default(); SWEEP_ITEMS]);
        let r_ranks = blk.local::<[u32; SWEEP_ITEMS]>([0; SWEEP_ITEMS]);
        // The tile's keys, striped, into registers.
        blk.for_each_thread(|t| {
            let _together = t.loads_together();
            let mut mine = [K::default(); SWEEP_ITEMS];
            for (k, key) in mine.iter_mut().enumerate() {
                let i = base + k * SWEEP_THREADS as usize + t.thread_idx() as usize;
                if i < n {
                    *key = t.load(&kin, i);
                }
            }
            t.set(r_keys, mine);
        });
        // Rank the tile's keys by digit, a round of SWEEP_THREADS keys at a time, in index order
        // (stable); `run` counts each digit's keys in the rounds before.
        for k in 0..SWEEP_ITEMS {
            let round = base + k * SWEEP_THREADS as usize;
            blk.for_each_warp(|w| {
                let first = round + w.warp_idx() as usize * 32;
                let mut digit = [0u32; 32];
                let mut valid = [false; 32];
                w.for_each_lane(|t| {
                    let l = t.lane_id() as usize;
                    // Every warp runs CUB's unrolled ranking, its lanes past the end too.
                    t.work(0, 0, RANK_KEY_INSTRUCTIONS);
                    if first + l < n {
                        digit[l] = t.get(r_keys)[k].digit(shift, width);
                        valid[l] = true;
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
                    if !valid[l] {
                        return;
                    }
                    let below = peers[l] & ((1u32 << l) - 1);
                    let mut ranks = t.get(r_ranks);
                    ranks[k] = below.count_ones();
                    t.set(r_ranks, ranks);
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
                if d >= RADIX {
                    return;
                }
                let mut acc = t.load_shared(run, d);
                for w in 0..SWEEP_WARPS {
                    let c = t.load_shared(warp_cnt, w * RADIX + d);
                    t.store_shared(warp_base, w * RADIX + d, acc);
                    t.store_shared(warp_cnt, w * RADIX + d, 0);
                    acc += c;
                }
                t.store_shared(run, d, acc);
            });
            blk.sync_threads();
            // Each key's rank among the tile's keys of its digit.
            blk.for_each_thread(|t| {
                if round + (t.thread_idx() as usize) < n {
                    let d = t.get(r_keys)[k].digit(shift, width) as usize;
                    let mut ranks = t.get(r_ranks);
                    ranks[k] += t.load_shared(warp_base, t.warp_id() as usize * RADIX + d);
                    t.set(r_ranks, ranks);
                }
            });
            blk.sync_threads();
        }
        // Thread d's look-back: the keys of digit d in the tiles before this one.
        blk.for_each_thread(|t| {
            let d = t.thread_idx() as usize;
            if d >= RADIX {
                return;
            }
            let before = status.look_back(t, b, d, t.load_shared(run, d), 0, |a, c| a + c);
            t.store_shared(start, d, t.load(&offs, pass * RADIX + d) + before);
        });
        blk.sync_threads();
        blk.for_each_thread(|t| {
            let (mine, ranks) = (t.get(r_keys), t.get(r_ranks));
            let mut vals = [None; SWEEP_ITEMS];
            {
                let _together = t.loads_together();
                for (k, v) in vals.iter_mut().enumerate() {
                    let i = base + k * SWEEP_THREADS as usize + t.thread_idx() as usize;
                    if i < n {
                        *v = Some(t.load(&vin, i));
                    }
                }
            }
            for (k, v) in vals.into_iter().enumerate() {
                if let Some(v) = v {
                    let d = mine[k].digit(shift, width) as usize;
                    let pos = (t.load_shared(start, d) + ranks[k]) as usize;
                    t.store(&kout, pos, mine[k]);
                    t.store(&vout, pos, v);
                }
            }
        });
    })
    .expect("radix launch shape is valid");
}
