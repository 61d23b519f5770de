//! PDACRT on the GPU behind [`RayCaster`]: the twin of [`crate::cast::pdacrt`] in
//! `cuda/pdacrt.cu`, kernel for kernel.

use super::ffi::{self, Library, WrParams, WrStats, library_path};
use super::keys::{closest_by_keys, hits_of_keys, occluded_by_keys};
use crate::cast::pdacrt::PdacrtParams;
use crate::cast::pdacrt::kernels::NO_HIT;
use crate::cast::{CastStats, RayCaster};
use crate::error::{Error, Result};
use crate::geometry::{Hit, Ray, SLAB_WIDEN};
use rayon::prelude::*;
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
    /// Host synchronisations that read totals back (two per level, one per pass).
    pub read_backs: u32,
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
            read_backs: s.read_backs,
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
    /// The triangles' largest coordinate magnitude (`geometry::batch_slack`).
    magnitude: f32,
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
        let (flat, scene_box, magnitude) = crate::cast::flat::flatten(tris);
        let handle = lib.create(&flat, scene_box)?;
        Ok(GpuPdacrt {
            lib,
            handle: Mutex::new(handle),
            tris: flat,
            magnitude,
            device,
            params,
            last: Mutex::new(GpuStats::default()),
        })
    }

    /// Replaces the triangles (a new frame of changing geometry): uploads them in place
    /// of the old ones, keeping the working buffers. PDACRT keeps no structure, so this
    /// is all a frame needs before tracing. Returns the host wall time of the copy to
    /// the device (as [`super::GpuBvhStats::upload_ms`]), milliseconds. On an error no
    /// triangle is left (every ray misses).
    pub fn set_triangles(&mut self, tris: &[[glam::Vec3; 3]]) -> Result<f64> {
        let (flat, scene_box, magnitude) = crate::cast::flat::flatten(tris);
        self.magnitude = magnitude;
        let start = std::time::Instant::now();
        let handle = self.handle.get_mut().unwrap_or_else(|e| e.into_inner());
        let done = self.lib.set_triangles(handle, &flat, scene_box);
        self.tris = if done.is_ok() { flat } else { Vec::new() };
        done?;
        Ok(start.elapsed().as_secs_f64() * 1e3)
    }

    /// The GPU's name, compute capability and SM count.
    pub fn device_name(&self) -> &str {
        &self.device
    }

    /// What the most recent call did on the GPU.
    pub fn last_stats(&self) -> GpuStats {
        *self.last.lock().unwrap_or_else(|e| e.into_inner())
    }

    fn wr_params(&self, rays: &[Ray]) -> WrParams {
        let p = &self.params;
        WrParams {
            leaf_rays: p.leaf_rays,
            leaf_triangles: p.leaf_triangles,
            max_depth: p.max_depth,
            brute_force_block: p.brute_force_block,
            leaf_pairs: p.leaf_pairs(),
            chunk_rays: p.chunk_rays as u64,
            slab_widen: SLAB_WIDEN,
            grow: crate::geometry::batch_slack(self.magnitude, rays.par_iter().map(|r| r.origin)),
        }
    }

    /// Every ray's key (`geometry::hit_key`): `u64::MAX` for a miss; with `any_hit`, 0
    /// for a blocked ray.
    pub fn trace_keys(&self, rays: &[Ray], any_hit: bool) -> Result<Vec<u64>> {
        let mut keys = vec![NO_HIT; rays.len()];
        let handle = self.handle.lock().unwrap_or_else(|e| e.into_inner());
        let stats = self.lib.trace(&handle, rays, any_hit, &self.wr_params(rays), &mut keys)?;
        *self.last.lock().unwrap_or_else(|e| e.into_inner()) = stats.into();
        Ok(keys)
    }

    /// The hits that closest-hit keys stand for (barycentrics recomputed on the host).
    pub fn hits_of_keys(&self, rays: &[Ray], keys: &[u64], hits: &mut [Hit]) {
        hits_of_keys(&self.tris, rays, keys, hits);
    }

    /// Closest hits, or the library's error.
    pub fn try_closest(&self, rays: &[Ray], hits: &mut [Hit]) -> Result<CastStats> {
        let seconds = closest_by_keys(&self.tris, rays, hits, || self.trace_keys(rays, false))?;
        Ok(self.cast_stats(rays.len(), seconds))
    }

    /// Occlusion, or the library's error.
    pub fn try_occluded(&self, rays: &[Ray], out: &mut [bool]) -> Result<CastStats> {
        let seconds = occluded_by_keys(out, || self.trace_keys(rays, true))?;
        Ok(self.cast_stats(rays.len(), seconds))
    }

    fn cast_stats(&self, rays: usize, seconds: f64) -> CastStats {
        let s = self.last_stats();
        CastStats { rays, seconds, peak_working_bytes: s.working_bytes as usize, tests: s.tests }
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

    /// Each call is a round trip to the GPU: batches, not single rays.
    fn casts_single_rays(&self) -> bool {
        false
    }
}
