//! The bidirectional core shared by light tracing, BDPT, LVC-BDPT and CIS-LBDPT
//! (Veach 1997; the vertex bookkeeping follows the structure of pbrt's BDPT): subpath
//! vertices, the strategies that join a light and a camera subpath, and their
//! multiple-importance weights. How subpaths are extended is in `render/walk.rs`.
//!
//! A light subpath starts at a point sampled on a light (by power), a camera subpath at
//! the pinhole. Strategy (s, t) joins the first s light vertices to the first t camera
//! vertices: s = 0 (the camera path hits an emitter), s = 1 (a fresh light sample,
//! next-event estimation), t = 1 (a light vertex connected to the camera and splatted
//! onto the film), and the general connections. Each is weighted by the balance
//! heuristic over all strategies that could have produced the same path, computed from
//! the area densities of every vertex in both directions (`mis_weight`). Densities
//! through a vertex whose sampled lobe was a delta are taken as 1 on both sides and
//! strategies that would connect at such a vertex are excluded, so delta factors cancel.
//!
//! Light and camera connections need a pinhole camera (`aperture_radius = 0`).

use super::context::Context;
use crate::bsdf::TransportMode;
use crate::cost::declare;
use crate::cost::{BRANCH, DIV, DOT, NORMALIZE, SQRT, V3, V3_DIV, VERTEX_COPY};
use crate::geometry::{Ray, offset_ray_origin};
use crate::lights::LightSample;
use crate::sampling::Rng;
use crate::scene::{Camera, Projection};
use glam::{Vec2, Vec3};

/// The part of the code this module's declared arithmetic counts as ([`crate::cost::Part`]).
const COST_PART: crate::cost::Part = crate::cost::Part::Bidirectional;

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[repr(u32)]
/// What a subpath vertex is.
pub enum VertexKind {
    /// The camera (pinhole) vertex.
    Camera,
    /// A light sample (area light point or point light); for paths that reach an
    /// emitter from the camera side, the hit vertex is relabelled a light.
    Light,
    /// A scattering surface.
    Surface,
}

/// One vertex of a light or camera subpath. Plain data (it lives in device buffers of
/// the streaming integrator too).
#[derive(Clone, Copy, Debug)]
#[repr(C)]
pub struct Vertex {
    /// What the vertex is.
    pub kind: VertexKind,
    /// Position.
    pub p: Vec3,
    /// Unit geometric normal (surfaces, area lights), the viewing direction (camera),
    /// or zero (point lights).
    pub n: Vec3,
    /// Triangle of a surface or area light; `u32::MAX` otherwise.
    pub tri: u32,
    /// Throughput of the subpath up to this vertex (for a light vertex, 1 / its density).
    pub beta: Vec3,
    /// Emitted radiance (area light) or intensity (point light).
    pub le: Vec3,
    /// The lobe sampled here was a delta lobe (or: a point light).
    pub delta: bool,
    /// Padding (plain-data layout).
    pub _pad: [u8; 3],
}

// SAFETY: #[repr(C)], 4-byte fields and an explicit pad after the bool; kinds and bools
// are only ever written by other vertices.
unsafe impl simt::DeviceCopy for Vertex {}

impl Vertex {
    /// A point light's vertex: a light with no surface (delta in position).
    pub fn is_point_light(&self) -> bool {
        self.kind == VertexKind::Light && self.n == Vec3::ZERO
    }

    #[allow(clippy::too_many_arguments)]
    /// A vertex from its parts.
    pub fn new(kind: VertexKind, p: Vec3, n: Vec3, tri: u32, beta: Vec3, delta: bool, le: Vec3) -> Vertex {
        Vertex { kind, p, n, tri, beta, le, delta, _pad: [0; 3] }
    }
}

impl Default for Vertex {
    fn default() -> Self {
        Vertex::new(VertexKind::Camera, Vec3::ZERO, Vec3::ZERO, u32::MAX, Vec3::ZERO, false, Vec3::ZERO)
    }
}

/// Longest full path (light and camera vertices together) the bidirectional
/// integrators handle: `max_depth + 2` vertices.
pub const MAX_PATH: usize = crate::limits::MAX_PATH_VERTICES;

/// A full path on the stack, so kernels can build one without allocating.
pub type VertexList = StackList<Vertex, MAX_PATH>;

/// Up to `N` values on the stack. Slots past `len` are never read, so a new list costs
/// nothing (no fill of its `N` slots).
#[derive(Clone, Copy)]
pub struct StackList<T: Copy, const N: usize> {
    buf: [std::mem::MaybeUninit<T>; N],
    len: usize,
}

impl<T: Copy, const N: usize> Default for StackList<T, N> {
    fn default() -> Self {
        StackList { buf: [const { std::mem::MaybeUninit::uninit() }; N], len: 0 }
    }
}

impl<T: Copy, const N: usize> StackList<T, N> {
    /// Empties the list.
    pub fn clear(&mut self) {
        self.len = 0;
    }
    /// Appends a value (the list holds `N`).
    pub fn push(&mut self, v: T) {
        self.buf[self.len] = std::mem::MaybeUninit::new(v);
        self.len += 1;
    }
    /// Appends values.
    pub fn extend<'a>(&mut self, vs: impl IntoIterator<Item = &'a T>)
    where
        T: 'a,
    {
        for v in vs {
            self.push(*v);
        }
    }
}

impl<T: Copy, const N: usize> std::ops::Deref for StackList<T, N> {
    type Target = [T];
    fn deref(&self) -> &[T] {
        // SAFETY: the first `len` slots were written by `push`.
        unsafe { std::slice::from_raw_parts(self.buf.as_ptr() as *const T, self.len) }
    }
}

impl<T: Copy, const N: usize> std::ops::DerefMut for StackList<T, N> {
    fn deref_mut(&mut self) -> &mut [T] {
        // SAFETY: as for `deref`.
        unsafe { std::slice::from_raw_parts_mut(self.buf.as_mut_ptr() as *mut T, self.len) }
    }
}

/// Pinhole camera importance toward direction `w` (unit): `(We, pdf of the direction,
/// film position in pixels)`, or `None` outside the image grown by `margin` pixels on
/// every side (the reach of the pixel filter: [`crate::filter::Filter::margin`]). `We`
/// and the pdf are normalised over the image itself, as the camera samples it.
#[inline]
#[track_caller]
pub fn camera_importance(cam: &Camera, proj: &Projection, w: Vec3, margin: f32) -> Option<(f32, f32, Vec2)> {
    let _inlined = crate::cost::scope();
    declare!(DOT + BRANCH);
    let cos = w.dot(cam.forward);
    if cos <= 0.0 {
        return None;
    }
    // The projection onto the film and its bounds test, the two densities; the
    // half-angle's tangent comes worked out once per render (`proj`), as the GPU twin
    // reads it from the scene's constants, and the twin's one division for the aspect
    // ratio is counted here.
    declare!(5 * DIV + V3_DIV + 2 * DOT + 4 * BRANCH + 22);
    let Projection { tan_half, aspect, width, height } = *proj;
    let p = w / cos;
    let (sx, sy) = (p.dot(cam.right) / (tan_half * aspect), p.dot(cam.up) / tan_half);
    let film = Vec2::new((sx + 1.0) * 0.5 * width as f32, (1.0 - sy) * 0.5 * height as f32);
    let inside = |v: f32, n: u32| v >= -margin && v <= n as f32 + margin;
    if !(inside(film.x, width) && inside(film.y, height)) {
        return None;
    }
    let area = 4.0 * tan_half * tan_half * aspect;
    let cos2 = cos * cos;
    Some((1.0 / (area * cos2 * cos2), 1.0 / (area * cos2 * cos), film))
}

/// `|cos|` between a vertex's normal and `w` (1 for point lights).
#[inline]
#[track_caller]
pub(crate) fn cos_at(v: &Vertex, w: Vec3) -> f32 {
    let _inlined = crate::cost::scope();
    declare!(2 * BRANCH + DOT + 1);
    match v.kind {
        VertexKind::Light if v.n == Vec3::ZERO => 1.0,
        _ => v.n.dot(w).abs(),
    }
}

pub(crate) fn light_vertex(ls: &LightSample) -> Vertex {
    let tri = ls.tri;
    Vertex::new(VertexKind::Light, ls.position, ls.normal, tri, Vec3::splat(1.0 / ls.pdf), ls.is_delta, ls.emitted)
}

/// What one vertex scatters from `wo_point` toward `wi_point` (emission for a light).
/// (One copy per call site for `simt`'s model, as nvcc inlines it at each.)
#[inline]
#[track_caller]
pub(crate) fn vertex_f(ctx: &Context, v: &Vertex, prev: Option<&Vertex>, toward: Vec3, mode: TransportMode) -> Vec3 {
    let _inlined = crate::cost::scope();
    vertex_f_inlined(ctx, v, prev, toward, mode)
}

fn vertex_f_inlined(ctx: &Context, v: &Vertex, prev: Option<&Vertex>, toward: Vec3, mode: TransportMode) -> Vec3 {
    declare!(V3 + NORMALIZE + 2 * BRANCH);
    let w = (toward - v.p).normalize();
    match v.kind {
        VertexKind::Light => {
            declare!(2 * BRANCH + DOT);
            if v.n == Vec3::ZERO || v.n.dot(w) > 0.0 { v.le } else { Vec3::ZERO }
        }
        VertexKind::Surface => {
            declare!(BRANCH);
            let Some(prev) = prev else { return Vec3::ZERO };
            declare!(V3 + NORMALIZE + 3 * BRANCH);
            let wo = (prev.p - v.p).normalize();
            let material = ctx.scene.bsdf_facing(v.tri, wo.dot(v.n));
            let (wo, wi) = material.local_pair(v.n, wo, w);
            material.f(wo, wi, mode)
        }
        VertexKind::Camera => Vec3::ZERO,
    }
}

/// A shadow ray between two vertices (offset off both surfaces).
#[inline]
#[track_caller]
pub(crate) fn shadow_ray(a: &Vertex, b: &Vertex) -> Ray {
    let _inlined = crate::cost::scope();
    // Both ends offset off their surfaces (side tests, the offset's scaled nudges), and
    // the segment.
    declare!(2 * (3 * BRANCH + V3 + DOT + 15) + V3 + 10);
    let off = |v: &Vertex, toward: Vec3| {
        if v.kind == VertexKind::Camera || v.n == Vec3::ZERO {
            v.p
        } else {
            let n = if v.n.dot(toward - v.p) > 0.0 { v.n } else { -v.n };
            offset_ray_origin(v.p, n)
        }
    };
    let (pa, pb) = (off(a, b.p), off(b, a.p));
    Ray::segment(pa, pb - pa, 1.0 - 1e-4)
}

#[inline]
#[track_caller]
pub(crate) fn connectible(ctx: &Context, v: &Vertex) -> bool {
    let _inlined = crate::cost::scope();
    declare!(3 * BRANCH);
    v.kind != VertexKind::Surface || !ctx.scene.material(v.tri).is_delta()
}

/// A contribution waiting for its shadow ray: value, and where it goes (`None`: this
/// sample's pixel; `Some(p)`: a splat on pixel `p`).
pub(crate) type Pending = (Option<Ray>, Vec3, Option<Vec2>);

/// The t = 1 strategy for light vertex `s - 1`: its contribution to the pixel it projects on.
///
/// A point light's own vertex (s = 1) is never connected: the pinhole camera and the
/// light are both points, so that path has no area to integrate over (its value would
/// be a Dirac spike on one pixel, growing with the resolution), and no other strategy
/// can produce it. Point lights are invisible to the camera, as in the path tracer,
/// pbrt and Mitsuba.
pub(crate) fn connect_to_camera(
    ctx: &Context,
    light: &[Vertex],
    s: usize,
    cam_v: &Vertex,
) -> Option<(Vec3, Vec2, Ray)> {
    let v = &light[s - 1];
    if !connectible(ctx, v) || (s == 1 && v.is_point_light()) {
        return None;
    }
    let d = v.p - cam_v.p;
    let d2 = d.length_squared();
    let w = d / d2.sqrt();
    let (we, _, film) = camera_importance(&ctx.scene.camera, &ctx.projection, w, ctx.opts.filter.margin())?;
    let cos_cam = w.dot(cam_v.n);
    let prev = if s >= 2 { light.get(s - 2) } else { None };
    let f = vertex_f(ctx, v, prev, cam_v.p, TransportMode::Importance);
    let l = v.beta * f * cos_at(v, -w) * we * cos_cam / d2;
    (l.max_element() > 0.0).then(|| (l, film, shadow_ray(v, cam_v)))
}

/// The camera vertex at the sample's eye point.
pub(crate) fn camera_vertex(cam: &Camera) -> Vertex {
    Vertex::new(VertexKind::Camera, cam.position, cam.forward, u32::MAX, Vec3::ONE, false, Vec3::ZERO)
}

/// The full path of strategy (s, t): light vertices `0..s`, then camera vertices
/// `t-1..=0`, with the connection vertices marked non-delta (they are evaluated by
/// their continuous part).
#[inline]
#[track_caller]
pub(crate) fn full_path(light: &[Vertex], cam: &[Vertex], s: usize, t: usize, out: &mut VertexList) {
    let _inlined = crate::cost::scope();
    declare!((s + t) as u32 * VERTEX_COPY + 2 * BRANCH);
    out.clear();
    out.extend(&light[..s]);
    out.extend(cam[..t].iter().rev());
    if s > 0 {
        out[s - 1].delta = out[s - 1].is_point_light();
    }
    if t > 0 {
        out[s].delta = false;
    }
}

/// Strategy s = 0 at camera vertex `t - 1`: the camera path reached an emitter.
/// Returns the unweighted contribution and the full path (in `path`).
#[inline]
#[track_caller]
pub(crate) fn strategy_emitter(cam: &[Vertex], t: usize, light: &[Vertex], path: &mut VertexList) -> Option<Vec3> {
    let _inlined = crate::cost::scope();
    declare!(2 + 2 * BRANCH + V3 + DOT);
    let v = cam[t - 1];
    if v.le.max_element() <= 0.0 || v.n.dot(cam[t - 2].p - v.p) <= 0.0 {
        return None;
    }
    declare!(VERTEX_COPY + V3);
    full_path(light, cam, 0, t, path);
    path[0] = Vertex { kind: VertexKind::Light, ..path[0] };
    Some(v.beta * v.le)
}

/// Uniform numbers [`strategy_light_sample`] draws from the stream, at a connectible
/// camera vertex (none elsewhere): the light's choice and a point on it.
pub(crate) const LIGHT_SAMPLE_DRAWS: usize = 3;

/// Strategy s = 1 at camera vertex `t - 1`: a fresh light sample (next-event
/// estimation), drawing [`LIGHT_SAMPLE_DRAWS`] numbers. Returns the unweighted
/// contribution and its shadow ray; the full path is left in `path`.
#[inline]
#[track_caller]
pub(crate) fn strategy_light_sample(
    ctx: &Context,
    cam: &[Vertex],
    t: usize,
    rng: &mut Rng,
    path: &mut VertexList,
) -> Option<(Vec3, Ray)> {
    let _inlined = crate::cost::scope();
    let c = &cam[t - 1];
    if !connectible(ctx, c) {
        return None;
    }
    let ls = ctx.lights.sample(ctx.scene, rng.uniform(), rng.uniform2())?;
    declare!(DIV + 4 + V3 + DOT + BRANCH);
    let lv = light_vertex(&ls);
    let d = lv.p - c.p;
    let d2 = d.length_squared();
    if d2 == 0.0 {
        return None;
    }
    declare!(SQRT + V3_DIV + 2 + DIV + 4 * V3 + 2 + BRANCH);
    let wdir = d / d2.sqrt();
    let le = vertex_f(ctx, &lv, None, c.p, TransportMode::Importance);
    let f = vertex_f(ctx, c, cam.get(t - 2), lv.p, TransportMode::Radiance);
    let g = cos_at(c, wdir) * cos_at(&lv, wdir) / d2;
    let l = c.beta * f * le * lv.beta * g;
    if l.max_element() <= 0.0 {
        return None;
    }
    declare!((t + 1) as u32 * VERTEX_COPY);
    path.clear();
    path.push(lv);
    path.extend(cam[..t].iter().rev());
    path[1].delta = false;
    Some((l, shadow_ray(c, &lv)))
}

/// A general connection: light vertex `s - 1` of `light` with camera vertex `t - 1`.
/// Returns the unweighted contribution and its shadow ray; the full path is left in `path`.
#[inline]
#[track_caller]
pub(crate) fn strategy_connect(
    ctx: &Context,
    light: &[Vertex],
    s: usize,
    cam: &[Vertex],
    t: usize,
    path: &mut VertexList,
) -> Option<(Vec3, Ray)> {
    let _inlined = crate::cost::scope();
    let (lv, c) = (&light[s - 1], &cam[t - 1]);
    let l = connect_contribution(ctx, lv, if s >= 2 { light.get(s - 2) } else { None }, cam, t)?;
    full_path(light, cam, s, t, path);
    Some((l, shadow_ray(lv, c)))
}

/// The unweighted contribution of [`strategy_connect`], from the light vertex `lv`, the
/// one before it on its subpath (`None` for the light's own vertex) and the camera
/// subpath: what a resampled connection weighs its candidates by, without loading the
/// rest of their subpaths or building the path.
///
/// (One copy per call site and entry for `simt`'s model.)
#[inline]
#[track_caller]
pub(crate) fn connect_contribution(
    ctx: &Context,
    lv: &Vertex,
    lv_prev: Option<&Vertex>,
    cam: &[Vertex],
    t: usize,
) -> Option<Vec3> {
    let _inlined = crate::cost::scope();
    connect_contribution_inlined(ctx, lv, lv_prev, cam, t)
}

fn connect_contribution_inlined(
    ctx: &Context,
    lv: &Vertex,
    lv_prev: Option<&Vertex>,
    cam: &[Vertex],
    t: usize,
) -> Option<Vec3> {
    let c = &cam[t - 1];
    if !connectible(ctx, lv) || !connectible(ctx, c) {
        return None;
    }
    declare!(V3 + DOT + BRANCH);
    let d = lv.p - c.p;
    let d2 = d.length_squared();
    if d2 == 0.0 {
        return None;
    }
    declare!(SQRT + V3_DIV + 2 + DIV + 4 * V3 + 2 + BRANCH);
    let wdir = d / d2.sqrt();
    let fl = vertex_f(ctx, lv, lv_prev, c.p, TransportMode::Importance);
    let fc = vertex_f(ctx, c, cam.get(t - 2), lv.p, TransportMode::Radiance);
    let g = cos_at(lv, wdir) * cos_at(c, wdir) / d2;
    let l = lv.beta * fl * g * fc * c.beta;
    (l.max_element() > 0.0).then_some(l)
}
