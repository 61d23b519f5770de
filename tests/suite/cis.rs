//! CIS-LBDPT: agreement with BDPT over independent seeds with every idea on and each switched off,
//! its relation to uniform LVC, determinism, and what sorting does to SIMD efficiency.

use crate::common::*;
use crate::reference::{self, TestBox};
use crate::seeds::{assert_agree, runs};
use warpray::cast::BvhCaster;
use warpray::converge::relmse;
use warpray::film::Film;
use warpray::render::CisParams;
use warpray::render::{Budget, IntegratorKind, LvcParams, RenderOptions, Renderer, render};
use warpray::scene::{Scene, cornell_box};

fn opts(kind: IntegratorKind, spp: u32, cis: CisParams, lvc: LvcParams, seed: u64) -> RenderOptions {
    RenderOptions {
        width: 32,
        height: 32,
        budget: Budget::Samples(spp),
        max_depth: 8,
        integrator: kind,
        seed,
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

fn small_pool(p: CisParams) -> CisParams {
    // A pool smaller than the image, so regeneration really happens.
    CisParams { pool: 300, ..p }
}

/// The ablations that change the estimate's distribution. Sorting and compaction
/// reorder the work, not the random numbers:
/// `cis_is_deterministic_across_thread_counts_with_or_without_sorting_and_compaction`
/// checks that their images are the same to the bit, so they need no statistics.
fn variants() -> Vec<(&'static str, CisParams)> {
    let d = small_pool(CisParams::default());
    vec![
        ("all on", d),
        ("no importance sampling", CisParams { importance: false, ..d }),
        ("four passes per iteration", CisParams { samples_per_iteration: 4, ..d }),
    ]
}

/// CIS with every idea on, each switched off, and with four camera passes sharing each
/// light pass (the six passes end inside an iteration) agrees with BDPT (the shared reference,
/// `reference.rs`) over 16 seeds each, in the image mean (to a precision that shows a
/// 1 % bias: 0.18 %) and block by block.
fn converges(which: TestBox, what: &str) {
    let (scene, bdpt) = (&which.scene(), reference::bdpt(which));
    for (name, p) in variants() {
        let cis = runs(name, 300, 32, 8, |seed| {
            film(scene, &opts(IntegratorKind::Cis, 6, p, LvcParams::default(), seed)).mean()
        });
        eprintln!("{what}: {}", assert_agree(&cis, &bdpt, 0.0018));
    }
}

#[test]
fn cis_and_its_ablations_converge_to_bdpt_on_the_cornell_box() {
    converges(TestBox::Cornell, "cornell");
}

#[test]
fn cis_with_one_candidate_and_one_draw_is_uniform_lvc() {
    // N = M = 1: the single candidate is always drawn with weight 1, so the estimator is
    // uniform LVC with one connection. Same distribution: the same limit (over 16 seeds
    // each), and the same per-pixel spread against a BDPT average within sampling noise.
    let scene = cornell_box();
    let cis = CisParams { candidates: 1, draws: 1, ..small_pool(CisParams::default()) };
    let lvc = LvcParams { connections: 1, ..LvcParams::default() };
    let a = runs("cis N=M=1", 300, 32, 8, |seed| film(&scene, &opts(IntegratorKind::Cis, 6, cis, lvc, seed)).mean());
    let b =
        runs("lvc 1 connection", 500, 32, 8, |seed| film(&scene, &opts(IntegratorKind::Lvc, 6, cis, lvc, seed)).mean());
    eprintln!("{}", assert_agree(&a, &b, 0.0018));
    let reference = &reference::bdpt(TestBox::Cornell).average;
    let (ea, eb) = (relmse(&a.first, reference), relmse(&b.first, reference));
    assert!((ea / eb - 1.0).abs() < 0.25, "error against the reference: CIS {ea:.5} vs LVC {eb:.5}");
}

#[test]
fn cis_is_deterministic_across_thread_counts_with_or_without_sorting_compaction_or_measurement() {
    let scene = glossy_glass_box();
    let run_measured = |threads, sort, regenerate, measure| {
        let o = opts(
            IntegratorKind::Cis,
            2,
            CisParams { sort, regenerate, measure, ..small_pool(CisParams::default()) },
            LvcParams::default(),
            13,
        );
        rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap().install(|| film(&scene, &o))
    };
    let run = |threads, sort, regenerate| run_measured(threads, sort, regenerate, false);
    let (a, b) = (run(1, true, true), run(2, true, true));
    assert!(a.sum == b.sum && a.splat == b.splat, "1 and 2 threads differ");
    // Sorting and compaction reorder the work, not the random numbers: the same image.
    let c = run(2, false, true);
    assert!(a.sum == c.sum && a.splat == c.splat, "sorting changed the image");
    let d = run(2, true, false);
    assert!(a.sum == d.sum && a.splat == d.splat, "compaction changed the image");
    // A measured launch evaluates every MIS density where a weight needs it, as the
    // CUDA twin does; an unmeasured one reads the camera subpath's densities evaluated
    // once per vertex: the same weights, bit for bit.
    let e = run_measured(2, true, true, true);
    assert!(a.sum == e.sum && a.splat == e.splat, "measurement changed the image");
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
        let o = opts(IntegratorKind::Cis, 1, p, LvcParams::default(), 13);
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

/// The heavy tier (README, docs/testing.md): tests that need many samples for their
/// power, run by CI and before a release rather than before every commit.
mod heavy {
    use super::*;

    #[test]
    #[ignore = "heavy tier, run by CI: cargo test --profile suite --workspace --features inspector,cuda,embree --test suite -- --ignored ::heavy::"]
    fn cis_and_its_ablations_converge_to_bdpt_on_a_glossy_and_glass_scene() {
        converges(TestBox::GlossyGlass, "glossy+glass");
    }
}
