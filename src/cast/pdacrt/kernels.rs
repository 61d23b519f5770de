//! PDACRT's kernels. Each takes a thread and plain `Copy` data (views and work items);
//! none allocates, forks or launches. The host code in `mod.rs` launches them.
//!
//! About 770 lines on purpose: these are the stages of the paper's pipeline (filter,
//! status codes, partition, terminal brute force) in the order they run, sharing the
//! same views and work items; split, the order and the shared data would be harder to
//! follow.

use crate::cast::dacrt::leaf_pairs;
use crate::cast::flat::{corners, hit_of_key};
use crate::geometry::hit_key;
use crate::geometry::{Aabb, Hit, Ray, RayShear, cull_distance, inv_dir, triangle_test};
use glam::Vec3;
use simt::{Block, DeviceCopy, Global, GlobalMut, Place, Readable, Thread};

/// Triangle and ray codes, packed under the node id: `node << 2 | code`. In the order
/// of a segmented sort by this key, each node's elements come as L, B, R, N, so the
/// left child's elements (L, B), the right child's (B, R) and all that enter either
/// (L, B, R) are contiguous; the scatter writes exactly that order.
pub(crate) const LEFT: u32 = 0;
pub(crate) const BOTH: u32 = 1;
pub(crate) const RIGHT: u32 = 2;
pub(crate) const NEITHER: u32 = 3;

/// Key of "no hit yet"; shadow rays that are blocked get [`BLOCKED`] (`geometry::hit_key`).
pub(crate) use crate::geometry::hit_key::{BLOCKED, NONE as NO_HIT};

/// Child kinds.
pub(crate) const DROPPED: u32 = 0;
pub(crate) const INNER: u32 = 1;
pub(crate) const TERMINAL: u32 = 2;

/// Split attempts (one per axis, longest first) before a node that no plane separates
/// becomes terminal.
pub(crate) const MAX_TRIES: u32 = 3;

/// A node of a level: its box, its ranges in the level's id arrays, and how many
/// split planes already failed to separate its elements.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
#[repr(C)]
pub(crate) struct NodeData {
    pub bounds: Aabb,
    pub ray_start: u32,
    pub ray_count: u32,
    pub tri_start: u32,
    pub tri_count: u32,
    pub tries: u32,
}

/// What becomes of one child: its kind, its sizes, and where its elements go. `whole` marks the retry of a node that
/// no plane separated: it takes every element that enters the node (L, B and R).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
#[repr(C)]
pub(crate) struct ChildData {
    pub kind: u32,
    pub rays: u32,
    pub tris: u32,
    pub dest_node: u32,
    pub dest_ray: u32,
    pub dest_tri: u32,
    pub whole: u32,
}

/// Per child, what the scans count: (1 if chosen, its rays, its triangles).
pub(crate) type Triple = [u32; 3];

// SAFETY: #[repr(C)] structs of 4-byte fields without padding.
unsafe impl DeviceCopy for NodeData {}
unsafe impl DeviceCopy for ChildData {}

/// The ray's interval end: its closest hit so far, or its own `t_max`.
#[inline]
fn t_far(ray: &Ray, key: u64) -> f32 {
    if key == NO_HIT { ray.t_max } else { hit_key::t_of(key).min(ray.t_max) }
}

/// `f32` to `u32` with the same order, so boxes can grow by integer atomics.
#[inline]
pub(crate) fn ordered(x: f32) -> u32 {
    let b = x.to_bits();
    if b >> 31 == 1 { !b } else { b | 0x8000_0000 }
}

#[inline]
pub(crate) fn unordered(u: u32) -> f32 {
    f32::from_bits(if u >> 31 == 1 { u & 0x7fff_ffff } else { !u })
}

/// The empty box in the ordered encoding (min words at their largest, max at their
/// smallest): the starting value of [`node_bounds`]' atomics.
pub(crate) const EMPTY_ORDERED: [u32; 6] = [u32::MAX, u32::MAX, u32::MAX, 0, 0, 0];

/// Triangle references one thread of [`node_bounds`] walks. Short runs keep the
/// launch wide: with runs of 256 the root level of the dragon was 3,404 threads in 14
/// blocks, too few blocks for 16 CPU threads (or a GPU's 132 SMs), and the kernel
/// scaled 5x from 1 to 16 threads against 9-11x for the others.
pub(crate) const BOUNDS_RUN: usize = 32;

/// `pdacrt::node_bounds`: thread `k` grows its nodes' boxes by the triangle references
/// `k·RUN .. (k+1)·RUN` (grouped by node), one atomic min/max per word whenever the
/// node changes: afterwards `bounds[6n..6n+6]` holds the union of node `n`'s triangle
/// boxes (ordered encoding).
pub(crate) fn node_bounds(
    t: &Thread,
    tri_ids: &Global<u32>,
    tri_node: &Global<u32>,
    tris: &Global<[f32; 9]>,
    bounds: &GlobalMut<u32>,
    k: usize,
) {
    let (first, end) = (k * BOUNDS_RUN, ((k + 1) * BOUNDS_RUN).min(tri_ids.len()));
    // A word is read before its atomic, which is made only when it would change the
    // word: near the root thousands of threads share one node, and their atomics on
    // its six words were the kernel's cost at 16 threads (4.8x from 1 thread, against
    // 9-11x for the other kernels); once a box has grown, the reads find it so.
    // The arithmetic is declared with the counts of the twin's SASS (`BOUNDS_*`).
    let flush = |node: u32, b: Aabb, in_loop: bool| {
        let base = node as usize * 6;
        t.work(0, 0, BOUNDS_FLUSH_ADDRESS + if in_loop { BOUNDS_FLUSH_RESET } else { 0 });
        // Six words, unrolled in the SASS (min x, max x, min y, ...): each its own
        // instructions.
        for (copy, (word, value)) in
            (0..3).flat_map(|a| [(a, ordered(b.min[a])), (3 + a, ordered(b.max[a]))]).enumerate()
        {
            let _word = t.unroll(copy);
            let old = t.load(bounds, base + word);
            // The last word has no reconvergence of its own: it joins the trip's (in
            // the loop) or exits (after it).
            let last = copy == 5;
            t.work(0, 0, if last { BOUNDS_LAST_WORD_TEST } else { BOUNDS_WORD_TEST });
            if (word < 3 && value < old) || (word >= 3 && value > old) {
                if word < 3 {
                    t.red_min(bounds, base + word, value);
                } else {
                    t.red_max(bounds, base + word, value);
                }
                if last && in_loop {
                    t.work(0, 0, BOUNDS_LAST_ATOMIC_MOVE);
                }
            }
            if !last {
                t.work(0, 0, BOUNDS_WORD_JOIN);
            }
        }
    };
    let mut current = t.load(tri_node, first);
    t.work(0, 0, BOUNDS_HEAD);
    let mut acc = Aabb::EMPTY;
    for i in first..end {
        // Every lane makes the same trips (but the last thread's), in step: trip `j` of
        // one lane is the same warp instruction as trip `j` of another, and a flush at
        // trip 5 is not matched with another lane's flush at trip 9.
        let _trip = t.unroll(i - first);
        let node = t.load(tri_node, i);
        t.work(0, 0, BOUNDS_TRIP_TEST);
        if node != current {
            flush(current, acc, true);
            current = node;
            acc = Aabb::EMPTY;
        }
        // Three rounds a trip, as the twin's SASS issues them: the node (above), the
        // id, the triangle's nine words.
        let id = t.load(tri_ids, i) as usize;
        let tri = {
            let _together = t.loads_together();
            t.load(tris, id)
        };
        acc = acc.union(Aabb::from_points(&corners(tri)));
        t.work(0, 0, BOUNDS_TRIP_UNION);
    }
    t.work(0, 0, BOUNDS_TAIL);
    flush(current, acc, false);
}

// Instructions of `pdacrt::node_bounds` besides its loads and atomics, as the twin's
// SASS has them (sm_90; `docs/measured/pdacrt-kernels-sm90.sass`, whose paths
// `tests.rs` walks to derive each of these): after the bounds check, the addresses,
// the first node, the empty box and the loop's set-up; per trip, the node test before
// the branch, and after it the triangle's address, the box union (18 FMNMX) and the
// loop counter; per flush, the word address (and, inside the loop, the box reset); per
// word, the ordered encoding, the compare and the branch, then the reconvergence (the
// last word has neither its own set-up of the reconvergence nor the reconvergence, and
// inside the loop, a lane that makes its atomic copies the node once more); between
// the loop and the last flush, the loop's reconvergence.
pub(super) const BOUNDS_HEAD: u32 = 33;
pub(super) const BOUNDS_TRIP_TEST: u32 = 5;
pub(super) const BOUNDS_TRIP_UNION: u32 = 38;
pub(super) const BOUNDS_FLUSH_ADDRESS: u32 = 2;
pub(super) const BOUNDS_FLUSH_RESET: u32 = 7;
pub(super) const BOUNDS_WORD_TEST: u32 = 6;
pub(super) const BOUNDS_WORD_JOIN: u32 = 1;
pub(super) const BOUNDS_LAST_WORD_TEST: u32 = 5;
pub(super) const BOUNDS_LAST_ATOMIC_MOVE: u32 = 1;
pub(super) const BOUNDS_TAIL: u32 = 3;

/// `pdacrt::split_nodes`: shrinks node `n`'s box to its triangles (stored back into the
/// node) and writes children `2n` and `2n + 1`: the halves at the spatial median of the
/// box's axis number `tries` by decreasing extent.
pub(crate) fn split_node(
    t: &Thread,
    nodes: &GlobalMut<NodeData>,
    tight: &Global<u32>,
    children: &GlobalMut<Aabb>,
    n: usize,
) {
    // Every load in one round, as the twin's SASS issues them.
    let together = t.loads_together();
    let mut node = t.load(nodes, n);
    let w = |a: usize| unordered(t.load(tight, n * 6 + a));
    let union = Aabb { min: Vec3::new(w(0), w(1), w(2)), max: Vec3::new(w(3), w(4), w(5)) };
    drop(together);
    node.bounds = node.bounds.intersection(union);
    t.store(nodes, n, node);
    let axis = node.bounds.axes_by_extent()[(node.tries % MAX_TRIES) as usize];
    let (lo, hi) = node.bounds.split(axis, node.bounds.center()[axis]);
    t.store(children, 2 * n, lo);
    t.store(children, 2 * n + 1, hi);
}

#[inline]
fn code_of(left: bool, right: bool) -> u32 {
    match (left, right) {
        (true, false) => LEFT,
        (true, true) => BOTH,
        (false, true) => RIGHT,
        (false, false) => NEITHER,
    }
}

/// `pdacrt::filter_triangles`: L/B/R/N for triangle reference `i` by box overlap.
pub(crate) fn filter_triangle(
    t: &Thread,
    tri_ids: &Global<u32>,
    tri_node: &Global<u32>,
    tris: &Global<[f32; 9]>,
    children: &Global<Aabb>,
    codes: &GlobalMut<u32>,
    i: usize,
) {
    // As the twin's SASS issues them: the node with the id, then the triangle's nine
    // words, then each box word on its own between the overlap test's compares.
    let together = t.loads_together();
    let (node, id) = (t.load(tri_node, i), t.load(tri_ids, i) as usize);
    drop(together);
    let tri = {
        let _together = t.loads_together();
        t.load(tris, id)
    };
    let b = Aabb::from_points(&corners(tri));
    let overlaps = |k: usize| b.overlaps(&t.load(children, k));
    let code = code_of(overlaps(2 * node as usize), overlaps(2 * node as usize + 1));
    t.store(codes, i, node << 2 | code);
}

/// `pdacrt::filter_rays`: L/B/R/N for ray reference `i`: does the ray enter each child,
/// grown by `grow` (`geometry::batch_slack`), before its closest hit so far (early
/// termination)?
#[allow(clippy::too_many_arguments)]
pub(crate) fn filter_ray(
    t: &Thread,
    ray_ids: &Global<u32>,
    ray_node: &Global<u32>,
    rays: &Global<Ray>,
    keys: &Global<u64>,
    children: &Global<Aabb>,
    any_hit: bool,
    grow: f32,
    codes: &GlobalMut<u32>,
    i: usize,
) {
    // Seven rounds, as the twin's SASS issues them: the node with the id; the key; the
    // ray's origin, interval and first direction word; each further direction word;
    // each child's box.
    let together = t.loads_together();
    let node = t.load(ray_node, i);
    let id = t.load(ray_ids, i) as usize;
    drop(together);
    let key = t.load(keys, id);
    let code = if any_hit && key == BLOCKED {
        NEITHER
    } else {
        let together = t.loads_together();
        let o = |f: fn(&Ray) -> &f32| t.load_field(rays, id, f);
        let origin = Vec3::new(o(|r| &r.origin.x), o(|r| &r.origin.y), o(|r| &r.origin.z));
        let (t_min, t_max, dx) = (o(|r| &r.t_min), o(|r| &r.t_max), o(|r| &r.dir.x));
        drop(together);
        let dir = Vec3::new(dx, o(|r| &r.dir.y), o(|r| &r.dir.z));
        let r = Ray { origin, dir, t_min, t_max };
        let inv = inv_dir(r.dir);
        let far = cull_distance(t_far(&r, key));
        let child = |k: usize| {
            let _together = t.loads_together();
            t.load(children, k)
        };
        let enters = |k: usize| child(k).grown(grow).intersect(r.origin, inv, r.t_min, far).is_some();
        code_of(enters(2 * node as usize), enters(2 * node as usize + 1))
    };
    t.store(codes, i, node << 2 | code);
}

/// A status code as a one-hot vector over (L, B, R); N counts nowhere. The exclusive
/// scan of these (`simt::transform_exclusive_scan`, so they are never stored) ranks
/// every element among the elements of its code before it.
#[inline]
pub(crate) fn one_hot(code: u32) -> Triple {
    let mut f = [0; 3];
    if code & 3 != NEITHER {
        f[(code & 3) as usize] = 1;
    }
    f
}

/// The exclusive-scan entry at `k`, where `k` may be one past the end (the total).
#[inline]
fn rank_at(t: &Thread, ranks: &Global<Triple>, codes: &Global<u32>, k: usize) -> Triple {
    let n = ranks.len();
    if k < n {
        t.load(ranks, k)
    } else {
        let (r, f) = (t.load(ranks, n - 1), one_hot(t.load(codes, n - 1)));
        [r[0] + f[0], r[1] + f[1], r[2] + f[2]]
    }
}

/// `pdacrt::count_codes`: node `n`'s L/B/R/N counts into `counts[n * 4 + code]` and the
/// rank of its first element into `base[n]`, from the scan: a node's elements are
/// contiguous, so its counts are the differences of the scan at its two ends (what
/// `reduce_by_key` over the sorted codes computes, with no sort).
#[allow(clippy::too_many_arguments)]
pub(crate) fn count_node_codes(
    t: &Thread,
    nodes: &Global<NodeData>,
    rays: bool,
    ranks: &Global<Triple>,
    codes: &Global<u32>,
    counts: &GlobalMut<u32>,
    base: &GlobalMut<Triple>,
    n: usize,
) {
    // Only the two fields read are loaded, as compiled code does (`Thread::load_field`).
    let field = |f: fn(&NodeData) -> &u32| t.load_field(nodes, n, f);
    // Two rounds, as the twin's SASS issues them: the two fields, then both ranks.
    let together = t.loads_together();
    let (start, count) = if rays {
        (field(|x| &x.ray_start), field(|x| &x.ray_count))
    } else {
        (field(|x| &x.tri_start), field(|x| &x.tri_count))
    };
    drop(together);
    let together = t.loads_together();
    let first = rank_at(t, ranks, codes, start as usize);
    let end = rank_at(t, ranks, codes, (start + count) as usize);
    drop(together);
    let mut entering = 0;
    for c in 0..3 {
        t.store(counts, n * 4 + c, end[c] - first[c]);
        entering += end[c] - first[c];
    }
    t.store(counts, n * 4 + 3, count - entering);
    t.store(base, n, first);
}

/// Limits that make a child terminal.
#[derive(Clone, Copy, Debug)]
pub(crate) struct LeafRule {
    pub leaf_rays: u32,
    pub leaf_tris: u32,
    /// True when the children being made are at the depth cap.
    pub at_max_depth: bool,
}

// Instructions of `pdacrt::classify_children` besides its loads and stores, block by
// block, as the twin's SASS has them (sm_90; derived from
// `docs/measured/pdacrt-kernels-sm90.sass` by `tests.rs`): the shared head after the
// loads, the first block of either arm on `stuck`, the stuck arm's branch-free leaf
// rule, the other arm's short-circuit tests (the pairs test's terminal lanes jump to
// the join, its inner lanes fall into the inner block), and the shared tail before the
// stores (address arithmetic, predicates, the reconvergence).
pub(super) const CLASSIFY_HEAD: u32 = 27;
pub(super) const CLASSIFY_ARM: u32 = 9;
pub(super) const CLASSIFY_STUCK_RULE: u32 = 13;
pub(super) const CLASSIFY_TRIS_TEST: u32 = 4;
pub(super) const CLASSIFY_RAYS_TEST: u32 = 3;
pub(super) const CLASSIFY_PAIRS_TEST: u32 = 7;
pub(super) const CLASSIFY_PAIRS_JUMP: u32 = 1;
pub(super) const CLASSIFY_DEPTH_TEST: u32 = 3;
pub(super) const CLASSIFY_INNER: u32 = 2;
pub(super) const CLASSIFY_TAIL: u32 = 18;

/// `pdacrt::classify_children`: child `c` of node `c / 2`: sizes, source ranges, and
/// whether it is dropped (no rays or no triangles), terminal, or an inner node of the
/// next level. A split after which either child keeps every ray and triangle of the
/// node separated nothing: then child 0 carries the whole node (every element that
/// enters it) to the next level for another axis, or, when every axis has failed, to
/// the terminal stage; child 1 is dropped. Writes the counting triples for the scans.
#[allow(clippy::too_many_arguments)]
pub(crate) fn classify_child(
    t: &Thread,
    nodes: &Global<NodeData>,
    ray_counts: &Global<u32>,
    tri_counts: &Global<u32>,
    rule: LeafRule,
    children: &GlobalMut<ChildData>,
    inner: &GlobalMut<Triple>,
    terminal: &GlobalMut<Triple>,
    c: usize,
) {
    let n = c / 2;
    let right = c % 2 == 1;
    // The eight loads come first, before any branch, as in the twin's SASS, issued as
    // one round: the node's two sizes and its counts of the three codes that enter a
    // child. `tries` is loaded
    // only where it is read. The arithmetic is declared arm by arm with the counts of
    // that SASS (`CLASSIFY_*`).
    let field = |f: fn(&NodeData) -> &u32| t.load_field(nodes, n, f);
    let together = t.loads_together();
    let (ray_count, tri_count) = (field(|x| &x.ray_count), field(|x| &x.tri_count));
    let rc = |code: u32| t.load(ray_counts, n * 4 + code as usize);
    let tc = |code: u32| t.load(tri_counts, n * 4 + code as usize);
    let [rays_left, rays_both, rays_right] = [rc(LEFT), rc(BOTH), rc(RIGHT)];
    let [tris_left, tris_both, tris_right] = [tc(LEFT), tc(BOTH), tc(RIGHT)];
    drop(together);
    t.work(0, 0, CLASSIFY_HEAD);
    let (left_rays, left_tris) = (rays_left + rays_both, tris_left + tris_both);
    let (right_rays, right_tris) = (rays_both + rays_right, tris_both + tris_right);
    let keeps_all = |r: u32, tr: u32| r == ray_count && tr == tri_count;
    let stuck = keeps_all(left_rays, left_tris) || keeps_all(right_rays, right_tris);
    // Few triangles, or few rays *and* few pairs (as DACRT's leaf rule), or the cap.
    let pairs = leaf_pairs(rule.leaf_rays as u64, rule.leaf_tris as u64);
    let (kind, rays, tris, whole) = if stuck {
        t.work(0, 0, CLASSIFY_ARM);
        let (r, tr) = (left_rays + rays_right, left_tris + tris_right);
        let kind = if right || r == 0 || tr == 0 {
            DROPPED
        } else {
            // Branch-free in the SASS: the whole leaf rule and the tries.
            let tries = field(|x| &x.tries);
            t.work(0, 0, CLASSIFY_STUCK_RULE);
            let small =
                tr <= rule.leaf_tris || (r <= rule.leaf_rays && r as u64 * tr as u64 <= pairs) || rule.at_max_depth;
            if small || tries + 1 >= MAX_TRIES { TERMINAL } else { INNER }
        };
        (kind, r, tr, 1)
    } else {
        t.work(0, 0, CLASSIFY_ARM);
        let (r, tr) = if right { (right_rays, right_tris) } else { (left_rays, left_tris) };
        // The leaf rule's short circuits are branches here, each with its own count.
        let kind = if r == 0 || tr == 0 {
            DROPPED
        } else {
            t.work(0, 0, CLASSIFY_TRIS_TEST);
            if tr <= rule.leaf_tris {
                TERMINAL
            } else {
                t.work(0, 0, CLASSIFY_RAYS_TEST);
                let inner = if r <= rule.leaf_rays {
                    t.work(0, 0, CLASSIFY_PAIRS_TEST);
                    let inner = r as u64 * tr as u64 > pairs && !rule.at_max_depth;
                    if !inner {
                        t.work(0, 0, CLASSIFY_PAIRS_JUMP);
                    }
                    inner
                } else {
                    t.work(0, 0, CLASSIFY_DEPTH_TEST);
                    !rule.at_max_depth
                };
                if inner {
                    t.work(0, 0, CLASSIFY_INNER);
                    INNER
                } else {
                    TERMINAL
                }
            }
        };
        (kind, r, tr, 0)
    };
    t.work(0, 0, CLASSIFY_TAIL);
    // `inner[c] = kind == INNER ? chosen : none`: compiled as two predicated stores of
    // three words, each touching memory for its lanes only (the twin's SASS).
    for (buf, k) in [(inner, INNER), (terminal, TERMINAL)] {
        t.store_if(kind == k, buf, c, [1, rays, tris]);
        t.store_if(kind != k, buf, c, [0, 0, 0]);
    }
    t.store(children, c, ChildData { kind, rays, tris, whole, ..Default::default() });
}

/// `pdacrt::emit_children`: with the scans done, child `c` gets its place in the next
/// level (or the terminal buffer) and writes its node there.
#[allow(clippy::too_many_arguments)]
pub(crate) fn emit_child(
    t: &Thread,
    nodes: &Global<NodeData>,
    child_boxes: &Global<Aabb>,
    inner_scan: &Global<Triple>,
    terminal_scan: &Global<Triple>,
    children: &GlobalMut<ChildData>,
    next_nodes: &GlobalMut<NodeData>,
    terminal_nodes: &GlobalMut<NodeData>,
    c: usize,
) {
    // The four fields read, each loaded on its own and all before the branch, as nvcc
    // compiles it (the destinations are written, not read): one round, as are the
    // scan's triple and the box below.
    let field = |f: fn(&ChildData) -> &u32| t.load_field(children, c, f);
    let together = t.loads_together();
    let (kind, rays, tris, whole) = (field(|x| &x.kind), field(|x| &x.rays), field(|x| &x.tris), field(|x| &x.whole));
    drop(together);
    // The scan's source is if-converted too: one load after the arms pick the array.
    let (scan, out) = match kind {
        INNER => (Place::of(inner_scan, c), next_nodes),
        TERMINAL => (Place::of(terminal_scan, c), terminal_nodes),
        _ => return,
    };
    let scan = {
        let _together = t.loads_together();
        t.load_place(scan)
    };
    let cd = ChildData { kind, rays, tris, dest_node: scan[0], dest_ray: scan[1], dest_tri: scan[2], whole };
    t.store(children, c, cd);
    // So is the box's: each arm picks an address (and the parent's arm loads `tries`),
    // and every lane loads the box once after the branch (the twin's SASS).
    let (place, tries) = if cd.whole == 1 {
        let parent = c / 2;
        (Place::field(nodes, parent, |x| &x.bounds), t.load_field(nodes, parent, |x| &x.tries) + 1)
    } else {
        (Place::of(child_boxes, c), 0)
    };
    let bounds = {
        let _together = t.loads_together();
        t.load_place(place)
    };
    let node = NodeData {
        bounds,
        ray_start: cd.dest_ray,
        ray_count: cd.rays,
        tri_start: cd.dest_tri,
        tri_count: cd.tris,
        tries,
    };
    t.store(out, cd.dest_node as usize, node);
}

/// Where one level's elements go.
#[derive(Clone, Copy)]
pub(crate) struct Destinations<'a> {
    pub next_ids: GlobalMut<'a, u32>,
    pub next_node: GlobalMut<'a, u32>,
    pub terminal_ids: GlobalMut<'a, u32>,
}

/// What the scatter reads besides the children: the elements, their nodes, codes and
/// ranks, and per node the rank of its first element and its code counts.
#[derive(Clone, Copy)]
pub(crate) struct Split<'a> {
    pub ids: Global<'a, u32>,
    pub node_of: Global<'a, u32>,
    pub codes: Global<'a, u32>,
    pub ranks: Global<'a, Triple>,
    pub base: Global<'a, Triple>,
    pub counts: Global<'a, u32>,
}

/// `pdacrt::scatter_rays` / `pdacrt::scatter_triangles`: element `i` (code L, B or R of
/// its node) goes to the children that take it, at its rank among its node's elements
/// of the same code, after those of the smaller codes that the child also takes: the
/// stable order of a segmented sort by code. A left child takes L then B, a right
/// child B then R, a whole-node retry L, B, R.
pub(crate) fn scatter_ref(
    t: &Thread,
    sp: &Split,
    children: &Global<ChildData>,
    rays: bool,
    dest: &Destinations,
    i: usize,
) {
    let code = t.load(&sp.codes, i) & 3;
    if code == NEITHER {
        return;
    }
    let c = code as usize;
    // Rounds of loads as the twin's SASS issues them: the node with this element's
    // rank (one word of the triple, the code's); the node's base rank and the id with
    // the left child's two flags; then per child taken, its two destinations, then the
    // counts of the codes before this one.
    let together = t.loads_together();
    let node = t.load(&sp.node_of, i) as usize;
    let rank_i = t.load_field(&sp.ranks, i, |r| &r[c]);
    drop(together);
    let flags = |side: usize| {
        let field = |f: fn(&ChildData) -> &u32| t.load_field(children, 2 * node + side, f);
        (field(|x| &x.whole) == 1, field(|x| &x.kind))
    };
    let together = t.loads_together();
    let rank = rank_i - t.load_field(&sp.base, node, |r| &r[c]);
    let id = t.load(&sp.ids, i);
    let left = flags(0);
    drop(together);
    // Two trips, which compiled code unrolls: each side's accesses are its own
    // instructions, executed by the lanes whose reference goes to that side.
    for side in 0..2 {
        let _side = t.unroll(side);
        let (whole, kind) = if side == 0 {
            left
        } else {
            let _together = t.loads_together();
            flags(1)
        };
        let takes = whole || if side == 0 { code != RIGHT } else { code != LEFT };
        if !takes || kind == DROPPED {
            continue;
        }
        let field = |f: fn(&ChildData) -> &u32| t.load_field(children, 2 * node + side, f);
        let together = t.loads_together();
        let dst = if rays { field(|x| &x.dest_ray) } else { field(|x| &x.dest_tri) };
        let dest_node = field(|x| &x.dest_node);
        drop(together);
        let first_code = if whole || side == 0 { LEFT } else { BOTH };
        let before: u32 = {
            let _together = t.loads_together();
            (first_code..code).map(|c| t.load(&sp.counts, node * 4 + c as usize)).sum()
        };
        let pos = (dst + before + rank) as usize;
        if kind == INNER {
            t.store(&dest.next_ids, pos, id);
            t.store(&dest.next_node, pos, dest_node);
        } else {
            t.store(&dest.terminal_ids, pos, id);
        }
    }
}

/// Triangles staged in shared memory per round of the brute-force kernel.
pub(crate) const STAGE: usize = 128;

// Instruction weights of the brute-force kernel's arithmetic: what the GPU twin
// executes, as nvcc 13.0 compiles it for sm_90 (`docs/measured/pdacrt-kernels-sm90.sass`,
// whose paths `tests.rs` walks to derive each), less the memory instructions that
// `simt` counts itself. Declared as work, region 0.

/// One ray–triangle test up to its edge test, closest hit: 103 instructions per trip of
/// the twin's test loop (the shared loads of the triangle, the cull distance's next
/// float up, the shear, the edge functions, the loop's own), less the one shared load
/// `simt` counts for the triangle. Path 0.
pub(super) const TEST_INSTRUCTIONS: u32 = 102;
/// The same for any hit (the loop compiled apart, without the next float up): 82
/// instructions per trip, less the shared load.
pub(super) const ANY_HIT_TEST_INSTRUCTIONS: u32 = 81;
/// The path past the edge test to the distance test (determinant, reciprocal,
/// distance), run only by the lanes whose ray's line meets the triangle. Path 1.
pub(super) const PAST_EDGES_INSTRUCTIONS: u32 = 28;
/// Closest hit, a distance inside the ray's range: the triangle's id, the candidate
/// key and its comparison (14 instructions, less the id's shared load).
pub(super) const CANDIDATE_INSTRUCTIONS: u32 = 13;
/// Any hit, a distance inside the ray's range: the result kept and the loop left. (The
/// trip it leaves from is still counted whole, so such a lane is counted 5 instructions
/// of the loop's tail that it skips, once per ray.)
pub(super) const ANY_HIT_LEAVE_INSTRUCTIONS: u32 = 4;
/// A lane with a ray, once per stage of triangles: the shear's set-up (three divisions
/// on their fast paths), the test loop's, and the stage loop's own after the tests.
/// Path 5.
pub(super) const RAY_SETUP_INSTRUCTIONS: u32 = 104;
/// One step of the binary search for the block's terminal node: a 10-instruction loop
/// body, less its load. Path 2.
pub(super) const SEARCH_STEP_INSTRUCTIONS: u32 = 9;
/// One trip of the staging loop: a 31-instruction body, less the 12 memory instructions
/// `simt` counts itself (the id's load, the triangle's nine 4-byte loads, and the two
/// shared stores, one instruction each in the model). Path 3.
pub(super) const STAGE_STEP_INSTRUCTIONS: u32 = 19;

/// Shared memory of one brute-force block: `STAGE` (128) triangles (36 bytes) and their
/// ids (4 bytes), and the block's test count (8 bytes).
pub const BRUTE_FORCE_SHARED_BYTES: usize = STAGE * 40 + 8;

/// Inputs of the terminal brute-force kernel.
#[derive(Clone, Copy)]
pub(crate) struct BruteForceArgs<'a> {
    pub terminals: Global<'a, NodeData>,
    /// Exclusive scan of ray chunks per terminal node.
    pub chunk_start: Global<'a, u32>,
    pub terminal_count: usize,
    pub ray_ids: Global<'a, u32>,
    pub tri_ids: Global<'a, u32>,
    pub rays: Global<'a, Ray>,
    pub tris: Global<'a, [f32; 9]>,
    pub keys: GlobalMut<'a, u64>,
    /// Per ray: terminal nodes it was tested in (the inspector's work heat map), when
    /// asked for.
    pub visits: Option<GlobalMut<'a, u32>>,
    /// Ray–triangle tests made (one counter).
    pub tests: GlobalMut<'a, u64>,
    pub any_hit: bool,
}

/// `pdacrt::brute_force`: block `b` takes one chunk of up to `block_dim` rays of one
/// terminal node; the node's triangles pass through shared memory [`STAGE`] at a
/// time, every ray testing every staged triangle; closest hits land with a 64-bit
/// atomic minimum of (distance, triangle id).
pub(crate) fn brute_force(blk: &mut Block, a: &BruteForceArgs) {
    let b = blk.block_idx();
    // The terminal node owning this chunk: a binary search that every thread makes on
    // the same addresses (uniform loads).
    let (mut lo, mut hi) = (0usize, a.terminal_count);
    while hi - lo > 1 {
        let mid = (lo + hi) / 2;
        blk.work_uniform(0, 2, SEARCH_STEP_INSTRUCTIONS);
        if blk.load_uniform(&a.chunk_start, mid) <= b { lo = mid } else { hi = mid }
    }
    // The node's four ranges, each a uniform load of its own field.
    let mut field = |f: fn(&NodeData) -> &u32| blk.load_uniform_field(&a.terminals, lo, f) as usize;
    let (ray_start, ray_count, tri_start, tri_count) =
        (field(|x| &x.ray_start), field(|x| &x.ray_count), field(|x| &x.tri_start), field(|x| &x.tri_count));
    let chunk = (b - blk.load_uniform(&a.chunk_start, lo)) as usize * blk.block_dim() as usize;
    let stage = blk.shared::<[f32; 9]>(STAGE);
    let stage_ids = blk.shared::<u32>(STAGE);
    // The block's tests, summed in shared memory: one global atomic per block instead
    // of one per thread (with one per thread, 16 threads queued on one cache line; the
    // change cut a 64x64 light-tracing render's cast time by about 30 % on 16 cores).
    let block_tests = blk.shared::<u64>(1);
    let best = blk.local::<u64>(NO_HIT);
    let ray_reg = blk.local::<Ray>(Ray::new(Vec3::ZERO, Vec3::ZERO));
    let ray_id = blk.local::<u32>(u32::MAX);
    let tests = blk.local::<u64>(0);
    blk.for_each_thread(|t| {
        let k = chunk + t.thread_idx() as usize;
        if k < ray_count {
            let id = t.load(&a.ray_ids, ray_start + k);
            t.set(ray_id, id);
            // The ray's eight words and its key in one round (the twin's SASS).
            let _together = t.loads_together();
            t.set(ray_reg, t.load(&a.rays, id as usize));
            t.set(best, t.load(&a.keys, id as usize));
        }
    });
    let mut first = 0usize;
    while first < tri_count {
        let count = STAGE.min(tri_count - first);
        blk.sync_threads();
        blk.for_each_thread(|t| {
            let mut s = t.thread_idx() as usize;
            while s < count {
                t.work(0, 3, STAGE_STEP_INSTRUCTIONS);
                let tri = t.load(&a.tri_ids, tri_start + first + s);
                t.store_shared(stage_ids, s, tri);
                let words = {
                    let _together = t.loads_together();
                    t.load(&a.tris, tri as usize)
                };
                t.store_shared(stage, s, words);
                s += t.block_dim() as usize;
            }
        });
        blk.sync_threads();
        blk.for_each_thread(|t| {
            let id = t.get(ray_id);
            if id == u32::MAX {
                return;
            }
            let mut key = t.get(best);
            if a.any_hit && key == BLOCKED {
                return;
            }
            t.work(0, 5, RAY_SETUP_INSTRUCTIONS);
            let r = t.get(ray_reg);
            let shear = RayShear::new(r.dir);
            let mut far = t_far(&r, key);
            let mut done = 0u32;
            for s in 0..count {
                done += 1;
                let tri = corners(t.load_shared(stage, s));
                let t_max = if a.any_hit { r.t_max } else { far.next_up() };
                let (past_edges, hit) = triangle_test(r.origin, &shear, tri, r.t_min, t_max);
                if !past_edges {
                    continue;
                }
                // `count` is the block's, so every lane runs trip `s` at once: the path
                // past the edges is one warp instruction per trip, for the lanes on it.
                let blocked = t.unrolled(s, || {
                    t.work(0, 1, PAST_EDGES_INSTRUCTIONS);
                    let (th, _, _) = hit?;
                    t.work(0, 4, if a.any_hit { ANY_HIT_LEAVE_INSTRUCTIONS } else { CANDIDATE_INSTRUCTIONS });
                    if !a.any_hit {
                        let candidate = hit_key::pack(th, t.load_shared(stage_ids, s));
                        if candidate < key {
                            key = candidate;
                            far = th;
                        }
                    }
                    a.any_hit.then_some(())
                });
                if blocked.is_some() {
                    key = BLOCKED;
                    break;
                }
            }
            t.work(0, 0, done * if a.any_hit { ANY_HIT_TEST_INSTRUCTIONS } else { TEST_INSTRUCTIONS });
            t.set(tests, t.get(tests) + done as u64);
            t.set(best, key);
        });
        first += count;
    }
    blk.sync_threads();
    blk.for_each_thread(|t| {
        let id = t.get(ray_id);
        if id != u32::MAX {
            if let Some(v) = &a.visits {
                t.red_add(v, id as usize, 1);
            }
            t.atomic_add_shared_u64(block_tests, 0, t.get(tests));
            if t.get(best) != NO_HIT {
                t.red_min_u64(&a.keys, id as usize, t.get(best));
            }
        }
    });
    blk.sync_threads();
    blk.for_each_thread(|t| {
        if t.thread_idx() == 0 {
            t.red_add_u64(&a.tests, 0, t.load_shared(block_tests, 0));
        }
    });
}

/// `pdacrt::resolve_hits`: key of ray `i` into its [`Hit`].
pub(crate) fn resolve_hit(
    t: &Thread,
    rays: &Global<Ray>,
    tris: &Global<[f32; 9]>,
    keys: &Global<u64>,
    out: &GlobalMut<Hit>,
    i: usize,
) {
    let key = t.load(keys, i);
    let tri = if key == NO_HIT { [0.0; 9] } else { t.load(tris, hit_key::prim_of(key) as usize) };
    t.store(out, i, hit_of_key(&t.load(rays, i), key, tri));
}
