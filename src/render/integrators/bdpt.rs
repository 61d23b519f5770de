//! Bidirectional path tracing (Veach 1997), run as wavefronts.
//!
//! It takes the samples of one or more passes (`walk::Passes`: a small image's passes
//! share waves, so the caster still gets large batches) in waves of up to 65,536
//! samples (fewer with the casters that take rays one at a time: `Context::wave`).
//! Per wave, the host loop reads like the algorithm:
//!
//! 1. *camera subpaths* (BDPT): every sample's camera subpath, one batch of rays per bounce;
//! 2. *light subpaths*: every sample's light subpath, the same way;
//! 3. *connect*: every sample evaluates its strategies in parallel, leaving pending
//!    contributions with their shadow rays;
//! 4. *resolve*: all shadow rays of the wave as one batch; visible contributions go to
//!    the sample's pixel or, for camera connections (t = 1), onto the film as splats.
//!
//! Light tracing (`integrators/light.rs`) is the t = 1 strategies alone, unweighted. The
//! strategies and their weights live in [`crate::render::bidir`], the wavefront walks in
//! `render/walk.rs`.

use crate::cast::CastStats;
use crate::film::Film;
use crate::render::bidir::{
    Pending, Vertex, VertexList, camera_vertex, connect_to_camera, full_path, strategy_connect, strategy_emitter,
    strategy_light_sample,
};
use crate::render::context::{Context, Passes};
use crate::render::mis::{Known, mis_weight, subpath_densities};
use crate::render::walk::{
    Walker, WaveBuffers, extend_together, flush_wave, resolve_wave, start_camera_wave, start_light_wave,
};
use crate::sampling::Rng;

/// Bidirectional path tracing, one camera and one light subpath per pixel sample.
#[derive(Default)]
pub struct Bdpt {
    pub(super) buffers: WaveBuffers,
}

impl Bdpt {
    /// Renders the passes of `span` (one camera and one light subpath per pixel and
    /// pass, every connection weighted by MIS), in waves that may hold several passes.
    pub(crate) fn render_passes(&mut self, ctx: &Context, span: Passes, film: &mut Film) -> CastStats {
        let max_vertices = ctx.opts.max_depth as usize + 1;
        let b = &mut self.buffers;
        let mut stats = CastStats::default();
        let mut estimates = Vec::with_capacity(span.per_pass as usize);
        for wave in span.waves(b.wave(ctx)) {
            // Camera and light subpaths, extended together: one batch of rays per bounce.
            let n = wave.len();
            let camera = start_camera_wave(ctx, span, wave.clone(), &mut b.camera, &mut b.camera_walkers);
            // A sample's light stream derives from its camera stream's key (not its state).
            let keys: &[Walker] = camera.walkers;
            let light =
                start_light_wave(ctx, n, |i| keys[i].rng.derive(1), max_vertices, &mut b.light, &mut b.light_walkers);
            stats = stats.merge(extend_together(ctx, &mut [camera, light]));
            let walkers = &b.camera_walkers;
            let (camera, light) = (&b.camera, &b.light);
            b.pending.fill(camera.len(), |i, out, path: &mut VertexList| {
                let mut rng = walkers[i].rng;
                connect(ctx, camera.get(i), light.get(i), &mut rng, path, out)
            });
            let (resolved, shadow) = resolve_wave(ctx, &mut b.pending);
            stats = stats.merge(shadow);
            flush_wave(film, span, wave, resolved, Some(&mut estimates), |_, _| {});
        }
        stats
    }
}

/// Every strategy of one sample's camera and light subpaths, weighted, waiting for
/// their shadow rays, appended to `pending`. `rng` is the sample's stream after its
/// camera subpath (light samples for s = 1 draw from it).
fn connect(
    ctx: &Context,
    cam: &[Vertex],
    light: &[Vertex],
    rng: &mut Rng,
    path: &mut VertexList,
    pending: &mut Vec<Pending>,
) {
    let max_depth = ctx.opts.max_depth as usize;
    let cam_v = camera_vertex(&ctx.scene.camera);
    // The subpaths' own densities, evaluated once for all the strategies that join them.
    let (light_d, cam_d) = (subpath_densities(ctx, light), subpath_densities(ctx, cam));
    let known = Known { light: &light_d, camera: &cam_d };
    // A strategy image keeps one (s, t), with or without its MIS weight.
    let weight =
        |path: &[Vertex], s: usize, t: usize| ctx.opts.strategy_weight(s, t, || mis_weight(ctx, path, s, known));
    for t in 1..=cam.len() {
        for s in 0..=light.len() {
            let depth = (s + t) as isize - 2;
            if depth < 0 || depth as usize > max_depth || (s == 0 && t < 2) {
                continue;
            }
            if !ctx.opts.keeps(s, t) {
                continue;
            }
            match (s, t) {
                (0, _) => {
                    if let Some(l) = strategy_emitter(cam, t, light, path) {
                        pending.push((None, l * weight(path, 0, t).unwrap_or(0.0), None));
                    }
                }
                (_, 1) => {
                    if let Some((l, px, ray)) = connect_to_camera(ctx, light, s, &cam_v) {
                        full_path(light, cam, s, 1, path);
                        pending.push((Some(ray), l * weight(path, s, 1).unwrap_or(0.0), Some(px)));
                    }
                }
                (1, _) => {
                    if let Some((l, ray)) = strategy_light_sample(ctx, cam, t, rng, path) {
                        pending.push((Some(ray), l * weight(path, 1, t).unwrap_or(0.0), None));
                    }
                }
                _ => {
                    if let Some((l, ray)) = strategy_connect(ctx, light, s, cam, t, path) {
                        pending.push((Some(ray), l * weight(path, s, t).unwrap_or(0.0), None));
                    }
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::render::context::TestSetup;
    use crate::render::{IntegratorKind, LightTracer, LvcBdpt, LvcParams, RenderOptions};
    use crate::scene::cornell_box;

    /// Each sample draws from its own streams, so rendering passes one at a time, or
    /// several together in waves of any size (one wave for all three passes, waves of
    /// 1,000 that straddle the passes' ends, waves of 7), leaves the film bit for bit
    /// the same: its sums, splats and squared sums. The squared sums are also checked
    /// against each pass's own estimate (rendered alone), so a splat counted in the
    /// wrong pass's variance is caught even when every grouping makes the same error.
    #[test]
    fn grouping_passes_and_the_wave_size_do_not_change_the_image() {
        let scene = cornell_box();
        let (size, passes) = (32u32, 3u32);
        for integrator in [IntegratorKind::Light, IntegratorKind::Bdpt, IntegratorKind::Lvc] {
            let opts =
                RenderOptions { width: size, height: size, integrator, seed: 5, max_depth: 5, ..Default::default() };
            check_grouping(&TestSetup::new(&scene).ctx(&opts), integrator, size, passes);
        }
    }

    /// The body of the test above for one integrator.
    fn check_grouping(ctx: &Context, integrator: IntegratorKind, size: u32, passes: u32) {
        let per_pass = size * size;
        let render = |spans: &[Passes], wave: u32| {
            let mut film = Film::new(size, size).unwrap();
            let buffers = WaveBuffers { wave: Some(wave), ..Default::default() };
            let mut light = LightTracer { buffers };
            let mut bdpt = Bdpt { buffers: WaveBuffers { wave: Some(wave), ..Default::default() } };
            let mut lvc = LvcBdpt {
                buffers: WaveBuffers { wave: Some(wave), ..Default::default() },
                ..LvcBdpt::new(LvcParams::default())
            };
            for &span in spans {
                match integrator {
                    IntegratorKind::Light => light.render_passes(ctx, span, &mut film),
                    IntegratorKind::Bdpt => bdpt.render_passes(ctx, span, &mut film),
                    _ => lvc.render_passes(ctx, span, &mut film),
                };
            }
            let bits = |v: &[glam::Vec3]| v.iter().flat_map(|c| c.to_array().map(f32::to_bits)).collect::<Vec<_>>();
            (film.passes, bits(&film.sum), bits(&film.splat), bits(&film.sum_sq))
        };
        let one_by_one: Vec<Passes> = (0..passes).map(|first| Passes { first, count: 1, per_pass }).collect();
        let reference = render(&one_by_one, per_pass);
        assert_eq!(reference.0, passes);
        assert!(reference.1.iter().chain(&reference.2).any(|&b| f32::from_bits(b) > 0.0), "{integrator:?}: black");
        let together = [Passes { first: 0, count: passes, per_pass }];
        for wave in [per_pass * passes, 1000, 7] {
            assert!(render(&together, wave) == reference, "{integrator:?}: grouped, waves of {wave}: another film");
        }
        // Each pass's own estimate (its camera estimate plus its splats) is what the
        // squared sums add up: rendered alone on a fresh film, pass p's estimate is
        // that film's sum plus its splats, bit for bit.
        let mut expected = vec![0u32; reference.3.len()];
        for p in &one_by_one {
            let (_, sum, splat, _) = render(std::slice::from_ref(p), per_pass);
            for ((q, s), l) in expected.iter_mut().zip(sum).zip(splat) {
                let x = f32::from_bits(s) + f32::from_bits(l);
                *q = (f32::from_bits(*q) + x * x).to_bits();
            }
        }
        assert!(expected == reference.3, "{integrator:?}: squared sums are not the passes' own estimates");
    }

    /// Russian roulette weighs a light subpath's throughput against its start, so the
    /// same streams give light subpaths of the same lengths with the lights 1,000 times
    /// brighter; with the emitted power in the throughput it would keep every bright
    /// subpath alive to the depth limit.
    #[test]
    fn light_subpaths_survive_roulette_alike_whatever_the_lights_brightness() {
        use crate::render::walk::{Subpaths, extend_together, start_light_wave};
        const N: usize = 4096;
        let max_vertices = 14;
        let lengths = |brightness: f32| {
            let mut scene = cornell_box();
            scene.emission.iter_mut().for_each(|e| *e *= brightness);
            let opts = RenderOptions { width: 64, height: 64, max_depth: 12, ..Default::default() };
            let setup = TestSetup::new(&scene);
            let ctx = &setup.ctx(&opts);
            let (mut subpaths, mut walkers) = (Subpaths::default(), Vec::new());
            let walk = start_light_wave(
                ctx,
                N,
                |i| Rng::for_sample(9, i as u64, 0),
                max_vertices,
                &mut subpaths,
                &mut walkers,
            );
            extend_together(ctx, &mut [walk]);
            (0..N).map(|i| subpaths.get(i).len()).collect::<Vec<_>>()
        };
        let (dim, bright) = (lengths(1.0), lengths(1000.0));
        let differ = dim.iter().zip(&bright).filter(|(a, b)| a != b).count();
        assert!(differ <= N / 1000, "{differ} of {N} light subpaths end elsewhere with brighter lights");
        // The comparison covers the roulette only if many subpaths reach it (more than
        // three bounces: five vertices or more).
        let reached = dim.iter().filter(|&&l| l > 4).count();
        assert!(reached > N / 10, "only {reached} of {N} subpaths reached the roulette");
    }
}
