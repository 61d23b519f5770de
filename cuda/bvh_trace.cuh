// The GPU BVH's node and its traversal for one ray, as a device function: the baseline's
// trace kernel (bvh.cu) runs it one thread per ray, and the LVC megakernel
// (render_driver.cuh) runs it inside its threads, where each thread traces its own rays.
#pragma once

#include <cuda_runtime.h>

#include "geometry.cuh"

namespace bvh {

using namespace wr;

/// Deeper than any tree built here: 30 Morton bits, then at most 32 bits of index.
constexpr int STACK = 64;

/// An inner node: both children's boxes and references (>= 0: inner node; < 0: the
/// leaf holding sorted triangle ~ref).
struct alignas(16) Node {
    Aabb box[2];
    int32_t child[2];
    uint32_t pad[2];
};
static_assert(sizeof(Node) == 64, "Node layout");

/// A built tree as its traversal reads it, with the slab test's widening
/// (`geometry::SLAB_WIDEN`) and how far boxes grow (`geometry::batch_slack`).
struct View {
    const Node* nodes;
    const Tri* tris;
    const uint32_t* ids;
    int32_t root;
    float widen, grow;
};

/// The tree a handle of bvh.cu holds (valid until its next build).
View view_of(void* handle, float widen, float grow);

__device__ inline Aabb load_box(const Node* node, int side) {
    const float4* q = reinterpret_cast<const float4*>(node);
    float4 a = __ldg(q), b = __ldg(q + 1), c = __ldg(q + 2);
    return side == 0 ? Aabb{{a.x, a.y, a.z}, {a.w, b.x, b.y}} : Aabb{{b.z, b.w, c.x}, {c.y, c.z, c.w}};
}

/// The closest-hit key of `r` (the smallest key, as PDACRT's leaf keeps it; NO_HIT for
/// none) or, with `any_hit`, BLOCKED at the first blocker; counts the ray-triangle
/// tests and inner nodes visited.
__device__ inline uint64_t trace_key(const View& t, const Ray& r, bool any_hit, uint32_t& tests, uint32_t& visits) {
    uint64_t key = NO_HIT;
    if (!ray_valid(r) || t.root == INT32_MIN) return key;
    Vec3 inv = inv_dir(r.d);
    Shear sh = make_shear(r.d);
    float far_t = r.t_max;
    int32_t stack[STACK];
    int sp = 0;
    int32_t cur = t.root;
    while (true) {
        if (cur < 0) {
            const Tri* tri = t.tris + ~cur;
            float v[9];
#pragma unroll
            for (int k = 0; k < 9; k++) v[k] = __ldg(&tri->v[k]);
            float th;
            tests++;
            if (any_hit) {
                if (hit_triangle(r.o, sh, v, r.t_min, r.t_max, th)) return BLOCKED;
            } else if (hit_triangle(r.o, sh, v, r.t_min, nextafterf(far_t, INFINITY), th)) {
                uint64_t candidate = pack_hit(th, __ldg(&t.ids[~cur]));
                if (candidate < key) {
                    key = candidate;
                    far_t = th;
                }
            }
        } else {
            visits++;
            const Node* node = t.nodes + cur;
            float cull_t = cull_distance(far_t, t.widen);
            float n0 = r.t_min, n1 = r.t_min;
            bool h0 = slab_entry(grown(load_box(node, 0), t.grow), r.o, inv, cull_t, t.widen, n0);
            bool h1 = slab_entry(grown(load_box(node, 1), t.grow), r.o, inv, cull_t, t.widen, n1);
            int2 ch = __ldg(reinterpret_cast<const int2*>(&node->child[0]));
            if (h0 && h1) {
                bool swap = n1 < n0;
                cur = swap ? ch.y : ch.x;
                stack[sp++] = swap ? ch.x : ch.y;
                continue;
            }
            if (h0 || h1) {
                cur = h0 ? ch.x : ch.y;
                continue;
            }
        }
        if (sp == 0) break;
        cur = stack[--sp];
    }
    return key;
}

}  // namespace bvh
