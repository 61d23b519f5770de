//! What the GPU casters' keys (`geometry::hit_key`) stand for on the host: the one
//! reading of a key that the PDACRT twin and the BVH baseline share.

use crate::cast::pdacrt::kernels::{BLOCKED, NO_HIT, hit_of_key};
use crate::error::Result;
use crate::geometry::{Hit, Ray, hit_key};
use std::time::Instant;

/// The hits that closest-hit keys stand for, barycentrics recomputed on the host from
/// the triangles the keys index.
pub(crate) fn hits_of_keys(tris: &[[f32; 9]], rays: &[Ray], keys: &[u64], hits: &mut [Hit]) {
    for ((h, r), &k) in hits.iter_mut().zip(rays).zip(keys) {
        let tri = if k == NO_HIT { [0.0; 9] } else { tris[hit_key::prim_of(k) as usize] };
        *h = hit_of_key(r, k, tri);
    }
}

/// Any-hit keys as occlusion flags.
fn occlusion_of_keys(keys: &[u64], out: &mut [bool]) {
    out.iter_mut().zip(keys).for_each(|(o, &k)| *o = k == BLOCKED);
}

/// A closest-hit call of a GPU caster: its keys from `trace`, then the hits they stand
/// for. Returns the call's seconds.
pub(crate) fn closest_by_keys(
    tris: &[[f32; 9]],
    rays: &[Ray],
    hits: &mut [Hit],
    trace: impl FnOnce() -> Result<Vec<u64>>,
) -> Result<f64> {
    assert_eq!(rays.len(), hits.len(), "one hit slot per ray");
    let start = Instant::now();
    let keys = trace()?;
    hits_of_keys(tris, rays, &keys, hits);
    Ok(start.elapsed().as_secs_f64())
}

/// An occlusion call of a GPU caster: its any-hit keys from `trace`, as flags. Returns
/// the call's seconds.
pub(crate) fn occluded_by_keys(out: &mut [bool], trace: impl FnOnce() -> Result<Vec<u64>>) -> Result<f64> {
    let start = Instant::now();
    let keys = trace()?;
    assert_eq!(keys.len(), out.len(), "one result slot per ray");
    occlusion_of_keys(&keys, out);
    Ok(start.elapsed().as_secs_f64())
}
