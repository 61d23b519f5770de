//! The ray batches of the DACRT paper's tables, shared by the tables example, the caster
//! tests, the benches and the inspector: primary rays through pixel centres, and from
//! their hits shadow rays to one point light, mirror reflections and cosine-weighted
//! ambient-occlusion rays; and the changing-geometry case, a waving grid with its camera
//! and shadow rays.

use super::bvh::BvhCaster;
use super::caster::RayCaster;
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

/// The changing-geometry benchmark's mesh at time `time` (frames 0.25 apart in the
/// examples): `n × n` quads over [-1, 1]² in x and z, heights from two travelling waves,
/// so every vertex moves every frame. Procedural, not a Stanford model: their terms
/// forbid animating those.
pub fn waving_grid(n: usize, time: f32) -> Vec<[Vec3; 3]> {
    let p = |i: usize, j: usize| {
        let (x, y) = (i as f32 / n as f32 * 2.0 - 1.0, j as f32 / n as f32 * 2.0 - 1.0);
        let h = 0.08 * (7.0 * x + 2.0 * time).sin() * (5.0 * y - 1.3 * time).cos()
            + 0.03 * (23.0 * (x + y) + 5.0 * time).sin();
        Vec3::new(x, h, y)
    };
    let mut tris = Vec::with_capacity(2 * n * n);
    for j in 0..n {
        for i in 0..n {
            let (a, b, c, d) = (p(i, j), p(i + 1, j), p(i + 1, j + 1), p(i, j + 1));
            tris.push([a, b, c]);
            tris.push([a, c, d]);
        }
    }
    tris
}

/// The camera the waving grid is viewed from (it fills most of the image).
pub fn waving_grid_camera() -> Camera {
    Camera::look_at(Vec3::new(0.0, 1.3, -2.2), Vec3::new(0.0, -0.1, 0.0), Vec3::Y, 45.0)
}

/// Shadow rays from every primary hit on the grid `tris` to the point light above it.
pub fn waving_grid_shadow_rays(tris: &[[Vec3; 3]], primary: &[Ray], hits: &[Hit]) -> Vec<Ray> {
    let light = Vec3::new(0.3, 2.0, -0.4);
    primary
        .iter()
        .zip(hits)
        .filter(|(_, h)| h.is_hit())
        .map(|(r, h)| {
            let [a, b, c] = tris[h.prim as usize];
            let n = (b - a).cross(c - a).normalize_or_zero();
            let n = if n.dot(r.dir) > 0.0 { -n } else { n };
            let p = offset_ray_origin(r.at(h.t), n);
            Ray::segment(p, light - p, 1.0)
        })
        .collect()
}
