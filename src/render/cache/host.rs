//! The light vertex cache on the host: the vertices of one iteration's light subpaths,
//! their MIS sample counts, the wavefront light pass that fills it (`build_caches`),
//! and the strategies a camera vertex evaluates against it (uniform draws for LVC-BDPT,
//! resampled ones for CIS-LBDPT), shared with the device kernels.

use crate::cast::CastStats;
use crate::cost::{BRANCH, DIV, LUMINANCE, V3};
use crate::film::luminance;
use crate::render::bidir::{
    LIGHT_SAMPLE_DRAWS, Pending, Vertex, VertexKind, VertexList, camera_vertex, connect_contribution,
    connect_to_camera, connectible, full_path, strategy_connect, strategy_emitter, strategy_light_sample,
};
use crate::render::context::{Context, Passes};
use crate::render::mis::{Densities, Known, mis_weight_counts, subpath_densities};
use crate::render::options::Iterations;
use crate::render::walk::{PendingLists, Subpaths, extend_together, resolve_wave, start_light_wave};
use crate::sampling::Rng;
use glam::{Vec2, Vec3};

/// The part of the code this module's declared arithmetic counts as ([`crate::cost::Part`]).
const COST_PART: crate::cost::Part = crate::cost::Part::Bidirectional;

/// The light vertices of one iteration.
#[derive(Clone, Debug, Default)]
pub struct LightVertexCache {
    /// Every vertex of every light subpath, subpath after subpath (light origins too,
    /// for the MIS weights of connections).
    pub vertices: Vec<Vertex>,
    /// Per cached vertex: the index of its subpath's first vertex, and `s` (its index
    /// in the subpath plus one).
    pub entries: Vec<(u32, u32)>,
    /// Light subpaths traced into the cache.
    pub light_paths: u32,
}

impl LightVertexCache {
    /// The subpath of entry `e` up to and including the cached vertex.
    pub fn subpath(&self, e: usize) -> (&[Vertex], usize) {
        let (start, s) = self.entries[e];
        (&self.vertices[start as usize..start as usize + s as usize], s as usize)
    }

    /// Asks the CPU to start loading the subpaths of `drawn` entries ([`prefetch_entries`]).
    #[inline]
    pub(crate) fn prefetch(&self, drawn: &[usize]) {
        prefetch_entries(
            drawn,
            |e| simt::prefetch_host(self.entries.as_ptr().wrapping_add(e), 1),
            |e| self.entries[e],
            |start, s| simt::prefetch_host(self.vertices.as_ptr().wrapping_add(start), s),
        );
    }

    /// Samples drawn per connection strategy: `n_c · N_L / |cache|`.
    pub fn connection_count(&self, n_c: u32) -> f64 {
        StrategyCounts::connections(n_c, self.light_paths, self.entries.len())
    }
}

/// MIS sample counts of the strategies in one LVC iteration.
#[derive(Clone, Copy, Debug)]
pub struct StrategyCounts {
    /// Light paths per camera sample (light-tracing splats).
    pub splat: f64,
    /// Cache connections per camera sample and strategy.
    pub connection: f64,
    /// Light subpaths whose splats make one camera pass's light-tracing estimate: the
    /// iteration's `N_L` over its camera passes ([`Iterations`]).
    pub splat_paths: f64,
}

impl StrategyCounts {
    /// The counts of an iteration of `n_light` light subpaths whose cache holds
    /// `entries` vertices, with `n_c` connections per camera vertex, shared by the
    /// camera passes of `iterations`.
    pub(crate) fn new(ctx: &Context, n_light: u32, entries: usize, n_c: u32, iterations: Iterations) -> StrategyCounts {
        let pixels = (ctx.opts.width * ctx.opts.height) as f64;
        let splat_paths = n_light as f64 / iterations.0 as f64;
        StrategyCounts {
            splat: splat_paths / pixels,
            connection: Self::connections(n_c, n_light, entries),
            splat_paths,
        }
    }

    /// Samples drawn per connection strategy: `n_c · N_L / |cache|` (0 for an empty cache).
    fn connections(n_c: u32, n_light: u32, entries: usize) -> f64 {
        if entries == 0 { 0.0 } else { n_c as f64 * n_light as f64 / entries as f64 }
    }

    /// Sample count of strategy (s light vertices, t camera vertices) for the balance/power heuristic.
    pub fn count(&self, s: usize, t: usize) -> f64 {
        if t == 1 {
            self.splat
        } else if s >= 2 {
            self.connection
        } else {
            1.0
        }
    }
}

/// One iteration's light pass: the cache, its MIS counts, and the camera splats of
/// every light vertex (in path order), one list per camera pass of the iteration.
pub(crate) struct LightPass {
    pub cache: LightVertexCache,
    pub counts: StrategyCounts,
    pub splats: Vec<Vec<(Vec2, Vec3)>>,
}

/// The light passes of the iterations of `span` (`span.per_pass` light subpaths each),
/// traced as wavefronts together: each wave's light subpaths may belong to several
/// iterations, and each subpath goes to its own iteration's cache, in path order. The
/// splats of every light vertex to the camera are weighted with its iteration's
/// `counts`, which need the cache size, so they are made after the caches are built,
/// and listed by the camera pass of `iterations` they join.
pub(crate) fn build_caches(
    ctx: &Context,
    span: Passes,
    (n_c, iterations): (u32, Iterations),
    wave_size: u32,
) -> (Vec<LightPass>, CastStats) {
    let max_vertices = ctx.opts.max_depth as usize + 1;
    let n_light = span.per_pass;
    let mut caches: Vec<LightVertexCache> =
        (0..span.count).map(|_| LightVertexCache { light_paths: n_light, ..Default::default() }).collect();
    let iteration = |k: u32| (k / n_light) as usize;
    let mut stats = CastStats::default();
    let (mut subpaths, mut walkers) = (Subpaths::default(), Vec::new());
    // Per light path: where its vertices start in its iteration's cache, and how many it has.
    let mut paths = Vec::with_capacity(span.total() as usize);
    for wave in span.waves(wave_size) {
        let rng_of = |i: usize| {
            let (path, pass) = span.at(wave.start + i as u32);
            light_path_rng(ctx, path, pass)
        };
        let light = start_light_wave(ctx, wave.len(), rng_of, max_vertices, &mut subpaths, &mut walkers);
        stats = stats.merge(extend_together(ctx, &mut [light]));
        for (i, k) in wave.enumerate() {
            let cache = &mut caches[iteration(k)];
            let verts = subpaths.get(i);
            let start = cache.vertices.len() as u32;
            paths.push((start, verts.len() as u32));
            for (v_idx, v) in verts.iter().enumerate() {
                if v.kind == VertexKind::Surface && connectible(ctx, v) {
                    cache.entries.push((start, v_idx as u32 + 1));
                }
            }
            cache.vertices.extend_from_slice(verts);
        }
    }
    let counts: Vec<StrategyCounts> =
        caches.iter().map(|c| StrategyCounts::new(ctx, n_light, c.entries.len(), n_c, iterations)).collect();
    // Splats (t = 1) of every light vertex, in path order, their shadow rays cast one
    // wave at a time.
    let mut splats = vec![vec![Vec::new(); iterations.0 as usize]; span.count as usize];
    let mut pending = PendingLists::default();
    for wave in span.waves(wave_size) {
        let first = wave.start as usize;
        pending.fill(wave.len(), |i, out, path: &mut VertexList| {
            let (start, len) = paths[first + i];
            let q = iteration(wave.start + i as u32);
            let verts = &caches[q].vertices[start as usize..(start + len) as usize];
            let known = subpath_densities(ctx, verts);
            let sink = &mut |ray, l, px| out.push((Some(ray), l, Some(px)));
            light_splats(ctx, verts, &known, counts[q], path, sink);
        });
        let (resolved, shadow) = resolve_wave(ctx, &mut pending);
        stats = stats.merge(shadow);
        for (i, k) in wave.enumerate() {
            let share = iterations.share_of(span.at(k).0, n_light) as usize;
            splats[iteration(k)][share].extend_from_slice(resolved.sample(i).1);
        }
    }
    let passes = caches.into_iter().zip(counts).zip(splats);
    (passes.map(|((cache, counts), splats)| LightPass { cache, counts, splats }).collect(), stats)
}

/// The random stream of light subpath `path` in pass `pass` (by path and pass, never
/// by slot or thread; every light pass draws from these).
pub(crate) fn light_path_rng(ctx: &Context, path: u32, pass: u32) -> Rng {
    Rng::for_sample(ctx.opts.seed ^ 0x4c56_4321, path as u64, pass as u64)
}

/// The camera splats (t = 1) of one light subpath of an iteration whose camera passes
/// each take `counts.splat_paths` subpaths' splats, in vertex order, each given to
/// `sink` as (shadow ray, weighted value, film position). `known`: the subpath's
/// densities, or empty (kernels evaluate them). Allocation-free: kernels call it.
pub(crate) fn light_splats(
    ctx: &Context,
    verts: &[Vertex],
    known: &[Densities],
    counts: StrategyCounts,
    path: &mut VertexList,
    sink: &mut dyn FnMut(crate::geometry::Ray, Vec3, Vec2),
) {
    let cam_v = camera_vertex(&ctx.scene.camera);
    let scale = ((ctx.opts.width * ctx.opts.height) as f64 / counts.splat_paths) as f32;
    for s in 1..=verts.len() {
        if !ctx.opts.keeps(s, 1) {
            continue;
        }
        let Some((l, px, ray)) = connect_to_camera(ctx, verts, s, &cam_v) else { continue };
        full_path(verts, std::slice::from_ref(&cam_v), s, 1, path);
        let Some(w) = ctx.opts.strategy_weight(s, 1, || {
            mis_weight_counts(ctx, path, s, Known { light: known, camera: &[] }, |s, t| counts.count(s, t))
        }) else {
            continue;
        };
        sink(ray, l * w * scale, px);
    }
}

#[inline]
#[track_caller]
fn uniform_entry(cache_len: usize, rng: &mut Rng) -> usize {
    let _inlined = crate::cost::scope();
    crate::cost::declare!(5);
    entry_at(cache_len, rng.uniform())
}

/// A prefetch of the subpaths of `drawn` cache entries, on the host's cache or the
/// device's: every entry's record first (`record`), then, reading each (`read`), the
/// subpath it names (`subpath(start, s)`), so that the misses of each pass overlap. A
/// hint: it reads the records, not the subpaths.
#[inline]
pub(crate) fn prefetch_entries(
    drawn: &[usize],
    record: impl Fn(usize),
    read: impl Fn(usize) -> (u32, u32),
    subpath: impl Fn(usize, usize),
) {
    drawn.iter().for_each(|&e| record(e));
    for &e in drawn {
        let (start, s) = read(e);
        subpath(start as usize, s as usize);
    }
}

/// The cache entry a uniform number `u` in [0, 1) picks.
#[inline]
fn entry_at(cache_len: usize, u: f32) -> usize {
    ((u * cache_len as f32) as usize).min(cache_len - 1)
}

/// Most candidates a resampled connection considers.
pub const MAX_CANDIDATES: usize = 32;

/// How a camera vertex chooses the cache vertices it connects to.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Connections {
    /// `n` entries drawn uniformly.
    Uniform {
        /// Entries per camera vertex.
        n: u32,
    },
    /// Resampled importance sampling (Talbot et al. 2005): `candidates` entries drawn
    /// uniformly, `draws` chosen among them with replacement in proportion to their
    /// unshadowed contribution, each weighted by `mean(p̂) / p̂(chosen)` so the
    /// estimate stays unbiased.
    Resampled {
        /// Entries drawn uniformly.
        candidates: u32,
        /// Connections chosen among them.
        draws: u32,
    },
}

impl Connections {
    /// Connections made per camera vertex (what the MIS counts and the estimator's
    /// normalisation use).
    pub fn per_vertex(&self) -> u32 {
        match *self {
            Connections::Uniform { n } => n,
            Connections::Resampled { draws, .. } => draws,
        }
    }
}

/// How [`vertex_strategies`] reads the cache: `subpath(e, list, tail)` (below), and a
/// prefetch hint for a set of entries (none in a measured launch: drawing them ahead
/// would be counted).
pub(crate) type CacheAccess<'a> = (&'a dyn Fn(usize, &mut VertexList, bool) -> usize, Prefetch<'a>);

/// A prefetch hint for the subpaths of a set of cache entries, if any.
pub(crate) type Prefetch<'a> = Option<&'a dyn Fn(&[usize])>;

/// Every strategy at camera vertex `t - 1` except the camera splats: the emitter it hit
/// (s = 0), a light sample (s = 1), and connections to cache vertices, each pushed to
/// `sink` with its MIS weight applied. `subpath(e, list, tail)` puts cache entry `e`'s
/// light subpath up to the cached vertex into `list` and returns its length `s`; with
/// `tail` only its last two vertices (one when `s` is 1), which is all a resampling
/// candidate's weight reads. `cam_known`: the camera subpath's densities, or empty
/// (kernels evaluate them). The light subpaths' densities are evaluated per connection:
/// reading them from the cache costs a second random access into it, for no measured
/// gain. Allocation-free: kernels call it.
#[allow(clippy::too_many_arguments)]
pub(crate) fn vertex_strategies(
    ctx: &Context,
    (cam, cam_known): (&[Vertex], &[Densities]),
    t: usize,
    cache_len: usize,
    (subpath, prefetch): CacheAccess,
    counts: StrategyCounts,
    connections: Connections,
    rng: &mut Rng,
    path: &mut VertexList,
    sink: &mut dyn FnMut(Pending),
) {
    let max_depth = ctx.opts.max_depth as usize;
    let count = |s: usize, t: usize| counts.count(s, t);
    // Strategy images drop strategies here, at the sink, after every random number a
    // full render would draw has been drawn.
    let weight = |path: &VertexList, s: usize| {
        let known = Known { light: &[], camera: cam_known };
        ctx.opts.strategy_weight(s, t, || mis_weight_counts(ctx, path, s, known, count))
    };
    let connects = cache_len > 0 && connections.per_vertex() > 0 && t <= max_depth;
    if let (true, Some(prefetch)) = (connects, prefetch) {
        // The entries the connections below will draw start loading now, so that their
        // misses hide behind the emitter and light-sample strategies: a copy of the
        // stream, past the light sample's draws where it makes them, draws the same
        // entries (connections draw nothing between them). A wrong guess costs time only.
        let mut ahead = *rng;
        if connectible(ctx, &cam[t - 1]) {
            (0..LIGHT_SAMPLE_DRAWS).for_each(|_| _ = ahead.uniform());
        }
        let n = match connections {
            Connections::Uniform { n } => n as usize,
            Connections::Resampled { candidates, .. } => (candidates as usize).clamp(1, MAX_CANDIDATES),
        };
        let (mut drawn, n) = ([0usize; MAX_CANDIDATES], n.min(MAX_CANDIDATES));
        drawn[..n].iter_mut().for_each(|e| *e = entry_at(cache_len, ahead.uniform()));
        prefetch(&drawn[..n]);
    }
    // (Each strategy is a scope for `simt`'s model: nvcc inlines `weight` at each.)
    {
        let _strategy = crate::cost::scope();
        if t - 2 <= max_depth
            && let Some(l) = strategy_emitter(cam, t, &[], path)
            && let Some(w) = weight(path, 0)
        {
            sink((None, l * w, None));
        }
    }
    {
        let _strategy = crate::cost::scope();
        if t - 1 <= max_depth
            && let Some((l, ray)) = strategy_light_sample(ctx, cam, t, rng, path)
            && let Some(w) = weight(path, 1)
        {
            sink((Some(ray), l * w, None));
        }
    }
    if !connects {
        return;
    }
    // One light-subpath buffer for every candidate and connection (filled in place).
    let mut light = VertexList::default();
    let mut connect = |e: usize, extra: f32, path: &mut VertexList, sink: &mut dyn FnMut(Pending)| {
        let s = subpath(e, &mut light, false);
        crate::cost::declare!(BRANCH);
        if s + t - 2 > max_depth {
            return;
        }
        if let Some((l, ray)) = strategy_connect(ctx, &light, s, cam, t, path)
            && let Some(w) = weight(path, s)
        {
            crate::cost::declare!(2 + DIV + V3);
            sink((Some(ray), l * (w * extra / counts.connection as f32), None));
        }
    };
    match connections {
        Connections::Uniform { n } => {
            for _ in 0..n {
                let _trip = crate::cost::scope();
                let e = uniform_entry(cache_len, rng);
                connect(e, 1.0, path, sink);
            }
        }
        Connections::Resampled { candidates, draws } => {
            let n = (candidates as usize).clamp(1, MAX_CANDIDATES);
            let (mut entry, mut target) = ([0usize; MAX_CANDIDATES], [0f32; MAX_CANDIDATES]);
            let mut total = 0.0f32;
            let mut tail = VertexList::default();
            for k in 0..n {
                let _trip = crate::cost::scope();
                entry[k] = uniform_entry(cache_len, rng);
                let s = subpath(entry[k], &mut tail, true);
                crate::cost::declare!(3 * BRANCH);
                let (lv, prev) = match &tail[..] {
                    [prev, lv] => (Some(lv), Some(prev)),
                    [lv] => (Some(lv), None),
                    _ => (None, None),
                };
                target[k] = match lv {
                    Some(lv) if s + t - 2 <= max_depth => {
                        connect_contribution(ctx, lv, prev, cam, t).map_or(0.0, |l| luminance(l).max(0.0))
                    }
                    _ => 0.0,
                };
                crate::cost::declare!(LUMINANCE + 2);
                total += target[k];
            }
            crate::cost::declare!(BRANCH);
            if total <= 0.0 {
                return;
            }
            crate::cost::declare!(DIV + 2);
            let mean = total / n as f32;
            for _ in 0..draws {
                let _trip = crate::cost::scope();
                let mut u = rng.uniform() * total;
                let mut k = 0;
                while k + 1 < n && (u >= target[k] || target[k] == 0.0) {
                    u -= target[k];
                    k += 1;
                }
                // The search: its tests, subtraction and step per candidate passed.
                crate::cost::declare!(1 + 6 * (k as u32 + 1) + BRANCH);
                if target[k] > 0.0 {
                    crate::cost::declare!(DIV);
                    connect(entry[k], mean / target[k], path, sink);
                }
            }
        }
    }
}

/// All strategies along one camera subpath (megakernel form of [`vertex_strategies`]).
#[allow(clippy::too_many_arguments)]
pub(crate) fn camera_strategies(
    ctx: &Context,
    cam: &[Vertex],
    cache: &LightVertexCache,
    counts: StrategyCounts,
    connections: Connections,
    rng: &mut Rng,
    path: &mut VertexList,
    pending: &mut Vec<Pending>,
) {
    let subpath = |e: usize, list: &mut VertexList, tail: bool| {
        let (light, s) = cache.subpath(e);
        list.clear();
        list.extend(if tail { &light[s.saturating_sub(2)..] } else { light });
        s
    };
    // The camera subpath's densities, evaluated once for all its vertices' strategies.
    let cam_known = &subpath_densities(ctx, cam);
    let prefetch = |drawn: &[usize]| cache.prefetch(drawn);
    let access: CacheAccess = (&subpath, Some(&prefetch));
    for t in 2..=cam.len() {
        let sink = &mut |p| pending.push(p);
        vertex_strategies(ctx, (cam, cam_known), t, cache.entries.len(), access, counts, connections, rng, path, sink);
    }
}
