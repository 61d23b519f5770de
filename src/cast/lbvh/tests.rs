use super::kernels::*;
use super::*;
use crate::cast::BruteForce;
use crate::geometry::Aabb;
use glam::Vec3;

fn random_triangles(n: usize, seed: u64) -> Vec<[Vec3; 3]> {
    let mut rng = crate::sampling::Rng::for_sample(seed, 0, 0);
    let mut p = || Vec3::new(rng.uniform(), rng.uniform(), rng.uniform());
    (0..n)
        .map(|_| {
            let c = p() * 4.0 - 2.0;
            [c, c + (p() - 0.5) * 0.6, c + (p() - 0.5) * 0.6]
        })
        .collect()
}

fn random_rays(n: usize, seed: u64) -> Vec<Ray> {
    let mut rng = crate::sampling::Rng::for_sample(seed, 1, 0);
    let mut p = || Vec3::new(rng.uniform(), rng.uniform(), rng.uniform());
    (0..n)
        .map(|k| {
            let o = p() * 8.0 - 4.0;
            let target = p() * 3.0 - 1.5;
            let mut r = Ray::new(o, target - o);
            if k % 3 == 0 {
                r.t_max = 0.7; // segments, some of which end before their hit
            }
            r
        })
        .collect()
}

#[test]
fn spread_and_morton_codes_have_known_answers() {
    let b = Aabb { min: Vec3::ZERO, max: Vec3::ONE };
    // The top corner: all 30 bits; the bottom one none; x alone lands on bits 2, 5, ...
    assert_eq!(morton(Vec3::ONE, &b), (1 << 30) - 1);
    assert_eq!(morton(Vec3::ZERO, &b), 0);
    assert_eq!(morton(Vec3::new(1.0, 0.0, 0.0), &b), 0x2492_4924);
    // 0.5 is step 512, the highest of ten bits: bit 27 for y.
    assert_eq!(morton(Vec3::new(0.0, 0.5, 0.0), &b), 1 << 28);
    // A flat box quantises that axis to the middle; NaN to 0.
    let flat = Aabb { min: Vec3::ZERO, max: Vec3::new(1.0, 1.0, 0.0) };
    assert_eq!(morton(Vec3::ZERO, &flat), 1 << 27);
    assert_eq!(morton(Vec3::new(f32::NAN, 0.0, 0.0), &b), 0);
}

/// Every leaf below `node`, and checks that each inner node's box holds its subtree's
/// triangles' boxes.
fn leaves_below(bvh: &Lbvh, child: i32, out: &mut Vec<u32>) -> Aabb {
    let sorted = bvh.sorted.as_slice();
    if child < 0 {
        out.push(!child as u32);
        let [a, b, c] = crate::cast::flat::corners(sorted[!child as usize]);
        return Aabb::from_points(&[a, b, c]);
    }
    let node = bvh.nodes.as_slice()[child as usize];
    let mut union = Aabb::EMPTY;
    for side in 0..2 {
        let below = leaves_below(bvh, node.child.0[side], out);
        assert_eq!(Node::child_box(&node.boxes, side), below, "node {child} side {side}: its box is its subtree's");
        union = union.union(below);
    }
    union
}

#[test]
fn the_hierarchy_holds_every_triangle_once_in_fitted_boxes() {
    for (n, measured) in [(1, false), (2, false), (3, true), (1000, false), (777, true)] {
        let tris = random_triangles(n, n as u64);
        let dev = Device::default();
        dev.set_measure(measured);
        let bvh = Lbvh::on_device(&tris, dev);
        let mut leaves = Vec::new();
        leaves_below(&bvh, bvh.root(), &mut leaves);
        leaves.sort_unstable();
        assert_eq!(leaves, (0..n as u32).collect::<Vec<_>>(), "{n} triangles: each leaf once");
        // The sorted triangles are the originals, permuted by the ids.
        for (k, &id) in bvh.ids.as_slice().iter().enumerate() {
            assert_eq!(bvh.sorted.as_slice()[k], bvh.tris.as_slice()[id as usize]);
        }
    }
}

#[test]
fn keys_equal_brute_force_measured_or_not() {
    let tris = random_triangles(1500, 3);
    let rays = random_rays(3000, 4);
    let brute = BruteForce::from_triangles(tris.clone());
    let mut want = vec![Hit::MISS; rays.len()];
    brute.closest(&rays, &mut want);
    let mut want_blocked = vec![false; rays.len()];
    brute.occluded(&rays, &mut want_blocked);
    assert!(want.iter().filter(|h| h.is_hit()).count() > 500, "the rays hit something");
    for measured in [false, true] {
        let dev = Device::default();
        dev.set_measure(measured);
        let bvh = Lbvh::on_device(&tris, dev);
        let mut got = vec![Hit::MISS; rays.len()];
        let stats = bvh.closest(&rays, &mut got);
        for (i, (g, w)) in got.iter().zip(&want).enumerate() {
            assert_eq!((g.t.to_bits(), g.prim), (w.t.to_bits(), w.prim), "ray {i} (measured: {measured})");
        }
        assert!(stats.tests > 0 && stats.tests < rays.len() as u64 * 200, "tests {}", stats.tests);
        let mut blocked = vec![false; rays.len()];
        bvh.occluded(&rays, &mut blocked);
        assert_eq!(blocked, want_blocked, "occlusion (measured: {measured})");
    }
}

#[test]
fn the_warp_sums_count_each_lanes_tests_and_visits() {
    // The counters summed by shuffles and one atomic per warp equal the sum of the
    // same rays traced one per launch (one lane, nothing to shuffle), measured or not.
    let tris = random_triangles(300, 9);
    let rays = random_rays(1000, 10);
    let alone = Lbvh::on_device(&tris, Device::default());
    let (mut tests, mut visits) = (0, 0);
    for r in &rays {
        let (_, t, v) = alone.trace_keys(std::slice::from_ref(r), false);
        (tests, visits) = (tests + t, visits + v);
    }
    assert!(visits > rays.len() as u64 && tests > 0);
    for measured in [false, true] {
        let dev = Device::default();
        dev.set_measure(measured);
        let bvh = Lbvh::on_device(&tris, dev);
        let (_, t, v) = bvh.trace_keys(&rays, false);
        assert_eq!((t, v), (tests, visits), "measured: {measured}");
        if measured {
            let trace = bvh.device().kernel_stats().into_iter().find(|k| k.name == "bvh::trace").unwrap();
            assert!(trace.simd_efficiency().is_some_and(|e| e > 0.0 && e <= 1.0));
        }
    }
}

#[test]
fn empty_and_degenerate_input_is_harmless() {
    let none = Lbvh::on_device(&[], Device::default());
    let rays = random_rays(40, 1);
    let mut hits = vec![Hit::MISS; rays.len()];
    none.closest(&rays, &mut hits);
    assert!(hits.iter().all(|h| !h.is_hit()));
    // Identical triangles (equal codes: the index breaks ties) and invalid rays.
    let same = vec![[Vec3::ZERO, Vec3::X, Vec3::Y]; 100];
    let bvh = Lbvh::on_device(&same, Device::default());
    let mut rays = vec![Ray::new(Vec3::new(0.2, 0.2, 1.0), Vec3::NEG_Z); 50];
    rays.push(Ray::new(Vec3::splat(f32::NAN), Vec3::Z));
    rays.push(Ray::new(Vec3::ZERO, Vec3::ZERO));
    let mut hits = vec![Hit::MISS; rays.len()];
    bvh.closest(&rays, &mut hits);
    assert!(hits[..50].iter().all(|h| h.prim == 0 && h.t == 1.0), "the smallest id wins a tie: {:?}", hits[0]);
    assert!(!hits[50].is_hit() && !hits[51].is_hit());
    bvh.closest(&[], &mut []);
}

const SASS: &str = include_str!("../../../docs/measured/bvh-kernels-sm90.sass");

/// The instruction weights the kernels declare, derived from the twin's compiled code:
/// each is the path one lane takes through a stretch of the stored SASS
/// (`docs/measured/bvh-kernels-sm90.sass`, printed by `sh cuda/kernels_sass.sh bvh`),
/// named by its first address, the address it stops at and the branches it takes, less
/// the memory instructions `simt` counts itself. A recompiled twin whose code changes
/// fails here until the weights follow it.
#[test]
fn the_kernels_weights_are_paths_through_the_twins_sass() {
    use crate::sass::{function, walk};
    let (t, f) = (true, false);
    let end = u32::MAX;
    // The two straight kernels, whole (every division on its fast path).
    let mc = function(SASS, "morton_codes");
    let whole = walk(&mc, 0, end, &[f, f, t, f, t, f, t]);
    assert_eq!((whole.work(), whole.memory), (MORTON, 6 + 9 + 2), "bounds, triangle, code and id");
    let g = walk(&function(SASS, "gather_triangles"), 0, end, &[f]);
    assert_eq!((g.work(), g.memory), (GATHER, 1 + 9 + 9 + 6));
    // emit_hierarchy, site by site: (in range, codes differ) and (outside the array).
    let e = function(SASS, "emit_hierarchy");
    let w = |from, until, taken: &[bool]| walk(&e, from, until, taken).work();
    assert_eq!(w(0, 0x120, &[f]), EMIT_HEAD);
    assert_eq!((w(0x120, 0x1f0, &[f, f]), w(0x120, 0x1f0, &[t])), DELTA_NEXT);
    assert_eq!((w(0x1f0, 0x300, &[f, f]), w(0x1f0, 0x300, &[t])), DELTA_PREV);
    assert_eq!((w(0x300, 0x470, &[f, f]), w(0x300, 0x470, &[t])), DELTA_MIN);
    assert_eq!(w(0x470, 0x4a0, &[]), DOUBLING_SETUP);
    assert_eq!((w(0x4a0, 0x4a0, &[f, f, t]), w(0x4a0, 0x4a0, &[t, t])), DOUBLING_STEP);
    assert_eq!(w(0x4a0, 0x640, &[f, f, f]), DOUBLING_STEP.0 + LOOP_EXIT, "the last trip and the loop's exit");
    assert_eq!(w(0x640, 0x6b0, &[f]), BINARY_SETUP);
    assert_eq!((w(0x6b0, 0x6b0, &[f, f, t]), w(0x6b0, 0x6b0, &[t, t])), BINARY_STEP);
    assert_eq!(w(0x6b0, 0x870, &[f, f, f]), BINARY_STEP.0 + LOOP_EXIT);
    assert_eq!(w(0x870, 0x9b0, &[f, f]), DELTA_NODE.0);
    assert_eq!(w(0x9b0, 0x9e0, &[]), SPLIT_SETUP);
    assert_eq!((w(0x9e0, 0x9e0, &[f, f, t]), w(0x9e0, 0x9e0, &[t, t])), SPLIT_STEP);
    assert_eq!(w(0x9e0, 0xbc0, &[f, f, f]), SPLIT_STEP.0 + LOOP_EXIT);
    assert_eq!((w(0xbc0, end, &[t]), w(0xbc0, end, &[f])), (EMIT_TAIL, EMIT_TAIL_ROOT));
    // fit_boxes: the head, then per level up to the atomic, its test, and the second
    // arrival's union and loop test (the same at the root, where the loop ends).
    let fb = function(SASS, "fit_boxes");
    let path = |from, until, taken: &[bool]| walk(&fb, from, until, taken);
    assert_eq!((path(0, 0x1d0, &[f, f]).work(), path(0, 0x1d0, &[f, f]).memory), (FIT_HEAD, 7));
    let step = path(0x1d0, 0x2b0, &[]);
    assert_eq!((step.work(), step.memory), (FIT_STEP, 4), "three 8-byte stores and the atomic");
    assert_eq!(path(0x2b0, end, &[t]).work(), FIT_ARRIVAL, "the first arrival leaves");
    let second = path(0x2b0, 0x1d0, &[f, t]);
    assert_eq!((second.work(), second.memory), (FIT_ARRIVAL + FIT_UNION, 7));
    assert_eq!(path(0x2b0, end, &[f, f]).work(), FIT_ARRIVAL + FIT_UNION);
    // trace: a valid ray's set-up to the loop's head (0xc10).
    let tr = function(SASS, "5trace");
    let path = |from, until, taken: &[bool]| walk(&tr, from, until, taken);
    let head = path(0, 0xc10, &[&[f; 9][..], &[t; 6]].concat());
    assert_eq!((head.work(), head.memory), (TRACE_HEAD, 8 + 3 + 1), "the ray, its direction again, t_max");
    // An inner node (both boxes' slab tests with every axis finite), then each arm.
    let visit = path(0xc10, 0x15c0, &[f, t, t, t, t, t, t]);
    assert_eq!((visit.work(), visit.memory), (VISIT, 4 + 3 + 1), "t_min and origin, three quads, the children");
    assert_eq!(path(0x15c0, 0xc10, &[t]).work(), VISIT_BOTH, "both: the push (STL), back to the head");
    assert_eq!(path(0x15c0, 0xc10, &[f, f]).work(), VISIT_ONE);
    assert_eq!(path(0x15c0, 0x27d0, &[f, t]).work(), VISIT_NONE);
    assert_eq!(path(0x27d0, 0xc10, &[f]).work(), POP, "the pop (LDL)");
    assert_eq!(path(0x27d0, 0x2840, &[t]).work(), LOOP_END);
    // A leaf, closest hit: edges fail; past them, distance outside; the candidate.
    let far = [f, f, f]; // the cull distance's next float up: finite, non-zero
    let leaf = |rest: &[bool]| path(0xc10, 0x27d0, &[&[t, t][..], &far, rest].concat());
    assert_eq!((leaf(&[t, t]).work(), leaf(&[t, t]).memory), (TEST, 4 + 9), "origin, t_min, the triangle");
    assert_eq!(leaf(&[t, f, f, t, t]).work(), TEST + PAST_EDGES);
    let hit = leaf(&[t, f, f, t, f]);
    assert_eq!((hit.work(), hit.memory), (TEST + PAST_EDGES + CANDIDATE, 4 + 9 + 1), "and the id");
    // Any hit: edges fail; past them, distance outside; the hit leaves the loop.
    let miss = path(0xc10, 0x27d0, &[t, f, t]);
    assert_eq!((miss.work(), miss.memory), (ANY_HIT_TEST, 4 + 9 + 1), "and t_max");
    assert_eq!(path(0xc10, 0x27d0, &[t, f, f, f, t, t]).work(), ANY_HIT_TEST + PAST_EDGES);
    assert_eq!(path(0xc10, 0x2840, &[t, f, f, f, t, f]).work(), ANY_HIT_TEST + PAST_EDGES + ANY_HIT_LEAVE);
    // After the loop: the key's store and two warp sums of 64-bit counts (20 shuffles,
    // of which the model issues 10 itself), lane 0's reductions apart.
    let (lane0, other) = (path(0x2840, end, &[f, f]), path(0x2840, end, &[t, t]));
    assert_eq!((other.work() - 10, other.memory), (TRACE_TAIL, 1));
    assert_eq!((lane0.work() - other.work(), lane0.memory), (TRACE_TAIL_LANE0.iter().sum(), 3));
}
