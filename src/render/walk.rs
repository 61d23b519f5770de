//! Subpaths extended as a wavefront, for the bidirectional integrators (light tracing,
//! BDPT, LVC-BDPT and the light pass of CIS-LBDPT).
//!
//! A wave holds up to [`Context::wave`] subpaths side by side, of one pass or, for a small
//! image, of several ([`Passes`]). Each bounce gathers the next ray
//! of every live subpath into one batch, casts it through the caster (so DACRT and
//! PDACRT see thousands of rays per call, never one), and then advances every subpath
//! in parallel with its hit: store the vertex, sample the BSDF, apply Russian roulette.
//! Connections are gathered the same way: every sample's shadow rays go to the caster
//! as one batch ([`resolve_wave`]).
//!
//! Each subpath owns its random stream (seeded by pixel or path and sample), and draws
//! from it in the same order a one-path-at-a-time walk would, so images do not depend
//! on the wave size, the thread count or the caster.

use super::bidir::{Pending, Vertex, VertexKind, camera_vertex, light_vertex};
use super::context::{Context, Passes};
use crate::bsdf::TransportMode;
use crate::cast::CastStats;
use crate::geometry::{Hit, Ray, barycentric_point, offset_ray_origin};
use crate::sampling::{Frame, Rng, cosine_hemisphere, uniform_sphere};
use glam::{Vec2, Vec3};
use rayon::prelude::*;
use std::f32::consts::{FRAC_1_PI, PI};
use std::ops::Range;

/// Region 0 of the statistics of every kernel that shades a hit (CIS's camera and
/// light shading, the LVC megakernel): one branch arm per material kind
/// ([`crate::scene::MaterialKind::index`]).
pub(crate) const SHADE_REGION: usize = 0;

/// Region of the arithmetic a shading kernel (`cis::shade`, the LVC megakernels) runs in
/// code it shares with the CPU integrators (BSDFs, sampling, MIS weights, connections),
/// declared there through `simt::declare!` with the weights of [`crate::cost`]; its
/// parts of the code follow in the regions after it.
pub const ARITHMETIC_REGION: usize = 1;
/// A shading launch's regions, in index order: the dispatch, then the declared
/// arithmetic by part of the code ([`crate::cost::Part`], in its order).
pub const SHADE_REGIONS: &[&str] = &[
    "shade",
    "arithmetic",
    "arithmetic: microfacet",
    "arithmetic: bsdf",
    "arithmetic: bidirectional",
    "arithmetic: sampling",
    "arithmetic: lights",
];

/// Adds a wave's resolved samples to the film in sample order: each sample's splats,
/// then, at the end of each pass, `before_close(film, pass)` (LVC adds the pass's
/// light splats there) and that pass's estimates (`add_pass`, when `estimates` is
/// given) or the end of a splat-only pass. The film sees the same calls in the same
/// order as when passes are rendered one at a time.
pub(crate) fn flush_wave(
    film: &mut crate::film::Film,
    span: Passes,
    wave: Range<u32>,
    resolved: Resolved,
    mut estimates: Option<&mut Vec<Vec3>>,
    mut before_close: impl FnMut(&mut crate::film::Film, u32),
) {
    // The splats of each run of samples up to a pass's end go to the film in one call
    // (the same splats in the same order, which the film may add in parallel).
    let splats_of = |run: Range<usize>| run.flat_map(|i| resolved.sample(i).1.iter().copied());
    let mut run_start = 0;
    for (i, k) in wave.clone().enumerate() {
        if let Some(e) = estimates.as_deref_mut() {
            e.push(resolved.sample(i).0);
        }
        if span.ends_pass(k) {
            film.add_splats(splats_of(run_start..i + 1));
            run_start = i + 1;
            before_close(film, span.at(k).1);
            match estimates.as_deref_mut() {
                Some(e) => {
                    film.add_pass(span.at(k).1, e);
                    e.clear();
                }
                None => film.end_pass(),
            }
        }
    }
    film.add_splats(splats_of(run_start..wave.len()));
}

/// One subpath being extended: its next ray, throughput and random stream.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Walker {
    pub ray: Ray,
    pub beta: Vec3,
    pub rng: Rng,
    /// Bounces made (Russian roulette starts after 3).
    pub bounces: u32,
    /// Whether it has a ray to cast.
    pub live: bool,
    /// What Russian roulette multiplies the throughput's largest component by: 1 for
    /// camera subpaths, whose throughput starts at the camera sample's weight; for a
    /// light subpath the reciprocal of its starting throughput's largest component, which
    /// carries the light's emitted power, so that its survival does not depend on the
    /// units or the brightness of the lights ([`start_light_subpath`]).
    pub rr_scale: f32,
    /// Position of this walker's ray in the current batch.
    slot: u32,
}

impl Walker {
    /// A walker that will cast `ray` with throughput `beta`.
    pub fn new(ray: Ray, beta: Vec3, rng: Rng) -> Walker {
        Walker { ray, beta, rng, bounces: 0, live: true, rr_scale: 1.0, slot: u32::MAX }
    }

    /// A walker resumed from stored state (a device pool slot).
    pub fn resume(ray: Ray, beta: Vec3, rng: Rng, bounces: u32, live: bool, rr_scale: f32) -> Walker {
        Walker { bounces, live, rr_scale, ..Walker::new(ray, beta, rng) }
    }

    /// A walker that casts nothing (its subpath is complete as it stands).
    pub fn done(rng: Rng) -> Walker {
        Walker { live: false, ..Walker::new(Ray::new(Vec3::ZERO, Vec3::Z), Vec3::ZERO, rng) }
    }
}

/// The subpaths of one wave: subpath `i`'s vertices are `verts[i * stride..][..len[i]]`.
#[derive(Default)]
pub(crate) struct Subpaths {
    verts: Vec<Vertex>,
    len: Vec<u32>,
    stride: usize,
}

impl Subpaths {
    /// Makes room for `n` empty subpaths of up to `stride` vertices (reusing the buffers).
    pub fn reset(&mut self, n: usize, stride: usize) {
        self.stride = stride;
        self.len.clear();
        self.len.resize(n, 0);
        self.verts.resize(n * stride, Vertex::default());
    }

    /// Subpath `i`.
    pub fn get(&self, i: usize) -> &[Vertex] {
        &self.verts[i * self.stride..][..self.len[i] as usize]
    }

    /// Number of subpaths.
    pub fn len(&self) -> usize {
        self.len.len()
    }

    /// Each subpath's storage with its length, in parallel, for starting subpaths.
    pub fn par_slots_mut(&mut self) -> impl IndexedParallelIterator<Item = (&mut [Vertex], &mut u32)> {
        self.verts.par_chunks_mut(self.stride.max(1)).zip(self.len.par_iter_mut())
    }
}

/// Camera subpaths of the samples `wave` of `span` (jittered, up to `max_depth`
/// bounces), the wave's sample `i` in slot `i`: started, not yet extended (see
/// [`extend_together`]). Each walker keeps its pixel sample's random stream for the
/// connections that follow.
pub(crate) fn start_camera_wave<'a>(
    ctx: &Context,
    span: Passes,
    wave: Range<u32>,
    subpaths: &'a mut Subpaths,
    walkers: &'a mut Vec<Walker>,
) -> Walk<'a> {
    let camera = &ctx.scene.camera;
    let max_vertices = ctx.opts.max_depth as usize + 2;
    subpaths.reset(wave.len(), max_vertices);
    subpaths
        .par_slots_mut()
        .zip(wave)
        .map(|((verts, len), k)| {
            let (pixel, pass) = span.at(k);
            verts[0] = camera_vertex(camera);
            *len = 1;
            let rng = Rng::for_sample(ctx.opts.seed, pixel as u64, pass as u64);
            let (film_pos, weight) = ctx.camera_sample(pixel, pass);
            Walker::new(camera.ray(&ctx.projection, film_pos, Vec2::ZERO), Vec3::splat(weight), rng)
        })
        .collect_into_vec(walkers);
    Walk { walkers, subpaths, mode: TransportMode::Radiance, max_vertices }
}

/// `n` light subpaths of up to `max_vertices` vertices, subpath `i` drawing from
/// `rng_of(i)`: a light sample (by power) as the first vertex, and a walker to extend
/// it in importance mode.
pub(crate) fn start_light_wave<'a>(
    ctx: &Context,
    n: usize,
    rng_of: impl Fn(usize) -> Rng + Sync,
    max_vertices: usize,
    subpaths: &'a mut Subpaths,
    walkers: &'a mut Vec<Walker>,
) -> Walk<'a> {
    subpaths.reset(n, max_vertices);
    subpaths
        .par_slots_mut()
        .enumerate()
        .map(|(i, (verts, len))| {
            let (origin, walker) = start_light_subpath(ctx, rng_of(i), max_vertices);
            if let Some(v) = origin {
                verts[0] = v;
                *len = 1;
            }
            walker
        })
        .collect_into_vec(walkers);
    Walk { walkers, subpaths, mode: TransportMode::Importance, max_vertices }
}

/// The first vertex of a light subpath (none when the scene has no light to sample),
/// and the walker that continues it. Allocation-free: kernels call it.
pub(crate) fn start_light_subpath(ctx: &Context, mut rng: Rng, max_vertices: usize) -> (Option<Vertex>, Walker) {
    let Some(ls) = ctx.lights.sample(ctx.scene, rng.uniform(), rng.uniform2()) else {
        return (None, Walker::done(rng));
    };
    let origin = light_vertex(&ls);
    let (dir, pdf_dir, cos) = if ls.is_delta {
        (uniform_sphere(rng.uniform2()), 1.0 / (4.0 * PI), 1.0)
    } else {
        let local = cosine_hemisphere(rng.uniform2());
        (Frame::from_normal(ls.normal).to_world(local), local.z * FRAC_1_PI, local.z)
    };
    if pdf_dir <= 0.0 || max_vertices < 2 {
        return (Some(origin), Walker::done(rng));
    }
    let beta = origin.beta * ls.emitted * cos / pdf_dir;
    let start = if ls.is_delta { ls.position } else { offset_ray_origin(ls.position, ls.normal) };
    let largest = beta.max_element();
    let rr_scale = if largest > 0.0 { 1.0 / largest } else { 1.0 };
    (Some(origin), Walker { rr_scale, ..Walker::new(Ray::new(start, dir), beta, rng) })
}

/// A set of subpaths to extend together: their walkers and storage, the transport
/// mode of their BSDF samples, and their longest length.
pub(crate) struct Walk<'a> {
    pub walkers: &'a mut [Walker],
    pub subpaths: &'a mut Subpaths,
    pub mode: TransportMode,
    pub max_vertices: usize,
}

/// Extends several sets of subpaths (e.g. a wave's camera and light subpaths) with one
/// batch of rays per bounce for all of them: fewer, larger batches for the caster.
pub(crate) fn extend_together(ctx: &Context, walks: &mut [Walk]) -> CastStats {
    let mut stats = CastStats::default();
    let (mut rays, mut hits) = (Vec::new(), Vec::new());
    for walk in walks.iter_mut() {
        for (w, &len) in walk.walkers.iter_mut().zip(&walk.subpaths.len) {
            w.live &= (len as usize) < walk.max_vertices;
        }
    }
    loop {
        // Gather: the live walkers' rays, set after set, in walker order.
        rays.clear();
        for w in walks.iter_mut().flat_map(|walk| walk.walkers.iter_mut()).filter(|w| w.live) {
            w.slot = rays.len() as u32;
            rays.push(w.ray);
        }
        if rays.is_empty() {
            return stats;
        }
        hits.clear();
        hits.resize(rays.len(), Hit::MISS);
        stats = stats.merge(ctx.caster.closest(&rays, &mut hits));
        // Advance every live walker with its hit.
        for walk in walks.iter_mut() {
            let (mode, max_vertices, stride) = (walk.mode, walk.max_vertices, walk.subpaths.stride);
            let slots = walk.subpaths.verts.par_chunks_mut(stride).zip(walk.subpaths.len.par_iter_mut());
            walk.walkers.par_iter_mut().zip(slots).for_each(|(w, (verts, len))| {
                if w.live
                    && let Some(v) = step(ctx, w, &hits[w.slot as usize], *len as usize, mode, max_vertices)
                {
                    verts[*len as usize] = v;
                    *len += 1;
                }
            });
        }
    }
}

/// One bounce of one subpath of `len` vertices: the hit becomes its next vertex
/// (returned; none on a miss or a degenerate triangle), then the BSDF chooses the next
/// ray, or the walker stops (`live` false). Allocation-free: kernels call it.
pub(crate) fn step(
    ctx: &Context,
    w: &mut Walker,
    hit: &Hit,
    len: usize,
    mode: TransportMode,
    max_vertices: usize,
) -> Option<Vertex> {
    w.live = false;
    if !hit.is_hit() {
        return None;
    }
    let [a, b, c] = ctx.scene.vertices(hit.prim);
    // The render's stored normal: the value the corners give (as the kernels' CUDA twins
    // compute it), read instead of worked out; the model declares neither.
    let n = ctx.normal(hit.prim);
    if n == Vec3::ZERO {
        return None;
    }
    let p = barycentric_point([a, b, c], hit.u, hit.v);
    let mut vertex = Vertex::new(VertexKind::Surface, p, n, hit.prim, w.beta, false, ctx.scene.emission_of(hit.prim));
    if len + 1 >= max_vertices {
        return Some(vertex);
    }
    let frame = Frame::from_normal(n);
    let wo = frame.to_local(-w.ray.dir.normalize());
    let Some(s) = ctx.scene.bsdf(hit.prim, wo).sample_f(wo, w.rng.uniform(), w.rng.uniform2(), mode) else {
        return Some(vertex);
    };
    vertex.delta = s.delta;
    w.beta *= s.weight;
    w.bounces += 1;
    if w.bounces > 3 {
        let q = (w.beta.max_element() * w.rr_scale).min(0.95);
        if w.rng.uniform() >= q {
            return Some(vertex);
        }
        w.beta /= q;
    }
    if !w.beta.is_finite() || w.beta.max_element() <= 0.0 {
        return Some(vertex);
    }
    let wi = frame.to_world(s.wi);
    w.ray = Ray::new(offset_ray_origin(p, if wi.dot(n) > 0.0 { n } else { -n }), wi);
    w.live = true;
    Some(vertex)
}

/// Every sample's pending contributions in a wave, in chunks of [`PENDING_CHUNK`]
/// samples: in a chunk, sample `i`'s are `items[ends[i - 1]..ends[i]]`. Chunks are
/// filled and resolved in parallel, so nothing is allocated per sample, and they are
/// fixed, so the lists are the same at any thread count. Kept from wave to wave with
/// the shadow-ray batch they resolve through: a wave's lists and rays run to tens of
/// megabytes, which fresh allocations would page-fault in again every wave.
#[derive(Default)]
pub(crate) struct PendingLists {
    chunks: Vec<Chunk<Pending>>,
    /// Chunks the current wave uses (the ones past it keep their storage).
    used: usize,
    /// The wave's shadow rays, in list order, and whether each is blocked.
    rays: Vec<Ray>,
    blocked: Vec<bool>,
}

/// Samples per chunk of pending lists.
const PENDING_CHUNK: usize = 256;

/// One chunk's lists, side by side (`ends[i]` closes sample `i`'s).
struct Chunk<T> {
    items: Vec<T>,
    ends: Vec<usize>,
}

impl<T> Chunk<T> {
    fn new() -> Self {
        Chunk { items: Vec::new(), ends: Vec::with_capacity(PENDING_CHUNK) }
    }

    fn clear(&mut self) {
        self.items.clear();
        self.ends.clear();
    }

    /// Closes the list of the next sample.
    fn close(&mut self) {
        self.ends.push(self.items.len());
    }

    /// Sample `i`'s list (`i` within the chunk).
    fn get(&self, i: usize) -> &[T] {
        &self.items[if i == 0 { 0 } else { self.ends[i - 1] }..self.ends[i]]
    }
}

impl PendingLists {
    /// Makes the lists those of samples `0..n`: `one(i, out, scratch)` appends sample
    /// `i`'s contributions to `out` (`scratch` is a per-thread buffer it may reuse).
    pub(crate) fn fill<S: Default>(&mut self, n: usize, one: impl Fn(usize, &mut Vec<Pending>, &mut S) + Sync + Send) {
        self.used = n.div_ceil(PENDING_CHUNK);
        if self.chunks.len() < self.used {
            self.chunks.resize_with(self.used, Chunk::new);
        }
        self.chunks[..self.used].par_iter_mut().enumerate().for_each_init(S::default, |scratch, (c, chunk)| {
            chunk.clear();
            for i in c * PENDING_CHUNK..((c + 1) * PENDING_CHUNK).min(n) {
                one(i, &mut chunk.items, scratch);
                chunk.close();
            }
        });
    }
}

/// One chunk of a [`Resolved`] wave: its samples' estimates and their splats.
type ResolvedChunk = (Vec<Vec3>, Chunk<(Vec2, Vec3)>);

/// What the samples of a wave add to the image once their shadow rays are answered:
/// each sample's pixel estimate and its splats (in the order they were made), in the
/// pending lists' chunks.
pub(crate) struct Resolved {
    chunks: Vec<ResolvedChunk>,
}

impl Resolved {
    /// Sample `i`'s estimate and splats.
    pub(crate) fn sample(&self, i: usize) -> (Vec3, &[(Vec2, Vec3)]) {
        let (estimates, splats) = &self.chunks[i / PENDING_CHUNK];
        (estimates[i % PENDING_CHUNK], splats.get(i % PENDING_CHUNK))
    }
}

/// Casts the shadow rays of every sample's pending contributions as one batch and sums
/// each sample's visible ones, in sample order.
pub(crate) fn resolve_wave(ctx: &Context, pending: &mut PendingLists) -> (Resolved, CastStats) {
    let PendingLists { chunks, used, rays, blocked } = pending;
    let chunks = &chunks[..*used];
    // Where each chunk's rays and answers start; the rays gathered into them in parallel.
    let counts: Vec<usize> = chunks.par_iter().map(|c| c.items.iter().filter(|p| p.0.is_some()).count()).collect();
    let starts: Vec<usize> = counts.iter().scan(0, |at, &n| Some(std::mem::replace(at, *at + n))).collect();
    let total = counts.iter().sum();
    // Written in place in parallel (a serial fill of the buffer first would be a serial
    // pass over tens of megabytes at every thread count).
    rays.clear();
    rays.reserve(total);
    let mut slices = Vec::with_capacity(chunks.len());
    let mut rest = &mut rays.spare_capacity_mut()[..total];
    for &n in &counts {
        let (slice, tail) = rest.split_at_mut(n);
        slices.push(slice);
        rest = tail;
    }
    let written: usize = chunks
        .par_iter()
        .zip(slices)
        .map(|(c, out)| out.iter_mut().zip(c.items.iter().filter_map(|p| p.0)).map(|(o, ray)| o.write(ray)).count())
        .sum();
    assert_eq!(written, total, "every counted shadow ray is written");
    // SAFETY: the first `total` slots of the spare capacity were written just above
    // (each chunk's slice holds exactly its counted rays, and the writes were counted).
    unsafe { rays.set_len(total) };
    blocked.clear();
    blocked.resize(total, false);
    let stats = if rays.is_empty() { CastStats::default() } else { ctx.caster.occluded(rays, blocked) };
    let resolved = chunks
        .par_iter()
        .zip(starts)
        .map(|(c, start)| {
            let mut blocked = blocked[start..].iter();
            let (mut estimates, mut splats) = (Vec::with_capacity(c.ends.len()), Chunk::new());
            for i in 0..c.ends.len() {
                let mut estimate = Vec3::ZERO;
                for &(ray, l, target) in c.get(i) {
                    if ray.is_some() && *blocked.next().unwrap_or(&true) {
                        continue;
                    }
                    match target {
                        None => estimate += l,
                        Some(px) => splats.items.push((px, l)),
                    }
                }
                estimates.push(estimate);
                splats.close();
            }
            (estimates, splats)
        })
        .collect();
    (Resolved { chunks: resolved }, stats)
}

/// Buffers of one wave, kept across waves and passes, and the wave size.
#[derive(Default)]
pub(crate) struct WaveBuffers {
    pub camera: Subpaths,
    pub light: Subpaths,
    pub camera_walkers: Vec<Walker>,
    pub light_walkers: Vec<Walker>,
    /// The wave's pending contributions and their shadow rays.
    pub pending: PendingLists,
    /// Samples per wave, or `None` for the context's ([`Context::wave`]); the image
    /// does not depend on it.
    pub wave: Option<u32>,
}

impl WaveBuffers {
    /// Samples per wave with `ctx`.
    pub fn wave(&self, ctx: &Context) -> u32 {
        self.wave.unwrap_or_else(|| ctx.wave())
    }
}
