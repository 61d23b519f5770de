//! The GPU BVH's kernels (`cuda/bvh.cu`, one for one). Each takes a thread (the fit a
//! block, whose climb it runs a level at a time) and plain `Copy` data; none allocates
//! or launches. `mod.rs` launches them in the build's
//! order.
//!
//! The arithmetic each lane does besides its loads, stores and atomics is declared with
//! [`Thread::work`] in the weights at the bottom of this file, counted from the twin's
//! SASS (`docs/measured/bvh-kernels-sm90.sass`; the test in `tests.rs` walks it).
//!
//! About 590 lines on purpose: the five kernels in their launch order, sharing the node
//! layout, and the weights of all five in one block that reads against the SASS listing.

use crate::cast::flat::corners;
use crate::geometry::hit_key::{self, BLOCKED, NONE};
use crate::geometry::{Aabb, Ray, RayShear, cull_distance, inv_dir, triangle_test};
use glam::Vec3;
use simt::{Block, DeviceCopy, Global, GlobalMut, Readable, Thread, Warp};

/// Eight bytes stored as one vector (`STG.E.64`): two floats of a box.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
#[repr(C, align(8))]
pub(crate) struct Pair(pub [f32; 2]);

/// Sixteen bytes loaded as one vector (`float4`, `LDG.E.128`).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
#[repr(C, align(16))]
pub(crate) struct Quad(pub [Pair; 2]);

/// Two child references loaded as one vector (`int2`): `>= 0` an inner node, `< 0`
/// the leaf of sorted triangle `!child`.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
#[repr(C, align(8))]
pub(crate) struct Children(pub [i32; 2]);

/// An inner node as the twin lays it out (64 bytes): both children's boxes (lo₀ hi₀
/// lo₁ hi₁, three floats each) in three quads, then the two child references.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
#[repr(C, align(16))]
pub(crate) struct Node {
    pub boxes: [Quad; 3],
    pub child: Children,
    pub pad: [u32; 2],
}

// SAFETY: #[repr(C)] of 4-byte fields; sizes 8, 16, 8 and 64 with no padding.
unsafe impl DeviceCopy for Pair {}
unsafe impl DeviceCopy for Quad {}
unsafe impl DeviceCopy for Children {}
unsafe impl DeviceCopy for Node {}

/// Float `k` (0..12) of a node's boxes.
#[inline]
fn float_of(q: &[Quad; 3], k: usize) -> &f32 {
    &q[k / 4].0[(k % 4) / 2].0[k % 2]
}

/// Pair `k` (0..6) of a node's boxes.
#[inline]
fn pair_of(q: &[Quad; 3], k: usize) -> &Pair {
    &q[k / 2].0[k % 2]
}

impl Node {
    /// Child `side`'s box.
    pub(crate) fn child_box(q: &[Quad; 3], side: usize) -> Aabb {
        let f = |k: usize| *float_of(q, 6 * side + k);
        Aabb { min: Vec3::new(f(0), f(1), f(2)), max: Vec3::new(f(3), f(4), f(5)) }
    }
}

/// Where a reference climbing the tree goes next: `parent << 1 | side`, or
/// [`NO_PARENT`] above the root.
pub(crate) const NO_PARENT: u32 = u32::MAX;

/// A triangle's centroid, summed then scaled as the twin does (`-fmad=false`).
#[inline]
fn centroid(v: &[f32; 9]) -> Vec3 {
    let third = 1.0f32 / 3.0;
    Vec3::new((v[0] + v[3] + v[6]) * third, (v[1] + v[4] + v[7]) * third, (v[2] + v[5] + v[8]) * third)
}

/// A centroid as a box of one point (what `bvh::centroid_bounds` reduces).
pub(crate) fn centroid_box(v: [f32; 9]) -> Aabb {
    let c = centroid(&v);
    Aabb { min: c, max: c }
}

/// Ten bits of `x` spread three apart.
#[inline]
fn spread_bits(x: u32) -> u32 {
    let x = x.wrapping_mul(0x0001_0001) & 0xFF00_00FF;
    let x = x.wrapping_mul(0x0000_0101) & 0x0F00_F00F;
    let x = x.wrapping_mul(0x0000_0011) & 0xC30C_30C3;
    x.wrapping_mul(0x0000_0005) & 0x4924_9249
}

/// `x` on `[lo, hi]` in 1024 steps (NaN becomes 0, as `fmaxf` makes it).
#[inline]
#[allow(clippy::manual_clamp, reason = "the twin's fmaxf then fminf, NaN included")]
fn quantise(x: f32, lo: f32, hi: f32) -> u32 {
    let u = if hi > lo { (x - lo) / (hi - lo) } else { 0.5 };
    (u * 1024.0).max(0.0).min(1023.0) as u32
}

/// The 30-bit Morton code of a point in `bounds`.
pub(crate) fn morton(c: Vec3, bounds: &Aabb) -> u32 {
    let q = |a: usize| spread_bits(quantise(c[a], bounds.min[a], bounds.max[a]));
    q(0) << 2 | q(1) << 1 | q(2)
}

/// `bvh::morton_codes`: triangle `i`'s code and its id.
pub(crate) fn morton_code(
    t: &Thread,
    tris: &Global<[f32; 9]>,
    bounds: &Global<Aabb>,
    codes: &GlobalMut<u32>,
    ids: &GlobalMut<u32>,
    i: usize,
) {
    // The box's six words and the triangle's nine are issued back to back and waited
    // for once (the twin's SASS).
    let together = t.loads_together();
    let b = t.load(bounds, 0);
    let tri = t.load(tris, i);
    drop(together);
    let c = centroid(&tri);
    t.work(0, 0, MORTON);
    t.store(codes, i, morton(c, &b));
    t.store(ids, i, i as u32);
}

/// `bvh::gather_triangles`: the `i`-th triangle in code order, and its box.
pub(crate) fn gather_triangle(
    t: &Thread,
    tris: &Global<[f32; 9]>,
    ids: &Global<u32>,
    sorted: &GlobalMut<[f32; 9]>,
    leaf_boxes: &GlobalMut<Aabb>,
    i: usize,
) {
    // The id, then the triangle's nine words in one round (the twin's SASS).
    let id = t.load(ids, i) as usize;
    let tri = {
        let _together = t.loads_together();
        t.load(tris, id)
    };
    t.work(0, 0, GATHER);
    t.store(sorted, i, tri);
    let [a, b, c] = corners(tri);
    t.store(leaf_boxes, i, Aabb::from_points(&[a, b, c]));
}

/// Karras's δ: the length of the common prefix of codes `i` and `j`, the index
/// breaking ties between equal codes; -1 outside the array. Each call site has its own
/// instructions in the SASS (the loops' arithmetic with them): `weights` is the site's
/// (in range, outside).
#[inline]
#[track_caller]
fn delta(t: &Thread, codes: &Global<u32>, (i, j): (i64, i64), weights: (u32, u32)) -> i32 {
    let n = codes.len() as i64;
    if j < 0 || j >= n {
        t.work(0, 1, weights.1);
        return -1;
    }
    // Both codes are loaded again at every site (nvcc keeps no copy of `codes[i]`), back
    // to back and waited for once.
    let together = t.loads_together();
    let (a, b) = (t.load(codes, i as usize), t.load(codes, j as usize));
    drop(together);
    t.work(0, 0, weights.0);
    if a == b { 32 + (i as u32 ^ j as u32).leading_zeros() as i32 } else { (a ^ b).leading_zeros() as i32 }
}

/// `bvh::emit_hierarchy`: inner node `i` of `n - 1` finds its range of leaves
/// (Karras 2012), splits it where the codes' common prefix ends, and links its two
/// children; each child learns its parent and side.
pub(crate) fn emit_node(
    t: &Thread,
    codes: &Global<u32>,
    nodes: &GlobalMut<Node>,
    inner_parent: &GlobalMut<u32>,
    leaf_parent: &GlobalMut<u32>,
    i: usize,
) {
    let i = i as i64;
    t.work(0, 2, EMIT_HEAD);
    let d: i64 =
        if delta(t, codes, (i, i + 1), DELTA_NEXT) - delta(t, codes, (i, i - 1), DELTA_PREV) >= 0 { 1 } else { -1 };
    let d_min = delta(t, codes, (i, i - d), DELTA_MIN);
    // The far end: a doubling search, then a binary one.
    t.work(0, 2, DOUBLING_SETUP);
    let mut l_max = 2;
    let mut trip = 0;
    while {
        let _trip = t.unroll(trip);
        trip += 1;
        delta(t, codes, (i, i + l_max * d), DOUBLING_STEP) > d_min
    } {
        l_max *= 2;
    }
    t.work(0, 2, LOOP_EXIT + BINARY_SETUP);
    let mut l = 0;
    let mut step = l_max / 2;
    // Each loop reconverges at its exit: trip `k` of a loop is one step of the warp.
    let mut trip = 0;
    while step >= 1 {
        let _trip = t.unroll(trip);
        trip += 1;
        if delta(t, codes, (i, i + (l + step) * d), BINARY_STEP) > d_min {
            l += step;
        }
        step /= 2;
    }
    t.work(0, 2, LOOP_EXIT);
    let j = i + l * d;
    // The split: the last leaf that shares more than the range's common prefix.
    let d_node = delta(t, codes, (i, j), DELTA_NODE);
    t.work(0, 2, SPLIT_SETUP);
    let (mut s, mut step) = (0, l);
    let mut trip = 0;
    loop {
        let _trip = t.unroll(trip);
        trip += 1;
        step = (step + 1) >> 1;
        if delta(t, codes, (i, i + (s + step) * d), SPLIT_STEP) > d_node {
            s += step;
        }
        if step <= 1 {
            break;
        }
    }
    t.work(0, 2, LOOP_EXIT + if i == 0 { EMIT_TAIL_ROOT } else { EMIT_TAIL });
    let split = i + s * d + d.min(0);
    let (lo, hi) = (i.min(j), i.max(j));
    // Each side: two predicated pairs of stores (the child reference and the child's
    // parent), as the SASS has them.
    for (side, child, leaf) in [(0, split, lo == split), (1, split + 1, hi == split + 1)] {
        let _side = t.unroll(side);
        let up = (i as u32) << 1 | side as u32;
        t.store_field_if(!leaf, nodes, i as usize, |n| &n.child.0[side], child as i32);
        t.store_if(!leaf, inner_parent, child as usize, up);
        t.store_field_if(leaf, nodes, i as usize, |n| &n.child.0[side], !(child as i32));
        t.store_if(leaf, leaf_parent, child as usize, up);
    }
    if i == 0 {
        t.store(inner_parent, 0, NO_PARENT);
    }
}

/// `bvh::fit_boxes` as one block runs it: each leaf carries its box up the tree, writing
/// it into its parent's slot; the first reference to reach a node stops there, the
/// second unites both slots and goes on.
///
/// One phase per level of the climb: every lane still climbing goes up one node before
/// any goes up the next, as the lanes of a warp do in lockstep and the block's warps do
/// side by side on a GPU. Which reference reaches a node first then follows the levels
/// climbed, as on the GPU, where the lane from the deeper side arrives later and goes on;
/// a thread running its whole climb before the next thread starts would instead hand
/// every node to the later thread, and its warps would climb in fewer, fuller steps
/// than the GPU's (docs/simt.md, "The GPU BVH's build").
pub(crate) fn fit_boxes(
    blk: &mut Block,
    leaf_boxes: &Global<Aabb>,
    leaf_parent: &Global<u32>,
    inner_parent: &Global<u32>,
    nodes: &GlobalMut<Node>,
    arrivals: &GlobalMut<u32>,
    n: usize,
) {
    let up = blk.local(NO_PARENT);
    let carried = blk.local(Aabb::EMPTY);
    blk.for_each_thread(|t| {
        let i = t.global_idx();
        if i >= n {
            return;
        }
        t.set(up, t.load(leaf_parent, i));
        // The box's six words are issued back to back and waited for once (as are the
        // parent's index and the sibling's box below: the SASS has them so).
        let b = {
            let _together = t.loads_together();
            t.load(leaf_boxes, i)
        };
        t.set(carried, b);
        t.work(0, 0, FIT_HEAD);
    });
    loop {
        let mut climbing = false;
        blk.for_each_thread(|t| {
            let at = t.get(up);
            if at == NO_PARENT {
                return;
            }
            climbing = true;
            let (next, b) = fit_level(t, inner_parent, nodes, arrivals, at, t.get(carried));
            t.set(up, next);
            t.set(carried, b);
        });
        if !climbing {
            break;
        }
    }
}

/// One level of a reference's climb from its box `b` into node `up >> 1`'s slot
/// `up & 1`: returns where it goes next (`NO_PARENT`: it stops) and the box it carries.
fn fit_level(
    t: &Thread,
    inner_parent: &Global<u32>,
    nodes: &GlobalMut<Node>,
    arrivals: &GlobalMut<u32>,
    up: u32,
    b: Aabb,
) -> (u32, Aabb) {
    let (p, side) = ((up >> 1) as usize, (up & 1) as usize);
    t.work(0, 0, FIT_STEP);
    // Three 8-byte stores into the parent's slot (`Aabb box[2]` is 8-aligned at either
    // side).
    let v = [b.min.x, b.min.y, b.min.z, b.max.x, b.max.y, b.max.z];
    for k in 0..3 {
        t.store_field(nodes, p, |n| pair_of(&n.boxes, 3 * side + k), Pair([v[2 * k], v[2 * k + 1]]));
    }
    t.thread_fence();
    let first = t.atomic_add(arrivals, p, 1) == 0;
    t.work(0, 0, FIT_ARRIVAL);
    if first {
        return (NO_PARENT, b);
    }
    t.thread_fence();
    let together = t.loads_together();
    let next = t.load(inner_parent, p);
    // The sibling's slot, written by the reference that arrived first: six `volatile`
    // single-float loads (past L1).
    let f = |k: usize| t.load_field(nodes, p, |n| float_of(&n.boxes, 6 * (side ^ 1) + k));
    let other = Aabb { min: Vec3::new(f(0), f(1), f(2)), max: Vec3::new(f(3), f(4), f(5)) };
    drop(together);
    t.work(0, 0, FIT_UNION);
    (next, b.union(other))
}

/// A built tree as the traversal reads it.
#[derive(Clone, Copy)]
pub(crate) struct TreeView<'a> {
    pub nodes: Global<'a, Node>,
    pub tris: Global<'a, [f32; 9]>,
    pub ids: Global<'a, u32>,
    /// `>= 0`: the root's inner node; `< 0`: a tree of one leaf; [`EMPTY_TREE`]:
    /// nothing.
    pub root: i32,
    /// How far boxes grow (`geometry::batch_slack`).
    pub grow: f32,
    /// The region the traversal's work is declared in (the launch's name for it).
    pub region: usize,
}

/// Where a lane's ray is: in a buffer, loaded where the compiled kernel loads its
/// fields (`bvh::trace`), or held in registers (a megakernel's own ray).
#[derive(Clone, Copy)]
pub(crate) enum RayAt<'a> {
    Loaded(&'a Global<'a, Ray>, usize),
    Held(Ray),
}

impl RayAt<'_> {
    #[track_caller]
    fn origin(&self, t: &Thread) -> Vec3 {
        match self {
            RayAt::Loaded(rays, i) => ray_vector(t, rays, *i, |r| &r.origin),
            RayAt::Held(r) => r.origin,
        }
    }
    #[track_caller]
    fn t_min(&self, t: &Thread) -> f32 {
        match self {
            RayAt::Loaded(rays, i) => t.load_field(*rays, *i, |r| &r.t_min),
            RayAt::Held(r) => r.t_min,
        }
    }
    #[track_caller]
    fn t_max(&self, t: &Thread) -> f32 {
        match self {
            RayAt::Loaded(rays, i) => t.load_field(*rays, *i, |r| &r.t_max),
            RayAt::Held(r) => r.t_max,
        }
    }
}

/// The root of a tree with no triangles.
pub(crate) const EMPTY_TREE: i32 = i32::MIN;

/// Deeper than any tree built here: 30 Morton bits, then at most 32 bits of index.
pub(crate) const STACK: usize = 64;

/// A vector of ray `i`, `pick` choosing it: three 4-byte loads, as the SASS makes.
#[inline]
#[track_caller]
fn ray_vector(t: &Thread, rays: &Global<Ray>, i: usize, pick: fn(&Ray) -> &Vec3) -> Vec3 {
    Vec3::new(
        t.load_field(rays, i, |r| &pick(r).x),
        t.load_field(rays, i, |r| &pick(r).y),
        t.load_field(rays, i, |r| &pick(r).z),
    )
}

/// Ray `i`'s closest-hit key (the smallest, as PDACRT's leaf keeps it; [`NONE`] for
/// none) or, with `any_hit`, [`BLOCKED`] at the first blocker, with the tests made and
/// the inner nodes visited. Iteration `k` of every lane's loop is one step of the warp
/// (`Thread::unroll`), as a warp runs a `while` loop in lockstep. The ray's fields are
/// loaded where the compiled code loads them: all of them once to test the ray, and its
/// origin and interval again at every node and leaf (nvcc keeps no copy of them).
///
/// A held ray (a megakernel's) makes no loads of its own and is charged the kernel's
/// weights: the traversal inlined in another kernel is the same code, with other
/// registers (its SASS was not walked).
pub(crate) fn trace_key(t: &Thread, tree: &TreeView, ray: RayAt, any_hit: bool) -> (u64, u32, u32) {
    let (mut tests, mut visits) = (0, 0);
    let mut key = NONE;
    let rg = tree.region;
    let r = match ray {
        RayAt::Loaded(rays, i) => t.load(rays, i),
        RayAt::Held(r) => r,
    };
    if !r.is_valid() || tree.root == EMPTY_TREE {
        return (key, tests, visits);
    }
    let dir = match ray {
        RayAt::Loaded(rays, i) => ray_vector(t, rays, i, |r| &r.dir),
        RayAt::Held(r) => r.dir,
    };
    let t_max = ray.t_max(t);
    let inv = inv_dir(dir);
    let shear = RayShear::new(dir);
    t.work(rg, 0, TRACE_HEAD);
    let mut far = t_max;
    let mut stack = [0i32; STACK];
    let mut sp = 0;
    let mut cur = tree.root;
    let mut step = 0;
    loop {
        let _step = t.unroll(step);
        step += 1;
        if cur < 0 {
            // The SASS issues the ray's fields and the triangle's nine words back to
            // back and waits once (one round of the time model's chain).
            let together = t.loads_together();
            let (origin, t_min) = (ray.origin(t), ray.t_min(t));
            let tri = t.load(&tree.tris, !cur as usize);
            let t_max = if any_hit { ray.t_max(t) } else { far.next_up() };
            drop(together);
            tests += 1;
            let (past_edges, hit) = triangle_test(origin, &shear, corners(tri), t_min, t_max);
            t.work(rg, 1, if any_hit { ANY_HIT_TEST } else { TEST });
            if past_edges {
                t.work(rg, 2, PAST_EDGES);
                if let Some((th, _, _)) = hit {
                    if any_hit {
                        t.work(rg, 3, ANY_HIT_LEAVE);
                        return (BLOCKED, tests, visits);
                    }
                    let candidate = hit_key::pack(th, t.load(&tree.ids, !cur as usize));
                    t.work(rg, 3, CANDIDATE);
                    if candidate < key {
                        key = candidate;
                        far = th;
                    }
                }
            }
        } else {
            visits += 1;
            // Three rounds, as the SASS issues them: the ray's origin and interval with
            // the first two quads of boxes, then the third quad, then the children.
            let together = t.loads_together();
            let t_min = ray.t_min(t);
            let origin = ray.origin(t);
            let q01 = [0, 1].map(|k| t.load_field(&tree.nodes, cur as usize, |n| &n.boxes[k]));
            drop(together);
            let q = [q01[0], q01[1], t.load_field(&tree.nodes, cur as usize, |n| &n.boxes[2])];
            let ch = t.load_field(&tree.nodes, cur as usize, |n| &n.child).0;
            t.work(rg, 4, VISIT);
            let cull = cull_distance(far);
            let enter = |side| {
                Node::child_box(&q, side).grown(tree.grow).intersect(origin, inv, t_min, cull).map(|(near, _)| near)
            };
            match (enter(0), enter(1)) {
                (Some(n0), Some(n1)) => {
                    let swap = n1 < n0;
                    cur = if swap { ch[1] } else { ch[0] };
                    stack[sp] = if swap { ch[0] } else { ch[1] };
                    sp += 1;
                    t.work(rg, 5, VISIT_BOTH);
                    continue;
                }
                (Some(_), None) | (None, Some(_)) => {
                    cur = if enter(0).is_some() { ch[0] } else { ch[1] };
                    t.work(rg, 6, VISIT_ONE);
                    continue;
                }
                (None, None) => t.work(rg, 7, VISIT_NONE),
            }
        }
        if sp == 0 {
            t.work(rg, 8, LOOP_END);
            break;
        }
        sp -= 1;
        cur = stack[sp];
        t.work(rg, 9, POP);
    }
    (key, tests, visits)
}

/// Sums each lane's count over the warp (a shuffle-down tree) and adds the total to
/// `totals[which]` once, from lane 0, whose own instructions around its atomic are
/// `lane0_work`.
pub(crate) fn add_warp(w: &mut Warp, counts: &[u32; 32], totals: &GlobalMut<u64>, which: usize, lane0_work: u32) {
    let mut c = counts.map(|x| x as u64);
    let mut d = 16;
    while d > 0 {
        let down = w.shfl_down(&c, d);
        for lane in 0..32 {
            c[lane] += down[lane];
        }
        d /= 2;
    }
    w.for_each_lane(|t| {
        if t.lane_id() == 0 {
            t.work(0, 10, lane0_work);
            t.red_add_u64(totals, which, c[0]);
        }
    });
}

// Instructions of the kernels besides their loads, stores and atomics, as the twin's
// SASS has them (sm_90, `docs/measured/bvh-kernels-sm90.sass`, whose paths `tests.rs`
// walks to derive each of these).

// `bvh::morton_codes` and `bvh::gather_triangles`: the whole kernel (the divisions on
// their fast paths).
pub(crate) const MORTON: u32 = 114;
pub(crate) const GATHER: u32 = 42;

// `bvh::emit_hierarchy`, per δ site (in range, outside the array): the first two, the
// direction's and `d_min`'s, a trip of the doubling search, of the binary search, of
// the split's search, and the node's own; each loop's set-up, and its exit's
// reconvergence; the head (bounds check, set-up) and the tail (the links' address
// arithmetic; the root stores its missing parent too).
pub(crate) const EMIT_HEAD: u32 = 18;
pub(crate) const DELTA_NEXT: (u32, u32) = (8, 2);
pub(crate) const DELTA_PREV: (u32, u32) = (11, 5);
pub(crate) const DELTA_MIN: (u32, u32) = (16, 10);
pub(crate) const DOUBLING_SETUP: u32 = 3;
pub(crate) const DOUBLING_STEP: (u32, u32) = (20, 13);
pub(crate) const BINARY_SETUP: u32 = 7;
pub(crate) const BINARY_STEP: (u32, u32) = (22, 15);
/// `j` is always inside the array: the second value is never charged.
pub(crate) const DELTA_NODE: (u32, u32) = (15, 0);
pub(crate) const SPLIT_SETUP: u32 = 3;
pub(crate) const SPLIT_STEP: (u32, u32) = (24, 17);
pub(crate) const LOOP_EXIT: u32 = 1;
pub(crate) const EMIT_TAIL: u32 = 22;
pub(crate) const EMIT_TAIL_ROOT: u32 = 24;

// `bvh::fit_boxes`: the head (bounds check, the leaf's parent and its test, the box's
// addresses); per level, the slot's address and the fences before the atomic, the
// arrival's test, and for the second arrival the sibling's address, the union and the
// loop's test.
pub(crate) const FIT_HEAD: u32 = 22;
pub(crate) const FIT_STEP: u32 = 10;
pub(crate) const FIT_ARRIVAL: u32 = 2;
pub(crate) const FIT_UNION: u32 = 18;

// `bvh::trace`: a valid ray's set-up (its eight validity tests, the reciprocal
// direction and the shear, each division on its fast path); per inner node, both slab
// tests to the child references (every axis finite), then the arm taken: both
// children (the push to the local-memory stack), one, or none; per leaf, the
// triangle's test to the edge functions' verdict, past it to the distance, and the
// candidate (closest hit) or the leave (any hit); a pop from the stack, or the loop's
// end; and after the loop, the key's store and the two warp sums (their shuffles
// counted by the model itself: 5 per 64-bit sum, the SASS has 10), lane 0's reduction
// apart.
pub(crate) const TRACE_HEAD: u32 = 154;
pub(crate) const VISIT: u32 = 111;
pub(crate) const VISIT_BOTH: u32 = 9;
pub(crate) const VISIT_ONE: u32 = 10;
pub(crate) const VISIT_NONE: u32 = 5;
pub(crate) const TEST: u32 = 92;
pub(crate) const ANY_HIT_TEST: u32 = 86;
pub(crate) const PAST_EDGES: u32 = 28;
pub(crate) const CANDIDATE: u32 = 11;
pub(crate) const ANY_HIT_LEAVE: u32 = 2;
pub(crate) const POP: u32 = 7;
pub(crate) const LOOP_END: u32 = 3;
pub(crate) const TRACE_TAIL: u32 = 45;
pub(crate) const TRACE_TAIL_LANE0: [u32; 2] = [1, 3];
