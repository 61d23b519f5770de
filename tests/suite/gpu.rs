//! PDACRT's GPU twin (feature `cuda`). The tests that need a GPU are `#[ignore]`d with
//! the reason, so every run lists them as not run; on the GPU machine:
//!
//! ```text
//! sh cuda/build.sh && cargo test --release --features cuda --test gpu -- --include-ignored
//! ```
//!
//! There, a missing library or GPU fails the test rather than skipping it.
#![cfg(feature = "cuda")]

use glam::Vec3;
use warpray::cast::{BruteForce, RayCaster};
use warpray::error::Error;
use warpray::geometry::{Hit, Ray};
use warpray::gpu::GpuPdacrt;
use warpray::pdacrt::{Pdacrt, PdacrtParams};
use warpray::scene::{ObjOptions, Scene, cornell_box, load_obj};

#[test]
fn a_missing_library_is_a_typed_error_that_says_how_to_build_it() {
    let tris = cornell_box().triangle_vertices();
    let e = GpuPdacrt::with_library("/nonexistent/libwarpray_cuda.so", &tris, PdacrtParams::default())
        .err()
        .expect("no library there");
    match &e {
        Error::Gpu { library, msg } => {
            assert_eq!(library.to_str(), Some("/nonexistent/libwarpray_cuda.so"));
            assert!(msg.contains("cuda/build.sh") && msg.contains("WARPRAY_CUDA_LIB"), "{msg}");
        }
        other => panic!("expected Error::Gpu, got {other:?}"),
    }
    // A file that is not a shared library.
    let dir = std::env::temp_dir().join(format!("warpray-gpu-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let fake = dir.join("libwarpray_cuda.so");
    std::fs::write(&fake, b"not an ELF file").unwrap();
    let e = GpuPdacrt::with_library(&fake, &tris, PdacrtParams::default()).err().expect("not a library");
    assert!(matches!(&e, Error::Gpu { msg, .. } if msg.contains("cannot open")), "{e}");
    std::fs::remove_dir_all(&dir).ok();
}

fn gpu(scene: &Scene, params: PdacrtParams) -> GpuPdacrt {
    GpuPdacrt::new(&scene.triangle_vertices(), params).unwrap_or_else(|e| {
        panic!("\n\nTHIS TEST NEEDS AN NVIDIA GPU and the library from `sh cuda/build.sh`: {e}\n\n")
    })
}

/// Rays from random points in and around the box toward random points, plus the
/// awkward ones: zero direction, NaN origin, axis-parallel, in the plane of a wall.
fn rays(scene: &Scene, n: usize, seed: u64) -> Vec<Ray> {
    let b = scene.bounds();
    let (lo, hi) = (b.min - 0.2 * b.extent(), b.max + 0.2 * b.extent());
    let mut rng = crate::common::rng(seed);
    let mut out: Vec<Ray> = (0..n)
        .map(|_| {
            let o = crate::common::random_in_box(&mut rng, lo, hi);
            Ray::new(o, crate::common::random_in_box(&mut rng, b.min, b.max) - o)
        })
        .collect();
    out.push(Ray::new(b.center(), Vec3::ZERO));
    out.push(Ray::new(Vec3::new(f32::NAN, 0.0, 0.0), Vec3::X));
    out.push(Ray::new(b.center(), Vec3::X));
    out.push(Ray::new(Vec3::new(b.center().x, b.min.y, b.center().z), Vec3::Z));
    out.push(Ray::segment(b.center(), Vec3::Y, 1e-3));
    out
}

fn check_against_cpu(scene: &Scene, params: PdacrtParams, rays: &[Ray]) {
    let g = gpu(scene, params);
    let cpu = Pdacrt::from_triangles(&scene.triangle_vertices(), params);
    let brute = BruteForce::new(scene);
    let (mut gh, mut ch, mut bh) =
        (vec![Hit::MISS; rays.len()], vec![Hit::MISS; rays.len()], vec![Hit::MISS; rays.len()]);
    g.closest(rays, &mut gh);
    cpu.closest(rays, &mut ch);
    brute.closest(rays, &mut bh);
    let (mut go, mut co, mut bo) = (vec![false; rays.len()], vec![false; rays.len()], vec![false; rays.len()]);
    g.occluded(rays, &mut go);
    cpu.occluded(rays, &mut co);
    brute.occluded(rays, &mut bo);
    for i in 0..rays.len() {
        // The same kernels and rounding: the same key, bit for bit.
        assert_eq!((gh[i].t.to_bits(), gh[i].prim), (ch[i].t.to_bits(), ch[i].prim), "ray {i}: {:?}", rays[i]);
        assert_eq!(gh[i].is_hit(), bh[i].is_hit(), "ray {i} against brute force: {:?}", rays[i]);
        if bh[i].is_hit() {
            assert!((gh[i].t - bh[i].t).abs() <= 1e-5 * bh[i].t.max(1.0), "ray {i}: {} vs {}", gh[i].t, bh[i].t);
        }
        assert_eq!(go[i], co[i], "ray {i} occlusion");
        assert_eq!(go[i], bo[i], "ray {i} occlusion against brute force");
    }
    assert!(g.last_stats().levels > 0 && g.last_stats().tests > 0);
}

#[test]
#[ignore = "needs an NVIDIA GPU and target/cuda/libwarpray_cuda.so (sh cuda/build.sh); run with --include-ignored"]
fn gpu_keys_equal_the_emulators_and_brute_force_on_the_cornell_box() {
    let scene = cornell_box();
    let rays = rays(&scene, 20_000, 1);
    check_against_cpu(&scene, PdacrtParams::default(), &rays);
    // Several chunks and a small leaf: more levels, more terminal nodes.
    let p = PdacrtParams { chunk_rays: 3_000, leaf_rays: 8, leaf_triangles: 2, ..Default::default() };
    check_against_cpu(&scene, p, &rays);
}

#[test]
#[ignore = "needs an NVIDIA GPU, target/cuda/libwarpray_cuda.so and the bunny model; run with --include-ignored"]
fn gpu_keys_equal_the_emulators_on_the_bunny() {
    let scene = load_obj(crate::common::require_model("bunny"), &ObjOptions::default()).unwrap();
    let b = warpray::cast::batches::batches(&scene, 128, 128, 1, 1);
    let mut rays = b.primary;
    rays.extend(b.ambient);
    rays.extend(b.shadow);
    check_against_cpu(&scene, PdacrtParams::default(), &rays);
}
