//! Known answers for the arithmetic `pdacrt::node_bounds` declares: one warp whose lanes
//! change node at different trips of their runs.

use super::kernels::*;
use crate::sass::{function, walk};
use simt::{Device, DeviceConfig};

/// The twin's kernels as nvcc 13.0 compiled them for sm_90.
const SASS: &str = include_str!("../../../docs/measured/pdacrt-kernels-sm90.sass");

/// 32 threads of 32 references each. Lane `l` walks node `2l` and, from trip
/// `1 + l % 4` on, node `2l + 1`: one flush inside the loop (at one of four trips, eight
/// lanes each) and one after it, every word of both making its atomic. Each lane's
/// declared work must be its path through the twin's SASS, walked branch by branch. The
/// lanes run their trips in step, so the flushes at four different trips are four warp
/// instructions each, not one.
#[test]
fn node_bounds_declares_its_sass_counts_with_trips_in_step() {
    let dev = Device::new(DeviceConfig { measure: true, ..Default::default() });
    let lanes = 32;
    let refs = lanes * BOUNDS_RUN;
    // Four triangles, reference i uses triangle i % 4.
    let tri = |k: usize| {
        let o = k as f32;
        [o, 0.0, 0.0, o + 1.0, 0.0, 0.0, o, 1.0, 2.0 * o]
    };
    let tris: Vec<[f32; 9]> = (0..4).map(tri).collect();
    let ids: Vec<u32> = (0..refs as u32).map(|i| i % 4).collect();
    let change = |l: usize| 1 + l % 4;
    let nodes: Vec<u32> = (0..refs)
        .map(|i| {
            let (l, j) = (i / BOUNDS_RUN, i % BOUNDS_RUN);
            (2 * l + usize::from(j >= change(l))) as u32
        })
        .collect();
    let (tb, ib, nb) = (dev.alloc_from(&tris), dev.alloc_from(&ids), dev.alloc_from(&nodes));
    let mut bounds = dev.alloc_from(&(0..2 * lanes).flat_map(|_| EMPTY_ORDERED).collect::<Vec<u32>>());
    let rec = {
        let (tv, iv, nv, bv) = (tb.view(), ib.view(), nb.view(), bounds.view_mut());
        dev.for_each_in("pdacrt::node_bounds", &["bounds"], lanes, |t, k| node_bounds(t, &iv, &nv, &tv, &bv, k))
    };
    // The boxes are right: node 2l holds triangles 0 .. change(l) (mod 4), node 2l + 1
    // the rest of the run (all four).
    for l in 0..lanes {
        let first: Vec<usize> = (0..change(l)).map(|j| (l * BOUNDS_RUN + j) % 4).collect();
        let max_x = first.iter().map(|&k| k as f32 + 1.0).fold(f32::MIN, f32::max);
        assert_eq!(bounds.as_slice()[2 * l * 6 + 3], ordered(max_x), "node {}", 2 * l);
        assert_eq!(bounds.as_slice()[(2 * l + 1) * 6 + 5], ordered(6.0), "node {}", 2 * l + 1);
    }
    // Lane l's branches in the SASS: into the loop; per trip, the node test (taken: the
    // same node) and, at the change, five words that make their atomics (not taken) and
    // the last (not taken), then the loop's test; after the loop, six words that make
    // their atomics, the last one's exit not taken.
    let code = function(SASS, "node_bounds");
    let lane_path = |l: usize| {
        let mut taken = vec![false];
        for j in 0..BOUNDS_RUN {
            taken.push(j != change(l));
            if j == change(l) {
                taken.extend([false; 6]);
            }
            taken.push(j + 1 < BOUNDS_RUN);
        }
        taken.extend([false; 6]);
        walk(&code, 0xc0, u32::MAX, &taken).work() as u64
    };
    let active: u64 = (0..lanes).map(lane_path).sum();
    let in_loop_flush = BOUNDS_FLUSH_ADDRESS
        + BOUNDS_FLUSH_RESET
        + 5 * (BOUNDS_WORD_TEST + BOUNDS_WORD_JOIN)
        + BOUNDS_LAST_WORD_TEST
        + BOUNDS_LAST_ATOMIC_MOVE;
    let last_flush = BOUNDS_FLUSH_ADDRESS + 5 * (BOUNDS_WORD_TEST + BOUNDS_WORD_JOIN) + BOUNDS_LAST_WORD_TEST;
    let issued = (BOUNDS_HEAD
        + BOUNDS_RUN as u32 * (BOUNDS_TRIP_TEST + BOUNDS_TRIP_UNION)
        + 4 * in_loop_flush
        + BOUNDS_TAIL
        + last_flush) as u64;
    let work = &rec.regions[0];
    assert_eq!((work.name, work.issued, work.active), ("bounds", issued, active));
}

/// One warp of 32 children (16 nodes) through `pdacrt::classify_children`, each arm of
/// its SASS taken by some lanes: nodes 0-3 separate nothing (child 0 terminal after the
/// stuck arm's leaf rule, child 1 dropped), nodes 4-9 split with many rays (inner, after
/// the depth test), nodes 10-12 with few rays and many pairs (inner, after the pairs
/// test), nodes 13-15 with few rays and few pairs (terminal, after the pairs test). Each lane's declared work must be its path through the twin's SASS; each
/// block is one warp instruction.
#[test]
fn classify_children_declares_its_sass_counts_arm_by_arm() {
    let dev = Device::new(DeviceConfig { measure: true, ..Default::default() });
    // (rays L, B, R), (triangles L, B, R) per node.
    let counts = |n: usize| match n {
        0..4 => ([10, 0, 0], [100, 0, 0]),
        4..10 => ([40, 5, 40], [200, 10, 200]),
        10..13 => ([10, 0, 10], [300, 0, 300]),
        _ => ([5, 0, 5], [20, 0, 20]),
    };
    let nodes: Vec<NodeData> = (0..16)
        .map(|n| {
            let (r, t) = counts(n);
            NodeData { ray_count: r.iter().sum(), tri_count: t.iter().sum(), ..Default::default() }
        })
        .collect();
    // One side's counts per node, in the kernel's four-code layout.
    let four = |rays: bool| -> Vec<u32> {
        (0..16)
            .flat_map(|n| {
                let c = if rays { counts(n).0 } else { counts(n).1 };
                let mut w = [0u32; 4];
                for (code, v) in [LEFT, BOTH, RIGHT].into_iter().zip(c) {
                    w[code as usize] = v;
                }
                w
            })
            .collect()
    };
    let (nb, rb, tb) = (dev.alloc_from(&nodes), dev.alloc_from(&four(true)), dev.alloc_from(&four(false)));
    let mut children = dev.alloc::<ChildData>(32);
    let (mut inner, mut terminal) = (dev.alloc::<[u32; 3]>(32), dev.alloc::<[u32; 3]>(32));
    let rule = LeafRule { leaf_rays: 32, leaf_tris: 16, at_max_depth: false };
    let rec = {
        let (nv, rv, tv) = (nb.view(), rb.view(), tb.view());
        let (cv, iv, ev) = (children.view_mut(), inner.view_mut(), terminal.view_mut());
        dev.for_each_in("pdacrt::classify_children", &["classify"], 32, |t, c| {
            classify_child(t, &nv, &rv, &tv, rule, &cv, &iv, &ev, c)
        })
    };
    let kinds: Vec<u32> = children.as_slice().iter().map(|c| c.kind).collect();
    let want: Vec<u32> = (0..32)
        .map(|c| match c {
            0..8 if c % 2 == 0 => TERMINAL,
            0..8 => DROPPED,
            8..26 => INNER,
            _ => TERMINAL,
        })
        .collect();
    assert_eq!(kinds, want);
    // The branches of each kind of lane in the SASS: stuck (taken) then kept or dropped;
    // splitting (not taken), kept, more triangles than a leaf, then many rays (taken) and
    // not at the depth cap, or few rays and enough pairs to stay inner (taken) or not.
    let code = function(SASS, "classify_children");
    let lane = |taken: &[bool]| walk(&code, 0xa0, u32::MAX, taken).work() as u64;
    let (kept, dropped) = (lane(&[true, false]), lane(&[true, true]));
    let (depth, pairs) = (lane(&[false, false, false, true, false]), lane(&[false, false, false, false, true]));
    let few_pairs = lane(&[false, false, false, false, false]);
    let active = 4 * kept + 4 * dropped + 12 * depth + 6 * pairs + 6 * few_pairs;
    let issued = (CLASSIFY_HEAD
        + 2 * CLASSIFY_ARM
        + CLASSIFY_STUCK_RULE
        + CLASSIFY_TRIS_TEST
        + CLASSIFY_RAYS_TEST
        + CLASSIFY_DEPTH_TEST
        + CLASSIFY_PAIRS_TEST
        + CLASSIFY_PAIRS_JUMP
        + CLASSIFY_INNER
        + CLASSIFY_TAIL) as u64;
    let work = &rec.regions[0];
    assert_eq!((work.name, work.issued, work.active), ("classify", issued, active));
}

/// The instruction weights the kernels declare, derived from the twin's compiled code:
/// each is the path one lane takes through a stretch of the stored SASS
/// (`docs/measured/pdacrt-kernels-sm90.sass`, printed by `sh cuda/kernels_sass.sh pdacrt`),
/// named by its first address, the address it stops at and the branches it takes, less
/// the memory instructions `simt` counts itself. A recompiled twin whose code changes
/// fails here until the weights follow it.
#[test]
fn the_kernels_weights_are_paths_through_the_twins_sass() {
    let (t, f) = (true, false);
    let nb = function(SASS, "node_bounds");
    let w = |from, until, taken: &[bool]| walk(&nb, from, until, taken).work();
    assert_eq!(w(0xc0, 0x2e0, &[f]), BOUNDS_HEAD, "from the bounds check into the loop");
    assert_eq!(w(0x2e0, 0x340, &[f]), BOUNDS_TRIP_TEST, "a trip's node test, the node changing");
    assert_eq!(w(0x720, 0x2e0, &[t]), BOUNDS_TRIP_UNION, "the trip's join, the union and the loop's test");
    assert_eq!(w(0x340, 0x360, &[]), BOUNDS_FLUSH_ADDRESS);
    assert_eq!(w(0x360, 0x3d0, &[f]), BOUNDS_WORD_TEST, "the first word, up to its atomic");
    assert_eq!(w(0x3e0, 0x3f0, &[]), BOUNDS_WORD_JOIN);
    assert_eq!(w(0xd40, 0xda0, &[f]), BOUNDS_LAST_WORD_TEST, "the last flush's last word");
    assert_eq!(w(0x630, 0x700, &[f]), BOUNDS_LAST_WORD_TEST + BOUNDS_FLUSH_RESET, "the loop's last word and reset");
    assert_eq!(w(0x700, 0x720, &[]), BOUNDS_LAST_ATOMIC_MOVE);
    assert_eq!(w(0xa20, 0xa50, &[]), BOUNDS_TAIL);
    let cc = function(SASS, "classify_children");
    let w = |from, until, taken: &[bool]| walk(&cc, from, until, taken).work();
    assert_eq!(w(0xa0, 0x2d0, &[f]), CLASSIFY_HEAD);
    assert_eq!(w(0x2d0, 0x360, &[f]), CLASSIFY_ARM, "the arm that splits");
    assert_eq!(w(0x4a0, 0x530, &[f]), CLASSIFY_ARM, "the stuck arm");
    assert_eq!(w(0x530, 0x610, &[]), CLASSIFY_STUCK_RULE);
    assert_eq!(w(0x360, 0x3a0, &[f]), CLASSIFY_TRIS_TEST);
    assert_eq!(w(0x3a0, 0x3d0, &[f]), CLASSIFY_RAYS_TEST);
    assert_eq!(w(0x3d0, 0x480, &[t]), CLASSIFY_PAIRS_TEST, "the pairs test to the inner block");
    assert_eq!(w(0x3d0, 0x610, &[f]), CLASSIFY_PAIRS_TEST + CLASSIFY_PAIRS_JUMP, "the pairs test to the join");
    assert_eq!(w(0x450, 0x480, &[f]), CLASSIFY_DEPTH_TEST);
    assert_eq!(w(0x480, 0x610, &[]), CLASSIFY_INNER);
    assert_eq!(w(0x610, u32::MAX, &[]), CLASSIFY_TAIL, "the join to the exit");
    let bf = function(SASS, "brute_force");
    let path = |from, until, taken: &[bool]| walk(&bf, from, until, taken);
    assert_eq!(path(0x100, 0x100, &[t]).work(), SEARCH_STEP_INSTRUCTIONS);
    // A lane with a ray, once per stage of triangles: the shear (three divisions on their
    // fast paths) and the test loop's set-up, then the stage loop's own after the tests.
    let setup = path(0x810, 0xea0, &[f, f, t, t, t, f]).work() + path(0x2100, 0x540, &[t]).work();
    assert_eq!(setup, RAY_SETUP_INSTRUCTIONS);
    // The model counts a triangle (nine words) as one shared store and one load.
    let stage = path(0x600, 0x600, &[t]);
    assert_eq!((stage.issued, stage.memory), (31, 20));
    assert_eq!(stage.issued - 12, STAGE_STEP_INSTRUCTIONS);
    // One trip whose edge test fails: closest hit (the cull distance finite, non-zero),
    // and any hit. The nine shared loads of the triangle are one load in the model.
    let closest = path(0xea0, 0xea0, &[t, f, f, f, t, t, t]);
    assert_eq!((closest.issued - 1, closest.memory), (TEST_INSTRUCTIONS, 9));
    let any = path(0xea0, 0xea0, &[f, t, t, t]);
    assert_eq!((any.issued - 1, any.memory), (ANY_HIT_TEST_INSTRUCTIONS, 9));
    // Past the edges, to a distance outside the range (fast reciprocal), in both loops.
    assert_eq!(path(0x1db0, 0x20a0, &[f, t, t]).work(), PAST_EDGES_INSTRUCTIONS);
    assert_eq!(path(0x14a0, 0x20b0, &[f, t, t]).work(), PAST_EDGES_INSTRUCTIONS);
    // And inside it: closest hit compares the candidate key; any hit leaves the loop.
    assert_eq!(path(0x1db0, 0x20a0, &[f, t, f]).work(), PAST_EDGES_INSTRUCTIONS + CANDIDATE_INSTRUCTIONS);
    assert_eq!(path(0x14a0, 0x2100, &[f, t, f]).work(), PAST_EDGES_INSTRUCTIONS + ANY_HIT_LEAVE_INSTRUCTIONS);
}
