//! The ray batches of the DACRT paper's tables, shared by the tables example, the caster
//! tests, the benches and the inspector: primary rays through pixel centres, and from
//! their hits shadow rays to one point light, mirror reflections and cosine-weighted
//! ambient-occlusion rays.

use super::{BvhCaster, RayCaster};
use crate::geometry::{Hit, Ray, offset_ray_origin};
use crate::sampling::{Frame, Rng, cosine_hemisphere};
use crate::scene::{Camera, Scene};
use glam::{Vec2, Vec3};

/// One ray per pixel centre of a `width × height` image.
pub fn primary_rays(camera: &Camera, width: u32, height: u32) -> Vec<Ray> {
    (0..width * height)
        .map(|i| {
            let film = Vec2::new((i % width) as f32 + 0.5, (i / width) as f32 + 0.5);
            camera.generate_ray(film, width, height, Vec2::ZERO)
        })
        .collect()
}

/// Primary rays and the secondary batches made from their hits.
#[derive(Clone, Debug, Default)]
pub struct Batches {
    /// Camera rays.
    pub primary: Vec<Ray>,
    /// Segments to a point light above the scene's centre (test with `occluded`).
    pub shadow: Vec<Ray>,
    /// Mirror reflections of the primary rays at their hits.
    pub specular: Vec<Ray>,
    /// `ao_per_hit` rays per primary hit.
    pub ambient: Vec<Ray>,
}

/// The batches for the scene's camera; hits are found with the BVH. AO directions come
/// from (seed, pixel), so the batches do not depend on scheduling.
pub fn batches(scene: &Scene, width: u32, height: u32, ao_per_hit: usize, seed: u64) -> Batches {
    let primary = primary_rays(&scene.camera, width, height);
    let mut hits = vec![Hit::MISS; primary.len()];
    BvhCaster::new(scene).closest(&primary, &mut hits);
    let b = scene.bounds();
    let light = b.center() + Vec3::new(0.1, 0.45, 0.2) * b.extent();
    let mut out = Batches::default();
    for (i, (ray, hit)) in primary.iter().zip(&hits).enumerate() {
        if !hit.is_hit() {
            continue;
        }
        let n = scene.normal(hit.prim).normalize();
        let n = if n.dot(ray.dir) > 0.0 { -n } else { n };
        let p = offset_ray_origin(ray.at(hit.t), n);
        out.shadow.push(Ray::segment(p, light - p, 1.0));
        out.specular.push(Ray::new(p, ray.dir - 2.0 * ray.dir.dot(n) * n));
        let frame = Frame::from_normal(n);
        let mut rng = Rng::for_sample(seed, i as u64, 0);
        for _ in 0..ao_per_hit {
            out.ambient.push(Ray::new(p, frame.to_world(cosine_hemisphere(rng.uniform2()))));
        }
    }
    out.primary = primary;
    out
}

/// Puts the camera inside the scene's box, looking along its longest horizontal axis
/// (how the tables view the conference room: every pixel hits).
pub fn interior_camera(scene: &mut Scene) {
    let b = scene.bounds();
    let eye = b.center() + Vec3::new(-0.3, 0.1, 0.0) * b.extent();
    scene.camera = Camera::look_at(eye, b.center() + Vec3::new(0.3, -0.1, 0.0) * b.extent(), Vec3::Y, 60.0);
}
