//! The GPU baseline PDACRT is measured against (`cuda/bvh.cu`): a linear BVH rebuilt on
//! the GPU from Morton codes (Karras 2012) and traversed one ray per thread with a
//! stack, as a GPU programmer without RT cores would cast rays against geometry that
//! changes every frame. Its keys are PDACRT's (`geometry::hit_key`), bit for bit: the
//! same triangle test decides every hit.
//!
//! ```no_run
//! # use warpray::prelude::*;
//! use warpray::gpu::GpuBvh;
//! let scene = cornell_box();
//! let gpu = GpuBvh::new(&scene.triangle_vertices())?;
//! let built = gpu.last_build();
//! println!("{} inner nodes built in {:.3} ms on {}", built.nodes, built.build_ms, gpu.device_name());
//! # Ok::<(), warpray::error::Error>(())
//! ```

use super::ffi::{GpuBvhStats, Handle, Library, library_path};
use super::keys::{closest_by_keys, occluded_by_keys};
use crate::cast::{CastStats, RayCaster};
use crate::error::Result;
use crate::geometry::{Hit, Ray};
use rayon::prelude::*;
use std::path::PathBuf;
use std::sync::Mutex;

/// The GPU BVH behind [`RayCaster`]; [`GpuBvh::rebuild`] replaces the triangles (a
/// new frame) and builds again.
pub struct GpuBvh {
    // Dropped before the library that frees it.
    handle: Mutex<Handle>,
    lib: Library,
    tris: Vec<[f32; 9]>,
    /// The triangles' largest coordinate magnitude (`geometry::batch_slack`).
    magnitude: f32,
    device: String,
    build: GpuBvhStats,
    trace: Mutex<GpuBvhStats>,
}

impl GpuBvh {
    /// Opens the library at [`library_path`], uploads the triangles and builds.
    pub fn new(tris: &[[glam::Vec3; 3]]) -> Result<Self> {
        Self::with_library(library_path(), tris)
    }

    /// As [`GpuBvh::new`], with the library at `path`.
    pub fn with_library(path: impl Into<PathBuf>, tris: &[[glam::Vec3; 3]]) -> Result<Self> {
        let lib = Library::open(path.into())?;
        let device = lib.device_name()?;
        let handle = lib.bvh_create()?;
        let mut bvh = GpuBvh {
            handle: Mutex::new(handle),
            lib,
            tris: Vec::new(),
            magnitude: 0.0,
            device,
            build: GpuBvhStats::default(),
            trace: Mutex::new(GpuBvhStats::default()),
        };
        bvh.rebuild(tris)?;
        Ok(bvh)
    }

    /// Replaces the triangles and rebuilds; returns what the build did. On an error
    /// the structure is empty (every ray misses), never stale.
    pub fn rebuild(&mut self, tris: &[[glam::Vec3; 3]]) -> Result<GpuBvhStats> {
        (self.tris, _, self.magnitude) = crate::cast::flat::flatten(tris);
        self.build = GpuBvhStats::default();
        let handle = self.handle.get_mut().unwrap_or_else(|e| e.into_inner());
        let stats = self.lib.bvh_build(handle, &self.tris);
        if stats.is_err() {
            self.tris.clear();
        }
        self.build = stats?;
        Ok(self.build)
    }

    /// The GPU's name, compute capability and SM count.
    pub fn device_name(&self) -> &str {
        &self.device
    }

    /// What the most recent build did.
    pub fn last_build(&self) -> GpuBvhStats {
        self.build
    }

    /// What the most recent trace did.
    pub fn last_trace(&self) -> GpuBvhStats {
        *self.trace.lock().unwrap_or_else(|e| e.into_inner())
    }

    /// Every ray's key, as [`super::GpuPdacrt::trace_keys`].
    pub fn trace_keys(&self, rays: &[Ray], any_hit: bool) -> Result<Vec<u64>> {
        let mut keys = vec![u64::MAX; rays.len()];
        let handle = self.handle.lock().unwrap_or_else(|e| e.into_inner());
        let grow = crate::geometry::batch_slack(self.magnitude, rays.par_iter().map(|r| r.origin));
        let stats = self.lib.bvh_trace(&handle, rays, any_hit, grow, &mut keys)?;
        *self.trace.lock().unwrap_or_else(|e| e.into_inner()) = stats;
        Ok(keys)
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

    /// Working bytes: the rays and their keys on the device.
    fn cast_stats(&self, rays: usize, seconds: f64) -> CastStats {
        CastStats { rays, seconds, peak_working_bytes: 40 * rays, tests: self.last_trace().tests }
    }
}

/// As for [`super::GpuPdacrt`]: a failure of the GPU after the structure was built
/// panics with the library's message; the `try_` methods return it instead.
impl RayCaster for GpuBvh {
    fn name(&self) -> &'static str {
        "gpu-bvh"
    }

    fn closest(&self, rays: &[Ray], hits: &mut [Hit]) -> CastStats {
        self.try_closest(rays, hits).unwrap_or_else(|e| panic!("GPU BVH on {} failed: {e}", self.device))
    }

    fn occluded(&self, rays: &[Ray], out: &mut [bool]) -> CastStats {
        self.try_occluded(rays, out).unwrap_or_else(|e| panic!("GPU BVH on {} failed: {e}", self.device))
    }

    fn memory_bytes(&self) -> usize {
        self.build.bytes as usize
    }

    /// Each call is a round trip to the GPU: batches, not single rays.
    fn casts_single_rays(&self) -> bool {
        false
    }
}
