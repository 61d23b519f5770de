//! Progressive rendering: passes of one sample per pixel accumulate on a [`Film`]
//! until a sample count or a time budget is reached.
//!
//! Path length convention (as pbrt's): `max_depth` is the largest number of scattering
//! events on a path. 0 shows only emitters seen directly; 1 is direct lighting.
//! Russian roulette starts after 3 bounces.
//!
//! The floors, lowest first, each importing only from those below it: the settings
//! ([`options`], [`registry`]) and what a pass sees (`context`); the light-transport
//! core the integrators share ([`bidir`] vertices and connections, `mis`, `walk`,
//! `compact`); the light vertex cache ([`cache`]) that LVC-BDPT, its megakernel and
//! CIS-LBDPT share; the integrators, one room each ([`integrators`]); the renderer
//! ([`Renderer`], [`render`]). This file only names them.
//!
//! [`Film`]: crate::film::Film

pub mod bidir;
pub mod cache;
mod compact;
pub(crate) mod context;
pub mod integrators;
pub(crate) mod mis;
pub mod options;
pub mod registry;
mod renderer;
mod walk;

pub use integrators::bdpt::Bdpt;
pub use integrators::cis::{self, CisLbdpt};
pub use integrators::light::LightTracer;
pub use integrators::lvc::LvcBdpt;
pub use integrators::megakernel::LvcMegakernel;
pub use integrators::path::PathTracer;
pub use options::{
    Budget, CisParams, IntegratorKind, Iterations, LvcParams, MAX_SECONDS, RenderOptions, RenderStats, Strategy,
};
pub use registry::Variant;
pub use renderer::{Renderer, render};
