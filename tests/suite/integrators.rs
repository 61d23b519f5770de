//! The integrators against an analytic case and against each other.

use crate::common::*;
use warpray::cast::BvhCaster;
use warpray::film::Film;
use warpray::glam::{Vec2, Vec3};
use warpray::render::{Budget, IntegratorKind, RenderOptions, render};
use warpray::scene::{Camera, Material, Scene, cornell_box};

fn render_mean(scene: &Scene, kind: IntegratorKind, size: u32, spp: u32, max_depth: u32) -> (Vec3, Film) {
    render_mean_seeded(scene, kind, size, spp, max_depth, 5)
}

fn render_mean_seeded(
    scene: &Scene,
    kind: IntegratorKind,
    size: u32,
    spp: u32,
    max_depth: u32,
    seed: u64,
) -> (Vec3, Film) {
    let caster = BvhCaster::new(scene);
    let opts = RenderOptions {
        width: size,
        height: size,
        budget: Budget::Samples(spp),
        max_depth,
        integrator: kind,
        seed,
        ..Default::default()
    };
    let (film, _) = render(scene, &caster, &opts, |_, _| true).unwrap();
    assert_eq!(film.rejected, 0, "{}: non-finite samples", kind.name());
    (film.image_mean(), film)
}

/// Inside a closed sphere of albedo ρ whose every point emits Le, the radiance is
/// Le / (1 − ρ) everywhere.
#[test]
fn furnace_closed_sphere_matches_the_analytic_radiance() {
    let (v, f) = icosphere(2);
    // Reverse the winding so the normals (and the one-sided emission) face inward.
    let tris: Vec<[Vec3; 3]> = f.iter().map(|t| [v[t[0] as usize], v[t[2] as usize], v[t[1] as usize]]).collect();
    let mut scene = scene_from_triangles(&tris);
    let (albedo, le) = (0.5, 1.0);
    scene.materials[0] = Material::Diffuse { albedo: Vec3::splat(albedo) };
    scene.emission[0] = Vec3::splat(le);
    scene.camera = Camera::look_at(Vec3::new(0.1, -0.05, 0.0), Vec3::new(0.3, 0.2, 1.0), Vec3::Y, 60.0);
    let want = le / (1.0 - albedo);
    // Light tracing is the noisiest here (every pixel gets splats from all over the sphere).
    for (kind, spp) in [(IntegratorKind::Path, 128), (IntegratorKind::Light, 1024), (IntegratorKind::Bdpt, 32)] {
        let (mean, _) = render_mean(&scene, kind, 32, spp, 60);
        let err = (mean - Vec3::splat(want)).abs().max_element() / want;
        assert!(err < 0.01, "{}: image mean {mean}, analytic {want} (error {:.2} %)", kind.name(), err * 100.0);
    }
}

fn relmse(a: &[Vec3], b: &[Vec3]) -> f64 {
    a.iter().zip(b).map(|(x, y)| (*x - *y).length_squared() as f64 / ((*y).length_squared() as f64 + 1e-2)).sum::<f64>()
        / a.len() as f64
}

/// The three integrators' image means agree within their standard errors over eight
/// independent seeds, and their per-pixel disagreement falls as samples grow (one
/// seed's image against the eight seeds' average).
fn converge_together(scene: &Scene, size: u32, spp: [u32; 3], what: &str) {
    const SEEDS: u64 = 8;
    let lum = |c: Vec3| c.dot(Vec3::new(0.2126, 0.7152, 0.0722)) as f64;
    let mut stats = Vec::new();
    let mut low = Vec::new();
    let mut high = Vec::new();
    for (kind, n) in IntegratorKind::CORE.into_iter().zip(spp) {
        let mut means = Vec::new();
        let mut sum = vec![Vec3::ZERO; (size * size) as usize];
        for seed in 0..SEEDS {
            let (m, f) = render_mean_seeded(scene, kind, size, n / SEEDS as u32, 8, seed);
            means.push(lum(m));
            let img = f.mean();
            sum.iter_mut().zip(&img).for_each(|(s, v)| *s += *v / SEEDS as f32);
            if seed == 0 {
                low.push(img);
            }
        }
        stats.push((kind, statistics(&means)));
        high.push(sum);
    }
    for i in 0..3 {
        for j in i + 1..3 {
            let ((ki, (a, sa)), (kj, (b, sb))) = (stats[i], stats[j]);
            let z = (a - b) / (sa * sa + sb * sb).sqrt();
            assert!(
                z.abs() < 4.0,
                "{what}: {} mean {a:.5} ± {sa:.5} vs {} mean {b:.5} ± {sb:.5} (z = {z:.2})",
                ki.name(),
                kj.name()
            );
            let (r_low, r_high) = (relmse(&low[i], &low[j]), relmse(&high[i], &high[j]));
            assert!(
                r_high < 0.5 * r_low,
                "{what}: relMSE {} vs {} went {r_low:.4} -> {r_high:.4}",
                ki.name(),
                kj.name()
            );
        }
    }
    // Power: each mean is known to better than 0.5 %.
    for (kind, (m, se)) in &stats {
        assert!(*se < 0.005 * m, "{what}: {} standard error {se} against mean {m}", kind.name());
    }
}

#[test]
fn path_light_and_bdpt_agree_on_the_cornell_box() {
    converge_together(&cornell_box(), 32, [1024, 1024, 256], "cornell");
}

#[test]
fn path_light_and_bdpt_agree_on_a_glossy_and_glass_scene() {
    converge_together(&glossy_glass_box(), 32, [1024, 1024, 256], "glossy+glass");
}

#[test]
fn the_film_guards_against_nan_and_inf() {
    let mut film = Film::new(2, 2).unwrap();
    film.add_pass(0, &[Vec3::ONE, Vec3::NAN, Vec3::splat(f32::INFINITY), Vec3::new(-1.0, 0.0, 0.0)]);
    film.add_splats([(Vec2::new(0.5, 0.5), Vec3::NAN), (Vec2::new(1.5, 0.5), Vec3::ONE), (Vec2::NAN, Vec3::ONE)]);
    assert_eq!(film.rejected, 5);
    assert!(film.mean().iter().all(|v| v.is_finite()));
    assert_eq!(film.mean()[0], Vec3::ONE);
    assert_eq!(film.mean()[1], Vec3::ONE);
}

#[test]
fn every_integrator_is_deterministic_across_thread_counts() {
    let scene = glossy_glass_box();
    for kind in IntegratorKind::ALL {
        let run = |threads| {
            rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .unwrap()
                .install(|| render_mean(&scene, kind, 24, 2, 8).1)
        };
        let (a, b) = (run(1), run(2));
        assert!(a.sum == b.sum && a.splat == b.splat, "{}: 1 and 2 threads differ", kind.name());
    }
}
