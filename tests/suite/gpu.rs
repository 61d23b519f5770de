//! PDACRT's GPU twin and the GPU BVH baseline (feature `cuda`). The tests that need a GPU are `#[ignore]`d with
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
use warpray::gpu::{GpuBvh, GpuPdacrt};
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
    same_hits_as_cpu(&g, &scene.triangle_vertices(), params, rays);
    assert!(g.last_stats().levels > 0 && g.last_stats().tests > 0);
}

/// `g`'s closest hits equal the CPU PDACRT's bit for bit (the same triangle test and
/// key rule decide them) and brute force's to rounding; occlusion equals both.
fn same_hits_as_cpu(g: &dyn RayCaster, tris: &[[Vec3; 3]], params: PdacrtParams, rays: &[Ray]) {
    let cpu = Pdacrt::from_triangles(tris, params);
    let brute = BruteForce::from_triangles(tris.to_vec());
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
        assert_eq!(
            (gh[i].t.to_bits(), gh[i].prim),
            (ch[i].t.to_bits(), ch[i].prim),
            "{}, ray {i}: {:?}",
            g.name(),
            rays[i]
        );
        assert_eq!(gh[i].is_hit(), bh[i].is_hit(), "ray {i} against brute force: {:?}", rays[i]);
        if bh[i].is_hit() {
            assert!((gh[i].t - bh[i].t).abs() <= 1e-5 * bh[i].t.max(1.0), "ray {i}: {} vs {}", gh[i].t, bh[i].t);
        }
        assert_eq!(go[i], co[i], "ray {i} occlusion");
        assert_eq!(go[i], bo[i], "ray {i} occlusion against brute force");
    }
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

fn gpu_bvh(tris: &[[Vec3; 3]]) -> GpuBvh {
    GpuBvh::new(tris).unwrap_or_else(|e| {
        panic!("\n\nTHIS TEST NEEDS AN NVIDIA GPU and the library from `sh cuda/build.sh`: {e}\n\n")
    })
}

#[test]
fn the_gpu_bvh_without_its_library_is_a_typed_error() {
    let tris = cornell_box().triangle_vertices();
    let e = GpuBvh::with_library("/nonexistent/libwarpray_cuda.so", &tris).err().expect("no library there");
    assert!(matches!(&e, Error::Gpu { msg, .. } if msg.contains("cuda/build.sh")), "{e}");
}

#[test]
#[ignore = "needs an NVIDIA GPU and target/cuda/libwarpray_cuda.so (sh cuda/build.sh); run with --include-ignored"]
fn gpu_bvh_hits_equal_pdacrts_and_brute_force_on_the_cornell_box() {
    let scene = cornell_box();
    let tris = scene.triangle_vertices();
    let g = gpu_bvh(&tris);
    let built = g.last_build();
    assert_eq!(built.nodes as usize, tris.len() - 1);
    assert!(built.build_ms > 0.0 && built.bytes > 0, "{built:?}");
    let mut probe = rays(&scene, 20_000, 1);
    probe.extend(crate::common::rays_at_corners(&scene, &mut crate::common::rng(3)));
    same_hits_as_cpu(&g, &tris, PdacrtParams::default(), &probe);
    let t = g.last_trace();
    assert!(t.tests > 0 && t.visits > 0 && t.trace_ms > 0.0, "{t:?}");
}

#[test]
#[ignore = "needs an NVIDIA GPU and target/cuda/libwarpray_cuda.so (sh cuda/build.sh); run with --include-ignored"]
fn gpu_casters_take_each_frame_of_the_waving_grid_and_tiny_scenes() {
    use warpray::cast::batches::{primary_rays, waving_grid, waving_grid_camera, waving_grid_shadow_rays};
    let mut g = gpu_bvh(&waving_grid(48, -0.25));
    let mut p = GpuPdacrt::new(&waving_grid(48, -0.25), PdacrtParams::default()).unwrap();
    let primary = primary_rays(&waving_grid_camera(), 96, 96);
    for frame in 0..3 {
        let tris = waving_grid(48, frame as f32 * 0.25);
        g.rebuild(&tris).unwrap();
        p.set_triangles(&tris).unwrap();
        let mut hits = vec![Hit::MISS; primary.len()];
        BruteForce::from_triangles(tris.clone()).closest(&primary, &mut hits);
        assert!(hits.iter().filter(|h| h.is_hit()).count() > primary.len() / 2, "the grid fills the view");
        let mut rays = primary.clone();
        rays.extend(waving_grid_shadow_rays(&tris, &primary, &hits));
        same_hits_as_cpu(&g, &tris, PdacrtParams::default(), &rays);
        same_hits_as_cpu(&p, &tris, PdacrtParams::default(), &rays);
    }
    // No triangle, one, two, a stack of nearly coincident ones, and copies of one
    // (equal Morton codes: the index breaks the tie; equal distances: the smallest id).
    let one = [Vec3::new(-1.0, -1.0, 1.0), Vec3::new(1.0, -1.0, 1.0), Vec3::new(0.0, 1.0, 1.0)];
    let stacked: Vec<[Vec3; 3]> = (0..300).map(|k| one.map(|p| p + Vec3::new(0.0, 0.0, k as f32 * 1e-3))).collect();
    let scene = cornell_box();
    let probe = rays(&scene, 2_000, 2);
    let front: Vec<Ray> = (0..500)
        .map(|k| Ray::new(Vec3::new(-0.5 + k as f32 / 500.0, -0.2, -1.0), Vec3::Z))
        .chain(probe.iter().copied())
        .collect();
    for tris in [vec![], vec![one], vec![one, one.map(|p| p * 0.5)], stacked, vec![one; 100]] {
        g.rebuild(&tris).unwrap();
        same_hits_as_cpu(&g, &tris, PdacrtParams::default(), &front);
    }
}

#[test]
#[ignore = "needs an NVIDIA GPU, target/cuda/libwarpray_cuda.so and the bunny model; run with --include-ignored"]
fn gpu_bvh_hits_equal_pdacrts_on_the_bunny_batches() {
    let scene = load_obj(crate::common::require_model("bunny"), &ObjOptions::default()).unwrap();
    let b = warpray::cast::batches::batches(&scene, 128, 128, 1, 1);
    let mut rays = b.primary;
    rays.extend(b.ambient);
    rays.extend(b.specular);
    rays.extend(b.shadow);
    rays.extend(crate::common::rays_at_corners(&scene, &mut crate::common::rng(4)).into_iter().step_by(7));
    let tris = scene.triangle_vertices();
    same_hits_as_cpu(&gpu_bvh(&tris), &tris, PdacrtParams::default(), &rays);
}
