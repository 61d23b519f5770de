//! One bounce of one path, read from the scene and shaded one path at a time: the
//! emission the path meets, a light sample for its shadow ray (next-event estimation,
//! MIS by the power heuristic against BSDF sampling), and the BSDF sample that
//! continues it, with Russian roulette.
//!
//! The three steps ([`with_emission`], [`next_event`], [`continue_path`]) take plain
//! values and are always inlined: [`shade`] calls them for every material, and
//! `lanes.rs` calls them for sixteen diffuse hits at once, in a loop the compiler runs
//! on SIMD lanes. Either way a lane computes the same operations in the same order, so
//! both give the same bits.

use super::state::{Bounce, PathState, Shadow};
use crate::bsdf::{BsdfSample, TransportMode};
use crate::geometry::{Hit, Ray, barycentric_point, offset_ray_origin};
use crate::lights::LightSample;
use crate::render::context::Context;
use crate::sampling::{Frame, power_heuristic};
use crate::scene::Material;
use glam::Vec3;

/// One bounce of one path: emission, light sample, BSDF sample. Returns the light
/// sample's shadow ray and what it brings, if any.
pub(super) fn shade(ctx: &Context, bounce: Bounce, p: &mut PathState, hit: &Hit) -> Shadow {
    if !hit.is_hit() {
        p.alive = false;
        return None;
    }
    let scene = ctx.scene;
    let ng = ctx.normal(hit.prim);
    if ng == Vec3::ZERO {
        p.alive = false;
        return None;
    }
    let pos = barycentric_point(scene.vertices(hit.prim), hit.u, hit.v);
    let wo = -p.ray.dir.normalize();
    let le = scene.emission_of(hit.prim);
    p.radiance = with_emission(p, bounce, le, ng, wo, hit.t, emitter_density(ctx, hit.prim, le));
    if bounce.last {
        p.alive = false;
        return None;
    }

    let frame = Frame::from_normal(ng);
    let wo_local = frame.to_local(wo);
    let material = scene.bsdf(hit.prim, wo_local);
    let light = if material.is_delta() { None } else { ctx.lights.sample(scene, p.rng.uniform(), p.rng.uniform2()) };
    let shadow = light.map(|ls| next_event(material, &frame, wo_local, pos, ng, p.throughput, &ls)).filter(brings);
    let sample = material.sample_f(wo_local, p.rng.uniform(), p.rng.uniform2(), TransportMode::Radiance);
    // Drawn whether or not the path survives to use it: a path that ends here never
    // draws again, so the numbers of those that go on are the same.
    let u_rr = if bounce.roulette { p.rng.uniform() } else { 0.0 };
    continue_path(p, sample.map(|s| (s, material.eta(wo_local, s.wi))), &frame, pos, ng, bounce, u_rr);
    shadow
}

/// Light sampling's area density at triangle `prim`, which emits `le`: read only where
/// the triangle emits (zero elsewhere, where [`with_emission`] does not use it).
#[inline(always)]
pub(super) fn emitter_density(ctx: &Context, prim: u32, le: Vec3) -> f32 {
    if le.max_element() > 0.0 { ctx.lights.pdf_area(prim) } else { 0.0 }
}

/// The path's radiance after the hit's emission `le` (from a triangle of unit normal
/// `ng`, met from direction `wo` at distance `t` along the path's ray): weighed against
/// light sampling (whose area density there is `pdf_area`) unless the path came
/// straight from the camera or by a delta lobe.
#[inline(always)]
pub(super) fn with_emission(
    p: &PathState,
    bounce: Bounce,
    le: Vec3,
    ng: Vec3,
    wo: Vec3,
    t: f32,
    pdf_area: f32,
) -> Vec3 {
    let cos_emit = ng.dot(wo);
    if le.max_element() > 0.0 && cos_emit > 0.0 {
        let weight = if bounce.first || p.prev_delta {
            1.0
        } else {
            let dist = t * p.ray.dir.length();
            let pdf_light = pdf_area * dist * dist / cos_emit;
            power_heuristic(p.prev_pdf, pdf_light)
        };
        p.radiance + p.throughput * le * weight
    } else {
        p.radiance
    }
}

/// Next-event estimation at `pos` toward the light sample `ls`: the shadow ray and what
/// it brings to a path of this throughput (a shadow only where that [`brings`]
/// something; the ray is made either way, so that a lane computes it without a branch).
#[inline(always)]
pub(super) fn next_event(
    material: &Material,
    frame: &Frame,
    wo_local: Vec3,
    pos: Vec3,
    ng: Vec3,
    throughput: Vec3,
    ls: &LightSample,
) -> (Ray, Vec3) {
    let to_light = ls.position - pos;
    let dist2 = to_light.length_squared();
    let wi = to_light / dist2.sqrt();
    let wi_local = frame.to_local(wi);
    let f = material.f(wo_local, wi_local, TransportMode::Radiance);
    let cos_surf = wi_local.z.abs();
    let contribution = if f == Vec3::ZERO || dist2 == 0.0 {
        Vec3::ZERO
    } else if ls.is_delta {
        f * cos_surf * ls.emitted / (dist2 * ls.pdf)
    } else {
        let cos_light = ls.normal.dot(-wi);
        if cos_light <= 0.0 {
            Vec3::ZERO
        } else {
            let pdf_light = ls.pdf * dist2 / cos_light;
            let weight = power_heuristic(pdf_light, material.pdf(wo_local, wi_local));
            f * cos_surf * ls.emitted * weight / pdf_light
        }
    };
    let origin = leave(pos, ng, wi);
    let target = if ls.is_delta { ls.position } else { offset_ray_origin(ls.position, ls.normal) };
    (Ray::segment(origin, target - origin, 1.0 - 1e-4), throughput * contribution)
}

/// Whether a shadow ray's contribution is worth casting: positive and finite.
#[inline(always)]
pub(super) fn brings((_, l): &(Ray, Vec3)) -> bool {
    l.max_element() > 0.0 && l.is_finite()
}

/// Continues the path along the BSDF sample (with the relative index it crosses), or
/// ends it: no sample, Russian roulette (`u_rr`, once it applies), or a throughput that
/// is no longer finite and positive.
#[inline(always)]
pub(super) fn continue_path(
    p: &mut PathState,
    sample: Option<(BsdfSample, f32)>,
    frame: &Frame,
    pos: Vec3,
    ng: Vec3,
    bounce: Bounce,
    u_rr: f32,
) {
    let Some((s, eta)) = sample else {
        p.alive = false;
        return;
    };
    let wi = frame.to_world(s.wi);
    p.throughput *= s.weight;
    p.prev_pdf = s.pdf;
    p.prev_delta = s.delta;
    p.eta2 *= eta * eta;
    // Russian roulette once the path has made `rr_depth` bounces (this one included).
    if bounce.roulette {
        let q = (p.throughput.max_element() * p.eta2).min(0.95);
        if u_rr >= q {
            p.alive = false;
            return;
        }
        p.throughput /= q;
    }
    if !p.throughput.is_finite() || p.throughput.max_element() <= 0.0 {
        p.alive = false;
        return;
    }
    p.ray = Ray::new(leave(pos, ng, wi), wi);
}

/// The origin of a ray leaving `pos` toward `w`: moved off the surface on `w`'s side.
#[inline(always)]
fn leave(pos: Vec3, ng: Vec3, w: Vec3) -> Vec3 {
    offset_ray_origin(pos, if w.dot(ng) > 0.0 { ng } else { -ng })
}
