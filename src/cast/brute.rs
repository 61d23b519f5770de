//! Brute force: every ray against every triangle. O(rays × triangles); the oracle that
//! every other caster is tested against, and the leaf stage's reference.

use super::caster::{CastStats, RayCaster, Triangles, any_hit_ids, intersect_ids, per_ray, triangles_bytes};
use crate::geometry::{Hit, Ray, RayShear};
use crate::scene::Scene;

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
        let n = self.tris.len() as u32;
        per_ray(rays, hits, |ray| {
            let mut hit = Hit::MISS;
            if !ray.is_valid() {
                return (hit, 0);
            }
            intersect_ids(&self.tris, 0..n, ray, &RayShear::new(ray.dir), &mut hit);
            (hit, n as u64)
        })
    }

    fn occluded(&self, rays: &[Ray], out: &mut [bool]) -> CastStats {
        let n = self.tris.len() as u32;
        per_ray(rays, out, |ray| {
            if ray.is_valid() { any_hit_ids(&self.tris, 0..n, ray, &RayShear::new(ray.dir)) } else { (false, 0) }
        })
    }

    fn memory_bytes(&self) -> usize {
        triangles_bytes(&self.tris)
    }
}
