//! Packets of rays through the 4-wide BVH: each node's child boxes and each leaf's
//! triangles are tested against the packet's rays on SIMD lanes, one per ray (sixteen
//! on AVX-512, [`F16`]; eight on AVX2, [`F8`]), with the box and triangle tests of
//! [`lane_ops`](crate::geometry::lane_ops) that the single-ray traversal runs over four
//! children or triangles. A packet visits a node when any of its rays enters the
//! node's box; each ray keeps its own best hit, cull distance and mask of live lanes,
//! so every lane's answer is the single-ray traversal's (and brute force's) bit for
//! bit, whatever order the packet takes: the boxes are tested as the single ray tests
//! them, and the closest hit, ties to the smaller id, does not depend on the order
//! triangles are met in.
//!
//! What it saves over one ray at a time is per ray what a node costs once per packet
//! (its loads, the stack, the branches that decide where to go), and the lanes: eight
//! or sixteen rays on one register against four boxes on one SSE register. Rays that
//! a packet cannot take (a direction component zero, which the slab test decides by
//! position) go one at a time.

use super::node::{LEAF, Leaf, leaf_of};
use super::{Bvh4, SHALLOW_DEPTH, SHORT_STACK, STACK};
use crate::cast::caster::{CastStats, per_packet};
use crate::geometry::lane_ops::{LaneHits, slab, splat3, watertight};
use crate::geometry::packet_lanes::{F8, F16, Packed, Width};
use crate::geometry::{Hit, Ray, RayShear, closer, cull_distance, inv_dir, triangle_test};
use glam::Vec3;

/// A packet's rays, lane by lane. Lanes past the rays, or whose ray goes one at a time,
/// are not live: they hold zeros and no answer is read from them.
struct Packet<L> {
    origin: [L; 3],
    inv: [L; 3],
    rows: [[L; 3]; 3],
    t_min: L,
    t_max: L,
    grow: L,
    live: u32,
}

impl<L: Packed> Packet<L> {
    /// The packet of up to `L::WIDTH` rays; lanes of `single` (a bit per ray) are left out.
    #[inline(always)]
    fn new(bvh: &Bvh4, rays: &[Ray], single: u32) -> Packet<L> {
        let zero = L::Array::default();
        let (mut origin, mut inv, mut rows) = ([zero; 3], [zero; 3], [[zero; 3]; 3]);
        let (mut t_min, mut t_max, mut grow, mut live) = (zero, zero, zero, 0);
        for (k, ray) in rays.iter().enumerate().filter(|(k, _)| single >> k & 1 == 0) {
            let (i, shear) = (inv_dir(ray.dir), RayShear::new(ray.dir).rows());
            for a in 0..3 {
                (origin[a][k], inv[a][k]) = (ray.origin[a], i[a]);
                for (r, row) in shear.iter().enumerate() {
                    rows[r][a][k] = row[a];
                }
            }
            (t_min[k], t_max[k], grow[k]) = (ray.t_min, ray.t_max, bvh.grow(ray));
            live |= 1 << k;
        }
        let f = L::from_array;
        Packet {
            origin: origin.map(f),
            inv: inv.map(f),
            rows: rows.map(|r| r.map(f)),
            t_min: f(t_min),
            t_max: f(t_max),
            grow: f(grow),
            live,
        }
    }

    /// Which live lanes of `active` a leaf triangle is hit by within `(t_min, far)`,
    /// with each lane's `(t, u, v)`: the lane test, and the scalar test for lanes on an
    /// edge (its double-precision tie-break), as [`Triangles4`](crate::geometry::lanes::Triangles4) does.
    #[inline(always)]
    fn test(&self, rays: &[Ray], tri: [Vec3; 3], active: u32, far: L) -> LaneHits<L> {
        let p = tri.map(splat3);
        let mut h = watertight(&p, self.origin, &self.rows, self.t_min, far);
        h.mask &= active;
        let edge = h.on_edge & active;
        if edge != 0 {
            on_edge(&mut h, edge, rays, tri, far);
        }
        h
    }
}

/// Lanes with an edge function exactly zero: the scalar test decides them.
#[cold]
#[inline(never)]
fn on_edge<L: Packed>(h: &mut LaneHits<L>, mut edge: u32, rays: &[Ray], tri: [Vec3; 3], far: L) {
    let (far, mut t, mut u, mut v) = (far.to_array(), h.t.to_array(), h.u.to_array(), h.v.to_array());
    while edge != 0 {
        let k = edge.trailing_zeros() as usize;
        edge &= edge - 1;
        let ray = &rays[k];
        if let (_, Some(hit)) = triangle_test(ray.origin, &RayShear::new(ray.dir), tri, ray.t_min, far[k]) {
            h.mask |= 1 << k;
            (t[k], u[k], v[k]) = hit;
        }
    }
    (h.t, h.u, h.v) = (L::from_array(t), L::from_array(u), L::from_array(v));
}

/// Rays of a batch a packet leaves to the single-ray traversal: a zero (or non-finite)
/// reciprocal direction component, or an invalid ray.
#[inline(always)]
fn singles(rays: &[Ray]) -> u32 {
    rays.iter().enumerate().fold(0, |m, (k, r)| m | (!(r.is_valid() && inv_dir(r.dir).is_finite()) as u32) << k)
}

/// The packet of `rays`, after answering the rays it leaves out with `one` (invalid
/// ones with `miss`) and setting the others' answers to `miss`; and the tests made.
#[inline(always)]
fn start<L: Packed, T: Copy>(
    bvh: &Bvh4,
    rays: &[Ray],
    out: &mut [T],
    miss: T,
    one: impl Fn(&Ray) -> (T, u64),
) -> (Packet<L>, u64) {
    let single = singles(rays);
    let mut tests = 0;
    for (k, (ray, o)) in rays.iter().zip(out.iter_mut()).enumerate() {
        *o = miss;
        if single >> k & 1 == 1 && ray.is_valid() {
            let (answer, t) = one(ray);
            (*o, tests) = (answer, tests + t);
        }
    }
    (Packet::new(bvh, rays, single), tests)
}

/// Up to `L::WIDTH` rays' closest hits (written to `hits`) and the ray–triangle tests
/// made. Needs a BVH without outliers.
#[inline(always)]
fn closest<L: Packed>(bvh: &Bvh4, rays: &[Ray], hits: &mut [Hit]) -> u64 {
    if bvh.depth <= SHALLOW_DEPTH {
        closest_in::<L, SHORT_STACK>(bvh, rays, hits)
    } else {
        closest_in::<L, STACK>(bvh, rays, hits)
    }
}

#[inline(always)]
fn closest_in<L: Packed, const N: usize>(bvh: &Bvh4, rays: &[Ray], hits: &mut [Hit]) -> u64 {
    let (p, mut tests) = start::<L, _>(bvh, rays, hits, Hit::MISS, |ray| bvh.closest_one(ray));
    let Some(root) = bvh.root.filter(|_| p.live != 0) else { return tests };
    // Per lane: the far end of leaf tests (the best hit's next float, which keeps ties)
    // and the distance past which boxes are culled, as the single-ray traversal sets them.
    let t_max = p.t_max.to_array();
    let (mut far_lanes, mut cull_lanes) = (t_max, t_max);
    for k in 0..L::WIDTH {
        cull_lanes[k] = cull_distance(t_max[k]);
    }
    let (mut far, mut cull) = (p.t_max, L::from_array(cull_lanes));
    let (mut codes, mut masks, mut nears) = ([0u32; N], [0u32; N], [L::splat(0.0); N]);
    (codes[0], masks[0], nears[0]) = (root, p.live, L::splat(f32::NEG_INFINITY));
    let mut top = 1;
    while top > 0 {
        top -= 1;
        let (code, near) = (codes[top], nears[top]);
        let active = masks[top] & L::bits(near.le(cull));
        if active == 0 {
            continue;
        }
        if code & LEAF != 0 {
            let (l, len) = leaf_of(code);
            let leaf: &Leaf = &bvh.leaves[l];
            // The far end stays the one from before the leaf for all its triangles, as in
            // the single-ray traversal; a closer hit updates it (and the cull) after.
            let mut closer_found = false;
            for j in 0..len {
                let h = p.test(rays, leaf.tris.triangle(j), active, far);
                tests += active.count_ones() as u64;
                if h.mask == 0 {
                    continue;
                }
                let (mut hit, t, u, v) = (h.mask, h.t.to_array(), h.u.to_array(), h.v.to_array());
                while hit != 0 {
                    let k = hit.trailing_zeros() as usize;
                    hit &= hit - 1;
                    let best = &mut hits[k];
                    if closer((t[k], leaf.ids[j]), (best.t, best.prim)) {
                        *best = Hit { t: t[k], prim: leaf.ids[j], u: u[k], v: v[k] };
                        far_lanes[k] = best.t.next_up().min(t_max[k]);
                        cull_lanes[k] = cull_distance(best.t.min(t_max[k]));
                        closer_found = true;
                    }
                }
            }
            if closer_found {
                (far, cull) = (L::from_array(far_lanes), L::from_array(cull_lanes));
            }
            continue;
        }
        let node = &bvh.nodes[code as usize];
        let mut entered = [(0u32, 0u32, L::splat(0.0), 0.0f32); 4];
        let mut count = 0;
        for c in 0..node.children as usize {
            let b = node.boxes.get(c);
            let (m, near) = slab(splat3(b.min), splat3(b.max), p.origin, p.inv, p.grow, p.t_min, cull);
            let m = m & active;
            if m != 0 {
                // The nearest entry among the rays that enter orders the pushes.
                entered[count] = (node.child[c], m, near, near.min_where(m));
                count += 1;
            }
        }
        // Push farthest first, so the nearest is taken next.
        entered[..count].sort_unstable_by(|a, b| b.3.total_cmp(&a.3));
        for &(child, m, near, _) in &entered[..count] {
            (codes[top], masks[top], nears[top]) = (child, m, near);
            top += 1;
        }
    }
    tests
}

/// Whether anything lies on each of up to `L::WIDTH` rays within its interval
/// (written to `out`), and the ray–triangle tests made. Needs a BVH without outliers.
#[inline(always)]
fn occluded<L: Packed>(bvh: &Bvh4, rays: &[Ray], out: &mut [bool]) -> u64 {
    if bvh.depth <= SHALLOW_DEPTH {
        occluded_in::<L, SHORT_STACK>(bvh, rays, out)
    } else {
        occluded_in::<L, STACK>(bvh, rays, out)
    }
}

#[inline(always)]
fn occluded_in<L: Packed, const N: usize>(bvh: &Bvh4, rays: &[Ray], out: &mut [bool]) -> u64 {
    let (p, mut tests) = start::<L, _>(bvh, rays, out, false, |ray| bvh.occluded_one(ray));
    let Some(root) = bvh.root.filter(|_| p.live != 0) else { return tests };
    let mut cull = p.t_max.to_array();
    for k in 0..L::WIDTH {
        cull[k] = cull_distance(cull[k]);
    }
    let cull = L::from_array(cull);
    let mut blocked = 0u32;
    let (mut codes, mut masks) = ([0u32; N], [0u32; N]);
    (codes[0], masks[0]) = (root, p.live);
    let mut top = 1;
    while top > 0 && blocked != p.live {
        top -= 1;
        let (code, active) = (codes[top], masks[top] & !blocked);
        if active == 0 {
            continue;
        }
        if code & LEAF != 0 {
            let (l, len) = leaf_of(code);
            let leaf = &bvh.leaves[l];
            let mut left = active;
            for j in 0..len {
                tests += left.count_ones() as u64;
                left &= !p.test(rays, leaf.tris.triangle(j), left, p.t_max).mask;
                if left == 0 {
                    break;
                }
            }
            blocked |= active & !left;
            continue;
        }
        let node = &bvh.nodes[code as usize];
        for c in 0..node.children as usize {
            let b = node.boxes.get(c);
            let m = slab(splat3(b.min), splat3(b.max), p.origin, p.inv, p.grow, p.t_min, cull).0 & active;
            if m != 0 {
                (codes[top], masks[top]) = (node.child[c], m);
                top += 1;
            }
        }
    }
    for (k, o) in out.iter_mut().enumerate() {
        if p.live >> k & 1 == 1 {
            *o = blocked >> k & 1 == 1;
        }
    }
    tests
}

/// A packet traversal compiled for one extension: unsafe to call where the CPU lacks it.
type Traversal<T> = unsafe fn(&Bvh4, &[Ray], &mut [T]) -> u64;

impl Width {
    /// The closest hits of a batch, in packets of this width.
    pub(super) fn closest(self, bvh: &Bvh4, rays: &[Ray], hits: &mut [Hit]) -> CastStats {
        self.trace(bvh, rays, hits, [closest_avx512, closest_avx2])
    }

    /// The occlusion of a batch, in packets of this width.
    pub(super) fn occluded(self, bvh: &Bvh4, rays: &[Ray], out: &mut [bool]) -> CastStats {
        self.trace(bvh, rays, out, [occluded_avx512, occluded_avx2])
    }

    /// Every packet of the batch through the traversal compiled for this width
    /// (`traversals` in the order of [`Width::ALL`]).
    fn trace<T: Send>(self, bvh: &Bvh4, rays: &[Ray], out: &mut [T], traversals: [Traversal<T>; 2]) -> CastStats {
        let traversal = self.pick(traversals);
        // SAFETY: the traversal is compiled for this width's extension, which the CPU
        // has (`pick` checked).
        per_packet(rays, out, self.rays(), |r, o| unsafe { traversal(bvh, r, o) })
    }
}

/// [`closest`] on AVX2 lanes. Call only on a CPU with AVX2.
#[target_feature(enable = "avx2")]
fn closest_avx2(bvh: &Bvh4, rays: &[Ray], hits: &mut [Hit]) -> u64 {
    closest::<F8>(bvh, rays, hits)
}

/// [`occluded`] on AVX2 lanes. Call only on a CPU with AVX2.
#[target_feature(enable = "avx2")]
fn occluded_avx2(bvh: &Bvh4, rays: &[Ray], out: &mut [bool]) -> u64 {
    occluded::<F8>(bvh, rays, out)
}

/// [`closest`] on AVX-512 lanes. Call only on a CPU with AVX-512F.
#[target_feature(enable = "avx512f")]
fn closest_avx512(bvh: &Bvh4, rays: &[Ray], hits: &mut [Hit]) -> u64 {
    closest::<F16>(bvh, rays, hits)
}

/// [`occluded`] on AVX-512 lanes. Call only on a CPU with AVX-512F.
#[target_feature(enable = "avx512f")]
fn occluded_avx512(bvh: &Bvh4, rays: &[Ray], out: &mut [bool]) -> u64 {
    occluded::<F16>(bvh, rays, out)
}

const _: () = assert!(F8::WIDTH <= 32 && F16::WIDTH <= 32, "lane masks are u32");

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cast::{BruteForce, RayCaster};
    use crate::sampling::Rng;

    /// Every packet width this CPU runs; fails loudly where it runs none.
    fn widths() -> Vec<usize> {
        let widths: Vec<usize> = Width::ALL.into_iter().filter(|w| w.supported()).map(Width::rays).collect();
        assert!(
            !widths.is_empty(),
            "this CPU has no AVX2, so the BVH4's packets cannot run here: the test has nothing to check"
        );
        widths
    }

    /// Traces `rays` through packets of every width and checks each answer against the
    /// single-ray traversal (bit for bit) and brute force; returns the hits and the
    /// blocked rays counted.
    fn agree(tris: &[[Vec3; 3]], rays: &[Ray], label: &str) -> (usize, usize) {
        let n = rays.len();
        let brute = BruteForce::from_triangles(tris.to_vec());
        let (mut truth, mut truth_o) = (vec![Hit::MISS; n], vec![false; n]);
        brute.closest(rays, &mut truth);
        brute.occluded(rays, &mut truth_o);
        let (mut hits, mut blocked) = (0, 0);
        for width in widths() {
            let bvh = Bvh4::from_triangles(tris.to_vec()).max_packet(width);
            assert_eq!(bvh.packets(rays.len()).map(Width::rays), Some(width), "packets of {width} rays");
            // The answers' slots start stale: every one must be written.
            let stale = Hit { t: 1.0, prim: 7, u: 0.5, v: 0.5 };
            let (mut got, mut got_o) = (vec![stale; n], vec![true; n]);
            bvh.closest(rays, &mut got);
            bvh.occluded(rays, &mut got_o);
            let bits = |h: &Hit| (h.prim, h.t.to_bits(), h.u.to_bits(), h.v.to_bits());
            for (k, ray) in rays.iter().enumerate() {
                let (single, single_o) =
                    if ray.is_valid() { (bvh.closest_one(ray).0, bvh.occluded_one(ray).0) } else { (Hit::MISS, false) };
                let at = format!("{label}, {width}-ray packets, ray {k}: {ray:?}");
                assert_eq!(bits(&got[k]), bits(&single), "{at}");
                assert_eq!((got[k].prim, got[k].t.to_bits()), (truth[k].prim, truth[k].t.to_bits()), "{at}");
                assert_eq!((got_o[k], got_o[k]), (single_o, truth_o[k]), "occlusion, {at}");
            }
            hits += got.iter().filter(|h| h.is_hit()).count();
            blocked += got_o.iter().filter(|&&b| b).count();
        }
        (hits, blocked)
    }

    /// Packets of every width this CPU runs answer every ray as the single-ray
    /// traversal does, bit for bit, and as brute force: corners and rays on a coarse
    /// grid (shared edges, edge functions exactly zero, rays along faces, zero direction
    /// components in the middle of packets, ties at `t_max`), invalid rays, an empty
    /// scene, and batches that end in part of a packet.
    #[test]
    fn packets_answer_as_single_rays_and_brute_force() {
        let mut r = Rng::for_sample(23, 0, 0);
        let (mut hits, mut blocked, mut rays_seen) = (0, 0, 0);
        for trial in 0..24 {
            let coarse = trial % 2 == 0;
            let point = |r: &mut Rng| {
                let v = Vec3::new(r.uniform(), r.uniform(), r.uniform()) * 4.0 - 2.0;
                if coarse { (v * 2.0).round() * 0.5 } else { v }
            };
            // Trial 0 is an empty scene (no tree at all).
            let count = if trial == 0 { 0 } else { 40 + trial * 25 };
            let tris: Vec<[Vec3; 3]> = (0..count).map(|_| [point(&mut r), point(&mut r), point(&mut r)]).collect();
            let rays: Vec<Ray> = (0..1000 + trial)
                .map(|k| {
                    let o = point(&mut r) * 1.5;
                    let mut d = point(&mut r) - o;
                    if k % 7 == 0 {
                        d[k % 3] = 0.0;
                    }
                    match k % 11 {
                        0 => Ray { origin: o, dir: Vec3::ZERO, t_min: 0.0, t_max: 1.0 },
                        1 | 2 => Ray::segment(o, d, (r.uniform() * 8.0).floor() * 0.25),
                        _ => Ray::new(o, d),
                    }
                })
                .collect();
            let (h, b) = agree(&tris, &rays, &format!("trial {trial}"));
            (hits, blocked, rays_seen) = (hits + h, blocked + b, rays_seen + rays.len() * widths().len());
        }
        // Both answers occur often (the check is not one-sided).
        assert!(hits > rays_seen / 10 && hits < rays_seen * 9 / 10, "{hits} hits of {rays_seen}");
        assert!(blocked > rays_seen / 10 && blocked < rays_seen * 9 / 10, "{blocked} blocked of {rays_seen}");
    }
}
