//! Light tracing as wavefronts: per wave, every light subpath (one batch of rays per
//! bounce), then every vertex's connection to the camera, whose shadow rays go to the
//! caster as one batch; visible contributions land on the film as splats. These are
//! BDPT's t = 1 strategies alone, unweighted.

use crate::cast::CastStats;
use crate::film::Film;
use crate::render::bidir::{camera_vertex, connect_to_camera};
use crate::render::context::{Context, Passes};
use crate::render::walk::{WaveBuffers, extend_together, flush_wave, resolve_wave, start_light_wave};
use crate::sampling::Rng;

/// Light tracing: light subpaths splatted onto the film through the camera.
#[derive(Default)]
pub struct LightTracer {
    pub(super) buffers: WaveBuffers,
}

impl LightTracer {
    /// Renders the passes of `span` (one light subpath per pixel and pass, splatted
    /// through the camera), in waves that may hold several passes.
    pub(crate) fn render_passes(&mut self, ctx: &Context, span: Passes, film: &mut Film) -> CastStats {
        let max_vertices = ctx.opts.max_depth as usize + 1;
        let cam_v = camera_vertex(&ctx.scene.camera);
        let b = &mut self.buffers;
        let mut stats = CastStats::default();
        for wave in span.waves(b.wave(ctx)) {
            let rng_of = |i: usize| {
                let (path, pass) = span.at(wave.start + i as u32);
                Rng::for_sample(ctx.opts.seed ^ 0x4c54, path as u64, pass as u64)
            };
            let light = start_light_wave(ctx, wave.len(), rng_of, max_vertices, &mut b.light, &mut b.light_walkers);
            stats = stats.merge(extend_together(ctx, &mut [light]));
            let light = &b.light;
            b.pending.fill(light.len(), |i, out, _: &mut ()| {
                let verts = light.get(i);
                let splats = (1..=verts.len()).filter_map(|s| connect_to_camera(ctx, verts, s, &cam_v));
                out.extend(splats.map(|(l, px, ray)| (Some(ray), l, Some(px))));
            });
            let (resolved, shadow) = resolve_wave(ctx, &mut b.pending);
            stats = stats.merge(shadow);
            flush_wave(film, span, wave, resolved, None, |_, _| {});
        }
        stats
    }
}
