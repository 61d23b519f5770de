//! A point light over a diffuse plane, where the image is known in closed form: the
//! plane's radiance at `p` is ρ/π · I cos θ / d². Every integrator must reproduce it
//! (over several seeds, against their standard error) and show no spike where the
//! light projects: the bidirectional integrators used to connect the point light's
//! own vertex to the camera, a pixel of about 3,700 on a 0.1 image.

use crate::common::*;
use warpray::cast::BvhCaster;
use warpray::glam::{Vec2, Vec3};
use warpray::render::{Budget, IntegratorKind, RenderOptions, render};
use warpray::scene::{Camera, Material, PointLight, Scene};

const ALBEDO: f32 = 0.5;
const SIZE: u32 = 24;

/// A 4 × 4 quad in y = 0 facing up, a point light of intensity 1 at (0.3, 1, 0.2), and
/// a camera that sees both the plane and the light.
fn scene() -> Scene {
    let q =
        [Vec3::new(-2.0, 0.0, -2.0), Vec3::new(2.0, 0.0, -2.0), Vec3::new(2.0, 0.0, 2.0), Vec3::new(-2.0, 0.0, 2.0)];
    // Wound so the normal points up (+y).
    let mut s = scene_from_triangles(&[[q[0], q[2], q[1]], [q[0], q[3], q[2]]]);
    s.materials[0] = Material::Diffuse { albedo: Vec3::splat(ALBEDO) };
    s.point_lights.push(PointLight { position: Vec3::new(0.3, 1.0, 0.2), intensity: Vec3::ONE });
    s.camera = Camera::look_at(Vec3::new(0.0, 2.5, 3.0), Vec3::new(0.0, 0.3, 0.0), Vec3::Y, 50.0);
    s
}

/// The analytic image, each pixel averaged over 8 × 8 stratified positions.
fn analytic(s: &Scene) -> Vec<f32> {
    let light = s.point_lights[0].position;
    let mut img = Vec::new();
    for py in 0..SIZE {
        for px in 0..SIZE {
            let mut sum = 0.0;
            for k in 0..64 {
                let film = Vec2::new(
                    px as f32 + (k % 8) as f32 / 8.0 + 1.0 / 16.0,
                    py as f32 + (k / 8) as f32 / 8.0 + 1.0 / 16.0,
                );
                let r = s.camera.generate_ray(film, SIZE, SIZE, Vec2::ZERO);
                if r.dir.y >= 0.0 {
                    continue;
                }
                let t = -r.origin.y / r.dir.y;
                let p = r.at(t);
                if p.x.abs() > 2.0 || p.z.abs() > 2.0 {
                    continue;
                }
                let d = light - p;
                let cos = d.y / d.length();
                sum += ALBEDO / std::f32::consts::PI * cos / d.length_squared();
            }
            img.push(sum / 64.0);
        }
    }
    img
}

#[test]
fn every_integrator_matches_the_closed_form_with_no_spike_at_the_light() {
    let s = scene();
    let want = analytic(&s);
    let want_mean = want.iter().sum::<f32>() as f64 / want.len() as f64;
    let want_max = want.iter().copied().fold(0.0, f32::max);
    let caster = BvhCaster::new(&s);
    let seeds = 6;
    for (kind, spp) in [
        (IntegratorKind::Path, 16),
        (IntegratorKind::Light, 64),
        (IntegratorKind::Bdpt, 16),
        (IntegratorKind::Lvc, 16),
        (IntegratorKind::Cis, 16),
    ] {
        let mut means = Vec::new();
        for seed in 0..seeds {
            let opts = RenderOptions {
                width: SIZE,
                height: SIZE,
                budget: Budget::Samples(spp),
                integrator: kind,
                seed,
                ..Default::default()
            };
            let (film, _) = render(&s, &caster, &opts, |_, _| true).unwrap();
            let img = film.mean();
            let max = img.iter().map(|p| p.max_element()).fold(0.0, f32::max);
            assert!(
                max < 2.0 * want_max,
                "{}: brightest pixel {max} against the analytic {want_max} (a spike where the light projects?)",
                kind.name()
            );
            means.push(img.iter().map(|p| p.x as f64).sum::<f64>() / img.len() as f64);
        }
        let m = means.iter().sum::<f64>() / seeds as f64;
        let var = means.iter().map(|x| (x - m).powi(2)).sum::<f64>() / (seeds - 1) as f64;
        let se = (var / seeds as f64).sqrt();
        // Four standard errors of the seed means, plus 0.3 % for the analytic
        // image's own supersampling.
        let tol = 4.0 * se + 0.003 * want_mean;
        assert!(
            (m - want_mean).abs() <= tol,
            "{}: image mean {m:.6} against the analytic {want_mean:.6} (±{tol:.6}; standard error {se:.6})",
            kind.name()
        );
    }
}
