//! The integrators, one room each, and the dispatch the renderer calls. Every
//! integrator renders a span of passes (`render_passes(ctx, span, film)`); those that
//! keep their own batches render the span one pass at a time.

pub mod bdpt;
pub mod cis;
pub mod light;
pub mod lvc;
pub mod megakernel;
pub mod path;

use super::context::{Context, Passes, WAVE};
use super::options::{IntegratorKind, RenderOptions};
use crate::cast::CastStats;
use crate::film::Film;
use bdpt::Bdpt;
use cis::CisLbdpt;
use light::LightTracer;
use lvc::LvcBdpt;
use megakernel::LvcMegakernel;
use path::PathTracer;

/// A running integrator with its buffers.
pub(crate) enum Integrator {
    Path(PathTracer),
    Light(LightTracer),
    Bdpt(Bdpt),
    Lvc(LvcBdpt),
    LvcMegakernel(LvcMegakernel),
    Cis(Box<CisLbdpt>),
}

impl Integrator {
    /// The integrator `opts` names, with its buffers (`ctx` for the path tracer's,
    /// the caster's device for CIS-LBDPT to share).
    pub fn new(ctx: &Context) -> Integrator {
        let opts: &RenderOptions = ctx.opts;
        match opts.integrator {
            IntegratorKind::Path => Integrator::Path(PathTracer::new(ctx)),
            IntegratorKind::Light => Integrator::Light(LightTracer::default()),
            IntegratorKind::Bdpt => Integrator::Bdpt(Bdpt::default()),
            IntegratorKind::Lvc => Integrator::Lvc(LvcBdpt::new(opts.lvc)),
            IntegratorKind::LvcMegakernel => Integrator::LvcMegakernel(LvcMegakernel::new(opts.lvc)),
            IntegratorKind::Cis => Integrator::Cis(Box::new(match ctx.caster.device() {
                Some(dev) => CisLbdpt::on_device(opts.cis, dev.clone()),
                None => CisLbdpt::new(opts.cis),
            })),
        }
    }

    /// How many passes of `pixels` samples render together: as many as fit in one wave
    /// of [`WAVE`] samples for the wavefront integrators (at least one), so that a small
    /// image still hands the caster large batches; one for those that keep their own
    /// batches (the path tracer, the megakernel, CIS-LBDPT).
    pub fn pass_group(&self, pixels: u32) -> u32 {
        let per_pass = match self {
            Integrator::Light(_) | Integrator::Bdpt(_) => pixels,
            Integrator::Lvc(l) => pixels.max(l.params.light_paths),
            _ => return 1,
        };
        (WAVE / per_pass.max(1)).max(1)
    }

    /// Adds the passes of `span` to `film`.
    pub fn render_passes(&mut self, ctx: &Context, span: Passes, film: &mut Film) -> CastStats {
        match self {
            Integrator::Path(i) => i.render_passes(ctx, span, film),
            Integrator::Light(i) => i.render_passes(ctx, span, film),
            Integrator::Bdpt(i) => i.render_passes(ctx, span, film),
            Integrator::Lvc(i) => i.render_passes(ctx, span, film),
            Integrator::LvcMegakernel(i) => i.render_passes(ctx, span, film),
            Integrator::Cis(i) => i.render_passes(ctx, span, film),
        }
    }

    /// The device the integrator's own kernels run on, if any.
    pub fn device(&self) -> Option<&simt::Device> {
        match self {
            Integrator::LvcMegakernel(m) => Some(m.device()),
            Integrator::Cis(c) => Some(c.device()),
            _ => None,
        }
    }
}
