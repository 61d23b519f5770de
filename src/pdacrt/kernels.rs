//! PDACRT's kernels. Each takes a thread and plain `Copy` data (views and work items);
//! none allocates, forks or launches. The host code in `mod.rs` launches them.

use crate::geometry::{Aabb, RayShear, intersect_triangle};
use glam::Vec3;
use simt::{Block, DeviceCopy, Global, GlobalMut, Readable, Thread};

/// Triangle and ray codes, packed under the node id: `node << 2 | code`. Sorted by this
/// key, each node's elements come as L, B, R, N, so the left child's elements (L, B)
/// and the right child's (B, R) are both contiguous.
pub const LEFT: u32 = 0;
pub const BOTH: u32 = 1;
pub const RIGHT: u32 = 2;
pub const NEITHER: u32 = 3;

/// Key of "no hit yet"; shadow rays that are blocked get [`BLOCKED`].
pub const NO_HIT: u64 = u64::MAX;
pub const BLOCKED: u64 = 0;

/// Child kinds.
pub const DROPPED: u32 = 0;
pub const INNER: u32 = 1;
pub const TERMINAL: u32 = 2;

#[derive(Clone, Copy, Debug, Default, PartialEq)]
#[repr(C)]
pub struct RayData {
    pub origin: [f32; 3],
    pub dir: [f32; 3],
    pub inv_dir: [f32; 3],
    pub t_min: f32,
    pub t_max: f32,
    pub _pad: f32,
}

#[derive(Clone, Copy, Debug, Default, PartialEq)]
#[repr(C)]
pub struct BoxData {
    pub min: [f32; 3],
    pub max: [f32; 3],
}

/// A node of a level: its box and its ranges in the level's id arrays.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
#[repr(C)]
pub struct NodeData {
    pub bounds: BoxData,
    pub ray_start: u32,
    pub ray_count: u32,
    pub tri_start: u32,
    pub tri_count: u32,
}

/// What becomes of one child: its kind, sizes, where its elements come from in the
/// parent's sorted arrays, and where they go.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
#[repr(C)]
pub struct ChildData {
    pub kind: u32,
    pub rays: u32,
    pub tris: u32,
    pub ray_src: u32,
    pub tri_src: u32,
    pub dest_node: u32,
    pub dest_ray: u32,
    pub dest_tri: u32,
}

/// Per child, what the scans count: (1 if chosen, its rays, its triangles).
pub type Triple = [u32; 3];

/// Closest-hit result per ray: distance, triangle, barycentrics.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
#[repr(C)]
pub struct HitData {
    pub t: f32,
    pub prim: u32,
    pub u: f32,
    pub v: f32,
}

// SAFETY: all of these are #[repr(C)] structs of 4-byte fields without padding.
unsafe impl DeviceCopy for RayData {}
unsafe impl DeviceCopy for BoxData {}
unsafe impl DeviceCopy for NodeData {}
unsafe impl DeviceCopy for ChildData {}
unsafe impl DeviceCopy for HitData {}

impl BoxData {
    pub fn from_aabb(b: Aabb) -> Self {
        BoxData { min: b.min.to_array(), max: b.max.to_array() }
    }
    pub fn aabb(&self) -> Aabb {
        Aabb { min: Vec3::from_array(self.min), max: Vec3::from_array(self.max) }
    }
}

#[inline]
pub fn pack_hit(t: f32, prim: u32) -> u64 {
    (t.to_bits() as u64) << 32 | prim as u64
}

#[inline]
fn key_t(key: u64) -> f32 {
    f32::from_bits((key >> 32) as u32)
}

/// The ray's interval end: its closest hit so far, or its own `t_max`.
#[inline]
fn t_far(ray: &RayData, key: u64) -> f32 {
    if key == NO_HIT { ray.t_max } else { key_t(key).min(ray.t_max) }
}

/// `pdacrt::split_nodes`: children `2n` and `2n + 1` of node `n`, split at the spatial
/// median of the longest axis.
pub fn split_node(t: &Thread, nodes: &Global<NodeData>, children: &GlobalMut<BoxData>, n: usize) {
    let b = t.load(nodes, n).bounds.aabb();
    let axis = b.longest_axis();
    let mid = b.center()[axis];
    let (mut lo, mut hi) = (b, b);
    lo.max[axis] = mid;
    hi.min[axis] = mid;
    t.store(children, 2 * n, BoxData::from_aabb(lo));
    t.store(children, 2 * n + 1, BoxData::from_aabb(hi));
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
pub fn filter_triangle(
    t: &Thread,
    tri_ids: &Global<u32>,
    tri_node: &Global<u32>,
    tris: &Global<[f32; 9]>,
    children: &Global<BoxData>,
    codes: &GlobalMut<u32>,
    i: usize,
) {
    let node = t.load(tri_node, i);
    let v = t.load(tris, t.load(tri_ids, i) as usize);
    let (a, b, c) = (Vec3::new(v[0], v[1], v[2]), Vec3::new(v[3], v[4], v[5]), Vec3::new(v[6], v[7], v[8]));
    let (tmin, tmax) = (a.min(b).min(c), a.max(b).max(c));
    let overlaps = |k: usize| {
        let cb = t.load(children, k).aabb();
        tmin.cmple(cb.max).all() && tmax.cmpge(cb.min).all()
    };
    let code = code_of(overlaps(2 * node as usize), overlaps(2 * node as usize + 1));
    t.store(codes, i, node << 2 | code);
}

/// `pdacrt::filter_rays`: L/B/R/N for ray reference `i`: does the ray enter each child
/// before its closest hit so far (early termination)?
#[allow(clippy::too_many_arguments)]
pub fn filter_ray(
    t: &Thread,
    ray_ids: &Global<u32>,
    ray_node: &Global<u32>,
    rays: &Global<RayData>,
    keys: &Global<u64>,
    children: &Global<BoxData>,
    any_hit: bool,
    codes: &GlobalMut<u32>,
    i: usize,
) {
    let node = t.load(ray_node, i);
    let id = t.load(ray_ids, i) as usize;
    let key = t.load(keys, id);
    let code = if any_hit && key == BLOCKED {
        NEITHER
    } else {
        let r = t.load(rays, id);
        let (o, inv) = (Vec3::from_array(r.origin), Vec3::from_array(r.inv_dir));
        let far = t_far(&r, key);
        let enters = |k: usize| t.load(children, k).aabb().intersect(o, inv, r.t_min, far).is_some();
        code_of(enters(2 * node as usize), enters(2 * node as usize + 1))
    };
    t.store(codes, i, node << 2 | code);
}

/// `pdacrt::count_codes`: run `k` of the reduce-by-key output into the table
/// `counts[node * 4 + code]`.
pub fn scatter_count(t: &Thread, run_keys: &Global<u32>, run_counts: &Global<u32>, counts: &GlobalMut<u32>, k: usize) {
    let key = t.load(run_keys, k);
    t.store(counts, key as usize, t.load(run_counts, k));
}

/// Limits that make a child terminal.
#[derive(Clone, Copy, Debug)]
pub struct LeafRule {
    pub leaf_rays: u32,
    pub leaf_tris: u32,
    /// True when the children being made are at the depth cap.
    pub at_max_depth: bool,
}

/// `pdacrt::classify_children`: child `c` of node `c / 2`: sizes, source ranges, and
/// whether it is dropped (no rays or no triangles), terminal, or an inner node of the
/// next level. Writes the counting triples for the scans.
#[allow(clippy::too_many_arguments)]
pub fn classify_child(
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
    let node = t.load(nodes, n);
    let rc = |code: u32| t.load(ray_counts, n * 4 + code as usize);
    let tc = |code: u32| t.load(tri_counts, n * 4 + code as usize);
    let (rays, tris, ray_src, tri_src) = if right {
        (rc(BOTH) + rc(RIGHT), tc(BOTH) + tc(RIGHT), node.ray_start + rc(LEFT), node.tri_start + tc(LEFT))
    } else {
        (rc(LEFT) + rc(BOTH), tc(LEFT) + tc(BOTH), node.ray_start, node.tri_start)
    };
    let no_progress = rays == node.ray_count && tris == node.tri_count;
    let kind = if rays == 0 || tris == 0 {
        DROPPED
    } else if rays <= rule.leaf_rays || tris <= rule.leaf_tris || rule.at_max_depth || no_progress {
        TERMINAL
    } else {
        INNER
    };
    let triple = |k| if kind == k { [1, rays, tris] } else { [0, 0, 0] };
    t.store(inner, c, triple(INNER));
    t.store(terminal, c, triple(TERMINAL));
    t.store(children, c, ChildData { kind, rays, tris, ray_src, tri_src, ..Default::default() });
}

/// `pdacrt::emit_children`: with the scans done, child `c` gets its place in the next
/// level (or the terminal buffer) and writes its node there.
#[allow(clippy::too_many_arguments)]
pub fn emit_child(
    t: &Thread,
    child_boxes: &Global<BoxData>,
    inner_scan: &Global<Triple>,
    terminal_scan: &Global<Triple>,
    children: &GlobalMut<ChildData>,
    next_nodes: &GlobalMut<NodeData>,
    terminal_nodes: &GlobalMut<NodeData>,
    c: usize,
) {
    let mut cd = t.load(children, c);
    let (scan, out) = match cd.kind {
        INNER => (t.load(inner_scan, c), next_nodes),
        TERMINAL => (t.load(terminal_scan, c), terminal_nodes),
        _ => return,
    };
    cd.dest_node = scan[0];
    cd.dest_ray = scan[1];
    cd.dest_tri = scan[2];
    t.store(children, c, cd);
    let node = NodeData {
        bounds: t.load(child_boxes, c),
        ray_start: cd.dest_ray,
        ray_count: cd.rays,
        tri_start: cd.dest_tri,
        tri_count: cd.tris,
    };
    t.store(out, cd.dest_node as usize, node);
}

/// Where one level's sorted elements go.
#[derive(Clone, Copy)]
pub struct Destinations<'a> {
    pub next_ids: GlobalMut<'a, u32>,
    pub next_node: GlobalMut<'a, u32>,
    pub terminal_ids: GlobalMut<'a, u32>,
}

/// `pdacrt::scatter_rays` / `pdacrt::scatter_triangles`: sorted element `i` (code
/// L, B or R of its node) is copied into the children that take it; B goes to both.
pub fn scatter_ref(
    t: &Thread,
    sorted_codes: &Global<u32>,
    sorted_ids: &Global<u32>,
    children: &Global<ChildData>,
    rays: bool,
    dest: &Destinations,
    i: usize,
) {
    let key = t.load(sorted_codes, i);
    let (node, code) = ((key >> 2) as usize, key & 3);
    if code == NEITHER {
        return;
    }
    let id = t.load(sorted_ids, i);
    for side in 0..2 {
        let takes = if side == 0 { code != RIGHT } else { code != LEFT };
        if !takes {
            continue;
        }
        let cd = t.load(children, 2 * node + side);
        let (src, dst) = if rays { (cd.ray_src, cd.dest_ray) } else { (cd.tri_src, cd.dest_tri) };
        let pos = dst as usize + (i - src as usize);
        match cd.kind {
            INNER => {
                t.store(&dest.next_ids, pos, id);
                t.store(&dest.next_node, pos, cd.dest_node);
            }
            TERMINAL => t.store(&dest.terminal_ids, pos, id),
            _ => {}
        }
    }
}

/// Triangles staged in shared memory per round of the brute-force kernel.
pub const STAGE: usize = 128;

/// Inputs of the terminal brute-force kernel.
#[derive(Clone, Copy)]
pub struct BruteForceArgs<'a> {
    pub terminals: Global<'a, NodeData>,
    /// Exclusive scan of ray chunks per terminal node, and its total at the end.
    pub chunk_start: Global<'a, u32>,
    pub terminal_count: usize,
    pub ray_ids: Global<'a, u32>,
    pub tri_ids: Global<'a, u32>,
    pub rays: Global<'a, RayData>,
    pub tris: Global<'a, [f32; 9]>,
    pub keys: GlobalMut<'a, u64>,
    /// Per ray: terminal nodes it was tested in (the inspector's work heat map).
    pub visits: GlobalMut<'a, u32>,
    pub any_hit: bool,
}

/// `pdacrt::brute_force`: block `b` takes one chunk of up to `block_dim` rays of one
/// terminal node; the node's triangles pass through shared memory [`STAGE`] at a
/// time, every ray testing every staged triangle; closest hits land with a 64-bit
/// atomic minimum of (distance, triangle id).
pub fn brute_force(blk: &mut Block, a: &BruteForceArgs) {
    let b = blk.block_idx();
    // The terminal node owning this chunk (binary search; the same in every thread).
    let (mut lo, mut hi) = (0usize, a.terminal_count);
    while hi - lo > 1 {
        let mid = (lo + hi) / 2;
        if a.chunk_start.read(mid) <= b { lo = mid } else { hi = mid }
    }
    let node = a.terminals.read(lo);
    let chunk = (b - a.chunk_start.read(lo)) as usize * blk.block_dim() as usize;
    let stage = blk.shared::<[f32; 9]>(STAGE);
    let best = blk.local::<u64>(NO_HIT);
    let ray_reg = blk.local::<RayData>(RayData::default());
    let ray_id = blk.local::<u32>(u32::MAX);
    blk.for_each_thread(|t| {
        let k = chunk + t.thread_idx() as usize;
        if k < node.ray_count as usize {
            let id = t.load(&a.ray_ids, node.ray_start as usize + k);
            t.set(ray_id, id);
            t.set(ray_reg, t.load(&a.rays, id as usize));
            t.set(best, t.load(&a.keys.as_global(), id as usize));
        }
    });
    let mut first = 0usize;
    while first < node.tri_count as usize {
        let count = STAGE.min(node.tri_count as usize - first);
        blk.sync_threads();
        blk.for_each_thread(|t| {
            let j = t.thread_idx() as usize;
            let mut s = j;
            while s < count {
                let tri = t.load(&a.tri_ids, node.tri_start as usize + first + s);
                t.store_shared(stage, s, t.load(&a.tris, tri as usize));
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
            let r = t.get(ray_reg);
            let (o, d) = (Vec3::from_array(r.origin), Vec3::from_array(r.dir));
            let shear = RayShear::new(d);
            let mut far = t_far(&r, key);
            t.work(0, 0, count as u32);
            for s in 0..count {
                let v = t.load_shared(stage, s);
                let (p0, p1, p2) =
                    (Vec3::new(v[0], v[1], v[2]), Vec3::new(v[3], v[4], v[5]), Vec3::new(v[6], v[7], v[8]));
                let tri = t.load(&a.tri_ids, node.tri_start as usize + first + s);
                if a.any_hit {
                    if intersect_triangle(o, &shear, p0, p1, p2, r.t_min, r.t_max).is_some() {
                        key = BLOCKED;
                        break;
                    }
                } else if let Some((th, _, _)) = intersect_triangle(o, &shear, p0, p1, p2, r.t_min, far.next_up()) {
                    let candidate = pack_hit(th, tri);
                    if candidate < key {
                        key = candidate;
                        far = th;
                    }
                }
            }
            t.set(best, key);
        });
        first += count;
    }
    blk.sync_threads();
    blk.for_each_thread(|t| {
        let id = t.get(ray_id);
        if id != u32::MAX {
            t.atomic_add(&a.visits, id as usize, 1);
            if t.get(best) != NO_HIT {
                t.atomic_min_u64(&a.keys, id as usize, t.get(best));
            }
        }
    });
}

/// `pdacrt::resolve_hits`: key of ray `i` into (t, triangle, barycentrics), with the
/// barycentrics from the same watertight test.
pub fn resolve_hit(
    t: &Thread,
    rays: &Global<RayData>,
    tris: &Global<[f32; 9]>,
    keys: &Global<u64>,
    out: &GlobalMut<HitData>,
    i: usize,
) {
    let key = t.load(keys, i);
    let miss = HitData { t: f32::INFINITY, prim: u32::MAX, u: 0.0, v: 0.0 };
    if key == NO_HIT {
        return t.store(out, i, miss);
    }
    let prim = (key & 0xffff_ffff) as u32;
    let th = key_t(key);
    let r = t.load(rays, i);
    let v = t.load(tris, prim as usize);
    let (p0, p1, p2) = (Vec3::new(v[0], v[1], v[2]), Vec3::new(v[3], v[4], v[5]), Vec3::new(v[6], v[7], v[8]));
    let o = Vec3::from_array(r.origin);
    let hit = intersect_triangle(o, &RayShear::new(Vec3::from_array(r.dir)), p0, p1, p2, r.t_min, th.next_up());
    let (tt, u, v) = hit.unwrap_or((th, 0.0, 0.0));
    t.store(out, i, HitData { t: tt, prim, u, v });
}
