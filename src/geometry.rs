//! Rays, hits, boxes and the robust primitives every caster shares.
//!
//! * [`intersect_triangle`]: the watertight ray/triangle test of Woop, Benthin and Wald
//!   (JCGT 2013). Edge functions are evaluated in a ray-aligned shear space and fall back
//!   to `f64` when one of them is exactly zero, so a ray that passes through a shared edge
//!   or vertex of a closed mesh always hits at least one of the triangles.
//! * [`Aabb::intersect`]: a slab test that accepts zero direction components (infinite
//!   reciprocals) without producing NaN, and widens its far distance by a few ulps so
//!   it never rejects a box that a watertight triangle test would hit (Ize 2013).
//! * [`offset_ray_origin`]: moves a surface point off its surface along the geometric
//!   normal by an amount that scales with the magnitude of the coordinates (Wächter and
//!   Binder, Ray Tracing Gems ch. 6), so secondary rays do not re-hit their own triangle.

use glam::Vec3;

pub(crate) mod hit_key;
mod slack;
pub(crate) use slack::{batch_slack, hit_slack, magnitude};
#[cfg(target_arch = "x86_64")]
pub(crate) mod lane_compact;
pub(crate) mod lane_ops;
pub mod lanes;
#[cfg(target_arch = "x86_64")]
pub(crate) mod packet_lanes;
mod watertight;
pub(crate) use watertight::triangle_test;
pub use watertight::{RayShear, intersect_triangle};

/// A ray with a parametric interval `[t_min, t_max)`. `dir` need not be normalised;
/// distances are in units of `dir`.
#[derive(Clone, Copy, Debug, PartialEq)]
#[repr(C)]
pub struct Ray {
    /// Where the ray starts.
    pub origin: Vec3,
    /// Direction (unit length from the constructors).
    pub dir: Vec3,
    /// Nearest distance that counts as a hit.
    pub t_min: f32,
    /// Farthest distance that counts as a hit (a shadow ray's segment end).
    pub t_max: f32,
}

impl Ray {
    /// A ray from `origin` along `dir`, unbounded.
    pub fn new(origin: Vec3, dir: Vec3) -> Self {
        Ray { origin, dir, t_min: 0.0, t_max: f32::INFINITY }
    }

    /// A ray limited to `t < t_max` (shadow rays toward a light).
    pub fn segment(origin: Vec3, dir: Vec3, t_max: f32) -> Self {
        Ray { origin, dir, t_min: 0.0, t_max }
    }

    /// The point at distance `t`.
    pub fn at(&self, t: f32) -> Vec3 {
        self.origin + self.dir * t
    }

    /// True when every component is finite and the direction is not zero.
    pub fn is_valid(&self) -> bool {
        self.origin.is_finite()
            && self.dir.is_finite()
            && self.dir != Vec3::ZERO
            && !self.t_min.is_nan()
            && !self.t_max.is_nan()
    }
}

/// The closest hit of a ray: distance, triangle id and barycentrics of vertices 1 and 2.
#[derive(Clone, Copy, Debug, PartialEq)]
#[repr(C)]
pub struct Hit {
    /// Distance along the ray (in units of its direction's length).
    pub t: f32,
    /// Triangle index into the scene, or [`Hit::NONE`] for a miss.
    pub prim: u32,
    /// Barycentric weight of the triangle's second vertex.
    pub u: f32,
    /// Barycentric weight of the triangle's third vertex.
    pub v: f32,
}

impl Hit {
    /// `prim` of a miss.
    pub const NONE: u32 = u32::MAX;
    /// No hit.
    pub const MISS: Hit = Hit { t: f32::INFINITY, prim: Hit::NONE, u: 0.0, v: 0.0 };

    /// Whether the ray hit something.
    pub fn is_hit(&self) -> bool {
        self.prim != Hit::NONE
    }

    /// Whether a hit at `t` on triangle `prim` replaces this one ([`closer`]).
    #[inline]
    pub fn loses_to(&self, t: f32, prim: u32) -> bool {
        closer((t, prim), (self.t, self.prim))
    }
}

/// Whether a hit at distance `a.0` on triangle `a.1` is closer than one at `b`: a
/// smaller distance, or the same distance on a smaller id (brute force's answer on
/// ties, which every caster gives; for non-negative distances, the order of
/// [`hit_key`] keys).
#[inline(always)]
pub fn closer(a: (f32, u32), b: (f32, u32)) -> bool {
    a.0 < b.0 || (a.0 == b.0 && a.1 < b.1)
}

impl Default for Hit {
    fn default() -> Self {
        Hit::MISS
    }
}

/// An axis-aligned box. The empty box has `min > max`.
#[derive(Clone, Copy, Debug, PartialEq)]
#[repr(C)]
pub struct Aabb {
    /// Smallest corner.
    pub min: Vec3,
    /// Largest corner.
    pub max: Vec3,
}

/// 1 + 2·γ(3) with γ(n) = nε/(1−nε): the widening that makes the slab test conservative.
pub(crate) const SLAB_WIDEN: f32 = 1.0 + 2.0 * (3.0 * f32::EPSILON * 0.5) / (1.0 - 3.0 * f32::EPSILON * 0.5);

/// Where a caster may stop looking at boxes for a ray whose interval ends at `far`
/// (its best hit so far, or its `t_max`): that distance widened as the slab test widens
/// box exits, so a box entered exactly at the best hit (a tie on a shared edge,
/// near-coplanar triangles) is still visited and the smaller key can win. DACRT's and
/// PDACRT's ray partitions cull with it; `cull_distance` in cuda/geometry.cuh is its
/// CUDA side.
#[inline]
pub(crate) fn cull_distance(far: f32) -> f32 {
    far * SLAB_WIDEN
}

/// [`cull_distance`] on SIMD lanes (DACRT's wide ray partition), the same product.
#[inline(always)]
pub(crate) fn cull_distance_lanes<L: lane_ops::Lanes>(far: L) -> L {
    far * L::splat(SLAB_WIDEN)
}

impl Default for Aabb {
    fn default() -> Self {
        Aabb::EMPTY
    }
}

impl Aabb {
    /// The box of nothing (the identity of `union`).
    pub const EMPTY: Aabb = Aabb { min: Vec3::splat(f32::INFINITY), max: Vec3::splat(f32::NEG_INFINITY) };

    /// The box around `points`.
    pub fn from_points(points: &[Vec3]) -> Aabb {
        points.iter().fold(Aabb::EMPTY, |b, &p| b.grow(p))
    }

    /// This box grown to hold `p`.
    pub fn grow(self, p: Vec3) -> Aabb {
        Aabb { min: self.min.min(p), max: self.max.max(p) }
    }

    /// This box grown by `g` on every side.
    #[inline]
    pub fn grown(self, g: f32) -> Aabb {
        Aabb { min: self.min - g, max: self.max + g }
    }

    /// The box around both.
    pub fn union(self, o: Aabb) -> Aabb {
        Aabb { min: self.min.min(o.min), max: self.max.max(o.max) }
    }

    /// Whether it holds no point.
    pub fn is_empty(&self) -> bool {
        self.min.cmpgt(self.max).any()
    }

    /// `max − min`.
    pub fn extent(&self) -> Vec3 {
        (self.max - self.min).max(Vec3::ZERO)
    }

    /// The midpoint.
    pub fn center(&self) -> Vec3 {
        (self.min + self.max) * 0.5
    }

    /// The axis (0, 1, 2) of greatest extent.
    pub fn longest_axis(&self) -> usize {
        let e = self.extent();
        if e.x >= e.y && e.x >= e.z {
            0
        } else if e.y >= e.z {
            1
        } else {
            2
        }
    }

    /// The common part of two boxes (empty when they do not overlap).
    pub fn intersection(self, o: Aabb) -> Aabb {
        Aabb { min: self.min.max(o.min), max: self.max.min(o.max) }
    }

    /// The boxes' coordinates, six a box in [`Aabb::as_floats`]' order (what wide lanes
    /// load a box a lane).
    pub(crate) fn floats(boxes: &[Aabb]) -> &[f32] {
        // SAFETY: as in `as_floats`: each box is six `f32` with no padding, and the
        // slice's boxes lie back to back (`size_of::<Aabb>()` is 24).
        const _: () = assert!(std::mem::size_of::<Aabb>() == 6 * std::mem::size_of::<f32>());
        unsafe { std::slice::from_raw_parts(boxes.as_ptr().cast::<f32>(), boxes.len() * 6) }
    }

    /// The six coordinates in memory order: `min.x, min.y, min.z, max.x, max.y, max.z`.
    #[inline]
    pub fn as_floats(&self) -> &[f32; 6] {
        // SAFETY: `Aabb` is `repr(C)` of two `Vec3`, each `repr(C)` of three `f32`: six
        // `f32` in this order, with `f32`'s alignment and no padding.
        unsafe { &*(self as *const Aabb as *const [f32; 6]) }
    }

    /// True when the closed boxes share at least one point.
    #[inline]
    pub fn overlaps(&self, o: &Aabb) -> bool {
        self.min.cmple(o.max).all() && self.max.cmpge(o.min).all()
    }

    /// The axes ordered by decreasing extent (ties keep x before y before z).
    pub fn axes_by_extent(&self) -> [usize; 3] {
        let e = self.extent();
        let mut axes = [0, 1, 2];
        axes.sort_by(|&a, &b| e[b].total_cmp(&e[a]));
        axes
    }

    /// The two halves of the box on either side of the plane `axis = pos`.
    pub fn split(&self, axis: usize, pos: f32) -> (Aabb, Aabb) {
        let (mut lo, mut hi) = (*self, *self);
        lo.max[axis] = pos;
        hi.min[axis] = pos;
        (lo, hi)
    }

    /// Surface area (0 for an empty box).
    pub fn surface_area(&self) -> f32 {
        let e = self.extent();
        2.0 * (e.x * e.y + e.y * e.z + e.z * e.x)
    }

    /// Slab test against a ray given with its reciprocal direction. Returns the
    /// parametric entry and exit distances clipped to `[t_min, t_max]`, or `None`.
    ///
    /// A zero direction component (infinite reciprocal) is decided by position alone:
    /// the ray is inside that slab when its origin lies in the closed interval, which
    /// avoids the NaN of `0 · ∞` for an origin exactly on a slab plane.
    #[inline]
    pub fn intersect(&self, origin: Vec3, inv_dir: Vec3, t_min: f32, t_max: f32) -> Option<(f32, f32)> {
        let mut near = t_min;
        let mut far = t_max;
        for a in 0..3 {
            if inv_dir[a].is_infinite() {
                if origin[a] < self.min[a] || origin[a] > self.max[a] {
                    return None;
                }
                continue;
            }
            let t0 = (self.min[a] - origin[a]) * inv_dir[a];
            let t1 = (self.max[a] - origin[a]) * inv_dir[a];
            near = near.max(t0.min(t1));
            far = far.min(t0.max(t1) * SLAB_WIDEN);
        }
        (near <= far).then_some((near, far))
    }
}

/// Reciprocal of a direction; zero components become signed infinities. The three
/// divisions run on one vector's lanes (the same IEEE quotients as one at a time).
#[inline]
pub fn inv_dir(dir: Vec3) -> Vec3 {
    Vec3::from(glam::Vec3A::ONE / glam::Vec3A::from(dir))
}

/// The point of triangle `[a, b, c]` with barycentric weights `u` (of `b`) and `v` (of
/// `c`): a hit's position, a point sampled on an area light. One expression, so that
/// every caller rounds it the same way.
#[inline(always)]
pub fn barycentric_point([a, b, c]: [Vec3; 3], u: f32, v: f32) -> Vec3 {
    a * (1.0 - u - v) + b * u + c * v
}

/// Geometric normal (not normalised) of a triangle, following its winding.
#[inline]
pub fn triangle_normal(p0: Vec3, p1: Vec3, p2: Vec3) -> Vec3 {
    (p1 - p0).cross(p2 - p0)
}

/// Offsets a surface point along the unit geometric normal `n` (flipped to the side
/// the new ray leaves from) so that a ray starting there does not hit its own surface.
/// Far from the origin the step is a fixed number of ulps of each coordinate; near
/// the origin, where ulps are tiny, it is a small fixed distance.
#[inline]
pub fn offset_ray_origin(p: Vec3, n: Vec3) -> Vec3 {
    const NEAR_ORIGIN: f32 = 1.0 / 32.0;
    const FLOAT_STEP: f32 = 1.0 / 65536.0;
    const ULP_STEP: f32 = 256.0;
    let mut out = p;
    for a in 0..3 {
        let ulps = (ULP_STEP * n[a]) as i32;
        let bits = p[a].to_bits() as i32;
        let stepped = f32::from_bits(if p[a] < 0.0 { bits - ulps } else { bits + ulps } as u32);
        out[a] = if p[a].abs() < NEAR_ORIGIN { p[a] + FLOAT_STEP * n[a] } else { stepped };
    }
    out
}

// SAFETY: #[repr(C)] structs of 4-byte fields (glam's `Vec3` is three `f32`), no
// padding: they travel in device buffers as they are.
unsafe impl simt::DeviceCopy for Ray {}
unsafe impl simt::DeviceCopy for Hit {}
unsafe impl simt::DeviceCopy for Aabb {}

/// A unit sphere about the origin as a closed, outward-facing triangle mesh with shared
/// vertices: the regular icosahedron, each triangle split in four `subdivisions` times
/// (20·4^n triangles), every new vertex pushed out onto the sphere.
pub fn icosphere(subdivisions: u32) -> (Vec<Vec3>, Vec<[u32; 3]>) {
    let g = (1.0 + 5f32.sqrt()) / 2.0;
    let corners = [
        (-1.0, g, 0.0),
        (1.0, g, 0.0),
        (-1.0, -g, 0.0),
        (1.0, -g, 0.0),
        (0.0, -1.0, g),
        (0.0, 1.0, g),
        (0.0, -1.0, -g),
        (0.0, 1.0, -g),
        (g, 0.0, -1.0),
        (g, 0.0, 1.0),
        (-g, 0.0, -1.0),
        (-g, 0.0, 1.0),
    ];
    let mut p: Vec<Vec3> = corners.iter().map(|&(x, y, z)| Vec3::new(x, y, z).normalize()).collect();
    #[rustfmt::skip]
    let mut t: Vec<[u32; 3]> = vec![
        [0, 11, 5], [0, 5, 1], [0, 1, 7], [0, 7, 10], [0, 10, 11],
        [1, 5, 9], [5, 11, 4], [11, 10, 2], [10, 7, 6], [7, 1, 8],
        [3, 9, 4], [3, 4, 2], [3, 2, 6], [3, 6, 8], [3, 8, 9],
        [4, 9, 5], [2, 4, 11], [6, 2, 10], [8, 6, 7], [9, 8, 1],
    ];
    for _ in 0..subdivisions {
        let mut mid = std::collections::HashMap::new();
        let mut split = |a: u32, b: u32, p: &mut Vec<Vec3>| {
            *mid.entry((a.min(b), a.max(b))).or_insert_with(|| {
                p.push(((p[a as usize] + p[b as usize]) * 0.5).normalize());
                p.len() as u32 - 1
            })
        };
        let mut next = Vec::with_capacity(t.len() * 4);
        for [a, b, c] in t {
            let (ab, bc, ca) = (split(a, b, &mut p), split(b, c, &mut p), split(c, a, &mut p));
            next.extend([[a, ab, ca], [b, bc, ab], [c, ca, bc], [ab, bc, ca]]);
        }
        t = next;
    }
    (p, t)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn triangle_hit_and_barycentrics() {
        let (p0, p1, p2) = (Vec3::new(0.0, 0.0, 0.0), Vec3::new(1.0, 0.0, 0.0), Vec3::new(0.0, 1.0, 0.0));
        let o = Vec3::new(0.25, 0.5, 1.0);
        let d = Vec3::new(0.0, 0.0, -1.0);
        let (t, u, v) = intersect_triangle(o, &RayShear::new(d), p0, p1, p2, 0.0, f32::INFINITY).unwrap();
        assert!((t - 1.0).abs() < 1e-6);
        assert!((u - 0.25).abs() < 1e-6 && (v - 0.5).abs() < 1e-6);
        // Behind the origin and beyond t_max are misses.
        assert!(intersect_triangle(o, &RayShear::new(-d), p0, p1, p2, 0.0, f32::INFINITY).is_none());
        assert!(intersect_triangle(o, &RayShear::new(d), p0, p1, p2, 0.0, 0.5).is_none());
    }

    #[test]
    fn slab_accepts_zero_direction_components() {
        let b = Aabb { min: Vec3::ZERO, max: Vec3::ONE };
        // Axis-aligned ray inside the x and y slabs, origin exactly on the min x plane.
        let o = Vec3::new(0.0, 0.5, -1.0);
        let d = Vec3::new(0.0, 0.0, 1.0);
        let (n, f) = b.intersect(o, inv_dir(d), 0.0, f32::INFINITY).unwrap();
        assert!((n - 1.0).abs() < 1e-6 && (f - 2.0).abs() < 1e-5);
        // Outside the y slab with a zero y component: a miss.
        let o = Vec3::new(0.5, 1.5, -1.0);
        assert!(b.intersect(o, inv_dir(d), 0.0, f32::INFINITY).is_none());
    }

    #[test]
    fn offset_leaves_the_surface_on_the_normal_side() {
        for &p in &[Vec3::new(1000.0, -2000.0, 3.0), Vec3::new(0.001, 0.0, -0.01), Vec3::new(-5.0, 7.0, 1e-6)] {
            let n = Vec3::new(0.3, -0.5, 0.8).normalize();
            let q = offset_ray_origin(p, n);
            assert!((q - p).dot(n) > 0.0, "{p} -> {q}");
        }
    }
}
