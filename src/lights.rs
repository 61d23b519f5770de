//! Light sampling: emissive triangles (one-sided, emitting from the winding's front
//! face) and point lights, chosen in proportion to their power, then a uniform point
//! on the chosen triangle.

use crate::film::luminance;
use crate::geometry::barycentric_point;
use crate::sampling::uniform_triangle;
use crate::scene::Scene;
use glam::{Vec2, Vec3};
use std::f32::consts::PI;

/// The part of the code this module's declared arithmetic counts as ([`crate::cost::Part`]).
const COST_PART: crate::cost::Part = crate::cost::Part::Lights;

#[derive(Clone, Copy, Debug, PartialEq)]
/// A light source the integrators can sample.
pub enum Light {
    /// An emissive triangle of the scene.
    Area {
        /// The triangle.
        tri: u32,
        /// Its area.
        area: f32,
        /// Its unit normal (the emitting side).
        normal: Vec3,
        /// Emitted radiance.
        radiance: Vec3,
    },
    /// A point light.
    Point {
        /// Position.
        position: Vec3,
        /// Radiant intensity.
        intensity: Vec3,
    },
}

impl Light {
    /// The sample of this light at `position` (its point light's position, or a point
    /// of its triangle: [`area_point`]), chosen with probability `p_sel`.
    #[inline(always)]
    pub(crate) fn sample_at(&self, position: Vec3, p_sel: f32) -> LightSample {
        match *self {
            Light::Area { tri, area, normal, radiance } => {
                LightSample { position, normal, emitted: radiance, pdf: p_sel / area, is_delta: false, tri }
            }
            Light::Point { intensity, .. } => LightSample {
                position,
                normal: Vec3::ZERO,
                emitted: intensity,
                pdf: p_sel,
                is_delta: true,
                tri: u32::MAX,
            },
        }
    }
}

/// The point `u` places uniformly on an area light's triangle (`corners`).
#[inline(always)]
pub(crate) fn area_point(corners: [Vec3; 3], u: Vec2) -> Vec3 {
    let (b1, b2) = uniform_triangle(u);
    barycentric_point(corners, b1, b2)
}

/// A point sampled on a light.
#[derive(Clone, Copy, Debug)]
pub struct LightSample {
    /// The sampled point.
    pub position: Vec3,
    /// Unit normal of the emitting surface (zero for point lights).
    pub normal: Vec3,
    /// Radiance leaving an area light's front face, or a point light's intensity.
    pub emitted: Vec3,
    /// Probability of the choice times the area density (1/area); for point lights
    /// the selection probability alone.
    pub pdf: f32,
    /// Whether the light is a point (no area: it cannot be hit).
    pub is_delta: bool,
    /// The emitting triangle (area lights), or `u32::MAX`.
    pub tri: u32,
}

#[derive(Clone, Debug, Default)]
/// The scene's lights with a power-proportional selection distribution.
pub struct Lights {
    /// Every light: area lights in triangle order, then point lights.
    pub lights: Vec<Light>,
    /// Cumulative selection probabilities, `cdf[i]` = P(choice <= i).
    cdf: Vec<f32>,
    /// Per scene triangle: index into `lights`, or `u32::MAX`.
    light_of_tri: Vec<u32>,
}

impl Lights {
    /// The lights of `scene` (emissive triangles of positive area and point lights).
    pub fn new(scene: &Scene) -> Lights {
        let mut lights = Vec::new();
        let mut light_of_tri = vec![u32::MAX; scene.triangle_count()];
        for tri in 0..scene.triangle_count() as u32 {
            if let Some((n, area)) = scene.area_emitter(tri) {
                light_of_tri[tri as usize] = lights.len() as u32;
                lights.push(Light::Area { tri, area, normal: n.normalize(), radiance: scene.emission_of(tri) });
            }
        }
        lights.extend(scene.point_lights.iter().map(|p| Light::Point { position: p.position, intensity: p.intensity }));
        let power: Vec<f32> = lights
            .iter()
            .map(|l| match *l {
                Light::Area { area, radiance, .. } => PI * area * luminance(radiance).max(1e-12),
                Light::Point { intensity, .. } => 4.0 * PI * luminance(intensity).max(1e-12),
            })
            .collect();
        let total: f64 = power.iter().map(|&p| p as f64).sum();
        let mut acc = 0.0f64;
        let mut cdf: Vec<f32> = power
            .iter()
            .map(|&p| {
                acc += p as f64;
                (acc / total) as f32
            })
            .collect();
        if let Some(last) = cdf.last_mut() {
            *last = 1.0;
        }
        Lights { lights, cdf, light_of_tri }
    }

    /// The selection's cumulative probabilities and each triangle's light (or
    /// `u32::MAX`), as the GPU twin of the shading kernel reads them.
    #[cfg(feature = "cuda")]
    pub(crate) fn tables(&self) -> (&[f32], &[u32]) {
        (&self.cdf, &self.light_of_tri)
    }

    /// Whether there is no light.
    pub fn is_empty(&self) -> bool {
        self.lights.is_empty()
    }

    fn select_pdf(&self, i: usize) -> f32 {
        use crate::cost::read;
        read!(self.cdf, i) - if i == 0 { 0.0 } else { read!(self.cdf, i - 1) }
    }

    /// The first light whose cumulative probability exceeds `u_select` (the last if
    /// none does): a binary search, each trip one read of the table.
    fn select(&self, u_select: f32) -> usize {
        let (mut lo, mut hi) = (0, self.cdf.len());
        while lo < hi {
            let mid = (lo + hi) / 2;
            if crate::cost::read!(self.cdf, mid) <= u_select {
                lo = mid + 1;
            } else {
                hi = mid;
            }
        }
        lo.min(self.lights.len() - 1)
    }

    /// The light `u_select` chooses and the probability of choosing it: the first step
    /// of [`Lights::sample`], apart for callers that place the point themselves (the
    /// path tracer's lanes of diffuse hits). `None` when there is no light or the
    /// choice has no probability.
    #[inline]
    pub(crate) fn pick(&self, u_select: f32) -> Option<(&Light, f32)> {
        if self.lights.is_empty() {
            return None;
        }
        let i = self.select(u_select);
        let p_sel = self.select_pdf(i);
        if p_sel <= 0.0 { None } else { Some((&self.lights[i], p_sel)) }
    }

    /// Picks a light with `u_select` and a point on it with `u`.
    #[inline(always)]
    #[track_caller]
    pub fn sample(&self, scene: &Scene, u_select: f32, u: Vec2) -> Option<LightSample> {
        let _inlined = crate::cost::scope();
        if self.lights.is_empty() {
            return None;
        }
        // (`simt`'s model: the binary search's trips, the selection's difference.)
        let trips = usize::BITS - self.cdf.len().leading_zeros();
        crate::cost::declare!(6 * trips + 4 + 2 * crate::cost::BRANCH);
        let (light, p_sel) = self.pick(u_select)?;
        crate::cost::declare!(crate::cost::BRANCH);
        let position = match *light {
            Light::Area { tri, .. } => {
                use crate::cost::{DIV, SQRT, V3};
                crate::cost::declare!(SQRT + 3 + 6 * V3 + DIV, reads(light, 9));
                area_point(scene.vertices(tri), u)
            }
            Light::Point { position, .. } => {
                crate::cost::reads!(light, 7);
                position
            }
        };
        Some(light.sample_at(position, p_sel))
    }

    /// Selection probability of the point light at `position` (0 if there is none).
    pub fn point_select_pdf(&self, position: Vec3) -> f32 {
        self.lights
            .iter()
            .position(|l| {
                crate::cost::reads!(l, 4);
                matches!(l, Light::Point { position: p, .. } if *p == position)
            })
            .map_or(0.0, |i| self.select_pdf(i))
    }

    /// Area density (selection × 1/area) with which [`Lights::sample`] picks a point on
    /// scene triangle `tri`; 0 for non-emitters.
    pub fn pdf_area(&self, tri: u32) -> f32 {
        if tri as usize >= self.light_of_tri.len() {
            return 0.0;
        }
        match crate::cost::read!(self.light_of_tri, tri as usize) {
            u32::MAX => 0.0,
            i => {
                let light = &self.lights[i as usize];
                crate::cost::reads!(light, 1);
                match *light {
                    Light::Area { area, .. } => {
                        crate::cost::reads!(light, 1);
                        self.select_pdf(i as usize) / area
                    }
                    Light::Point { .. } => 0.0,
                }
            }
        }
    }
}
