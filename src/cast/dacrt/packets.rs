//! DACRT's ray order and packet filtering for its ray partitions (after Mora 2011, who
//! bounds rays that share an origin by a cone and rejects a whole packet when its cone
//! misses a cell).
//!
//! A trace renumbers its rays in coherence order, so the rays of a packet are
//! consecutive ids, and every ray list in the recursion stays in ascending id order
//! (the partitions are stable). A packet is bounded by intervals: its origins' box, the
//! range of each reciprocal direction component, the smallest `t_min` and the largest
//! `t_max`. Interval arithmetic on the slab test then gives a lower bound on every
//! member's entry distance and an upper bound on its exit distance; when the bounds do
//! not overlap, no ray of the packet enters the box and the packet is rejected with one
//! test. Otherwise its rays are tested one by one, as without packets. Unlike a cone,
//! the bound needs no shared origin, so shadow rays from nearby points toward one light
//! are filtered too.
//!
//! The bound is exact in floating point: rounding is monotone, so the interval ends,
//! computed with the same operations as a ray's own test, bound what that test computes.
//! An axis on which some member's direction component is zero (an infinite reciprocal),
//! or on which the members' directions have both signs, gives no bound.

use crate::geometry::lanes::RaySlab;
use crate::geometry::{Aabb, Ray, SLAB_WIDEN};
use glam::{Vec3, Vec3A};
use rayon::prelude::*;

/// A run of fewer of one packet's rays in a ray list is tested ray by ray: a packet
/// test costs about two ray tests, and short runs are rarely rejected whole (32-ray
/// packets, runs of 2, 4 and 8 measured on the VM: `docs/history/dacrt-runs.md`).
pub(super) const MIN_RUN: usize = 8;

/// Bounds of one packet's rays (see the module docs).
#[derive(Clone, Copy, Debug)]
pub(super) struct PacketBounds {
    o_lo: Vec3,
    o_hi: Vec3,
    inv_lo: Vec3,
    inv_hi: Vec3,
    t_min: f32,
    t_max: f32,
    /// Axes with an infinite reciprocal in some member, or reciprocals of both signs:
    /// no bound on them.
    free: [bool; 3],
}

impl PacketBounds {
    fn of(rays: &[Ray], inv: &[Vec3]) -> PacketBounds {
        let mut b = PacketBounds {
            o_lo: Vec3::INFINITY,
            o_hi: Vec3::NEG_INFINITY,
            inv_lo: Vec3::INFINITY,
            inv_hi: Vec3::NEG_INFINITY,
            t_min: f32::INFINITY,
            t_max: f32::NEG_INFINITY,
            free: [false; 3],
        };
        for (r, i) in rays.iter().zip(inv) {
            b.o_lo = b.o_lo.min(r.origin);
            b.o_hi = b.o_hi.max(r.origin);
            b.inv_lo = b.inv_lo.min(*i);
            b.inv_hi = b.inv_hi.max(*i);
            b.t_min = b.t_min.min(r.t_min);
            b.t_max = b.t_max.max(r.t_max);
        }
        for a in 0..3 {
            // No bound from an axis with a zero component or both signs.
            b.free[a] =
                b.inv_lo[a].is_infinite() || b.inv_hi[a].is_infinite() || (b.inv_lo[a] < 0.0) != (b.inv_hi[a] < 0.0);
        }
        b
    }

    /// True when no member ray can enter `b` (no member's own slab test,
    /// [`Aabb::intersect`] up to its `t_max`, can succeed). `b` must not be inverted.
    #[inline]
    pub(super) fn misses(&self, b: &Aabb) -> bool {
        let mut near = self.t_min;
        let mut far = self.t_max;
        for a in 0..3 {
            if self.free[a] {
                continue;
            }
            // With the direction's sign fixed, a member's entry distance is least for
            // the origin farthest along the axis from the entry plane, and its exit
            // distance greatest for the origin farthest back from the exit plane; each
            // is then a product with the reciprocal, extreme at one end of its range.
            let (il, ih) = (self.inv_lo[a], self.inv_hi[a]);
            let (enter, exit) = if il > 0.0 {
                (b.min[a] - self.o_hi[a], b.max[a] - self.o_lo[a])
            } else {
                (b.max[a] - self.o_lo[a], b.min[a] - self.o_hi[a])
            };
            near = near.max((enter * il).min(enter * ih));
            far = far.min((exit * il).max(exit * ih) * SLAB_WIDEN);
        }
        near > far
    }
}

/// The packets of a trace: packet `p` holds the rays `p << shift ..` of the trace's
/// (renumbered) rays.
pub(super) struct Packets {
    shift: u32,
    bounds: Vec<PacketBounds>,
}

impl Packets {
    /// Packets of `size` rays (a power of two) over the trace's rays; `None` for size 0.
    pub(super) fn new(rays: &[Ray], slabs: &[RaySlab], size: usize) -> Option<Packets> {
        if size == 0 {
            return None;
        }
        let inv: Vec<Vec3> = slabs.par_iter().map(RaySlab::inv_dir).collect();
        let size = size.next_power_of_two();
        let bounds = rays.par_chunks(size).zip(inv.par_chunks(size)).map(|(r, i)| PacketBounds::of(r, i)).collect();
        Some(Packets { shift: size.trailing_zeros(), bounds })
    }

    pub(super) fn bytes(&self) -> usize {
        self.bounds.len() * std::mem::size_of::<PacketBounds>()
    }

    #[inline]
    pub(super) fn of(&self, ray: u32) -> usize {
        (ray >> self.shift) as usize
    }

    #[inline]
    pub(super) fn misses(&self, packet: usize, b: &Aabb) -> bool {
        self.bounds[packet].misses(b)
    }
}

/// A Morton-style key that puts rays with nearby origins and directions next to each
/// other: 10 bits per component of the origin (in `bounds`) and the unit direction,
/// interleaved (direction bits first at every level): bit `b` of component `j` (x, y,
/// z of the direction, then of the origin) lands on bit `6b + 5 - j`. Each component
/// is `(c.clamp(0, 1) · 1023) as usize`, computed three lanes at a time: the lanes run
/// the scalar operations (the direction's length as `(x·x + y·y) + z·z`), so the key is
/// the same on every machine.
pub(super) fn coherence_key(ray: &Ray, bounds: &Aabb) -> u64 {
    let o = (Vec3A::from(ray.origin) - Vec3A::from(bounds.min)) / Vec3A::from(bounds.extent().max(Vec3::splat(1e-30)));
    let d = Vec3A::from(ray.dir).normalize_or_zero() * 0.5 + 0.5;
    let (o, d) = (o.clamp(Vec3A::ZERO, Vec3A::ONE) * 1023.0, d.clamp(Vec3A::ZERO, Vec3A::ONE) * 1023.0);
    // A NaN (a ray or box with non-finite coordinates) becomes 0, as `as` makes it.
    let q = |x: f32| {
        if x.is_nan() {
            0
        } else {
            // SAFETY: `x` is not NaN and lies in [0, 1023] (clamped, then scaled), where
            // truncation to an integer is defined.
            unsafe { x.to_int_unchecked::<u32>() as usize }
        }
    };
    let comps = [q(d.x), q(d.y), q(d.z), q(o.x), q(o.y), q(o.z)];
    comps.iter().enumerate().fold(0, |key, (j, &c)| key | SPREAD6[c] << (5 - j))
}

/// The coherence key's origin bits: a batch whose keys agree on all of them starts
/// from one point (to 1/1024 of the scene's box on every axis).
pub(super) const ORIGIN_BITS: u64 = {
    let (mut bits, mut b) = (0u64, 0);
    while b < 10 {
        bits |= 0b111 << (6 * b);
        b += 1;
    }
    bits
};

/// Every 10-bit value with bit `b` moved to bit `6b`: one lookup per component instead
/// of a loop over the key's 60 bits.
static SPREAD6: [u64; 1024] = {
    let mut table = [0u64; 1024];
    let mut v = 0;
    while v < 1024 {
        let mut b = 0;
        while b < 10 {
            table[v] |= ((v as u64 >> b) & 1) << (6 * b);
            b += 1;
        }
        v += 1;
    }
    table
};

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::inv_dir;
    use crate::sampling::Rng;

    /// The coherence key's table lookups put every component bit where the plain
    /// interleave (bit by bit, direction first at every level) puts it, for random rays
    /// and for each single set bit of each component.
    #[test]
    fn coherence_key_interleaves_like_the_bit_loop() {
        let interleave = |comps: [u64; 6]| {
            let mut key = 0u64;
            for bit in (0..10).rev() {
                for c in comps {
                    key = key << 1 | (c >> bit & 1);
                }
            }
            key
        };
        for j in 0..6 {
            for b in 0..10 {
                let mut comps = [0; 6];
                comps[j] = 1 << b;
                let lookup = comps.iter().enumerate().fold(0, |k, (j, &c)| k | SPREAD6[c as usize] << (5 - j));
                assert_eq!(lookup, interleave(comps), "component {j}, bit {b}");
            }
        }
        let bounds = Aabb { min: Vec3::splat(-2.0), max: Vec3::new(3.0, 1.0, 2.0) };
        let mut rng = Rng::for_sample(5, 0, 0);
        for _ in 0..2000 {
            let mut u = || rng.uniform();
            let ray = Ray::new(
                Vec3::new(u() * 6.0 - 2.5, u() * 4.0 - 2.5, u() * 5.0 - 2.5),
                Vec3::new(u() - 0.5, u() - 0.5, u() - 0.5),
            );
            let q = |x: f32| (x.clamp(0.0, 1.0) * 1023.0) as u64;
            let o = (ray.origin - bounds.min) / bounds.extent();
            let d = ray.dir.normalize_or_zero() * 0.5 + 0.5;
            assert_eq!(coherence_key(&ray, &bounds), interleave([q(d.x), q(d.y), q(d.z), q(o.x), q(o.y), q(o.z)]));
        }
    }

    /// A packet of rays around one direction from nearby origins (some trials share the
    /// origin, some have a zero or sign-changing direction component, some end early).
    fn packet(rng: &mut Rng, trial: u64) -> Vec<Ray> {
        let mut u = || rng.uniform() * 2.0 - 1.0;
        let centre = Vec3::new(u(), u(), u());
        let axis = Vec3::new(u(), u(), u()).normalize_or(Vec3::Z);
        let spread = [0.0, 0.01, 0.1, 0.5][(trial % 4) as usize];
        let width = [0.0, 0.05, 0.3][(trial / 4 % 3) as usize];
        (0..32)
            .map(|k| {
                let mut dir = (axis + Vec3::new(u(), u(), u()) * spread).normalize_or(Vec3::X);
                if trial.is_multiple_of(7) && k % 5 == 0 {
                    dir.y = 0.0;
                }
                let origin = centre + Vec3::new(u(), u(), u()) * width;
                let t_min = if trial.is_multiple_of(3) { u().abs() * 0.2 } else { 0.0 };
                let t_max = if trial.is_multiple_of(2) { f32::INFINITY } else { 0.5 + u().abs() * 3.0 };
                Ray { origin, dir, t_min, t_max }
            })
            .collect()
    }

    /// A box near the packet: around a point on one member ray, sometimes with a corner
    /// exactly on it, sometimes flat.
    fn near_box(rng: &mut Rng, rays: &[Ray], trial: u64) -> Aabb {
        let r = rays[(rng.uniform() * rays.len() as f32) as usize % rays.len()];
        let p = r.origin
            + r.dir * (rng.uniform() * 4.0 - 0.5)
            + Vec3::new(rng.uniform(), rng.uniform(), rng.uniform()) * 0.2
            - 0.1;
        let mut e = Vec3::new(rng.uniform(), rng.uniform(), rng.uniform()) * 0.3;
        if trial.is_multiple_of(5) {
            e.z = 0.0;
        }
        if trial % 6 == 1 {
            let q = r.origin + r.dir * (rng.uniform() * 2.0);
            return Aabb { min: q, max: q + e };
        }
        Aabb { min: p, max: p + e }
    }

    #[test]
    fn a_packet_rejects_only_boxes_that_no_member_enters() {
        let (mut rejected, mut all_miss) = (0, 0);
        for trial in 0..20_000u64 {
            let mut rng = Rng::for_sample(7, trial, 0);
            let rays = packet(&mut rng, trial);
            let inv: Vec<Vec3> = rays.iter().map(|r| inv_dir(r.dir)).collect();
            let bounds = PacketBounds::of(&rays, &inv);
            let b = near_box(&mut rng, &rays, trial);
            let enters = rays.iter().zip(&inv).filter(|(r, i)| b.intersect(r.origin, **i, r.t_min, r.t_max).is_some());
            let entering = enters.count();
            if bounds.misses(&b) {
                assert_eq!(entering, 0, "trial {trial}: packet rejected {b:?} but {entering} rays enter it");
                rejected += 1;
            }
            all_miss += (entering == 0) as u32;
        }
        // The test is not vacuous, and the bound is not useless: a good share of the
        // boxes that every member misses are rejected by the packet alone (38 % over
        // these trials, whose packets are up to 0.5 wide in direction and 0.3 in origin).
        assert!(all_miss > 2_000, "only {all_miss} boxes missed by every ray");
        assert!(rejected * 4 > all_miss, "packets rejected {rejected} of {all_miss} boxes that every ray misses");
    }
}
