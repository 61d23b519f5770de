//! DACRT's ray steps: the batch's valid rays in coherence order (`Dacrt::valid_rays`),
//! and the stable ray partition (`Trace::partition_rays`): on the widest SIMD lanes
//! the CPU has (sixteen rays at once on AVX-512, eight on AVX2, their records
//! transposed in registers; `partition_in`), one ray at a time on SSE, or with packet
//! filtering, which rejects a packet's run of rays with one test over the bounds of
//! `packets.rs`. Every way moves the same rays to the same places.

use super::packets::{MIN_RUN, Packets, coherence_key};
use super::state::{Dacrt, Trace, place, stable_partition};
use crate::geometry::hit_key;
use crate::geometry::lane_compact::compact;
use crate::geometry::lane_ops::{first_lanes, slab, splat3};
use crate::geometry::lanes::RaySlab;
use crate::geometry::packet_lanes::{F8, F16, Packed, Width};
use crate::geometry::{Aabb, Ray, cull_distance_lanes, hit_slack};
use rayon::prelude::*;
use std::sync::atomic::Ordering::Relaxed;

impl Dacrt {
    /// The ids of the rays that are valid and meet the scene's box, ascending, with
    /// their coherence keys, and the key bits that differ between them: each chunk of
    /// the batch keeps its own in one pass, then the chunks' lists are copied side by
    /// side into lists of the exact length.
    pub(super) fn valid_rays(&self, rays: &[Ray]) -> (Vec<u32>, Vec<u64>, u64) {
        const CHUNK: usize = 1 << 14;
        let scene_box = self.scene_box;
        // Each chunk's ids and keys, and the OR and AND of its keys.
        let kept: Vec<(Vec<u32>, Vec<u64>, u64, u64)> = rays
            .par_chunks(CHUNK)
            .enumerate()
            .map(|(c, chunk)| {
                let (mut ids, mut keys) = (Vec::with_capacity(chunk.len()), Vec::with_capacity(chunk.len()));
                let (mut or, mut and) = (0, u64::MAX);
                for (i, r) in chunk.iter().enumerate() {
                    let grown = scene_box.grown(hit_slack(self.magnitude, r.origin.abs().max_element()));
                    if r.is_valid() && RaySlab::new(r).enters(&grown, r.t_max) {
                        let key = coherence_key(r, &scene_box);
                        (or, and) = (or | key, and & key);
                        ids.push((c * CHUNK + i) as u32);
                        keys.push(key);
                    }
                }
                (ids, keys, or, and)
            })
            .collect();
        let (or, and) = kept.iter().fold((0, u64::MAX), |(o, a), k| (o | k.2, a & k.3));
        let m = kept.iter().map(|k| k.0.len()).sum();
        let (mut ids, mut keys) = (vec![0u32; m], vec![0u64; m]);
        let (mut id_rest, mut key_rest) = (&mut ids[..], &mut keys[..]);
        let mut slots = Vec::with_capacity(kept.len());
        for k in &kept {
            let (a, ta) = id_rest.split_at_mut(k.0.len());
            let (b, tb) = key_rest.split_at_mut(k.1.len());
            slots.push((a, b));
            (id_rest, key_rest) = (ta, tb);
        }
        slots.into_par_iter().zip(kept).for_each(|((a, b), k)| {
            a.copy_from_slice(&k.0);
            b.copy_from_slice(&k.1);
        });
        (ids, keys, or ^ and)
    }

    /// The ids of `order` sorted by their rays' coherence keys (`keys`, one per id, of
    /// which the bits `varying` differ),
    /// ties by id (so the order is deterministic). Key and id share one word: the key's
    /// 32 bits from its highest bit that differs between rays (primary rays share their
    /// origin bits).
    pub(super) fn coherence_order(&self, order: Vec<u32>, keys: Vec<u64>, varying: u64) -> Vec<u32> {
        let shift = (64 - varying.leading_zeros()).saturating_sub(32);
        // A stable radix sort (simt's, on its CPU backend) of the 32 bits: the ids are
        // in ascending order, so ties stay ordered by id.
        let dev = simt::Device::default();
        let mut coarse = dev.alloc_vec(keys.par_iter().map(|&k| (k >> shift) as u32).collect::<Vec<u32>>());
        drop(keys);
        let mut ids = dev.alloc_vec(order);
        simt::sort_by_key(&dev, &mut coarse, &mut ids);
        ids.into_vec()
    }
}

impl Trace {
    /// Moves the rays of `ids` that enter `b` to the front, keeping the order of both
    /// parts (so ids stay ascending and a packet's rays adjacent); returns how many
    /// enter. Without packets the rays are tested on the trace's lanes (sixteen or eight
    /// at a time on AVX-512 or AVX2, one at a time on SSE); with them, a run of one
    /// packet's rays is rejected at once when the packet misses.
    pub(super) fn partition_rays(&self, ids: &mut [u32], b: &Aabb, rejected: &mut Vec<u32>) -> usize {
        // Kept rays move down to `n` (never past the ray being read); rejected ones go
        // to `rejected[m]`.
        let b = &self.grown(b);
        stable_partition(ids, rejected, |ids, rejected| match (&self.packets, self.lanes) {
            (None, Some(width)) => self.partition_wide(width, ids, b, rejected),
            (None, None) => {
                let (mut n, mut m) = (0, 0);
                for k in 0..ids.len() {
                    let r = ids[k];
                    place(ids, rejected, r, self.enters(r, b), &mut n, &mut m);
                }
                (n, m)
            }
            (Some(packets), _) => self.partition_packets(packets, ids, b, rejected),
        })
    }

    /// The partition's loop with packet filtering: a run of at least [`MIN_RUN`] of one
    /// packet's rays is rejected with one test when the packet misses `b`.
    fn partition_packets(&self, packets: &Packets, ids: &mut [u32], b: &Aabb, rejected: &mut [u32]) -> (usize, usize) {
        let (mut n, mut m, mut i) = (0, 0, 0);
        while i < ids.len() {
            let p = packets.of(ids[i]);
            let mut j = i + 1;
            while j < ids.len() && packets.of(ids[j]) == p {
                j += 1;
            }
            let whole = j - i >= MIN_RUN && packets.misses(p, b);
            for k in i..j {
                let r = ids[k];
                place(ids, rejected, r, !whole && self.enters(r, b), &mut n, &mut m);
            }
            i = j;
        }
        (n, m)
    }

    /// The partition's loop on `width`'s lanes (without packets).
    fn partition_wide(&self, width: Width, ids: &mut [u32], grown: &Aabb, rejected: &mut [u32]) -> (usize, usize) {
        type Loop = unsafe fn(&Trace, &mut [u32], &Aabb, &mut [u32]) -> (usize, usize);
        let wide = width.pick::<Loop>([partition_avx512, partition_avx2]);
        // SAFETY: the loop is compiled for the width's extension, which the CPU has
        // (`pick` checked).
        unsafe { wide(self, ids, grown, rejected) }
    }
}

#[target_feature(enable = "avx512f")]
fn partition_avx512(tr: &Trace, ids: &mut [u32], grown: &Aabb, rejected: &mut [u32]) -> (usize, usize) {
    partition_in::<F16>(tr, ids, grown, rejected)
}

#[target_feature(enable = "avx2")]
fn partition_avx2(tr: &Trace, ids: &mut [u32], grown: &Aabb, rejected: &mut [u32]) -> (usize, usize) {
    partition_in::<F8>(tr, ids, grown, rejected)
}

/// The rays of `ids` against `grown`, `L::WIDTH` at a time: each lane loads its ray's
/// record from `Trace::slabs` (`Packed::records`) and its interval's end from its key
/// (`Packed::from_fn`, set from registers), and the slab test
/// of `geometry::lane_ops` answers as `RaySlab::enters` does, bit for bit (a lane whose
/// ray has a zero direction component takes `Trace::enters` itself); the list's last
/// rays, fewer than a block, are tested one at a time.
#[inline(always)]
fn partition_in<L: Packed>(tr: &Trace, ids: &mut [u32], grown: &Aabb, rejected: &mut [u32]) -> (usize, usize) {
    let w = L::WIDTH;
    let floats = RaySlab::floats(&tr.slabs);
    let (lo, hi, zero) = (splat3::<L>(grown.min), splat3::<L>(grown.max), L::splat(0.0));
    let inf = L::splat(f32::INFINITY);
    let (mut n, mut m, mut i) = (0, 0, 0);
    let mut own = [0u32; 32];
    while i + w <= ids.len() {
        let block = &ids[i..i + w];
        // The records, a ray a lane (`RaySlab::floats`: origin, `t_min`, reciprocal
        // direction, `t_max`).
        let [ox, oy, oz, t_min, ix, iy, iz, t_max] = L::records::<8>(floats, block);
        let (o, inv) = ([ox, oy, oz], [ix, iy, iz]);
        own[..w].copy_from_slice(block);
        // The key's distance: NaN for no hit yet (`NONE`'s bits), whose minimum with
        // `t_max` below is `t_max` (`minps` returns its second operand for a NaN).
        let t_key = L::from_fn(|k| hit_key::t_of(tr.keys[own[k] as usize].load(Relaxed)));
        let t_far = cull_distance_lanes(t_key.min(t_max));
        // Any-hit: a blocked ray's key is 0 (the only keys are `NONE` and `BLOCKED`).
        let blocked = if tr.any_hit { L::bits(t_key.eq(zero)) } else { 0 };
        let finite = L::bits(inv[0].abs().lt(inf) & inv[1].abs().lt(inf) & inv[2].abs().lt(inf));
        let mut enters = slab(lo, hi, o, inv, zero, t_min, t_far).0 & finite & !blocked;
        // A zero direction component: the box test by position, as the SSE step.
        let mut odd = !finite & !blocked & first_lanes(w);
        while odd != 0 {
            let k = odd.trailing_zeros();
            odd &= odd - 1;
            enters |= (tr.enters(own[k as usize], grown) as u32) << k;
        }
        // As `place` a ray at a time: the entering rays to the front, the others aside.
        n += compact::<L>(&own[..w], enters, ids, n);
        m += compact::<L>(&own[..w], !enters & first_lanes(w), rejected, m);
        i += w;
    }
    for k in i..ids.len() {
        let r = ids[k];
        place(ids, rejected, r, tr.enters(r, grown), &mut n, &mut m);
    }
    (n, m)
}

#[cfg(test)]
mod tests {
    use super::super::cases::{case, widths};
    use super::*;
    use crate::geometry::hit_key::pack;
    use crate::sampling::Rng;
    use glam::Vec3;

    /// The wide partition moves the same rays to the same places as the SSE one.
    #[test]
    fn wide_ray_partitions_answer_as_the_sse_one() {
        let (mut kept, mut total) = (0, 0);
        for width in widths() {
            for trial in 0..3_000u64 {
                let any_hit = trial % 2 == 1;
                let (_, mut wide) = case(&mut Rng::for_sample(21, trial, 0), any_hit, true);
                wide.lanes = Some(width);
                let (_, sse) = case(&mut Rng::for_sample(21, trial, 0), any_hit, false);
                let mut rng = Rng::for_sample(22, trial, 0);
                let mut c = || (rng.uniform() * 8.0).floor() * 0.5 - 2.0;
                let (a, b) = (Vec3::new(c(), c(), c()), Vec3::new(c(), c(), c()) + 0.25);
                let box_ = Aabb { min: a.min(b), max: a.max(b) };
                let grown = sse.grown(&box_);
                // Some closest hits just before the box (an ulp before the entry): only
                // the cull distance's widening lets those rays in.
                for (r, ray) in sse.rays.iter().enumerate().filter(|(r, _)| !any_hit && r % 2 == 0) {
                    if let Some((near, _)) =
                        grown.intersect(ray.origin, crate::geometry::inv_dir(ray.dir), 0.0, f32::INFINITY)
                    {
                        let key = pack(near.next_down().max(0.0), r as u32);
                        wide.keys[r].store(key, Relaxed);
                        sse.keys[r].store(key, Relaxed);
                    }
                }
                // Lists of every length around a block, in a random order of ids.
                let len = (trial as usize * 7) % 200;
                let ids: Vec<u32> = (0..len as u32).map(|i| (i * 37 + trial as u32) % 200).collect();
                let (mut w_ids, mut s_ids) = (ids.clone(), ids.clone());
                let n = wide.partition_rays(&mut w_ids, &box_, &mut Vec::new());
                let sn = sse.partition_rays(&mut s_ids, &box_, &mut Vec::new());
                assert_eq!((n, &w_ids), (sn, &s_ids), "{width:?}, trial {trial}");
                (kept, total) = (kept + n, total + len);
            }
        }
        // Both answers are common.
        assert!(widths().is_empty() || (kept * 10 > total && kept * 10 < total * 9), "{kept} of {total}");
    }
}
