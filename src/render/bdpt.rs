//! Bidirectional path tracing (Veach 1997), run as wavefronts.
//!
//! It takes the pixels of a pass in waves of up to 65,536 samples (`walk::WAVE`).
//! Per wave, the host loop reads like the algorithm:
//!
//! 1. *camera subpaths* (BDPT): every sample's camera subpath, one batch of rays per bounce;
//! 2. *light subpaths*: every sample's light subpath, the same way;
//! 3. *connect*: every sample evaluates its strategies in parallel, leaving pending
//!    contributions with their shadow rays;
//! 4. *resolve*: all shadow rays of the wave as one batch; visible contributions go to
//!    the sample's pixel or, for camera connections (t = 1), onto the film as splats.
//!
//! Light tracing (`render/light.rs`) is the t = 1 strategies alone, unweighted. The
//! strategies and their weights live in [`super::bidir`], the wavefront walks in
//! `render/walk.rs`.

use super::Context;
use super::bidir::{
    Pending, Vertex, VertexList, camera_vertex, connect_to_camera, full_path, mis_weight, strategy_connect,
    strategy_emitter, strategy_light_sample,
};
use super::walk::{Walker, WaveBuffers, extend_together, resolve_wave, start_camera_wave, start_light_wave, waves};
use crate::cast::CastStats;
use crate::film::Film;
use crate::sampling::Rng;
use rayon::prelude::*;

/// Bidirectional path tracing, one camera and one light subpath per pixel sample.
#[derive(Default)]
pub struct Bdpt {
    buffers: WaveBuffers,
}

impl Bdpt {
    /// Renders one pass: one camera and one light subpath per pixel, every connection weighted by MIS.
    pub(crate) fn render_pass(&mut self, ctx: &Context, pass: u32, film: &mut Film) -> CastStats {
        let max_vertices = ctx.opts.max_depth as usize + 1;
        let b = &mut self.buffers;
        let mut stats = CastStats::default();
        let mut estimates = Vec::with_capacity((ctx.opts.width * ctx.opts.height) as usize);
        for wave in waves(ctx.opts.width * ctx.opts.height, b.wave) {
            // Camera and light subpaths, extended together: one batch of rays per bounce.
            let n = wave.len();
            let camera = start_camera_wave(ctx, pass, wave, &mut b.camera, &mut b.camera_walkers);
            // A sample's light stream derives from its camera stream's key (not its state).
            let keys: &[Walker] = camera.walkers;
            let light =
                start_light_wave(ctx, n, |i| keys[i].rng.derive(1), max_vertices, &mut b.light, &mut b.light_walkers);
            stats = stats.merge(extend_together(ctx, &mut [camera, light]));
            let walkers = &b.camera_walkers;
            let (camera, light) = (&b.camera, &b.light);
            let pending: Vec<Vec<Pending>> = (0..camera.len())
                .into_par_iter()
                .map_init(VertexList::default, |path, i| {
                    let mut rng = walkers[i].rng;
                    connect(ctx, camera.get(i), light.get(i), &mut rng, path)
                })
                .collect();
            let (resolved, shadow) = resolve_wave(ctx, &pending);
            stats = stats.merge(shadow);
            for (estimate, splats) in resolved {
                estimates.push(estimate);
                film.add_splats(splats);
            }
        }
        film.add_pass(pass, &estimates);
        stats
    }
}

/// Every strategy of one sample's camera and light subpaths, weighted, waiting for
/// their shadow rays. `rng` is the sample's stream after its camera subpath (light
/// samples for s = 1 draw from it).
fn connect(ctx: &Context, cam: &[Vertex], light: &[Vertex], rng: &mut Rng, path: &mut VertexList) -> Vec<Pending> {
    let max_depth = ctx.opts.max_depth as usize;
    let cam_v = camera_vertex(&ctx.scene.camera);
    let mut pending: Vec<Pending> = Vec::new();
    // A strategy image keeps one (s, t), with or without its MIS weight.
    let weight = |path: &[Vertex], s: usize, t: usize| ctx.opts.strategy_weight(s, t, || mis_weight(ctx, path, s));
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
    pending
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cast::BvhCaster;
    use crate::lights::Lights;
    use crate::render::{IntegratorKind, LightTracer, LvcBdpt, LvcParams, RenderOptions};
    use crate::scene::cornell_box;

    /// Each sample draws from its own streams, so cutting a pass into waves of any size
    /// (here 4,096 samples in one wave against waves of 1,000 and of 7) leaves the image
    /// bit for bit the same.
    #[test]
    fn the_wave_size_does_not_change_the_image() {
        let scene = cornell_box();
        let lights = Lights::new(&scene);
        let caster = BvhCaster::new(&scene);
        for integrator in [IntegratorKind::Light, IntegratorKind::Bdpt, IntegratorKind::Lvc] {
            let opts = RenderOptions { width: 64, height: 64, integrator, seed: 5, max_depth: 5, ..Default::default() };
            let ctx = Context { scene: &scene, lights: &lights, caster: &caster, opts: &opts };
            let images: Vec<Vec<glam::Vec3>> = [4096, 1000, 7]
                .into_iter()
                .map(|wave| {
                    let mut film = Film::new(64, 64).unwrap();
                    let buffers = WaveBuffers { wave, ..Default::default() };
                    match integrator {
                        IntegratorKind::Light => LightTracer { buffers }.render_pass(&ctx, 0, &mut film),
                        IntegratorKind::Bdpt => Bdpt { buffers }.render_pass(&ctx, 0, &mut film),
                        _ => LvcBdpt { buffers, ..LvcBdpt::new(LvcParams::default()) }.render_pass(&ctx, 0, &mut film),
                    };
                    film.mean()
                })
                .collect();
            assert!(images[0].iter().any(|p| p.max_element() > 0.0), "{integrator:?}: black image");
            for (k, img) in images.iter().enumerate().skip(1) {
                assert!(*img == images[0], "{integrator:?}: wave size #{k} changed the image");
            }
        }
    }
}
