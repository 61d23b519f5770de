//! The integrators against an analytic case and against each other.

use crate::common::*;
use crate::reference::{self, TestBox};
use crate::seeds::{Runs, assert_agree, assert_constant, runs};
use warpray::cast::{BvhCaster, CastStats, RayCaster};
use warpray::film::Film;
use warpray::geometry::{Hit, Ray};
use warpray::glam::{Vec2, Vec3};
use warpray::render::{Budget, IntegratorKind, RenderOptions, render};
use warpray::scene::{Camera, Material, Scene};

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

fn relmse(a: &[Vec3], b: &[Vec3]) -> f64 {
    a.iter().zip(b).map(|(x, y)| (*x - *y).length_squared() as f64 / ((*y).length_squared() as f64 + 1e-2)).sum::<f64>()
        / a.len() as f64
}

/// Path and light tracing agree with BDPT over 16 seeds each (`seeds.rs`: image means
/// and block by block), and each one's per-pixel disagreement with BDPT falls as samples
/// grow (one seed's image against the average of 16). `spp` is per seed: path, light;
/// BDPT is the shared reference (`reference.rs`, 16 spp). Light tracing's image mean is
/// known to about 0.1 % here (combined with BDPT's, at most 0.3 %: a 2 % bias fails). The
/// path tracer's is not: the Cornell box's small light and the glass's caustics give it
/// a heavy tail, and its standard error over 16 seeds of 64 spp ranged from 0.28 % to
/// 0.7 % across seed sets, so only 1 % is asked of it (a 6 % bias fails); `direct.rs`
/// and the Mitsuba box check the path tracer to 0.1 % and 0.25 %.
fn converge_together(which: TestBox, spp: [u32; 2], what: &str) {
    let scene = which.scene();
    let size = reference::SIZE;
    let all: Vec<Runs> = [IntegratorKind::Path, IntegratorKind::Light]
        .into_iter()
        .zip(spp)
        .map(|(kind, n)| {
            runs(&format!("{what}: {}", kind.name()), 0, size as usize, 8, |seed| {
                render_mean_seeded(&scene, kind, size, n, reference::MAX_DEPTH, seed).1.mean()
            })
        })
        .collect();
    let bdpt = reference::bdpt(which);
    for (r, precision) in all.iter().zip([0.01, 0.003]) {
        eprintln!("{}", assert_agree(r, &bdpt, precision));
        let (low, high) = (relmse(&r.first, &bdpt.first), relmse(&r.average, &bdpt.average));
        assert!(high < 0.5 * low, "{}: relMSE against bdpt went {low:.4} -> {high:.4}", r.what);
    }
}

#[test]
fn path_light_and_bdpt_agree_on_the_cornell_box() {
    converge_together(TestBox::Cornell, [64, 24], "cornell");
}

/// Russian roulette changes noise, never the image: on the glossy-and-glass box (whose
/// refractions give the survival probability its η² factor) the path tracer with
/// roulette from the first bounce agrees with the path tracer without any, 16 seeds
/// each (a roulette that forgot to divide by its survival probability darkens the
/// image by far more than the 2 % precision asked here).
#[test]
fn russian_roulette_from_the_first_bounce_keeps_the_path_tracers_image() {
    let scene = TestBox::GlossyGlass.scene();
    let (size, depth) = (reference::SIZE, reference::MAX_DEPTH);
    let with_rr = |rr_depth: u32, base: u64| {
        runs(&format!("path, rr_depth {rr_depth}"), base, size as usize, 8, |seed| {
            let opts = RenderOptions {
                width: size,
                height: size,
                budget: Budget::Samples(16),
                max_depth: depth,
                rr_depth,
                seed,
                ..Default::default()
            };
            let (film, _) = render(&scene, &BvhCaster::new(&scene), &opts, |_, _| true).unwrap();
            assert_eq!(film.rejected, 0);
            film.mean()
        })
    };
    let (early, never) = (with_rr(1, 700), with_rr(depth + 1, 800));
    eprintln!("{}", assert_agree(&early, &never, 0.02));
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

/// The BVH's calls, from a caster that asks for large batches as DACRT does: the path
/// tracer then traces each pass as one wavefront instead of in chunks.
struct WholePasses(BvhCaster);

impl RayCaster for WholePasses {
    fn name(&self) -> &'static str {
        "whole-passes"
    }
    fn closest(&self, rays: &[Ray], hits: &mut [Hit]) -> CastStats {
        self.0.closest(rays, hits)
    }
    fn occluded(&self, rays: &[Ray], out: &mut [bool]) -> CastStats {
        self.0.occluded(rays, out)
    }
    fn memory_bytes(&self) -> usize {
        self.0.memory_bytes()
    }
    fn casts_single_rays(&self) -> bool {
        false
    }
}

#[test]
fn the_path_tracers_chunks_give_the_whole_wavefronts_image_at_any_thread_count() {
    // 96 × 96 pixels: several chunks of paths, traced in parallel.
    let scene = glossy_glass_box();
    let opts = RenderOptions {
        width: 96,
        height: 96,
        budget: Budget::Samples(2),
        max_depth: 8,
        integrator: IntegratorKind::Path,
        ..Default::default()
    };
    let run = |caster: &dyn RayCaster, threads| {
        let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
        pool.install(|| render(&scene, caster, &opts, |_, _| true).unwrap().0)
    };
    let chunked = BvhCaster::new(&scene);
    let whole = WholePasses(BvhCaster::new(&scene));
    let want = run(&whole, 1);
    assert!(want.image_mean().max_element() > 0.0, "the box renders black");
    for (caster, threads) in [(&chunked as &dyn RayCaster, 1), (&chunked, 3), (&whole, 2)] {
        let got = run(caster, threads);
        assert!(
            got.sum == want.sum && got.splat == want.splat,
            "{} on {threads} threads: another image",
            caster.name()
        );
    }
}

/// The heavy tier (README, docs/testing.md): tests that need many samples for their
/// power, run by CI and before a release rather than before every commit.
mod heavy {
    use super::*;

    /// Inside a closed sphere of albedo ρ whose every point emits Le, the radiance is
    /// Le / (1 − ρ) everywhere: each integrator's image over 16 seeds matches it in the mean
    /// (path and BDPT to 0.15 %, so a 1 % bias fails) and block by block.
    #[test]
    #[ignore = "heavy tier, run by CI: cargo test --profile suite --workspace --features inspector,cuda,embree --test suite -- --ignored ::heavy::"]
    fn furnace_closed_sphere_matches_the_analytic_radiance() {
        let (v, f) = icosphere(2);
        // Reverse the winding so the normals (and the one-sided emission) face inward.
        let tris: Vec<[Vec3; 3]> = f.iter().map(|t| [v[t[0] as usize], v[t[2] as usize], v[t[1] as usize]]).collect();
        let mut scene = scene_from_triangles(&tris);
        let (albedo, le) = (0.5, 1.0);
        scene.materials[0] = Material::Diffuse { albedo: Vec3::splat(albedo) };
        scene.emission[0] = Vec3::splat(le);
        scene.camera = Camera::look_at(Vec3::new(0.1, -0.05, 0.0), Vec3::new(0.3, 0.2, 1.0), Vec3::Y, 60.0);
        let want = Vec3::splat(le / (1.0 - albedo));
        // Light tracing is the noisiest here (every pixel gets splats from all over the
        // sphere): its mean is known to 0.3 % (a 2 % bias fails).
        for (kind, spp, precision) in
            [(IntegratorKind::Path, 8, 0.0015), (IntegratorKind::Light, 64, 0.003), (IntegratorKind::Bdpt, 2, 0.0015)]
        {
            let r = runs(kind.name(), 40, 32, 8, |seed| render_mean_seeded(&scene, kind, 32, spp, 60, seed).1.mean());
            eprintln!("{}", assert_constant(&r, want, precision));
        }
    }

    #[test]
    #[ignore = "heavy tier, run by CI: cargo test --profile suite --workspace --features inspector,cuda,embree --test suite -- --ignored ::heavy::"]
    fn path_light_and_bdpt_agree_on_a_glossy_and_glass_scene() {
        converge_together(TestBox::GlossyGlass, [64, 24], "glossy+glass");
    }
}
