//! Helpers shared by the integration tests.
#![allow(dead_code)]

use std::path::PathBuf;
use warpray::cast::RayCaster;
use warpray::geometry::{Hit, Ray};
use warpray::glam::Vec3;
use warpray::sampling::{Rng, uniform_sphere};
use warpray::scene::{Coat, LayerBase, Layered, Material, Scene, cornell_box, find_model, metals, models_dir};

/// The path of a standard model. A test that needs a model which is not there fails
/// loudly, naming the folder and the variable to set: it never passes silently.
pub fn require_model(stem: &str) -> PathBuf {
    match find_model(stem) {
        Some(p) => p,
        None => panic!(
            "\n\n*** MODEL MISSING: '{stem}' was not found in {} ***\n\
             Set WARPRAY_MODELS to the folder holding the standard models \
             (CI uses WARPRAY_MODELS=../shared/models).\n",
            models_dir().display()
        ),
    }
}

/// A deterministic stream for test data.
pub fn rng(seed: u64) -> Rng {
    Rng::for_sample(seed, 0xdead_beef, 7)
}

pub fn random_in_box(rng: &mut Rng, min: Vec3, max: Vec3) -> Vec3 {
    min + (max - min) * Vec3::new(rng.uniform(), rng.uniform(), rng.uniform())
}

pub fn random_dir(rng: &mut Rng) -> Vec3 {
    uniform_sphere(rng.uniform2())
}

/// A scene made of the given triangles, one diffuse material, no lights.
pub fn scene_from_triangles(tris: &[[Vec3; 3]]) -> Scene {
    let mut s = Scene::empty("<test>");
    for t in tris {
        let base = s.positions.len() as u32;
        s.positions.extend_from_slice(t);
        s.triangles.push([base, base + 1, base + 2]);
        s.material_of.push(0);
    }
    s.add_material("default", Material::DEFAULT, Vec3::ZERO);
    s
}

/// An `n × n` grid of unit quads in z = 0 (two triangles each): split planes of the
/// divide-and-conquer casters and BVH node faces fall on its grid lines.
pub fn quad_grid(n: u32) -> Vec<[Vec3; 3]> {
    let mut tris = Vec::new();
    for i in 0..n {
        for j in 0..n {
            let (x, y) = (i as f32, j as f32);
            let q = [
                Vec3::new(x, y, 0.0),
                Vec3::new(x + 1.0, y, 0.0),
                Vec3::new(x + 1.0, y + 1.0, 0.0),
                Vec3::new(x, y + 1.0, 0.0),
            ];
            tris.push([q[0], q[1], q[2]]);
            tris.push([q[0], q[2], q[3]]);
        }
    }
    tris
}

/// An icosphere of radius 1 with shared (indexed) vertices: a closed mesh.
pub fn icosphere(subdivisions: u32) -> (Vec<Vec3>, Vec<[u32; 3]>) {
    warpray::geometry::icosphere(subdivisions)
}

/// The Cornell box with glossy, metallic, layered and rough-glass surfaces (no delta
/// lobes, so light tracing can see every path too).
pub fn glossy_glass_box() -> Scene {
    let mut s = cornell_box();
    let set = |s: &mut Scene, name: &str, m: Material| {
        let i = s.material_names.iter().position(|n| n == name).unwrap();
        s.materials[i] = m;
    };
    set(&mut s, "shortBlock", Material::RoughGlass { ior: 1.5, roughness: 0.3, tint: Vec3::new(0.95, 0.97, 1.0) });
    let (eta, k) = metals::GOLD;
    set(&mut s, "tallBlock", Material::Conductor { eta, k, roughness: 0.35 });
    let paint = Layered {
        coats: [Coat { ior: 1.5, roughness: 0.3, absorption: Vec3::ZERO }; 2],
        coat_count: 1,
        base: LayerBase::Diffuse { albedo: Vec3::new(0.725, 0.71, 0.68) },
    };
    set(&mut s, "white", Material::Layered(paint));
    set(
        &mut s,
        "green",
        Material::Glossy { diffuse: Vec3::new(0.1, 0.35, 0.07), specular: Vec3::splat(0.3), roughness: 0.4 },
    );
    s
}

/// (mean, standard error of the mean) of per-seed values.
pub fn statistics(means: &[f64]) -> (f64, f64) {
    let n = means.len() as f64;
    let mean = means.iter().sum::<f64>() / n;
    let var = means.iter().map(|m| (m - mean).powi(2)).sum::<f64>() / (n - 1.0);
    (mean, (var / n).sqrt())
}

/// Every caster finds what the oracle finds on every ray: a hit or none, the same
/// distance (relative 1e-5; ties at one distance may name different triangles), and
/// the same barycentrics where the triangle is the same.
pub fn assert_closest_agree(oracle: &dyn RayCaster, casters: &[Box<dyn RayCaster + '_>], rays: &[Ray], what: &str) {
    let mut want = vec![Hit::MISS; rays.len()];
    oracle.closest(rays, &mut want);
    for c in casters {
        let mut got = vec![Hit::MISS; rays.len()];
        c.closest(rays, &mut got);
        for (i, (w, g)) in want.iter().zip(&got).enumerate() {
            assert_eq!(w.is_hit(), g.is_hit(), "{what}/{}: ray {i} {:?}: {w:?} vs {g:?}", c.name(), rays[i]);
            if w.is_hit() {
                let rel = (w.t - g.t).abs() / w.t.abs().max(1e-30);
                assert!(rel <= 1e-5, "{what}/{}: ray {i}: t {} vs {}", c.name(), w.t, g.t);
                if w.prim == g.prim {
                    assert!((w.u - g.u).abs() < 1e-5 && (w.v - g.v).abs() < 1e-5);
                }
            }
        }
    }
}

/// The rays of a batch that an oracle too slow for the whole batch is asked about, in
/// order: every ray on which two of `results` disagree (a hit against a miss, another
/// triangle, or distances apart by more than 1e-6 relative), every ray whose first
/// result lies within 1e-3 of a triangle edge in barycentrics (where ties and the
/// edge rules decide), and every `stride`-th ray, a uniform sample.
pub fn rays_worth_an_oracle(results: &[&[Hit]], stride: usize) -> Vec<usize> {
    let n = results[0].len();
    (0..n)
        .filter(|&i| {
            let first = results[0][i];
            let disagree = results[1..].iter().any(|r| {
                let h = r[i];
                h.is_hit() != first.is_hit()
                    || (h.is_hit() && (h.prim != first.prim || (h.t - first.t).abs() > 1e-6 * first.t.abs()))
            });
            let near_edge = first.is_hit() && first.u.min(first.v).min(1.0 - first.u - first.v) < 1e-3;
            disagree || near_edge || i % stride == 0
        })
        .collect()
}

/// Every caster answers every shadow ray as the oracle does.
pub fn assert_occluded_agree(oracle: &dyn RayCaster, casters: &[Box<dyn RayCaster + '_>], rays: &[Ray], what: &str) {
    let mut want = vec![false; rays.len()];
    oracle.occluded(rays, &mut want);
    for c in casters {
        let mut got = vec![false; rays.len()];
        c.occluded(rays, &mut got);
        let diff: Vec<usize> = (0..rays.len()).filter(|&i| want[i] != got[i]).collect();
        assert!(diff.is_empty(), "{what}/{}: {} disagreements, first ray {:?}", c.name(), diff.len(), rays[diff[0]]);
    }
}

/// `n` rays from random points in the scene's box (padded by half its size) toward
/// random points inside it.
pub fn rays_through(scene: &Scene, r: &mut Rng, n: usize) -> Vec<Ray> {
    let b = scene.bounds();
    let pad = b.extent().max(Vec3::splat(1.0)) * 0.5;
    (0..n)
        .map(|_| {
            let o = random_in_box(r, b.min - pad, b.max + pad);
            Ray::new(o, (random_in_box(r, b.min, b.max) - o).normalize_or(Vec3::X))
        })
        .collect()
}

/// The small render on which casters are compared: 12×12 pixels, 2 samples, seed 3.
pub fn small_render(integrator: warpray::render::IntegratorKind) -> warpray::render::RenderOptions {
    warpray::render::RenderOptions {
        width: 12,
        height: 12,
        budget: warpray::render::Budget::Samples(2),
        integrator,
        seed: 3,
        ..Default::default()
    }
}

/// Rays from random points around the scene aimed exactly at its triangles' corners and
/// edge midpoints, where several triangles are hit at one distance and the smallest id
/// must win: a caster that culls a box at the best distance itself loses some of these.
pub fn rays_at_corners(scene: &Scene, rng: &mut Rng) -> Vec<Ray> {
    let b = scene.bounds();
    let (lo, hi) = (b.min - 0.5 * b.extent(), b.max + 0.5 * b.extent());
    scene
        .triangle_vertices()
        .iter()
        .flat_map(|&[a, b, c]| [a, b, c, (a + b) * 0.5, (b + c) * 0.5, (c + a) * 0.5])
        .map(|target| {
            let o = random_in_box(rng, lo, hi);
            Ray::new(o, target - o)
        })
        .collect()
}

/// The CUDA twins built for the CPU (`cuda/cis_host_check.cpp`, the device code compiled
/// by g++ behind the library's C interface), once per test process.
pub fn host_library() -> PathBuf {
    static LIB: std::sync::OnceLock<PathBuf> = std::sync::OnceLock::new();
    LIB.get_or_init(|| {
        let dir = std::env::temp_dir().join(format!("warpray-cuda-host-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let lib = dir.join("libwarpray_cuda_host.so");
        let status = std::process::Command::new("g++")
            .args(["-std=c++17", "-O2", "-ffp-contract=off", "-shared", "-fPIC", "-o"])
            .arg(&lib)
            .arg("cuda/cis_host_check.cpp")
            .status()
            .unwrap_or_else(|e| {
                panic!("\n\nTHIS TEST NEEDS g++ (a C++17 compiler) to build cuda/cis_host_check.cpp: {e}\n\n")
            });
        assert!(status.success(), "g++ failed on cuda/cis_host_check.cpp");
        lib
    })
    .clone()
}
