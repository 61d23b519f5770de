//! The BVH casters (obvhs' and warpray's 4-wide one) never miss a legal ray: signed
//! zeros and axis-parallel directions, origins on node faces, rays from inside closed
//! meshes, extreme coordinates and coincident triangles (each a case that obvhs 0.4's
//! own traversal or build got wrong).

use crate::common::*;
use warpray::cast::{BruteForce, Bvh4, BvhCaster, RayCaster};
use warpray::geometry::{Hit, Ray};
use warpray::glam::Vec3;
use warpray::scene::cornell_box;

/// Both BVH casters over a triangle list, the BVH4 with each of its traversals (the
/// widest packets this CPU runs, packets of 8, one ray at a time).
fn bvhs(tris: &[[Vec3; 3]]) -> [Box<dyn RayCaster>; 4] {
    let bvh4 = || Bvh4::from_triangles(tris.to_vec());
    [
        Box::new(BvhCaster::from_triangles(tris.to_vec())),
        Box::new(bvh4()),
        Box::new(bvh4().max_packet(8)),
        Box::new(bvh4().single_rays()),
    ]
}

/// Same hit or miss as brute force, the same distance, and the same occlusion, for
/// every BVH caster of [`bvhs`].
fn agree(tris: &[[Vec3; 3]], rays: &[Ray], what: &str) {
    let brute = BruteForce::from_triangles(tris.to_vec());
    for bvh in bvhs(tris) {
        agree_with(&brute, bvh.as_ref(), rays, &format!("{what} ({})", bvh.name()));
    }
}

/// [`agree`] for one caster.
fn agree_with(brute: &BruteForce, bvh: &dyn RayCaster, rays: &[Ray], what: &str) {
    let (mut want, mut got) = (vec![Hit::MISS; rays.len()], vec![Hit::MISS; rays.len()]);
    brute.closest(rays, &mut want);
    bvh.closest(rays, &mut got);
    let wrong: Vec<usize> = (0..rays.len())
        .filter(|&i| want[i].is_hit() != got[i].is_hit() || (want[i].is_hit() && want[i].t != got[i].t))
        .collect();
    assert!(
        wrong.is_empty(),
        "{what}: {} of {} rays differ; first {:?}: brute {:?}, bvh {:?}",
        wrong.len(),
        rays.len(),
        rays[wrong[0]],
        want[wrong[0]],
        got[wrong[0]]
    );
    let (mut want, mut got) = (vec![false; rays.len()], vec![false; rays.len()]);
    brute.occluded(rays, &mut want);
    bvh.occluded(rays, &mut got);
    let wrong: Vec<usize> = (0..rays.len()).filter(|&i| want[i] != got[i]).collect();
    assert!(
        wrong.is_empty(),
        "{what}: occlusion differs for {} of {} rays; first {:?}: brute {}, bvh {}",
        wrong.len(),
        rays.len(),
        rays[wrong[0]],
        want[wrong[0]],
        got[wrong[0]]
    );
}

/// The six axis directions with every combination of signed zeros.
fn axis_directions() -> Vec<Vec3> {
    let mut out = Vec::new();
    for axis in 0..3 {
        for sign in [1.0f32, -1.0] {
            for zeros in 0..4 {
                let mut d = [0.0f32; 3];
                d[axis] = sign;
                let (a, b) = ((axis + 1) % 3, (axis + 2) % 3);
                d[a] = if zeros & 1 == 1 { -0.0 } else { 0.0 };
                d[b] = if zeros & 2 == 2 { -0.0 } else { 0.0 };
                out.push(Vec3::from_array(d));
            }
        }
    }
    out
}

#[test]
fn the_readme_ray_hits_the_cornell_box() {
    let scene = cornell_box();
    let bvh = BvhCaster::new(&scene);
    let mut hit = [Hit::MISS];
    bvh.closest(&[Ray::new(Vec3::new(0.5, 1.5, 3.0), -Vec3::Z)], &mut hit);
    let mut want = [Hit::MISS];
    BruteForce::new(&scene).closest(&[Ray::new(Vec3::new(0.5, 1.5, 3.0), -Vec3::Z)], &mut want);
    assert!(want[0].is_hit() && hit[0].t == want[0].t, "bvh {:?}, brute force {:?}", hit[0], want[0]);
}

#[test]
fn axis_parallel_rays_with_signed_zeros_against_brute_force() {
    let scene = cornell_box();
    let tris = scene.triangle_vertices();
    let b = scene.bounds();
    let mut r = rng(3);
    let mut rays = Vec::new();
    for _ in 0..300 {
        let o = random_in_box(&mut r, b.min - Vec3::splat(0.5), b.max + Vec3::splat(0.5));
        for d in axis_directions() {
            rays.push(Ray::new(o, d));
        }
    }
    agree(&tris, &rays, "cornell, axis-parallel");
    let (v, f) = icosphere(3);
    let sphere: Vec<[Vec3; 3]> = f.iter().map(|t| t.map(|i| v[i as usize])).collect();
    let rays: Vec<Ray> = (0..400)
        .flat_map(|_| {
            let o = random_in_box(&mut r, Vec3::splat(-1.5), Vec3::splat(1.5));
            axis_directions().into_iter().map(move |d| Ray::new(o, d))
        })
        .collect();
    agree(&sphere, &rays, "icosphere, axis-parallel");
}

#[test]
fn axis_parallel_rays_whose_origins_lie_on_node_faces() {
    // A 16 × 16 grid of unit quads in z = 0; rays straight down from every point of a
    // quarter-unit lattice over it, including the grid's own edges and corners.
    let tris = quad_grid(16);
    let mut rays = Vec::new();
    for i in 0..=64 {
        for j in 0..=64 {
            let o = Vec3::new(i as f32 * 0.25, j as f32 * 0.25, 3.0);
            rays.push(Ray::new(o, Vec3::new(0.0, 0.0, -1.0)));
            rays.push(Ray::new(o, Vec3::new(-0.0, -0.0, -1.0)));
        }
    }
    agree(&tris, &rays, "grid, rays on node faces");
}

#[test]
fn rays_from_inside_closed_spheres_never_escape() {
    for sub in 3..=6 {
        let (v, f) = icosphere(sub);
        let tris: Vec<[Vec3; 3]> = f.iter().map(|t| t.map(|i| v[i as usize])).collect();
        let mut r = rng(40 + sub as u64);
        let mut rays: Vec<Ray> = (0..20_000)
            .map(|_| Ray::new(random_in_box(&mut r, Vec3::splat(-0.5), Vec3::splat(0.5)), random_dir(&mut r)))
            .collect();
        // From the centre through every vertex: the rays most likely to slip between
        // the triangles that share it.
        rays.extend(v.iter().map(|&p| Ray::new(Vec3::ZERO, p)));
        rays.extend(axis_directions().into_iter().map(|d| Ray::new(Vec3::ZERO, d)));
        for bvh in bvhs(&tris) {
            let name = bvh.name();
            let mut hits = vec![Hit::MISS; rays.len()];
            bvh.closest(&rays, &mut hits);
            let escaped: Vec<&Ray> = rays.iter().zip(&hits).filter(|(_, h)| !h.is_hit()).map(|(r, _)| r).collect();
            assert!(
                escaped.is_empty(),
                "{name}, subdivision {sub}: {} rays escaped, first {:?}",
                escaped.len(),
                escaped[0]
            );
            let mut blocked = vec![false; rays.len()];
            bvh.occluded(&rays, &mut blocked);
            assert!(blocked.iter().all(|&b| b), "{name}, subdivision {sub}: an occlusion ray escaped");
        }
    }
}

#[test]
fn rays_through_the_vertices_of_a_small_sphere_far_from_the_origin() {
    // Rounding in obvhs' node test grows with the coordinates' magnitude, not the
    // sphere's size: a unit sphere at 1000 has node boxes whose planes are 1e-4 apart in
    // relative terms. Rays from the centre through every vertex and edge midpoint, and
    // from far outside the padded region (the robust traversal's cases) at every vertex.
    let (v, f) = icosphere(4);
    let centre = Vec3::new(1000.0, -500.0, 250.0);
    let v: Vec<Vec3> = v.iter().map(|&p| centre + p * 0.5).collect();
    let tris: Vec<[Vec3; 3]> = f.iter().map(|t| t.map(|i| v[i as usize])).collect();
    let mut rays: Vec<Ray> = v.iter().map(|&p| Ray::new(centre, p - centre)).collect();
    rays.extend(
        tris.iter().flat_map(|t| [0.5 * (t[0] + t[1]), 0.5 * (t[1] + t[2])]).map(|p| Ray::new(centre, p - centre)),
    );
    let far = centre + Vec3::new(3000.0, 2000.0, -1000.0);
    rays.extend(v.iter().step_by(7).map(|&p| Ray::new(far, p - far)));
    agree(&tris, &rays, "unit sphere at 1000");
}

#[test]
fn every_traversal_mode_keeps_rays_inside_a_closed_sphere() {
    use warpray::cast::Traversal;
    let (v, f) = icosphere(4);
    let tris: Vec<[Vec3; 3]> = f.iter().map(|t| t.map(|i| v[i as usize])).collect();
    let rays: Vec<Ray> = v.iter().map(|&p| Ray::new(Vec3::ZERO, p)).collect();
    for mode in [Traversal::Fast, Traversal::Checked, Traversal::Robust] {
        let bvh = BvhCaster::from_triangles(tris.clone()).with_traversal(mode);
        let mut hits = vec![Hit::MISS; rays.len()];
        bvh.closest(&rays, &mut hits);
        assert!(hits.iter().all(|h| h.is_hit()), "{mode:?}: a ray through a vertex escaped");
    }
}

#[test]
fn extreme_coordinates_beside_a_unit_triangle() {
    let unit = [Vec3::new(0.0, 0.0, 0.0), Vec3::new(1.0, 0.0, 0.0), Vec3::new(0.0, 1.0, 0.0)];
    let huge = [Vec3::new(-1e19, -1e19, 5.0), Vec3::new(1e19, -1e19, 5.0), Vec3::new(0.0, 1e19, 5.0)];
    let tris = vec![unit, huge];
    let rays: Vec<Ray> = (0..100)
        .map(|i| Ray::new(Vec3::new(0.2 + i as f32 * 0.001, 0.3, 2.0), Vec3::new(0.0, 0.0, -1.0)))
        .chain((0..100).map(|i| Ray::new(Vec3::new(0.2, 0.3 + i as f32 * 0.001, 2.0), Vec3::new(0.01, 0.0, 1.0))))
        .collect();
    agree(&tris, &rays, "±1e19 beside a unit triangle");
}

#[test]
fn twenty_thousand_coincident_triangles() {
    let t = [Vec3::new(-1.0, -1.0, 0.0), Vec3::new(1.0, -1.0, 0.0), Vec3::new(0.0, 1.0, 0.0)];
    let mut tris = vec![t; 20_000];
    tris.push([Vec3::new(-1.0, -1.0, 1.0), Vec3::new(1.0, -1.0, 1.0), Vec3::new(0.0, 1.0, 1.0)]);
    let mut r = rng(9);
    let rays: Vec<Ray> = (0..300)
        .map(|_| Ray::new(random_in_box(&mut r, Vec3::new(-0.5, -0.5, 2.0), Vec3::new(0.5, 0.5, 3.0)), -Vec3::Z))
        .collect();
    agree(&tris, &rays, "coincident");
}

#[test]
fn every_traversal_mode_agrees_with_brute_force_on_ordinary_rays() {
    use warpray::cast::Traversal;
    let scene = cornell_box();
    let tris = scene.triangle_vertices();
    let b = scene.bounds();
    let mut r = rng(21);
    let rays: Vec<Ray> = (0..5000)
        .map(|_| {
            let o = random_in_box(&mut r, b.min, b.max);
            Ray { t_max: r.uniform() * 3.0, ..Ray::new(o, random_dir(&mut r)) }
        })
        .collect();
    let brute = BruteForce::from_triangles(tris.clone());
    let (mut want_hit, mut want_occ) = (vec![Hit::MISS; rays.len()], vec![false; rays.len()]);
    brute.closest(&rays, &mut want_hit);
    brute.occluded(&rays, &mut want_occ);
    assert!(want_occ.iter().any(|&o| o) && want_occ.iter().any(|&o| !o), "both answers occur");
    for mode in [Traversal::Fast, Traversal::Checked, Traversal::Robust] {
        let bvh = BvhCaster::from_triangles(tris.clone()).with_traversal(mode);
        let (mut hit, mut occ) = (vec![Hit::MISS; rays.len()], vec![false; rays.len()]);
        bvh.closest(&rays, &mut hit);
        bvh.occluded(&rays, &mut occ);
        assert!(hit.iter().zip(&want_hit).all(|(a, b)| a.t == b.t), "{mode:?}: closest hits");
        assert_eq!(occ, want_occ, "{mode:?}: occlusion");
    }
}

#[test]
fn a_fan_of_two_hundred_thousand_slivers() {
    // A convex polygon of 200,000 corners, fan-triangulated as the PLY and OBJ loaders
    // do: every triangle shares corner 0 and spans the whole polygon, so every box
    // overlaps every other (obvhs' PLOC build took over a minute on it, quadratic).
    // warpray's 4-wide BVH builds it by binned SAH in O(n log n); its answers are
    // brute force's.
    let n = 200_000;
    let corner = |k: usize| {
        let a = std::f32::consts::TAU * k as f32 / n as f32;
        Vec3::new(a.cos(), a.sin(), 0.0)
    };
    let tris: Vec<[Vec3; 3]> = (1..n - 1).map(|k| [corner(0), corner(k), corner(k + 1)]).collect();
    let mut r = rng(31);
    let rays: Vec<Ray> = (0..200)
        .map(|_| Ray::new(random_in_box(&mut r, Vec3::new(-1.0, -1.0, 1.0), Vec3::new(1.0, 1.0, 2.0)), -Vec3::Z))
        .collect();
    let brute = BruteForce::from_triangles(tris.clone());
    let bvh4 = Bvh4::from_triangles(tris);
    agree_with(&brute, &bvh4, &rays, "fan of slivers (bvh4)");
}

#[test]
fn hits_the_watertight_test_reports_just_off_a_large_floor() {
    // From the conference room: a ray starting 3e-5 under its floor (coordinates near
    // 1,000) and leaving it is reported hit by the watertight test at t = 3.8e-5,
    // outside the floor's exact box. A BVH whose boxes are exact loses it; brute force
    // and every other caster report it. Small triangles around make the floor a leaf
    // below nodes whose boxes are tested.
    let floor = [
        Vec3::new(-946.8875, -1.572159, 668.4894),
        Vec3::new(1653.2471, -1.572159, 668.4894),
        Vec3::new(1653.2471, -1.572159, -1016.10486),
    ];
    let mut tris = vec![floor];
    let mut r = rng(43);
    for _ in 0..64 {
        let c = random_in_box(&mut r, Vec3::new(-900.0, 0.0, -900.0), Vec3::new(1600.0, 400.0, 600.0));
        tris.push([c, c + Vec3::new(5.0, 0.0, 0.0), c + Vec3::new(0.0, 5.0, 1.0)]);
    }
    let mut rays = vec![
        Ray::new(Vec3::new(422.09717, -1.5721896, 212.83295), Vec3::new(0.7627332, -0.58807045, 0.26909304)),
        Ray::new(Vec3::new(384.83405, -1.5721896, -602.7712), Vec3::new(0.8284043, -0.513056, -0.22476646)),
    ];
    // Rays from just under and over the floor, in every direction.
    for _ in 0..2000 {
        let o = random_in_box(&mut r, Vec3::new(0.0, -1.57219, -900.0), Vec3::new(1600.0, -1.57213, 600.0));
        rays.push(Ray::new(o, random_dir(&mut r)));
    }
    let brute = BruteForce::from_triangles(tris.clone());
    let mut want = [Hit::MISS];
    brute.closest(&rays[..1], &mut want);
    assert!(want[0].is_hit() && want[0].t < 1e-4, "the case is still a near miss that the test reports: {:?}", want[0]);
    agree(&tris, &rays, "just off a large floor");
    // DACRT and PDACRT cull by boxes too, grown the same way.
    let dacrt = warpray::cast::Dacrt::from_triangles(tris.clone(), warpray::cast::DacrtParams::default());
    agree_with(&brute, &dacrt, &rays, "just off a large floor (dacrt)");
    let pdacrt = warpray::cast::pdacrt::Pdacrt::from_triangles(&tris, warpray::cast::pdacrt::PdacrtParams::default());
    agree_with(&brute, &pdacrt, &rays, "just off a large floor (pdacrt)");
}
