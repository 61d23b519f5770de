//! Split planes that do not depend on the rays: a binned SAH over a subsample of a
//! node's triangles, and the median of their centroids; and a child's triangle test.

use super::state::{Dacrt, SAH_BINS, SAH_SAMPLES, partition};
use crate::geometry::Aabb;
use glam::{BVec4A, Vec4};

/// The triangle test of a child's partition: which triangles' boxes overlap the child,
/// and the union of those boxes (a child's tight box is the child clipped to it).
///
/// A box's six floats are read as two overlapping 4-lane loads, `(min.x, min.y, min.z,
/// max.x)` and `(min.z, max.x, max.y, max.z)`, each compared with the child's far or
/// near corner padded by an infinity in the lane that belongs to the other corner: one
/// comparison per load, no branch. The answer is `Aabb::overlaps`'s (NaN in any
/// coordinate fails both), and the union the same minima and maxima.
pub(super) struct Grower {
    /// The child's far corner against each box's `min` lanes (last lane +∞).
    far: Vec4,
    /// The child's near corner against each box's `max` lanes (first lane −∞).
    near: Vec4,
    lo: Vec4,
    hi: Vec4,
}

impl Grower {
    pub(super) fn new(child: &Aabb) -> Grower {
        Grower {
            far: child.max.extend(f32::INFINITY),
            near: Vec4::new(f32::NEG_INFINITY, child.min.x, child.min.y, child.min.z),
            lo: Vec4::INFINITY,
            hi: Vec4::NEG_INFINITY,
        }
    }

    /// Whether the box overlaps the child; a box that does joins the union.
    #[inline(always)]
    pub(super) fn test(&mut self, b: &Aabb) -> bool {
        let f = b.as_floats();
        let (lo, hi) = (Vec4::from_slice(&f[0..4]), Vec4::from_slice(&f[2..6]));
        let keep = (lo.cmple(self.far) & hi.cmpge(self.near)).all();
        let m = BVec4A::splat(keep);
        self.lo = Vec4::select(m, self.lo.min(lo), self.lo);
        self.hi = Vec4::select(m, self.hi.max(hi), self.hi);
        keep
    }

    /// The union of the boxes kept so far (empty if none: a kept box has `min.x <=
    /// max.x`, lanes 0 of `lo` and 1 of `hi`).
    pub(super) fn union(&self) -> Aabb {
        if self.lo.x > self.hi.y {
            return Aabb::EMPTY;
        }
        Aabb { min: self.lo.truncate(), max: glam::Vec3::new(self.hi.y, self.hi.z, self.hi.w) }
    }
}

impl Dacrt {
    /// Partitions `tris` so those whose boxes overlap `child` come first; returns their
    /// count and the union of their boxes.
    #[inline]
    pub(super) fn partition_triangles(&self, tris: &mut [u32], child: &Aabb) -> (usize, Aabb) {
        let mut g = Grower::new(child);
        let n = partition(tris, |t| g.test(&self.boxes[t as usize]));
        (n, g.union())
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
