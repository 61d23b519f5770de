//! The floor of the BSDF files: what a sample is and which way a path carries light.
//! `mod.rs`, `layered.rs`, `microfacet.rs` and `plastic.rs` build on it.

use glam::Vec3;

/// Whether a path carries radiance (from the camera) or importance (from a light).
/// Refraction scales radiance by 1/η² but not importance (Veach 1997, ch. 5).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum TransportMode {
    /// Light flowing toward the camera (paths traced from the camera).
    Radiance,
    /// Importance flowing toward the lights (paths traced from the lights): adjoint BSDF.
    Importance,
}

/// A sampled direction. `weight = f · |cos θi| / pdf`; for delta lobes `f` and `pdf`
/// are the discrete probability and matching value, so the same identity holds.
#[derive(Clone, Copy, Debug)]
pub struct BsdfSample {
    /// Sampled incident direction, local frame.
    pub wi: Vec3,
    /// BSDF value for the pair.
    pub f: Vec3,
    /// Density of `wi` (solid angle), or the discrete probability of a delta lobe.
    pub pdf: f32,
    /// `f · |cos θi| / pdf`.
    pub weight: Vec3,
    /// Whether a delta lobe was sampled.
    pub delta: bool,
}
