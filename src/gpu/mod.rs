//! PDACRT on a real NVIDIA GPU (cargo feature `cuda`): the twin of [`crate::cast::pdacrt`],
//! kernel for kernel, in `cuda/pdacrt.cu`, so that what `simt` predicts can be checked
//! against hardware counters (`docs/gpu-check.md`).
//!
//! The CUDA side is a shared library built by `cuda/build.sh` with `nvcc` (its level
//! pipeline uses CUB's scans and selection, which need host-side CUDA compilation) and
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

mod cis;
mod ffi;
pub mod lines;
pub mod ncu;
pub mod source;

pub use cis::{BounceCheck, GpuCis, ShadeCheck, check_render};

use crate::cast::pdacrt::PdacrtParams;
use crate::cast::pdacrt::kernels::{BLOCKED, NO_HIT, hit_of_key};
use crate::cast::{CastStats, LEAF_PAIRS_FACTOR, RayCaster};
use crate::error::{Error, Result};
use crate::geometry::{Hit, Ray, SLAB_WIDEN};
pub use ffi::{DEFAULT_LIBRARY, LIBRARY_ENV, library_path};
use ffi::{Library, WrParams, WrStats};
use std::path::PathBuf;
use std::sync::Mutex;

/// What the GPU did in the most recent call.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct GpuStats {
    /// GPU time of the pipeline with the rays resident (CUDA events), milliseconds.
    pub trace_ms: f64,
    /// Host wall time of the call, uploads and downloads included, milliseconds.
    pub call_ms: f64,
    /// Ray–triangle tests made.
    pub tests: u64,
    /// Levels summed over chunks.
    pub levels: u32,
    /// Kernel and CUB launches.
    pub launches: u32,
    /// Device bytes of the working buffers (triangles excluded).
    pub working_bytes: u64,
}

impl From<WrStats> for GpuStats {
    fn from(s: WrStats) -> Self {
        GpuStats {
            trace_ms: s.trace_ms,
            call_ms: s.call_ms,
            tests: s.tests,
            levels: s.levels,
            launches: s.launches,
            working_bytes: s.peak_bytes,
        }
    }
}

/// PDACRT on the GPU, behind the same [`RayCaster`] trait as the CPU casters. The
/// keys (distance bits, triangle id) are those of [`crate::cast::pdacrt::Pdacrt`], bit for bit.
pub struct GpuPdacrt {
    // Dropped before the library that frees it.
    handle: Mutex<ffi::Handle>,
    lib: Library,
    tris: Vec<[f32; 9]>,
    device: String,
    /// Tunables, as on the CPU; `measure` and `inspect` have no GPU counterpart.
    pub params: PdacrtParams,
    last: Mutex<GpuStats>,
}

impl GpuPdacrt {
    /// Opens the library at [`library_path`] and uploads the triangles.
    pub fn new(tris: &[[glam::Vec3; 3]], params: PdacrtParams) -> Result<Self> {
        Self::with_library(library_path(), tris, params)
    }

    /// As [`GpuPdacrt::new`], with the library at `path`.
    pub fn with_library(path: impl Into<PathBuf>, tris: &[[glam::Vec3; 3]], params: PdacrtParams) -> Result<Self> {
        let lib = Library::open(path.into())?;
        let device = lib.device_name()?;
        let (flat, scene_box) = crate::cast::pdacrt::flatten(tris);
        let handle = lib.create(&flat, scene_box)?;
        Ok(GpuPdacrt {
            lib,
            handle: Mutex::new(handle),
            tris: flat,
            device,
            params,
            last: Mutex::new(GpuStats::default()),
        })
    }

    /// The GPU's name, compute capability and SM count.
    pub fn device_name(&self) -> &str {
        &self.device
    }

    /// What the most recent call did on the GPU.
    pub fn last_stats(&self) -> GpuStats {
        *self.last.lock().unwrap_or_else(|e| e.into_inner())
    }

    fn wr_params(&self) -> WrParams {
        let p = &self.params;
        WrParams {
            leaf_rays: p.leaf_rays,
            leaf_triangles: p.leaf_triangles,
            max_depth: p.max_depth,
            brute_force_block: p.brute_force_block,
            leaf_pairs: LEAF_PAIRS_FACTOR * p.leaf_rays as u64 * p.leaf_triangles as u64,
            chunk_rays: p.chunk_rays as u64,
            slab_widen: SLAB_WIDEN,
            reserved: 0,
        }
    }

    /// Every ray's key (`geometry::hit_key`): `u64::MAX` for a miss; with `any_hit`, 0
    /// for a blocked ray.
    pub fn trace_keys(&self, rays: &[Ray], any_hit: bool) -> Result<Vec<u64>> {
        let mut keys = vec![NO_HIT; rays.len()];
        let handle = self.handle.lock().unwrap_or_else(|e| e.into_inner());
        let stats = self.lib.trace(&handle, rays, any_hit, &self.wr_params(), &mut keys)?;
        *self.last.lock().unwrap_or_else(|e| e.into_inner()) = stats.into();
        Ok(keys)
    }

    /// The hits that closest-hit keys stand for (barycentrics recomputed on the host).
    pub fn hits_of_keys(&self, rays: &[Ray], keys: &[u64], hits: &mut [Hit]) {
        for ((h, r), &k) in hits.iter_mut().zip(rays).zip(keys) {
            let tri = if k == NO_HIT { [0.0; 9] } else { self.tris[crate::geometry::hit_key::prim_of(k) as usize] };
            *h = hit_of_key(r, k, tri);
        }
    }

    /// Closest hits, or the library's error.
    pub fn try_closest(&self, rays: &[Ray], hits: &mut [Hit]) -> Result<CastStats> {
        assert_eq!(rays.len(), hits.len(), "one hit slot per ray");
        let start = std::time::Instant::now();
        let keys = self.trace_keys(rays, false)?;
        self.hits_of_keys(rays, &keys, hits);
        Ok(self.cast_stats(rays.len(), start))
    }

    /// Occlusion, or the library's error.
    pub fn try_occluded(&self, rays: &[Ray], out: &mut [bool]) -> Result<CastStats> {
        assert_eq!(rays.len(), out.len(), "one result slot per ray");
        let start = std::time::Instant::now();
        let keys = self.trace_keys(rays, true)?;
        out.iter_mut().zip(&keys).for_each(|(o, &k)| *o = k == BLOCKED);
        Ok(self.cast_stats(rays.len(), start))
    }

    fn cast_stats(&self, rays: usize, start: std::time::Instant) -> CastStats {
        let s = self.last_stats();
        CastStats {
            rays,
            seconds: start.elapsed().as_secs_f64(),
            peak_working_bytes: s.working_bytes as usize,
            tests: s.tests,
        }
    }

    fn fail(&self, e: Error) -> ! {
        panic!("GPU PDACRT on {} failed: {e}", self.device)
    }
}

/// The trait's calls cannot return errors: a failure of the GPU after the caster was
/// made (out of device memory, a lost device) panics with the library's message; use
/// [`GpuPdacrt::try_closest`] / [`GpuPdacrt::try_occluded`] to handle it instead.
impl RayCaster for GpuPdacrt {
    fn name(&self) -> &'static str {
        "gpu-pdacrt"
    }

    fn closest(&self, rays: &[Ray], hits: &mut [Hit]) -> CastStats {
        self.try_closest(rays, hits).unwrap_or_else(|e| self.fail(e))
    }

    fn occluded(&self, rays: &[Ray], out: &mut [bool]) -> CastStats {
        self.try_occluded(rays, out).unwrap_or_else(|e| self.fail(e))
    }

    fn memory_bytes(&self) -> usize {
        self.tris.len() * 36
    }
}
