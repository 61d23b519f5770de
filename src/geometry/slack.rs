//! How far the casters that cull by boxes (BVH4, DACRT) grow them, so that a hit the
//! watertight test reports just off a triangle is never culled.

use glam::Vec3;

/// The watertight test computes a triangle's corners relative to the ray origin and
/// sheared, rounding each step: a hit it reports can lie off the triangle (or behind
/// the origin) by a few ε times the corners' distance from the origin. A ray starting
/// 3e-5 under the conference room's floor (coordinates near 1,000) and leaving it is
/// reported to hit the floor at t = 3.8e-5, outside the floor's exact box. Casters that
/// cull by boxes grow them by [`hit_slack`] so that every such hit stays inside.
const HIT_SLACK: f32 = 32.0 * f32::EPSILON;

/// How far to grow boxes for rays from `origin` (or from origins of at most that
/// magnitude) in a scene whose largest coordinate magnitude is `magnitude`.
#[inline]
pub(crate) fn hit_slack(magnitude: f32, origin: f32) -> f32 {
    HIT_SLACK * (magnitude + origin)
}

/// How far to grow boxes for a whole batch of rays, given their origins: [`hit_slack`]
/// for the largest finite origin coordinate (DACRT and PDACRT grow once per call;
/// BVH4 per ray). Rays with a non-finite origin are invalid and traced by no caster.
pub(crate) fn batch_slack(magnitude: f32, origins: impl rayon::iter::ParallelIterator<Item = Vec3>) -> f32 {
    use rayon::prelude::*;
    let largest = origins.map(|o| o.abs().max_element()).filter(|c| c.is_finite()).reduce(|| 0.0, f32::max);
    hit_slack(magnitude, largest)
}

/// The largest magnitude of the finite coordinates of a triangle list.
pub(crate) fn magnitude(tris: &[[Vec3; 3]]) -> f32 {
    use rayon::prelude::*;
    tris.par_iter()
        .flat_map_iter(|t| t.iter().flat_map(|v| v.to_array()))
        .filter(|c| c.is_finite())
        .map(f32::abs)
        .reduce(|| 0.0, f32::max)
}
