//! The light vertex cache's kernels: storing ended subpaths, their camera splats, and
//! the camera side's reads ([`CacheRead`]). Plain `Copy` arguments; no allocation.

use super::host::{Connections, Prefetch, StrategyCounts, light_splats, prefetch_entries, vertex_strategies};
use crate::geometry::Ray;
use crate::render::bidir::{MAX_PATH, Pending, StackList, Vertex, VertexKind, VertexList, connectible};
use crate::render::context::Context;
use crate::render::mis::{Densities, subpath_densities};
use crate::sampling::Rng;
use glam::{Vec2, Vec3};
use simt::{DeviceCopy, Global, GlobalMut, Readable, Thread};

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
/// splat entries (shadow rays still to be cast), if its number is in `share`.
#[allow(clippy::too_many_arguments)]
pub fn light_splat(
    t: &Thread,
    ctx: &Context,
    p: usize,
    (paths, vertices): (&Global<[u32; 3]>, &Global<Vertex>),
    (counts, share): (StrategyCounts, (u32, u32)),
    stride: usize,
    splats: &GlobalMut<SplatData>,
) {
    splat_entries(t, ctx, p, (paths, vertices), (counts, share), (stride, splats), &|_| 1);
}

/// The camera splats of cache subpath `p` into its `stride` entries, in vertex order,
/// each with the state `state_of(shadow ray)` gives it (0: left out); the rest cleared,
/// and all of them when the subpath's number is outside `share` (the subpath numbers
/// whose splats join this camera pass: [`super::host::Iterations::splat_range`]).
pub fn splat_entries(
    t: &Thread,
    ctx: &Context,
    p: usize,
    (paths, vertices): (&Global<[u32; 3]>, &Global<Vertex>),
    (counts, share): (StrategyCounts, (u32, u32)),
    (stride, splats): (usize, &GlobalMut<SplatData>),
    state_of: &dyn Fn(Ray) -> u32,
) {
    let [number, start, len] = t.load(paths, p);
    let mut next = 0;
    if (share.0..share.1).contains(&number) {
        let mut verts = VertexList::default();
        load_vertices(t, vertices, start as usize..start as usize + len as usize, &mut verts);
        let mut path = VertexList::default();
        light_splats(ctx, &verts, &[], counts, &mut path, &mut |ray, value, film| {
            let state = state_of(ray);
            if state != 0 {
                t.store(splats, p * stride + next, SplatData { ray, value, film, state });
                next += 1;
            }
        });
    }
    for k in next..stride {
        t.store(splats, p * stride + k, SplatData::default());
    }
}

/// The densities of camera subpath `cam` that every strategy at its vertices reads
/// ([`subpath_densities`]), evaluated once; none in a measured launch, whose lanes
/// evaluate each density where a weight needs it, as the CUDA twins do (the weights
/// are the same bit for bit either way).
pub fn known_densities(t: &Thread, ctx: &Context, cam: &[Vertex]) -> StackList<Densities, MAX_PATH> {
    if t.is_measured() { StackList::default() } else { subpath_densities(ctx, cam) }
}

/// The light vertex cache as camera-side kernels read it: CIS's `cis::shade` and the
/// LVC megakernel's `lvc::camera_path`.
#[derive(Clone, Copy)]
pub struct CacheRead<'a> {
    /// Vertices, subpath after subpath.
    pub vertices: Global<'a, Vertex>,
    /// Per cache entry: its subpath's first vertex and `s`.
    pub entries: Global<'a, [u32; 2]>,
    /// Light subpaths per vertex count, for the MIS weights.
    pub counts: StrategyCounts,
    /// How camera vertices pick cache vertices.
    pub connections: Connections,
}

/// Appends vertices `range` of `from` to `into`: each vertex copied whole, its fifteen
/// words loaded back to back and waited for once (one round of the time model's
/// chain), as a copy of a record compiles when nothing of one word is needed to load
/// the next. Each call site is a copy of its own, as nvcc inlines it ([`Thread::inlined`]).
#[track_caller]
pub(crate) fn load_vertices(
    t: &Thread,
    from: &impl Readable<Vertex>,
    range: std::ops::Range<usize>,
    into: &mut VertexList,
) {
    let _call = t.inlined();
    // Not `#[track_caller]`: the loads and their group keep sites of their own.
    fn copy(t: &Thread, from: &impl Readable<Vertex>, range: std::ops::Range<usize>, into: &mut VertexList) {
        for k in range {
            let _vertex = t.loads_together();
            into.push(t.load(from, k));
        }
    }
    copy(t, from, range, into)
}

impl CacheRead<'_> {
    /// Cache entry `e`'s light subpath up to its vertex, loaded into `light` (with
    /// `tail`, only its last two vertices); returns `s`.
    pub fn subpath(&self, t: &Thread, e: usize, light: &mut VertexList, tail: bool) -> usize {
        let [start, s] = t.load(&self.entries, e);
        light.clear();
        let from = if tail { (s as usize).saturating_sub(2) } else { 0 };
        load_vertices(t, &self.vertices, start as usize + from..start as usize + s as usize, light);
        s as usize
    }

    /// Every strategy at vertex `t_len` of the camera subpath `cam`, with its cache
    /// connections, into `sink` (LVC's `vertex_strategies` over this cache).
    /// `cam_known`: the camera subpath's densities ([`known_densities`]), or empty.
    #[allow(clippy::too_many_arguments)]
    pub fn strategies(
        &self,
        t: &Thread,
        ctx: &Context,
        (cam, cam_known): (&[Vertex], &[Densities]),
        t_len: usize,
        rng: &mut Rng,
        path: &mut VertexList,
        sink: &mut dyn FnMut(Pending),
    ) {
        let subpath = |e: usize, light: &mut VertexList, tail: bool| self.subpath(t, e, light, tail);
        let prefetch = |drawn: &[usize]| self.prefetch(drawn);
        let hint: Prefetch = if t.is_measured() { None } else { Some(&prefetch) };
        let n = self.entries.len();
        let access = (&subpath as _, hint);
        vertex_strategies(ctx, (cam, cam_known), t_len, n, access, self.counts, self.connections, rng, path, sink);
    }

    /// `LightVertexCache::prefetch` on the device cache: a host hint that loads nothing
    /// the launch counts.
    fn prefetch(&self, drawn: &[usize]) {
        prefetch_entries(
            drawn,
            |e| self.entries.prefetch(e, 1),
            |e| self.entries.read(e).into(),
            |start, s| self.vertices.prefetch(start, s),
        );
    }
}

// SAFETY: #[repr(C)], fields of 4 bytes without padding.
unsafe impl DeviceCopy for SplatData {}
