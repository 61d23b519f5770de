//! The LVC-BDPT megakernel on the `simt` device (`--integrator lvc-mk`): the
//! baseline that CIS-LBDPT's stream is measured against, run the way a GPU megakernel
//! runs it, one thread per subpath doing the whole subpath, so that the device measures
//! its divergence.
//!
//! Each iteration (of one or more camera passes, [`Iterations`]):
//! 1. `lvc::light_path`: one thread per light subpath traces it whole (a wave of up to
//!    `WAVE` at a time) and stages its vertices; the wave is appended to the device
//!    light vertex cache in subpath order (`cis::cache_counts`, scans, `cis::cache_store`,
//!    shared with the stream);
//! 2. `lvc::splat`: one thread per cached subpath of the camera pass's share connects
//!    each vertex to the camera, tracing each shadow ray at once;
//! 3. `lvc::camera_path`: one thread per pixel traces its camera subpath and evaluates
//!    every strategy at every vertex, tracing each shadow ray at once.
//!
//! Threads draw the same random numbers in the same order as the wavefront LVC-BDPT
//! (`lvc.rs`), and the cache holds the same subpaths in the same order, so the image is
//! the same bit for bit: the megakernel differs in how the work is scheduled, never in
//! what it computes. Rays go to the caster one at a time, so this wants a caster built
//! for single rays (the BVH, or brute force on small scenes).

pub(crate) mod kernels;

use crate::cast::CastStats;
use crate::film::Film;
use crate::render::bidir::Vertex;
use crate::render::cache::device::{DeviceCache, append_paths, visible_splats};
use crate::render::cache::host::Connections;
use crate::render::cache::kernels::{CacheRead, SplatData};
use crate::render::context::{Context, Passes, WAVE, waves};
use crate::render::options::{Iterations, LvcParams};
use kernels::*;
use simt::{Device, DeviceConfig, LaunchConfig};

/// LVC-BDPT as megakernels: its settings and the device its kernels run on.
pub struct LvcMegakernel {
    /// Its settings.
    pub params: LvcParams,
    dev: Device,
    /// The cache of the last iteration, with its number, for its next camera passes.
    cache: Option<(u32, DeviceCache)>,
}

impl LvcMegakernel {
    /// The megakernel integrator with `params`, on a device of its own (measured when
    /// `params.measure`).
    pub fn new(params: LvcParams) -> Self {
        let dev = Device::new(DeviceConfig { measure: params.measure, ..Default::default() });
        LvcMegakernel { params, dev, cache: None }
    }

    /// The device the megakernels run on.
    pub fn device(&self) -> &Device {
        &self.dev
    }

    /// Renders the passes of `span`, one at a time, each iteration's light pass once
    /// (stage 1 at the first of its camera passes that this integrator renders).
    pub(crate) fn render_passes(&mut self, ctx: &Context, span: Passes, film: &mut Film) -> CastStats {
        let n_light = self.params.light_paths_for(ctx.opts.width * ctx.opts.height);
        let (n_c, iterations) = (self.params.connections, self.params.iterations());
        let stride = ctx.opts.max_depth as usize + 1;
        span.numbers().fold(CastStats::default(), |stats, pass| {
            let number = iterations.of(pass);
            if self.cache.as_ref().is_none_or(|(n, _)| *n != number) {
                self.cache = None;
                self.cache = Some((number, light_paths(&self.dev, ctx, number, n_light, stride)));
            }
            let cache = &self.cache.as_ref().expect("made above").1;
            stats.merge(render_pass(&self.dev, ctx, pass, cache, (n_c, iterations), film))
        })
    }
}

/// Threads per block of the megakernel launches.
const BLOCK: u32 = 128;

/// What the time model needs of a megakernel's GPU twin (`cuda/render.cu`'s
/// `mk_light_path`, `mk_splat`, `mk_camera_path`): its registers per thread, as Nsight
/// Compute reported them on the H200 (`docs/measured/gpu-render-kernels-h200-bedroom-512.md`),
/// which bound the blocks an SM holds, and the bytes of its SASS
/// (`docs/measured/cuda-kernel-code-bytes-sm90.tsv`), which say whether its warps fetch
/// their instructions from beyond the SM's instruction cache.
struct Twin {
    name: &'static str,
    registers: u32,
    code_bytes: u32,
}

const LIGHT_PATH: Twin = Twin { name: "lvc::light_path", registers: 160, code_bytes: 229_888 };
const SPLAT: Twin = Twin { name: "lvc::splat", registers: 128, code_bytes: 137_216 };
const CAMERA_PATH: Twin = Twin { name: "lvc::camera_path", registers: 167, code_bytes: 685_056 };

/// Launches `kernel(thread, i)` for `i` in `0..n` in blocks of [`BLOCK`], with the
/// shading, arithmetic and `trace` regions named and what the time model needs of the
/// `twin`.
fn launch_per_item(dev: &Device, twin: &Twin, n: usize, kernel: impl Fn(&simt::Thread, usize) + Sync) {
    let cfg = LaunchConfig::linear(n, BLOCK)
        .with_regions(&REGIONS)
        .with_registers(twin.registers)
        .with_code_bytes(twin.code_bytes);
    dev.launch(twin.name, cfg, |blk| {
        blk.for_each_thread(|t| {
            let i = t.global_idx();
            if i < n {
                // The shared code's declared arithmetic (BSDFs, sampling, connections;
                // `cost::declare!`) counts as this lane's, as in `cis::shade`.
                t.ambient(ARITHMETIC_REGION, || kernel(t, i))
            }
        })
    })
    .expect("a linear launch of 128-thread blocks is valid");
}

/// One camera pass of LVC-BDPT as megakernels on `dev` against its iteration's
/// `cache`: the splats of the pass's share of the cached subpaths, then the camera
/// subpaths, with `n_c` uniform cache connections per camera vertex.
fn render_pass(
    dev: &Device,
    ctx: &Context,
    pass: u32,
    cache: &DeviceCache,
    (n_c, iterations): (u32, Iterations),
    film: &mut Film,
) -> CastStats {
    let stride = ctx.opts.max_depth as usize + 1;
    let counts = cache.counts(ctx, n_c, iterations);
    // Splats of the pass's share, a wave of cached subpaths (in number order) at a time.
    let share = iterations.splat_range(pass, cache.light_paths);
    let mut splats = Vec::new();
    for wave in waves(share.1 - share.0, WAVE) {
        let (first, m) = ((share.0 + wave.start) as usize, wave.len());
        let mut entries = dev.alloc_pooled::<SplatData>(m * stride);
        let (pv, vv, sv) = (cache.paths.slice(first, m), cache.vertices.view(), entries.view_mut());
        launch_per_item(dev, &SPLAT, m, |t, p| splat(t, ctx, p, (&pv, &vv), (counts, share), stride, &sv));
        splats.extend(visible_splats(dev, &entries));
    }
    film.add_splats(splats);
    // Camera subpaths, one thread per pixel.
    let pixels = (ctx.opts.width * ctx.opts.height) as usize;
    let mut estimates = dev.alloc::<[f32; 3]>(pixels);
    {
        let connections = Connections::Uniform { n: n_c };
        let read = CacheRead { vertices: cache.vertices.view(), entries: cache.entries.view(), counts, connections };
        let ev = estimates.view_mut();
        launch_per_item(dev, &CAMERA_PATH, pixels, |t, i| camera_path(t, ctx, i as u32, pass, &read, &ev));
    }
    let est: Vec<glam::Vec3> = estimates.as_slice().iter().map(|&e| glam::Vec3::from_array(e)).collect();
    film.add_pass(pass, &est);
    CastStats { peak_working_bytes: dev.memory().peak, ..Default::default() }
}

/// Stage 1: iteration `number`'s light subpaths, one thread each, a wave at a time,
/// appended to the cache in subpath order.
fn light_paths(dev: &Device, ctx: &Context, number: u32, n_light: u32, stride: usize) -> DeviceCache {
    let mut cache = DeviceCache::new(dev, n_light);
    for wave in waves(n_light, WAVE) {
        let m = wave.len();
        let mut staging = dev.alloc_pooled::<Vertex>(m * stride);
        let mut done = dev.alloc_pooled::<[u32; 3]>(m);
        {
            let (sv, dv) = (staging.view_mut(), done.view_mut());
            launch_per_item(dev, &LIGHT_PATH, m, |t, i| light_path(t, ctx, i, (wave.start, number), stride, &sv, &dv));
        }
        append_paths(dev, ctx, &done, &staging, stride, &mut cache);
    }
    cache
}

#[cfg(test)]
mod tests {
    use super::kernels::TRACE_REGION;
    use crate::cast::BvhCaster;
    use crate::render::{IntegratorKind, RenderOptions, Renderer};
    use crate::scene::cornell_box;

    /// The megakernel schedules LVC-BDPT differently and computes the same thing: its
    /// image equals the wavefront one bit for bit, over two passes (so the light pass,
    /// the splats and the camera pass all count), with its kernels on the device; and
    /// over five passes with three camera passes per iteration (a light pass shared,
    /// the splats divided among the passes, an iteration left unfinished).
    #[test]
    fn the_megakernel_renders_the_wavefront_image() {
        let scene = cornell_box();
        let caster = BvhCaster::new(&scene);
        let image = |megakernel: bool, (passes, per_iteration): (u32, u32)| {
            let integrator = if megakernel { IntegratorKind::LvcMegakernel } else { IntegratorKind::Lvc };
            let mut opts =
                RenderOptions { width: 40, height: 30, integrator, seed: 9, max_depth: 6, ..Default::default() };
            opts.lvc.samples_per_iteration = per_iteration;
            let mut r = Renderer::new(&scene, &caster, &opts).unwrap();
            let mut film = r.film().unwrap();
            for pass in 0..passes {
                r.pass(pass, &mut film);
            }
            let kernels: Vec<(&str, u64)> =
                r.device().map(|d| d.kernel_stats().iter().map(|k| (k.name, k.launches)).collect()).unwrap_or_default();
            (film.mean(), kernels)
        };
        for shape in [(2, 1), (5, 3)] {
            let (wavefront, none) = image(false, shape);
            let (mega, kernels) = image(true, shape);
            assert!(none.is_empty());
            let launches = |name: &str| kernels.iter().find(|k| k.0 == name).map(|k| k.1);
            // Stage 1 once per iteration (two of them), the others once per pass.
            let light = if shape.1 == 1 { shape.0 } else { 2 };
            assert_eq!(launches("lvc::light_path"), Some(light as u64), "{kernels:?}");
            for k in ["cis::cache_store", "lvc::splat", "lvc::camera_path"] {
                assert!(launches(k).is_some(), "{k} did not run: {kernels:?}");
            }
            assert_eq!(launches("lvc::camera_path"), Some(shape.0 as u64));
            assert!(wavefront.iter().any(|p| p.max_element() > 0.0));
            let differ = wavefront.iter().zip(&mega).filter(|(a, b)| a != b).count();
            assert_eq!(differ, 0, "{shape:?}: {differ} pixels differ");
        }
    }

    /// With the GPU BVH's twin, each thread traverses its own rays (the traversal's
    /// work counted in the launch's `trace` region, measured): the same image again.
    #[test]
    fn the_megakernel_traversing_in_its_threads_renders_the_same_image() {
        let scene = cornell_box();
        let image = |caster: &dyn crate::cast::RayCaster, measure: bool| {
            let mut opts = RenderOptions {
                width: 24,
                height: 16,
                integrator: IntegratorKind::LvcMegakernel,
                seed: 4,
                max_depth: 5,
                ..Default::default()
            };
            opts.lvc.measure = measure;
            let mut r = Renderer::new(&scene, caster, &opts).unwrap();
            let mut film = r.film().unwrap();
            r.pass(0, &mut film);
            let trace = r.device().and_then(|d| {
                d.kernel_stats()
                    .into_iter()
                    .find(|k| k.name == "lvc::camera_path")
                    .map(|k| k.regions[TRACE_REGION].issued)
            });
            (film.mean(), trace)
        };
        let (want, _) = image(&BvhCaster::new(&scene), false);
        let (got, trace) = image(&crate::cast::Lbvh::new(&scene), true);
        assert_eq!(want, got);
        // Far more than one instruction per ray: the traversal itself was counted.
        assert!(trace.is_some_and(|issued| issued > 24 * 16 * 100), "{trace:?}");
    }
}
