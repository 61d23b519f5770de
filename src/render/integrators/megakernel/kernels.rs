//! The LVC-BDPT megakernel's kernels: each thread does a whole subpath, tracing its
//! rays one at a time where it needs them, as a GPU megakernel traverses its BVH per
//! thread. Plain functions of a thread and `Copy` data; none allocates, forks or
//! launches. Each ray is traversed in the thread when the caster can (`--caster lbvh`,
//! the GPU BVH's twin), its work counted in region `trace`; else it is declared as one
//! instruction of that region (arm 0: closest hit, arm 1: shadow). Each shading as one of region `shade` on its material's
//! arm, so that the measured SIMD efficiency counts the lanes idle while others go on.

use crate::bsdf::TransportMode;
use crate::geometry::{Hit, Ray};
use crate::render::bidir::{Vertex, VertexList, camera_vertex};
use crate::render::cache::host::{StrategyCounts, light_path_rng};
use crate::render::cache::kernels::{CacheRead, SplatData, known_densities, splat_entries};
use crate::render::context::Context;
pub use crate::render::walk::ARITHMETIC_REGION;
use crate::render::walk::{SHADE_REGION, SHADE_REGIONS, Walker, start_light_subpath, step};
use crate::sampling::Rng;
use glam::{Vec2, Vec3};
use simt::{Global, GlobalMut, Thread};

/// The regions a megakernel launch names: a shading launch's (the dispatch, then the
/// shared code's arithmetic by part, [`ARITHMETIC_REGION`] on), then the ray casts'.
pub const REGIONS: [&str; SHADE_REGIONS.len() + 1] = {
    let mut r = [""; SHADE_REGIONS.len() + 1];
    let mut k = 0;
    while k < SHADE_REGIONS.len() {
        r[k] = SHADE_REGIONS[k];
        k += 1;
    }
    r[k] = "trace";
    r
};
/// Region of the ray casts.
pub const TRACE_REGION: usize = SHADE_REGIONS.len();

/// The closest hit of `ray`: traversed in this thread where the caster can (the GPU
/// BVH's twin, its work counted in region `trace`), else cast alone through the caster
/// and declared as one instruction.
fn trace(t: &Thread, ctx: &Context, ray: Ray) -> Hit {
    if let Some(k) = ctx.caster.in_thread() {
        return k.closest_in_thread(t, &ray, TRACE_REGION);
    }
    t.work(TRACE_REGION, 0, 1);
    ctx.caster.closest_single(&ray).0
}

/// Whether nothing blocks shadow ray `ray`, traversed as [`trace`] does.
fn unblocked(t: &Thread, ctx: &Context, ray: Ray) -> bool {
    if let Some(k) = ctx.caster.in_thread() {
        return !k.occluded_in_thread(t, &ray, TRACE_REGION);
    }
    t.work(TRACE_REGION, 1, 1);
    !ctx.caster.occluded_single(&ray).0
}

/// Extends `verts` with `w` until the walker stops, one traced ray per bounce.
fn walk(t: &Thread, ctx: &Context, w: &mut Walker, verts: &mut VertexList, mode: TransportMode, max_vertices: usize) {
    w.live &= verts.len() < max_vertices;
    while w.live {
        let hit = trace(t, ctx, w.ray);
        if hit.is_hit() {
            t.work(SHADE_REGION, ctx.scene.material(hit.prim).kind().index(), 1);
        }
        if let Some(v) = step(ctx, w, &hit, verts.len(), mode, max_vertices) {
            verts.push(v);
        }
    }
}

/// `lvc::light_path`: light subpath `first + i` traced whole and staged in slot `i`
/// (`stride` vertices), listed in `done` as (slot, subpath, length).
pub fn light_path(
    t: &Thread,
    ctx: &Context,
    i: usize,
    (first, pass): (u32, u32),
    stride: usize,
    staging: &GlobalMut<Vertex>,
    done: &GlobalMut<[u32; 3]>,
) {
    let path = first + i as u32;
    let (origin, mut w) = start_light_subpath(ctx, light_path_rng(ctx, path, pass), stride);
    let mut verts = VertexList::default();
    if let Some(v) = origin {
        verts.push(v);
        walk(t, ctx, &mut w, &mut verts, TransportMode::Importance, stride);
    }
    for (k, v) in verts.iter().enumerate() {
        t.store(staging, i * stride + k, *v);
    }
    t.store(done, i, [i as u32, path, verts.len() as u32]);
}

/// `lvc::splat`: the camera splats of cache subpath `p`, each shadow ray traced at
/// once; the visible ones fill its `stride` entries (`state` 2) in vertex order.
#[allow(clippy::too_many_arguments)]
pub fn splat(
    t: &Thread,
    ctx: &Context,
    p: usize,
    (paths, vertices): (&Global<[u32; 3]>, &Global<Vertex>),
    (counts, share): (StrategyCounts, (u32, u32)),
    stride: usize,
    splats: &GlobalMut<SplatData>,
) {
    let visible = |ray| if unblocked(t, ctx, ray) { 2 } else { 0 };
    splat_entries(t, ctx, p, (paths, vertices), (counts, share), (stride, splats), &visible);
}

/// `lvc::camera_path`: pixel `pixel`'s sample of pass `pass`, whole: its camera subpath
/// traced, then every strategy at every vertex, each shadow ray traced at once; the
/// estimate goes to `estimates[pixel]`.
pub fn camera_path(
    t: &Thread,
    ctx: &Context,
    pixel: u32,
    pass: u32,
    cache: &CacheRead,
    estimates: &GlobalMut<[f32; 3]>,
) {
    let camera = &ctx.scene.camera;
    let mut cam = VertexList::default();
    cam.push(camera_vertex(camera));
    let rng = Rng::for_sample(ctx.opts.seed, pixel as u64, pass as u64);
    let (film_pos, weight) = ctx.camera_sample(pixel, pass);
    let mut walker = Walker::new(camera.ray(&ctx.projection, film_pos, Vec2::ZERO), Vec3::splat(weight), rng);
    walk(t, ctx, &mut walker, &mut cam, TransportMode::Radiance, ctx.opts.max_depth as usize + 2);
    let mut rng = walker.rng;
    let (mut path, mut estimate) = (VertexList::default(), Vec3::ZERO);
    let known = known_densities(t, ctx, &cam);
    for k in 2..=cam.len() {
        cache.strategies(t, ctx, (&cam, &known), k, &mut rng, &mut path, &mut |p| {
            if p.0.is_none_or(|ray| unblocked(t, ctx, ray)) {
                estimate += p.1;
            }
        });
    }
    t.store(estimates, pixel as usize, estimate.to_array());
}
