//! LVC-BDPT against the BDPT reference, and its determinism.

use crate::common::*;
use warpray::cast::BvhCaster;
use warpray::film::Film;
use warpray::glam::Vec3;
use warpray::render::{Budget, IntegratorKind, LvcParams, RenderOptions, render};
use warpray::scene::{Scene, cornell_box};

fn film(scene: &Scene, kind: IntegratorKind, spp: u32, lvc: LvcParams) -> Film {
    let caster = BvhCaster::new(scene);
    let opts = RenderOptions {
        width: 32,
        height: 32,
        budget: Budget::Samples(spp),
        max_depth: 8,
        integrator: kind,
        seed: 11,
        lvc,
        ..Default::default()
    };
    let (f, _) = render(scene, &caster, &opts, |_, _| true).unwrap();
    assert_eq!(f.rejected, 0);
    f
}

fn lum(c: Vec3) -> f32 {
    c.dot(Vec3::new(0.2126, 0.7152, 0.0722))
}

fn relmse(a: &[Vec3], b: &[Vec3]) -> f64 {
    warpray::converge::relmse(a, b)
}

/// Image mean within 0.5 % of a BDPT reference, and per-pixel relMSE against it falling
/// as samples grow.
fn converges_to_bdpt(scene: &Scene, lvc: LvcParams, what: &str) {
    let reference = film(scene, IntegratorKind::Bdpt, 512, LvcParams::default());
    let low = film(scene, IntegratorKind::Lvc, 16, lvc);
    let high = film(scene, IntegratorKind::Lvc, 128, lvc);
    let (m, r) = (lum(high.image_mean()), lum(reference.image_mean()));
    assert!((m - r).abs() / r < 0.005, "{what}: LVC mean {m} vs BDPT {r}");
    let (e_low, e_high) = (relmse(&low.mean(), &reference.mean()), relmse(&high.mean(), &reference.mean()));
    assert!(e_high < 0.5 * e_low, "{what}: relMSE {e_low:.5} -> {e_high:.5}");
}

#[test]
fn lvc_converges_to_bdpt_on_the_cornell_box() {
    converges_to_bdpt(&cornell_box(), LvcParams::default(), "cornell");
    // Fewer light paths than pixels and more connections per vertex.
    converges_to_bdpt(
        &cornell_box(),
        LvcParams { light_paths: 300, connections: 5, ..Default::default() },
        "cornell, 300 light paths",
    );
}

#[test]
fn lvc_converges_to_bdpt_on_a_glossy_and_glass_scene() {
    converges_to_bdpt(&glossy_glass_box(), LvcParams::default(), "glossy+glass");
}

#[test]
fn lvc_is_deterministic_across_thread_counts() {
    let scene = glossy_glass_box();
    let run = |threads| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap()
            .install(|| film(&scene, IntegratorKind::Lvc, 2, LvcParams::default()))
    };
    let (a, b) = (run(1), run(2));
    assert!(a.sum == b.sum && a.splat == b.splat);
}
