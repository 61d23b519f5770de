//! Auxiliary images (AOVs) written as extra EXR channels beside the beauty image:
//! what denoisers and image comparisons need, named as tev and pbrt-v4 group them.
//!
//! | AOV        | channels                       | per pixel                                                   |
//! |------------|--------------------------------|-------------------------------------------------------------|
//! | `albedo`   | `Albedo.R`, `Albedo.G`, `Albedo.B` | directional albedo of the first surface seen: the mean of the BSDF sample weight `f·cos/pdf`, one BSDF sample per camera ray |
//! | `normal`   | `N.X`, `N.Y`, `N.Z`            | world-space normal of the first surface, turned to face the camera, averaged over the pixel's rays (shorter than 1 on edges) |
//! | `depth`    | `Z`                            | camera-space depth (distance along the view axis) of the first surface, averaged over the rays that hit; +∞ where none did |
//! | `variance` | `Variance.R`, `.G`, `.B`       | sample variance of the pixel's per-pass estimates ([`Film::variance`]); NaN (undefined) after one pass, and `--spp 1` with it is refused |
//!
//! The geometric AOVs come from a separate pass of `samples` jittered camera rays per
//! pixel, cast as one batch per sample through the render's own caster, seeded by
//! pixel and sample like the render (same image at any thread count).

use crate::bsdf::TransportMode;
use crate::cast::RayCaster;
use crate::error::Result;
use crate::film::Film;
use crate::geometry::{Hit, Ray};
use crate::sampling::{Frame, Rng};
use crate::scene::Scene;
use glam::{Vec2, Vec3};
use rayon::prelude::*;

/// One auxiliary image.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "cli", derive(clap::ValueEnum))]
pub enum Aov {
    /// Directional albedo of the first surface (`Albedo.R/G/B`).
    Albedo,
    /// Normal of the first surface, facing the camera (`N.X/Y/Z`).
    Normal,
    /// Camera-space depth of the first surface (`Z`).
    Depth,
    /// Per-pixel sample variance of the render (`Variance.R/G/B`).
    Variance,
}

impl Aov {
    /// Every AOV, in channel order.
    pub const ALL: [Aov; 4] = [Aov::Albedo, Aov::Normal, Aov::Depth, Aov::Variance];
}

/// The geometric AOVs of one image.
#[derive(Clone, Debug)]
pub struct GBuffer {
    /// Image width, pixels.
    pub width: u32,
    /// Image height, pixels.
    pub height: u32,
    /// Directional albedo of the first surface (zero where nothing was hit).
    pub albedo: Vec<Vec3>,
    /// Camera-facing normal of the first surface, averaged (zero where nothing was hit).
    pub normal: Vec<Vec3>,
    /// +∞ where no ray of the pixel hit anything.
    pub depth: Vec<f32>,
}

/// Stream tag that keeps the AOV pass's random numbers apart from the render's.
const AOV_STREAM: u64 = 0xa0_5eed;

/// Casts `samples` jittered camera rays per pixel (one batch per sample) and averages
/// what the first surface shows.
pub fn render_gbuffer(
    scene: &Scene,
    caster: &dyn RayCaster,
    width: u32,
    height: u32,
    samples: u32,
    seed: u64,
) -> Result<GBuffer> {
    crate::film::check_size(width, height)?;
    let n = (width * height) as usize;
    let cam = &scene.camera;
    let mut acc = vec![(Vec3::ZERO, Vec3::ZERO, 0.0f32, 0u32); n];
    let (mut rays, mut hits) = (Vec::with_capacity(n), vec![Hit::MISS; n]);
    for sample in 0..samples.max(1) {
        (0..n)
            .into_par_iter()
            .map(|pixel| {
                let mut rng = Rng::for_sample(seed ^ AOV_STREAM, pixel as u64, sample as u64);
                let film = Vec2::new((pixel as u32 % width) as f32, (pixel as u32 / width) as f32) + rng.uniform2();
                cam.generate_ray(film, width, height, rng.uniform2())
            })
            .collect_into_vec(&mut rays);
        caster.closest(&rays, &mut hits);
        acc.par_iter_mut().zip(&rays).zip(&hits).enumerate().for_each(|(pixel, ((a, ray), hit))| {
            if let Some((albedo, normal, z)) = first_surface(scene, ray, hit, seed, pixel as u64, sample as u64) {
                a.0 += albedo;
                a.1 += normal;
                a.2 += z;
                a.3 += 1;
            }
        });
    }
    let inv = 1.0 / samples.max(1) as f32;
    Ok(GBuffer {
        width,
        height,
        albedo: acc.iter().map(|a| a.0 * inv).collect(),
        normal: acc.iter().map(|a| a.1 * inv).collect(),
        depth: acc.iter().map(|a| if a.3 > 0 { a.2 / a.3 as f32 } else { f32::INFINITY }).collect(),
    })
}

/// Albedo estimate, camera-facing normal and camera-space depth at a ray's hit.
fn first_surface(scene: &Scene, ray: &Ray, hit: &Hit, seed: u64, pixel: u64, sample: u64) -> Option<(Vec3, Vec3, f32)> {
    if !hit.is_hit() {
        return None;
    }
    let ng = scene.unit_normal(hit.prim);
    if ng == Vec3::ZERO {
        return None;
    }
    let wo = -ray.dir.normalize();
    let normal = if ng.dot(wo) < 0.0 { -ng } else { ng };
    let frame = Frame::from_normal(ng);
    let mut rng = Rng::for_sample(seed ^ AOV_STREAM, pixel, sample).derive(1);
    let wo_local = frame.to_local(wo);
    let albedo = scene
        .bsdf(hit.prim, wo_local)
        .sample_f(wo_local, rng.uniform(), rng.uniform2(), TransportMode::Radiance)
        .map_or(Vec3::ZERO, |s| s.weight);
    let z = hit.t * ray.dir.dot(scene.camera.forward);
    Some((albedo, normal, z))
}

/// The EXR channels of `aovs`, named as in the table above, for
/// [`Film::write_exr_aovs`]. `gbuffer` is needed for all but `variance`.
pub fn channels(aovs: &[Aov], film: &Film, gbuffer: Option<&GBuffer>) -> Vec<(String, Vec<f32>)> {
    fn rgb(out: &mut Vec<(String, Vec<f32>)>, prefix: &str, names: [&str; 3], v: &[Vec3]) {
        for (i, c) in names.into_iter().enumerate() {
            out.push((format!("{prefix}.{c}"), v.iter().map(|p| p[i]).collect()));
        }
    }
    let mut out = Vec::new();
    for aov in Aov::ALL.into_iter().filter(|a| aovs.contains(a)) {
        match (aov, gbuffer) {
            (Aov::Variance, _) => rgb(&mut out, "Variance", ["R", "G", "B"], &film.variance()),
            (Aov::Albedo, Some(g)) => rgb(&mut out, "Albedo", ["R", "G", "B"], &g.albedo),
            (Aov::Normal, Some(g)) => rgb(&mut out, "N", ["X", "Y", "Z"], &g.normal),
            (Aov::Depth, Some(g)) => out.push(("Z".to_string(), g.depth.clone())),
            (_, None) => {}
        }
    }
    out
}
