//! The BVH baseline: obvhs' compressed wide BVH (CWBVH, Ylitie et al. 2017), built with
//! PLOC in parallel. Closest hits use `ray_traverse`; shadow rays use
//! `ray_traverse_miss`, which stops at the first hit (`ray_traverse_anyhit` would visit
//! every hit). Triangles are tested with warpray's watertight test, as in every caster.
//!
//! obvhs 0.4 culls BVH nodes whose exit distance is below a fixed `t = 1e-4` (its node
//! test ignores `Ray::tmin`), which would lose hits closer than that. The ray handed
//! to obvhs therefore starts [`NODE_EPSILON_SHIFT`] (in `t` units) behind the real
//! origin; triangles are still tested from the real origin in real `t`.
//!
//! obvhs 0.4 also changes rays with a direction component of magnitude at most
//! `f32::EPSILON`: its `safe_inverse` replaces the reciprocal by ±1/ε (so the traversal
//! follows a slightly different ray, which leaves a box at once when the origin lies on
//! the box's face), and a `-0.0` component gets a negative reciprocal while the node
//! test picks near and far planes by `d < 0.0`, which inverts every slab (every such
//! ray missed). Those rays are traversed here instead ([`BvhCaster::traverse_robust`]):
//! over the same CWBVH nodes, child boxes decoded and rounded outward, tested with
//! warpray's conservative slab test, which decides a zero component by position.

use super::caster::{CastStats, RayCaster, Triangles, any_hit_ids, per_ray, triangles_bytes};
use crate::geometry::{Aabb, Hit, Ray, RayShear, intersect_triangle, inv_dir};
use crate::scene::Scene;
use glam::{Vec3, Vec3A};
use obvhs::{BvhBuildParams, cwbvh::CwBvh, cwbvh::builder::build_cwbvh};
use rayon::prelude::*;
use std::time::{Duration, Instant};

/// How far (in `t`) the ray given to obvhs starts behind the real origin: twice obvhs'
/// fixed node epsilon.
pub const NODE_EPSILON_SHIFT: f32 = 2e-4;

/// obvhs' compressed wide BVH (CWBVH), with a robust re-check of misses (see [`Traversal`]).
pub struct BvhCaster {
    /// How rays are traversed (see [`Traversal`]).
    pub traversal: Traversal,
    tris: Triangles,
    /// obvhs primitive index → scene triangle id (exact duplicates are built once,
    /// under their smallest id; outliers are left out).
    ids: Vec<u32>,
    /// Triangles with a coordinate beyond [`OUTLIER_COORDINATE`] (or not finite), which
    /// obvhs' build cannot take: tested against every ray.
    outliers: Vec<u32>,
    /// `None` for a scene with no triangles (obvhs needs at least one).
    bvh: Option<CwBvh>,
    /// Where a ray's origin must lie for obvhs' node test to be conservative on the
    /// padded boxes (see [`NodePadding`]); rays from elsewhere take the robust traversal.
    region: Aabb,
    build: BvhBuild,
    build_seconds: f64,
}

impl BvhCaster {
    /// Builds the BVH of a scene's triangles.
    pub fn new(scene: &Scene) -> Self {
        Self::from_triangles(scene.triangle_vertices())
    }

    /// Builds the BVH of a triangle list (obvhs' medium preset).
    pub fn from_triangles(tris: Triangles) -> Self {
        Self::with_build(tris, BvhBuild::default())
    }

    /// Builds the BVH of a triangle list with one of obvhs' build presets.
    pub fn with_build(tris: Triangles, build: BvhBuild) -> Self {
        let start = Instant::now();
        let regular = |t: &[Vec3; 3]| t.iter().all(|v| v.is_finite() && v.abs().max_element() <= OUTLIER_COORDINATE);
        let outliers: Vec<u32> =
            (0..tris.len() as u32).into_par_iter().filter(|&i| !regular(&tris[i as usize])).collect();
        let ids = unique_regular_ids(&tris, regular);
        let padding = NodePadding::of(ids.iter().map(|&i| &tris[i as usize]));
        let bvh = (!ids.is_empty()).then(|| {
            let boxes: Vec<PaddedBox> = ids.iter().map(|&i| padding.pad(&tris[i as usize])).collect();
            build_cwbvh(&boxes, build.params(), &mut Duration::default())
        });
        BvhCaster {
            traversal: Traversal::default(),
            tris,
            ids,
            outliers,
            bvh,
            region: padding.region,
            build,
            build_seconds: start.elapsed().as_secs_f64(),
        }
    }

    /// The scene id of obvhs primitive slot `slot`.
    #[inline]
    fn prim(&self, bvh: &CwBvh, slot: usize) -> u32 {
        self.ids[bvh.primitive_indices[slot] as usize]
    }

    /// Tests the outliers, shrinking `best` (ties: the smaller id).
    fn closest_outliers(&self, ray: &Ray, best: &mut Hit) -> u64 {
        let shear = RayShear::new(ray.dir);
        for &prim in &self.outliers {
            let [a, b, c] = self.tris[prim as usize];
            let far = best.t.next_up().min(ray.t_max);
            if let Some((t, u, v)) = intersect_triangle(ray.origin, &shear, a, b, c, ray.t_min, far)
                && best.loses_to(t, prim)
            {
                *best = Hit { t, prim, u, v };
            }
        }
        self.outliers.len() as u64
    }

    /// The same caster with another traversal mode.
    pub fn with_traversal(mut self, traversal: Traversal) -> Self {
        self.traversal = traversal;
        self
    }

    /// The ray obvhs traverses: shifted back by [`NODE_EPSILON_SHIFT`], with `t` shifted
    /// to match.
    fn obvhs_ray(ray: &Ray) -> obvhs::ray::Ray {
        let s = NODE_EPSILON_SHIFT;
        let origin = ray.origin - ray.dir * s;
        obvhs::ray::Ray::new(Vec3A::from(origin), Vec3A::from(ray.dir), ray.t_min + s, ray.t_max + s)
    }

    /// Closest hit of one ray, and the triangles it tested.
    fn closest_one(&self, bvh: &CwBvh, ray: &Ray) -> (Hit, u64) {
        let shear = RayShear::new(ray.dir);
        let mut best = Hit::MISS;
        let mut tests = 0u64;
        let mut obvhs_hit = obvhs::ray::RayHit::none();
        bvh.ray_traverse(Self::obvhs_ray(ray), &mut obvhs_hit, |_, id| {
            tests += 1;
            let prim = self.prim(bvh, id);
            let [a, b, c] = self.tris[prim as usize];
            // Up to one ulp past the best hit, so that a tie with a smaller id wins.
            let far = if best.is_hit() { best.t.next_up().min(ray.t_max) } else { ray.t_max };
            match intersect_triangle(ray.origin, &shear, a, b, c, ray.t_min, far) {
                Some((t, u, v)) if best.loses_to(t, prim) => {
                    best = Hit { t, prim, u, v };
                    t + NODE_EPSILON_SHIFT
                }
                _ => f32::INFINITY,
            }
        });
        (best, tests)
    }
}

/// obvhs' build presets, by what they trade (obvhs 0.4's `BvhBuildParams`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "cli", derive(clap::ValueEnum))]
pub enum BvhBuild {
    /// PLOC with the smallest search radius, one primitive per leaf, no reinsertion:
    /// the quickest build, the slowest traversal.
    Fastest,
    /// As `Fastest` with up to 8 primitives per leaf and 1 % reinsertion.
    VeryFast,
    /// A wider PLOC search and 2 % reinsertion.
    Fast,
    /// obvhs' default for a static scene: a medium PLOC search and 5 % reinsertion.
    #[default]
    Medium,
}

impl BvhBuild {
    fn params(self) -> BvhBuildParams {
        match self {
            BvhBuild::Fastest => BvhBuildParams::fastest_build(),
            BvhBuild::VeryFast => BvhBuildParams::very_fast_build(),
            BvhBuild::Fast => BvhBuildParams::fast_build(),
            BvhBuild::Medium => BvhBuildParams::medium_build(),
        }
    }
}

/// How [`BvhCaster`] traverses its BVH. Every mode sends the rays obvhs cannot
/// represent (a direction component of magnitude at most `f32::EPSILON`, `-0.0`
/// included), and rays from outside the region the node padding covers, through the
/// robust traversal.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "cli", derive(clap::ValueEnum))]
pub enum Traversal {
    /// obvhs' SIMD traversal for every other ray, over boxes padded so that its
    /// rounding cannot reject a box the ray enters (docs/bvh.md). The default.
    #[default]
    Fast,
    /// As `Fast`, and every miss or unblocked shadow ray is checked again by the
    /// robust traversal (a second line of defence, for verification).
    Checked,
    /// Every ray through the robust traversal: never rejects a box the ray enters
    /// (5–10× the trace time of `Fast`).
    Robust,
}

/// Triangles with a coordinate of larger magnitude are kept out of obvhs' build (its
/// SAH costs overflow `f32` near 1e19 and the build panics) and tested against every
/// ray instead.
pub const OUTLIER_COORDINATE: f32 = 1e15;

/// The ids of the regular triangles, each exact duplicate (same nine coordinates,
/// bit for bit) only once, under its smallest id, in increasing order. obvhs' build
/// takes quadratic time on coincident triangles (20,000 copies: 25 s); brute force
/// reports the smallest id of equally distant triangles, so the duplicates are never
/// needed. Found by a parallel sort of per-triangle hashes.
fn unique_regular_ids(tris: &Triangles, regular: impl Fn(&[Vec3; 3]) -> bool + Sync) -> Vec<u32> {
    let bits = |t: &[Vec3; 3]| t.map(|v| v.to_array().map(f32::to_bits));
    let hash = |t: &[Vec3; 3]| {
        bits(t)
            .iter()
            .flatten()
            .fold(0xcbf2_9ce4_8422_2325u64, |h, &w| (h ^ w as u64).wrapping_mul(0x0000_0100_0000_01b3))
    };
    let mut keyed: Vec<(u64, u32)> = (0..tris.len() as u32)
        .into_par_iter()
        .filter(|&i| regular(&tris[i as usize]))
        .map(|i| (hash(&tris[i as usize]), i))
        .collect();
    keyed.par_sort_unstable();
    // A triangle is dropped when an earlier member of its hash run is the same
    // triangle; runs of one (almost all) need no comparison.
    let mut duplicate = vec![false; tris.len()];
    let mut run = 0;
    for k in 1..keyed.len() {
        if keyed[k].0 != keyed[k - 1].0 {
            run = k;
            continue;
        }
        let t = bits(&tris[keyed[k].1 as usize]);
        if keyed[run..k].iter().any(|&(_, j)| bits(&tris[j as usize]) == t) {
            duplicate[keyed[k].1 as usize] = true;
        }
    }
    (0..tris.len() as u32).into_par_iter().filter(|&i| !duplicate[i as usize] && regular(&tris[i as usize])).collect()
}

/// How far every triangle's box is grown before obvhs builds over it, so that obvhs'
/// node test, which rounds without widening, can never reject a box the real ray enters.
///
/// obvhs computes a child's slab distances as `q · (2^e / d) + (p − o) / d` in `f32`
/// (quantized plane `q` ≤ 255, node origin `p`). Each step rounds once: converted back
/// to space (times `d`), the computed plane is off by at most about
/// `3ε (node extent + |p − o|)` per axis (ε = `f32::EPSILON`). A ray that meets a
/// triangle's true box stays inside the box grown by `δ` for a `t` interval reaching
/// `δ / |d_i|` to either side in every axis, so the computed interval is not empty as
/// long as `δ` exceeds that error. With the scene's bounds of diagonal `D` and largest
/// coordinate magnitude `R`, and origins kept within the bounds grown by `2D`
/// (`|p − o| ≤ 2R + 2D`), `δ = 16ε (3D + 2R)` leaves a margin of more than two. Rays
/// from farther away, and rays obvhs changes (a direction component of magnitude at
/// most ε, `-0.0` included), take the robust traversal. For a unit-sized scene `δ` is
/// about 2e-5 of its size: the extra boxes a ray enters cost nothing measurable.
#[derive(Clone, Copy, Debug)]
struct NodePadding {
    delta: f32,
    region: Aabb,
}

impl NodePadding {
    fn of<'t>(tris: impl Iterator<Item = &'t [Vec3; 3]>) -> NodePadding {
        let bounds = tris.flatten().fold(Aabb::EMPTY, |b, &v| b.grow(v));
        if bounds.min.x > bounds.max.x {
            return NodePadding { delta: 0.0, region: Aabb::EMPTY };
        }
        let diag = (bounds.max - bounds.min).length();
        let r = bounds.min.abs().max(bounds.max.abs()).max_element();
        let delta = 16.0 * f32::EPSILON * (3.0 * diag + 2.0 * r);
        let grow = Vec3::splat(2.0 * diag);
        NodePadding { delta, region: Aabb { min: bounds.min - grow, max: bounds.max + grow } }
    }

    fn pad(&self, t: &[Vec3; 3]) -> PaddedBox {
        let lo = t[0].min(t[1]).min(t[2]) - Vec3::splat(self.delta);
        let hi = t[0].max(t[1]).max(t[2]) + Vec3::splat(self.delta);
        PaddedBox(obvhs::aabb::Aabb::new(lo.into(), hi.into()))
    }
}

/// A triangle's box grown by [`NodePadding`]: what obvhs builds over.
struct PaddedBox(obvhs::aabb::Aabb);

impl obvhs::Boundable for PaddedBox {
    fn aabb(&self) -> obvhs::aabb::Aabb {
        self.0
    }
}

impl BvhCaster {
    /// True when obvhs' traversal is not known to be conservative for this ray: a
    /// direction component of magnitude at most `f32::EPSILON` (`-0.0` included), which
    /// obvhs replaces, or an origin outside the region [`NodePadding`] covers.
    fn needs_robust_traversal(&self, ray: &Ray) -> bool {
        let (o, r) = (ray.origin, &self.region);
        ray.dir.abs().min_element() <= f32::EPSILON || !(o.cmpge(r.min).all() && o.cmple(r.max).all())
    }
}

/// Node indices a robust traversal keeps on the thread's stack (8 children per level;
/// deeper trees spill to the heap).
const STACK: usize = 64;

/// Relative outward widening of decoded child boxes: two ulps of `f32`.
const WIDEN: f32 = 2.0 * f32::EPSILON;

impl BvhCaster {
    /// Closest hit (or any hit, with `any_hit`) by a traversal of the CWBVH nodes that
    /// never rejects a box the ray enters: child boxes decoded from their quantized
    /// planes and rounded outward by one ulp, tested with [`Aabb::intersect`]. Returns
    /// the hit and the triangles tested.
    fn traverse_robust(&self, bvh: &CwBvh, ray: &Ray, any_hit: bool) -> (Hit, u64) {
        let shear = RayShear::new(ray.dir);
        let inv = inv_dir(ray.dir);
        let mut best = Hit::MISS;
        let mut tests = 0u64;
        // A small stack on the thread's stack, spilling to the heap for unusually deep
        // trees (never a panic).
        let mut stack = [0u32; STACK];
        let mut spill: Vec<u32> = Vec::new();
        let mut len = 1;
        loop {
            let index = if let Some(i) = spill.pop() {
                i
            } else if len > 0 {
                len -= 1;
                stack[len]
            } else {
                break;
            };
            let node = &bvh.nodes[index as usize];
            let (ext, p) = (Vec3::from(node.compute_extent()), node.p);
            for child in 0..8 {
                if node.is_child_empty(child) {
                    continue;
                }
                // q · 2^e is exact; adding p rounds once, so one relative ulp outward
                // (plus the smallest normal, for boxes at zero) keeps the box conservative.
                let q = |v: [u8; 8]| v[child] as f32;
                let lo = p + Vec3::new(q(node.child_min_x), q(node.child_min_y), q(node.child_min_z)) * ext;
                let hi = p + Vec3::new(q(node.child_max_x), q(node.child_max_y), q(node.child_max_z)) * ext;
                let pad = |v: Vec3| v.abs() * WIDEN + Vec3::splat(f32::MIN_POSITIVE);
                let b = Aabb { min: lo - pad(lo), max: hi + pad(hi) };
                let far = best.t.min(ray.t_max);
                if b.intersect(ray.origin, inv, ray.t_min, far).is_none() {
                    continue;
                }
                if !node.is_leaf(child) {
                    let next = node.child_node_index(child);
                    if len < STACK {
                        stack[len] = next;
                        len += 1;
                    } else {
                        spill.push(next);
                    }
                    continue;
                }
                let (first, count) = node.child_primitives(child);
                for i in first..first + count {
                    let prim = self.prim(bvh, i as usize);
                    let [a, b, c] = self.tris[prim as usize];
                    tests += 1;
                    let far = if any_hit { ray.t_max } else { best.t.next_up().min(ray.t_max) };
                    if let Some((t, u, v)) = intersect_triangle(ray.origin, &shear, a, b, c, ray.t_min, far) {
                        // Equal distances: the smaller triangle id, as brute force keeps.
                        if best.loses_to(t, prim) {
                            best = Hit { t, prim, u, v };
                        }
                        if any_hit {
                            return (best, tests);
                        }
                    }
                }
            }
        }
        (best, tests)
    }
}

impl RayCaster for BvhCaster {
    fn name(&self) -> &'static str {
        match self.build {
            BvhBuild::Medium => "bvh",
            BvhBuild::Fast => "bvh-fast",
            BvhBuild::VeryFast => "bvh-very-fast",
            BvhBuild::Fastest => "bvh-fastest",
        }
    }

    fn closest(&self, rays: &[Ray], hits: &mut [Hit]) -> CastStats {
        per_ray(rays, hits, |ray| self.closest_single(ray))
    }

    fn occluded(&self, rays: &[Ray], out: &mut [bool]) -> CastStats {
        per_ray(rays, out, |ray| self.occluded_single(ray))
    }

    fn closest_single(&self, ray: &Ray) -> (Hit, u64) {
        let (h, tests) = match &self.bvh {
            Some(bvh)
                if ray.is_valid() && (self.traversal == Traversal::Robust || self.needs_robust_traversal(ray)) =>
            {
                self.traverse_robust(bvh, ray, false)
            }
            Some(bvh) if ray.is_valid() => match self.closest_one(bvh, ray) {
                // obvhs' node test can reject a box the ray enters exactly
                // at a corner (a ray through a shared vertex): check misses.
                (h, n) if !h.is_hit() && self.traversal == Traversal::Checked => {
                    let (h, m) = self.traverse_robust(bvh, ray, false);
                    (h, n + m)
                }
                found => found,
            },
            _ => (Hit::MISS, 0),
        };
        let (mut h, mut tests) = (h, tests);
        if ray.is_valid() && !self.outliers.is_empty() {
            tests += self.closest_outliers(ray, &mut h);
        }
        (h, tests)
    }

    fn occluded_single(&self, ray: &Ray) -> (bool, u64) {
        let mut tests = 0u64;
        let blocked = match &self.bvh {
            Some(bvh)
                if ray.is_valid() && (self.traversal == Traversal::Robust || self.needs_robust_traversal(ray)) =>
            {
                let (hit, n) = self.traverse_robust(bvh, ray, true);
                tests = n;
                hit.is_hit()
            }
            Some(bvh) if ray.is_valid() => {
                let shear = RayShear::new(ray.dir);
                let blocked = !bvh.ray_traverse_miss(Self::obvhs_ray(ray), |_, id| {
                    tests += 1;
                    let [a, b, c] = self.tris[self.prim(bvh, id) as usize];
                    // Any hit in the real interval counts; report it inside obvhs'.
                    intersect_triangle(ray.origin, &shear, a, b, c, ray.t_min, ray.t_max)
                        .map_or(f32::INFINITY, |_| ray.t_min + NODE_EPSILON_SHIFT)
                });
                // As for closest hits: an unblocked answer is checked.
                blocked
                    || (self.traversal == Traversal::Checked && {
                        let (hit, n) = self.traverse_robust(bvh, ray, true);
                        tests += n;
                        hit.is_hit()
                    })
            }
            _ => false,
        } || (ray.is_valid() && !self.outliers.is_empty() && {
            let (hit, n) = any_hit_ids(&self.tris, self.outliers.iter().copied(), ray, &RayShear::new(ray.dir));
            tests += n;
            hit
        });
        (blocked, tests)
    }

    fn memory_bytes(&self) -> usize {
        let bvh = self.bvh.as_ref().map_or(0, |b| {
            b.nodes.len() * std::mem::size_of::<obvhs::cwbvh::node::CwBvhNode>() + b.primitive_indices.len() * 4
        });
        bvh + triangles_bytes(&self.tris) + (self.ids.len() + self.outliers.len()) * 4
    }

    fn build_seconds(&self) -> f64 {
        self.build_seconds
    }
}
