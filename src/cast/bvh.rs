//! The BVH baseline: obvhs' compressed wide BVH (CWBVH, Ylitie et al. 2017), built with
//! PLOC in parallel. Closest hits use `ray_traverse`; shadow rays use
//! `ray_traverse_miss`, which stops at the first hit (`ray_traverse_anyhit` would visit
//! every hit). Triangles are tested with warpray's watertight test, as in every caster.
//!
//! obvhs 0.4 culls BVH nodes whose exit distance is below a fixed `t = 1e-4` (its node
//! test ignores `Ray::tmin`), which would lose hits closer than that. The ray handed
//! to obvhs therefore starts [`NODE_EPSILON_SHIFT`] (in `t` units) behind the real
//! origin; triangles are still tested from the real origin in real `t`.

use super::{CastStats, RayCaster, Triangles, timed, triangles_bytes};
use crate::geometry::{Hit, Ray, RayShear, intersect_triangle};
use crate::scene::Scene;
use glam::Vec3A;
use obvhs::{BvhBuildParams, cwbvh::CwBvh, cwbvh::builder::build_cwbvh_from_tris, triangle::Triangle};
use rayon::prelude::*;
use std::time::{Duration, Instant};

/// How far (in `t`) the ray given to obvhs starts behind the real origin: twice obvhs'
/// fixed node epsilon.
pub const NODE_EPSILON_SHIFT: f32 = 2e-4;

pub struct BvhCaster {
    tris: Triangles,
    /// `None` for a scene with no triangles (obvhs needs at least one).
    bvh: Option<CwBvh>,
    build_seconds: f64,
}

impl BvhCaster {
    pub fn new(scene: &Scene) -> Self {
        Self::from_triangles(scene.triangle_vertices())
    }

    pub fn from_triangles(tris: Triangles) -> Self {
        let start = Instant::now();
        let bvh = (!tris.is_empty()).then(|| {
            let obvhs_tris: Vec<Triangle> =
                tris.iter().map(|t| Triangle { v0: t[0].into(), v1: t[1].into(), v2: t[2].into() }).collect();
            build_cwbvh_from_tris(&obvhs_tris, BvhBuildParams::medium_build(), &mut Duration::default())
        });
        BvhCaster { tris, bvh, build_seconds: start.elapsed().as_secs_f64() }
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
            let prim = bvh.primitive_indices[id];
            let [a, b, c] = self.tris[prim as usize];
            match intersect_triangle(ray.origin, &shear, a, b, c, ray.t_min, best.t.min(ray.t_max)) {
                Some((t, u, v)) => {
                    best = Hit { t, prim, u, v };
                    t + NODE_EPSILON_SHIFT
                }
                None => f32::INFINITY,
            }
        });
        (best, tests)
    }
}

impl RayCaster for BvhCaster {
    fn name(&self) -> &'static str {
        "bvh"
    }

    fn closest(&self, rays: &[Ray], hits: &mut [Hit]) -> CastStats {
        assert_eq!(rays.len(), hits.len(), "one hit slot per ray");
        timed(rays.len(), 0, || {
            rays.par_iter()
                .zip(hits.par_iter_mut())
                .with_min_len(64)
                .map(|(ray, hit)| {
                    let (h, tests) = match &self.bvh {
                        Some(bvh) if ray.is_valid() => self.closest_one(bvh, ray),
                        _ => (Hit::MISS, 0),
                    };
                    *hit = h;
                    tests
                })
                .sum()
        })
    }

    fn occluded(&self, rays: &[Ray], out: &mut [bool]) -> CastStats {
        assert_eq!(rays.len(), out.len(), "one result slot per ray");
        timed(rays.len(), 0, || {
            rays.par_iter()
                .zip(out.par_iter_mut())
                .with_min_len(64)
                .map(|(ray, o)| {
                    let mut tests = 0u64;
                    *o = match &self.bvh {
                        Some(bvh) if ray.is_valid() => {
                            let shear = RayShear::new(ray.dir);
                            !bvh.ray_traverse_miss(Self::obvhs_ray(ray), |_, id| {
                                tests += 1;
                                let [a, b, c] = self.tris[bvh.primitive_indices[id] as usize];
                                // Any hit in the real interval counts; report it inside obvhs'.
                                intersect_triangle(ray.origin, &shear, a, b, c, ray.t_min, ray.t_max)
                                    .map_or(f32::INFINITY, |_| ray.t_min + NODE_EPSILON_SHIFT)
                            })
                        }
                        _ => false,
                    };
                    tests
                })
                .sum()
        })
    }

    fn memory_bytes(&self) -> usize {
        let bvh = self.bvh.as_ref().map_or(0, |b| {
            b.nodes.len() * std::mem::size_of::<obvhs::cwbvh::node::CwBvhNode>() + b.primitive_indices.len() * 4
        });
        bvh + triangles_bytes(&self.tris)
    }

    fn build_seconds(&self) -> f64 {
        self.build_seconds
    }
}
