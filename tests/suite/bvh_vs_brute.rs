//! The obvhs BVH against brute force: same closest triangle (ties decided by distance),
//! same distance, same occlusion, on the built-in Cornell box (every ray) and the
//! Stanford bunny (brute force on the rays where the BVH and DACRT disagree, near edges,
//! and a uniform sample).

use crate::common::*;
use warpray::cast::{BruteForce, Bvh4, BvhCaster, Dacrt, RayCaster};
use warpray::geometry::{Hit, Ray};
use warpray::glam::Vec3;
use warpray::scene::{ObjOptions, Scene, cornell_box, load_obj};

/// Rays from random points around the scene's box toward random points inside it,
/// plus fully random directions from inside.
fn random_rays(scene: &Scene, n: usize, seed: u64) -> Vec<Ray> {
    let b = scene.bounds();
    let pad = b.extent() * 0.25;
    let mut r = rng(seed);
    (0..n)
        .map(|i| {
            if i % 2 == 0 {
                let o = random_in_box(&mut r, b.min - pad, b.max + pad);
                let target = random_in_box(&mut r, b.min, b.max);
                Ray::new(o, (target - o).normalize())
            } else {
                Ray::new(random_in_box(&mut r, b.min, b.max), random_dir(&mut r))
            }
        })
        .collect()
}

/// Asserts both hit lists agree: same triangle, or a different one at the same
/// distance (an edge shared by two triangles, coincident faces); distance within 1e-5.
fn assert_same_hits(rays: &[Ray], want: &[Hit], got: &[Hit], what: &str) {
    let mut tie_count = 0;
    for (i, (w, g)) in want.iter().zip(got).enumerate() {
        assert_eq!(w.is_hit(), g.is_hit(), "{what}: ray {i} {:?}: brute {:?} vs {:?}", rays[i], w, g);
        if !w.is_hit() {
            continue;
        }
        let rel = (w.t - g.t).abs() / w.t.abs().max(1e-30);
        assert!(rel <= 1e-5, "{what}: ray {i}: distance {} vs {} (rel {rel})", w.t, g.t);
        if w.prim != g.prim {
            tie_count += 1;
        }
    }
    // Ties must stay rare; many would mean the casters disagree on triangles.
    assert!(tie_count * 1000 < want.len().max(1000), "{what}: {tie_count} ties by distance");
}

/// The BVH against brute force on `n` random rays and `n` shadow segments. With
/// `oracle_stride` above 1 the scene is too large for brute force on every ray (the
/// bunny's 100,000 rays took 41 s of brute force against 0.07 s of BVH): DACRT, an
/// independent caster checked against brute force in `dacrt.rs`, casts every ray too,
/// and brute force answers the rays [`rays_worth_an_oracle`] picks (every ray where the
/// two disagree, every hit near an edge, every `oracle_stride`-th ray).
fn check_scene(scene: &Scene, n: usize, oracle_stride: usize, what: &str) {
    let brute = BruteForce::new(scene);
    let bvh = BvhCaster::new(scene);
    let dacrt = Dacrt::new(scene);
    let rays = random_rays(scene, n, 11);
    let mut got = vec![Hit::MISS; n];
    let mut second = vec![Hit::MISS; n];
    bvh.closest(&rays, &mut got);
    dacrt.closest(&rays, &mut second);
    let chosen = rays_worth_an_oracle(&[&got, &second], oracle_stride);
    let pick = |all: &[Hit]| chosen.iter().map(|&i| all[i]).collect::<Vec<_>>();
    let chosen_rays: Vec<Ray> = chosen.iter().map(|&i| rays[i]).collect();
    let mut want = vec![Hit::MISS; chosen.len()];
    brute.closest(&chosen_rays, &mut want);
    let hits = got.iter().filter(|h| h.is_hit()).count();
    assert!(hits > n / 4, "{what}: only {hits} of {n} rays hit: the test rays are not testing much");
    assert!(chosen.len() >= n / oracle_stride, "{what}: the oracle saw {} rays", chosen.len());
    assert_same_hits(&chosen_rays, &want, &pick(&got), what);
    assert_same_hits(&chosen_rays, &want, &pick(&second), &format!("{what} (dacrt)"));

    // Shadow rays: segments between random points, half of them ending exactly at the
    // closest hit found above (so t_max is tight against a surface).
    let mut r = rng(99);
    let b = scene.bounds();
    let shadow: Vec<Ray> = rays
        .iter()
        .zip(&got)
        .map(|(ray, h)| {
            if h.is_hit() && r.uniform() < 0.5 {
                Ray::segment(ray.origin, ray.dir, h.t * (1.0 - 1e-3))
            } else {
                let a = random_in_box(&mut r, b.min, b.max);
                let c = random_in_box(&mut r, b.min, b.max);
                Ray::segment(a, c - a, 1.0)
            }
        })
        .collect();
    let mut occ_got = vec![false; n];
    let mut occ_second = vec![false; n];
    bvh.occluded(&shadow, &mut occ_got);
    dacrt.occluded(&shadow, &mut occ_second);
    let chosen: Vec<usize> = (0..n).filter(|&i| occ_got[i] != occ_second[i] || i % oracle_stride == 0).collect();
    let chosen_rays: Vec<Ray> = chosen.iter().map(|&i| shadow[i]).collect();
    let mut occ_want = vec![false; chosen.len()];
    brute.occluded(&chosen_rays, &mut occ_want);
    let blocked = occ_got.iter().filter(|&&b| b).count();
    assert!(blocked > n / 20 && blocked < n - n / 20, "{what}: {blocked}/{n} shadow rays blocked: no contrast");
    for (k, &i) in chosen.iter().enumerate() {
        assert_eq!(occ_want[k], occ_got[i], "{what}: shadow ray {i} {:?}", shadow[i]);
        assert_eq!(occ_want[k], occ_second[i], "{what} (dacrt): shadow ray {i} {:?}", shadow[i]);
    }
}

#[test]
fn bvh_matches_brute_force_on_cornell_box() {
    check_scene(&cornell_box(), 200_000, 1, "cornell");
}

#[test]
fn bvh_matches_brute_force_on_bunny() {
    let scene = load_obj(require_model("bunny"), &ObjOptions::default()).unwrap();
    assert_eq!(scene.triangle_count(), 69_451);
    check_scene(&scene, 100_000, 25, "bunny");
}

#[test]
fn rays_at_shared_edges_and_vertices_of_a_closed_mesh_never_miss() {
    let (v, f) = icosphere(3);
    let tris: Vec<[Vec3; 3]> = f.iter().map(|t| t.map(|i| v[i as usize])).collect();
    let scene = scene_from_triangles(&tris);
    let casters: [Box<dyn RayCaster>; 3] =
        [Box::new(BruteForce::new(&scene)), Box::new(BvhCaster::new(&scene)), Box::new(Bvh4::new(&scene))];

    // Targets: every vertex and every edge midpoint (points of the surface shared by
    // several triangles), seen from random outside points and from the centre.
    let mut targets: Vec<Vec3> = v.clone();
    for t in &f {
        for k in 0..3 {
            targets.push((v[t[k] as usize] + v[t[(k + 1) % 3] as usize]) * 0.5);
        }
    }
    let mut r = rng(5);
    let mut rays = Vec::new();
    for &p in &targets {
        rays.push(Ray::new(Vec3::ZERO, p)); // from the centre, exactly through p
        // From outside, exactly at p, within ~25° of the surface normal (a ray at a
        // silhouette vertex may only graze the polyhedron and legitimately miss).
        let o = p * 3.0 + random_dir(&mut r) * 0.8;
        rays.push(Ray::new(o, p - o));
        // axis-aligned ray through p along its dominant axis
        let a = p.abs();
        let axis = if a.x >= a.y && a.x >= a.z {
            Vec3::X
        } else if a.y >= a.z {
            Vec3::Y
        } else {
            Vec3::Z
        };
        rays.push(Ray::new(p - axis * 5.0, axis));
    }
    for c in &casters {
        let mut hits = vec![Hit::MISS; rays.len()];
        c.closest(&rays, &mut hits);
        for (i, h) in hits.iter().enumerate() {
            assert!(h.is_hit(), "{}: ray {i} {:?} slipped through the mesh", c.name(), rays[i]);
        }
        let mut occ = vec![false; rays.len()];
        let segs: Vec<Ray> = rays.iter().map(|r| Ray { t_max: 1e6, ..*r }).collect();
        c.occluded(&segs, &mut occ);
        assert!(occ.iter().all(|&o| o), "{}: an occlusion ray slipped through", c.name());
    }
}

#[test]
fn empty_batches_invalid_rays_and_empty_scenes_are_harmless() {
    let scene = cornell_box();
    let casters: [Box<dyn RayCaster>; 3] =
        [Box::new(BruteForce::new(&scene)), Box::new(BvhCaster::new(&scene)), Box::new(Bvh4::new(&scene))];
    for c in &casters {
        let stats = c.closest(&[], &mut []);
        assert_eq!(stats.rays, 0);
        let bad = [
            Ray::new(Vec3::splat(f32::NAN), Vec3::X),
            Ray::new(Vec3::ZERO, Vec3::ZERO),
            Ray::new(Vec3::new(0.0, 1.0, 0.0), Vec3::new(f32::INFINITY, 0.0, 0.0)),
        ];
        let mut hits = [Hit { t: 1.0, prim: 3, u: 0.0, v: 0.0 }; 3];
        c.closest(&bad, &mut hits);
        assert!(hits.iter().all(|h| !h.is_hit()), "{}: invalid rays must miss", c.name());
        let mut occ = [true; 3];
        c.occluded(&bad, &mut occ);
        assert!(occ.iter().all(|&o| !o));
    }
    let empties: [Box<dyn RayCaster>; 2] =
        [Box::new(BvhCaster::from_triangles(Vec::new())), Box::new(Bvh4::from_triangles(Vec::new()))];
    for empty in empties {
        let mut hits = [Hit::MISS];
        empty.closest(&[Ray::new(Vec3::ZERO, Vec3::X)], &mut hits);
        assert!(!hits[0].is_hit(), "{}", empty.name());
    }
}
