//! Every strategy of BDPT, LVC-BDPT and CIS-LBDPT on its own, against a closed form
//! that shares no code with the integrators, with a statistical test over independent
//! seeds. LVC's and CIS's connection strategies (s ≥ 2, t ≥ 2) go through the light
//! vertex cache: uniform draws for LVC, resampled ones (RIS) for CIS, so an error in
//! the resampling weight moves CIS's connection images by its full size.
//!
//! Inside a closed enclosure whose every surface emits `Le` toward the inside and
//! reflects diffusely with albedo ρ, light that has bounced exactly `k` times has
//! radiance `Le ρ^k` everywhere, whatever the enclosure's shape. So:
//! * each strategy (s, t) *unweighted* must average `Le ρ^(s+t−2)` over the image (it
//!   samples every path of its depth on its own);
//! * the *MIS-weighted* strategies of one depth must add up to `Le ρ^k`.
//!
//! A test passes when the mean over 16 seeds is within 5 standard errors of the closed
//! form (a false alarm about once in 6,000 checks for Student's t with 15 degrees of
//! freedom). Each check also asks that its standard error be small (0.3 % of the value;
//! 0.6 % for the light-tracing strategies t = 1), so that the test has the power to see
//! errors of 1–3 %; docs/light-transport.md lists the mutations tried.

use crate::common::*;
use IntegratorKind::{Bdpt, Cis, Lvc};
use warpray::cast::BvhCaster;
use warpray::glam::Vec3;
use warpray::render::{Budget, IntegratorKind, RenderOptions, Strategy, render};
use warpray::scene::{Camera, Material, Scene};

const ALBEDO: f32 = 0.5;
const LE: f32 = 1.0;
const MAX_DEPTH: u32 = 3;
const SEEDS: u64 = 16;

/// The inside of an icosphere, emitting and reflecting everywhere.
fn furnace() -> Scene {
    let (v, f) = icosphere(2);
    // Reverse the winding so the normals (and the one-sided emission) face inward.
    let tris: Vec<[Vec3; 3]> = f.iter().map(|t| [v[t[0] as usize], v[t[2] as usize], v[t[1] as usize]]).collect();
    let mut scene = scene_from_triangles(&tris);
    scene.materials[0] = Material::Diffuse { albedo: Vec3::splat(ALBEDO) };
    scene.emission[0] = Vec3::splat(LE);
    scene.camera = Camera::look_at(Vec3::new(0.1, -0.05, 0.0), Vec3::new(0.3, 0.2, 1.0), Vec3::Y, 90.0);
    scene
}

/// The image mean (green channel: all are equal) of one render per seed.
fn seed_means(
    scene: &Scene,
    caster: &BvhCaster,
    integrator: IntegratorKind,
    strategy: Option<Strategy>,
    spp: u32,
) -> Vec<f64> {
    (0..SEEDS)
        .map(|seed| {
            let opts = RenderOptions {
                width: 16,
                height: 16,
                budget: Budget::Samples(spp),
                max_depth: MAX_DEPTH,
                seed: 1000 + seed,
                integrator,
                strategy,
                ..Default::default()
            };
            let (film, _) = render(scene, caster, &opts, |_, _| true).unwrap();
            assert_eq!(film.rejected, 0);
            film.image_mean().y as f64
        })
        .collect()
}

/// Checks `(mean, se)` against `want`, and that the standard error is below
/// `precision` of it (so the test can see an error of a few of those); the line
/// describing it.
fn check(what: &str, (mean, se): (f64, f64), want: f64, precision: f64, failures: &mut Vec<String>) -> String {
    let z = (mean - want) / se.max(1e-12);
    let line =
        format!("{what}: {mean:.5} ± {se:.5} against {want:.5} ({:+.2} %, z = {z:+.1})", 100.0 * (mean - want) / want);
    if z.abs() > 5.0 || se / want > precision {
        failures.push(line.clone());
    }
    line
}

/// The strategies (s, t) of path depth `k` that the bidirectional integrators use
/// (t ≥ 1; (0, 1) would need a path to hit the pinhole).
fn strategies(k: u32) -> impl Iterator<Item = (u32, u32)> {
    (1..=k + 2).map(move |t| (k + 2 - t, t)).filter(|&(s, t)| s > 0 || t >= 2)
}

/// Each strategy of `integrator` unweighted against `Le ρ^k`.
fn every_unweighted_strategy_matches_the_furnace(integrator: IntegratorKind) {
    let scene = furnace();
    let caster = BvhCaster::new(&scene);
    let mut failures = Vec::new();
    for k in 0..=MAX_DEPTH {
        for (s, t) in strategies(k) {
            // Light tracing strategies (t = 1) land on the film only when their vertex
            // is in view, and are noisier: more samples, and a looser guard on their
            // standard error (they see errors of about 3 % alone; the weighted sums
            // below see their share of smaller ones). In LVC and CIS one iteration's
            // few light paths (one per pixel) serve the whole image through the cache,
            // so their splats and cache connections need more samples for the same
            // standard error.
            let cached = integrator != Bdpt;
            if integrator == Cis && t == 1 {
                // CIS's light pass and its camera splats are LVC's (`build_cache`, the
                // same seeds): the LVC test checks these images, bit for bit the same.
                continue;
            }
            let (spp, precision) = match (s, t) {
                (_, 1) => (if cached { 128 } else { 64 }, 0.006),
                (2.., 2..) if cached => (64, 0.003),
                _ => (16, 0.003),
            };
            let st =
                statistics(&seed_means(&scene, &caster, integrator, Some(Strategy { s, t, weighted: false }), spp));
            let want = (LE * ALBEDO.powi(k as i32)) as f64;
            let what = format!("{integrator:?} (s, t) = ({s}, {t}), depth {k}");
            println!("{}", check(&what, st, want, precision, &mut failures));
        }
    }
    assert!(failures.is_empty(), "strategies off the closed form:\n{}", failures.join("\n"));
}

/// The weighted strategies of each depth of `integrator` summed against `Le ρ^k`,
/// and its full render against the sum over depths.
fn weighted_strategies_of_each_depth_add_up_to_the_furnace(integrator: IntegratorKind) {
    let scene = furnace();
    let caster = BvhCaster::new(&scene);
    let mut failures = Vec::new();
    // Depth by depth: per seed, the sum of that depth's weighted strategy images (the
    // strategies of one seed share their subpaths, so the sum is formed per seed and
    // the standard error taken over seeds).
    for k in 0..=MAX_DEPTH {
        let mut sums = vec![0.0; SEEDS as usize];
        for (s, t) in strategies(k) {
            let means = seed_means(&scene, &caster, integrator, Some(Strategy { s, t, weighted: true }), 8);
            sums.iter_mut().zip(means).for_each(|(a, m)| *a += m);
        }
        let want = (LE * ALBEDO.powi(k as i32)) as f64;
        let what = format!("{integrator:?} depth {k}, weighted sum");
        println!("{}", check(&what, statistics(&sums), want, 0.003, &mut failures));
    }
    // And the whole render, every strategy weighted at once.
    let want = (0..=MAX_DEPTH).map(|k| (LE * ALBEDO.powi(k as i32)) as f64).sum();
    let full = statistics(&seed_means(&scene, &caster, integrator, None, 8));
    println!("{}", check(&format!("{integrator:?} all depths, full render"), full, want, 0.003, &mut failures));
    assert!(failures.is_empty(), "weighted sums off the closed form:\n{}", failures.join("\n"));
}

#[test]
fn bdpt_weighted_strategies() {
    weighted_strategies_of_each_depth_add_up_to_the_furnace(Bdpt);
}

#[test]
fn lvc_weighted_strategies() {
    weighted_strategies_of_each_depth_add_up_to_the_furnace(Lvc);
}

#[test]
fn cis_weighted_strategies() {
    weighted_strategies_of_each_depth_add_up_to_the_furnace(Cis);
}

/// The heavy tier (README, docs/testing.md): tests that need many samples for their
/// power, run by CI and before a release rather than before every commit.
mod heavy {
    use super::*;

    #[test]
    #[ignore = "heavy tier, run by CI: cargo test --profile suite --workspace --features inspector,cuda,embree --test suite -- --ignored ::heavy::"]
    fn bdpt_unweighted_strategies() {
        every_unweighted_strategy_matches_the_furnace(Bdpt);
    }

    #[test]
    #[ignore = "heavy tier, run by CI: cargo test --profile suite --workspace --features inspector,cuda,embree --test suite -- --ignored ::heavy::"]
    fn lvc_unweighted_strategies() {
        every_unweighted_strategy_matches_the_furnace(Lvc);
    }

    #[test]
    #[ignore = "heavy tier, run by CI: cargo test --profile suite --workspace --features inspector,cuda,embree --test suite -- --ignored ::heavy::"]
    fn cis_unweighted_strategies() {
        every_unweighted_strategy_matches_the_furnace(Cis);
    }
}
