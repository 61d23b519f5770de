//! Split planes chosen with the rays (after Nabata et al. 2013, "Efficient
//! divide-and-conquer ray tracing using ray sampling"): where a node holds many rays
//! and triangles, candidate planes are priced by what they will make the recursion do,
//! estimated on samples of both lists. A child costs the rays that enter its tight box
//! (the child clipped to its triangles' boxes) times the triangles it keeps; the plane
//! with the smallest sum wins. The spatial median prices every plane as if all rays
//! entered both halves; with incoherent rays (ambient occlusion, mirrors) a plane that
//! most rays cross only on one side keeps them out of the other half and everything
//! below it.
//!
//! Only the choice of plane changes: the partitions that follow test every ray and
//! triangle, so the hits are the same whatever plane is chosen.

use super::state::{Dacrt, Trace, spread};
use crate::geometry::Aabb;

/// Triangles and rays sampled per decision.
const TRIANGLE_SAMPLES: usize = 32;
const RAY_SAMPLES: usize = 16;
/// Candidate planes per axis: at `k / (CANDIDATES + 1)` of the node's extent.
const CANDIDATES: usize = 3;

impl Dacrt {
    /// The candidate plane of least estimated cost, or `None` when the node is too small
    /// to be worth pricing ([`DacrtParams::sampled_min_pairs`]) or no axis has extent.
    /// `tris` index `boxes`.
    ///
    /// [`DacrtParams::sampled_min_pairs`]: super::state::DacrtParams::sampled_min_pairs
    pub(super) fn sampled_plane(
        &self,
        tr: &Trace,
        boxes: &[Aabb],
        bounds: &Aabb,
        rays: &[u32],
        tris: &[u32],
    ) -> Option<(usize, f32)> {
        let min_pairs = self.params.sampled_min_pairs;
        if min_pairs == 0 || (rays.len() as u64) * (tris.len() as u64) < min_pairs {
            return None;
        }
        // (On the stack: a decision costs a few microseconds, an allocation would show.)
        let mut box_buf = [Aabb::EMPTY; TRIANGLE_SAMPLES];
        let mut ray_buf = [0u32; RAY_SAMPLES];
        let nb = fill(&mut box_buf, spread(tris, TRIANGLE_SAMPLES).map(|&t| boxes[t as usize]));
        let nr = fill(&mut ray_buf, spread(rays, RAY_SAMPLES).copied());
        let (sample_boxes, sample_rays) = (&box_buf[..nb], &ray_buf[..nr]);
        let (ext, min) = (bounds.extent(), bounds.min);
        let mut best: Option<(u64, usize, f32)> = None;
        for axis in (0..3).filter(|&a| ext[a] > 0.0) {
            for k in 1..=CANDIDATES {
                let pos = min[axis] + ext[axis] * k as f32 / (CANDIDATES + 1) as f32;
                let (lo, hi) = bounds.split(axis, pos);
                let cost: u64 = [lo, hi]
                    .iter()
                    .map(|child| {
                        let (kept, union) = sample_boxes
                            .iter()
                            .filter(|b| b.overlaps(child))
                            .fold((0u64, Aabb::EMPTY), |(n, u), b| (n + 1, u.union(*b)));
                        if kept == 0 {
                            return 0;
                        }
                        let tight = tr.grown(&child.intersection(union));
                        kept * sample_rays.iter().filter(|&&r| tr.enters(r, &tight)).count() as u64
                    })
                    .sum();
                if best.is_none_or(|b| cost < b.0) {
                    best = Some((cost, axis, pos));
                }
            }
        }
        best.map(|(_, axis, pos)| (axis, pos))
    }
}

/// Writes `items` into `buf` (at most its length); returns how many.
fn fill<T>(buf: &mut [T], items: impl Iterator<Item = T>) -> usize {
    buf.iter_mut().zip(items).map(|(slot, v)| *slot = v).count()
}

#[cfg(test)]
mod tests {
    use super::super::state::DacrtParams;
    use super::*;
    use crate::geometry::Ray;
    use crate::geometry::lanes::RaySlab;
    use glam::Vec3;

    /// A strip of thin triangles along x (0 to 8), and rays straight down onto
    /// `x_range` only: the plane priced cheapest is the candidate that keeps the rays'
    /// side smallest, where the spatial median (x = 4) and a price of triangles alone
    /// (every candidate ties) would split elsewhere.
    fn choice(x_range: (f32, f32), min_pairs: u64) -> Option<(usize, f32)> {
        let tris: Vec<[Vec3; 3]> = (0..400)
            .map(|i| {
                let x = i as f32 * 0.02;
                [Vec3::new(x, 0.0, 0.0), Vec3::new(x + 0.015, 0.0, 0.0), Vec3::new(x, 1.0, 0.0)]
            })
            .collect();
        let d = Dacrt::from_triangles(tris, DacrtParams { sampled_min_pairs: min_pairs, ..DacrtParams::default() });
        let rays: Vec<Ray> = (0..300)
            .map(|i| {
                let x = x_range.0 + (x_range.1 - x_range.0) * (i as f32 + 0.5) / 300.0;
                Ray::new(Vec3::new(x, 0.5, 1.0), Vec3::NEG_Z)
            })
            .collect();
        let slabs = rays.iter().map(RaySlab::new).collect();
        let tr = Trace::new(rays, slabs, false, 0, 0, d.magnitude, false);
        let (ray_ids, tri_ids): (Vec<u32>, Vec<u32>) = ((0..300).collect(), (0..400).collect());
        d.sampled_plane(&tr, &d.boxes, &d.scene_box, &ray_ids, &tri_ids)
    }

    #[test]
    fn rays_on_one_side_choose_the_plane_that_keeps_them_there() {
        let ext = choice((0.0, 1.0), 1).map(|(a, _)| a);
        assert_eq!(ext, Some(0), "the strip's long axis");
        // Rays on the last eighth: the plane at three quarters; on the first eighth,
        // the plane at a quarter.
        assert_eq!(choice((7.0, 7.9), 1), Some((0, 3.0 / 4.0 * 7.995)));
        assert_eq!(choice((0.0, 0.9), 1), Some((0, 1.0 / 4.0 * 7.995)));
        // 300 rays × 400 triangles: priced from that many pairs on, not below.
        assert!(choice((7.0, 7.9), 120_000).is_some());
        assert_eq!(choice((7.0, 7.9), 120_001), None);
    }
}
