//! The progressive renderer: validated settings, the integrator it dispatches to, and
//! [`render`], the loop of pass groups under a sample or time budget.

use super::bidir::MAX_PATH;
use super::context::{Context, Passes};
use super::integrators::Integrator;
use super::integrators::cis::CisLbdpt;
use super::integrators::cis::kernels::MAX_CAMERA_VERTICES;
use super::options::{Budget, IntegratorKind, RENDER_FIXED_BYTES, RenderOptions, RenderStats};
use crate::cast::{CastStats, CountingCaster, RayCaster};
use crate::error::{Error, Result};
use crate::film::Film;
use crate::lights::Lights;
use crate::limits::{MAX_SECONDS, check_memory};
use crate::scene::Scene;
use std::time::{Duration, Instant};

/// A progressive renderer: validated settings, the lights, and the integrator with its
/// buffers. [`render`] drives one; the inspector drives one pass at a time.
pub struct Renderer<'a> {
    scene: &'a Scene,
    caster: &'a dyn RayCaster,
    opts: RenderOptions,
    lights: Lights,
    /// Every triangle's unit normal, for the integrators' hits.
    normals: Vec<glam::Vec3>,
    integrator: Integrator,
    /// (shadow rays, caster calls) of every pass so far.
    counts: (u64, u64, u64),
    /// Whether caster calls ever ran at the same time.
    overlapped: bool,
}

impl<'a> Renderer<'a> {
    /// Checks the scene and settings and prepares the integrator.
    pub fn new(scene: &'a Scene, caster: &'a dyn RayCaster, opts: &RenderOptions) -> Result<Self> {
        scene.check_renderable()?;
        crate::film::check_size(opts.width, opts.height)?;
        let pixels = opts.width as u64 * opts.height as u64;
        let need = RENDER_FIXED_BYTES + pixels * opts.integrator.bytes_per_pixel();
        check_memory(need).map_err(|over| Error::OverMemoryBudget {
            what: format!("a {}x{} render with {}", opts.width, opts.height, opts.integrator.name()),
            over,
        })?;
        if let Budget::Seconds(s) = opts.budget
            && !(s > 0.0 && s <= MAX_SECONDS)
        {
            return Err(Error::BadSetting(format!("time budget {s} s must be positive and at most {MAX_SECONDS:e} s")));
        }
        if opts.max_depth > 1024 {
            return Err(Error::BadSetting(format!("max depth {} is absurd (at most 1024)", opts.max_depth)));
        }
        if opts.rr_depth == 0 {
            return Err(Error::BadSetting("rr_depth 0: Russian roulette starts after at least 1 bounce".into()));
        }
        // Full paths live in fixed-size stack lists (kernels cannot allocate).
        let limit = match opts.integrator {
            IntegratorKind::Path | IntegratorKind::Light => u32::MAX,
            IntegratorKind::Bdpt | IntegratorKind::Lvc | IntegratorKind::LvcMegakernel => (MAX_PATH - 2) as u32,
            IntegratorKind::Cis => (MAX_CAMERA_VERTICES - 2) as u32,
        };
        if opts.max_depth > limit {
            return Err(Error::BadSetting(format!(
                "the {} integrator supports max depth up to {limit}",
                opts.integrator.name()
            )));
        }
        if opts.integrator != IntegratorKind::Path && scene.camera.aperture_radius > 0.0 {
            return Err(Error::BadSetting(format!(
                "the {} integrator connects to a pinhole camera; set the aperture radius to 0",
                opts.integrator.name()
            )));
        }
        if opts.strategy.is_some() && matches!(opts.integrator, IntegratorKind::Path | IntegratorKind::Light) {
            return Err(Error::BadSetting(format!(
                "strategy images belong to the bidirectional integrators (bdpt, lvc, lvc-mk, cis); the {} integrator has none",
                opts.integrator.name()
            )));
        }
        if opts.integrator == IntegratorKind::LvcMegakernel
            && !caster.casts_single_rays()
            && caster.in_thread().is_none()
        {
            return Err(Error::BadSetting(format!(
                "the LVC megakernel casts its rays one at a time, which the {} caster is not built for; use --caster bvh (or lbvh, traversed in the kernel's threads)",
                caster.name()
            )));
        }
        let lights = Lights::new(scene);
        let normals = scene.unit_normals();
        let projection = scene.camera.projection(opts.width, opts.height);
        let integrator =
            Integrator::new(&Context { scene, lights: &lights, caster, opts, normals: &normals, projection });
        let r = Renderer {
            scene,
            caster,
            opts: opts.clone(),
            lights,
            normals,
            integrator,
            counts: (0, 0, 0),
            overlapped: false,
        };
        if let Some(p) = &opts.gpu_profile {
            let dev = r.device().ok_or_else(|| {
                Error::BadSetting(format!(
                    "a GPU profile predicts the time of emulated GPU kernels, and the {} integrator with the {} caster launches none (CIS-LBDPT, the LVC megakernel and the pdacrt and lbvh casters do)",
                    opts.integrator.name(),
                    caster.name()
                ))
            })?;
            dev.set_measure(true);
            dev.set_gpu_profile(Some(p.clone()));
        }
        Ok(r)
    }

    /// The settings it renders with.
    pub fn options(&self) -> &RenderOptions {
        &self.opts
    }

    /// An empty film of the render's size.
    pub fn film(&self) -> Result<Film> {
        self.opts.film()
    }

    /// Adds pass number `pass` (one sample per pixel) to `film`.
    /// The returned statistics count every caster call the pass made, whichever
    /// integrator made them and from whichever thread.
    pub fn pass(&mut self, pass: u32, film: &mut Film) -> CastStats {
        self.passes(pass, 1, film)
    }

    /// How many passes [`Renderer::passes`] renders together: as many as fit in one
    /// wave of 65,536 samples (light tracing, BDPT and LVC's wavefront form; at least
    /// one), so that a small image still hands the caster large batches; one for the
    /// path tracer, CIS-LBDPT and the LVC megakernel, which keep their own batches.
    pub fn pass_group(&self) -> u32 {
        self.integrator.pass_group(self.opts.width * self.opts.height)
    }

    /// Adds passes `first..first + count` to `film`: the same film, bit for bit, as
    /// that many calls of [`Renderer::pass`] in order, but rendered in groups of
    /// [`Renderer::pass_group`] passes whose samples share waves (and caster calls).
    /// The whole call runs on the rayon pool, so the integrator's parallel steps do
    /// not hand over from the calling thread one by one.
    pub fn passes(&mut self, first: u32, count: u32, film: &mut Film) -> CastStats {
        let counter = CountingCaster::new(self.caster);
        let ctx = Context {
            scene: self.scene,
            lights: &self.lights,
            caster: &counter,
            opts: &self.opts,
            normals: &self.normals,
            projection: self.scene.camera.projection(self.opts.width, self.opts.height),
        };
        let (group, per_pass) = (self.pass_group(), self.opts.width * self.opts.height);
        let integrator = &mut self.integrator;
        let mut body = || {
            let mut stats = CastStats::default();
            let end = first.saturating_add(count);
            let mut at = first;
            while at < end {
                let span = Passes { first: at, count: group.min(end - at), per_pass };
                stats = stats.merge(integrator.render_passes(&ctx, span, film));
                at += span.count;
            }
            stats
        };
        let own = rayon::scope(|_| body());
        let counted = counter.stats();
        self.counts.0 += counter.shadow_rays();
        self.counts.1 += counter.calls();
        self.counts.2 += counter.single_rays();
        self.overlapped |= counter.overlapped();
        CastStats { peak_working_bytes: counted.peak_working_bytes.max(own.peak_working_bytes), ..counted }
    }

    /// Shadow rays, caster calls and single rays of every pass so far (see
    /// [`RenderStats`]).
    pub fn ray_counts(&self) -> (u64, u64, u64) {
        self.counts
    }

    /// Whether caster calls of any pass so far ran at the same time (from several
    /// threads), so that their summed seconds overlap.
    pub fn casts_overlapped(&self) -> bool {
        self.overlapped
    }

    /// The CIS-LBDPT integrator, when that is the one running (queue records, device).
    pub fn cis(&self) -> Option<&CisLbdpt> {
        match &self.integrator {
            Integrator::Cis(c) => Some(c),
            _ => None,
        }
    }

    /// The CIS-LBDPT integrator, mutable (to set an observer: [`CisLbdpt::observe`]).
    pub fn cis_mut(&mut self) -> Option<&mut CisLbdpt> {
        match &mut self.integrator {
            Integrator::Cis(c) => Some(c),
            _ => None,
        }
    }

    /// The emulated device of the render, when anything in it runs on one: the
    /// caster's (PDACRT), which a `cis` integrator shares, or the integrator's own.
    /// Its kernel table and memory peak cover the whole render.
    pub fn device(&self) -> Option<&simt::Device> {
        self.integrator.device().or_else(|| self.caster.device())
    }
}

/// Renders `scene` with `caster`. `on_pass(pass_index, film)` is called after each pass
/// (progress bars, checkpoints); return `false` from it to stop early.
pub fn render(
    scene: &Scene,
    caster: &dyn RayCaster,
    opts: &RenderOptions,
    mut on_pass: impl FnMut(u32, &Film) -> bool,
) -> Result<(Film, RenderStats)> {
    let mut renderer = Renderer::new(scene, caster, opts)?;
    let mut film = renderer.film()?;
    let mut stats = RenderStats::default();
    let start = Instant::now();
    let mut pass_seconds: Option<f64> = None;
    loop {
        let done = match opts.budget {
            Budget::Samples(n) => stats.passes >= n,
            Budget::Seconds(s) => stats.passes > 0 && start.elapsed() >= Duration::from_secs_f64(s),
        };
        if done {
            break;
        }
        // Under a time budget the groups start at one pass and then take about an
        // eighth of the time left, so the clock (and `on_pass`) is read often enough.
        let group = match opts.budget {
            Budget::Samples(n) => renderer.pass_group().min(n - stats.passes),
            Budget::Seconds(s) => match pass_seconds {
                None => 1,
                Some(t) => {
                    let left = s - start.elapsed().as_secs_f64();
                    ((left / 8.0 / t.max(1e-9)).min(u32::MAX as f64) as u32).clamp(1, renderer.pass_group())
                }
            },
        };
        let group_start = Instant::now();
        let pass = renderer.passes(stats.passes, group, &mut film);
        pass_seconds = Some(group_start.elapsed().as_secs_f64() / group as f64);
        stats.rays += pass.rays as u64;
        stats.cast_seconds += pass.seconds;
        stats.tests += pass.tests;
        stats.peak_working_bytes = stats.peak_working_bytes.max(pass.peak_working_bytes);
        stats.passes += group;
        if !on_pass(stats.passes, &film) {
            break;
        }
    }
    stats.seconds = start.elapsed().as_secs_f64();
    (stats.shadow_rays, stats.cast_calls, stats.single_rays) = renderer.ray_counts();
    stats.cast_overlapped = renderer.casts_overlapped();
    stats.device = renderer.device().map(|d| (d.kernel_stats(), d.memory().peak));
    stats.launches = renderer.device().map(|d| (d.launch_log(), d.launch_mark())).unwrap_or_default();
    Ok((film, stats))
}
