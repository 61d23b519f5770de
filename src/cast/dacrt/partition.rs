//! The packet-filtered steps of a DACRT trace: the batch's valid rays in coherence
//! order (`Dacrt::valid_rays`) and the stable ray partition that rejects a packet's run
//! of rays with one test (`Trace::partition_rays`), over the packet bounds of
//! `packets.rs`.

use super::packets::{MIN_RUN, coherence_key};
use super::state::{Dacrt, Trace};
use crate::geometry::{Aabb, Ray, hit_slack, inv_dir};
use rayon::prelude::*;

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
                    if r.is_valid() && grown.intersect(r.origin, inv_dir(r.dir), r.t_min, r.t_max).is_some() {
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
    /// enter. A run of one packet's rays is rejected at once when the packet misses.
    pub(super) fn partition_rays(&self, ids: &mut [u32], b: &Aabb, rejected: &mut Vec<u32>) -> usize {
        // Kept rays move down to `n` (never past the ray being read); rejected ones go
        // to `rejected[m]`, which holds room for every ray. Both writes happen for
        // every ray and only the counts depend on the test: no branch on its answer.
        if rejected.len() < ids.len() {
            rejected.resize(ids.len(), 0);
        }
        let b = &self.grown(b);
        let (mut n, mut m) = (0, 0);
        let keep = |ids: &mut [u32], rejected: &mut [u32], k: usize, n: &mut usize, m: &mut usize| {
            let r = ids[k];
            let enters = self.enters(r, b);
            ids[*n] = r;
            rejected[*m] = r;
            *n += enters as usize;
            *m += !enters as usize;
        };
        match &self.packets {
            None => (0..ids.len()).for_each(|k| keep(ids, rejected, k, &mut n, &mut m)),
            Some(packets) => {
                let mut i = 0;
                while i < ids.len() {
                    let p = packets.of(ids[i]);
                    let mut j = i + 1;
                    while j < ids.len() && packets.of(ids[j]) == p {
                        j += 1;
                    }
                    if j - i >= MIN_RUN && packets.misses(p, b) {
                        for k in i..j {
                            let r = ids[k];
                            rejected[m] = r;
                            m += 1;
                        }
                    } else {
                        (i..j).for_each(|k| keep(ids, rejected, k, &mut n, &mut m));
                    }
                    i = j;
                }
            }
        }
        ids[n..].copy_from_slice(&rejected[..m]);
        n
    }
}
