//! CIS-LBDPT: convergence to the BDPT reference with every idea on and each switched off,
//! its relation to uniform LVC, determinism, and what sorting does to SIMD efficiency.

use crate::common::*;
use warpray::cast::BvhCaster;
use warpray::film::Film;
use warpray::glam::Vec3;
use warpray::render::CisParams;
use warpray::render::{Budget, IntegratorKind, LvcParams, RenderOptions, Renderer, render};
use warpray::scene::{Scene, cornell_box};

fn opts(kind: IntegratorKind, spp: u32, cis: CisParams, lvc: LvcParams) -> RenderOptions {
    RenderOptions {
        width: 32,
        height: 32,
        budget: Budget::Samples(spp),
        max_depth: 8,
        integrator: kind,
        seed: 13,
        lvc,
        cis,
        ..Default::default()
    }
}

fn film(scene: &Scene, o: &RenderOptions) -> Film {
    let caster = BvhCaster::new(scene);
    let (f, _) = render(scene, &caster, o, |_, _| true).unwrap();
    assert_eq!(f.rejected, 0);
    f
}

fn lum(c: Vec3) -> f32 {
    c.dot(Vec3::new(0.2126, 0.7152, 0.0722))
}

fn small_pool(p: CisParams) -> CisParams {
    // A pool smaller than the image, so regeneration really happens.
    CisParams { pool: 300, ..p }
}

fn variants() -> Vec<(&'static str, CisParams)> {
    let d = small_pool(CisParams::default());
    vec![
        ("all on", d),
        ("no sorting", CisParams { sort: false, ..d }),
        ("no importance sampling", CisParams { importance: false, ..d }),
        ("no compaction", CisParams { regenerate: false, ..d }),
    ]
}

fn converges(scene: &Scene, what: &str) {
    let reference = film(scene, &opts(IntegratorKind::Bdpt, 512, CisParams::default(), LvcParams::default()));
    let r = lum(reference.image_mean());
    for (name, p) in variants() {
        let low = film(scene, &opts(IntegratorKind::Cis, 8, p, LvcParams::default()));
        let high = film(scene, &opts(IntegratorKind::Cis, 64, p, LvcParams::default()));
        let m = lum(high.image_mean());
        assert!((m - r).abs() / r < 0.005, "{what}/{name}: CIS mean {m} vs BDPT {r}");
        let e_low = warpray::converge::relmse(&low.mean(), &reference.mean());
        let e_high = warpray::converge::relmse(&high.mean(), &reference.mean());
        assert!(e_high < 0.5 * e_low, "{what}/{name}: relMSE {e_low:.5} -> {e_high:.5}");
    }
}

#[test]
fn cis_and_its_ablations_converge_to_bdpt_on_the_cornell_box() {
    converges(&cornell_box(), "cornell");
}

#[test]
fn cis_and_its_ablations_converge_to_bdpt_on_a_glossy_and_glass_scene() {
    converges(&glossy_glass_box(), "glossy+glass");
}

#[test]
fn cis_with_one_candidate_and_one_draw_is_uniform_lvc() {
    // N = M = 1: the single candidate is always drawn with weight 1, so the estimator is
    // uniform LVC with one connection. Same distribution: same mean, and the per-pixel
    // spread against a reference matches within sampling noise.
    let scene = cornell_box();
    let reference = film(&scene, &opts(IntegratorKind::Bdpt, 512, CisParams::default(), LvcParams::default()));
    let cis = CisParams { candidates: 1, draws: 1, ..small_pool(CisParams::default()) };
    let lvc = LvcParams { connections: 1, ..LvcParams::default() };
    let a = film(&scene, &opts(IntegratorKind::Cis, 32, cis, lvc));
    let b = film(&scene, &opts(IntegratorKind::Lvc, 32, cis, lvc));
    let (ma, mb) = (lum(a.image_mean()), lum(b.image_mean()));
    assert!((ma - mb).abs() / mb < 0.005, "means {ma} vs {mb}");
    let (ea, eb) = (
        warpray::converge::relmse(&a.mean(), &reference.mean()),
        warpray::converge::relmse(&b.mean(), &reference.mean()),
    );
    assert!((ea / eb - 1.0).abs() < 0.25, "error against the reference: CIS {ea:.5} vs LVC {eb:.5}");
}

#[test]
fn cis_is_deterministic_across_thread_counts_and_with_or_without_sorting() {
    let scene = glossy_glass_box();
    let run = |threads, sort| {
        let o =
            opts(IntegratorKind::Cis, 2, CisParams { sort, ..small_pool(CisParams::default()) }, LvcParams::default());
        rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap().install(|| film(&scene, &o))
    };
    let (a, b) = (run(1, true), run(2, true));
    assert!(a.sum == b.sum && a.splat == b.splat, "1 and 2 threads differ");
    // Sorting reorders the work, not the random numbers: the same image.
    let c = run(2, false);
    assert!(a.sum == c.sum, "sorting changed the image");
}

#[test]
fn sorting_by_material_raises_the_shading_kernels_simd_efficiency() {
    let scene = glossy_glass_box(); // diffuse, layered, rough glass, conductor, glossy
    let kinds: std::collections::HashSet<&str> = scene.materials.iter().map(|m| m.kind_name()).collect();
    assert!(kinds.len() >= 4, "{kinds:?}");
    let caster = BvhCaster::new(&scene);
    let (mut efficiency, mut whole) = (Vec::new(), Vec::new());
    for sort in [false, true] {
        let p = CisParams { sort, measure: true, pool: 1024, ..CisParams::default() };
        let o = opts(IntegratorKind::Cis, 1, p, LvcParams::default());
        let mut renderer = Renderer::new(&scene, &caster, &o).unwrap();
        let mut f = renderer.film().unwrap();
        renderer.pass(0, &mut f);
        let cis = renderer.cis().unwrap();
        let shade = cis.device().kernel_stats().into_iter().find(|k| k.name == "cis::shade").unwrap();
        let e = shade.regions.iter().find(|r| r.name == "shade").unwrap().simd_efficiency().unwrap();
        // The queue records saw the materials and the bounces.
        assert!(cis.records.iter().any(|r| r.queues.len() >= 3));
        assert!(cis.records.iter().all(|r| r.shade_simd.is_some()));
        efficiency.push(e);
        whole.push(shade.simd_efficiency().unwrap());
    }
    eprintln!(
        "cis::shade SIMD efficiency, dispatch region: unsorted {:.3}, sorted {:.3}",
        efficiency[0], efficiency[1]
    );
    eprintln!("cis::shade SIMD efficiency, whole kernel: unsorted {:.3}, sorted {:.3}", whole[0], whole[1]);
    assert!(efficiency[1] > efficiency[0] + 0.1, "sorted {:.3} vs unsorted {:.3}", efficiency[1], efficiency[0]);
    assert!(whole[1] > whole[0], "whole kernel: sorted {:.3} vs unsorted {:.3}", whole[1], whole[0]);
}
