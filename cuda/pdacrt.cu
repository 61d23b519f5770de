// PDACRT on a real GPU: the twin of `src/cast/pdacrt` (kernels.rs and level.rs), kernel
// for kernel and named the same (`pdacrt::filter_rays`, ...), with the primitives the
// emulator runs as `simt::*` done by CUB. Built into a shared library by
// `cuda/build.sh` and loaded at run time by `warpray::gpu` (cargo feature `cuda`), so
// nothing here is needed to build warpray.
//
// About 770 lines on purpose: every kernel of the trace, the level loop that launches
// them and the CUB calls between, in the order `src/cast/pdacrt` runs them, so that the
// twins can be read side by side.
//
// The data layouts are the Rust ones (`#[repr(C)]`, 4-byte fields), so a load here
// makes the requests the emulator counts for the same load. Floating-point work must
// round as the Rust code does: build with `-fmad=false` (no fused multiply-add) and
// IEEE division; then the keys (distance bits, triangle id) agree bit for bit.

#include <cub/device/device_scan.cuh>
#include <cub/device/device_select.cuh>
#include <thrust/iterator/transform_iterator.h>

#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <algorithm>
#include <array>
#include <chrono>
#include <string>

#include "device_buf.cuh"
#include "geometry.cuh"
#include "guarded.h"
#include "pdacrt_api.h"

namespace pdacrt {

using namespace wr;

// ---------------------------------------------------------------- data

struct NodeData {
    Aabb bounds;
    uint32_t ray_start, ray_count, tri_start, tri_count, tries;
};
struct ChildData {
    uint32_t kind, rays, tris, dest_node, dest_ray, dest_tri, whole;
};
struct Triple {
    uint32_t v[3];
};

static_assert(sizeof(NodeData) == 44, "NodeData layout");
static_assert(sizeof(ChildData) == 28, "ChildData layout");

constexpr uint32_t LEFT = 0, BOTH = 1, RIGHT = 2, NEITHER = 3;
constexpr uint32_t DROPPED = 0, INNER = 1, TERMINAL = 2;
constexpr uint32_t MAX_TRIES = 3;
constexpr int BOUNDS_RUN = 32;
constexpr int STAGE = 128;
constexpr int LINEAR_BLOCK = 256;  // `simt::Device::for_each`'s block

__device__ inline uint32_t ordered(float x) {
    uint32_t b = __float_as_uint(x);
    return (b >> 31) ? ~b : (b | 0x80000000u);
}
__device__ inline float unordered(uint32_t u) { return __uint_as_float((u >> 31) ? (u & 0x7fffffffu) : ~u); }

__device__ inline uint32_t code_of(bool l, bool r) { return l ? (r ? BOTH : LEFT) : (r ? RIGHT : NEITHER); }

struct OneHot {
    __host__ __device__ Triple operator()(uint32_t code) const {
        Triple f = {{0, 0, 0}};
        if ((code & 3) != NEITHER) f.v[code & 3] = 1;
        return f;
    }
};
struct Add3 {
    __host__ __device__ Triple operator()(const Triple& a, const Triple& b) const {
        return {{a.v[0] + b.v[0], a.v[1] + b.v[1], a.v[2] + b.v[2]}};
    }
};
struct AddU32 {
    __host__ __device__ uint32_t operator()(uint32_t a, uint32_t b) const { return a + b; }
};

// ---------------------------------------------------------------- kernels (kernels.rs)

__global__ void fill_u32(uint32_t* out, uint32_t value, size_t n) {
    size_t i = (size_t)blockIdx.x * blockDim.x + threadIdx.x;
    if (i < n) out[i] = value;
}
__global__ void fill_u64(uint64_t* out, uint64_t value, size_t n) {
    size_t i = (size_t)blockIdx.x * blockDim.x + threadIdx.x;
    if (i < n) out[i] = value;
}
__global__ void sequence(uint32_t* out, size_t n) {
    size_t i = (size_t)blockIdx.x * blockDim.x + threadIdx.x;
    if (i < n) out[i] = (uint32_t)i;
}

__global__ void clear_bounds(uint32_t* tight, size_t n) {
    size_t i = (size_t)blockIdx.x * blockDim.x + threadIdx.x;
    if (i < n) tight[i] = (i % 6) < 3 ? 0xffffffffu : 0u;
}

// As the emulated kernel: a word is read first and its atomic made only when it would
// change the word.
__device__ inline void flush_bounds(uint32_t* bounds, uint32_t node, const Aabb& b) {
    size_t base = (size_t)node * 6;
    for (int a = 0; a < 3; a++) {
        uint32_t lo = ordered(comp(b.lo, a)), hi = ordered(comp(b.hi, a));
        if (lo < bounds[base + a]) atomicMin(&bounds[base + a], lo);
        if (hi > bounds[base + 3 + a]) atomicMax(&bounds[base + 3 + a], hi);
    }
}

__global__ void node_bounds(const uint32_t* tri_ids, const uint32_t* tri_node, const Tri* tris, uint32_t* bounds,
                            size_t n_refs) {
    size_t k = (size_t)blockIdx.x * blockDim.x + threadIdx.x;
    size_t first = k * BOUNDS_RUN;
    if (first >= n_refs) return;
    size_t end = first + BOUNDS_RUN < n_refs ? first + BOUNDS_RUN : n_refs;
    uint32_t current = tri_node[first];
    Aabb acc = empty_box();
    for (size_t i = first; i < end; i++) {
        uint32_t node = tri_node[i];
        if (node != current) {
            flush_bounds(bounds, current, acc);
            current = node;
            acc = empty_box();
        }
        acc = box_union(acc, box_of(tris[tri_ids[i]]));
    }
    flush_bounds(bounds, current, acc);
}

__global__ void split_nodes(NodeData* nodes, const uint32_t* tight, Aabb* children, size_t n_nodes) {
    size_t n = (size_t)blockIdx.x * blockDim.x + threadIdx.x;
    if (n >= n_nodes) return;
    NodeData node = nodes[n];
    Vec3 lo = {unordered(tight[n * 6]), unordered(tight[n * 6 + 1]), unordered(tight[n * 6 + 2])};
    Vec3 hi = {unordered(tight[n * 6 + 3]), unordered(tight[n * 6 + 4]), unordered(tight[n * 6 + 5])};
    node.bounds.lo = vmax(node.bounds.lo, lo);
    node.bounds.hi = vmin(node.bounds.hi, hi);
    nodes[n] = node;
    // `axes_by_extent`: a stable sort of (x, y, z) by decreasing extent.
    Vec3 e = vmax(sub(node.bounds.hi, node.bounds.lo), {0.0f, 0.0f, 0.0f});
    int axes[3] = {0, 1, 2};
    for (int i = 1; i < 3; i++)
        for (int j = i; j > 0 && comp(e, axes[j]) > comp(e, axes[j - 1]); j--) {
            int s = axes[j];
            axes[j] = axes[j - 1];
            axes[j - 1] = s;
        }
    int axis = axes[node.tries % MAX_TRIES];
    float mid = (comp(node.bounds.lo, axis) + comp(node.bounds.hi, axis)) * 0.5f;
    Aabb l = node.bounds, r = node.bounds;
    set_comp(l.hi, axis, mid);
    set_comp(r.lo, axis, mid);
    children[2 * n] = l;
    children[2 * n + 1] = r;
}

__global__ void filter_triangles(const uint32_t* tri_ids, const uint32_t* tri_node, const Tri* tris,
                                 const Aabb* children, uint32_t* codes, size_t n) {
    size_t i = (size_t)blockIdx.x * blockDim.x + threadIdx.x;
    if (i >= n) return;
    uint32_t node = tri_node[i];
    Aabb b = box_of(tris[tri_ids[i]]);
    bool l = overlaps(b, children[2 * (size_t)node]);
    bool r = overlaps(b, children[2 * (size_t)node + 1]);
    codes[i] = node << 2 | code_of(l, r);
}

__global__ void filter_rays(const uint32_t* ray_ids, const uint32_t* ray_node, const Ray* rays, const uint64_t* keys,
                            const Aabb* children, int any_hit, float widen, float grow, uint32_t* codes,
                            size_t n) {
    size_t i = (size_t)blockIdx.x * blockDim.x + threadIdx.x;
    if (i >= n) return;
    uint32_t node = ray_node[i];
    uint32_t id = ray_ids[i];
    uint64_t key = keys[id];
    uint32_t code;
    if (any_hit && key == BLOCKED) {
        code = NEITHER;
    } else {
        Ray r = rays[id];
        Vec3 inv = inv_dir(r.d);
        float far_t = cull_distance(t_far(r, key), widen);
        bool l = enters(grown(children[2 * (size_t)node], grow), r.o, inv, r.t_min, far_t, widen);
        bool rt = enters(grown(children[2 * (size_t)node + 1], grow), r.o, inv, r.t_min, far_t, widen);
        code = code_of(l, rt);
    }
    codes[i] = node << 2 | code;
}

__device__ inline Triple rank_at(const Triple* ranks, const uint32_t* codes, size_t n, size_t k) {
    if (k < n) return ranks[k];
    return Add3()(ranks[n - 1], OneHot()(codes[n - 1]));
}

__global__ void count_codes(const NodeData* nodes, int rays, const Triple* ranks, const uint32_t* codes, size_t n_elems,
                            uint32_t* counts, Triple* base, size_t n_nodes) {
    size_t n = (size_t)blockIdx.x * blockDim.x + threadIdx.x;
    if (n >= n_nodes) return;
    NodeData node = nodes[n];
    uint32_t start = rays ? node.ray_start : node.tri_start;
    uint32_t count = rays ? node.ray_count : node.tri_count;
    Triple first = rank_at(ranks, codes, n_elems, start);
    Triple end = rank_at(ranks, codes, n_elems, (size_t)start + count);
    uint32_t entering = 0;
    for (int c = 0; c < 3; c++) {
        counts[n * 4 + c] = end.v[c] - first.v[c];
        entering += end.v[c] - first.v[c];
    }
    counts[n * 4 + 3] = count - entering;
    base[n] = first;
}

struct LeafRule {
    uint32_t leaf_rays, leaf_tris, at_max_depth;
    uint64_t pairs;
};

__global__ void classify_children(const NodeData* nodes, const uint32_t* ray_counts, const uint32_t* tri_counts,
                                  LeafRule rule, ChildData* children, Triple* inner, Triple* terminal,
                                  size_t n_children) {
    size_t c = (size_t)blockIdx.x * blockDim.x + threadIdx.x;
    if (c >= n_children) return;
    size_t n = c / 2;
    bool right = c % 2 == 1;
    NodeData node = nodes[n];
    const uint32_t* rc = ray_counts + n * 4;
    const uint32_t* tc = tri_counts + n * 4;
    uint32_t left_rays = rc[LEFT] + rc[BOTH], left_tris = tc[LEFT] + tc[BOTH];
    uint32_t right_rays = rc[BOTH] + rc[RIGHT], right_tris = tc[BOTH] + tc[RIGHT];
    bool stuck = (left_rays == node.ray_count && left_tris == node.tri_count) ||
                 (right_rays == node.ray_count && right_tris == node.tri_count);
    auto small = [&](uint32_t r, uint32_t tr) {
        return tr <= rule.leaf_tris || (r <= rule.leaf_rays && (uint64_t)r * tr <= rule.pairs) || rule.at_max_depth;
    };
    uint32_t kind, rays, tris, whole;
    if (stuck) {
        rays = left_rays + rc[RIGHT];
        tris = left_tris + tc[RIGHT];
        kind = (right || rays == 0 || tris == 0)              ? DROPPED
               : (small(rays, tris) || node.tries + 1 >= MAX_TRIES) ? TERMINAL
                                                               : INNER;
        whole = 1;
    } else {
        rays = right ? right_rays : left_rays;
        tris = right ? right_tris : left_tris;
        kind = (rays == 0 || tris == 0) ? DROPPED : (small(rays, tris) ? TERMINAL : INNER);
        whole = 0;
    }
    Triple chosen = {{1, rays, tris}}, none = {{0, 0, 0}};
    inner[c] = kind == INNER ? chosen : none;
    terminal[c] = kind == TERMINAL ? chosen : none;
    children[c] = {kind, rays, tris, 0, 0, 0, whole};
}

__global__ void emit_children(const NodeData* nodes, const Aabb* child_boxes, const Triple* inner_scan,
                              const Triple* terminal_scan, ChildData* children, NodeData* next_nodes,
                              NodeData* terminal_nodes, size_t n_children) {
    size_t c = (size_t)blockIdx.x * blockDim.x + threadIdx.x;
    if (c >= n_children) return;
    ChildData cd = children[c];
    Triple scan;
    NodeData* out;
    if (cd.kind == INNER) {
        scan = inner_scan[c];
        out = next_nodes;
    } else if (cd.kind == TERMINAL) {
        scan = terminal_scan[c];
        out = terminal_nodes;
    } else {
        return;
    }
    cd.dest_node = scan.v[0];
    cd.dest_ray = scan.v[1];
    cd.dest_tri = scan.v[2];
    children[c] = cd;
    NodeData node;
    if (cd.whole == 1) {
        NodeData parent = nodes[c / 2];
        node.bounds = parent.bounds;
        node.tries = parent.tries + 1;
    } else {
        node.bounds = child_boxes[c];
        node.tries = 0;
    }
    node.ray_start = cd.dest_ray;
    node.ray_count = cd.rays;
    node.tri_start = cd.dest_tri;
    node.tri_count = cd.tris;
    out[cd.dest_node] = node;
}

struct Split {
    const uint32_t *ids, *node_of, *codes;
    const Triple *ranks, *base;
    const uint32_t* counts;
};
struct Destinations {
    uint32_t *next_ids, *next_node, *terminal_ids;
};

__device__ inline void scatter_ref(const Split& sp, const ChildData* children, int rays, const Destinations& dest,
                                   size_t i) {
    uint32_t code = sp.codes[i] & 3;
    if (code == NEITHER) return;
    size_t node = sp.node_of[i];
    uint32_t rank = sp.ranks[i].v[code] - sp.base[node].v[code];
    uint32_t id = sp.ids[i];
    for (int side = 0; side < 2; side++) {
        ChildData cd = children[2 * node + side];
        bool takes = cd.whole == 1 || (side == 0 ? code != RIGHT : code != LEFT);
        if (!takes || cd.kind == DROPPED) continue;
        uint32_t first_code = (cd.whole == 1 || side == 0) ? LEFT : BOTH;
        uint32_t before = 0;
        for (uint32_t c = first_code; c < code; c++) before += sp.counts[node * 4 + c];
        uint32_t dst = rays ? cd.dest_ray : cd.dest_tri;
        size_t pos = (size_t)dst + before + rank;
        if (cd.kind == INNER) {
            dest.next_ids[pos] = id;
            dest.next_node[pos] = cd.dest_node;
        } else {
            dest.terminal_ids[pos] = id;
        }
    }
}

__global__ void scatter_rays(Split sp, const ChildData* children, Destinations dest, size_t n) {
    size_t i = (size_t)blockIdx.x * blockDim.x + threadIdx.x;
    if (i < n) scatter_ref(sp, children, 1, dest, i);
}
__global__ void scatter_triangles(Split sp, const ChildData* children, Destinations dest, size_t n) {
    size_t i = (size_t)blockIdx.x * blockDim.x + threadIdx.x;
    if (i < n) scatter_ref(sp, children, 0, dest, i);
}

__global__ void count_chunks(const NodeData* terminals, uint32_t block, uint32_t* chunks, size_t n) {
    size_t i = (size_t)blockIdx.x * blockDim.x + threadIdx.x;
    if (i < n) chunks[i] = (terminals[i].ray_count + block - 1) / block;
}

struct BruteForceArgs {
    const NodeData* terminals;
    const uint32_t* chunk_start;
    uint32_t terminal_count;
    const uint32_t *ray_ids, *tri_ids;
    const Ray* rays;
    const Tri* tris;
    uint64_t* keys;
    unsigned long long* tests;
    int any_hit;
};

__global__ void brute_force(BruteForceArgs a) {
    __shared__ Tri stage[STAGE];
    __shared__ uint32_t stage_ids[STAGE];
    __shared__ unsigned long long block_tests;
    if (threadIdx.x == 0) block_tests = 0;
    uint32_t b = blockIdx.x;
    uint32_t lo = 0, hi = a.terminal_count;
    while (hi - lo > 1) {
        uint32_t mid = (lo + hi) / 2;
        if (a.chunk_start[mid] <= b) lo = mid;
        else hi = mid;
    }
    NodeData node = a.terminals[lo];
    size_t chunk = (size_t)(b - a.chunk_start[lo]) * blockDim.x;
    size_t k = chunk + threadIdx.x;
    uint32_t ray_id = 0xffffffffu;
    Ray r = {};
    uint64_t best = NO_HIT;
    unsigned long long tests = 0;
    if (k < node.ray_count) {
        ray_id = a.ray_ids[node.ray_start + k];
        r = a.rays[ray_id];
        best = a.keys[ray_id];
    }
    for (uint32_t first = 0; first < node.tri_count; first += STAGE) {
        uint32_t count = node.tri_count - first < STAGE ? node.tri_count - first : STAGE;
        __syncthreads();
        for (uint32_t s = threadIdx.x; s < count; s += blockDim.x) {
            uint32_t tri = a.tri_ids[node.tri_start + first + s];
            stage_ids[s] = tri;
            stage[s] = a.tris[tri];
        }
        __syncthreads();
        if (ray_id == 0xffffffffu) continue;
        uint64_t key = best;
        if (a.any_hit && key == BLOCKED) continue;
        Shear sh = make_shear(r.d);
        float far_t = t_far(r, key);
        uint32_t done = 0;
        for (uint32_t s = 0; s < count; s++) {
            done++;
            float th;
            if (a.any_hit) {
                if (hit_triangle(r.o, sh, stage[s].v, r.t_min, r.t_max, th)) {
                    key = BLOCKED;
                    break;
                }
            } else if (hit_triangle(r.o, sh, stage[s].v, r.t_min, nextafterf(far_t, INFINITY), th)) {
                uint64_t candidate = pack_hit(th, stage_ids[s]);
                if (candidate < key) {
                    key = candidate;
                    far_t = th;
                }
            }
        }
        tests += done;
        best = key;
    }
    __syncthreads();
    if (ray_id != 0xffffffffu) {
        atomicAdd(&block_tests, tests);
        if (best != NO_HIT) atomicMin((unsigned long long*)&a.keys[ray_id], (unsigned long long)best);
    }
    __syncthreads();
    if (threadIdx.x == 0) atomicAdd(a.tests, block_tests);
}

}  // namespace pdacrt

// ---------------------------------------------------------------- host pipeline (mod.rs, level.rs)

namespace pdacrt {

struct LevelBuffers {
    Buf<NodeData> nodes;
    Buf<uint32_t> ray_ids, ray_node, tri_ids, tri_node;
    void swap(LevelBuffers& o) {
        nodes.swap(o.nodes);
        ray_ids.swap(o.ray_ids);
        ray_node.swap(o.ray_node);
        tri_ids.swap(o.tri_ids);
        tri_node.swap(o.tri_node);
    }
};

/// The level-0 stencil: the ray is valid and enters the scene's box.
struct EntersScene {
    Aabb box;
    float widen;
    __host__ __device__ bool operator()(const Ray& r) const {
        return ray_valid(r) && enters(box, r.o, inv_dir(r.d), r.t_min, r.t_max, widen);
    }
};

struct Tracer {
    Buf<Tri> tris;
    Aabb scene_box;
    size_t live = 0;
    Buf<Ray> rays;
    Buf<uint64_t> keys;
    LevelBuffers cur, next;
    Buf<uint32_t> ray_codes, tri_codes, tight, ray_counts, tri_counts;
    Buf<Aabb> child_boxes;
    Buf<Triple> ray_ranks, tri_ranks, ray_base, tri_base, inner, terminal, inner_scan, terminal_scan;
    Buf<ChildData> children;
    Buf<NodeData> term_nodes;
    Buf<uint32_t> term_ray_ids, term_tri_ids, chunks, chunk_start;
    Buf<unsigned long long> tests;
    Buf<int> selected;
    Buf<char> scratch;
    WrParams params;
    uint32_t launches = 0, levels = 0, read_backs = 0;
    /// Pinned host memory for `read_together`.
    static constexpr size_t STAGING_BYTES = 64;
    char* staging = nullptr;
    ~Tracer() {
        if (staging) cudaFreeHost(staging);
    }

    template <class T>
    void track(Buf<T>& b) {
        b.live = &live;
    }
    void track_all() {
        track(rays), track(keys), track(ray_codes), track(tri_codes), track(tight), track(ray_counts);
        track(tri_counts), track(child_boxes), track(ray_ranks), track(tri_ranks), track(ray_base), track(tri_base);
        track(inner), track(terminal), track(inner_scan), track(terminal_scan), track(children), track(term_nodes);
        track(term_ray_ids), track(term_tri_ids), track(chunks), track(chunk_start), track(tests), track(selected);
        track(scratch);
        for (LevelBuffers* l : {&cur, &next}) {
            track(l->nodes), track(l->ray_ids), track(l->ray_node), track(l->tri_ids), track(l->tri_node);
        }
    }

    /// CUB's temporary storage, kept between calls.
    void* temp(size_t bytes) {
        scratch.resize(bytes);
        return scratch.p;
    }

    static unsigned grid_of(size_t n) { return (unsigned)((n + LINEAR_BLOCK - 1) / LINEAR_BLOCK); }
    void launched(const char* name) {
        launches++;
        check(cudaGetLastError(), name);
    }

    template <class In, class Out, class Op, class Init>
    void exclusive_scan(In in, Out out, Op op, Init init, size_t n) {
        size_t bytes = 0;
        check(cub::DeviceScan::ExclusiveScan(nullptr, bytes, in, out, op, init, (int64_t)n), "scan size");
        check(cub::DeviceScan::ExclusiveScan(temp(bytes), bytes, in, out, op, init, (int64_t)n), "scan");
        launches++;
    }

    template <class T>
    T read(const Buf<T>& b, size_t i) {
        T v;
        check(cudaMemcpy(&v, b.p + i, sizeof(T), cudaMemcpyDeviceToHost), "read back");
        read_backs++;
        return v;
    }

    /// Reads element `i` of each buffer back with one synchronisation: asynchronous
    /// copies into pinned memory, then one wait (a level's four scan totals cost one
    /// round trip, not four).
    template <class T, size_t N>
    std::array<T, N> read_together(const std::array<const Buf<T>*, N>& bufs, size_t i) {
        static_assert(N * sizeof(T) <= STAGING_BYTES, "staging holds the values");
        if (!staging) check(cudaMallocHost(&staging, STAGING_BYTES), "cudaMallocHost");
        for (size_t k = 0; k < N; k++)
            check(cudaMemcpyAsync(staging + k * sizeof(T), bufs[k]->p + i, sizeof(T), cudaMemcpyDeviceToHost),
                  "read back");
        check(cudaStreamSynchronize(0), "read back");
        read_backs++;
        std::array<T, N> out;
        memcpy(out.data(), staging, N * sizeof(T));
        return out;
    }

    void trace_chunk(size_t n, int any_hit) {
        next.ray_ids.resize(n);
        sequence<<<grid_of(n), LINEAR_BLOCK>>>(next.ray_ids.p, n);
        launched("pdacrt::sequence");
        cur.ray_ids.resize(n);
        selected.resize(1);
        EntersScene enters_scene{grown(scene_box, params.grow), params.slab_widen};
        auto flags = thrust::make_transform_iterator(rays.p, enters_scene);
        size_t bytes = 0;
        check(cub::DeviceSelect::Flagged(nullptr, bytes, next.ray_ids.p, flags, cur.ray_ids.p, selected.p, (int64_t)n),
              "select size");
        check(cub::DeviceSelect::Flagged(temp(bytes), bytes, next.ray_ids.p, flags, cur.ray_ids.p, selected.p,
                                         (int64_t)n),
              "select");
        launches++;
        size_t r0 = (size_t)read(selected, 0);
        cur.ray_ids.resize(r0);
        cur.ray_node.resize(r0);
        if (r0) fill_u32<<<grid_of(r0), LINEAR_BLOCK>>>(cur.ray_node.p, 0, r0), launched("pdacrt::fill");
        size_t t = tris.n;
        cur.tri_ids.resize(t);
        cur.tri_node.resize(t);
        if (t == 0) return;  // nothing to hit: every key stays NO_HIT
        sequence<<<grid_of(t), LINEAR_BLOCK>>>(cur.tri_ids.p, t);
        launched("pdacrt::sequence");
        fill_u32<<<grid_of(t), LINEAR_BLOCK>>>(cur.tri_node.p, 0, t);
        launched("pdacrt::fill");
        cur.nodes.resize(1);
        NodeData root = {scene_box, 0, (uint32_t)r0, 0, (uint32_t)t, 0};
        check(cudaMemcpy(cur.nodes.p, &root, sizeof root, cudaMemcpyHostToDevice), "root node");
        uint32_t depth = 0;
        while (cur.nodes.n && cur.ray_ids.n && cur.tri_ids.n) {
            level(depth, any_hit);
            cur.swap(next);
            depth++;
        }
        levels += depth;
    }

    void level(uint32_t depth, int any_hit) {
        size_t n_nodes = cur.nodes.n, n_rays = cur.ray_ids.n, n_tris = cur.tri_ids.n;
        // node_bounds, split_nodes
        tight.resize(6 * n_nodes);
        clear_bounds<<<grid_of(6 * n_nodes), LINEAR_BLOCK>>>(tight.p, 6 * n_nodes);
        launched("pdacrt::clear_bounds");
        size_t runs = (n_tris + BOUNDS_RUN - 1) / BOUNDS_RUN;
        node_bounds<<<grid_of(runs), LINEAR_BLOCK>>>(cur.tri_ids.p, cur.tri_node.p, tris.p, tight.p, n_tris);
        launched("pdacrt::node_bounds");
        child_boxes.resize(2 * n_nodes);
        split_nodes<<<grid_of(n_nodes), LINEAR_BLOCK>>>(cur.nodes.p, tight.p, child_boxes.p, n_nodes);
        launched("pdacrt::split_nodes");
        // filter_triangles, filter_rays
        tri_codes.resize(n_tris);
        filter_triangles<<<grid_of(n_tris), LINEAR_BLOCK>>>(cur.tri_ids.p, cur.tri_node.p, tris.p, child_boxes.p,
                                                            tri_codes.p, n_tris);
        launched("pdacrt::filter_triangles");
        ray_codes.resize(n_rays);
        filter_rays<<<grid_of(n_rays), LINEAR_BLOCK>>>(cur.ray_ids.p, cur.ray_node.p, rays.p, keys.p, child_boxes.p,
                                                       any_hit, params.slab_widen, params.grow, ray_codes.p,
                                                       n_rays);
        launched("pdacrt::filter_rays");
        // the split by code: one scan of one-hot codes, count_codes
        struct Side {
            int rays;
            Buf<uint32_t>& codes;
            Buf<Triple>& ranks;
            Buf<uint32_t>& counts;
            Buf<Triple>& base;
        };
        Side sides[2] = {{1, ray_codes, ray_ranks, ray_counts, ray_base}, {0, tri_codes, tri_ranks, tri_counts, tri_base}};
        for (Side& s : sides) {
            size_t len = s.codes.n;
            s.ranks.resize(len);
            exclusive_scan(thrust::make_transform_iterator(s.codes.p, OneHot()), s.ranks.p, Add3(), Triple{{0, 0, 0}},
                           len);
            s.counts.resize(4 * n_nodes);
            s.base.resize(n_nodes);
            count_codes<<<grid_of(n_nodes), LINEAR_BLOCK>>>(cur.nodes.p, s.rays, s.ranks.p, s.codes.p, len,
                                                            s.counts.p, s.base.p, n_nodes);
            launched("pdacrt::count_codes");
        }
        // classify_children, two scans, emit_children
        size_t n_children = 2 * n_nodes;
        for (Buf<Triple>* b : {&inner, &terminal, &inner_scan, &terminal_scan}) b->resize(n_children);
        children.resize(n_children);
        LeafRule rule = {params.leaf_rays, params.leaf_triangles, depth + 1 >= params.max_depth, params.leaf_pairs};
        classify_children<<<grid_of(n_children), LINEAR_BLOCK>>>(cur.nodes.p, ray_counts.p, tri_counts.p, rule,
                                                                 children.p, inner.p, terminal.p, n_children);
        launched("pdacrt::classify_children");
        exclusive_scan(inner.p, inner_scan.p, Add3(), Triple{{0, 0, 0}}, n_children);
        exclusive_scan(terminal.p, terminal_scan.p, Add3(), Triple{{0, 0, 0}}, n_children);
        auto last = read_together<Triple, 4>({&inner_scan, &inner, &terminal_scan, &terminal}, n_children - 1);
        Triple nx = Add3()(last[0], last[1]);
        Triple tm = Add3()(last[2], last[3]);
        next.nodes.resize(nx.v[0]);
        term_nodes.resize(tm.v[0]);
        emit_children<<<grid_of(n_children), LINEAR_BLOCK>>>(cur.nodes.p, child_boxes.p, inner_scan.p, terminal_scan.p,
                                                             children.p, next.nodes.p, term_nodes.p, n_children);
        launched("pdacrt::emit_children");
        next.ray_ids.resize(nx.v[1]);
        next.ray_node.resize(nx.v[1]);
        next.tri_ids.resize(nx.v[2]);
        next.tri_node.resize(nx.v[2]);
        term_ray_ids.resize(tm.v[1]);
        term_tri_ids.resize(tm.v[2]);
        // scatter_rays, scatter_triangles
        Split rs = {cur.ray_ids.p, cur.ray_node.p, ray_codes.p, ray_ranks.p, ray_base.p, ray_counts.p};
        Destinations rd = {next.ray_ids.p, next.ray_node.p, term_ray_ids.p};
        if (n_rays) scatter_rays<<<grid_of(n_rays), LINEAR_BLOCK>>>(rs, children.p, rd, n_rays), launched("pdacrt::scatter_rays");
        Split ts = {cur.tri_ids.p, cur.tri_node.p, tri_codes.p, tri_ranks.p, tri_base.p, tri_counts.p};
        Destinations td = {next.tri_ids.p, next.tri_node.p, term_tri_ids.p};
        if (n_tris)
            scatter_triangles<<<grid_of(n_tris), LINEAR_BLOCK>>>(ts, children.p, td, n_tris),
                launched("pdacrt::scatter_triangles");
        // count_chunks, a scan, brute_force
        size_t k = tm.v[0];
        if (k == 0) return;
        uint32_t block = params.brute_force_block;
        chunks.resize(k);
        chunk_start.resize(k);
        count_chunks<<<grid_of(k), LINEAR_BLOCK>>>(term_nodes.p, block, chunks.p, k);
        launched("pdacrt::count_chunks");
        exclusive_scan(chunks.p, chunk_start.p, AddU32(), (uint32_t)0, k);
        auto end = read_together<uint32_t, 2>({&chunk_start, &chunks}, k - 1);
        uint32_t grid = end[0] + end[1];
        if (grid == 0) return;
        BruteForceArgs a = {term_nodes.p, chunk_start.p, (uint32_t)k, term_ray_ids.p, term_tri_ids.p,
                            rays.p,       tris.p,        keys.p,      tests.p,       any_hit};
        brute_force<<<grid, block>>>(a);
        launched("pdacrt::brute_force");
    }
};

static thread_local std::string last_error;

template <class F>
static int guarded(F f) {
    return wr::guarded(last_error, f);
}

}  // namespace pdacrt

using namespace pdacrt;

extern "C" int wr_api_version(void) { return WR_API_VERSION; }

extern "C" const char* wr_last_error(void) { return last_error.c_str(); }

extern "C" int wr_device_name(char* buf, uint32_t len) {
    return guarded([&] {
        int dev = 0;
        check(cudaGetDevice(&dev), "cudaGetDevice");
        cudaDeviceProp p;
        check(cudaGetDeviceProperties(&p, dev), "cudaGetDeviceProperties");
        snprintf(buf, len, "%s (sm_%d%d, %d SMs)", p.name, p.major, p.minor, p.multiProcessorCount);
    });
}

/// Uploads the triangles and their box into `t`; on failure `t` holds none.
static void upload_triangles(Tracer& t, const float* tris, uint64_t n_tris, const float* scene_box) {
    t.tris.resize(n_tris);
    cudaError_t e = n_tris ? cudaMemcpy(t.tris.p, tris, n_tris * sizeof(Tri), cudaMemcpyHostToDevice) : cudaSuccess;
    if (e != cudaSuccess) t.tris.n = 0;
    check(e, "upload triangles");
    t.scene_box = {{scene_box[0], scene_box[1], scene_box[2]}, {scene_box[3], scene_box[4], scene_box[5]}};
}

extern "C" int wr_pdacrt_create(const float* tris, uint64_t n_tris, const float* scene_box, void** handle) {
    return guarded([&] {
        Tracer* t = new Tracer();
        try {
            t->track_all();
            upload_triangles(*t, tris, n_tris, scene_box);
        } catch (...) {
            delete t;
            throw;
        }
        *handle = t;
    });
}

extern "C" int wr_pdacrt_set_triangles(void* handle, const float* tris, uint64_t n_tris, const float* scene_box) {
    return guarded([&] { upload_triangles(*static_cast<Tracer*>(handle), tris, n_tris, scene_box); });
}

extern "C" void wr_pdacrt_destroy(void* handle) { delete static_cast<Tracer*>(handle); }

extern "C" int wr_pdacrt_trace(void* handle, const void* rays, uint64_t n_rays, int any_hit, const WrParams* params,
                               uint64_t* keys, WrStats* stats) {
    return guarded([&] {
        Tracer& t = *static_cast<Tracer*>(handle);
        auto wall = std::chrono::steady_clock::now();
        t.params = *params;
        if (t.params.brute_force_block == 0 || t.params.brute_force_block > 1024)
            throw CudaError{"brute_force_block must be 1..=1024"};
        t.launches = t.levels = t.read_backs = 0;
        size_t resident = t.live;
        size_t peak = 0;
        t.tests.resize(1);
        check(cudaMemset(t.tests.p, 0, sizeof(unsigned long long)), "clear tests");
        cudaEvent_t start, stop;
        check(cudaEventCreate(&start), "event");
        check(cudaEventCreate(&stop), "event");
        double trace_ms = 0;
        size_t chunk = t.params.chunk_rays == 0 ? (n_rays ? n_rays : 1) : t.params.chunk_rays;
        const Ray* all = static_cast<const Ray*>(rays);
        for (size_t first = 0; first < n_rays; first += chunk) {
            size_t n = n_rays - first < chunk ? n_rays - first : chunk;
            t.rays.resize(n);
            check(cudaMemcpy(t.rays.p, all + first, n * sizeof(Ray), cudaMemcpyHostToDevice), "upload rays");
            t.keys.resize(n);
            check(cudaEventRecord(start), "event");
            fill_u64<<<Tracer::grid_of(n), LINEAR_BLOCK>>>(t.keys.p, NO_HIT, n);
            t.launched("pdacrt::fill");
            t.trace_chunk(n, any_hit);
            check(cudaEventRecord(stop), "event");
            check(cudaEventSynchronize(stop), "trace");
            float ms = 0;
            check(cudaEventElapsedTime(&ms, start, stop), "event time");
            trace_ms += ms;
            peak = std::max(peak, t.live);
            check(cudaMemcpy(keys + first, t.keys.p, n * sizeof(uint64_t), cudaMemcpyDeviceToHost), "download keys");
        }
        cudaEventDestroy(start);
        cudaEventDestroy(stop);
        stats->trace_ms = trace_ms;
        stats->read_backs = t.read_backs;  // the trace's own, before the counter's below
        stats->tests = t.read(t.tests, 0);
        stats->levels = t.levels;
        stats->launches = t.launches;
        stats->peak_bytes = peak > resident ? peak - resident : 0;
        stats->call_ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - wall).count();
    });
}
