//! Brute force: every ray against every triangle. O(rays × triangles); the oracle that
//! every other caster is tested against, and the leaf stage's reference.

use super::caster::{CastStats, RayCaster, Triangles, any_hit_ids, intersect_ids, timed, triangles_bytes};
use crate::geometry::{Hit, Ray, RayShear};
use crate::scene::Scene;
use rayon::prelude::*;

/// Every ray against every triangle: slow, simple, and the oracle the other casters are tested against.
pub struct BruteForce {
    tris: Triangles,
}

impl BruteForce {
    /// The caster for a scene's triangles.
    pub fn new(scene: &Scene) -> Self {
        BruteForce { tris: scene.triangle_vertices() }
    }

    /// The caster for a triangle list.
    pub fn from_triangles(tris: Triangles) -> Self {
        BruteForce { tris }
    }
}

impl RayCaster for BruteForce {
    fn name(&self) -> &'static str {
        "brute"
    }

    fn closest(&self, rays: &[Ray], hits: &mut [Hit]) -> CastStats {
        assert_eq!(rays.len(), hits.len(), "one hit slot per ray");
        let n = self.tris.len() as u32;
        timed(rays.len(), 0, || {
            rays.par_iter()
                .zip(hits.par_iter_mut())
                .with_min_len(16)
                .map(|(ray, hit)| {
                    *hit = Hit::MISS;
                    if !ray.is_valid() {
                        return 0;
                    }
                    intersect_ids(&self.tris, 0..n, ray, &RayShear::new(ray.dir), hit);
                    n as u64
                })
                .sum()
        })
    }

    fn occluded(&self, rays: &[Ray], out: &mut [bool]) -> CastStats {
        assert_eq!(rays.len(), out.len(), "one result slot per ray");
        let n = self.tris.len() as u32;
        timed(rays.len(), 0, || {
            rays.par_iter()
                .zip(out.par_iter_mut())
                .with_min_len(16)
                .map(|(ray, o)| {
                    let (hit, tests) = if ray.is_valid() {
                        any_hit_ids(&self.tris, 0..n, ray, &RayShear::new(ray.dir))
                    } else {
                        (false, 0)
                    };
                    *o = hit;
                    tests
                })
                .sum()
        })
    }

    fn memory_bytes(&self) -> usize {
        triangles_bytes(&self.tris)
    }
}
