//! PDACRT's brute-force kernel declares its arithmetic as the GPU twin compiles it
//! (`docs/gpu-check.md`, "Instruction weights"): each ray–triangle test, the path past
//! the edge test, and the staging loop, at their sm_90 instruction counts. A known
//! answer on one warp: the weights, and the path past the edges issued per trip of the
//! lockstep test loop for the lanes on it.

use warpray::cast::RayCaster;
use warpray::geometry::{Hit, Ray};
use warpray::glam::Vec3;
use warpray::pdacrt::{Pdacrt, PdacrtParams};

#[test]
fn brute_force_counts_its_tests_and_the_path_past_the_edges_per_trip() {
    // Ten triangles: A (z = -0.5, over x + y < 2) and B (z = -0.7, over 2 < x, (x - 2) +
    // y < 2) in the middle of the list, eight far to the side.
    let flat = |x: f32, z: f32| [Vec3::new(x, 0.0, z), Vec3::new(x + 2.0, 0.0, z), Vec3::new(x, 2.0, z)];
    let mut tris: Vec<[Vec3; 3]> = (0..8).map(|k| flat(100.0 + 3.0 * k as f32, -1.0)).collect();
    tris.insert(2, flat(0.0, -0.5));
    tris.insert(5, flat(2.0, -0.7));
    // One warp of rays straight down: lanes 0-15 over A only, lanes 16-31 over B only.
    let rays: Vec<Ray> = (0..32)
        .map(|k| {
            let x = if k < 16 { 0.1 + 0.05 * k as f32 } else { 2.1 + 0.05 * (k - 16) as f32 };
            Ray::new(Vec3::new(x, 0.1, 1.0), Vec3::NEG_Z)
        })
        .collect();
    let params = PdacrtParams {
        // The root's children are terminal; one warp per block; no host shortcut.
        leaf_rays: 1000,
        leaf_triangles: 1000,
        brute_force_block: 32,
        measure: true,
        tiny_batch: 0,
        ..Default::default()
    };
    let p = Pdacrt::from_triangles(&tris, params);
    let mut hits = vec![Hit::MISS; rays.len()];
    p.closest(&rays, &mut hits);
    assert!(hits[..16].iter().all(|h| h.prim == 2 && (h.t - 1.5).abs() < 1e-5), "{:?}", &hits[..16]);
    assert!(hits[16..].iter().all(|h| h.prim == 5 && (h.t - 1.7).abs() < 1e-5), "{:?}", &hits[16..]);
    let log = p.device().launch_log();
    let bf: Vec<_> = log.iter().filter(|r| r.name == "pdacrt::brute_force").collect();
    assert_eq!(bf.len(), 1, "one brute-force launch");
    let tests = &bf[0].regions[0];
    // The root's split leaves the eight far triangles in a child no ray enters, so the
    // one terminal node holds A and B and all 32 rays (one block, one warp).
    // Tests: 2 per lane, 102 instructions each besides the shared load (closest hit),
    // all 32 lanes. Past the edges: A on one trip (16 lanes) and B on the other (16
    // lanes), 28 each, and a distance in range, so 13 more for the candidate key: two
    // warp instructions of 16 lanes each, not one of 32. Staging: 2 triangles, one
    // 19-instruction trip for lanes 0 and 1, and one stage: the rays' set-up, 104 for
    // every lane. No search steps: one terminal node. (The weights are derived from the
    // twin's SASS by `cast::pdacrt::tests`.)
    let issued = 2 * 102 + 2 * 28 + 2 * 13 + 19 + 104;
    let active = 32 * 2 * 102 + 32 * 28 + 32 * 13 + 2 * 19 + 32 * 104;
    assert_eq!((tests.issued, tests.active), (issued, active));
}
