//! Known answers for the arithmetic `pdacrt::node_bounds` declares: one warp whose lanes
//! change node at different trips of their runs.

use super::kernels::{BOUNDS_RUN, EMPTY_ORDERED, node_bounds, ordered};
use simt::{Device, DeviceConfig};

/// 32 threads of 32 references each. Lane `l` walks node `2l` and, from trip
/// `1 + l % 4` on, node `2l + 1`: one flush inside the loop (at one of four trips, eight
/// lanes each) and one after it. The twin's SASS counts (per lane): 33 after the bounds
/// check, 5 + 38 per trip, 2 + 7 + 6 · (6 + 1) = 51 for a flush inside the loop,
/// 3 between the loop and the last flush, 2 + 6 · (6 + 1) = 44 for the last one. The
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
    let per_lane = 33 + BOUNDS_RUN as u64 * (5 + 38) + 51 + 3 + 44;
    let issued = 33 + BOUNDS_RUN as u64 * (5 + 38) + 4 * 51 + 3 + 44;
    let work = &rec.regions[0];
    assert_eq!((work.name, work.issued, work.active), ("bounds", issued, lanes as u64 * per_lane));
}

/// One warp of 32 children (16 nodes) through `pdacrt::classify_children`, each arm of
/// its SASS taken by some lanes: nodes 0-3 separate nothing (child 0 terminal after the
/// stuck arm's leaf rule, child 1 dropped), nodes 4-9 split with many rays (inner, after
/// the depth test), nodes 10-15 with few rays and many pairs (inner, after the pairs
/// test). Per lane: 27 + 9 + 11 + 18 = 65, 27 + 9 + 18 = 54, 27 + 9 + 4 + 3 + 3 + 2 + 18
/// = 66 and 27 + 9 + 4 + 3 + 8 + 2 + 18 = 71; each block one warp instruction.
#[test]
fn classify_children_declares_its_sass_counts_arm_by_arm() {
    use super::kernels::{BOTH, ChildData, DROPPED, INNER, LEFT, LeafRule, NodeData, RIGHT, TERMINAL, classify_child};
    let dev = Device::new(DeviceConfig { measure: true, ..Default::default() });
    // (rays L, B, R), (triangles L, B, R) per node.
    let counts = |n: usize| match n {
        0..4 => ([10, 0, 0], [100, 0, 0]),
        4..10 => ([40, 5, 40], [200, 10, 200]),
        _ => ([10, 0, 10], [300, 0, 300]),
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
    let want: Vec<u32> =
        (0..32).map(|c| if c < 8 { if c % 2 == 0 { TERMINAL } else { DROPPED } } else { INNER }).collect();
    assert_eq!(kinds, want);
    let issued = 27 + 9 + 11 + 9 + 4 + 3 + 3 + 8 + 2 + 18;
    let active = 4 * 65 + 4 * 54 + 12 * 66 + 12 * 71;
    let work = &rec.regions[0];
    assert_eq!((work.name, work.issued, work.active), ("classify", issued, active));
}
