//! Caster throughput: BVH build, closest-hit and shadow batches of primary rays for the
//! BVH, serial DACRT and PDACRT, Embree's two settings with the cargo feature `embree`
//! (build and trace apart), and the brute-force oracle for scale. The paper's full
//! tables come from `examples/dacrt_tables.rs`.
//! `cargo bench --features embree --bench casters`.
//! The bunny needs `WARPRAY_MODELS`; without it that group is skipped with a notice.

use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use std::hint::black_box;
#[cfg(feature = "embree")]
use warpray::cast::embree::{EmbreeCaster, EmbreeParams};
use warpray::prelude::*;

fn bench_scene(c: &mut Criterion, name: &str, scene: &Scene, with_brute: bool) {
    let rays = warpray::cast::batches::primary_rays(&scene.camera, 256, 256);
    let mut g = c.benchmark_group(format!("cast/{name}"));
    g.sample_size(10);
    g.throughput(Throughput::Elements(rays.len() as u64));
    let tris = scene.triangle_vertices();
    g.bench_function("bvh_build", |b| b.iter(|| BvhCaster::from_triangles(black_box(tris.clone()))));
    let bvh = BvhCaster::new(scene);
    let mut hits = vec![Hit::MISS; rays.len()];
    g.bench_function("bvh_closest", |b| b.iter(|| bvh.closest(black_box(&rays), &mut hits)));
    bvh.closest(&rays, &mut hits);
    let shadow: Vec<Ray> =
        rays.iter().zip(&hits).map(|(r, h)| Ray::segment(r.at(h.t.min(10.0)) + Vec3::Y * 1e-3, Vec3::Y, 1.0)).collect();
    let mut occ = vec![false; rays.len()];
    g.bench_function("bvh_occluded", |b| b.iter(|| bvh.occluded(black_box(&shadow), &mut occ)));
    let dacrt = Dacrt::new(scene);
    g.bench_function("dacrt_closest", |b| b.iter(|| dacrt.closest(black_box(&rays), &mut hits)));
    g.bench_function("dacrt_occluded", |b| b.iter(|| dacrt.occluded(black_box(&shadow), &mut occ)));
    let pdacrt = Pdacrt::new(scene);
    g.bench_function("pdacrt_closest", |b| b.iter(|| pdacrt.closest(black_box(&rays), &mut hits)));
    g.bench_function("pdacrt_occluded", |b| b.iter(|| pdacrt.occluded(black_box(&shadow), &mut occ)));
    #[cfg(feature = "embree")]
    for params in [EmbreeParams::default(), EmbreeParams::fastest()] {
        let label = params.label();
        g.bench_function(format!("{label}_build"), |b| {
            b.iter(|| EmbreeCaster::from_triangles(black_box(tris.clone()), params).expect("Embree"))
        });
        let e = EmbreeCaster::from_triangles(tris.clone(), params).expect("Embree");
        g.bench_function(format!("{label}_closest"), |b| b.iter(|| e.closest(black_box(&rays), &mut hits)));
        g.bench_function(format!("{label}_occluded"), |b| b.iter(|| e.occluded(black_box(&shadow), &mut occ)));
    }
    if with_brute {
        let brute = BruteForce::new(scene);
        g.bench_function("brute_closest", |b| b.iter(|| brute.closest(black_box(&rays), &mut hits)));
    }
    g.finish();
}

fn casters(c: &mut Criterion) {
    bench_scene(c, "cornell", &cornell_box(), true);
    match warpray::scene::find_model("bunny") {
        Some(p) => bench_scene(c, "bunny", &load_obj(p, &Default::default()).unwrap(), false),
        None => eprintln!("*** SKIPPED cast/bunny: bunny.obj.gz not found; set WARPRAY_MODELS ***"),
    }
}

criterion_group!(benches, casters);
criterion_main!(benches);
