//! What every integrator's pass sees: the scene, its lights, the caster and the
//! settings ([`Context`]), and the passes a call renders together ([`Passes`]).

use super::options::RenderOptions;
use crate::cast::RayCaster;
use crate::lights::Lights;
use crate::scene::{Projection, Scene};
use std::ops::Range;

/// Everything one pass needs.
pub(crate) struct Context<'a> {
    /// The scene.
    pub scene: &'a Scene,
    /// Its lights.
    pub lights: &'a Lights,
    /// The caster every ray goes through.
    pub caster: &'a dyn RayCaster,
    /// The render's settings.
    pub opts: &'a RenderOptions,
    /// Every triangle's unit geometric normal ([`Scene::unit_normals`]), read at hits.
    pub normals: &'a [glam::Vec3],
    /// The camera's projection of the image (`scene.camera.projection(width, height)`).
    pub projection: Projection,
}

impl Context<'_> {
    /// The unit geometric normal of triangle `tri`, as [`Scene::unit_normal`] gives it:
    /// read by the path tracer and by the subpath walks, which the megakernel and CIS's
    /// light pass share (their CUDA twins work it out from the corners, the same value;
    /// CIS's camera shading kernel does so too).
    #[inline]
    pub(crate) fn normal(&self, tri: u32) -> glam::Vec3 {
        self.normals[tri as usize]
    }

    /// Samples per wave of the bidirectional wavefronts (light tracing, BDPT, LVC) on
    /// the current thread pool: [`WAVE`] with the casters whose work comes from the
    /// batch (DACRT, PDACRT, the GPU casters); with those that take rays one at a time
    /// (BVH4, obvhs, Embree), 4,096 per thread and at least 8,192, so that a wave's
    /// pending connections (about 650 bytes a BDPT sample on the Cornell box) stay in
    /// the caches instead of streaming through memory (`docs/mitsuba.md`). The image
    /// does not depend on it.
    pub(crate) fn wave(&self) -> u32 {
        if self.caster.casts_single_rays() {
            (WAVE_PER_THREAD * rayon::current_num_threads() as u32).clamp(MIN_WAVE, WAVE)
        } else {
            WAVE
        }
    }

    /// Camera sample `pass` of `pixel`: its film position and weight.
    #[inline]
    pub(crate) fn camera_sample(&self, pixel: u32, pass: u32) -> (glam::Vec2, f32) {
        let (o, w) = (self.opts, self.opts.width);
        o.filter.camera_sample(o.filter_mode, o.seed, (pixel % w, pixel / w), w, pass)
    }
}

/// What a unit test's [`Context`] borrows besides the options: the scene, its lights, a
/// BVH caster and its unit normals.
#[cfg(test)]
pub(crate) struct TestSetup<'a> {
    scene: &'a Scene,
    lights: Lights,
    caster: crate::cast::BvhCaster,
    normals: Vec<glam::Vec3>,
}

#[cfg(test)]
impl<'a> TestSetup<'a> {
    /// The set-up for `scene`.
    pub fn new(scene: &'a Scene) -> TestSetup<'a> {
        TestSetup {
            scene,
            lights: Lights::new(scene),
            caster: crate::cast::BvhCaster::new(scene),
            normals: scene.unit_normals(),
        }
    }

    /// A context for the scene and `opts`.
    pub fn ctx<'b>(&'b self, opts: &'b RenderOptions) -> Context<'b> {
        let projection = self.scene.camera.projection(opts.width, opts.height);
        Context {
            scene: self.scene,
            lights: &self.lights,
            caster: &self.caster,
            opts,
            normals: &self.normals,
            projection,
        }
    }
}

/// Most samples (or light paths) in one wave: bounds the vertex and pending buffers
/// (about 64 bytes per vertex) whatever the image size.
pub(crate) const WAVE: u32 = 1 << 16;

/// Samples per thread in a wave of the bidirectional wavefronts when the caster takes
/// rays one at a time ([`Context::wave`]).
const WAVE_PER_THREAD: u32 = 1 << 12;

/// The fewest samples in such a wave.
const MIN_WAVE: u32 = 1 << 13;

/// The waves of up to `size` covering `0..n`, in order.
pub(crate) fn waves(n: u32, size: u32) -> impl Iterator<Item = Range<u32>> {
    let size = size.max(1);
    (0..n.div_ceil(size)).map(move |k| k * size..((k + 1) * size).min(n))
}

/// Consecutive passes rendered together, their samples numbered pass-major: sample
/// `k` is pixel (or light path) `k % per_pass` of pass `first + k / per_pass`. Waves
/// run over this numbering, so one wave may hold several passes of a small image
/// (fewer, larger caster batches), and every sample keeps the stream of its pixel and
/// pass: the image is the same however the passes are grouped.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct Passes {
    pub first: u32,
    pub count: u32,
    pub per_pass: u32,
}

impl Passes {
    /// Samples in all the passes. Callers keep this within `u32` (see
    /// [`super::Renderer::passes`]: several passes are grouped only below one wave).
    pub fn total(&self) -> u32 {
        self.per_pass * self.count
    }

    /// Sample `k`'s index within its pass, and its pass number.
    #[inline]
    pub fn at(&self, k: u32) -> (u32, u32) {
        (k % self.per_pass, self.first + k / self.per_pass)
    }

    /// The pass numbers.
    pub fn numbers(&self) -> Range<u32> {
        self.first..self.first + self.count
    }

    /// Whether sample `k` is the last of its pass.
    #[inline]
    pub fn ends_pass(&self, k: u32) -> bool {
        (k + 1).is_multiple_of(self.per_pass)
    }

    /// The waves of up to `size` samples over all the passes, in order.
    pub fn waves(&self, size: u32) -> impl Iterator<Item = Range<u32>> + use<> {
        waves(self.total(), size)
    }
}
