//! warpray's own BVH: four children per node, built by binned SAH in parallel
//! (`build.rs`), traversed one ray at a time with the four child boxes tested on SIMD
//! lanes ([`Boxes4`]) and each leaf's up to four triangles tested at once
//! ([`Triangles4`]).
//!
//! It needs none of the obvhs caster's defences: the child boxes are the triangles'
//! exact bounds, grown per ray by a bound on the watertight test's own rounding
//! (`geometry::hit_slack`), and the box test is warpray's conservative slab test (exits widened
//! by `SLAB_WIDEN`, zero direction components decided by position), lane for lane
//! [`Aabb::intersect`](crate::geometry::Aabb::intersect), so no box holding a hit the
//! triangle test would report is rejected, from any origin. Ties go to the smaller id, and triangles with a
//! coordinate that is not finite are tested against every ray, so the answers are
//! brute force's. Exact copies of a triangle are dropped where the builder finds them
//! (among triangles whose centroids coincide): they could never be the answer.

mod build;
mod node;
#[cfg(target_arch = "x86_64")]
mod packet;

use super::caster::{CastStats, RayCaster, Triangles, per_ray};
use crate::geometry::lanes::RaySlab;
use crate::geometry::packet_lanes::Width;
use crate::geometry::{Hit, Ray, RayShear, cull_distance, hit_slack, magnitude};
use crate::scene::Scene;
use glam::Vec3;
use node::{LEAF, LEAF_SIZE, Leaf, MAX_DEPTH, Node, leaf_of};
use rayon::prelude::*;
use std::time::Instant;

/// Stack entries a traversal may need: three pending siblings per level, and the root.
const STACK: usize = 3 * MAX_DEPTH + 1;
/// Levels a tree may have for the traversal to keep its stack short (64 entries):
/// nearly every tree. The stack is zeroed per ray, and a 220-entry stack cost more
/// than a small scene's whole traversal.
const SHALLOW_DEPTH: usize = 21;
/// The short stack: enough for a tree of [`SHALLOW_DEPTH`] levels.
const SHORT_STACK: usize = 3 * SHALLOW_DEPTH + 1;

/// The 4-wide BVH caster.
pub struct Bvh4 {
    nodes: Vec<Node>,
    leaves: Vec<Leaf>,
    /// The largest coordinate magnitude of the finite triangles.
    magnitude: f32,
    /// The root's code; `None` for a scene with no finite triangle.
    root: Option<u32>,
    /// Levels of inner nodes on the longest path from the root.
    depth: usize,
    /// Triangles with a coordinate that is not finite, in leaves tested by every ray
    /// (with their triangle counts).
    outliers: Vec<(Leaf, usize)>,
    /// The most rays a packet may hold (1: one ray at a time).
    max_packet: usize,
    build_seconds: f64,
}

impl Bvh4 {
    /// Builds the BVH of a scene's triangles.
    pub fn new(scene: &Scene) -> Self {
        Self::from_triangles(scene.triangle_vertices())
    }

    /// Builds the BVH of a triangle list.
    pub fn from_triangles(tris: Triangles) -> Self {
        let start = Instant::now();
        let finite = |t: &[Vec3; 3]| t.iter().all(|v| v.is_finite());
        let outlier_ids: Vec<u32> = (0..tris.len() as u32).filter(|&i| !finite(&tris[i as usize])).collect();
        let outliers = outlier_ids.chunks(LEAF_SIZE).map(|c| (Leaf::new(&tris, c), c.len())).collect();
        let ids: Vec<u32> = (0..tris.len() as u32).into_par_iter().filter(|&i| finite(&tris[i as usize])).collect();
        let magnitude = magnitude(&tris);
        let (nodes, leaves, root) = if ids.is_empty() {
            (Vec::new(), Vec::new(), None)
        } else {
            let b = build::build(&tris, &ids);
            (b.nodes, b.leaves, Some(b.root))
        };
        let depth = root.map_or(0, |r| node::depth(&nodes, r));
        let build_seconds = start.elapsed().as_secs_f64();
        Bvh4 { nodes, leaves, magnitude, root, depth, outliers, max_packet: usize::MAX, build_seconds }
    }

    /// The same tree, traced one ray at a time (no packets): the traversal packets are
    /// measured against. Same answers, bit for bit.
    pub fn single_rays(self) -> Self {
        Bvh4 { max_packet: 1, ..self }
    }

    /// The same tree, traced in packets of at most `rays` rays (8: AVX2's even on a CPU
    /// with AVX-512; 1: one ray at a time). Same answers, bit for bit.
    pub fn max_packet(self, rays: usize) -> Self {
        Bvh4 { max_packet: rays, ..self }
    }

    /// How far boxes are grown for a ray: a bound on how far from a triangle a hit the
    /// watertight test reports can lie (`geometry::hit_slack`).
    #[inline]
    fn grow(&self, ray: &Ray) -> f32 {
        hit_slack(self.magnitude, ray.origin.abs().max_element())
    }

    /// The packets a batch of `rays` rays goes through ([`packet`]): the widest this CPU
    /// runs (AVX-512 or AVX2) within [`max_packet`](Self::max_packet), for a tree
    /// without outliers (which every ray must test one at a time); `None` for one ray at
    /// a time, as also for a batch smaller than one packet (a megakernel thread's ray).
    #[cfg(target_arch = "x86_64")]
    fn packets(&self, rays: usize) -> Option<Width> {
        let fits = |w: &Width| w.rays() <= self.max_packet.min(rays) && w.supported();
        Width::ALL.into_iter().find(fits).filter(|_| self.outliers.is_empty())
    }

    /// Closest hit of one (valid) ray and the triangles it tested.
    fn closest_one(&self, ray: &Ray) -> (Hit, u64) {
        if self.depth <= SHALLOW_DEPTH { self.closest_in::<SHORT_STACK>(ray) } else { self.closest_in::<STACK>(ray) }
    }

    /// [`closest_one`](Self::closest_one) with a stack of `N` entries (at least three
    /// per level of the tree, and one).
    #[inline(always)]
    fn closest_in<const N: usize>(&self, ray: &Ray) -> (Hit, u64) {
        let shear = RayShear::new(ray.dir);
        let mut best = Hit::MISS;
        let mut tests = 0u64;
        // A leaf's triangles count when they hit before the best so far or tie with it.
        let mut leaf = |leaf: &Leaf, len: usize, best: &mut Hit| {
            let far = if best.is_hit() { best.t.next_up().min(ray.t_max) } else { ray.t_max };
            let (h, ids) = (leaf.tris.test(ray.origin, &shear, ray.t_min, far), &leaf.ids);
            if let Some(k) = h.closest(len, ids)
                && best.loses_to(h.t[k], ids[k])
            {
                *best = Hit { t: h.t[k], prim: ids[k], u: h.u[k], v: h.v[k] };
            }
            tests += len as u64;
        };
        for (l, len) in &self.outliers {
            leaf(l, *len, &mut best);
        }
        let Some(root) = self.root else { return (best, tests) };
        let slab = RaySlab::new(ray);
        let grow = self.grow(ray);
        let mut stack = [(0u32, 0f32); N];
        stack[0] = (root, f32::NEG_INFINITY);
        let mut top = 1;
        while top > 0 {
            top -= 1;
            let (code, near) = stack[top];
            // Boxes are cut at the best hit widened as box exits are, so a box entered
            // exactly at the best distance (a tie) is still visited.
            let cull = cull_distance(best.t.min(ray.t_max));
            if near > cull {
                continue;
            }
            if code & LEAF != 0 {
                let (l, len) = leaf_of(code);
                leaf(&self.leaves[l], len, &mut best);
                continue;
            }
            let node = &self.nodes[code as usize];
            let (mask, nears) = node.boxes.enters(&slab, cull, grow);
            let (mut mask, nears) = (mask & ((1 << node.children) - 1), nears.to_array());
            // Push the entered children farthest first, so the nearest is taken next.
            let first = top;
            while mask != 0 {
                let k = mask.trailing_zeros() as usize;
                mask &= mask - 1;
                let entry = (node.child[k], nears[k]);
                let mut at = top;
                while at > first && stack[at - 1].1 < entry.1 {
                    stack[at] = stack[at - 1];
                    at -= 1;
                }
                stack[at] = entry;
                top += 1;
            }
        }
        (best, tests)
    }

    /// Whether anything lies on one (valid) ray within its interval, and the
    /// triangles tested.
    fn occluded_one(&self, ray: &Ray) -> (bool, u64) {
        if self.depth <= SHALLOW_DEPTH { self.occluded_in::<SHORT_STACK>(ray) } else { self.occluded_in::<STACK>(ray) }
    }

    /// [`occluded_one`](Self::occluded_one) with a stack of `N` entries.
    #[inline(always)]
    fn occluded_in<const N: usize>(&self, ray: &Ray) -> (bool, u64) {
        let shear = RayShear::new(ray.dir);
        let mut tests = 0u64;
        let mut leaf = |leaf: &Leaf, len: usize| {
            tests += len as u64;
            leaf.tris.test(ray.origin, &shear, ray.t_min, ray.t_max).first(len).is_some()
        };
        if self.outliers.iter().any(|(l, len)| leaf(l, *len)) {
            return (true, tests);
        }
        let Some(root) = self.root else { return (false, tests) };
        let slab = RaySlab::new(ray);
        let grow = self.grow(ray);
        let cull = cull_distance(ray.t_max);
        let mut stack = [0u32; N];
        stack[0] = root;
        let mut top = 1;
        while top > 0 {
            top -= 1;
            let code = stack[top];
            if code & LEAF != 0 {
                let (l, len) = leaf_of(code);
                if leaf(&self.leaves[l], len) {
                    return (true, tests);
                }
                continue;
            }
            let node = &self.nodes[code as usize];
            let mut mask = node.boxes.enters(&slab, cull, grow).0 & ((1 << node.children) - 1);
            while mask != 0 {
                stack[top] = node.child[mask.trailing_zeros() as usize];
                top += 1;
                mask &= mask - 1;
            }
        }
        (false, tests)
    }
}

impl RayCaster for Bvh4 {
    fn name(&self) -> &'static str {
        // The traversal the width limit allows (narrower than 8: one ray at a time).
        match self.max_packet {
            0..8 => "bvh4-single",
            8..16 => "bvh4-8",
            _ => "bvh4",
        }
    }

    fn closest(&self, rays: &[Ray], hits: &mut [Hit]) -> CastStats {
        #[cfg(target_arch = "x86_64")]
        if let Some(width) = self.packets(rays.len()) {
            return width.closest(self, rays, hits);
        }
        per_ray(rays, hits, |ray| self.closest_single(ray))
    }

    fn occluded(&self, rays: &[Ray], out: &mut [bool]) -> CastStats {
        #[cfg(target_arch = "x86_64")]
        if let Some(width) = self.packets(rays.len()) {
            return width.occluded(self, rays, out);
        }
        per_ray(rays, out, |ray| self.occluded_single(ray))
    }

    fn closest_single(&self, ray: &Ray) -> (Hit, u64) {
        if ray.is_valid() { self.closest_one(ray) } else { (Hit::MISS, 0) }
    }

    fn occluded_single(&self, ray: &Ray) -> (bool, u64) {
        if ray.is_valid() { self.occluded_one(ray) } else { (false, 0) }
    }

    fn memory_bytes(&self) -> usize {
        use std::mem::size_of;
        self.nodes.len() * size_of::<Node>()
            + self.leaves.len() * size_of::<Leaf>()
            + self.outliers.len() * size_of::<(Leaf, usize)>()
    }

    fn build_seconds(&self) -> f64 {
        self.build_seconds
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cast::BruteForce;
    use crate::sampling::Rng;

    /// Levels of inner nodes below `code`, by recursion (the builder's own count is
    /// `node::depth`, a loop).
    fn levels(bvh: &Bvh4, code: u32) -> usize {
        if code & LEAF != 0 {
            return 0;
        }
        let n = &bvh.nodes[code as usize];
        1 + n.child[..n.children as usize].iter().map(|&c| levels(bvh, c)).max().unwrap_or(0)
    }

    /// The traversal's stack size is chosen from the tree's depth: the depth must be
    /// the tree's, and on a skewed and an even tree both stack sizes must give brute
    /// force's answers (the full-size one serves trees deeper than 21 levels, which
    /// the builder made for no scene tried, so it is run here on shallower trees).
    #[test]
    fn both_stack_sizes_answer_as_brute_force_and_the_depth_is_the_trees() {
        let tri = |x: f32| [Vec3::new(x, -1.0, -1.0), Vec3::new(x, 1.0, -1.0), Vec3::new(x, 0.0, 1.0)];
        let skewed: Triangles = (0..120).map(|i| tri(1.5f32.powi(i))).collect();
        let even: Triangles = (0..3000).map(|i| tri(i as f32 * 0.01)).collect();
        let mut r = Rng::for_sample(17, 0, 0);
        for tris in [skewed, even] {
            let bvh = Bvh4::from_triangles(tris.clone());
            assert_eq!(bvh.depth, levels(&bvh, bvh.root.unwrap()));
            assert!(bvh.depth > 3 && bvh.depth <= SHALLOW_DEPTH, "depth {}", bvh.depth);
            let brute = BruteForce::from_triangles(tris.clone());
            let far = tris.last().unwrap()[0].x * 1.1;
            let rays: Vec<Ray> = (0..2000)
                .map(|k| {
                    let o = Vec3::new(-1.0, r.uniform() * 1.6 - 0.8, r.uniform() * 1.6 - 0.8);
                    let d = Vec3::new(1.0, (r.uniform() - 0.5) * 1e-3, (r.uniform() - 0.5) * 1e-3);
                    if k % 2 == 0 { Ray::new(o, d) } else { Ray::segment(o, d, far * r.uniform()) }
                })
                .collect();
            let (mut want, mut blocked) = (vec![Hit::MISS; rays.len()], vec![false; rays.len()]);
            brute.closest(&rays, &mut want);
            brute.occluded(&rays, &mut blocked);
            assert!(want.iter().filter(|h| h.is_hit()).count() > 500, "too few hits to compare");
            let key = |h: &Hit| (h.prim, h.t.to_bits());
            for (ray, (w, &b)) in rays.iter().zip(want.iter().zip(&blocked)) {
                let short = (bvh.closest_in::<SHORT_STACK>(ray).0, bvh.occluded_in::<SHORT_STACK>(ray).0);
                let full = (bvh.closest_in::<STACK>(ray).0, bvh.occluded_in::<STACK>(ray).0);
                for (h, o) in [short, full] {
                    assert_eq!((key(&h), o), (key(w), b), "{ray:?}");
                }
            }
        }
    }
}
