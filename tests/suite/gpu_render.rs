//! Whole renders on the GPU (`cuda/render.cu`, feature `cuda`): CIS-LBDPT's stream and the
//! LVC-BDPT megakernels against the CPU integrators they port.
//!
//! The port is checked in every run without a GPU: the test builds it for the CPU with
//! `g++` (`cuda/cis_host_check.cpp`, brute force in place of the GPU BVH, glibc's maths as
//! in the Rust build), where it draws the same random numbers in the same order as the
//! CPU integrators and so must give their image pixel for pixel, up to rounding. The GPU
//! test is `#[ignore]`d with the reason; on the GPU machine run it with
//! `--include-ignored` after `sh cuda/build.sh`: there CUDA's sin, cos and exp round
//! differently, so a few paths take other branches and the images agree in their means.
#![cfg(feature = "cuda")]

use super::common::host_library;
use std::path::Path;
use warpray::glam::Vec3;
use warpray::gpu::GpuRender;
use warpray::render::{Budget, RenderOptions, Renderer, Variant};
use warpray::scene::{Scene, load_scene};

/// `passes` passes of `variant`, `per_iteration` of them per iteration, on the CPU (BVH
/// caster) and through the library's port.
fn both(
    lib: &Path,
    scene: &Scene,
    variant: &str,
    opts: RenderOptions,
    (passes, per_iteration): (u32, u32),
) -> (Vec<Vec3>, Vec<Vec3>) {
    let mut opts = Variant::parse(variant).unwrap().apply(RenderOptions { budget: Budget::Samples(passes), ..opts });
    opts.set_samples_per_iteration(per_iteration);
    let caster = warpray::cast::BvhCaster::new(scene);
    let mut r = Renderer::new(scene, &caster, &opts).unwrap();
    let mut cpu = r.film().unwrap();
    r.passes(0, passes, &mut cpu);
    let mut gpu_render = GpuRender::with_library(lib, scene, &opts)
        .unwrap_or_else(|e| panic!("\n\nTHIS TEST NEEDS the library {}: {e}\n\n", lib.display()));
    let mut gpu = r.film().unwrap();
    for pass in 0..passes {
        gpu_render.render_pass(pass, &mut gpu).unwrap();
    }
    (cpu.mean(), gpu.mean())
}

/// Pixels that differ by more than `rel` of their value (plus a floor), and the
/// relative difference of the image means.
fn compare(a: &[Vec3], b: &[Vec3], rel: f32) -> (usize, f64) {
    let differ =
        a.iter().zip(b).filter(|(x, y)| (**x - **y).abs().max_element() > rel * (x.max_element() + 1e-3)).count();
    let mean = |v: &[Vec3]| v.iter().map(|p| (p.x + p.y + p.z) as f64).sum::<f64>() / v.len() as f64;
    (differ, (mean(b) - mean(a)) / mean(a))
}

#[test]
fn the_ported_renders_give_the_cpu_images_on_the_cpu() {
    let lib = host_library();
    let opts = RenderOptions { width: 24, height: 18, seed: 5, max_depth: 6, ..Default::default() };
    let variants = ["lvc-mk", "cis", "cis-nosort", "cis-nois", "cis-nocompact"];
    // Two passes of one iteration each; and five passes, three per iteration (a light
    // pass shared, its splats divided, the last iteration unfinished).
    let cases = [("cornell", 1, 2, &variants[..]), ("assets/scenes/materials.toml", 1, 2, &variants[..])];
    let shared = [("cornell", 3, 5, &variants[..3]), ("assets/scenes/materials.toml", 3, 5, &variants[..2])];
    for (scene, per_iteration, passes, variants) in cases.into_iter().chain(shared) {
        let s = load_scene(scene).unwrap().scene;
        for variant in variants {
            let mut o = opts.clone();
            o.cis.pool = 100; // several regenerations per pass
            let (cpu, gpu) = both(&lib, &s, variant, o, (passes, per_iteration));
            let (differ, mean) = compare(&cpu, &gpu, 1e-4);
            let what = format!("{scene} {variant}, {per_iteration} per iteration");
            eprintln!("{what}: {differ} of {} pixels differ, means {mean:+.2e}", cpu.len());
            assert!(cpu.iter().any(|p| p.max_element() > 0.0), "{what}: a black image");
            assert_eq!(differ, 0, "{what}: {differ} pixels differ (means {mean:+.2e})");
        }
    }
}

#[test]
#[ignore = "needs an NVIDIA GPU and target/cuda/libwarpray_cuda.so (sh cuda/build.sh); run with --include-ignored"]
fn the_gpu_renders_agree_with_the_cpu_integrators() {
    let lib = warpray::gpu::library_path();
    let opts = RenderOptions { width: 64, height: 48, seed: 5, max_depth: 8, ..Default::default() };
    for scene in ["cornell", "assets/scenes/materials.toml", "assets/scenes/bedroom.toml"] {
        let s = load_scene(scene).unwrap().scene;
        for (variant, shape) in
            [("lvc-mk", (4, 1)), ("cis", (4, 1)), ("cis-nosort", (4, 1)), ("lvc-mk", (6, 4)), ("cis", (6, 4))]
        {
            let (cpu, gpu) = both(&lib, &s, variant, opts.clone(), shape);
            let (differ, mean) = compare(&cpu, &gpu, 1e-4);
            let what = format!("{scene} {variant}, {} per iteration", shape.1);
            eprintln!("{what}: {differ} of {} pixels differ, means {mean:+.2e}", cpu.len());
            // CUDA's sin, cos and exp send a few paths another way: most pixels agree
            // to rounding, and the image means within a percent.
            assert!(differ * 10 <= cpu.len(), "{what}: {differ} of {} pixels differ", cpu.len());
            assert!(mean.abs() < 0.01, "{what}: image means differ by {mean:+.2e}");
        }
    }
}

#[test]
fn settings_the_gpu_renders_cannot_render_are_refused_with_the_reason() {
    use warpray::filter::{Filter, FilterMode};
    let s = load_scene("cornell").unwrap().scene;
    let lib = host_library();
    let base = RenderOptions { width: 8, height: 8, ..Default::default() };
    let refused = |opts: RenderOptions, scene: &Scene| match GpuRender::with_library(&lib, scene, &opts) {
        Ok(_) => panic!("accepted {:?}", opts.integrator),
        Err(e) => e.to_string(),
    };
    let e = refused(Variant::parse("bdpt").unwrap().apply(base.clone()), &s);
    assert!(e.contains("not bdpt"), "{e}");
    let gaussian =
        RenderOptions { filter: Filter::mitsuba_gaussian(), ..Variant::parse("cis").unwrap().apply(base.clone()) };
    assert!(refused(gaussian.clone(), &s).contains("box filter"));
    // Splatted, any filter is fine.
    GpuRender::with_library(&lib, &s, &RenderOptions { filter_mode: FilterMode::Splat, ..gaussian }).unwrap();
    let mut lens = s.clone();
    lens.camera.aperture_radius = 0.1;
    assert!(refused(Variant::parse("lvc-mk").unwrap().apply(base.clone()), &lens).contains("pinhole"));
    // A film of another size than the render's.
    let mut r = GpuRender::with_library(&lib, &s, &Variant::parse("cis").unwrap().apply(base.clone())).unwrap();
    let mut small = warpray::film::Film::new(4, 4).unwrap();
    assert!(r.render_pass(0, &mut small).unwrap_err().to_string().contains("the film 4x4"));
    let plastic = load_scene("assets/scenes/bsdf/plastic.xml").unwrap().scene;
    assert!(refused(Variant::parse("cis").unwrap().apply(base), &plastic).contains("plastic"));
}

#[test]
fn the_command_line_renders_on_the_gpu_and_refuses_what_it_cannot() {
    let dir = std::env::temp_dir().join(format!("warpray-gpu-cli-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let out = dir.join("gpu.exr");
    let run = |args: &[&str]| {
        std::process::Command::new(env!("CARGO_BIN_EXE_warpray"))
            .args(args)
            .env("WARPRAY_CUDA_LIB", host_library())
            .output()
            .unwrap()
    };
    let ok = run(&[
        "render",
        "--gpu",
        "--integrator",
        "lvc-mk",
        "--spp",
        "2",
        "--spp-per-iteration",
        "2",
        "--size",
        "16x12",
        "-q",
        "-o",
    ]
    .iter()
    .copied()
    .chain([out.to_str().unwrap()])
    .collect::<Vec<_>>());
    let stdout = String::from_utf8_lossy(&ok.stdout);
    assert!(
        ok.status.success() && stdout.contains("2 spp, lvc-mk on the GPU"),
        "{stdout}{}",
        String::from_utf8_lossy(&ok.stderr)
    );
    assert!(out.is_file());
    let refused = run(&["render", "--gpu", "--integrator", "bdpt", "--spp", "1", "--size", "8x8", "-q", "-o", "x.png"]);
    let err = String::from_utf8_lossy(&refused.stderr);
    assert!(!refused.status.success() && err.contains("not bdpt"), "{err}");
    assert!(!std::path::Path::new("x.png").exists());
    std::fs::remove_dir_all(dir).ok();
}
