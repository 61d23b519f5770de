//! DACRT's leaf: brute force over a node's rays and triangles, the triangles four at
//! a time on SIMD lanes (`geometry::lanes`), deciding hits by the same watertight rule
//! as every caster.

use super::state::{Dacrt, Trace};
use crate::geometry::RayShear;
use crate::geometry::hit_key::{BLOCKED, pack};
use crate::geometry::lanes::Triangles4;
use std::sync::atomic::Ordering::Relaxed;

/// 4-triangle blocks a leaf keeps on the stack (16 triangles; the default leaf rule
/// makes leaves of at most 12 triangles, or at most 12 rays).
const LEAF_BLOCKS: usize = 4;
impl Dacrt {
    /// Brute force over a node's rays and triangles, four triangles at a time (the
    /// watertight test on 4 lanes, `geometry::lanes`). A leaf of up to
    /// [`LEAF_BLOCKS`] blocks loads them once for all its rays; a larger one (a few
    /// rays against many triangles) loads each block as each ray reaches it.
    pub(super) fn leaf(&self, tr: &Trace, rays: &[u32], tris: &[u32]) {
        let load = |ids: &[u32]| {
            let mut corners = [[glam::Vec3::ZERO; 3]; 4];
            ids.iter().zip(&mut corners).for_each(|(&t, c)| *c = self.tris[t as usize]);
            Triangles4::new(&corners[..ids.len()])
        };
        let kept: Vec<Triangles4>;
        let mut stack = [Triangles4::EMPTY; LEAF_BLOCKS];
        let preloaded: &[Triangles4] = if tris.len() <= 4 * LEAF_BLOCKS {
            tris.chunks(4).zip(&mut stack).for_each(|(ids, b)| *b = load(ids));
            &stack[..tris.len().div_ceil(4)]
        } else if rays.len() > 2 {
            kept = tris.chunks(4).map(load).collect();
            &kept
        } else {
            &[]
        };
        let mut tests = 0u64;
        for &r in rays {
            let ray = &tr.rays[r as usize];
            let key = &tr.keys[r as usize];
            let shear = RayShear::new(ray.dir);
            if tr.any_hit && key.load(Relaxed) == BLOCKED {
                continue;
            }
            // Closest hit: the smallest key (distance, then id) among the triangles hit
            // before the ray's current end (`next_up` keeps a tie at equal distance, so
            // the smaller id wins). Any hit: the first triangle hit, in list order; the
            // tests made are those up to it.
            let mut best = key.load(Relaxed);
            let t_far = if tr.any_hit { ray.t_max } else { tr.t_far(r).next_up() };
            let mut made = tris.len();
            for (b, ids) in tris.chunks(4).enumerate() {
                let fresh;
                let block = match preloaded.get(b) {
                    Some(block) => block,
                    None => {
                        fresh = load(ids);
                        &fresh
                    }
                };
                let h = block.test(ray.origin, &shear, ray.t_min, t_far);
                if tr.any_hit {
                    if let Some(k) = h.first(ids.len()) {
                        (made, best) = (4 * b + k + 1, BLOCKED);
                        break;
                    }
                    continue;
                }
                if let Some(k) = h.closest(ids.len(), ids) {
                    best = best.min(pack(h.t[k], ids[k]));
                }
            }
            tests += made as u64;
            key.fetch_min(best, Relaxed);
        }
        tr.tests.fetch_add(tests, Relaxed);
    }
}
