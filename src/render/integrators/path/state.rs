//! The path tracer's floor: a path's state between bounces and what a bounce leaves
//! for the shadow-ray batch, shared by the scalar shading (`shade.rs`), the shading
//! of diffuse hits on SIMD lanes (`lanes.rs`) and the wavefront loop (`mod.rs`).

use crate::geometry::Ray;
use crate::sampling::Rng;
use glam::Vec3;

#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) struct PathState {
    pub(super) pixel: u32,
    pub(super) rng: Rng,
    pub(super) ray: Ray,
    pub(super) throughput: Vec3,
    pub(super) radiance: Vec3,
    /// Solid-angle pdf of the BSDF sample that made `ray` (for MIS on emitter hits).
    pub(super) prev_pdf: f32,
    /// η² of the relative indices the path's refractions crossed (Russian roulette
    /// undoes the 1/η² that radiance took at each).
    pub(super) eta2: f32,
    pub(super) prev_delta: bool,
    pub(super) alive: bool,
}

/// A path's light sample this bounce, waiting for its shadow ray: the ray and the
/// radiance it brings if unblocked.
pub(super) type Shadow = Option<(Ray, Vec3)>;

/// What every path of a bounce shares: whether it is the camera's first hit, whether
/// emission there is the last thing the path adds (`max_depth`), and whether Russian
/// roulette applies after it.
#[derive(Clone, Copy, Debug)]
pub(super) struct Bounce {
    pub(super) first: bool,
    pub(super) last: bool,
    pub(super) roulette: bool,
}

impl Bounce {
    /// Bounce `depth` (0: the camera ray's hit) of a render with these depths.
    pub(super) fn new(depth: u32, max_depth: u32, rr_depth: u32) -> Bounce {
        Bounce { first: depth == 0, last: depth >= max_depth, roulette: depth + 1 >= rr_depth }
    }
}

#[cfg(test)]
mod tests {
    #[test]
    fn a_path_state_is_88_bytes() {
        // The figure the chunk size's comment (`mod.rs`) and docs/mitsuba.md give.
        assert_eq!(std::mem::size_of::<super::PathState>(), 88);
    }
}
