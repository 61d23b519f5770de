//! DACRT's shared top levels: the triangle partitions near the root, which do not
//! depend on the rays, computed once per trace call and walked by every ray group.
//! The planes are chosen on a sample of the triangles' boxes; every triangle is then
//! routed down them and gathered by cell in two parallel passes (a counting sort).

use super::routes::{Plan, Routes};
use super::stages::Stages;
use super::state::{Dacrt, Soup, Trace};
use crate::geometry::Aabb;
use glam::Vec3;
use rayon::prelude::*;

/// Every triangle's box, in order, is read in chunks of this many by the shared top's
/// routing passes.
const ROUTE_CHUNK: usize = 1 << 14;
/// The shared top's planes are chosen on a sample holding about this many triangles
/// per cell of [`DacrtParams::top_cell_triangles`](super::state::DacrtParams::top_cell_triangles).
/// (64 chose planes as good as 256 did on the dragon, in a quarter of the time:
/// ray–triangle tests within 1 % on its primary, shadow and mirror batches; 32 as good
/// as 64, the dragon's plan 2.0 against 3.5 ms and its calls 1–5 % shorter at 1024² on
/// two threads of the VM, tests within 0.4 %; 16 gained nothing more.)
const TOP_SAMPLES_PER_CELL: usize = 32;

/// A ray group's reusable buffers: the list of a cell's triangles, the rays a partition
/// sets aside, and with [`DacrtParams::cell_layout`](super::state::DacrtParams::cell_layout)
/// the copies of the cell's boxes and corners.
#[derive(Default)]
pub(super) struct Scratch {
    pub(super) tris: Vec<u32>,
    pub(super) rays: Vec<u32>,
    boxes: Vec<Aabb>,
    corners: Vec<[Vec3; 3]>,
}

/// The top levels of the recursion, whose triangle partitions do not depend on the
/// rays: computed once per call and shared by every ray group.
pub(super) enum Top {
    /// A node below which each group runs its own DACRT on a copy of its triangles,
    /// `range` of the shared id list.
    Cell {
        bounds: Aabb,
        range: std::ops::Range<usize>,
    },
    Split {
        bounds: Aabb,
        axis: usize,
        kids: Box<[Top; 2]>,
    },
}

impl Top {
    pub(super) fn bounds(&self) -> &Aabb {
        match self {
            Top::Cell { bounds, .. } | Top::Split { bounds, .. } => bounds,
        }
    }

    /// The node of `plan` over `region`: a cell's box is its region shrunk to its
    /// triangles' boxes, a split's the hull of its children's (empty ones left out).
    fn from_plan(plan: &Plan, region: Aabb, starts: &[usize], unions: &[Aabb]) -> Top {
        match plan {
            Plan::Cell(c) => Top::Cell { bounds: region.intersection(unions[*c]), range: starts[*c]..starts[*c + 1] },
            Plan::Split { axis, pos, kids } => {
                let (lo, hi) = region.split(*axis, *pos);
                let kids = Box::new([
                    Top::from_plan(&kids[0], lo, starts, unions),
                    Top::from_plan(&kids[1], hi, starts, unions),
                ]);
                let bounds = kids.iter().map(|k| *k.bounds()).filter(|b| !b.is_empty()).fold(Aabb::EMPTY, Aabb::union);
                Top::Split { bounds, axis: *axis, kids }
            }
        }
    }
}

/// The shared top levels: the tree, and the triangle ids of its cells, cell after cell.
pub(super) struct SharedTop {
    pub(super) root: Top,
    pub(super) ids: Vec<u32>,
}

impl Dacrt {
    /// How many independent ray groups a batch of `n` rays is traced in, and from how
    /// many rays a node forks its far child (0: never). Rays from one origin (a pinhole
    /// camera's, a point light's) make narrow groups in coherence order, each reaching
    /// few cells, so many small groups balance the threads at little cost and nothing
    /// forks; rays from many origins make groups that reach most cells, each one
    /// re-partitioning their triangles, so one group per thread, with forks, is cheaper,
    /// once a thread's share has at least twice
    /// [`fork_min_rays`](super::state::DacrtParams::fork_min_rays) rays (below that nothing
    /// would fork, and the threads would be left unbalanced).
    pub(super) fn grouping(&self, n: usize, one_origin: bool) -> (usize, usize) {
        let p = &self.params;
        let threads = rayon::current_num_threads();
        if threads <= 1 || p.groups_per_thread == 0 {
            return (1, 0);
        }
        // (A batch too small for a thread's share to fork is grouped as well.)
        let forked = !one_origin && p.fork_min_rays > 0 && n >= 2 * threads * p.fork_min_rays;
        let (per_thread, fork) = if forked { (1, p.fork_min_rays) } else { (p.groups_per_thread, 0) };
        // A group re-partitions the triangles of every cell it reaches: it should carry
        // at least a quarter as many rays as a cell has triangles.
        let cell = if p.top_cell_triangles == 0 { self.tris.len() } else { self.tris.len().min(p.top_cell_triangles) };
        let min_rays = p.min_group_rays.max(cell / 4).max(1);
        ((threads * per_thread).min(n / min_rays).max(1), fork)
    }

    /// The shared top levels: planes chosen on a sample of the triangles
    /// ([`Dacrt::plan_top`]), then every triangle routed down them and gathered by cell,
    /// a counting sort in two parallel passes over the boxes in order (the first
    /// counts each chunk's triangles per cell and grows the cells' boxes, the second
    /// writes the ids, each chunk into its own slots: the order is the same at any
    /// thread count). Returns the seconds of the three stages too (`top_plan`,
    /// `top_route`, `top_gather`).
    pub(super) fn build_top(&self) -> (SharedTop, [(&'static str, f64); 3]) {
        let (n, p) = (self.tris.len(), &self.params);
        let mut clock = Stages::default();
        if p.top_cell_triangles == 0 || n <= p.top_cell_triangles {
            let root = Top::Cell { bounds: self.scene_box, range: 0..n };
            return (
                SharedTop { root, ids: (0..n as u32).collect() },
                [("top_plan", 0.0), ("top_route", 0.0), ("top_gather", 0.0)],
            );
        }
        let stride = (p.top_cell_triangles / TOP_SAMPLES_PER_CELL).max(1);
        // (Every box is in its own cache line: the reads are spread over the threads.)
        let sample: Vec<Aabb> = self.boxes.par_iter().step_by(stride).copied().collect();
        let ids: Vec<u32> = (0..sample.len() as u32).collect();
        let mut plan = self.plan_top(&Trace::empty(), &sample, self.scene_box, ids, stride, 0);
        let mut cells = 0;
        plan.number(&mut cells);
        let routes = Routes::new(&plan, cells);
        clock.lap("top_plan");

        // Pass 1 also keeps each triangle's cell (`SEVERAL` for one that touches a plane
        // and is routed again in pass 2).
        const SEVERAL: u32 = u32::MAX;
        let mut cell_of = vec![0u32; n];
        let counted: Vec<(Vec<usize>, Vec<Aabb>)> = self
            .boxes
            .par_chunks(ROUTE_CHUNK)
            .zip(cell_of.par_chunks_mut(ROUTE_CHUNK))
            .map(|(chunk, cell_of)| {
                let (mut count, mut union) = (vec![0usize; cells], vec![Aabb::EMPTY; cells]);
                let mut last = None;
                for (b, cell) in chunk.iter().zip(cell_of) {
                    let mut add = |c: usize| {
                        count[c] += 1;
                        union[c] = union[c].union(*b);
                    };
                    *cell = match routes.descend_near(b, last) {
                        Ok(c) => {
                            add(c);
                            last = Some(c);
                            c as u32
                        }
                        Err(_) => {
                            routes.route_from(b, 0, &mut add);
                            SEVERAL
                        }
                    };
                }
                (count, union)
            })
            .collect();
        clock.lap("top_route");
        let mut starts = vec![0usize; cells + 1];
        let mut unions = vec![Aabb::EMPTY; cells];
        for c in 0..cells {
            starts[c + 1] = starts[c] + counted.iter().map(|(count, _)| count[c]).sum::<usize>();
            unions[c] = counted.iter().fold(Aabb::EMPTY, |u, (_, union)| u.union(union[c]));
        }
        // Each chunk's slots, one per cell: cell-major, chunks in order within a cell.
        let mut ids = vec![0u32; starts[cells]];
        let mut slots: Vec<Vec<&mut [u32]>> = counted.iter().map(|_| Vec::with_capacity(cells)).collect();
        let mut rest = &mut ids[..];
        for c in 0..cells {
            for (k, (count, _)) in counted.iter().enumerate() {
                let (slot, tail) = rest.split_at_mut(count[c]);
                slots[k].push(slot);
                rest = tail;
            }
        }
        self.boxes.par_chunks(ROUTE_CHUNK).zip(cell_of.par_chunks(ROUTE_CHUNK)).zip(slots).enumerate().for_each(
            |(k, ((chunk, cell_of), mut slots))| {
                let mut at = vec![0usize; cells];
                for (i, (b, &cell)) in chunk.iter().zip(cell_of).enumerate() {
                    let mut put = |c: usize| {
                        slots[c][at[c]] = (k * ROUTE_CHUNK + i) as u32;
                        at[c] += 1;
                    };
                    if cell == SEVERAL { routes.route_from(b, 0, &mut put) } else { put(cell as usize) }
                }
            },
        );
        let top = SharedTop { root: Top::from_plan(&plan, self.scene_box, &starts, &unions), ids };
        clock.lap("top_gather");
        (top, clock.seconds.try_into().expect("three laps"))
    }

    /// The shared top's planes over a sample of the triangles' boxes (`tris` index
    /// `sample`; each stands for `stride` triangles), by the recursion's own plane
    /// rules, down to cells of about `top_cell_triangles`; the halves in parallel.
    /// `none` is a trace without rays, made once (making one costs microseconds: on
    /// the dragon's 345 planes, 2-3 ms of one thread's time when each made its own).
    fn plan_top(&self, none: &Trace, sample: &[Aabb], bounds: Aabb, tris: Vec<u32>, stride: usize, depth: u32) -> Plan {
        let p = &self.params;
        if tris.len() * stride <= p.top_cell_triangles || depth >= p.max_depth {
            return Plan::Cell(0);
        }
        // Triangles alone decide the plane (no rays yet).
        let Some((axis, pos)) = self.choose_split(none, (sample, stride), &bounds, &[], &tris) else {
            return Plan::Cell(0);
        };
        let (lo, hi) = bounds.split(axis, pos);
        // Each side's sample ids and the union of their boxes, in one pass over the
        // node's ids (two parallel filters on large nodes).
        let ((lo_ids, lo_union), (hi_ids, hi_union)) = if tris.len() < 1 << 14 {
            let (mut l, mut h) = ((Vec::new(), Aabb::EMPTY), (Vec::new(), Aabb::EMPTY));
            for &t in &tris {
                let b = sample[t as usize];
                for (side, child) in [(&mut l, &lo), (&mut h, &hi)] {
                    if b.overlaps(child) {
                        side.0.push(t);
                        side.1 = side.1.union(b);
                    }
                }
            }
            (l, h)
        } else {
            let side = |child: &Aabb| {
                let ids: Vec<u32> = tris.par_iter().copied().filter(|&t| sample[t as usize].overlaps(child)).collect();
                let union = ids.iter().fold(Aabb::EMPTY, |u, &t| u.union(sample[t as usize]));
                (ids, union)
            };
            (side(&lo), side(&hi))
        };
        let (lo_box, hi_box) = (lo.intersection(lo_union), hi.intersection(hi_union));
        drop(tris);
        let (a, b) = rayon::join(
            || self.plan_top(none, sample, lo_box, lo_ids, stride, depth + 1),
            || self.plan_top(none, sample, hi_box, hi_ids, stride, depth + 1),
        );
        Plan::Split { axis, pos, kids: Box::new([a, b]) }
    }

    /// One ray group through the shared top levels, near child first; in each cell it
    /// reaches, the group's DACRT continues on a copy of the cell's triangles.
    pub(super) fn trace_top(
        &self,
        tr: &Trace,
        top: &SharedTop,
        node: &Top,
        rays: &mut [u32],
        scratch: &mut Scratch,
        depth: u32,
    ) {
        if rays.is_empty() {
            return;
        }
        match node {
            Top::Cell { bounds, range } => {
                if range.is_empty() {
                    return;
                }
                let Scratch { tris, rays: aside, boxes, corners } = scratch;
                let ids = &top.ids[range.clone()];
                tris.clear();
                // The cell's triangles laid out side by side (one gather here; the
                // partitions and leaves below then read them in ascending order), or
                // gathered from the scene by id at every step. A single cell is the
                // scene itself, already in order.
                let (soup, bytes) = if self.params.cell_layout && range.len() < self.tris.len() {
                    boxes.clear();
                    boxes.extend(ids.iter().map(|&t| self.boxes[t as usize]));
                    corners.clear();
                    corners.extend(ids.iter().map(|&t| self.tris[t as usize]));
                    tris.extend(0..ids.len() as u32);
                    let soup = Soup { boxes, corners, ids: Some(ids) };
                    (soup, ids.len() * (4 + std::mem::size_of::<Aabb>() + std::mem::size_of::<[Vec3; 3]>()))
                } else {
                    tris.extend_from_slice(ids);
                    (self.soup(), ids.len() * 4)
                };
                tr.alloc(bytes);
                self.recurse(tr, soup, *bounds, rays, tris, aside, depth);
                tr.free(bytes);
            }
            Top::Split { axis, kids, .. } => {
                let order = if tr.toward_hi(rays, *axis) { [0, 1] } else { [1, 0] };
                if tr.forks(rays.len()) {
                    return self.fork_top(tr, top, order.map(|k| &kids[k]), rays, scratch, depth);
                }
                for k in order {
                    let child = &kids[k];
                    let b = *child.bounds();
                    let nr = tr.partition_rays(rays, &b, &mut scratch.rays);
                    self.trace_top(tr, top, child, &mut rays[..nr], scratch, depth + 1);
                }
            }
        }
    }
}
