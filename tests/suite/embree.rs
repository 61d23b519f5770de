//! The Embree caster (cargo feature `embree`) against brute force: every preset on
//! the four batch kinds of real scenes, the watertight setting on adversarial input,
//! rebuilds and refits after moving vertices, and its errors. Without the Embree
//! library these tests fail and say how to install it; they never pass silently.
#![cfg(feature = "embree")]

use crate::common::*;
use warpray::cast::embree::{EmbreeCaster, EmbreeParams};
use warpray::cast::{BruteForce, RayCaster, Triangles};
use warpray::geometry::{Hit, Ray};
use warpray::glam::Vec3;
use warpray::scene::{ObjOptions, Scene, cornell_box, load_obj};

fn embree(tris: Triangles, params: EmbreeParams) -> Box<dyn RayCaster> {
    match EmbreeCaster::from_triangles(tris, params) {
        Ok(c) => Box::new(c),
        Err(e) => panic!(
            "\n\n*** EMBREE MISSING: {e} ***\nInstall it with `apt-get install libembree-dev` \
             (.ci/run does), or set WARPRAY_EMBREE to an Embree 4 library.\n"
        ),
    }
}

/// Every preset, single rays and packets, with and without the robust flag.
fn presets() -> Vec<EmbreeParams> {
    let d = EmbreeParams::default();
    vec![
        d,
        d.robust(),
        EmbreeParams { packets: true, ..d.robust() },
        EmbreeParams::fastest(),
        EmbreeParams::fastest().robust(),
        EmbreeParams::refit(),
    ]
}

/// A distance at which a hit is the ray's own starting surface: there warpray's test
/// and Embree's round `t ≈ 0` differently (1e-12 against 0), so one may see the
/// surface and the other not.
const AT_ORIGIN: f32 = 1e-6;

/// Closest hits and occlusion of every ray as brute force finds them, except where the
/// ray starts on a triangle (a hit closer than [`AT_ORIGIN`] on either side); those
/// exceptions are counted and must stay under 1 % of the rays.
fn check(brute: &BruteForce, casters: &[Box<dyn RayCaster + '_>], rays: &[Ray], shadow: bool, what: &str) {
    let mut want = vec![Hit::MISS; rays.len()];
    brute.closest(rays, &mut want);
    let mut want_occ = vec![false; rays.len()];
    brute.occluded(rays, &mut want_occ);
    for c in casters {
        let mut got = vec![Hit::MISS; rays.len()];
        c.closest(rays, &mut got);
        let mut got_occ = vec![false; rays.len()];
        c.occluded(rays, &mut got_occ);
        let mut at_origin = 0;
        for (i, (w, g)) in want.iter().zip(&got).enumerate() {
            let self_hit = w.t.min(g.t) < AT_ORIGIN;
            let same = w.is_hit() == g.is_hit() && (!w.is_hit() || (w.t - g.t).abs() <= 1e-5 * w.t.abs().max(1e-30));
            let same_occ = want_occ[i] == got_occ[i];
            if !(same && (same_occ || !shadow)) {
                assert!(
                    self_hit,
                    "{what}/{}: ray {i} {:?}: {w:?} vs {g:?}, occluded {} vs {}",
                    c.name(),
                    rays[i],
                    want_occ[i],
                    got_occ[i]
                );
                at_origin += 1;
            } else if w.is_hit() && w.prim == g.prim {
                assert!((w.u - g.u).abs() < 1e-5 && (w.v - g.v).abs() < 1e-5, "{what}/{}: ray {i}", c.name());
            }
        }
        assert!(at_origin * 100 <= rays.len(), "{what}/{}: {at_origin} rays disagree at their origin", c.name());
    }
}

fn check_scene(scene: &Scene, w: u32, ao: usize, settings: &[EmbreeParams], what: &str) {
    let b = warpray::cast::batches::batches(scene, w, w, ao, 3);
    assert!(!b.shadow.is_empty(), "{what}: the camera sees nothing");
    let casters: Vec<Box<dyn RayCaster>> = settings.iter().map(|&p| embree(scene.triangle_vertices(), p)).collect();
    let brute = BruteForce::new(scene);
    check(&brute, &casters, &b.primary, false, &format!("{what}/primary"));
    check(&brute, &casters, &b.shadow, true, &format!("{what}/shadow"));
    check(&brute, &casters, &b.specular, false, &format!("{what}/specular"));
    check(&brute, &casters, &b.ambient, true, &format!("{what}/ao"));
}

#[test]
fn every_preset_matches_brute_force_on_the_cornell_box() {
    check_scene(&cornell_box(), 48, 4, &presets(), "cornell");
}

#[test]
fn every_preset_matches_brute_force_on_the_bunny() {
    let scene = load_obj(require_model("bunny"), &ObjOptions::default()).unwrap();
    // Brute force over 69K triangles is the cost here: 24² rays, 2 AO rays per hit.
    check_scene(&scene, 24, 2, &presets(), "bunny");
}

/// Random rays of every kind through a small scene, against brute force, with
/// Embree's watertight mode (single rays and packets).
fn fuzz(tris: &[[Vec3; 3]], extra_rays: &[Ray], what: &str) {
    let scene = scene_from_triangles(tris);
    let mut r = rng(17);
    let mut rays = rays_through(&scene, &mut r, 3000);
    rays.extend_from_slice(extra_rays);
    let robust = EmbreeParams::default().robust();
    let casters = vec![
        embree(tris.to_vec(), robust),
        embree(tris.to_vec(), EmbreeParams { packets: true, ..EmbreeParams::fastest().robust() }),
    ];
    let brute = BruteForce::new(&scene);
    check(&brute, &casters, &rays, false, what);
    let segments: Vec<Ray> = rays.iter().map(|ray| Ray { t_max: r.uniform() * 4.0, ..*ray }).collect();
    check(&brute, &casters, &segments, true, what);
}

#[test]
fn watertight_on_shared_edges_coincident_huge_and_degenerate_triangles() {
    // Rays through the vertices and edges of a grid, on its grid lines and in its plane.
    // Only inside the grid: exactly on the mesh's open boundary (x or y = 0 or 16),
    // whether a ray touching the edge hits is a convention, and Embree's watertight
    // test and warpray's decide it differently (both are watertight between triangles).
    let mut extra = Vec::new();
    for k in 1..32 {
        let c = k as f32 * 0.5;
        extra.push(Ray::new(Vec3::new(c, c, 5.0), -Vec3::Z));
        extra.push(Ray::new(Vec3::new(8.0, c, 5.0), -Vec3::Z));
        extra.push(Ray::new(Vec3::new(-1.0, c, 0.0), Vec3::X));
        extra.push(Ray::new(Vec3::new(c, -1.0, 1.0), Vec3::Y));
    }
    fuzz(&quad_grid(16), &extra, "grid");
    let t = [Vec3::new(-1.0, -1.0, 0.0), Vec3::new(1.0, -1.0, 0.0), Vec3::new(0.0, 1.0, 0.0)];
    fuzz(&vec![t; 500], &[Ray::new(Vec3::new(0.0, 0.0, 2.0), -Vec3::Z)], "coincident");
    let mut r = rng(21);
    let mut tris = vec![[Vec3::new(-1e4, -1e4, 0.5), Vec3::new(1e4, -1e4, 0.5), Vec3::new(0.0, 1e4, 0.5)]];
    for _ in 0..300 {
        let p = random_in_box(&mut r, Vec3::splat(-2.0), Vec3::splat(2.0));
        tris.push([p, p + random_dir(&mut r) * 0.2, p + random_dir(&mut r) * 0.2]);
        tris.push([p, p, p + Vec3::X]);
        tris.push([p, p + Vec3::Y, p + 2.0 * Vec3::Y]);
    }
    fuzz(&tris, &[], "huge+degenerate");
}

#[test]
fn triangles_embree_cannot_take_are_still_hit() {
    // A triangle beyond Embree's coordinate range, one with a NaN corner, and a normal
    // one behind the first: the far one is found by warpray's own test.
    let tris = vec![
        [Vec3::new(-5e18, -5e18, -3.0), Vec3::new(5e18, -5e18, -3.0), Vec3::new(0.0, 5e18, -3.0)],
        [Vec3::NAN, Vec3::X, Vec3::Y],
        [Vec3::new(-1.0, -1.0, -5.0), Vec3::new(1.0, -1.0, -5.0), Vec3::new(0.0, 1.0, -5.0)],
    ];
    let c = embree(tris.clone(), EmbreeParams::default());
    let rays = [Ray::new(Vec3::ZERO, -Vec3::Z), Ray { t_max: 2.0, ..Ray::new(Vec3::ZERO, -Vec3::Z) }];
    let mut hits = [Hit::MISS; 2];
    c.closest(&rays, &mut hits);
    assert_eq!(hits[0].prim, 0);
    assert!((hits[0].t - 3.0).abs() < 1e-5, "{:?}", hits[0]);
    assert!(!hits[1].is_hit());
    let mut occ = [false; 2];
    c.occluded(&rays, &mut occ);
    assert_eq!(occ, [true, false]);
    // Empty batches, invalid rays, and an empty scene.
    assert_eq!(c.closest(&[], &mut []).rays, 0);
    let bad = [Ray::new(Vec3::NAN, Vec3::X), Ray::new(Vec3::ZERO, Vec3::ZERO)];
    let mut hits = [Hit { t: 1.0, prim: 0, u: 0.0, v: 0.0 }; 2];
    c.closest(&bad, &mut hits);
    assert!(hits.iter().all(|h| !h.is_hit()));
    let empty = embree(Vec::new(), EmbreeParams::fastest());
    let mut hits = [Hit::MISS; 1];
    empty.closest(&rays[..1], &mut hits);
    assert!(!hits[0].is_hit());
}

#[test]
fn rebuilds_and_refits_follow_moved_vertices() {
    // A grid, moved as a wave: after each update the caster answers for the new
    // triangles, whether it rebuilt (default, fastest) or refitted.
    let grid = quad_grid(24);
    let wave = |k: f32| -> Triangles {
        grid.iter().map(|t| t.map(|p| p + Vec3::Z * (0.3 * (p.x * 0.7 + k).sin() * (p.y * 0.5).cos()))).collect()
    };
    let mut r = rng(5);
    let rays: Vec<Ray> = (0..2000)
        .map(|_| {
            let o = random_in_box(&mut r, Vec3::new(0.0, 0.0, 2.0), Vec3::new(24.0, 24.0, 3.0));
            Ray::new(o, (random_in_box(&mut r, Vec3::ZERO, Vec3::new(24.0, 24.0, 0.0)) - o).normalize())
        })
        .collect();
    for params in [EmbreeParams::default(), EmbreeParams::fastest(), EmbreeParams::refit()] {
        let mut c = EmbreeCaster::from_triangles(wave(0.0), params.robust()).expect("Embree");
        for k in 1..4 {
            let moved = wave(k as f32);
            c.update(moved.clone()).unwrap();
            assert!(c.build_seconds() > 0.0);
            let brute = BruteForce::from_triangles(moved);
            let list: Vec<Box<dyn RayCaster + '_>> = vec![Box::new(ProxyRef(&c))];
            check(&brute, &list, &rays, true, &format!("{}/frame {k}", params.label()));
        }
        let err = c.update(grid[..10].to_vec()).unwrap_err().to_string();
        assert!(err.contains("10 triangles") && err.contains("Embree"), "{err}");
    }
}

/// Borrows a caster as a `Box<dyn RayCaster>` for the shared checks.
struct ProxyRef<'a>(&'a EmbreeCaster);

impl RayCaster for ProxyRef<'_> {
    fn name(&self) -> &'static str {
        self.0.name()
    }
    fn closest(&self, rays: &[Ray], hits: &mut [Hit]) -> warpray::cast::CastStats {
        self.0.closest(rays, hits)
    }
    fn occluded(&self, rays: &[Ray], out: &mut [bool]) -> warpray::cast::CastStats {
        self.0.occluded(rays, out)
    }
    fn memory_bytes(&self) -> usize {
        self.0.memory_bytes()
    }
}

#[test]
fn reports_its_structure_and_build_time() {
    let scene = cornell_box();
    let c = EmbreeCaster::from_triangles(scene.triangle_vertices(), EmbreeParams::default()).expect("Embree");
    // Embree's own allocations (its memory monitor) plus warpray's triangle copy.
    assert!(c.memory_bytes() > scene.triangle_count() * 36, "{}", c.memory_bytes());
    assert!(c.build_seconds() > 0.0);
    assert!(c.version() >= 30000, "version {}", c.version());
    assert_eq!(c.name(), "embree");
    assert_eq!(EmbreeParams::fastest().robust().label(), "embree-fast-robust");
    for p in [EmbreeParams::default(), EmbreeParams::fastest(), EmbreeParams::refit()] {
        for p in [p, p.robust()] {
            assert_eq!(EmbreeParams::by_label(p.label()), Some(p), "{}", p.label());
        }
    }
    assert_eq!(EmbreeParams::by_label("embree-slow"), None);
}

#[test]
fn renders_with_embree_match_the_bvh_at_any_thread_count() {
    use warpray::prelude::{BvhCaster, IntegratorKind, render};
    let scene = cornell_box();
    for integrator in [IntegratorKind::Path, IntegratorKind::Bdpt, IntegratorKind::Cis] {
        let opts = small_render(integrator);
        let bvh = render(&scene, &BvhCaster::new(&scene), &opts, |_, _| true).unwrap();
        for threads in [1, 3] {
            let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
            let (film, stats) = pool.install(|| {
                let e = EmbreeCaster::new(&scene).expect("Embree");
                render(&scene, &e, &opts, |_, _| true).unwrap()
            });
            assert_eq!(stats.rays, bvh.1.rays, "{} with Embree, {threads} threads: ray count", integrator.name());
            assert!(film.mean() == bvh.0.mean(), "{} with Embree, {threads} threads: image differs", integrator.name());
        }
    }
}

#[test]
fn a_missing_embree_library_is_an_error_naming_it() {
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_warpray"))
        .args(["render", "--caster", "embree", "--size", "8x8", "--spp", "1", "-q", "-o"])
        .arg(std::env::temp_dir().join("warpray-no-embree.png"))
        .env("WARPRAY_EMBREE", "/nonexistent/libembree4.so.4")
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success(), "{err}");
    assert!(err.contains("Embree library /nonexistent/libembree4.so.4") && err.contains("cannot open"), "{err}");
    assert!(!std::env::temp_dir().join("warpray-no-embree.png").exists(), "no output is written");
}
