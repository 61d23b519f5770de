//! The algorithms on a real NVIDIA GPU (cargo feature `cuda`): the twin of
//! [`crate::cast::pdacrt`], kernel for kernel, in `cuda/pdacrt.cu` ([`GpuPdacrt`]), so
//! that what `simt` predicts can be checked against hardware counters
//! (`docs/gpu-check.md`); CIS-LBDPT's shading and compaction ([`GpuCis`]); and the
//! baseline a GPU programmer would pick instead of PDACRT, a BVH rebuilt on the GPU and
//! traversed with a stack ([`GpuBvh`], `cuda/bvh.cu`).
//!
//! The CUDA side is a shared library built by `cuda/build.sh` with `nvcc` (its level
//! pipelines use CUB's scans, selection and sorts, which need host-side CUDA compilation) and
//! opened at run time, so building warpray with this feature needs no CUDA toolkit and
//! no GPU: [`GpuPdacrt::new`] says what is missing when either is absent.
//!
//! ```no_run
//! # use warpray::prelude::*;
//! use warpray::gpu::GpuPdacrt;
//! let scene = cornell_box();
//! let gpu = GpuPdacrt::new(&scene.triangle_vertices(), Default::default())?;
//! println!("tracing on {}", gpu.device_name());
//! # Ok::<(), warpray::error::Error>(())
//! ```

mod bvh;
pub mod calibrate;
mod cis;
mod ffi;
mod keys;
pub mod lines;
pub mod ncu;
mod pdacrt;
mod render;
mod scene;
pub mod source;
pub mod time_check;

pub use bvh::GpuBvh;
pub use cis::{BounceCheck, GpuCis, ShadeCheck, check_render};
pub use ffi::{DEFAULT_LIBRARY, GpuBvhStats, LIBRARY_ENV, library_path};
pub use pdacrt::{GpuPdacrt, GpuStats};
pub use render::{GpuRender, GpuRenderStats, GpuRunStats, render_on_gpu};
