//! What to render and how: the integrator, the budget, every integrator's settings,
//! and what a render reports. The floor every integrator and front end reads.

use crate::error::{Error, Result};

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
    /// BDPT with a light vertex cache (LVC-BDPT), as wavefronts on the host.
    Lvc,
    /// LVC-BDPT as megakernels on the simt device: one thread per subpath, rays
    /// traced one at a time (the same image as `Lvc`, bit for bit).
    #[cfg_attr(feature = "cli", value(name = "lvc-mk"))]
    LvcMegakernel,
    /// CIS-LBDPT: LVC-BDPT streamed on the simt emulator, sorted by material, with
    /// importance-sampled connections.
    Cis,
}

/// Bytes every render needs whatever its size (wave buffers, thread stacks): peak
/// resident memory at 512² less 512² times [`IntegratorKind::bytes_per_pixel`] was 105
/// to 190 MB.
pub const RENDER_FIXED_BYTES: u64 = 256 << 20;

impl IntegratorKind {
    /// The command-line name.
    pub fn name(self) -> &'static str {
        match self {
            IntegratorKind::Path => "path",
            IntegratorKind::Light => "light",
            IntegratorKind::Bdpt => "bdpt",
            IntegratorKind::Lvc => "lvc",
            IntegratorKind::LvcMegakernel => "lvc-mk",
            IntegratorKind::Cis => "cis",
        }
    }

    /// Bytes a render with this integrator needs per pixel, beyond the scene and
    /// [`RENDER_FIXED_BYTES`]: the slope of peak resident memory from 512² to 1024²
    /// (one pass, the built-in Cornell box, `/usr/bin/time -f %M`, 2026-12-02), rounded
    /// up by a quarter. Path tracing 416 B measured, light tracing 52, BDPT 55 (their
    /// waves hold at most 65,536 samples), LVC 433, its megakernel 428, CIS 393 (a light
    /// path per pixel and its cache).
    pub fn bytes_per_pixel(self) -> u64 {
        match self {
            IntegratorKind::Path => 520,
            IntegratorKind::Light => 65,
            IntegratorKind::Bdpt => 70,
            IntegratorKind::Lvc | IntegratorKind::LvcMegakernel => 540,
            IntegratorKind::Cis => 500,
        }
    }

    /// The unidirectional and bidirectional references (the light-transport core).
    pub const CORE: [IntegratorKind; 3] = [IntegratorKind::Path, IntegratorKind::Light, IntegratorKind::Bdpt];
    /// Every integrator.
    pub const ALL: [IntegratorKind; 6] = [
        IntegratorKind::Path,
        IntegratorKind::Light,
        IntegratorKind::Bdpt,
        IntegratorKind::Lvc,
        IntegratorKind::LvcMegakernel,
        IntegratorKind::Cis,
    ];
}

impl std::str::FromStr for IntegratorKind {
    type Err = Error;
    fn from_str(s: &str) -> Result<Self> {
        IntegratorKind::ALL.into_iter().find(|k| k.name().eq_ignore_ascii_case(s)).ok_or_else(|| {
            Error::BadSetting(format!("unknown integrator '{s}' (known: path, light, bdpt, lvc, lvc-mk, cis)"))
        })
    }
}

/// How long to render.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Budget {
    /// This many samples per pixel.
    Samples(u32),
    /// Passes until this much wall time has gone (at least one pass). The clock is
    /// read between groups of passes ([`crate::render::Renderer::pass_group`]), each sized to about an
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
    /// The path tracer's Russian roulette starts once a path has made this many
    /// bounces (Mitsuba's `rr_depth`, counted as Mitsuba counts it): from then on each
    /// path continues with probability min(max throughput · η², 0.95), η the relative
    /// index its refractions have crossed. 4 by default; Mitsuba's default, 5, is what
    /// scenes from Mitsuba XML get. The other integrators start theirs after 3 bounces
    /// (without η).
    pub rr_depth: u32,
    /// Random seed: the same seed gives the same image at any thread count.
    pub seed: u64,
    /// The light-transport algorithm.
    pub integrator: IntegratorKind,
    /// Light-vertex-cache settings (LVC-BDPT).
    pub lvc: LvcParams,
    /// CIS-LBDPT settings and switches.
    pub cis: CisParams,
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
    /// Predict the GPU time of the render's emulated kernels (CIS-LBDPT, the LVC
    /// megakernel, the PDACRT caster) on this GPU ([`simt::timing`]); turns the simt
    /// device's measurement on, which slows the render.
    pub gpu_profile: Option<simt::GpuProfile>,
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
    /// An empty film of these options' size, with their filter, filter mode and seed:
    /// what every renderer of them (CPU or GPU) accumulates into.
    pub fn film(&self) -> Result<crate::film::Film> {
        Ok(crate::film::Film::new(self.width, self.height)?.with_filter(self.filter, self.filter_mode, self.seed))
    }

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
            rr_depth: 4,
            seed: 0,
            integrator: IntegratorKind::Path,
            lvc: LvcParams::default(),
            cis: CisParams::default(),
            strategy: None,
            filter: crate::filter::Filter::Box,
            filter_mode: crate::filter::FilterMode::Sample,
            gpu_profile: None,
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
    /// Of `rays`, those cast one at a time from kernel threads (the LVC megakernel's),
    /// each its own call, untimed: their time is the kernels', not in `cast_seconds`.
    pub single_rays: u64,
    /// Whether caster calls ran at the same time (from several threads): then
    /// `cast_seconds` sums overlapping wall times and is not a part of `seconds`.
    pub cast_overlapped: bool,
    /// Largest working memory of any caster call, bytes (beyond its structure).
    pub peak_working_bytes: usize,
    /// The emulated device's kernel table when the render ran anything on one
    /// (PDACRT casting, CIS-LBDPT), with its peak device memory in bytes.
    pub device: Option<(Vec<simt::KernelSummary>, usize)>,
    /// The device's launches, oldest first, as far as its log holds them (the last
    /// [`simt::stats::LOG_CAPACITY`]), and how many launches the render made: the
    /// records `gpu_check time --records` reads (`warpray render --launch-records`).
    pub launches: (Vec<simt::LaunchRecord>, u64),
}

impl RenderStats {
    /// Rays cast per second of wall time.
    pub fn rays_per_second(&self) -> f64 {
        if self.seconds > 0.0 { self.rays as f64 / self.seconds } else { 0.0 }
    }
}

pub use crate::limits::MAX_SECONDS;

impl RenderOptions {
    /// Camera passes (samples per pixel) per light pass for the integrators with a
    /// light vertex cache (LVC-BDPT, its megakernel, CIS-LBDPT; [`Iterations`]); the
    /// others have no light pass to share and ignore it.
    pub fn set_samples_per_iteration(&mut self, k: u32) {
        (self.lvc.samples_per_iteration, self.cis.samples_per_iteration) = (k, k);
    }

    /// `opts` with a scene file's choices of what the image means (path depth, pixel
    /// filter and filter mode) and of how it is sampled (Russian roulette's start)
    /// wherever the file makes them: every front end (render, converge, the inspector)
    /// applies these, so a scene gives the same image in each.
    pub fn for_scene(settings: &crate::scene::RenderSettings, opts: RenderOptions) -> RenderOptions {
        RenderOptions {
            max_depth: settings.max_depth.unwrap_or(opts.max_depth),
            rr_depth: settings.rr_depth.unwrap_or(opts.rr_depth),
            filter: settings.filter.unwrap_or(opts.filter),
            filter_mode: settings.filter_mode.unwrap_or(opts.filter_mode),
            ..opts
        }
    }
}

/// Parameters of LVC-BDPT, on the host ([`IntegratorKind::Lvc`]) and as megakernels on
/// the device ([`IntegratorKind::LvcMegakernel`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LvcParams {
    /// Light subpaths per iteration (0: one per pixel).
    pub light_paths: u32,
    /// Cache connections per camera vertex (`n_c`).
    pub connections: u32,
    /// Camera samples per pixel (passes) per iteration, each iteration's light pass
    /// shared by them ([`Iterations`]; 0 counts as 1).
    pub samples_per_iteration: u32,
    /// The megakernel: measure the kernels' SIMD efficiency and memory traffic.
    pub measure: bool,
}

impl Default for LvcParams {
    fn default() -> Self {
        LvcParams { light_paths: 0, connections: 3, samples_per_iteration: 1, measure: false }
    }
}

impl LvcParams {
    /// Light subpaths per iteration of an image of `pixels` pixels.
    pub fn light_paths_for(&self, pixels: u32) -> u32 {
        if self.light_paths == 0 { pixels } else { self.light_paths }
    }

    /// How its passes make iterations.
    pub fn iterations(&self) -> Iterations {
        Iterations(self.samples_per_iteration.max(1))
    }
}

/// Parameters and switches of CIS-LBDPT ([`IntegratorKind::Cis`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CisParams {
    /// Camera samples in flight.
    pub pool: u32,
    /// Light subpaths per iteration (0: one per pixel).
    pub light_paths: u32,
    /// Candidates drawn uniformly from the cache per camera vertex (N).
    pub candidates: u32,
    /// Connections made per camera vertex (M), at most 8.
    pub draws: u32,
    /// Sort samples by material before shading.
    pub sort: bool,
    /// Resample the candidates by contribution (off: `draws` uniform connections).
    pub importance: bool,
    /// Compact dead samples and regenerate their slots at once.
    pub regenerate: bool,
    /// Camera samples per pixel (passes) per iteration, each iteration's light pass
    /// shared by them ([`Iterations`]; 0 counts as 1).
    pub samples_per_iteration: u32,
    /// Record SIMD efficiency and memory traffic of the kernels (slower).
    pub measure: bool,
}

impl CisParams {
    /// How its passes make iterations.
    pub fn iterations(&self) -> Iterations {
        Iterations(self.samples_per_iteration.max(1))
    }
}

impl Default for CisParams {
    fn default() -> Self {
        CisParams {
            pool: 1 << 16,
            light_paths: 0,
            candidates: 8,
            draws: 2,
            sort: true,
            importance: true,
            regenerate: true,
            samples_per_iteration: 1,
            measure: false,
        }
    }
}

/// How LVC iterations are made of passes: each iteration traces one light pass into
/// its cache, then renders this many camera passes (samples per pixel) against it
/// (at least 1; the CIS-LBDPT paper renders 4–8). The iteration's light subpaths share
/// its light tracing: each camera pass takes the splats of its own slice of them, by
/// subpath number, so every pass is an estimate of the image by itself and the passes
/// of an iteration together splat every subpath once.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Iterations(pub u32);

impl Iterations {
    /// The iteration of camera pass `pass`.
    #[inline]
    pub fn of(self, pass: u32) -> u32 {
        pass / self.0
    }

    /// Camera pass `pass`'s place within its iteration (0 for the first).
    #[inline]
    pub fn pass_in_iteration(self, pass: u32) -> u32 {
        pass % self.0
    }

    /// The light subpaths, by number `first..end` of `n_light`, whose splats join camera
    /// pass `pass`.
    pub fn splat_range(self, pass: u32, n_light: u32) -> (u32, u32) {
        let (j, k, n) = (self.pass_in_iteration(pass) as u64, self.0 as u64, n_light as u64);
        ((j * n).div_ceil(k) as u32, ((j + 1) * n).div_ceil(k) as u32)
    }

    /// The camera pass within its iteration that light subpath `path` (of `n_light`)
    /// splats into.
    #[inline]
    pub fn share_of(self, path: u32, n_light: u32) -> u32 {
        (path as u64 * self.0 as u64 / n_light.max(1) as u64) as u32
    }
}

#[cfg(test)]
mod tests {
    use super::Iterations;

    /// The camera passes of an iteration divide its light subpaths among them: every
    /// subpath goes to exactly one pass, the one `share_of` names, in slices that
    /// differ in size by at most one.
    #[test]
    fn the_passes_of_an_iteration_share_its_light_subpaths_once() {
        for k in [1, 2, 3, 4, 7, 8] {
            for n in [1, 5, 8, 63, 1000, 262_144] {
                let it = Iterations(k);
                let mut next = 0;
                for pass in 10 * k..11 * k {
                    let (first, end) = it.splat_range(pass, n);
                    assert_eq!(first, next, "k {k}, n {n}, pass {pass}");
                    assert!(end - first <= n.div_ceil(k) && end - first >= n / k);
                    for path in [first, end.saturating_sub(1)].into_iter().filter(|&p| (first..end).contains(&p)) {
                        assert_eq!(it.share_of(path, n), it.pass_in_iteration(pass));
                    }
                    next = end;
                }
                assert_eq!(next, n);
                assert_eq!((it.of(10 * k), it.of(11 * k - 1), it.of(11 * k)), (10, 10, 11));
            }
        }
    }
}
