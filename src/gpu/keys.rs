//! What the GPU casters' keys (`geometry::hit_key`) stand for on the host: the one
//! reading of a key that the PDACRT twin and the BVH baseline share.

pub(crate) use crate::cast::flat::hits_of_keys;
use crate::error::Result;
use crate::geometry::hit_key::BLOCKED;
use crate::geometry::{Hit, Ray};
use std::time::Instant;

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
