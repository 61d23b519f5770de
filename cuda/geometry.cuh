// The geometry every CUDA twin shares, one copy of each rule: the Rust data layouts
// (`#[repr(C)]`, 4-byte fields), the widened slab test, the watertight triangle test
// and the closest-hit key of src/geometry/hit_key.rs. PDACRT's leaf (cuda/pdacrt.cu)
// and the BVH baseline's traversal (cuda/bvh.cu) both call these, so both give the
// Rust casters' keys bit for bit (build with -fmad=false, as cuda/build.sh does).
#pragma once

#include <cmath>
#include <cstdint>

namespace wr {


struct Vec3 {
    float x, y, z;
};
struct Ray {
    Vec3 o, d;
    float t_min, t_max;
};
struct Aabb {
    Vec3 lo, hi;
};
struct Tri {
    float v[9];
};

static_assert(sizeof(Ray) == 32, "Ray layout");
static_assert(sizeof(Tri) == 36, "triangle layout");

constexpr uint64_t NO_HIT = ~0ull;
constexpr uint64_t BLOCKED = 0;

// ---------------------------------------------------------------- geometry (geometry.rs)

__host__ __device__ inline float comp(const Vec3& v, int a) { return a == 0 ? v.x : (a == 1 ? v.y : v.z); }
__host__ __device__ inline void set_comp(Vec3& v, int a, float x) {
    if (a == 0) v.x = x;
    else if (a == 1) v.y = x;
    else v.z = x;
}
__host__ __device__ inline Vec3 vmin(Vec3 a, Vec3 b) { return {fminf(a.x, b.x), fminf(a.y, b.y), fminf(a.z, b.z)}; }
__host__ __device__ inline Vec3 vmax(Vec3 a, Vec3 b) { return {fmaxf(a.x, b.x), fmaxf(a.y, b.y), fmaxf(a.z, b.z)}; }
__host__ __device__ inline Vec3 sub(Vec3 a, Vec3 b) { return {a.x - b.x, a.y - b.y, a.z - b.z}; }

__device__ inline Aabb empty_box() { return {{INFINITY, INFINITY, INFINITY}, {-INFINITY, -INFINITY, -INFINITY}}; }
__device__ inline Aabb box_union(Aabb a, Aabb b) { return {vmin(a.lo, b.lo), vmax(a.hi, b.hi)}; }
__device__ inline Aabb box_of(const Tri& t) {
    Aabb b = empty_box();
    for (int k = 0; k < 3; k++) {
        Vec3 p = {t.v[3 * k], t.v[3 * k + 1], t.v[3 * k + 2]};
        b.lo = vmin(b.lo, p);
        b.hi = vmax(b.hi, p);
    }
    return b;
}
__device__ inline bool overlaps(const Aabb& a, const Aabb& b) {
    return a.lo.x <= b.hi.x && a.lo.y <= b.hi.y && a.lo.z <= b.hi.z && a.hi.x >= b.lo.x && a.hi.y >= b.lo.y &&
           a.hi.z >= b.lo.z;
}

/// `Aabb::grown`: the box grown by `g` on every side (`geometry::batch_slack`, so that
/// no hit the watertight test reports just off a triangle is culled).
__host__ __device__ inline Aabb grown(const Aabb& b, float g) {
    return {{b.lo.x - g, b.lo.y - g, b.lo.z - g}, {b.hi.x + g, b.hi.y + g, b.hi.z + g}};
}

/// `Aabb::intersect`: the widened slab test; a zero direction component is decided
/// by position. On entry `near_t` is where the ray starts (t_min); on a true return it
/// is where the ray enters the box.
__host__ __device__ inline bool slab_entry(const Aabb& b, Vec3 o, Vec3 inv, float t_max, float widen, float& near_t) {
    float far_t = t_max;
    for (int a = 0; a < 3; a++) {
        float ia = comp(inv, a), oa = comp(o, a), lo = comp(b.lo, a), hi = comp(b.hi, a);
        if (isinf(ia)) {
            if (oa < lo || oa > hi) return false;
            continue;
        }
        float t0 = (lo - oa) * ia;
        float t1 = (hi - oa) * ia;
        near_t = fmaxf(near_t, fminf(t0, t1));
        far_t = fminf(far_t, fmaxf(t0, t1) * widen);
    }
    return near_t <= far_t;
}
__host__ __device__ inline bool enters(const Aabb& b, Vec3 o, Vec3 inv, float t_min, float t_max, float widen) {
    float near_t = t_min;
    return slab_entry(b, o, inv, t_max, widen, near_t);
}

__host__ __device__ inline Vec3 inv_dir(Vec3 d) { return {1.0f / d.x, 1.0f / d.y, 1.0f / d.z}; }

__host__ __device__ inline bool finite3(Vec3 v) { return isfinite(v.x) && isfinite(v.y) && isfinite(v.z); }
__host__ __device__ inline bool ray_valid(const Ray& r) {
    return finite3(r.o) && finite3(r.d) && !(r.d.x == 0.0f && r.d.y == 0.0f && r.d.z == 0.0f) && !isnan(r.t_min) &&
           !isnan(r.t_max);
}

/// `RayShear`: the permutation that makes the dominant axis z, and the shear.
struct Shear {
    int kx, ky, kz;
    float sx, sy, sz;
};
__device__ inline Shear make_shear(Vec3 d) {
    float ax = fabsf(d.x), ay = fabsf(d.y), az = fabsf(d.z);
    int kz = (ax >= ay && ax >= az) ? 0 : (ay >= az ? 1 : 2);
    int kx = (kz + 1) % 3, ky = (kx + 1) % 3;
    if (comp(d, kz) < 0.0f) {
        int s = kx;
        kx = ky;
        ky = s;
    }
    float dz = comp(d, kz);
    return {kx, ky, kz, comp(d, kx) / dz, comp(d, ky) / dz, 1.0f / dz};
}

/// `intersect_triangle`: watertight and two-sided; true with `t` for t_min < t < t_max,
/// and the barycentric weights `u`, `w` of the second and third corners.
__device__ inline bool hit_triangle_uv(Vec3 o, const Shear& s, const float* v, float t_min, float t_max, float& t_out,
                                       float& u, float& w) {
    Vec3 a = sub({v[0], v[1], v[2]}, o), b = sub({v[3], v[4], v[5]}, o), c = sub({v[6], v[7], v[8]}, o);
    float az0 = comp(a, s.kz), bz0 = comp(b, s.kz), cz0 = comp(c, s.kz);
    float ax = comp(a, s.kx) - s.sx * az0, ay = comp(a, s.ky) - s.sy * az0;
    float bx = comp(b, s.kx) - s.sx * bz0, by = comp(b, s.ky) - s.sy * bz0;
    float cx = comp(c, s.kx) - s.sx * cz0, cy = comp(c, s.ky) - s.sy * cz0;
    float e0 = cx * by - cy * bx;
    float e1 = ax * cy - ay * cx;
    float e2 = bx * ay - by * ax;
    if (e0 == 0.0f || e1 == 0.0f || e2 == 0.0f) {
        double dax = ax, day = ay, dbx = bx, dby = by, dcx = cx, dcy = cy;
        e0 = (float)(dcx * dby - dcy * dbx);
        e1 = (float)(dax * dcy - day * dcx);
        e2 = (float)(dbx * day - dby * dax);
    }
    if ((e0 < 0.0f || e1 < 0.0f || e2 < 0.0f) && (e0 > 0.0f || e1 > 0.0f || e2 > 0.0f)) return false;
    float det = e0 + e1 + e2;
    if (det == 0.0f || !isfinite(det)) return false;
    float t_scaled = e0 * (s.sz * az0) + e1 * (s.sz * bz0) + e2 * (s.sz * cz0);
    float inv_det = 1.0f / det;
    float t = t_scaled * inv_det;
    if (!(t > t_min && t < t_max)) return false;
    t_out = t;
    u = e1 * inv_det;
    w = e2 * inv_det;
    return true;
}
/// `hit_triangle_uv` for the distance alone.
__device__ inline bool hit_triangle(Vec3 o, const Shear& s, const float* v, float t_min, float t_max, float& t_out) {
    float u, w;
    return hit_triangle_uv(o, s, v, t_min, t_max, t_out, u, w);
}

// The closest-hit key of src/geometry/hit_key.rs: distance bits above the triangle id.
__device__ inline uint64_t pack_hit(float t, uint32_t prim) { return (uint64_t)__float_as_uint(t) << 32 | prim; }
__device__ inline float t_far(const Ray& r, uint64_t key) {
    return key == NO_HIT ? r.t_max : fminf(__uint_as_float((uint32_t)(key >> 32)), r.t_max);
}
/// Where a caster may stop looking at boxes for a ray whose best hit is at `far_t`
/// (`t_far`): that distance widened as the slab test widens box exits, so a box entered
/// exactly at the best hit (a tie on a shared edge, near-coplanar triangles) is still
/// visited and the smaller key can win. PDACRT's filter_rays and the BVH's traversal
/// cull with this; `geometry::cull_distance` is its Rust side (DACRT's and PDACRT's).
__device__ inline float cull_distance(float far_t, float widen) { return far_t * widen; }

}  // namespace wr
