//! What a DACRT trace is made of, one floor below the recursion's files: the caster
//! and its tunables, the per-call [`Trace`] (rays renumbered in coherence order, their
//! keys, packets and counters), the constants the steps share and the branch-free
//! partition. `mod.rs` and the step files (`top`, `planes`, `partition`, `leaf`,
//! `fork`) build on it.

use super::packets::Packets;
use crate::cast::caster::Triangles;
use crate::geometry::Ray;
use crate::geometry::hit_key::{self, BLOCKED, NONE};
use crate::geometry::lanes::RaySlab;
use crate::geometry::packet_lanes::Width;
use crate::geometry::{Aabb, batch_slack, cull_distance};
use glam::Vec3;
use rayon::prelude::*;
use std::sync::Mutex;
use std::sync::atomic::{AtomicU64, AtomicUsize, Ordering::Relaxed};

/// Tunables of [`Dacrt`]. The defaults were chosen by measurement (see
/// `docs/history/dacrt-runs.md`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DacrtParams {
    /// A node with at most this many rays is solved by brute force.
    pub leaf_rays: usize,
    /// A node with at most this many triangles is solved by brute force.
    pub leaf_triangles: usize,
    /// Recursion depth cap.
    pub max_depth: u32,
    /// Nodes with at least this many triangles split by binned SAH on a subsample
    /// (`usize::MAX`: spatial median everywhere).
    pub sah_min_triangles: usize,
    /// Smallest ray group traced on its own when several threads run; a group also
    /// carries at least a quarter as many rays as a shared-top cell has triangles (so
    /// 1,024 for cells of 4,096, and this floor on small scenes).
    pub min_group_rays: usize,
    /// The shared top levels stop splitting at cells of at most this many triangles
    /// (0: no shared top; every group starts from the root).
    pub top_cell_triangles: usize,
    /// Ray groups per thread (load balance) for a batch whose rays share one origin;
    /// 0 traces every batch as one group.
    pub groups_per_thread: usize,
    /// For a batch from many origins, when several threads run: one ray group per
    /// thread, and a node with at least this many rays hands its far child to rayon as
    /// a task (`fork.rs`), run after the near child on the same thread or at once by a
    /// thread that would otherwise idle (0: such batches are grouped like the others).
    pub fork_min_rays: usize,
    /// Rays per packet for packet filtering (rounded up to a power of two; 0: every
    /// ray is tested on its own). Off by default: on the 16-core machine it lost on the
    /// dragon and gained on the bunny (`docs/history/dacrt-runs.md`, run K).
    pub packet_rays: usize,
    /// Wide SIMD lanes for the ray partitions and the leaves (`lanes.rs`): sixteen on
    /// AVX-512, eight on AVX2, whichever the CPU has, found at run time; false, or a
    /// CPU with neither, runs the SSE steps. The answers are the same either way.
    pub lanes: bool,
    /// Lay each shared-top cell's triangles out side by side for the call (their boxes
    /// and corners copied in cell order, [`Soup`]), so that the partitions and leaves
    /// below a cell read a few hundred kilobytes in ascending order instead of
    /// gathering from the whole scene by id. The answers are the same either way.
    pub cell_layout: bool,
    /// Nodes with at least this many ray–triangle pairs choose their plane by pricing
    /// candidates on samples of their rays and triangles (`sampled.rs`); 0: never.
    /// The answers are the same either way.
    pub sampled_min_pairs: u64,
}

impl Default for DacrtParams {
    fn default() -> Self {
        DacrtParams {
            leaf_rays: 12,
            leaf_triangles: 12,
            max_depth: 48,
            sah_min_triangles: 10_000,
            min_group_rays: 128,
            top_cell_triangles: 4096,
            groups_per_thread: 8,
            fork_min_rays: 4096,
            packet_rays: 0,
            lanes: true,
            cell_layout: true,
            sampled_min_pairs: 1 << 20,
        }
    }
}

impl DacrtParams {
    /// One recursion over the whole batch, whatever the thread count.
    pub fn serial() -> Self {
        DacrtParams { groups_per_thread: 0, fork_min_rays: 0, ..Default::default() }
    }
}

/// Divide-and-conquer ray tracing over a triangle soup (see the module docs).
pub struct Dacrt {
    pub(super) tris: Triangles,
    pub(super) boxes: Vec<Aabb>,
    pub(super) scene_box: Aabb,
    /// The largest magnitude of the triangles' finite coordinates (for
    /// `geometry::hit_slack`).
    pub(super) magnitude: f32,
    /// Tunables; may be changed between calls.
    pub params: DacrtParams,
    /// The last call's seconds by stage ([`RayCaster::phase_seconds`]).
    pub(super) phases: Mutex<Vec<(&'static str, f64)>>,
}

/// The triangles one recursion works on, by slot: the triangle in slot `k` has the box
/// `boxes[k]`, the corners `corners[k]` and the scene id `ids[k]` (`k` itself when
/// `ids` is `None`). The caster's own arrays are the soup whose slots are the scene's
/// ids ([`Dacrt::soup`]); a shared-top cell laid out for the call
/// ([`DacrtParams::cell_layout`]) is one whose slots are its own. Slots are in the
/// order of the scene's ids either way, so lists, tests and ties do not change.
#[derive(Clone, Copy)]
pub(super) struct Soup<'a> {
    pub(super) boxes: &'a [Aabb],
    pub(super) corners: &'a [[Vec3; 3]],
    pub(super) ids: Option<&'a [u32]>,
}

impl Soup<'_> {
    /// The scene id of the triangle in `slot` (what hit keys carry).
    #[inline(always)]
    pub(super) fn id(&self, slot: u32) -> u32 {
        match self.ids {
            Some(ids) => ids[slot as usize],
            None => slot,
        }
    }
}

impl Dacrt {
    /// The caster's own triangles as a soup: slot = scene id.
    pub(super) fn soup(&self) -> Soup<'_> {
        Soup { boxes: &self.boxes, corners: &self.tris, ids: None }
    }
}

/// A node with few rays is a leaf only while it has at most this many times
/// `leaf_rays · leaf_triangles` ray–triangle pairs.
const LEAF_PAIRS_FACTOR: u64 = 4;

/// The most ray–triangle pairs a node with few rays may hold and still be a leaf:
/// DACRT's leaf rule, which PDACRT's `classify_children` and its CUDA twin share.
pub(crate) fn leaf_pairs(leaf_rays: u64, leaf_triangles: u64) -> u64 {
    LEAF_PAIRS_FACTOR * leaf_rays * leaf_triangles
}
/// At most `n` elements of `list`, spread evenly over it (every `⌈len / n⌉`-th): the
/// samples the plane choices and the near-child test read.
pub(super) fn spread<T>(list: &[T], n: usize) -> impl Iterator<Item = &T> {
    list.iter().step_by(list.len().div_ceil(n).max(1))
}

/// Rays whose directions choose which child is near (`Trace::toward_hi`).
pub(super) const NEAR_SAMPLES: usize = 32;
/// SAH bins per axis, and triangles sampled per SAH decision.
pub(super) const SAH_BINS: usize = 16;
pub(super) const SAH_SAMPLES: usize = 2048;

/// What one trace call shares between its recursive steps. Its rays are the batch's
/// valid rays renumbered in coherence order: a ray's id indexes `rays`, `slabs` and
/// `keys`.
pub(super) struct Trace {
    pub(super) rays: Vec<Ray>,
    /// Each ray packed for the box tests of the ray partitions.
    pub(super) slabs: Vec<RaySlab>,
    pub(super) keys: Vec<AtomicU64>,
    pub(super) packets: Option<Packets>,
    pub(super) any_hit: bool,
    pub(super) bytes: AtomicUsize,
    pub(super) peak: AtomicUsize,
    pub(super) tests: AtomicU64,
    /// The ray groups' and forked tasks' summed busy time (`fork.rs` keeps it exact).
    pub(super) busy_ns: AtomicU64,
    /// Nodes with at least this many rays fork their far child (0: never).
    pub(super) fork_min_rays: usize,
    /// How far every box is grown in the ray tests: `geometry::hit_slack` for the
    /// scene and the batch's largest origin coordinate, so that no hit the watertight
    /// test reports just off a triangle is culled.
    pub(super) grow: f32,
    /// The wide lanes the partitions (without packets) and leaves run on, if any.
    pub(super) lanes: Option<Width>,
}

impl Trace {
    /// A trace of `rays` (already renumbered) with no hits yet, given their records
    /// (`slabs[i]` is `RaySlab::new(&rays[i])`: the caller makes both in one pass).
    pub(super) fn new(
        rays: Vec<Ray>,
        slabs: Vec<RaySlab>,
        any_hit: bool,
        packet_rays: usize,
        fork_min_rays: usize,
        magnitude: f32,
        lanes: bool,
    ) -> Trace {
        debug_assert_eq!(rays.len(), slabs.len());
        let grow = batch_slack(magnitude, rays.par_iter().map(|r| r.origin));
        let keys: Vec<AtomicU64> = (0..rays.len()).into_par_iter().map(|_| AtomicU64::new(NONE)).collect();
        let packets = Packets::new(&rays, &slabs, packet_rays);
        let lanes = if lanes { Width::widest() } else { None };
        Trace {
            rays,
            slabs,
            keys,
            packets,
            any_hit,
            bytes: AtomicUsize::new(0),
            peak: AtomicUsize::new(0),
            tests: AtomicU64::new(0),
            busy_ns: AtomicU64::new(0),
            fork_min_rays,
            grow,
            lanes,
        }
    }

    /// A trace with no rays (the shared top levels choose planes from triangles alone).
    pub(super) fn empty() -> Trace {
        Trace::new(Vec::new(), Vec::new(), false, 0, 0, 0.0, false)
    }

    pub(super) fn alloc(&self, bytes: usize) {
        let now = self.bytes.fetch_add(bytes, Relaxed) + bytes;
        self.peak.fetch_max(now, Relaxed);
    }
    pub(super) fn free(&self, bytes: usize) {
        self.bytes.fetch_sub(bytes, Relaxed);
    }

    /// The ray's interval end: its closest hit so far, or its own `t_max`.
    #[inline]
    pub(super) fn t_far(&self, id: u32) -> f32 {
        let k = self.keys[id as usize].load(Relaxed);
        if k == NONE { self.rays[id as usize].t_max } else { hit_key::t_of(k).min(self.rays[id as usize].t_max) }
    }

    /// Whether most of the rays travel toward `+axis`, judged on at most
    /// [`NEAR_SAMPLES`] of them spread over the list (the near child is visited first;
    /// the choice changes the order of work, never the hits).
    pub(super) fn toward_hi(&self, rays: &[u32], axis: usize) -> bool {
        let sum: f32 = spread(rays, NEAR_SAMPLES).map(|&r| self.rays[r as usize].dir[axis].signum()).sum();
        sum >= 0.0
    }

    /// A node's box as the ray tests see it: grown by [`Trace::grow`]. Callers grow a
    /// box once and test every ray of the node against it.
    #[inline]
    pub(super) fn grown(&self, b: &Aabb) -> Aabb {
        b.grown(self.grow)
    }

    /// Whether ray `id`, cut at its best hit so far, enters `grown` (a box from
    /// [`Trace::grown`]).
    #[inline]
    pub(super) fn enters(&self, id: u32, grown: &Aabb) -> bool {
        let k = self.keys[id as usize].load(Relaxed);
        if self.any_hit && k == BLOCKED {
            return false;
        }
        let s = &self.slabs[id as usize];
        s.enters(grown, cull_distance(if k == NONE { s.t_max() } else { hit_key::t_of(k).min(s.t_max()) }))
    }
}

/// A stable partition of `ids` in place: `split` moves the kept ids to the front of
/// `ids` and the others to the front of `aside` (each in its order, with [`place`] or
/// a wide loop) and returns both counts; the ids set aside then follow the kept ones.
/// Returns how many are kept. `aside` is grown to room for every id.
pub(super) fn stable_partition(
    ids: &mut [u32],
    aside: &mut Vec<u32>,
    split: impl FnOnce(&mut [u32], &mut [u32]) -> (usize, usize),
) -> usize {
    if aside.len() < ids.len() {
        aside.resize(ids.len(), 0);
    }
    let (n, m) = split(ids, aside);
    ids[n..].copy_from_slice(&aside[..m]);
    n
}

/// One step of a stable partition: `id` goes to the front of `ids` (at `n`) when
/// `keep`, else to `aside` (at `m`). Both writes happen and only the counts depend on
/// the answer (no branch on it: the answers are as good as random). `n` never passes
/// the element being read, so a partition in place reads every element before it is
/// overwritten; the caller copies `aside[..m]` after the kept ones.
#[inline(always)]
pub(super) fn place(ids: &mut [u32], aside: &mut [u32], id: u32, keep: bool, n: &mut usize, m: &mut usize) {
    ids[*n] = id;
    aside[*m] = id;
    *n += keep as usize;
    *m += !keep as usize;
}
