//! Whole renders on the GPU (`cuda/render.cu`, `cuda/render_driver.cuh`): one pass at a
//! time of CIS-LBDPT as a stream of named kernels (light stream, camera stream: generate,
//! extend through the GPU BVH, sort by material, shade, connect, accumulate, retire,
//! compact and regenerate) or of LVC-BDPT as megakernels (one thread per light subpath,
//! per cached subpath's splats and per pixel, each tracing its own rays through the same
//! BVH). The kernels are ports of the Rust integrators' kernels, drawing the same random
//! numbers in the same order; each pass's estimates and camera splats come back to a
//! host [`Film`], so the GPU image accumulates as the CPU's does.

use super::ffi::{Library, library_path};
use super::scene::{SceneTables, WrCisScene};
use crate::error::{Error, Result};
use crate::film::Film;
use crate::geometry::{SLAB_WIDEN, hit_slack, magnitude};
use crate::lights::{Light, Lights};
use crate::render::cis::kernels::MAX_DRAWS;
use crate::render::{IntegratorKind, RenderOptions};
use crate::scene::Scene;
use glam::{Vec2, Vec3};
use std::ffi::c_void;
use std::path::PathBuf;

/// `WrRenderSettings` of `cuda/render_api.h`.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default)]
struct WrRenderSettings {
    method: u32,
    sort: u32,
    resampled: u32,
    regenerate: u32,
    candidates: u32,
    draws: u32,
    light_paths: u32,
    pool: u32,
    seed: u64,
    widen: f32,
    grow: f32,
    per_iteration: u32,
}

/// What the GPU did for a render's set-up or one pass (`WrRenderStats` of
/// `cuda/render_api.h`).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct GpuRenderStats {
    /// Set-up: the GPU BVH's build, milliseconds of GPU time.
    pub build_ms: f64,
    /// The pass's GPU time (CUDA events), before its estimates and splats are read back.
    pub pass_ms: f64,
    /// Of which the light pass (at the first pass of an iteration) and the pass's camera splats.
    pub light_ms: f64,
    /// Reading back the estimates and splats (host wall time).
    pub readback_ms: f64,
    /// Rays the stream cast (the megakernels trace theirs inside their threads, uncounted).
    pub rays: u64,
    /// Bounces of the camera stream.
    pub bounces: u64,
    /// Light vertex cache entries.
    pub cache_entries: u64,
    /// Visible camera splats.
    pub splats: u64,
}

/// CIS-LBDPT or the LVC-BDPT megakernels rendering on the GPU.
pub struct GpuRender {
    handle: *mut c_void,
    lib: Library,
    setup: GpuRenderStats,
    size: (u32, u32),
}

// SAFETY: the handle is used by one `&mut self` call at a time, and the CUDA runtime
// allows a context to be used from any host thread.
unsafe impl Send for GpuRender {}

impl Drop for GpuRender {
    fn drop(&mut self) {
        // SAFETY: `handle` came from `wr_render_create` and is dropped once, before `lib`.
        unsafe { (self.lib.render.destroy)(self.handle) }
    }
}

impl GpuRender {
    /// The render `opts` asks for (`integrator` `cis`, with its switches, or `lvc-mk`)
    /// of `scene` on the GPU of the library at [`library_path`]: uploads the scene and
    /// builds the GPU BVH.
    pub fn new(scene: &Scene, opts: &RenderOptions) -> Result<GpuRender> {
        Self::with_library(library_path(), scene, opts)
    }

    /// As [`GpuRender::new`], with the library at `path` (the CPU build of the port,
    /// `cuda/cis_host_check.cpp`, serves the same interface).
    pub fn with_library(path: impl Into<PathBuf>, scene: &Scene, opts: &RenderOptions) -> Result<GpuRender> {
        let settings = settings(scene, opts)?;
        let lib = Library::open(path.into())?;
        let tables = SceneTables::new(scene, "the GPU renders")?;
        let s: WrCisScene = tables.record(scene, opts, (settings.resampled, settings.candidates, settings.draws));
        let (mut handle, mut setup) = (std::ptr::null_mut(), GpuRenderStats::default());
        // SAFETY: every pointer in `s` points into `tables`, alive for the call, with
        // the counts given; the library copies what it keeps. The records have the
        // header's layouts.
        let rc = unsafe {
            (lib.render.create)(
                (&s as *const WrCisScene).cast(),
                (&settings as *const WrRenderSettings).cast(),
                &mut handle,
                (&mut setup as *mut GpuRenderStats).cast(),
            )
        };
        if rc != 0 {
            return Err(lib.error_from(lib.render.last_error, "setting up the GPU render"));
        }
        Ok(GpuRender { handle, lib, setup, size: (opts.width, opts.height) })
    }

    /// The device the library renders on.
    pub fn device_name(&self) -> Result<String> {
        self.lib.device_name()
    }

    /// What the set-up did (the BVH build).
    pub fn setup(&self) -> GpuRenderStats {
        self.setup
    }

    /// Renders pass `pass` and adds it to `film` (its camera splats, then its
    /// estimates, as the CPU integrators add theirs).
    pub fn render_pass(&mut self, pass: u32, film: &mut Film) -> Result<GpuRenderStats> {
        if (film.width, film.height) != self.size {
            return Err(Error::BadSetting(format!(
                "the GPU render is {}x{}, the film {}x{}",
                self.size.0, self.size.1, film.width, film.height
            )));
        }
        let pixels = film.width as usize * film.height as usize;
        let mut estimates = vec![0f32; 3 * pixels];
        let (mut splats, mut n_splats, mut stats) = (std::ptr::null(), 0u64, GpuRenderStats::default());
        // SAFETY: `estimates` holds 3 floats per pixel of the film, which has the render's
        // size; the library writes the splat pointer and count and the stats record.
        let rc = unsafe {
            (self.lib.render.pass)(
                self.handle,
                pass,
                estimates.as_mut_ptr(),
                &mut splats,
                &mut n_splats,
                (&mut stats as *mut GpuRenderStats).cast(),
            )
        };
        if rc != 0 {
            return Err(self.lib.error_from(self.lib.render.last_error, "rendering a pass on the GPU"));
        }
        let records: &[[f32; 5]] = if n_splats == 0 {
            &[]
        } else {
            // SAFETY: the library keeps `n_splats` records of 5 floats at `splats` until
            // its next call on this handle, which `&mut self` rules out meanwhile.
            unsafe { std::slice::from_raw_parts(splats.cast(), n_splats as usize) }
        };
        film.add_splats(records.iter().map(|r| (Vec2::new(r[0], r[1]), Vec3::new(r[2], r[3], r[4]))));
        let est: Vec<Vec3> = estimates.chunks_exact(3).map(Vec3::from_slice).collect();
        film.add_pass(pass, &est);
        Ok(stats)
    }
}

/// The library's settings for `opts`, or why the GPU renders cannot render them.
fn settings(scene: &Scene, opts: &RenderOptions) -> Result<WrRenderSettings> {
    use crate::filter::{Filter, FilterMode};
    let refuse = |why: &str| Err(Error::BadSetting(format!("the GPU renders {why}")));
    if opts.strategy.is_some() {
        return refuse("render every strategy; strategy images are not ported");
    }
    if opts.filter_mode == FilterMode::Sample && opts.filter != Filter::Box {
        return refuse("sample the box filter only; use --filter box, or --filter-mode splat for another filter");
    }
    if scene.camera.aperture_radius > 0.0 {
        return refuse("have a pinhole camera only (the scene's camera has an aperture)");
    }
    // Every ray starts at the camera, a light or a point offset from a surface: grow the
    // BVH's boxes for the largest of those origins, as geometry::batch_slack does.
    let lights = Lights::new(scene);
    let point_lights = lights.lights.iter().filter_map(|l| match l {
        Light::Point { position, .. } => Some(position.abs().max_element()),
        Light::Area { .. } => None,
    });
    let mag = magnitude(&scene.triangle_vertices());
    let origins = point_lights.fold(mag.max(scene.camera.position.abs().max_element()), f32::max);
    let mut s = WrRenderSettings {
        seed: opts.seed,
        widen: SLAB_WIDEN,
        grow: hit_slack(mag, origins * 1.001 + 1e-3),
        ..Default::default()
    };
    match opts.integrator {
        IntegratorKind::Cis => {
            let p = opts.cis;
            s.sort = p.sort as u32;
            s.resampled = p.importance as u32;
            s.regenerate = p.regenerate as u32;
            s.candidates = if p.importance { p.candidates } else { 0 };
            s.draws = p.draws.min(MAX_DRAWS as u32);
            s.light_paths = p.light_paths;
            s.pool = p.pool;
            s.per_iteration = p.iterations().0;
        }
        IntegratorKind::LvcMegakernel => {
            s.method = 1;
            s.draws = opts.lvc.connections;
            s.light_paths = opts.lvc.light_paths;
            s.per_iteration = opts.lvc.iterations().0;
        }
        other => {
            return refuse(&format!("are CIS-LBDPT (cis) and the LVC-BDPT megakernels (lvc-mk), not {}", other.name()));
        }
    }
    Ok(s)
}

/// What a whole render on the GPU did ([`render_on_gpu`]).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct GpuRunStats {
    /// Passes rendered (samples per pixel).
    pub passes: u32,
    /// Wall time of the passes, seconds (set-up left out).
    pub seconds: f64,
    /// The set-up: the GPU BVH's build, milliseconds.
    pub build_ms: f64,
    /// Sums over the passes of their GPU time, of the light passes' part of it, and of
    /// the read-backs, milliseconds.
    pub gpu_ms: f64,
    /// See `gpu_ms`.
    pub light_ms: f64,
    /// See `gpu_ms`.
    pub readback_ms: f64,
}

/// Renders `scene` as `opts` says (its integrator `cis` or `lvc-mk`, its budget in
/// samples or seconds) on the GPU of the library at [`library_path`], into a new film;
/// `on_pass(passes done)` after each pass returns false to stop early.
pub fn render_on_gpu(
    scene: &Scene,
    opts: &RenderOptions,
    mut on_pass: impl FnMut(u32) -> bool,
) -> Result<(Film, GpuRunStats)> {
    use crate::render::Budget;
    let mut gpu = GpuRender::new(scene, opts)?;
    let mut film = opts.film()?;
    let mut run = GpuRunStats { build_ms: gpu.setup().build_ms, ..Default::default() };
    let start = std::time::Instant::now();
    loop {
        let done = match opts.budget {
            Budget::Samples(n) => run.passes >= n,
            Budget::Seconds(t) => run.passes > 0 && start.elapsed().as_secs_f64() >= t,
        };
        if done {
            break;
        }
        let s = gpu.render_pass(run.passes, &mut film)?;
        run.passes += 1;
        (run.gpu_ms, run.light_ms, run.readback_ms) =
            (run.gpu_ms + s.pass_ms, run.light_ms + s.light_ms, run.readback_ms + s.readback_ms);
        if !on_pass(run.passes) {
            break;
        }
    }
    run.seconds = start.elapsed().as_secs_f64();
    Ok((film, run))
}
