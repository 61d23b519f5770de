//! Serial divide-and-conquer ray tracing (Mora 2011): no stored structure. The recursion
//! carries a box, a list of ray ids and a list of triangle ids. Each step splits the box
//! at the spatial median of its longest axis, partitions both id lists *in place* so the
//! child's triangles (boxes overlapping the child) and rays (entering the child before
//! their current closest hit: early termination) form a prefix, and recurses into the
//! near child first. Small lists go to a brute-force leaf.
//!
//! Guards: a child that keeps all of its parent's rays and triangles goes to the leaf
//! (coincident or huge triangles cannot be split), and the depth is capped.
//!
//! "CPU DACRT" in the tables: the top levels fork with `rayon::join` (the far child
//! works on a copy of the id lists), so both children run at once; closest hits are
//! shared through 64-bit atomic minima of (distance bits, triangle id).

use super::{CastStats, RayCaster, Triangles, triangles_bytes};
use crate::geometry::{Aabb, Hit, Ray, RayShear, intersect_triangle, inv_dir};
use crate::scene::Scene;
use glam::Vec3;
use rayon::prelude::*;
use std::sync::atomic::{AtomicU64, AtomicUsize, Ordering::Relaxed};
use std::time::Instant;

/// Tunables of [`Dacrt`]. The defaults were chosen by measurement (see
/// `docs/dacrt.md`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DacrtParams {
    /// A node with at most this many rays is solved by brute force.
    pub leaf_rays: usize,
    /// A node with at most this many triangles is solved by brute force.
    pub leaf_triangles: usize,
    /// Recursion depth cap.
    pub max_depth: u32,
    /// Levels at which the two children run in parallel (0: serial).
    pub parallel_depth: u32,
    /// Nodes with fewer rays than this never fork.
    pub parallel_min_rays: usize,
}

impl Default for DacrtParams {
    fn default() -> Self {
        DacrtParams { leaf_rays: 12, leaf_triangles: 12, max_depth: 48, parallel_depth: 6, parallel_min_rays: 2048 }
    }
}

impl DacrtParams {
    /// One thread's recursion: no forking.
    pub fn serial() -> Self {
        DacrtParams { parallel_depth: 0, ..Default::default() }
    }
}

pub struct Dacrt {
    tris: Triangles,
    boxes: Vec<Aabb>,
    scene_box: Aabb,
    pub params: DacrtParams,
}

/// Key of "no hit yet".
const NONE: u64 = u64::MAX;
/// Key of an occluded shadow ray.
const BLOCKED: u64 = 0;

#[inline]
fn pack(t: f32, prim: u32) -> u64 {
    (t.to_bits() as u64) << 32 | prim as u64
}

#[inline]
fn unpack_t(key: u64) -> f32 {
    f32::from_bits((key >> 32) as u32)
}

/// What one trace call shares between its recursive steps.
struct Trace<'a> {
    rays: &'a [Ray],
    inv: Vec<Vec3>,
    keys: Vec<AtomicU64>,
    any_hit: bool,
    bytes: AtomicUsize,
    peak: AtomicUsize,
}

impl Trace<'_> {
    fn alloc(&self, bytes: usize) {
        let now = self.bytes.fetch_add(bytes, Relaxed) + bytes;
        self.peak.fetch_max(now, Relaxed);
    }
    fn free(&self, bytes: usize) {
        self.bytes.fetch_sub(bytes, Relaxed);
    }

    /// The ray's interval end: its closest hit so far, or its own `t_max`.
    #[inline]
    fn t_far(&self, id: u32) -> f32 {
        let k = self.keys[id as usize].load(Relaxed);
        if k == NONE { self.rays[id as usize].t_max } else { unpack_t(k).min(self.rays[id as usize].t_max) }
    }

    #[inline]
    fn enters(&self, id: u32, b: &Aabb) -> bool {
        let k = self.keys[id as usize].load(Relaxed);
        if self.any_hit && k == BLOCKED {
            return false;
        }
        let r = &self.rays[id as usize];
        b.intersect(r.origin, self.inv[id as usize], r.t_min, self.t_far(id)).is_some()
    }
}

/// Moves the elements satisfying `keep` to the front; returns how many there are.
fn partition(ids: &mut [u32], mut keep: impl FnMut(u32) -> bool) -> usize {
    let mut n = 0;
    for i in 0..ids.len() {
        if keep(ids[i]) {
            ids.swap(n, i);
            n += 1;
        }
    }
    n
}

impl Dacrt {
    pub fn new(scene: &Scene) -> Self {
        Self::from_triangles(scene.triangle_vertices(), DacrtParams::default())
    }

    pub fn from_triangles(tris: Triangles, params: DacrtParams) -> Self {
        let boxes: Vec<Aabb> = tris.iter().map(|t| Aabb::from_points(t)).collect();
        let scene_box = boxes.iter().fold(Aabb::EMPTY, |a, b| a.union(*b));
        Dacrt { tris, boxes, scene_box, params }
    }

    pub fn with_params(mut self, params: DacrtParams) -> Self {
        self.params = params;
        self
    }

    fn leaf(&self, tr: &Trace, rays: &[u32], tris: &[u32]) {
        for &r in rays {
            let ray = &tr.rays[r as usize];
            let key = &tr.keys[r as usize];
            let shear = RayShear::new(ray.dir);
            if tr.any_hit {
                if key.load(Relaxed) == BLOCKED {
                    continue;
                }
                let hit = tris.iter().any(|&t| {
                    let [a, b, c] = self.tris[t as usize];
                    intersect_triangle(ray.origin, &shear, a, b, c, ray.t_min, ray.t_max).is_some()
                });
                if hit {
                    key.store(BLOCKED, Relaxed);
                }
                continue;
            }
            let mut best = key.load(Relaxed);
            let mut t_far = tr.t_far(r);
            for &t in tris {
                let [a, b, c] = self.tris[t as usize];
                // `<=` keeps a tie at equal distance so the smaller id wins below.
                if let Some((th, _, _)) = intersect_triangle(ray.origin, &shear, a, b, c, ray.t_min, t_far.next_up()) {
                    let k = pack(th, t);
                    if k < best {
                        best = k;
                        t_far = th;
                    }
                }
            }
            key.fetch_min(best, Relaxed);
        }
    }

    fn recurse(&self, tr: &Trace, bounds: Aabb, rays: &mut [u32], tris: &mut [u32], depth: u32) {
        if rays.is_empty() || tris.is_empty() {
            return;
        }
        let p = &self.params;
        if rays.len() <= p.leaf_rays || tris.len() <= p.leaf_triangles || depth >= p.max_depth {
            return self.leaf(tr, rays, tris);
        }
        let axis = bounds.longest_axis();
        let mid = bounds.center()[axis];
        let (mut lo, mut hi) = (bounds, bounds);
        lo.max[axis] = mid;
        hi.min[axis] = mid;
        // Near child first, judged by the rays' mean direction along the split axis.
        let toward_hi: f32 = rays.iter().map(|&r| tr.rays[r as usize].dir[axis].signum()).sum();
        let (near, far) = if toward_hi >= 0.0 { (lo, hi) } else { (hi, lo) };

        if depth < p.parallel_depth && rays.len() >= p.parallel_min_rays {
            let bytes = (rays.len() + tris.len()) * 4;
            tr.alloc(bytes);
            let (mut far_rays, mut far_tris) = (rays.to_vec(), tris.to_vec());
            rayon::join(
                || self.child(tr, near, rays, tris, depth),
                || self.child(tr, far, &mut far_rays, &mut far_tris, depth),
            );
            tr.free(bytes);
        } else {
            self.child(tr, near, rays, tris, depth);
            self.child(tr, far, rays, tris, depth);
        }
    }

    /// Partitions the parent's lists for `child` and recurses (or solves a node that
    /// would make no progress by brute force).
    fn child(&self, tr: &Trace, child: Aabb, rays: &mut [u32], tris: &mut [u32], depth: u32) {
        let nt = partition(tris, |t| {
            let b = &self.boxes[t as usize];
            b.min.cmple(child.max).all() && b.max.cmpge(child.min).all()
        });
        let nr = partition(rays, |r| tr.enters(r, &child));
        if nt == tris.len() && nr == rays.len() {
            return self.leaf(tr, &rays[..nr], &tris[..nt]);
        }
        self.recurse(tr, child, &mut rays[..nr], &mut tris[..nt], depth + 1)
    }

    /// Runs the recursion for one batch; returns the per-ray keys and the peak bytes.
    fn trace(&self, rays: &[Ray], any_hit: bool) -> (Vec<AtomicU64>, usize) {
        let n = rays.len();
        let inv: Vec<Vec3> = rays.par_iter().map(|r| inv_dir(r.dir)).collect();
        let keys: Vec<AtomicU64> = (0..n).map(|_| AtomicU64::new(NONE)).collect();
        let tr = Trace { rays, inv, keys, any_hit, bytes: AtomicUsize::new(0), peak: AtomicUsize::new(0) };
        let mut ray_ids: Vec<u32> = (0..n as u32).filter(|&i| rays[i as usize].is_valid()).collect();
        let mut tri_ids: Vec<u32> = (0..self.tris.len() as u32).collect();
        // ids, keys and reciprocal directions
        tr.alloc(ray_ids.len() * 4 + tri_ids.len() * 4 + n * (8 + 12));
        let nr = partition(&mut ray_ids, |r| tr.enters(r, &self.scene_box));
        self.recurse(&tr, self.scene_box, &mut ray_ids[..nr], &mut tri_ids, 0);
        let peak = tr.peak.load(Relaxed);
        (tr.keys, peak)
    }
}

impl RayCaster for Dacrt {
    fn name(&self) -> &'static str {
        "dacrt"
    }

    fn closest(&self, rays: &[Ray], hits: &mut [Hit]) -> CastStats {
        assert_eq!(rays.len(), hits.len(), "one hit slot per ray");
        let start = Instant::now();
        let (keys, peak) = self.trace(rays, false);
        hits.par_iter_mut().zip(keys).zip(rays).for_each(|((h, k), ray)| {
            let k = k.into_inner();
            *h = if k == NONE {
                Hit::MISS
            } else {
                // Barycentrics of the winner, from the same watertight test.
                let prim = (k & 0xffff_ffff) as u32;
                let [a, b, c] = self.tris[prim as usize];
                let t = unpack_t(k);
                intersect_triangle(ray.origin, &RayShear::new(ray.dir), a, b, c, ray.t_min, t.next_up())
                    .map_or(Hit { t, prim, u: 0.0, v: 0.0 }, |(t, u, v)| Hit { t, prim, u, v })
            };
        });
        CastStats { rays: rays.len(), seconds: start.elapsed().as_secs_f64(), peak_working_bytes: peak }
    }

    fn occluded(&self, rays: &[Ray], out: &mut [bool]) -> CastStats {
        assert_eq!(rays.len(), out.len(), "one result slot per ray");
        let start = Instant::now();
        let (keys, peak) = self.trace(rays, true);
        out.par_iter_mut().zip(keys).for_each(|(o, k)| *o = k.into_inner() == BLOCKED);
        CastStats { rays: rays.len(), seconds: start.elapsed().as_secs_f64(), peak_working_bytes: peak }
    }

    fn memory_bytes(&self) -> usize {
        triangles_bytes(&self.tris) + self.boxes.len() * std::mem::size_of::<Aabb>()
    }
}
