//! Split planes that do not depend on the rays: a binned SAH over a subsample of a
//! node's triangles, and the median of their centroids; and a child's triangle test.

use super::state::{SAH_BINS, SAH_SAMPLES, place, spread, stable_partition};
use crate::geometry::Aabb;
use crate::geometry::lane_compact::compact;
use crate::geometry::lane_ops::{first_lanes, splat3};
use crate::geometry::packet_lanes::{F8, F16, Packed, Width};
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

/// Partitions `tris` (slots of `boxes`) so those whose boxes overlap `child` come
/// first, both parts in their order (`aside` holds the others meanwhile); returns their
/// count and the union of their boxes. On wide lanes the boxes are tested sixteen or
/// eight at a time (`partition_wide`), with the same answers, order and union as the
/// [`Grower`] one at a time.
#[inline]
pub(super) fn partition_triangles(
    lanes: Option<Width>,
    boxes: &[Aabb],
    tris: &mut [u32],
    child: &Aabb,
    aside: &mut Vec<u32>,
) -> (usize, Aabb) {
    let mut union = Aabb::EMPTY;
    let n = stable_partition(tris, aside, |tris, aside| {
        let (n, m, u) = match lanes {
            Some(width) => {
                type Loop = unsafe fn(&[Aabb], &mut [u32], &Aabb, &mut [u32]) -> (usize, usize, Aabb);
                let wide = width.pick::<Loop>([partition_avx512, partition_avx2]);
                // SAFETY: the loop is compiled for the width's extension, which the CPU
                // has (`pick` checked).
                unsafe { wide(boxes, tris, child, aside) }
            }
            None => {
                let mut g = Grower::new(child);
                let (n, m) = partition_tail(boxes, tris, 0, (0, 0), &mut g, aside);
                (n, m, g.union())
            }
        };
        union = u;
        (n, m)
    });
    (n, union)
}

#[target_feature(enable = "avx512f")]
fn partition_avx512(boxes: &[Aabb], tris: &mut [u32], child: &Aabb, aside: &mut [u32]) -> (usize, usize, Aabb) {
    partition_in::<F16>(boxes, tris, child, aside)
}

#[target_feature(enable = "avx2")]
fn partition_avx2(boxes: &[Aabb], tris: &mut [u32], child: &Aabb, aside: &mut [u32]) -> (usize, usize, Aabb) {
    partition_in::<F8>(boxes, tris, child, aside)
}

/// The partition of `tris[from..]` one box at a time through the [`Grower`], the counts
/// `(n, m)` so far given and returned.
#[inline(always)]
fn partition_tail(
    boxes: &[Aabb],
    tris: &mut [u32],
    from: usize,
    (mut n, mut m): (usize, usize),
    g: &mut Grower,
    aside: &mut [u32],
) -> (usize, usize) {
    for k in from..tris.len() {
        let id = tris[k];
        place(tris, aside, id, g.test(&boxes[id as usize]), &mut n, &mut m);
    }
    (n, m)
}

/// The partition of the triangles overlapping `child`, `L::WIDTH` boxes at a time: the
/// boxes' six floats loaded a box a lane, each lane's overlap answered as
/// [`Aabb::overlaps`] does (a NaN in any coordinate fails), the block's ids stored to
/// their sides in order (`geometry::lane_compact::compact`), and the union of the kept boxes kept per
/// lane (minima and maxima are exact, so the order they are met in does not matter);
/// the last boxes, fewer than a block, go through the [`Grower`].
#[inline(always)]
fn partition_in<L: Packed>(boxes: &[Aabb], tris: &mut [u32], child: &Aabb, aside: &mut [u32]) -> (usize, usize, Aabb) {
    let w = L::WIDTH;
    let floats = Aabb::floats(boxes);
    let (near, far) = (splat3::<L>(child.min), splat3::<L>(child.max));
    let (mut lo, mut hi) = ([L::splat(f32::INFINITY); 3], [L::splat(f32::NEG_INFINITY); 3]);
    let (mut n, mut m, mut i) = (0, 0, 0);
    let mut own = [0u32; 32];
    while i + w <= tris.len() {
        own[..w].copy_from_slice(&tris[i..i + w]);
        let [x0, y0, z0, x1, y1, z1, _, _] = L::records::<6>(floats, &own[..w]);
        let (b_lo, b_hi) = ([x0, y0, z0], [x1, y1, z1]);
        let keep = b_lo[0].le(far[0])
            & b_lo[1].le(far[1])
            & b_lo[2].le(far[2])
            & near[0].le(b_hi[0])
            & near[1].le(b_hi[1])
            & near[2].le(b_hi[2]);
        for a in 0..3 {
            lo[a] = L::select(keep, lo[a].min(b_lo[a]), lo[a]);
            hi[a] = L::select(keep, hi[a].max(b_hi[a]), hi[a]);
        }
        let bits = L::bits(keep);
        n += compact::<L>(&own[..w], bits, tris, n);
        m += compact::<L>(&own[..w], !bits & first_lanes(w), aside, m);
        i += w;
    }
    let mut g = Grower::new(child);
    (n, m) = partition_tail(boxes, tris, i, (n, m), &mut g, aside);
    if i == 0 {
        // A list shorter than a block: the `Grower` saw every box.
        return (n, m, g.union());
    }
    let (mut min, mut max) = ([f32::INFINITY; 3], [f32::NEG_INFINITY; 3]);
    for a in 0..3 {
        let (l, h) = (lo[a].to_array(), hi[a].to_array());
        for k in 0..w {
            (min[a], max[a]) = (min[a].min(l[k]), max[a].max(h[k]));
        }
    }
    let (union, tail) = (Aabb { min: min.into(), max: max.into() }, g.union());
    // Nothing kept in the blocks leaves an inverted box; the union with the tail's
    // (possibly empty) box is then the tail's.
    (n, m, if union.min.x > union.max.x { tail } else { union.union(tail) })
}

/// Binned SAH over a subsample of the triangles (their boxes clipped to the node):
/// cost of a plane = area(left)·n(left) + area(right)·n(right).
pub(super) fn sah_plane(boxes: &[Aabb], bounds: &Aabb, tris: &[u32]) -> Option<(usize, f32)> {
    let (ext, min) = (bounds.extent(), bounds.min);
    let bin = |axis: usize, x: f32| (((x - min[axis]) / ext[axis] * SAH_BINS as f32) as usize).min(SAH_BINS - 1);
    // Each sampled box is clipped once and binned on every axis of some extent.
    let (mut starts, mut ends) = ([[0u32; SAH_BINS]; 3], [[0u32; SAH_BINS]; 3]);
    let axes = || (0..3).filter(|&a| ext[a] > 0.0);
    for &t in spread(tris, SAH_SAMPLES) {
        let b = boxes[t as usize].intersection(*bounds);
        for axis in axes() {
            starts[axis][bin(axis, b.min[axis])] += 1;
            ends[axis][bin(axis, b.max[axis])] += 1;
        }
    }
    let mut best: Option<(f32, usize, f32)> = None;
    for axis in axes() {
        for k in 1..SAH_BINS {
            let pos = min[axis] + ext[axis] * k as f32 / SAH_BINS as f32;
            let n_lo: u32 = starts[axis][..k].iter().sum();
            let n_hi: u32 = ends[axis][k..].iter().sum();
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
    let mut c: Vec<f32> = spread(tris, SAH_SAMPLES).map(|&t| boxes[t as usize].center()[axis]).collect();
    if c.is_empty() {
        return None;
    }
    let mid = c.len() / 2;
    let (_, m, _) = c.select_nth_unstable_by(mid, f32::total_cmp);
    Some((axis, *m))
}

#[cfg(test)]
mod tests {
    use super::super::cases::widths;
    use super::super::state::{Dacrt, DacrtParams};
    use super::*;
    use crate::sampling::Rng;
    use glam::Vec3;

    /// The wide triangle partition leaves the list in the same order as the one at a
    /// time, with the same count and union, bit for bit: boxes on a coarse grid
    /// (touching the child's faces), random ones, flat ones and some with a NaN.
    #[test]
    fn wide_triangle_partitions_answer_as_the_grower() {
        let (mut kept, mut total) = (0, 0);
        for width in widths() {
            for trial in 0..2_000u64 {
                let mut rng = Rng::for_sample(31, trial, 0);
                let mut c = |coarse: bool| {
                    let v = rng.uniform() * 4.0 - 2.0;
                    if coarse { (v * 2.0).round() * 0.5 } else { v }
                };
                let tris: Vec<[Vec3; 3]> = (0..120)
                    .map(|k| {
                        let coarse = k % 2 == 0;
                        let mut p = [0; 3].map(|_| Vec3::new(c(coarse), c(coarse), c(coarse)));
                        if k % 17 == 3 {
                            p[1].y = f32::NAN;
                        }
                        if k % 5 == 1 {
                            p[2].z = p[0].z;
                            p[1].z = p[0].z;
                        }
                        p
                    })
                    .collect();
                let d = Dacrt::from_triangles(tris, DacrtParams::default());
                let (a, b) = (Vec3::new(c(true), c(true), c(true)), Vec3::new(c(true), c(true), c(true)));
                let child = Aabb { min: a.min(b), max: a.max(b) };
                let len = (trial as usize * 13) % 121;
                let ids: Vec<u32> = (0..len as u32).map(|i| (i * 53 + trial as u32) % 120).collect();
                let (mut w_ids, mut s_ids) = (ids.clone(), ids);
                let (wn, wu) = partition_triangles(Some(width), &d.boxes, &mut w_ids, &child, &mut Vec::new());
                let (sn, su) = partition_triangles(None, &d.boxes, &mut s_ids, &child, &mut Vec::new());
                assert_eq!((wn, &w_ids), (sn, &s_ids), "{width:?}, trial {trial}");
                let bits = |b: Aabb| b.as_floats().map(f32::to_bits);
                assert_eq!(bits(wu), bits(su), "{width:?}, trial {trial}: union {wu:?} against {su:?}");
                (kept, total) = (kept + wn, total + len);
            }
        }
        assert!(widths().is_empty() || (kept * 10 > total && kept * 10 < total * 9), "{kept} of {total}");
    }
}
