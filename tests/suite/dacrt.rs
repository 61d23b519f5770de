//! Divide-and-conquer casters (serial DACRT, PDACRT) and the 4-wide BVH against brute force and the obvhs BVH: same closest triangle
//! (ties by distance), same distance, same occlusion, on primary, shadow, specular and
//! ambient-occlusion batches over real scenes, and on adversarial input.

use crate::common::*;
use warpray::cast::{BruteForce, Bvh4, BvhCaster, CastStats, Dacrt, DacrtParams, Lbvh, RayCaster};
use warpray::geometry::{Hit, Ray};
use warpray::glam::Vec3;
use warpray::pdacrt::{Pdacrt, PdacrtParams};
use warpray::scene::{ObjOptions, Scene, cornell_box, load_obj};

/// The casters under test, each with its name. PDACRT measured on the emulator with
/// one-ray, one-triangle leaves (a kernel launch per level, every instruction counted)
/// joins when `measured` is set, on the small scenes: on the bunny and the conference
/// room it took 80 % of this file's time, and what it would add there (counting does
/// not change a hit) is checked on the small scenes and by `simt`'s own tests.
fn casters_under_test(scene: &Scene, measured: bool) -> Vec<Box<dyn RayCaster>> {
    let mut casters: Vec<Box<dyn RayCaster>> = vec![
        Box::new(Dacrt::new(scene)),
        // One recursion, with packet filtering, on the SSE steps alone (what a CPU
        // without AVX2 runs; the others take the widest lanes this CPU has), gathering
        // the triangles from the scene by id (the others lay each shared-top cell out).
        Box::new(Dacrt::from_triangles(
            scene.triangle_vertices(),
            DacrtParams { packet_rays: 32, lanes: false, cell_layout: false, ..DacrtParams::serial() },
        )),
        // Tiny leaves force deep recursion; small packets are tested at every level, and
        // every node prices its planes on samples of its rays (`sampled_min_pairs`).
        Box::new(Dacrt::from_triangles(
            scene.triangle_vertices(),
            DacrtParams {
                leaf_rays: 1,
                leaf_triangles: 1,
                packet_rays: 8,
                sampled_min_pairs: 1,
                ..DacrtParams::default()
            },
        )),
        // Forks at nearly every node of a batch from many origins (far halves run as
        // tasks, taken over by idle threads), in a pool of its own of 4 threads so that
        // it forks on a machine of any size.
        Box::new(InPool(
            Dacrt::from_triangles(
                scene.triangle_vertices(),
                DacrtParams { fork_min_rays: 2, leaf_rays: 2, leaf_triangles: 2, ..DacrtParams::default() },
            ),
            rayon::ThreadPoolBuilder::new().num_threads(4).build().expect("a pool of 4 threads"),
        )),
        Box::new(Pdacrt::new(scene)),
        // The 4-wide BVH meets the same batches and adversarial sets.
        Box::new(Bvh4::new(scene)),
        // So does the GPU BVH's emulated twin.
        Box::new(Lbvh::new(scene)),
    ];
    if measured {
        let dev = simt::Device::default();
        dev.set_measure(true);
        casters.push(Box::new(Lbvh::on_device(&scene.triangle_vertices(), dev)));
        casters.push(Box::new(Pdacrt::from_triangles(
            &scene.triangle_vertices(),
            PdacrtParams { leaf_rays: 1, leaf_triangles: 1, measure: true, ..PdacrtParams::default() },
        )));
    }
    casters
}

/// The largest scene on which [`check_scene`] compares the measured tiny-leaf PDACRT.
const MEASURED_MAX_TRIANGLES: usize = 5_000;

/// A caster whose calls run in a thread pool of their own.
struct InPool<C>(C, rayon::ThreadPool);

impl<C: RayCaster> RayCaster for InPool<C> {
    fn name(&self) -> &'static str {
        self.0.name()
    }
    fn closest(&self, rays: &[Ray], hits: &mut [Hit]) -> CastStats {
        self.1.install(|| self.0.closest(rays, hits))
    }
    fn occluded(&self, rays: &[Ray], out: &mut [bool]) -> CastStats {
        self.1.install(|| self.0.occluded(rays, out))
    }
    fn memory_bytes(&self) -> usize {
        self.0.memory_bytes()
    }
}

/// Primary rays, and from their hits: shadow rays to a point, mirror reflections, and
/// cosine-weighted ambient-occlusion rays.
fn batches(scene: &Scene, w: u32, h: u32, ao_per_hit: usize) -> [Vec<Ray>; 4] {
    let b = warpray::cast::batches::batches(scene, w, h, ao_per_hit, 3);
    [b.primary, b.shadow, b.specular, b.ambient]
}

fn check_scene(scene: &Scene, oracle: &dyn RayCaster, w: u32, h: u32, ao: usize, what: &str) {
    let [primary, shadow, specular, ambient] = batches(scene, w, h, ao);
    assert!(!shadow.is_empty(), "{what}: the camera sees nothing");
    // Casters are built once per scene and reused for every batch.
    let casters = casters_under_test(scene, scene.triangle_count() <= MEASURED_MAX_TRIANGLES);
    assert_closest_agree(oracle, &casters, &primary, &format!("{what}/primary"));
    assert_occluded_agree(oracle, &casters, &shadow, &format!("{what}/shadow"));
    assert_closest_agree(oracle, &casters, &specular, &format!("{what}/specular"));
    assert_closest_agree(oracle, &casters, &ambient, &format!("{what}/ao"));
    assert_occluded_agree(oracle, &casters, &ambient, &format!("{what}/ao-occlusion"));
}

#[test]
fn dacrt_matches_brute_force_on_the_cornell_box() {
    // 48² primary rays and 4 AO rays per hit: about 20,000 rays per batch kind through
    // five casters (two of them with one-ray, one-triangle leaves). 96² with 8 took
    // over two minutes of the suite; every batch kind and leaf setting is still here.
    let scene = cornell_box();
    check_scene(&scene, &BruteForce::new(&scene), 48, 48, 4, "cornell");
}

#[test]
fn dacrt_matches_brute_force_on_the_bunny() {
    let scene = load_obj(require_model("bunny"), &ObjOptions::default()).unwrap();
    check_scene(&scene, &BruteForce::new(&scene), 40, 40, 2, "bunny");
}

fn conference_inside() -> Scene {
    let mut scene = load_obj(require_model("conference"), &ObjOptions::default()).unwrap();
    warpray::cast::batches::interior_camera(&mut scene);
    scene
}

#[test]
fn dacrt_matches_brute_force_in_the_conference_room() {
    let scene = conference_inside();
    check_scene(&scene, &BruteForce::new(&scene), 20, 20, 1, "conference");
}

#[test]
fn dacrt_matches_the_bvh_on_bunny_and_conference_room() {
    // The BVH itself is checked against brute force hit for hit (bvh_vs_brute.rs), so
    // it serves as the oracle where brute force would take minutes.
    // Sizes keep this test near half a minute on two cores (160² and 128² took 145 s).
    for (name, size, ao) in [("bunny", 96, 2), ("conference", 80, 2)] {
        let scene = load_obj(require_model(name), &ObjOptions::default()).unwrap();
        let mut scene = scene;
        if name == "conference" {
            // Inside the room, looking along it.
            let b = scene.bounds();
            let eye = b.center() + Vec3::new(-0.3, 0.1, 0.0) * b.extent();
            scene.camera = warpray::scene::Camera::look_at(
                eye,
                b.center() + Vec3::new(0.3, -0.1, 0.0) * b.extent(),
                Vec3::Y,
                60.0,
            );
        }
        check_scene(&scene, &BvhCaster::new(&scene), size, size, ao, name);
    }
}

/// Random rays of every kind through a small scene, against brute force (`measured`:
/// with the measured tiny-leaf PDACRT).
fn fuzz(tris: &[[Vec3; 3]], extra_rays: &[Ray], measured: bool, what: &str) {
    fuzz_with(tris, 3000, extra_rays, measured, what);
}

/// [`fuzz`] with `n_rays` random rays.
fn fuzz_with(tris: &[[Vec3; 3]], n_rays: usize, extra_rays: &[Ray], measured: bool, what: &str) {
    let scene = scene_from_triangles(tris);
    let casters = casters_under_test(&scene, measured);
    let mut r = rng(17);
    let mut rays = rays_through(&scene, &mut r, n_rays);
    rays.extend_from_slice(extra_rays);
    let brute = BruteForce::new(&scene);
    assert_closest_agree(&brute, &casters, &rays, what);
    let segments: Vec<Ray> = rays.iter().map(|ray| Ray { t_max: r.uniform() * 4.0, ..*ray }).collect();
    assert_occluded_agree(&brute, &casters, &segments, what);
}

#[test]
fn two_thousand_coincident_triangles() {
    // Every ray that meets one meets all of them at the same distance, so no split can
    // separate them and each caster tests them all per ray (10,000 copies took seven
    // minutes of the suite; what is under test, splits that cannot separate them and a
    // bounded depth, is the same at any count). The measured tiny-leaf PDACRT, which
    // counts every instruction of every test, sees 250 copies (2,000 took 40 s). Every
    // ray meets all or none of the copies, so 1,000 random rays (3,000 took 13 s of the
    // suite) reach each caster's deepest level as often as it needs.
    let t = [Vec3::new(-1.0, -1.0, 0.0), Vec3::new(1.0, -1.0, 0.0), Vec3::new(0.0, 1.0, 0.0)];
    let down = [Ray::new(Vec3::new(0.0, 0.0, 2.0), -Vec3::Z)];
    fuzz_with(&vec![t; 2_000], 1000, &down, false, "coincident");
    fuzz_with(&vec![t; 250], 1000, &down, true, "coincident (measured)");
}

#[test]
fn axis_aligned_rays_split_planes_and_shared_edges() {
    // A 16x16 grid of unit quads in z = 0: every split plane of the recursion falls on
    // grid lines, where the quads' shared edges are.
    let tris = quad_grid(16);
    let mut extra = Vec::new();
    for k in 0..=32 {
        let c = k as f32 * 0.5;
        extra.push(Ray::new(Vec3::new(c, c, 5.0), -Vec3::Z)); // through vertices and edges
        extra.push(Ray::new(Vec3::new(8.0, c, 5.0), -Vec3::Z)); // on the first split plane x = 8
        extra.push(Ray::new(Vec3::new(-1.0, c, 0.0), Vec3::X)); // in the plane of the grid
        extra.push(Ray::new(Vec3::new(c, -1.0, 1.0), Vec3::Y)); // parallel, above it
    }
    fuzz(&tris, &extra, true, "grid");
}

#[test]
fn one_huge_triangle_among_small_ones_and_zero_area_triangles() {
    let mut r = rng(21);
    let mut tris = vec![[Vec3::new(-1e4, -1e4, 0.5), Vec3::new(1e4, -1e4, 0.5), Vec3::new(0.0, 1e4, 0.5)]];
    for _ in 0..500 {
        let p = random_in_box(&mut r, Vec3::splat(-2.0), Vec3::splat(2.0));
        tris.push([p, p + random_dir(&mut r) * 0.2, p + random_dir(&mut r) * 0.2]);
    }
    for _ in 0..100 {
        let p = random_in_box(&mut r, Vec3::splat(-2.0), Vec3::splat(2.0));
        tris.push([p, p, p + Vec3::X]); // zero area: two corners coincide
        tris.push([p, p + Vec3::Y, p + 2.0 * Vec3::Y]); // zero area: collinear
    }
    fuzz(&tris, &[], true, "huge+degenerate");
}

#[test]
fn empty_batches_and_batches_that_hit_nothing() {
    let scene = cornell_box();
    for c in casters_under_test(&scene, true) {
        assert_eq!(c.closest(&[], &mut []).rays, 0);
        assert_eq!(c.occluded(&[], &mut []).rays, 0);
        let away: Vec<Ray> = (0..5000).map(|i| Ray::new(Vec3::new(i as f32 * 0.001, 50.0, 0.0), Vec3::Y)).collect();
        let mut hits = vec![Hit { t: 1.0, prim: 0, u: 0.0, v: 0.0 }; away.len()];
        c.closest(&away, &mut hits);
        assert!(hits.iter().all(|h| !h.is_hit()), "{}", c.name());
        let mut occ = vec![true; away.len()];
        c.occluded(&away, &mut occ);
        assert!(occ.iter().all(|&o| !o));
        let bad = [Ray::new(Vec3::NAN, Vec3::X), Ray::new(Vec3::ZERO, Vec3::ZERO)];
        let mut hits = [Hit { t: 1.0, prim: 0, u: 0.0, v: 0.0 }; 2];
        c.closest(&bad, &mut hits);
        assert!(hits.iter().all(|h| !h.is_hit()));
    }
}

#[test]
fn dacrt_reports_bounded_working_memory() {
    let scene = cornell_box();
    let [primary, ..] = batches(&scene, 64, 64, 0);
    let d = Dacrt::new(&scene);
    let mut hits = vec![Hit::MISS; primary.len()];
    let stats = d.closest(&primary, &mut hits);
    let n = primary.len();
    // ids + keys + reciprocals, plus copies at the parallel levels: within a few times
    // the per-ray state, never anything like rays × triangles.
    assert!(stats.peak_working_bytes >= n * 24, "{}", stats.peak_working_bytes);
    assert!(stats.peak_working_bytes <= n * 24 + 8 * (n + 32) * 4 * 2, "{}", stats.peak_working_bytes);
}

#[test]
fn pdacrt_level_records_add_up_and_depth_is_bounded() {
    let scene = cornell_box();
    let [primary, ..] = batches(&scene, 64, 64, 0);
    let p =
        Pdacrt::from_triangles(&scene.triangle_vertices(), PdacrtParams { measure: true, ..PdacrtParams::default() });
    let mut hits = vec![Hit::MISS; primary.len()];
    let stats = p.closest(&primary, &mut hits);
    let levels = p.levels();
    assert!(!levels.is_empty());
    // Level 0 is the root with every ray that enters the scene and every triangle.
    assert_eq!((levels[0].nodes, levels[0].rays, levels[0].triangle_refs), (1, primary.len(), 32));
    for w in levels.windows(2) {
        // The next level's nodes are the inner children of this one: at most two each.
        assert!(w[1].nodes <= 2 * w[0].nodes);
        assert_eq!(w[1].level, w[0].level + 1);
    }
    assert!(levels.len() as u32 <= PdacrtParams::default().max_depth + 1);
    assert!(levels.iter().map(|l| l.terminal_nodes).sum::<usize>() > 0);
    for l in &levels {
        assert_eq!(l.id_bytes, (l.rays + l.triangle_refs) * 8);
        let names: Vec<&str> = l.kernels.iter().map(|k| k.name).collect();
        for k in [
            "pdacrt::split_nodes",
            "pdacrt::filter_rays",
            "pdacrt::filter_triangles",
            "pdacrt::count_codes",
            "simt::scan_tiles",
            "pdacrt::scatter_rays",
        ] {
            assert!(names.contains(&k), "level {} lacks {k}: {names:?}", l.level);
        }
        assert!(l.kernels.iter().all(|k| k.simd_efficiency.is_some_and(|e| e > 0.0 && e <= 1.0)));
    }
    // Working memory is the id arrays and per-ray state: far below rays × triangles.
    assert!(stats.peak_working_bytes > primary.len() * 8);
    assert!(stats.peak_working_bytes < primary.len() * 400, "{}", stats.peak_working_bytes);
    // The device's statistics name the brute-force kernel with its shared memory.
    let k = p.device().kernel_stats();
    let bf = k.iter().find(|k| k.name == "pdacrt::brute_force").expect("terminal nodes were solved");
    assert_eq!(bf.shared_bytes, warpray::pdacrt::BRUTE_FORCE_SHARED_BYTES);
}

#[test]
fn depth_cap_holds_on_coincident_triangles_with_tiny_leaves() {
    // Tiny leaves would split forever without the guards: coincident triangles never
    // separate, so the no-progress rule must make the root's children terminal.
    let t = [Vec3::new(-1.0, -1.0, 0.0), Vec3::new(1.0, -1.0, 0.0), Vec3::new(0.0, 1.0, 0.0)];
    let tris = vec![t; 2000];
    let params = PdacrtParams { leaf_rays: 1, leaf_triangles: 1, ..PdacrtParams::default() };
    let p = Pdacrt::from_triangles(&tris, params);
    let rays: Vec<Ray> = (0..500).map(|i| Ray::new(Vec3::new(-0.5 + i as f32 * 0.002, 0.0, 1.0), -Vec3::Z)).collect();
    let mut hits = vec![Hit::MISS; rays.len()];
    p.closest(&rays, &mut hits);
    assert!(hits.iter().all(|h| h.is_hit() && (h.t - 1.0).abs() < 1e-6 && h.prim == 0), "smallest id wins ties");
    assert!(p.levels().len() as u32 <= params.max_depth + 1);
}

/// PDACRT keeps its workspace between calls (buffers with stale contents of a larger
/// batch): every call still matches brute force, the same batch gives the same hits and
/// reports the same working set again, and a batch after a larger one matches a fresh
/// caster's result.
#[test]
fn pdacrt_reuses_its_workspace_without_changing_results() {
    let scene = cornell_box();
    let [primary, shadow, specular, ambient] = batches(&scene, 32, 32, 4);
    let oracle = BruteForce::new(&scene);
    let reused = Pdacrt::new(&scene);
    let closest = |c: &dyn RayCaster, rays: &[Ray]| {
        let mut h = vec![Hit::MISS; rays.len()];
        let st = c.closest(rays, &mut h);
        (h.iter().map(|h| (h.is_hit(), h.prim, h.t.to_bits())).collect::<Vec<_>>(), (st.peak_working_bytes, st.tests))
    };
    let (first, first_peak) = closest(&reused, &ambient);
    for rays in [&primary, &specular] {
        let fresh = Pdacrt::new(&scene);
        assert_eq!(closest(&reused, rays).0, closest(&fresh, rays).0);
        let (mut a, mut b) = (vec![false; shadow.len()], vec![false; shadow.len()]);
        reused.occluded(&shadow, &mut a);
        oracle.occluded(&shadow, &mut b);
        assert_eq!(a, b);
    }
    let (again, again_peak) = closest(&reused, &ambient);
    assert_eq!(first, again);
    assert_eq!(
        first_peak, again_peak,
        "a reused workspace counts in the call's working set; its test counter restarts"
    );
    let mut want = vec![Hit::MISS; ambient.len()];
    oracle.closest(&ambient, &mut want);
    assert!(want.iter().zip(&first).all(|(w, g)| w.is_hit() == g.0 && (!w.is_hit() || w.prim == g.1)));
}

/// A DACRT call reports its stages in order; the stages that run one after another add
/// up to no more than the call, the two halves of `prepare` (run side by side) each fit
/// in it, the shared top's three stages fit in its half, and the groups' longest time
/// fits in their summed time. Other casters report none.
#[test]
fn dacrt_reports_its_stages() {
    let scene = cornell_box();
    let [primary, ..] = batches(&scene, 64, 64, 0);
    // Cells of 8 triangles: the Cornell box's shared top has planes.
    let d = Dacrt::new(&scene).with_params(DacrtParams { top_cell_triangles: 8, ..DacrtParams::default() });
    assert!(d.phase_seconds().is_empty(), "no call yet");
    let st = d.closest(&primary, &mut vec![Hit::MISS; primary.len()]);
    let phases = d.phase_seconds();
    let names: Vec<&str> = phases.iter().map(|p| p.0).collect();
    assert_eq!(
        names,
        [
            "filter",
            "prepare",
            "prepare_top",
            "prepare_rays",
            "top_plan",
            "top_route",
            "top_gather",
            "groups",
            "groups_busy",
            "groups_longest",
            "back"
        ]
    );
    let at = |n: &str| phases.iter().find(|p| p.0 == n).unwrap().1;
    assert!(phases.iter().all(|p| p.1.is_finite() && p.1 >= 0.0), "{phases:?}");
    let laps = at("filter") + at("prepare") + at("groups") + at("back");
    assert!(laps <= st.seconds, "stages {laps} s in a call of {} s", st.seconds);
    assert!(at("prepare_top") <= at("prepare") && at("prepare_rays") <= at("prepare"), "{phases:?}");
    let top = at("top_plan") + at("top_route") + at("top_gather");
    assert!(top <= at("prepare_top") && at("top_plan") > 0.0, "{phases:?}");
    assert!(at("groups_longest") <= at("groups_busy") && at("groups_busy") > 0.0, "{phases:?}");
    assert!(BruteForce::new(&scene).phase_seconds().is_empty());
}

#[test]
fn dacrt_pdacrt_and_both_bvhs_keep_the_smallest_key_where_triangles_tie() {
    // Rays aimed exactly at corners and edge midpoints, where several triangles are hit
    // at one distance and the smallest id must win (brute force's answer), bit for bit.
    // A box culled at the best distance itself, unwidened, loses some of these ties: a
    // ray entering a box exactly at its best hit computes an entry a rounding above it
    // (the GPU BVH twin and PDACRT's `filter_rays` both did so on the conference room,
    // and DACRT's ray partition on this waving grid).
    let mut r = rng(29);
    let grid = warpray::cast::batches::waving_grid(24, 0.3);
    let tilted: Vec<[Vec3; 3]> =
        quad_grid(12).iter().map(|t| t.map(|p| Vec3::new(p.x, p.y + 0.37 * p.x, p.z - 0.21 * p.y))).collect();
    for (tris, what) in [(cornell_box().triangle_vertices(), "cornell"), (grid, "waving grid"), (tilted, "tilted grid")]
    {
        let scene = scene_from_triangles(&tris);
        let rays = rays_at_corners(&scene, &mut r);
        let mut want = vec![Hit::MISS; rays.len()];
        BruteForce::new(&scene).closest(&rays, &mut want);
        let tiny = PdacrtParams { leaf_rays: 4, leaf_triangles: 2, ..PdacrtParams::default() };
        let tiny_dacrt =
            DacrtParams { leaf_rays: 1, leaf_triangles: 1, sampled_min_pairs: 1, ..DacrtParams::default() };
        // Shared-top cells of 64 triangles, laid out for the call or gathered by id: a
        // cell's slots are not the scene's ids, and its ties must still go to the
        // smaller scene id.
        let cells = DacrtParams { top_cell_triangles: 64, ..DacrtParams::default() };
        let casters: [(&str, Box<dyn RayCaster>); 10] = [
            ("bvh4", Box::new(Bvh4::from_triangles(tris.clone()))),
            ("bvh4, packets of 8", Box::new(Bvh4::from_triangles(tris.clone()).max_packet(8))),
            ("bvh4, one ray at a time", Box::new(Bvh4::from_triangles(tris.clone()).single_rays())),
            ("lbvh", Box::new(Lbvh::on_device(&tris, simt::Device::default()))),
            ("pdacrt", Box::new(Pdacrt::from_triangles(&tris, PdacrtParams::default()))),
            ("pdacrt, tiny leaves", Box::new(Pdacrt::from_triangles(&tris, tiny))),
            ("dacrt", Box::new(Dacrt::from_triangles(tris.clone(), DacrtParams::default()))),
            ("dacrt, tiny leaves", Box::new(Dacrt::from_triangles(tris.clone(), tiny_dacrt))),
            ("dacrt, cells of 64", Box::new(Dacrt::from_triangles(tris.clone(), cells))),
            (
                "dacrt, cells of 64 by id",
                Box::new(Dacrt::from_triangles(tris.clone(), DacrtParams { cell_layout: false, ..cells })),
            ),
        ];
        for (caster, c) in casters {
            let mut got = vec![Hit::MISS; rays.len()];
            c.closest(&rays, &mut got);
            let lost: Vec<usize> = (0..rays.len())
                .filter(|&i| (got[i].t.to_bits(), got[i].prim) != (want[i].t.to_bits(), want[i].prim))
                .collect();
            assert!(
                lost.is_empty(),
                "{what}, {caster}: {} of {} rays differ from brute force, first {:?}: {:?} vs {:?}",
                lost.len(),
                rays.len(),
                rays[lost[0]],
                got[lost[0]],
                want[lost[0]]
            );
        }
    }
}
