//! Batch ray casting: one trait for every caster.
//!
//! A caster is built once per scene and answers batches: [`RayCaster::closest`] fills
//! one [`Hit`](crate::geometry::Hit) per ray, [`RayCaster::occluded`] one `bool` per ray (any hit with
//! `t_min < t < t_max`). Each call returns [`CastStats`]. Rays that are not finite or
//! have a zero direction never hit anything.
//!
//! Casters here: [`BruteForce`] (the test oracle), [`BvhCaster`] (obvhs' compressed
//! wide BVH), [`Bvh4`] (warpray's own 4-wide BVH), [`Dacrt`] (divide-and-conquer, no stored structure) and
//! [`pdacrt::Pdacrt`] (DACRT breadth-first on the `simt` emulator), [`Lbvh`] (the GPU BVH
//! baseline's build and traversal on the emulator, kernel for kernel `cuda/bvh.cu`), and with the cargo
//! feature `embree`, [`embree::EmbreeCaster`] (Intel's Embree, the CPU baseline).

pub mod batches;
mod brute;
mod bvh;
mod bvh4;
mod caster;
mod dacrt;
#[cfg(feature = "embree")]
pub mod embree;
pub(crate) mod flat;
mod lbvh;
pub mod pdacrt;

pub use brute::BruteForce;
pub use bvh::{BvhBuild, BvhCaster, Traversal};
pub use bvh4::Bvh4;
pub use caster::{CastStats, CountingCaster, InThread, RayCaster, Triangles, any_hit_ids, intersect_ids, phases_json};
pub use dacrt::{Dacrt, DacrtParams};
pub use lbvh::Lbvh;

use crate::scene::Scene;

/// Which caster to build; parsed from the command line.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "cli", derive(clap::ValueEnum))]
pub enum CasterKind {
    /// obvhs compressed wide BVH (CWBVH), built in parallel.
    Bvh,
    /// warpray's own 4-wide BVH: binned SAH build in parallel, SIMD box and triangle
    /// tests. The renderer's default.
    Bvh4,
    /// Every ray against every triangle: the test oracle.
    Brute,
    /// Divide-and-conquer ray tracing (Mora 2011), parallel at the top levels.
    Dacrt,
    /// Breadth-first parallel DACRT (Ravichandran & Narayanan 2013) on the simt emulator.
    Pdacrt,
    /// A linear BVH built from Morton codes and traversed one ray per thread, on the
    /// simt emulator: the GPU baseline PDACRT is measured against.
    Lbvh,
    /// Intel's Embree with its default build (cargo feature `embree`).
    #[cfg(feature = "embree")]
    Embree,
}

impl CasterKind {
    /// Builds the caster of this kind for `scene`. Only Embree can fail (its library
    /// is opened at run time).
    pub fn build(self, scene: &Scene) -> crate::error::Result<Box<dyn RayCaster>> {
        Ok(match self {
            CasterKind::Bvh => Box::new(BvhCaster::new(scene)),
            CasterKind::Bvh4 => Box::new(Bvh4::new(scene)),
            CasterKind::Brute => Box::new(BruteForce::new(scene)),
            CasterKind::Dacrt => Box::new(Dacrt::new(scene)),
            CasterKind::Pdacrt => Box::new(crate::cast::pdacrt::Pdacrt::new(scene)),
            CasterKind::Lbvh => Box::new(Lbvh::new(scene)),
            #[cfg(feature = "embree")]
            CasterKind::Embree => Box::new(embree::EmbreeCaster::new(scene)?),
        })
    }

    /// Every kind this build offers.
    pub fn all() -> &'static [CasterKind] {
        &[
            CasterKind::Bvh,
            CasterKind::Bvh4,
            CasterKind::Brute,
            CasterKind::Dacrt,
            CasterKind::Pdacrt,
            CasterKind::Lbvh,
            #[cfg(feature = "embree")]
            CasterKind::Embree,
        ]
    }
}
