//! Split planes that do not depend on the rays: a binned SAH over a subsample of a
//! node's triangles, and the median of their centroids; and a child's triangle test.

use super::{Dacrt, SAH_BINS, SAH_SAMPLES};
use crate::geometry::Aabb;

impl Dacrt {
    /// True when triangle `t`'s box overlaps `child`; such a box is added to `union`
    /// (a child's tight box is the child clipped to that union).
    #[inline]
    pub(super) fn overlaps_growing(&self, t: u32, child: &Aabb, union: &mut Aabb) -> bool {
        let b = &self.boxes[t as usize];
        let keep = b.overlaps(child);
        if keep {
            *union = union.union(*b);
        }
        keep
    }
}

/// Binned SAH over a subsample of the triangles (their boxes clipped to the node):
/// cost of a plane = area(left)·n(left) + area(right)·n(right).
pub(super) fn sah_plane(boxes: &[Aabb], bounds: &Aabb, tris: &[u32]) -> Option<(usize, f32)> {
    let step = tris.len().div_ceil(SAH_SAMPLES).max(1);
    let (ext, min) = (bounds.extent(), bounds.min);
    let mut best: Option<(f32, usize, f32)> = None;
    for axis in 0..3 {
        if ext[axis] <= 0.0 {
            continue;
        }
        let bin = |x: f32| (((x - min[axis]) / ext[axis] * SAH_BINS as f32) as usize).min(SAH_BINS - 1);
        let (mut starts, mut ends) = ([0u32; SAH_BINS], [0u32; SAH_BINS]);
        for &t in tris.iter().step_by(step) {
            let b = boxes[t as usize].intersection(*bounds);
            starts[bin(b.min[axis])] += 1;
            ends[bin(b.max[axis])] += 1;
        }
        for k in 1..SAH_BINS {
            let pos = min[axis] + ext[axis] * k as f32 / SAH_BINS as f32;
            let n_lo: u32 = starts[..k].iter().sum();
            let n_hi: u32 = ends[k..].iter().sum();
            let (lo, hi) = bounds.split(axis, pos);
            let cost = lo.surface_area() * n_lo as f32 + hi.surface_area() * n_hi as f32;
            if best.is_none_or(|b| cost < b.0) {
                best = Some((cost, axis, pos));
            }
        }
    }
    best.map(|(_, a, p)| (a, p))
}

/// The median of (a subsample of) the triangle centroids along `axis`.
pub(super) fn centroid_median(boxes: &[Aabb], tris: &[u32], axis: usize) -> Option<(usize, f32)> {
    let step = tris.len().div_ceil(SAH_SAMPLES).max(1);
    let mut c: Vec<f32> = tris.iter().step_by(step).map(|&t| boxes[t as usize].center()[axis]).collect();
    if c.is_empty() {
        return None;
    }
    let mid = c.len() / 2;
    let (_, m, _) = c.select_nth_unstable_by(mid, f32::total_cmp);
    Some((axis, *m))
}
