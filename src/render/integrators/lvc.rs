//! LVC-BDPT (Davidovič et al. 2014) as wavefronts on the host: the baseline whose
//! camera paths evaluate every strategy of a sample together.
//!
//! Each iteration first traces `N_L` light subpaths and stores their connectible surface
//! vertices in a light vertex cache; every light vertex is also splatted to the camera.
//! Then each camera subpath, at each vertex, takes the emitter it hit (s = 0), a fresh
//! light sample (s = 1), and `n_c` connections to cache vertices drawn uniformly. A
//! connection stands for all `|cache|` vertices, each used `n_c · N_L / |cache|` times
//! per camera sample on average, so its contribution is divided by that count and the
//! balance heuristic counts connection strategies with that many samples (light-tracing
//! splats with `N_L / pixels`). The cache and the strategies live in
//! [`crate::render::cache`]; the same algorithm as megakernels on the device is
//! [`super::megakernel`]. An iteration may render several camera passes against its
//! cache ([`crate::render::Iterations`]), sharing its light tracing among them.

use crate::cast::CastStats;
use crate::film::Film;
use crate::render::bidir::VertexList;
use crate::render::cache::host::{Connections, LightPass, LightVertexCache, build_caches, camera_strategies};
use crate::render::context::{Context, Passes};
use crate::render::options::LvcParams;
use crate::render::walk::{WaveBuffers, extend_together, flush_wave, resolve_wave, start_camera_wave};

/// LVC-BDPT: every pixel sample's camera subpath connects to a shared light vertex
/// cache. The megakernel baseline: all strategies of a sample are evaluated together.
pub struct LvcBdpt {
    /// Its settings.
    pub params: LvcParams,
    /// The light pass of the last iteration rendered, with its number, kept for the
    /// iteration's next camera passes (and the inspector and tests).
    pub(crate) kept: Option<(u32, LightPass)>,
    pub(crate) buffers: WaveBuffers,
}

impl LvcBdpt {
    /// An LVC-BDPT integrator with `params`.
    pub fn new(params: LvcParams) -> Self {
        LvcBdpt { params, kept: None, buffers: WaveBuffers::default() }
    }

    /// The light vertex cache of the last iteration rendered.
    pub fn last_cache(&self) -> Option<&LightVertexCache> {
        self.kept.as_ref().map(|(_, light)| &light.cache)
    }

    /// Renders the passes of `span` (one camera path per pixel and pass): first the
    /// light pass of every iteration they belong to, traced together ([`build_caches`];
    /// the kept one is reused when the span starts in it), then the camera paths in
    /// waves that may hold several passes, each connecting to its own iteration's cache.
    pub(crate) fn render_passes(&mut self, ctx: &Context, span: Passes, film: &mut Film) -> CastStats {
        let n_light = self.params.light_paths_for(ctx.opts.width * ctx.opts.height);
        let n_c = self.params.connections;
        let iterations = self.params.iterations();
        let (first, last) = (iterations.of(span.first), iterations.of(span.first + span.count - 1));
        let kept = self.kept.take().filter(|(number, _)| *number == first);
        let build_from = first + kept.is_some() as u32;
        let (mut light, mut stats) = if build_from <= last {
            let light_span = Passes { first: build_from, count: last - build_from + 1, per_pass: n_light };
            build_caches(ctx, light_span, (n_c, iterations), self.buffers.wave(ctx))
        } else {
            (Vec::new(), CastStats::default())
        };
        if let Some((_, pass)) = kept {
            light.insert(0, pass);
        }
        let b = &mut self.buffers;
        let mut estimates = Vec::with_capacity(span.per_pass as usize);
        for wave in span.waves(b.wave(ctx)) {
            let camera = start_camera_wave(ctx, span, wave.clone(), &mut b.camera, &mut b.camera_walkers);
            stats = stats.merge(extend_together(ctx, &mut [camera]));
            let (camera, walkers) = (&b.camera, &b.camera_walkers);
            let caches = &light;
            b.pending.fill(camera.len(), |i, out, path: &mut VertexList| {
                let mut rng = walkers[i].rng;
                let it = &caches[(iterations.of(span.at(wave.start + i as u32).1) - first) as usize];
                let connections = Connections::Uniform { n: n_c };
                camera_strategies(ctx, camera.get(i), &it.cache, it.counts, connections, &mut rng, path, out)
            });
            let (resolved, shadow) = resolve_wave(ctx, &mut b.pending);
            stats = stats.merge(shadow);
            // A pass's share of its iteration's light splats reaches the film just
            // before its camera estimates (read, not used up: a pass may be rendered
            // again while its iteration's light pass is kept).
            flush_wave(film, span, wave, resolved, Some(&mut estimates), |film, pass| {
                let splats = &light[(iterations.of(pass) - first) as usize].splats;
                film.add_splats(splats[iterations.pass_in_iteration(pass) as usize].iter().copied())
            });
        }
        self.kept = light.pop().map(|pass| (last, pass));
        stats
    }
}
