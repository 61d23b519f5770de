//! Progressive rendering: passes of one sample per pixel accumulate on a [`Film`]
//! until a sample count or a time budget is reached.
//!
//! Path length convention (as pbrt's): `max_depth` is the largest number of scattering
//! events on a path. 0 shows only emitters seen directly; 1 is direct lighting.
//! Russian roulette starts after 3 bounces.

pub mod bdpt;
pub mod bidir;
pub mod cis;
mod compact;
mod light;
pub mod lvc;
pub(crate) mod megakernel;
pub(crate) mod mis;
mod path;
pub mod registry;
mod walk;

pub use bdpt::Bdpt;
pub use light::LightTracer;
pub use lvc::{LvcBdpt, LvcParams};
pub use path::PathTracer;
pub use registry::Variant;

use crate::cast::{CastStats, CountingCaster, RayCaster};
use crate::error::{Error, Result};
use crate::film::Film;
use crate::lights::Lights;
use crate::scene::Scene;
use std::time::{Duration, Instant};
use walk::Passes;

/// Light-transport algorithms selectable from the command line and the library.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "cli", derive(clap::ValueEnum))]
pub enum IntegratorKind {
    /// Unidirectional path tracing with next-event estimation and MIS.
    Path,
    /// Light tracing: paths from the lights, splatted onto the film through the camera.
    Light,
    /// Bidirectional path tracing with MIS over all strategies.
    Bdpt,
    /// BDPT with a light vertex cache (LVC-BDPT), one task per path.
    Lvc,
    /// CIS-LBDPT: LVC-BDPT streamed on the simt emulator, sorted by material, with
    /// importance-sampled connections.
    Cis,
}

impl IntegratorKind {
    /// The command-line name.
    pub fn name(self) -> &'static str {
        match self {
            IntegratorKind::Path => "path",
            IntegratorKind::Light => "light",
            IntegratorKind::Bdpt => "bdpt",
            IntegratorKind::Lvc => "lvc",
            IntegratorKind::Cis => "cis",
        }
    }

    /// The unidirectional and bidirectional references (the light-transport core).
    pub const CORE: [IntegratorKind; 3] = [IntegratorKind::Path, IntegratorKind::Light, IntegratorKind::Bdpt];
    /// Every integrator.
    pub const ALL: [IntegratorKind; 5] =
        [IntegratorKind::Path, IntegratorKind::Light, IntegratorKind::Bdpt, IntegratorKind::Lvc, IntegratorKind::Cis];
}

/// A running integrator with its buffers.
enum Integrator {
    Path(PathTracer),
    Light(LightTracer),
    Bdpt(Bdpt),
    Lvc(LvcBdpt),
    Cis(Box<cis::CisLbdpt>),
}

impl std::str::FromStr for IntegratorKind {
    type Err = Error;
    fn from_str(s: &str) -> Result<Self> {
        IntegratorKind::ALL
            .into_iter()
            .find(|k| k.name().eq_ignore_ascii_case(s))
            .ok_or_else(|| Error::BadSetting(format!("unknown integrator '{s}' (known: path, light, bdpt, lvc, cis)")))
    }
}

/// How long to render.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Budget {
    /// This many samples per pixel.
    Samples(u32),
    /// Passes until this much wall time has gone (at least one pass). The clock is
    /// read between groups of passes ([`Renderer::pass_group`]), each sized to about an
    /// eighth of the time left, so a render overshoots by at most about that much.
    Seconds(f64),
}

#[derive(Clone, Debug)]
/// What to render and how.
pub struct RenderOptions {
    /// Image width, pixels.
    pub width: u32,
    /// Image height, pixels.
    pub height: u32,
    /// Samples per pixel or a time budget.
    pub budget: Budget,
    /// Largest number of bounces (0: emitters only, 1: direct light).
    pub max_depth: u32,
    /// Random seed: the same seed gives the same image at any thread count.
    pub seed: u64,
    /// The light-transport algorithm.
    pub integrator: IntegratorKind,
    /// Light-vertex-cache settings (LVC-BDPT).
    pub lvc: LvcParams,
    /// CIS-LBDPT settings and switches.
    pub cis: cis::CisParams,
    /// BDPT, LVC-BDPT and CIS-LBDPT: keep one strategy's contributions and drop the
    /// rest (pbrt-v4's strategy images), for tests that check each strategy on its own.
    /// The random streams stay those of the full render in LVC and CIS (dropped
    /// strategies are still sampled, so resampled connections choose among the same
    /// candidates); BDPT skips dropped strategies outright.
    pub strategy: Option<Strategy>,
    /// Pixel reconstruction filter (box by default; Mitsuba scenes ask for a Gaussian).
    pub filter: crate::filter::Filter,
    /// How camera samples meet the filter: drawn from it (default, pbrt-v4) or splatted
    /// and normalised (Mitsuba scenes, Mitsuba 3's way).
    pub filter_mode: crate::filter::FilterMode,
}

/// One bidirectional strategy: `s` light-subpath vertices joined to `t` camera-subpath
/// vertices. Unweighted, its image alone estimates all light of path depth `s + t − 2`
/// that the strategy can sample; weighted (MIS), the strategies of one depth sum to it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Strategy {
    /// Light-subpath vertices.
    pub s: u32,
    /// Camera-subpath vertices.
    pub t: u32,
    /// Whether its MIS weight is applied.
    pub weighted: bool,
}

impl RenderOptions {
    /// Whether strategy (s, t) contributes: every strategy does, unless a strategy
    /// image keeps only one.
    #[inline]
    pub(crate) fn keeps(&self, s: usize, t: usize) -> bool {
        self.strategy.is_none_or(|o| (o.s as usize, o.t as usize) == (s, t))
    }

    /// The weight strategy (s, t) carries: `None` when a strategy image drops it,
    /// 1 when the kept strategy is unweighted, its MIS weight `mis()` otherwise.
    #[inline]
    pub(crate) fn strategy_weight(&self, s: usize, t: usize, mis: impl FnOnce() -> f32) -> Option<f32> {
        match self.strategy {
            _ if !self.keeps(s, t) => None,
            Some(o) if !o.weighted => Some(1.0),
            _ => Some(mis()),
        }
    }
}

impl Default for RenderOptions {
    fn default() -> Self {
        RenderOptions {
            width: 512,
            height: 512,
            budget: Budget::Samples(64),
            max_depth: 8,
            seed: 0,
            integrator: IntegratorKind::Path,
            lvc: LvcParams::default(),
            cis: cis::CisParams::default(),
            strategy: None,
            filter: crate::filter::Filter::Box,
            filter_mode: crate::filter::FilterMode::Sample,
        }
    }
}

/// What a render did.
#[derive(Clone, Debug, Default)]
pub struct RenderStats {
    /// Passes (samples per pixel) done.
    pub passes: u32,
    /// Wall time of the render, seconds.
    pub seconds: f64,
    /// Rays cast (closest and shadow).
    pub rays: u64,
    /// Seconds spent inside the caster, summed over calls (calls made in parallel
    /// each count their own wall time).
    pub cast_seconds: f64,
    /// Ray–triangle tests the caster made.
    pub tests: u64,
    /// Of `rays`, those cast by `occluded` (shadow and connection rays); the others
    /// were closest-hit rays (camera, bounce and light-path rays).
    pub shadow_rays: u64,
    /// Caster calls: `rays / cast_calls` is the mean batch.
    pub cast_calls: u64,
    /// Largest working memory of any caster call, bytes (beyond its structure).
    pub peak_working_bytes: usize,
    /// The emulated device's kernel table when the render ran anything on one
    /// (PDACRT casting, CIS-LBDPT), with its peak device memory in bytes.
    pub device: Option<(Vec<simt::KernelSummary>, usize)>,
}

impl RenderStats {
    /// Rays cast per second of wall time.
    pub fn rays_per_second(&self) -> f64 {
        if self.seconds > 0.0 { self.rays as f64 / self.seconds } else { 0.0 }
    }
}

/// Everything one pass needs.
pub(crate) struct Context<'a> {
    /// The scene.
    pub scene: &'a Scene,
    /// Its lights.
    pub lights: &'a Lights,
    /// The caster every ray goes through.
    pub caster: &'a dyn RayCaster,
    /// The render's settings.
    pub opts: &'a RenderOptions,
}

impl Context<'_> {
    /// Camera sample `pass` of `pixel`: its film position and weight.
    #[inline]
    pub(crate) fn camera_sample(&self, pixel: u32, pass: u32) -> (glam::Vec2, f32) {
        let (o, w) = (self.opts, self.opts.width);
        o.filter.camera_sample(o.filter_mode, o.seed, (pixel % w, pixel / w), w, pass)
    }
}

/// A progressive renderer: validated settings, the lights, and the integrator with its
/// buffers. [`render`] drives one; the inspector drives one pass at a time.
pub struct Renderer<'a> {
    scene: &'a Scene,
    caster: &'a dyn RayCaster,
    opts: RenderOptions,
    lights: Lights,
    integrator: Integrator,
    /// (shadow rays, caster calls) of every pass so far.
    counts: (u64, u64),
}

pub use crate::limits::MAX_SECONDS;

impl RenderOptions {
    /// `opts` with a scene file's choices of what the image means (path depth, pixel
    /// filter and filter mode) wherever the file makes them: every front end (render,
    /// converge, the inspector) applies these, so a scene gives the same image in each.
    pub fn for_scene(settings: &crate::scene::RenderSettings, opts: RenderOptions) -> RenderOptions {
        RenderOptions {
            max_depth: settings.max_depth.unwrap_or(opts.max_depth),
            filter: settings.filter.unwrap_or(opts.filter),
            filter_mode: settings.filter_mode.unwrap_or(opts.filter_mode),
            ..opts
        }
    }
}

impl<'a> Renderer<'a> {
    /// Checks the scene and settings and prepares the integrator.
    pub fn new(scene: &'a Scene, caster: &'a dyn RayCaster, opts: &RenderOptions) -> Result<Self> {
        scene.check_renderable()?;
        crate::film::check_size(opts.width, opts.height)?;
        if let Budget::Seconds(s) = opts.budget
            && !(s > 0.0 && s <= MAX_SECONDS)
        {
            return Err(Error::BadSetting(format!("time budget {s} s must be positive and at most {MAX_SECONDS:e} s")));
        }
        if opts.max_depth > 1024 {
            return Err(Error::BadSetting(format!("max depth {} is absurd (at most 1024)", opts.max_depth)));
        }
        // Full paths live in fixed-size stack lists (kernels cannot allocate).
        let limit = match opts.integrator {
            IntegratorKind::Path | IntegratorKind::Light => u32::MAX,
            IntegratorKind::Bdpt | IntegratorKind::Lvc => (bidir::MAX_PATH - 2) as u32,
            IntegratorKind::Cis => (cis::kernels::MAX_CAMERA_VERTICES - 2) as u32,
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
                "strategy images belong to the bidirectional integrators (bdpt, lvc, cis); the {} integrator has none",
                opts.integrator.name()
            )));
        }
        if opts.integrator == IntegratorKind::Lvc && opts.lvc.megakernel && matches!(caster.name(), "dacrt" | "pdacrt")
        {
            return Err(Error::BadSetting(format!(
                "the LVC megakernel casts its rays one at a time, which the {} caster is not built for; use --caster bvh",
                caster.name()
            )));
        }
        let lights = Lights::new(scene);
        let integrator = match opts.integrator {
            IntegratorKind::Path => {
                let ctx = Context { scene, lights: &lights, caster, opts };
                Integrator::Path(PathTracer::new(&ctx))
            }
            IntegratorKind::Light => Integrator::Light(LightTracer::default()),
            IntegratorKind::Bdpt => Integrator::Bdpt(Bdpt::default()),
            IntegratorKind::Lvc => Integrator::Lvc(LvcBdpt::new(opts.lvc)),
            IntegratorKind::Cis => Integrator::Cis(Box::new(match caster.device() {
                Some(dev) => cis::CisLbdpt::on_device(opts.cis, dev.clone()),
                None => cis::CisLbdpt::new(opts.cis),
            })),
        };
        Ok(Renderer { scene, caster, opts: opts.clone(), lights, integrator, counts: (0, 0) })
    }

    /// The settings it renders with.
    pub fn options(&self) -> &RenderOptions {
        &self.opts
    }

    /// An empty film of the render's size.
    pub fn film(&self) -> Result<Film> {
        let film = Film::new(self.opts.width, self.opts.height)?;
        Ok(film.with_filter(self.opts.filter, self.opts.filter_mode, self.opts.seed))
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
        let pixels = self.opts.width * self.opts.height;
        let per_pass = match &self.integrator {
            Integrator::Light(_) | Integrator::Bdpt(_) => pixels,
            Integrator::Lvc(l) if l.dev.is_none() => pixels.max(l.params.light_paths),
            _ => return 1,
        };
        (walk::WAVE / per_pass.max(1)).max(1)
    }

    /// Adds passes `first..first + count` to `film`: the same film, bit for bit, as
    /// that many calls of [`Renderer::pass`] in order, but rendered in groups of
    /// [`Renderer::pass_group`] passes whose samples share waves (and caster calls).
    /// The whole call runs on the rayon pool, so the integrator's parallel steps do
    /// not hand over from the calling thread one by one.
    pub fn passes(&mut self, first: u32, count: u32, film: &mut Film) -> CastStats {
        let counter = CountingCaster::new(self.caster);
        let ctx = Context { scene: self.scene, lights: &self.lights, caster: &counter, opts: &self.opts };
        let (group, per_pass) = (self.pass_group(), self.opts.width * self.opts.height);
        let integrator = &mut self.integrator;
        let mut body = || {
            let mut stats = CastStats::default();
            let end = first.saturating_add(count);
            let mut at = first;
            while at < end {
                let span = Passes { first: at, count: group.min(end - at), per_pass };
                let zero = CastStats::default();
                let done = match &mut *integrator {
                    Integrator::Path(i) => span.numbers().fold(zero, |s, p| s.merge(i.render_pass(&ctx, p, film))),
                    Integrator::Light(i) => i.render_passes(&ctx, span, film),
                    Integrator::Bdpt(i) => i.render_passes(&ctx, span, film),
                    Integrator::Lvc(i) => i.render_passes(&ctx, span, film),
                    Integrator::Cis(i) => span.numbers().fold(zero, |s, p| s.merge(i.render_pass(&ctx, p, film))),
                };
                stats = stats.merge(done);
                at += span.count;
            }
            stats
        };
        let own = rayon::scope(|_| body());
        let counted = counter.stats();
        self.counts.0 += counter.shadow_rays();
        self.counts.1 += counter.calls();
        CastStats { peak_working_bytes: counted.peak_working_bytes.max(own.peak_working_bytes), ..counted }
    }

    /// Shadow rays and caster calls of every pass so far (see [`RenderStats`]).
    pub fn ray_counts(&self) -> (u64, u64) {
        self.counts
    }

    /// The CIS-LBDPT integrator, when that is the one running (queue records, device).
    pub fn cis(&self) -> Option<&cis::CisLbdpt> {
        match &self.integrator {
            Integrator::Cis(c) => Some(c),
            _ => None,
        }
    }

    /// The CIS-LBDPT integrator, mutable (to set an observer: [`cis::CisLbdpt::observe`]).
    pub fn cis_mut(&mut self) -> Option<&mut cis::CisLbdpt> {
        match &mut self.integrator {
            Integrator::Cis(c) => Some(c),
            _ => None,
        }
    }

    /// The emulated device of the render, when anything in it runs on one: the
    /// caster's (PDACRT), which a `cis` integrator shares, or the integrator's own.
    /// Its kernel table and memory peak cover the whole render.
    pub fn device(&self) -> Option<&simt::Device> {
        let lvc = match &self.integrator {
            Integrator::Lvc(l) => l.device(),
            _ => None,
        };
        self.cis().map(|c| c.device()).or(lvc).or_else(|| self.caster.device())
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
    (stats.shadow_rays, stats.cast_calls) = renderer.ray_counts();
    stats.device = renderer.device().map(|d| (d.kernel_stats(), d.memory().peak));
    Ok((film, stats))
}
