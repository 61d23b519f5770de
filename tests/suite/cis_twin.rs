//! CIS-LBDPT's GPU twin (`cuda/cis.cu`, feature `cuda`) against the emulator, bounce by
//! bounce, on the inputs a render captured: every sample's slot, new vertex and pending
//! contributions, and the compacted list.
//!
//! The port (`cuda/cis_device.cuh`) is checked in every run without a GPU: the test
//! builds it for the CPU with `g++` (`cuda/cis_host_check.cpp`), where the maths library
//! is the Rust build's, so every sample must agree. The GPU test is `#[ignore]`d with the
//! reason; on the GPU machine run it with `--include-ignored` after `sh cuda/build.sh`
//! (there a few samples may take another branch: CUDA's sin, cos and exp round
//! differently from glibc's).
#![cfg(feature = "cuda")]

use super::common::host_library;
use std::path::Path;
use warpray::render::{Budget, IntegratorKind, RenderOptions};
use warpray::scene::load_scene;

/// Per bounce: (samples, samples that differ, compacted list equal).
fn twin_bounces(library: &Path, scene: &str, sorted: bool) -> Vec<(usize, usize, bool)> {
    // Paths from the package root, where cargo runs tests (and the GPU machine's runs).
    let scene = load_scene(scene).unwrap().scene;
    let caster = warpray::cast::BvhCaster::new(&scene);
    let mut opts = RenderOptions {
        width: 48,
        height: 48,
        budget: Budget::Samples(1),
        integrator: IntegratorKind::Cis,
        max_depth: 8,
        ..Default::default()
    };
    opts.cis.sort = sorted;
    let checks = warpray::gpu::check_render(library, &scene, &caster, &opts)
        .unwrap_or_else(|e| panic!("\n\nTHIS TEST NEEDS the twin library {}: {e}\n\n", library.display()));
    assert!(checks.len() >= 3, "the render made {} bounces", checks.len());
    checks
        .into_iter()
        .map(|c| {
            if let Some(f) = &c.shade.first {
                eprintln!("bounce {}: {} of {} differ; first: {f}", c.bounce, c.shade.differ, c.shade.lanes);
            }
            (c.shade.lanes, c.shade.differ, c.compaction_same)
        })
        .collect()
}

#[test]
fn the_ported_shading_and_compaction_agree_with_the_emulator_on_the_cpu() {
    let lib = host_library();
    // Diffuse walls and lights; every material kind and layered stacks; a window-lit room.
    for scene in ["cornell", "assets/scenes/materials.toml", "assets/scenes/white-room.toml"] {
        for sorted in [true, false] {
            for (b, (lanes, differ, same)) in twin_bounces(&lib, scene, sorted).into_iter().enumerate() {
                assert_eq!(differ, 0, "{scene} sorted={sorted} bounce {b}: {differ} of {lanes} samples differ");
                assert!(same, "{scene} sorted={sorted} bounce {b}: the compacted lists differ");
            }
        }
    }
}

#[test]
#[ignore = "needs an NVIDIA GPU and target/cuda/libwarpray_cuda.so (sh cuda/build.sh); run with --include-ignored"]
fn the_gpu_shading_and_compaction_agree_with_the_emulator() {
    let lib = warpray::gpu::library_path();
    for scene in ["cornell", "assets/scenes/materials.toml", "assets/scenes/bedroom.toml"] {
        for sorted in [true, false] {
            for (b, (lanes, differ, same)) in twin_bounces(&lib, scene, sorted).into_iter().enumerate() {
                // CUDA's transcendental functions round differently: allow 1 % of samples.
                assert!(differ * 100 <= lanes, "{scene} sorted={sorted} bounce {b}: {differ} of {lanes} differ");
                assert!(same, "{scene} sorted={sorted} bounce {b}: the compacted lists differ");
            }
        }
    }
}
