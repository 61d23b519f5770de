#![warn(missing_docs)]
//! # warpray
//!
//! Two published GPU ray-tracing algorithms run on CPUs, through the [`simt`] crate,
//! which emulates a SIMT machine on rayon and measures what a GPU would care about.
//!
//! This crate holds the renderer: a scene model of flat arrays ([`scene`]), one batch
//! ray-casting trait with several casters ([`cast`]), materials and lights, progressive
//! integrators ([`render`]) and film output ([`film`]).
//!
//! ```
//! use warpray::prelude::*;
//!
//! // The built-in Cornell box, the default BVH caster, and a tiny progressive render.
//! let scene = cornell_box();
//! let caster = Bvh4::new(&scene);
//! let opts = RenderOptions { width: 32, height: 32, budget: Budget::Samples(4), ..Default::default() };
//! let (film, stats) = render(&scene, &caster, &opts, |_, _| true).unwrap();
//! assert_eq!(film.passes, 4);
//! assert!(film.image_mean().max_element() > 0.0 && stats.rays > 0);
//!
//! // Batch ray casting: one hit per ray.
//! let rays = [Ray::new(Vec3::new(0.5, 1.5, 3.0), Vec3::new(0.0, 0.0, -1.0))];
//! let mut hits = [Hit::MISS];
//! caster.closest(&rays, &mut hits);
//! assert!((hits[0].t - 4.0).abs() < 1e-4); // the back wall at z = -1
//! ```

pub mod aov;
pub mod bsdf;
pub mod cast;
pub mod converge;
pub(crate) mod cost;
pub mod diff;
pub mod error;
pub mod film;
pub mod filter;
pub mod geometry;
#[cfg(feature = "cuda")]
pub mod gpu;
#[cfg(feature = "inspector")]
pub mod inspector;
pub mod lights;
pub mod limits;
pub mod machine;
#[cfg(test)]
pub(crate) mod sass;
/// PDACRT, one of the casters (`cast::pdacrt`), also at the crate's root.
pub use cast::pdacrt;
/// CIS-LBDPT lives with the other integrators under `render`; this is its old path.
pub use render::cis;
pub mod render;
pub mod sampling;
pub mod scene;

pub use glam;

/// The README's code, compiled as a doctest so it cannot rot.
#[cfg(doctest)]
#[doc = include_str!("../README.md")]
pub struct ReadmeDoctests;

/// The names most programs need.
pub mod prelude {
    pub use crate::cast::pdacrt::Pdacrt;
    pub use crate::cast::{BruteForce, Bvh4, BvhCaster, CastStats, CasterKind, Dacrt, RayCaster};
    pub use crate::error::{Error, Result};
    pub use crate::film::Film;
    pub use crate::geometry::{Aabb, Hit, Ray};
    pub use crate::render::{Budget, IntegratorKind, RenderOptions, RenderStats, render};
    pub use crate::scene::{Camera, Material, PointLight, Scene, SceneDesc, cornell_box, load_obj, load_scene};
    pub use glam::{Vec2, Vec3};
}
