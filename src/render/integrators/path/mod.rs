//! Path tracing with next-event estimation and multiple importance sampling (power
//! heuristic) between light sampling and BSDF sampling, run as wavefronts: every
//! bounce casts a wavefront's live paths through the caster as one batch, shades them,
//! casts the batch of their shadow rays, and drops finished paths. A wavefront is a
//! chunk of the pass's pixels, or the whole pass for casters that want large batches
//! ([`CHUNK`]).

use crate::cast::CastStats;
use crate::film::Film;
use crate::geometry::{Hit, Ray};
use crate::render::compact::compact_into;
use crate::render::context::{Context, Passes};
use crate::sampling::Rng;
use glam::Vec3;
use lanes::Group;
use rayon::prelude::*;
use shade::shade;
use state::{Bounce, PathState, Shadow};

mod lanes;
mod shade;
mod state;
#[cfg(test)]
mod tests;

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

            let bounce = Bounce::new(depth, ctx.opts.max_depth, ctx.opts.rr_depth);
            self.shadows.resize(self.paths.len(), None);
            self.paths
                .par_chunks_mut(SERIAL)
                .zip(self.hits.par_chunks(SERIAL))
                .zip(self.shadows.par_chunks_mut(SERIAL))
                .for_each(|((paths, hits), shadows)| shade_all(ctx, bounce, paths, hits, shadows, &mut Group::new()));

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

/// One bounce of a run of paths: the hits on Lambertian surfaces through the SIMD
/// lanes of `group`, sixteen at a time, the others one at a time. Each path's shadow
/// goes to its slot of `shadows`.
fn shade_all(
    ctx: &Context,
    bounce: Bounce,
    paths: &mut [PathState],
    hits: &[Hit],
    shadows: &mut [Shadow],
    group: &mut Group,
) {
    for (k, hit) in hits.iter().enumerate() {
        if let Some(albedo) = lanes::diffuse_albedo(ctx, bounce, hit) {
            group.push(ctx, bounce, k, &mut paths[k], hit, albedo);
            if group.is_full() {
                group.shade(bounce, paths, shadows);
            }
        } else {
            shadows[k] = shade(ctx, bounce, &mut paths[k], hit);
        }
    }
    group.shade(bounce, paths, shadows);
}
