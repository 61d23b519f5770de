//! Path tracing with next-event estimation and multiple importance sampling (power
//! heuristic) between light sampling and BSDF sampling, run as wavefronts: every
//! bounce casts a wavefront's live paths through the caster as one batch, shades them,
//! casts the batch of their shadow rays, and drops finished paths. A wavefront is a
//! chunk of the pass's pixels, or the whole pass for casters that want large batches
//! ([`CHUNK`]).

use crate::bsdf::TransportMode;
use crate::cast::CastStats;
use crate::film::Film;
use crate::geometry::{Hit, Ray, offset_ray_origin};
use crate::render::compact::compact_into;
use crate::render::context::{Context, Passes};
use crate::sampling::{Frame, Rng, power_heuristic};
use glam::Vec3;
use rayon::prelude::*;

#[derive(Clone, Copy, Debug)]
struct PathState {
    pixel: u32,
    rng: Rng,
    ray: Ray,
    throughput: Vec3,
    radiance: Vec3,
    /// Solid-angle pdf of the BSDF sample that made `ray` (for MIS on emitter hits).
    prev_pdf: f32,
    /// η² of the relative indices the path's refractions crossed (Russian roulette
    /// undoes the 1/η² that radiance took at each).
    eta2: f32,
    prev_delta: bool,
    alive: bool,
}

/// A path's light sample this bounce, waiting for its shadow ray: the ray and the
/// radiance it brings if unblocked.
type Shadow = Option<(Ray, Vec3)>;

/// Paths traced together from camera to end by one task, when the caster takes small
/// batches well (a stored structure traversed per ray or per packet): each chunk's
/// buffers stay in its core's cache (at most 2,048 paths of 88 bytes), and
/// chunks need no barrier between bounces. A pass is cut into at least eight chunks per
/// thread where it can be (not below [`MIN_CHUNK`] paths), so that threads finish
/// together. The divide-and-conquer and GPU casters trace the pass as one wavefront,
/// since their work per call comes from the batch's size. Every path's stream comes
/// from its pixel and pass, so the image does not depend on the chunks. (Mitsuba box,
/// 2 threads, CPU s at 32 spp: 2.19 in chunks of 2,048, 2.24 of 512, 2.27 of 256, 2.5
/// as one wavefront.)
const CHUNK: usize = 2048;

/// The smallest chunk of paths one task traces.
const MIN_CHUNK: usize = 256;

/// Paths one task takes inside a wavefront: a chunk runs as one task.
const SERIAL: usize = 4096;

/// The path tracer's buffers: one wavefront's per chunk.
pub struct PathTracer {
    /// Per pixel: its path's estimate this pass.
    estimates: Vec<Vec3>,
    /// Wavefront buffers kept between passes, one per chunk in flight.
    pool: std::sync::Mutex<Vec<Wavefront>>,
}

/// One wavefront's reusable buffers.
#[derive(Default)]
struct Wavefront {
    paths: Vec<PathState>,
    /// The live paths of the next bounce, compacted out of `paths`.
    spare: Vec<PathState>,
    /// Per path that ended this bounce: its pixel and estimate.
    finished: Vec<(u32, Vec3)>,
    rays: Vec<Ray>,
    hits: Vec<Hit>,
    /// Per live path: its light sample of this bounce (kept apart from the path state,
    /// which the compaction copies every bounce).
    shadows: Vec<Shadow>,
    shadow_rays: Vec<Ray>,
    shadow_owner: Vec<u32>,
    blocked: Vec<bool>,
}

impl PathTracer {
    /// A path tracer with buffers for the render's image size.
    pub(crate) fn new(ctx: &Context) -> Self {
        let n = (ctx.opts.width * ctx.opts.height) as usize;
        PathTracer { estimates: vec![Vec3::ZERO; n], pool: Default::default() }
    }

    /// Adds the passes of `span` to `film`, one at a time.
    pub(crate) fn render_passes(&mut self, ctx: &Context, span: Passes, film: &mut Film) -> CastStats {
        span.numbers().fold(CastStats::default(), |stats, pass| stats.merge(self.render_pass(ctx, pass, film)))
    }

    /// One sample per pixel, added to `film`. Returns the caster statistics of the pass.
    fn render_pass(&mut self, ctx: &Context, pass: u32, film: &mut Film) -> CastStats {
        let n = self.estimates.len();
        let chunk = if ctx.caster.casts_single_rays() {
            (n / (8 * rayon::current_num_threads())).clamp(MIN_CHUNK, CHUNK)
        } else {
            n.max(1)
        };
        let pool = &self.pool;
        let stats = self
            .estimates
            .par_chunks_mut(chunk)
            .enumerate()
            .map(|(k, estimates)| {
                let mut wf = pool.lock().unwrap().pop().unwrap_or_default();
                let stats = wf.trace(ctx, pass, (k * chunk) as u32, estimates);
                pool.lock().unwrap().push(wf);
                stats
            })
            .reduce(CastStats::default, CastStats::merge);
        film.add_pass(pass, &self.estimates);
        stats
    }
}

impl Wavefront {
    /// Traces the paths of pixels `first..first + estimates.len()` of pass `pass` to
    /// their ends, writing each pixel's estimate.
    fn trace(&mut self, ctx: &Context, pass: u32, first: u32, estimates: &mut [Vec3]) -> CastStats {
        let (cam, proj) = (&ctx.scene.camera, &ctx.projection);
        let seed = ctx.opts.seed;
        (first..first + estimates.len() as u32)
            .into_par_iter()
            .with_min_len(SERIAL)
            .map(|pixel| {
                let mut rng = Rng::for_sample(seed, pixel as u64, pass as u64);
                let (film_pos, weight) = ctx.camera_sample(pixel, pass);
                let ray = cam.ray(proj, film_pos, rng.uniform2());
                PathState {
                    pixel,
                    rng,
                    ray,
                    throughput: Vec3::splat(weight),
                    radiance: Vec3::ZERO,
                    prev_pdf: 0.0,
                    eta2: 1.0,
                    prev_delta: true,
                    alive: true,
                }
            })
            .collect_into_vec(&mut self.paths);
        estimates.fill(Vec3::ZERO);
        let mut stats = CastStats::default();

        for depth in 0..=ctx.opts.max_depth {
            if self.paths.is_empty() {
                break;
            }
            self.paths.par_iter().with_min_len(SERIAL).map(|p| p.ray).collect_into_vec(&mut self.rays);
            self.hits.resize(self.rays.len(), Hit::MISS);
            stats = stats.merge(ctx.caster.closest(&self.rays, &mut self.hits));

            self.paths
                .par_iter_mut()
                .zip(&self.hits)
                .with_min_len(SERIAL)
                .map(|(p, hit)| shade(ctx, depth, p, hit))
                .collect_into_vec(&mut self.shadows);

            // Shadow rays of this bounce, as one batch (in path order).
            compact_into(&self.shadows, &mut self.shadow_owner, |s| s.is_some(), |i, _| i as u32);
            let shadows = &self.shadows;
            let shadow_ray = |&i: &u32| shadows[i as usize].map_or(Ray::new(Vec3::ZERO, Vec3::Z), |s| s.0);
            self.shadow_owner.par_iter().with_min_len(SERIAL).map(shadow_ray).collect_into_vec(&mut self.shadow_rays);
            self.blocked.resize(self.shadow_rays.len(), false);
            stats = stats.merge(ctx.caster.occluded(&self.shadow_rays, &mut self.blocked));
            // What each unblocked shadow ray brings goes to its path.
            for (&i, &blocked) in self.shadow_owner.iter().zip(&self.blocked) {
                if let (false, Some((_, l))) = (blocked, self.shadows[i as usize]) {
                    self.paths[i as usize].radiance += l;
                }
            }

            // Finished paths leave their estimate; the live ones are compacted.
            compact_into(&self.paths, &mut self.finished, |p| !p.alive, |_, p| (p.pixel, p.radiance));
            for &(pixel, radiance) in &self.finished {
                estimates[(pixel - first) as usize] = radiance;
            }
            compact_into(&self.paths, &mut self.spare, |p| p.alive, |_, p| *p);
            std::mem::swap(&mut self.paths, &mut self.spare);
        }
        for p in &self.paths {
            estimates[(p.pixel - first) as usize] = p.radiance;
        }
        stats
    }
}

/// One bounce of one path: emission, light sample, BSDF sample. Returns the light
/// sample's shadow ray and what it brings, if any.
fn shade(ctx: &Context, depth: u32, p: &mut PathState, hit: &Hit) -> Shadow {
    if !hit.is_hit() {
        p.alive = false;
        return None;
    }
    let scene = ctx.scene;
    let [a, b, c] = scene.vertices(hit.prim);
    let pos = a * (1.0 - hit.u - hit.v) + b * hit.u + c * hit.v;
    let ng = ctx.normal(hit.prim);
    let wo = -p.ray.dir.normalize();
    if ng == Vec3::ZERO {
        p.alive = false;
        return None;
    }

    let le = scene.emission_of(hit.prim);
    let cos_emit = ng.dot(wo);
    if le.max_element() > 0.0 && cos_emit > 0.0 {
        let weight = if depth == 0 || p.prev_delta {
            1.0
        } else {
            let dist = hit.t * p.ray.dir.length();
            let pdf_light = ctx.lights.pdf_area(hit.prim) * dist * dist / cos_emit;
            power_heuristic(p.prev_pdf, pdf_light)
        };
        p.radiance += p.throughput * le * weight;
    }
    if depth >= ctx.opts.max_depth {
        p.alive = false;
        return None;
    }

    let frame = Frame::from_normal(ng);
    let wo_local = frame.to_local(wo);
    let material = scene.bsdf(hit.prim, wo_local);
    let mode = TransportMode::Radiance;

    // Next-event estimation.
    let mut shadow = None;
    if !material.is_delta()
        && let Some(ls) = ctx.lights.sample(scene, p.rng.uniform(), p.rng.uniform2())
    {
        let to_light = ls.position - pos;
        let dist2 = to_light.length_squared();
        let wi = to_light / dist2.sqrt();
        let wi_local = frame.to_local(wi);
        let f = material.f(wo_local, wi_local, mode);
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
        let contribution = p.throughput * contribution;
        if contribution.max_element() > 0.0 && contribution.is_finite() {
            let origin = offset_ray_origin(pos, if wi.dot(ng) > 0.0 { ng } else { -ng });
            let target = if ls.is_delta { ls.position } else { offset_ray_origin(ls.position, ls.normal) };
            shadow = Some((Ray::segment(origin, target - origin, 1.0 - 1e-4), contribution));
        }
    }

    // Continue the path.
    let Some(s) = material.sample_f(wo_local, p.rng.uniform(), p.rng.uniform2(), mode) else {
        p.alive = false;
        return shadow;
    };
    let wi = frame.to_world(s.wi);
    p.throughput *= s.weight;
    p.prev_pdf = s.pdf;
    p.prev_delta = s.delta;
    let eta = material.eta(wo_local, s.wi);
    p.eta2 *= eta * eta;
    // Russian roulette once the path has made `rr_depth` bounces (this one included).
    if depth + 1 >= ctx.opts.rr_depth {
        let q = (p.throughput.max_element() * p.eta2).min(0.95);
        if p.rng.uniform() >= q {
            p.alive = false;
            return shadow;
        }
        p.throughput /= q;
    }
    if !p.throughput.is_finite() || p.throughput.max_element() <= 0.0 {
        p.alive = false;
        return shadow;
    }
    p.ray = Ray::new(offset_ray_origin(pos, if wi.dot(ng) > 0.0 { ng } else { -ng }), wi);
    shadow
}

#[cfg(test)]
mod tests {
    #[test]
    fn a_path_state_is_88_bytes() {
        // The figure the chunk size's comment and docs/mitsuba.md give.
        assert_eq!(std::mem::size_of::<super::PathState>(), 88);
    }
}
