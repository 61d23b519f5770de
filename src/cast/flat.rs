//! Triangles as the emulated and CUDA kernels read them: nine floats each, and the hit
//! a closest-hit key stands for. PDACRT, the GPU BVH's twin and the GPU casters share
//! these, so a key means the same triangle and distance in all of them.

use crate::geometry::hit_key::{self, NONE};
use crate::geometry::{Aabb, Hit, Ray, RayShear, intersect_triangle, magnitude};
use glam::Vec3;
use rayon::prelude::*;

/// Triangles as the kernels read them (nine floats each), their bounding box and the
/// largest magnitude of their coordinates (`geometry::batch_slack`).
pub(crate) fn flatten(tris: &[[Vec3; 3]]) -> (Vec<[f32; 9]>, Aabb, f32) {
    let flat = tris
        .iter()
        .map(|t| {
            let [a, b, c] = t.map(|v| v.to_array());
            [a[0], a[1], a[2], b[0], b[1], b[2], c[0], c[1], c[2]]
        })
        .collect();
    (flat, tris.iter().fold(Aabb::EMPTY, |b, t| b.union(Aabb::from_points(t))), magnitude(tris))
}

/// A triangle's corners from its flat record.
#[inline]
pub(crate) fn corners(v: [f32; 9]) -> [Vec3; 3] {
    [Vec3::new(v[0], v[1], v[2]), Vec3::new(v[3], v[4], v[5]), Vec3::new(v[6], v[7], v[8])]
}

/// The hit a key stands for, with barycentrics from the same watertight test
/// (`tri` is the key's triangle; ignored for [`NONE`]).
pub(crate) fn hit_of_key(ray: &Ray, key: u64, tri: [f32; 9]) -> Hit {
    if key == NONE {
        return Hit::MISS;
    }
    let prim = hit_key::prim_of(key);
    let t = hit_key::t_of(key);
    let [a, b, c] = corners(tri);
    intersect_triangle(ray.origin, &RayShear::new(ray.dir), a, b, c, ray.t_min, t.next_up())
        .map_or(Hit { t, prim, u: 0.0, v: 0.0 }, |(t, u, v)| Hit { t, prim, u, v })
}

/// The hits that closest-hit keys stand for, barycentrics recomputed on the host from
/// the triangles the keys index.
pub(crate) fn hits_of_keys(tris: &[[f32; 9]], rays: &[Ray], keys: &[u64], hits: &mut [Hit]) {
    hits.par_iter_mut().zip(rays).zip(keys).for_each(|((h, r), &k)| {
        let tri = if k == NONE { [0.0; 9] } else { tris[hit_key::prim_of(k) as usize] };
        *h = hit_of_key(r, k, tri);
    });
}
