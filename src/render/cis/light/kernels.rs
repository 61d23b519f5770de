//! Kernels of the light pass on the device: CIS-LBDPT's stream of light subpaths, and
//! the device light vertex cache that the LVC-BDPT megakernel shares. Plain functions of
//! a thread and `Copy` data; none allocates, forks, launches or casts rays (the host in
//! `mod.rs` casts each bounce's rays as one batch between launches).

use crate::bsdf::TransportMode;
use crate::geometry::{Hit, Ray};
use crate::render::Context;
use crate::render::bidir::{Vertex, VertexKind, VertexList, connectible};
use crate::render::cis::kernels::{SHADE_REGION, kind_index};
use crate::render::lvc::{StrategyCounts, light_path_rng, light_splats};
use crate::render::walk::{Walker, start_light_subpath, step};
use crate::sampling::Rng;
use glam::{Vec2, Vec3};
use simt::{DeviceCopy, Global, GlobalMut, Thread};

/// One light subpath in the pool.
#[derive(Clone, Copy, Debug, Default)]
#[repr(C)]
pub struct LightSlot {
    /// The subpath's random stream.
    pub rng: Rng,
    /// The ray to cast next.
    pub ray: Ray,
    /// Throughput so far.
    pub beta: Vec3,
    /// Which light subpath of the iteration it is.
    pub path: u32,
    /// Vertices stored so far (in the slot's staging area).
    pub len: u32,
    /// Bounces made (Russian roulette starts after 3).
    pub bounces: u32,
    /// 1 while the subpath goes on.
    pub alive: u32,
    /// Padding to a 16-byte multiple.
    pub _pad: u32,
}

/// A camera splat waiting for its shadow ray (`state` 1), visible (2), or empty (0).
#[derive(Clone, Copy, Debug, Default)]
#[repr(C)]
pub struct SplatData {
    /// The shadow ray from the light vertex to the camera.
    pub ray: Ray,
    /// What it adds to the film.
    pub value: Vec3,
    /// Where on the film.
    pub film: Vec2,
    /// 0 empty, 1 waiting for its shadow ray, 2 visible.
    pub state: u32,
}

// SAFETY: #[repr(C)], 4- and 8-byte fields laid out without padding.
unsafe impl DeviceCopy for LightSlot {}
unsafe impl DeviceCopy for SplatData {}

impl LightSlot {
    fn new(w: &Walker, path: u32, len: u32) -> LightSlot {
        LightSlot { rng: w.rng, ray: w.ray, beta: w.beta, path, len, bounces: w.bounces, alive: w.live as u32, _pad: 0 }
    }

    fn walker(&self) -> Walker {
        Walker::resume(self.ray, self.beta, self.rng, self.bounces, self.alive != 0)
    }
}

/// `cis::light_generate`: light subpath `first_path + i` starts in free slot `free[i]`:
/// its light vertex goes to the slot's staging area (`stride` vertices per slot).
#[allow(clippy::too_many_arguments)]
pub fn light_generate(
    t: &Thread,
    ctx: &Context,
    i: usize,
    free: &Global<u32>,
    (first_path, pass): (u32, u32),
    stride: usize,
    slots: &GlobalMut<LightSlot>,
    staging: &GlobalMut<Vertex>,
) {
    let slot = t.load(free, i) as usize;
    let path = first_path + i as u32;
    let (origin, walker) = start_light_subpath(ctx, light_path_rng(ctx, path, pass), stride);
    if let Some(v) = origin {
        t.store(staging, slot * stride, v);
    }
    t.store(slots, slot, LightSlot::new(&walker, path, origin.is_some() as u32));
}

/// What the light shading kernel reads and writes.
#[derive(Clone, Copy)]
pub struct LightShadeArgs<'a> {
    /// Active slots in material order.
    pub order: Global<'a, u32>,
    /// The active list.
    pub active: Global<'a, u32>,
    /// Per active slot: its ray's hit.
    pub hits: Global<'a, Hit>,
    /// The pool.
    pub slots: GlobalMut<'a, LightSlot>,
    /// Staged vertices, `stride` per slot.
    pub staging: GlobalMut<'a, Vertex>,
    /// Vertices per subpath at most.
    pub stride: usize,
}

/// `cis::light_shade`: the subpath at sorted position `j` meets its hit: the vertex is
/// staged, and the BSDF (in importance mode) chooses the next ray or ends the subpath.
pub fn light_shade(t: &Thread, ctx: &Context, a: &LightShadeArgs, j: usize) {
    let i = t.load(&a.order, j) as usize;
    let slot_id = t.load(&a.active, i) as usize;
    let mut slot = t.load(&a.slots, slot_id);
    if slot.alive == 0 {
        return; // ended when it started (no light to sample): an idle lane
    }
    let hit = t.load(&a.hits, i);
    if hit.is_hit() {
        t.work(SHADE_REGION, kind_index(ctx.scene.material(hit.prim).kind_name()), 1);
    }
    let mut walker = slot.walker();
    let len = slot.len as usize;
    if let Some(v) = step(ctx, &mut walker, &hit, len, TransportMode::Importance, a.stride) {
        t.store(&a.staging, slot_id * a.stride + len, v);
        slot.len += 1;
    }
    let len = slot.len;
    slot = LightSlot::new(&walker, slot.path, len);
    t.store(&a.slots, slot_id, slot);
}

/// `cis::finished`: entry `i` of the finished list as (slot, subpath, vertices).
pub fn finished(t: &Thread, i: usize, done: &Global<u32>, slots: &Global<LightSlot>, out: &GlobalMut<[u32; 3]>) {
    let slot = t.load(done, i);
    let s = t.load(slots, slot as usize);
    t.store(out, i, [slot, s.path, s.len]);
}

/// The device light vertex cache: every vertex of every finished subpath, subpath after
/// subpath; per cached (connectible) vertex its subpath's first vertex and `s`; and per
/// subpath (its number in the iteration, first vertex, length).
#[derive(Clone, Copy)]
pub struct CacheViews<'a> {
    /// Vertices.
    pub vertices: GlobalMut<'a, Vertex>,
    /// Entries.
    pub entries: GlobalMut<'a, [u32; 2]>,
    /// Subpaths.
    pub paths: GlobalMut<'a, [u32; 3]>,
}

/// Whether staged vertex `k` of a subpath enters the cache.
fn cached(ctx: &Context, v: &Vertex) -> bool {
    v.kind == VertexKind::Surface && connectible(ctx, v)
}

/// `cis::cache_counts`: vertices and cache entries of finished subpath `f`.
pub fn cache_counts(
    t: &Thread,
    ctx: &Context,
    f: usize,
    (done, staging, stride): (&Global<[u32; 3]>, &Global<Vertex>, usize),
    n_vertices: &GlobalMut<u32>,
    n_entries: &GlobalMut<u32>,
) {
    let [slot, _, len] = t.load(done, f);
    let base = slot as usize * stride;
    let entries = (0..len as usize).filter(|&k| cached(ctx, &t.load(staging, base + k))).count();
    t.store(n_vertices, f, len);
    t.store(n_entries, f, entries as u32);
}

/// `cis::cache_store`: finished subpath `f` copied into the cache at its offsets
/// (`bases` are the cache's sizes before this append).
#[allow(clippy::too_many_arguments)]
pub fn cache_store(
    t: &Thread,
    ctx: &Context,
    f: usize,
    (done, staging, stride): (&Global<[u32; 3]>, &Global<Vertex>, usize),
    (vertex_offsets, entry_offsets): (&Global<u32>, &Global<u32>),
    bases: [u32; 3],
    cache: &CacheViews,
) {
    let [slot, path, len] = t.load(done, f);
    let start = bases[0] + t.load(vertex_offsets, f);
    let mut entry = (bases[1] + t.load(entry_offsets, f)) as usize;
    for k in 0..len as usize {
        let v = t.load(staging, slot as usize * stride + k);
        t.store(&cache.vertices, start as usize + k, v);
        if cached(ctx, &v) {
            t.store(&cache.entries, entry, [start, k as u32 + 1]);
            entry += 1;
        }
    }
    t.store(&cache.paths, bases[2] as usize + f, [path, start, len]);
}

/// `cis::light_splat`: the camera splats of cache subpath `p`, into its `stride`
/// splat entries (shadow rays still to be cast).
#[allow(clippy::too_many_arguments)]
pub fn light_splat(
    t: &Thread,
    ctx: &Context,
    p: usize,
    (paths, vertices): (&Global<[u32; 3]>, &Global<Vertex>),
    (counts, n_light): (StrategyCounts, u32),
    stride: usize,
    splats: &GlobalMut<SplatData>,
) {
    splat_entries(t, ctx, p, (paths, vertices), (counts, n_light), (stride, splats), &|_| 1);
}

/// The camera splats of cache subpath `p` into its `stride` entries, in vertex order,
/// each with the state `state_of(shadow ray)` gives it (0: left out); the rest cleared.
pub fn splat_entries(
    t: &Thread,
    ctx: &Context,
    p: usize,
    (paths, vertices): (&Global<[u32; 3]>, &Global<Vertex>),
    (counts, n_light): (StrategyCounts, u32),
    (stride, splats): (usize, &GlobalMut<SplatData>),
    state_of: &dyn Fn(Ray) -> u32,
) {
    let [_, start, len] = t.load(paths, p);
    let mut verts = VertexList::default();
    for k in 0..len as usize {
        verts.push(t.load(vertices, start as usize + k));
    }
    let (mut path, mut next) = (VertexList::default(), 0);
    light_splats(ctx, &verts, counts, n_light, &mut path, &mut |ray, value, film| {
        let state = state_of(ray);
        if state != 0 {
            t.store(splats, p * stride + next, SplatData { ray, value, film, state });
            next += 1;
        }
    });
    for k in next..stride {
        t.store(splats, p * stride + k, SplatData::default());
    }
}
