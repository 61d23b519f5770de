//! Divide-and-conquer ray tracing (Mora 2011): no stored structure. The recursion
//! carries a box, a list of ray ids and a list of triangle ids. Each step picks a split
//! plane, partitions both id lists *in place* so the child's triangles (boxes
//! overlapping the child) and rays (entering the child before their current closest
//! hit: early termination) form a prefix, and recurses into the near child first.
//! Small lists go to a brute-force leaf.
//!
//! * **Tight boxes.** A child's box is shrunk to the union of its triangles' boxes, so
//!   geometry that fills only part of a node never wastes a level, and rays that miss
//!   the geometry's box leave early.
//! * **Split choice.** Nodes with at least [`DacrtParams::sah_min_triangles`]
//!   triangles take the plane of a binned SAH over a subsample of their triangles
//!   (Mora's choice near the root). Below them, nodes holding at least
//!   [`DacrtParams::sampled_min_pairs`] ray–triangle pairs price nine candidate planes
//!   on 16 of their rays and 32 of their triangles (rays entering a child's tight box
//!   times the triangles it keeps: `sampled.rs`, after Nabata et al. 2013), so that
//!   rays crossing one part of a node stay out of the rest; smaller ones take the
//!   spatial median of the longest axis. (The conference room at 512², one thread on
//!   the 2-core VM: tests per ray 8.0 → 4.0 on primary and shadow rays, 15.5 → 10.2
//!   on mirror rays, 17.7 → 12.2 on AO, 10–19 % less time; the dragon and the bunny,
//!   whose triangles are small and even, gain no tests and pay 0–6 %.
//!   `docs/measured/dacrt-512-1t-2core-amd-avx2-cell-layout-and-ray-sampled-planes-each-off.jsonl`.) A plane that leaves
//!   some child with all of the node's rays and triangles
//!   separates nothing: then the other axes are tried, then the median of the
//!   triangle centroids. Only when no plane of any kind helps (coincident or huge
//!   triangles) does the node become a leaf. The depth is capped.
//! * **Leaf rule.** A node is solved by brute force when it has few triangles, or few
//!   rays *and* few ray–triangle pairs (a handful of rays against thousands of
//!   triangles is cheaper to keep splitting), or at the depth cap.
//! * **Cores.** The top levels' triangle partitions do not depend on the rays, so each
//!   call computes them once, down to cells of about
//!   [`DacrtParams::top_cell_triangles`] triangles: the planes are chosen on a sample
//!   (every 128th triangle for cells of 4,096, by the same rules as below), then every
//!   triangle is routed down them and gathered by cell (a counting sort: two parallel,
//!   streaming passes over the triangles' boxes). With more than one thread the
//!   batch's rays are cut into groups (in coherence order, below); each group walks
//!   the shared top levels near child first and runs its own DACRT inside the cells it
//!   reaches, serially, so early termination is kept. A batch from one origin (primary
//!   rays, rays from a point light) is cut into many groups; a batch from many origins
//!   into one per thread, whose recursions fork their far halves for idle threads to
//!   take (`fork.rs`). With one thread there is one group. Nothing is kept between
//!   calls.
//! * **Cell layout.** A group entering a cell copies the cell's boxes and corners side
//!   by side into its own buffers ([`DacrtParams::cell_layout`]; one gather), and the
//!   recursion below works on slots of that copy (`state::Soup`), so every partition
//!   and leaf reads a few hundred kilobytes in ascending order instead of gathering
//!   from the whole scene by id. Slots keep the order of the scene's ids and keys carry
//!   the scene's ids, so the lists, tests and ties are the same. (Dragon, 512², one
//!   thread on the 2-core VM: 7–11 % less time per call; the bunny and the conference
//!   room, whose cells' triangles already lie close in the scene's order, within 3 %.)
//! * **Ray order and packets.** The batch's valid rays are sorted by a coherence key (a
//!   Morton code over origin and direction) and copied in that order, so nearby rays
//!   sit together in memory, at any thread count (the conference room's AO rays at
//!   1024² on 16 threads: 3.7 s when the sorted ids indexed the batch where it lay,
//!   1.0-1.1 s copied); the ray partitions are stable, so every list stays in that
//!   order. With [`DacrtParams::packet_rays`] set, runs of one packet's rays are
//!   rejected with one interval test when the packet misses the child's box
//!   (`packets.rs` bounds the packets, `partition.rs` partitions with them).
//!
//! * **SIMD lanes.** Where the CPU has AVX-512 or AVX2 (found at run time;
//!   [`DacrtParams::lanes`]), the ray partitions test sixteen or eight rays at once
//!   against a child's box (their records loaded a ray a lane and transposed in
//!   registers), the triangle partitions sixteen or eight boxes at once, and a leaf
//!   tests a ray against sixteen or eight triangles at once; elsewhere the same steps
//!   run on SSE. Every width gives the same hits, tests and list orders.
//!
//! Files: `state.rs` is the floor (the caster, its tunables, a call's `Trace`, the
//! shared constants); this file is the recursion's driver, and `top`, `planes`,
//! `sampled`, `partition`, `leaf`, `fork` and `stages` are its steps, importing only the floor
//! (and `top` the plan and routes of `routes`, which import nothing of DACRT's).
//!
//! Every call counts its ray–triangle tests ([`CastStats::tests`]).

use super::caster::{CastStats, RayCaster, Triangles, triangles_bytes};
use crate::geometry::hit_key::{self, BLOCKED, NONE};
use crate::geometry::lanes::RaySlab;
use crate::geometry::{Aabb, Hit, Ray, RayShear, intersect_triangle, magnitude};
use crate::scene::Scene;
use packets::{ORIGIN_BITS, Packets};
use rayon::prelude::*;
use std::sync::Mutex;
use std::sync::atomic::{AtomicU64, Ordering::Relaxed};
use std::time::Instant;

#[cfg(test)]
mod cases;
mod fork;
mod leaf;
mod packets;
mod partition;
mod planes;
mod routes;
mod sampled;
mod stages;
mod state;
mod top;
use planes::{centroid_median, partition_triangles, sah_plane};
use stages::{Stages, timed};
pub(crate) use state::leaf_pairs;
pub use state::{Dacrt, DacrtParams};
use state::{Soup, Trace};
use top::Scratch;

impl Dacrt {
    /// A caster over the scene's triangles with the default parameters.
    pub fn new(scene: &Scene) -> Self {
        Self::from_triangles(scene.triangle_vertices(), DacrtParams::default())
    }

    /// A caster over a triangle list.
    pub fn from_triangles(tris: Triangles, params: DacrtParams) -> Self {
        let boxes: Vec<Aabb> = tris.par_iter().map(|t| Aabb::from_points(t)).collect();
        let scene_box = boxes.par_iter().copied().reduce(|| Aabb::EMPTY, Aabb::union);
        let magnitude = magnitude(&tris);
        Dacrt { tris, boxes, scene_box, magnitude, params, phases: Mutex::default() }
    }

    /// The same caster with other parameters.
    pub fn with_params(mut self, params: DacrtParams) -> Self {
        self.params = params;
        self
    }

    /// One node: `tris` are slots of `soup`.
    #[allow(clippy::too_many_arguments)]
    fn recurse(
        &self,
        tr: &Trace,
        soup: Soup,
        bounds: Aabb,
        rays: &mut [u32],
        tris: &mut [u32],
        spare: &mut Vec<u32>,
        depth: u32,
    ) {
        if rays.is_empty() || tris.is_empty() {
            return;
        }
        if self.is_leaf(rays.len(), tris.len(), depth) {
            return self.leaf(tr, soup, rays, tris);
        }
        let Some((axis, pos)) = self.choose_split(tr, (soup.boxes, 1), &bounds, rays, tris) else {
            return self.leaf(tr, soup, rays, tris);
        };
        let (lo, hi) = bounds.split(axis, pos);
        // Near child first, judged by the rays' mean direction along the split axis.
        let (near, far) = if tr.toward_hi(rays, axis) { (lo, hi) } else { (hi, lo) };
        if tr.forks(rays.len()) {
            return self.fork(tr, soup, [near, far], rays, tris, spare, depth);
        }
        self.child(tr, soup, near, rays, tris, spare, depth);
        self.child(tr, soup, far, rays, tris, spare, depth);
    }

    /// The leaf rule: few triangles, or few rays *and* few ray–triangle pairs (a node
    /// with a handful of rays but thousands of triangles is cheaper to split on), or
    /// the depth cap.
    fn is_leaf(&self, rays: usize, tris: usize, depth: u32) -> bool {
        let p = &self.params;
        tris <= p.leaf_triangles
            || (rays <= p.leaf_rays && (rays * tris) as u64 <= leaf_pairs(p.leaf_rays as u64, p.leaf_triangles as u64))
            || depth >= p.max_depth
    }

    /// The first candidate plane after which neither child keeps every ray and every
    /// triangle of the node; `None` when no candidate separates anything. `tris` index
    /// `boxes` (the scene's boxes, or the shared top's sample, where each box stands
    /// for `stride` triangles: the SAH threshold counts the triangles they stand for).
    fn choose_split(
        &self,
        tr: &Trace,
        (boxes, stride): (&[Aabb], usize),
        bounds: &Aabb,
        rays: &[u32],
        tris: &[u32],
    ) -> Option<(usize, f32)> {
        let axes = bounds.axes_by_extent();
        let ext = bounds.extent();
        let centre = bounds.center();
        // The candidates in order of preference, each computed only when every one
        // before it separates nothing (the centroid median allocates and selects).
        let candidate = |k: usize| match k {
            0 => {
                (tris.len() * stride >= self.params.sah_min_triangles).then(|| sah_plane(boxes, bounds, tris)).flatten()
            }
            1 => self.sampled_plane(tr, boxes, bounds, rays, tris),
            2..=4 => (ext[axes[k - 2]] > 0.0).then_some((axes[k - 2], centre[axes[k - 2]])),
            _ => centroid_median(boxes, tris, axes[0]),
        };
        // True when every triangle overlaps `child` and every ray enters it (stops at
        // the first element that does not).
        let keeps_all = |child: &Aabb| {
            let grown = tr.grown(child);
            tris.iter().all(|&t| boxes[t as usize].overlaps(child)) && rays.iter().all(|&r| tr.enters(r, &grown))
        };
        (0..6).filter_map(candidate).find(|&(axis, pos)| {
            let (lo, hi) = bounds.split(axis, pos);
            !keeps_all(&lo) && !keeps_all(&hi)
        })
    }

    /// Partitions the parent's lists for `child`, shrinks its box to its triangles,
    /// and recurses.
    #[allow(clippy::too_many_arguments)]
    fn child(
        &self,
        tr: &Trace,
        soup: Soup,
        child: Aabb,
        rays: &mut [u32],
        tris: &mut [u32],
        spare: &mut Vec<u32>,
        depth: u32,
    ) {
        let (nt, union) = partition_triangles(tr.lanes, soup.boxes, tris, &child, spare);
        if nt == 0 {
            return;
        }
        let tight = child.intersection(union);
        let nr = tr.partition_rays(rays, &tight, spare);
        self.recurse(tr, soup, tight, &mut rays[..nr], &mut tris[..nt], spare, depth + 1)
    }

    /// Runs the recursion for one batch; returns the per-ray keys (in the batch's
    /// order), the peak bytes and the ray–triangle tests made.
    fn trace(&self, rays: &[Ray], any_hit: bool) -> (Vec<AtomicU64>, usize, u64) {
        let mut clock = Stages::default();
        let n = rays.len();
        let (order, keys, varying) = self.valid_rays(rays);
        clock.lap("filter");
        if order.is_empty() || self.tris.is_empty() {
            self.keep_phases(clock);
            return ((0..n).map(|_| AtomicU64::new(NONE)).collect(), 0, 0);
        }
        let (groups, fork_min_rays) = self.grouping(order.len(), varying & ORIGIN_BITS == 0);
        // The shared top does not depend on the rays: it is built beside their sort and
        // copy, so that threads idle in one of the two help the other.
        let ((top, top_s), ((order, tr), sort_s)) = rayon::join(
            || timed(|| self.build_top()),
            || {
                timed(|| {
                    let order = self.coherence_order(order, keys, varying);
                    // The valid rays renumbered in that order: ids, keys, reciprocal
                    // directions, the copies of the rays, the map back, and the packets.
                    // (The sort's own 16 bytes per ray are freed before these are made.)
                    let (mut in_order, mut slabs) = (Vec::new(), Vec::new());
                    order
                        .par_iter()
                        .map(|&i| (rays[i as usize], RaySlab::new(&rays[i as usize])))
                        .unzip_into_vecs(&mut in_order, &mut slabs);
                    let tr = Trace::new(
                        in_order,
                        slabs,
                        any_hit,
                        self.params.packet_rays,
                        fork_min_rays,
                        self.magnitude,
                        self.params.lanes,
                    );
                    (order, tr)
                })
            },
        );
        clock.lap("prepare");
        let (top, top_stages) = top;
        clock.note("prepare_top", top_s);
        clock.note("prepare_rays", sort_s);
        top_stages.iter().for_each(|&(name, s)| clock.note(name, s));
        let m = order.len();
        tr.alloc(
            m * (4 + 8 + std::mem::size_of::<RaySlab>() + std::mem::size_of::<Ray>() + 4)
                + tr.packets.as_ref().map_or(0, Packets::bytes),
        );
        tr.alloc(top.ids.len() * 4);
        let mut ray_ids: Vec<u32> = (0..m as u32).collect();
        // Each group's own time: their sum against the stage's wall time and threads
        // says how well the groups shared the cores, the longest one what was left last.
        // (With forks a group's span also holds the waits for its far halves; the summed
        // time leaves them out.)
        let longest = AtomicU64::new(0);
        let group = |ids: &mut [u32], scratch: &mut Scratch| {
            let ((), s) = timed(|| self.trace_top(&tr, &top, &top.root, ids, scratch, 0));
            let ns = (s * 1e9) as u64;
            tr.busy_ns.fetch_add(ns, Relaxed);
            longest.fetch_max(ns, Relaxed);
        };
        if groups <= 1 {
            group(&mut ray_ids, &mut Scratch::default());
        } else {
            let size = m.div_ceil(groups);
            ray_ids.par_chunks_mut(size).for_each_init(Scratch::default, |scratch, ids| group(ids, scratch));
        }
        drop(ray_ids);
        clock.lap("groups");
        clock.note("groups_busy", tr.busy_ns.load(Relaxed) as f64 * 1e-9);
        clock.note("groups_longest", longest.into_inner() as f64 * 1e-9);
        // Back to the batch's order.
        tr.alloc(n * 8);
        let keys: Vec<AtomicU64> = (0..n).into_par_iter().map(|_| AtomicU64::new(NONE)).collect();
        order.par_iter().zip(&tr.keys).for_each(|(&i, k)| keys[i as usize].store(k.load(Relaxed), Relaxed));
        clock.lap("back");
        self.keep_phases(clock);
        (keys, tr.peak.load(Relaxed), tr.tests.load(Relaxed))
    }

    fn keep_phases(&self, clock: Stages) {
        *self.phases.lock().unwrap_or_else(|e| e.into_inner()) = clock.seconds;
    }
}

impl RayCaster for Dacrt {
    fn name(&self) -> &'static str {
        "dacrt"
    }

    fn casts_single_rays(&self) -> bool {
        false
    }

    fn closest(&self, rays: &[Ray], hits: &mut [Hit]) -> CastStats {
        assert_eq!(rays.len(), hits.len(), "one hit slot per ray");
        let start = Instant::now();
        let (keys, peak, tests) = self.trace(rays, false);
        hits.par_iter_mut().zip(keys).zip(rays).for_each(|((h, k), ray)| {
            let k = k.into_inner();
            *h = if k == NONE {
                Hit::MISS
            } else {
                // Barycentrics of the winner, from the same watertight test.
                let prim = hit_key::prim_of(k);
                let [a, b, c] = self.tris[prim as usize];
                let t = hit_key::t_of(k);
                intersect_triangle(ray.origin, &RayShear::new(ray.dir), a, b, c, ray.t_min, t.next_up())
                    .map_or(Hit { t, prim, u: 0.0, v: 0.0 }, |(t, u, v)| Hit { t, prim, u, v })
            };
        });
        CastStats { rays: rays.len(), seconds: start.elapsed().as_secs_f64(), peak_working_bytes: peak, tests }
    }

    fn occluded(&self, rays: &[Ray], out: &mut [bool]) -> CastStats {
        assert_eq!(rays.len(), out.len(), "one result slot per ray");
        let start = Instant::now();
        let (keys, peak, tests) = self.trace(rays, true);
        out.par_iter_mut().zip(keys).for_each(|(o, k)| *o = k.into_inner() == BLOCKED);
        CastStats { rays: rays.len(), seconds: start.elapsed().as_secs_f64(), peak_working_bytes: peak, tests }
    }

    fn memory_bytes(&self) -> usize {
        triangles_bytes(&self.tris) + self.boxes.len() * std::mem::size_of::<Aabb>()
    }

    fn phase_seconds(&self) -> Vec<(&'static str, f64)> {
        self.phases.lock().unwrap_or_else(|e| e.into_inner()).clone()
    }
}
