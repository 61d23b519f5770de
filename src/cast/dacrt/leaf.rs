//! DACRT's leaf: brute force over a node's rays and triangles, a ray at a time against
//! its triangles a lane per triangle (sixteen on AVX-512, eight on AVX2, four on SSE:
//! `geometry::packet_lanes`, the widest the CPU has, found once per call), with the
//! watertight test of `geometry::lane_ops` that every caster's lanes run. A lane whose
//! edge function is exactly zero takes the scalar test (its double-precision
//! tie-break), so every width gives the same keys and counts the same tests: hits and
//! images do not depend on the CPU's vector width (`tests` checks each width the CPU
//! has against SSE).

use super::state::{Dacrt, Soup, Trace};
use crate::geometry::hit_key::{BLOCKED, pack};
use crate::geometry::lane_ops::{first_lanes, splat3, watertight};
use crate::geometry::packet_lanes::{F8, F16, Packed};
use crate::geometry::{RayShear, closer, triangle_test};
use glam::{Vec3, Vec4};
use std::sync::atomic::Ordering::Relaxed;

impl Dacrt {
    /// Brute force over a node's rays and triangles on the trace's lanes. A leaf of up
    /// to [`LEAF_BLOCKS`] blocks loads them once for all its rays; a larger one (a few
    /// rays against many triangles) loads each block as each ray reaches it.
    /// `tris` are slots of `soup`; keys carry their scene ids.
    pub(super) fn leaf(&self, tr: &Trace, soup: Soup, rays: &[u32], tris: &[u32]) {
        match tr.lanes {
            None => leaf_in::<Vec4>(soup, tr, rays, tris),
            Some(width) => {
                type Loop = unsafe fn(Soup, &Trace, &[u32], &[u32]);
                let wide = width.pick::<Loop>([leaf_avx512, leaf_avx2]);
                // SAFETY: the loop is compiled for the width's extension, which the
                // CPU has (`pick` checked).
                unsafe { wide(soup, tr, rays, tris) }
            }
        }
    }
}

#[target_feature(enable = "avx512f")]
fn leaf_avx512(d: Soup, tr: &Trace, rays: &[u32], tris: &[u32]) {
    leaf_in::<F16>(d, tr, rays, tris)
}

#[target_feature(enable = "avx2")]
fn leaf_avx2(d: Soup, tr: &Trace, rays: &[u32], tris: &[u32]) {
    leaf_in::<F8>(d, tr, rays, tris)
}

/// Up to `L::WIDTH` triangles, corner by corner and axis by axis, a lane each; lanes past
/// the list hold zeros (a degenerate triangle, masked off by the caller).
#[inline(always)]
fn block<L: Packed>(tris: &[[Vec3; 3]], ids: &[u32]) -> [[L; 3]; 3] {
    let mut p = [[L::Array::default(); 3]; 3];
    for (k, &t) in ids.iter().enumerate() {
        let c = &tris[t as usize];
        for (corner, lanes) in c.iter().zip(&mut p) {
            for a in 0..3 {
                lanes[a][k] = corner[a];
            }
        }
    }
    let l = L::from_array;
    [[l(p[0][0]), l(p[0][1]), l(p[0][2])], [l(p[1][0]), l(p[1][1]), l(p[1][2])], [l(p[2][0]), l(p[2][1]), l(p[2][2])]]
}

/// Blocks a leaf keeps on the stack: 64 triangles on AVX-512, 32 on AVX2, 16 on SSE
/// (the default leaf rule makes leaves of at most 12 triangles, or at most 12 rays).
const LEAF_BLOCKS: usize = 4;

#[inline(always)]
fn leaf_in<L: Packed>(d: Soup, tr: &Trace, rays: &[u32], tris: &[u32]) {
    let w = L::WIDTH;
    let kept: Vec<[[L; 3]; 3]>;
    let mut stack = [[[L::splat(0.0); 3]; 3]; LEAF_BLOCKS];
    let preloaded: &[[[L; 3]; 3]] = if tris.len() <= w * LEAF_BLOCKS {
        for (ids, b) in tris.chunks(w).zip(&mut stack) {
            *b = block::<L>(d.corners, ids);
        }
        &stack[..tris.len().div_ceil(w)]
    } else if rays.len() > 2 {
        let mut blocks = Vec::with_capacity(tris.len().div_ceil(w));
        for ids in tris.chunks(w) {
            blocks.push(block::<L>(d.corners, ids));
        }
        kept = blocks;
        &kept
    } else {
        &[]
    };
    let mut tests = 0u64;
    for &r in rays {
        let ray = &tr.rays[r as usize];
        let key = &tr.keys[r as usize];
        if tr.any_hit && key.load(Relaxed) == BLOCKED {
            continue;
        }
        let shear = RayShear::new(ray.dir);
        let [r0, r1, r2] = shear.rows();
        let rows = [splat3::<L>(r0.into()), splat3::<L>(r1.into()), splat3::<L>(r2.into())];
        let origin = splat3::<L>(ray.origin);
        // Closest hit: the smallest key (distance, then id) among the triangles hit
        // before the ray's current end (`next_up` keeps a tie at equal distance, so the
        // smaller id wins). Any hit: the first triangle hit, in list order; the tests
        // made are those up to it.
        let mut best = key.load(Relaxed);
        let t_far = if tr.any_hit { ray.t_max } else { tr.t_far(r).next_up() };
        let (t_min_l, t_far_l) = (L::splat(ray.t_min), L::splat(t_far));
        let mut made = tris.len();
        for (b, ids) in tris.chunks(w).enumerate() {
            let fresh;
            let p = match preloaded.get(b) {
                Some(p) => p,
                None => {
                    fresh = block::<L>(d.corners, ids);
                    &fresh
                }
            };
            let h = watertight(p, origin, &rows, t_min_l, t_far_l);
            let live = first_lanes(ids.len());
            let (mut mask, mut edge) = (h.mask & live, h.on_edge & live);
            if mask == 0 && edge == 0 {
                continue;
            }
            let mut t = h.t.to_array();
            while edge != 0 {
                let k = edge.trailing_zeros() as usize;
                edge &= edge - 1;
                let corners = d.corners[ids[k] as usize];
                if let (_, Some((tk, _, _))) = triangle_test(ray.origin, &shear, corners, ray.t_min, t_far) {
                    (mask, t[k]) = (mask | 1 << k, tk);
                }
            }
            if mask == 0 {
                continue;
            }
            if tr.any_hit {
                (made, best) = (w * b + mask.trailing_zeros() as usize + 1, BLOCKED);
                break;
            }
            // The closest lane (ties to the smaller id: `closer`, every caster's rule).
            let mut lane = mask.trailing_zeros() as usize;
            let mut rest = mask & (mask - 1);
            while rest != 0 {
                let k = rest.trailing_zeros() as usize;
                rest &= rest - 1;
                if closer((t[k], d.id(ids[k])), (t[lane], d.id(ids[lane]))) {
                    lane = k;
                }
            }
            best = best.min(pack(t[lane], d.id(ids[lane])));
        }
        tests += made as u64;
        key.fetch_min(best, Relaxed);
    }
    tr.tests.fetch_add(tests, Relaxed);
}

#[cfg(test)]
mod tests {
    use super::super::cases::{case, widths};
    use super::super::state::DacrtParams;
    use super::*;
    use crate::sampling::Rng;

    /// The wide leaves find the same keys and count the same tests as the SSE one, for
    /// closest and any hits, with leaves of one triangle to more than four blocks.
    #[test]
    fn wide_leaves_answer_as_the_sse_one() {
        let mut hits = 0;
        for width in widths() {
            for trial in 0..600u64 {
                let any_hit = trial % 3 == 2;
                let (tris, mut wide) = case(&mut Rng::for_sample(23, trial, 0), any_hit, true);
                wide.lanes = Some(width);
                let (_, sse) = case(&mut Rng::for_sample(23, trial, 0), any_hit, false);
                let d = Dacrt::from_triangles(tris, DacrtParams::default());
                let n_tris = 1 + (trial as usize * 5) % 40;
                let n_rays = 1 + (trial as usize * 3) % 13;
                let tri_ids: Vec<u32> = (0..n_tris as u32).map(|i| (i * 7 + trial as u32) % 40).collect();
                let ray_ids: Vec<u32> = (0..n_rays as u32).map(|i| (i * 11 + trial as u32) % 200).collect();
                d.leaf(&wide, d.soup(), &ray_ids, &tri_ids);
                d.leaf(&sse, d.soup(), &ray_ids, &tri_ids);
                for &r in &ray_ids {
                    let (w, s) = (wide.keys[r as usize].load(Relaxed), sse.keys[r as usize].load(Relaxed));
                    assert_eq!(w, s, "{width:?}, trial {trial}, ray {r}");
                }
                assert_eq!(wide.tests.load(Relaxed), sse.tests.load(Relaxed), "{width:?}, trial {trial}: tests");
                let before = case(&mut Rng::for_sample(23, trial, 0), any_hit, false).1;
                hits += ray_ids
                    .iter()
                    .filter(|&&r| before.keys[r as usize].load(Relaxed) != sse.keys[r as usize].load(Relaxed))
                    .count();
            }
        }
        // The leaves found hits that changed keys (the check is not vacuous).
        assert!(widths().is_empty() || hits > 500, "{hits} keys changed");
    }
}
