// The baseline a GPU programmer would pick for geometry that changes every frame: a
// linear BVH rebuilt from scratch (Karras 2012, "Maximizing parallelism in the
// construction of BVHs, octrees and k-d trees") and a stack-based software traversal
// (the H200 has no RT cores), behind the same keys as PDACRT's twin so the two can be
// compared ray for ray (`warpray::gpu::GpuBvh`).
//
// Build, all on the device with no read-back: centroid bounds (CUB reduce), 30-bit
// Morton codes, CUB radix sort, triangles gathered into sorted order, the hierarchy
// (one thread per inner node), then boxes fitted bottom-up (one thread per leaf, the
// second child to arrive at a node goes on). One triangle per leaf. Each inner node
// holds both children's boxes (64 bytes), so a traversal step is one node fetch and two
// slab tests, nearer child first.

#include <cub/device/device_radix_sort.cuh>
#include <cub/device/device_reduce.cuh>
#include <thrust/iterator/transform_iterator.h>

#include <chrono>
#include <string>

#include "bvh_api.h"
#include "device_buf.cuh"
#include "bvh_trace.cuh"
#include "guarded.h"

namespace bvh {

using namespace wr;

constexpr int BLOCK = 256;
__device__ inline Vec3 centroid(const Tri& t) {
    return {(t.v[0] + t.v[3] + t.v[6]) * (1.0f / 3.0f), (t.v[1] + t.v[4] + t.v[7]) * (1.0f / 3.0f),
            (t.v[2] + t.v[5] + t.v[8]) * (1.0f / 3.0f)};
}

struct CentroidBox {
    __device__ Aabb operator()(const Tri& t) const {
        Vec3 c = centroid(t);
        return {c, c};
    }
};
struct BoxUnion {
    __device__ Aabb operator()(const Aabb& a, const Aabb& b) const { return box_union(a, b); }
};

/// Ten bits of `x` spread three apart.
__device__ inline uint32_t spread_bits(uint32_t x) {
    x = (x * 0x00010001u) & 0xFF0000FFu;
    x = (x * 0x00000101u) & 0x0F00F00Fu;
    x = (x * 0x00000011u) & 0xC30C30C3u;
    x = (x * 0x00000005u) & 0x49249249u;
    return x;
}
__device__ inline uint32_t quantise(float x, float lo, float hi) {
    float u = hi > lo ? (x - lo) / (hi - lo) : 0.5f;
    u = fminf(fmaxf(u * 1024.0f, 0.0f), 1023.0f);  // NaN becomes 0 here
    return (uint32_t)u;
}

__global__ void morton_codes(const Tri* tris, const Aabb* bounds, uint32_t* codes, uint32_t* ids, size_t n) {
    size_t i = (size_t)blockIdx.x * blockDim.x + threadIdx.x;
    if (i >= n) return;
    Aabb b = *bounds;
    Vec3 c = centroid(tris[i]);
    codes[i] = spread_bits(quantise(c.x, b.lo.x, b.hi.x)) << 2 | spread_bits(quantise(c.y, b.lo.y, b.hi.y)) << 1 |
               spread_bits(quantise(c.z, b.lo.z, b.hi.z));
    ids[i] = (uint32_t)i;
}

__global__ void gather_triangles(const Tri* tris, const uint32_t* ids, Tri* sorted, Aabb* leaf_boxes, size_t n) {
    size_t i = (size_t)blockIdx.x * blockDim.x + threadIdx.x;
    if (i >= n) return;
    Tri t = tris[ids[i]];
    sorted[i] = t;
    leaf_boxes[i] = box_of(t);
}

/// Karras's δ: the length of the common prefix of keys i and j, the index breaking ties
/// between equal codes; -1 outside the array.
__device__ inline int delta(const uint32_t* codes, int n, int i, int j) {
    if (j < 0 || j >= n) return -1;
    uint32_t a = codes[i], b = codes[j];
    return a == b ? 32 + __clz((uint32_t)i ^ (uint32_t)j) : __clz(a ^ b);
}

/// Inner node i of n - 1: its range of leaves, its split, its two children; each child
/// learns its parent and side (`parent << 1 | side`).
__global__ void emit_hierarchy(const uint32_t* codes, Node* nodes, uint32_t* inner_parent, uint32_t* leaf_parent,
                               int n) {
    int i = blockIdx.x * blockDim.x + threadIdx.x;
    if (i >= n - 1) return;
    int d = delta(codes, n, i, i + 1) - delta(codes, n, i, i - 1) >= 0 ? 1 : -1;
    int d_min = delta(codes, n, i, i - d);
    int l_max = 2;
    while (delta(codes, n, i, i + l_max * d) > d_min) l_max *= 2;
    int l = 0;
    for (int t = l_max / 2; t >= 1; t /= 2)
        if (delta(codes, n, i, i + (l + t) * d) > d_min) l += t;
    int j = i + l * d;
    int d_node = delta(codes, n, i, j);
    int s = 0, t = l;
    do {
        t = (t + 1) >> 1;
        if (delta(codes, n, i, i + (s + t) * d) > d_node) s += t;
    } while (t > 1);
    int split = i + s * d + min(d, 0);
    int lo = min(i, j), hi = max(i, j);
    Node& node = nodes[i];
    if (lo == split) {
        node.child[0] = ~split;
        leaf_parent[split] = (uint32_t)i << 1;
    } else {
        node.child[0] = split;
        inner_parent[split] = (uint32_t)i << 1;
    }
    if (hi == split + 1) {
        node.child[1] = ~(split + 1);
        leaf_parent[split + 1] = (uint32_t)i << 1 | 1;
    } else {
        node.child[1] = split + 1;
        inner_parent[split + 1] = (uint32_t)i << 1 | 1;
    }
    if (i == 0) inner_parent[0] = ~0u;
}

/// One thread per leaf climbs towards the root, writing the box it carries into its
/// parent's slot; the first to arrive at a node stops, the second unites both slots
/// and goes on.
__global__ void fit_boxes(const Aabb* leaf_boxes, const uint32_t* leaf_parent, const uint32_t* inner_parent,
                          Node* nodes, uint32_t* arrivals, int n) {
    int i = blockIdx.x * blockDim.x + threadIdx.x;
    if (i >= n) return;
    Aabb box = leaf_boxes[i];
    uint32_t up = leaf_parent[i];
    while (up != ~0u) {
        uint32_t p = up >> 1, side = up & 1;
        nodes[p].box[side] = box;
        __threadfence();
        if (atomicAdd(&arrivals[p], 1u) == 0) return;
        __threadfence();
        // The sibling's slot, written by the thread that arrived first: read past L1.
        const volatile float* o = (const volatile float*)&nodes[p].box[side ^ 1];
        Aabb ob = {{o[0], o[1], o[2]}, {o[3], o[4], o[5]}};
        box = box_union(box, ob);
        up = inner_parent[p];
    }
}

/// Sums a per-thread count over the warp and adds it to `total` once per warp.
__device__ inline void add_warp(unsigned long long* total, uint32_t count) {
    unsigned long long c = count;
    for (int o = 16; o > 0; o >>= 1) c += __shfl_down_sync(0xffffffffu, c, o);
    if ((threadIdx.x & 31) == 0) atomicAdd(total, c);
}

struct TraceArgs {
    View view;
    const Ray* rays;
    uint64_t* keys;
    unsigned long long *tests, *visits;
    size_t n_rays;
    int any_hit;
};

/// One thread per ray: closest hit (the smallest key, as PDACRT's leaf keeps it) or,
/// with any_hit, the first blocker.
__global__ void trace(TraceArgs a) {
    size_t i = (size_t)blockIdx.x * blockDim.x + threadIdx.x;
    uint32_t tests = 0, visits = 0;
    if (i < a.n_rays) a.keys[i] = trace_key(a.view, a.rays[i], a.any_hit, tests, visits);
    add_warp(a.tests, tests);
    add_warp(a.visits, visits);
}

struct Bvh {
    size_t n = 0;
    Buf<Tri> tris, sorted;
    Buf<Aabb> bounds, leaf_boxes;
    Buf<uint32_t> codes, ids, codes_sorted, ids_sorted, inner_parent, leaf_parent, arrivals;
    Buf<Node> nodes;
    Buf<Ray> rays;
    Buf<uint64_t> keys;
    Buf<unsigned long long> counters;
    Buf<char> scratch;

    void* temp(size_t bytes) {
        scratch.resize(bytes);
        return scratch.p;
    }
    static unsigned grid_of(size_t n) { return (unsigned)((n + BLOCK - 1) / BLOCK); }
    static void launched(const char* name) { check(cudaGetLastError(), name); }

    /// The build with the triangles resident: the stages of the file's header.
    void build() {
        if (n == 0) return;
        bounds.resize(1);
        size_t bytes = 0;
        auto boxes = thrust::make_transform_iterator(tris.p, CentroidBox());
        Aabb empty = {{INFINITY, INFINITY, INFINITY}, {-INFINITY, -INFINITY, -INFINITY}};
        check(cub::DeviceReduce::Reduce(nullptr, bytes, boxes, bounds.p, (int64_t)n, BoxUnion(), empty), "reduce size");
        check(cub::DeviceReduce::Reduce(temp(bytes), bytes, boxes, bounds.p, (int64_t)n, BoxUnion(), empty),
              "bvh::centroid_bounds");
        for (Buf<uint32_t>* b : {&codes, &ids, &codes_sorted, &ids_sorted, &leaf_parent}) b->resize(n);
        morton_codes<<<grid_of(n), BLOCK>>>(tris.p, bounds.p, codes.p, ids.p, n);
        launched("bvh::morton_codes");
        bytes = 0;
        check(cub::DeviceRadixSort::SortPairs(nullptr, bytes, codes.p, codes_sorted.p, ids.p, ids_sorted.p, (int64_t)n,
                                              0, 30),
              "sort size");
        check(cub::DeviceRadixSort::SortPairs(temp(bytes), bytes, codes.p, codes_sorted.p, ids.p, ids_sorted.p,
                                              (int64_t)n, 0, 30),
              "bvh::sort_codes");
        sorted.resize(n);
        leaf_boxes.resize(n);
        gather_triangles<<<grid_of(n), BLOCK>>>(tris.p, ids_sorted.p, sorted.p, leaf_boxes.p, n);
        launched("bvh::gather_triangles");
        if (n == 1) {
            nodes.resize(0);
            return;
        }
        nodes.resize(n - 1);
        inner_parent.resize(n - 1);
        arrivals.resize(n - 1);
        emit_hierarchy<<<grid_of(n - 1), BLOCK>>>(codes_sorted.p, nodes.p, inner_parent.p, leaf_parent.p, (int)n);
        launched("bvh::emit_hierarchy");
        check(cudaMemsetAsync(arrivals.p, 0, (n - 1) * sizeof(uint32_t)), "bvh::clear_arrivals");
        fit_boxes<<<grid_of(n), BLOCK>>>(leaf_boxes.p, leaf_parent.p, inner_parent.p, nodes.p, arrivals.p, (int)n);
        launched("bvh::fit_boxes");
    }

    int32_t root() const { return n == 0 ? INT32_MIN : (n == 1 ? ~0 : 0); }
    View view(float widen, float grow) const { return {nodes.p, sorted.p, ids_sorted.p, root(), widen, grow}; }
};

/// Times GPU work between two events.
struct EventTimer {
    cudaEvent_t start, stop;
    EventTimer() {
        check(cudaEventCreate(&start), "event");
        if (cudaEventCreate(&stop) != cudaSuccess) {
            cudaEventDestroy(start);
            throw CudaError{"event"};
        }
    }
    ~EventTimer() {
        cudaEventDestroy(start);
        cudaEventDestroy(stop);
    }
    template <class F>
    double time(F f) {
        check(cudaEventRecord(start), "event");
        f();
        check(cudaEventRecord(stop), "event");
        check(cudaEventSynchronize(stop), "synchronise");
        float ms = 0;
        check(cudaEventElapsedTime(&ms, start, stop), "event time");
        return ms;
    }
};

static thread_local std::string last_error;

template <class F>
static int guarded(F f) {
    return wr::guarded(last_error, f);
}

static double ms_since(std::chrono::steady_clock::time_point t) {
    return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t).count();
}

View view_of(void* handle, float widen, float grow) { return static_cast<Bvh*>(handle)->view(widen, grow); }

}  // namespace bvh

extern "C" const char* wr_bvh_last_error(void) { return bvh::last_error.c_str(); }

extern "C" int wr_bvh_create(void** handle) {
    return bvh::guarded([&] { *handle = new bvh::Bvh(); });
}

extern "C" void wr_bvh_destroy(void* handle) { delete static_cast<bvh::Bvh*>(handle); }

extern "C" int wr_bvh_build(void* handle, const float* tris, uint64_t n_tris, WrBvhStats* stats) {
    using namespace bvh;
    return guarded([&] {
        if (n_tris >= (1ull << 31)) throw CudaError{"at most 2^31 - 1 triangles"};
        Bvh& b = *static_cast<Bvh*>(handle);
        auto wall = std::chrono::steady_clock::now();
        b.n = 0;  // a failure below leaves an empty structure, never a stale one
        b.tris.resize(n_tris);
        if (n_tris) check(cudaMemcpy(b.tris.p, tris, n_tris * sizeof(Tri), cudaMemcpyHostToDevice), "upload triangles");
        *stats = WrBvhStats{};
        stats->upload_ms = ms_since(wall);
        b.n = n_tris;
        EventTimer timer;
        stats->build_ms = timer.time([&] { b.build(); });
        stats->nodes = n_tris > 1 ? n_tris - 1 : 0;
        stats->bytes = stats->nodes * sizeof(Node) + n_tris * (sizeof(Tri) + sizeof(uint32_t));
        stats->call_ms = ms_since(wall);
    });
}

extern "C" int wr_bvh_trace(void* handle, const void* rays, uint64_t n_rays, int any_hit, float slab_widen,
                            float grow, uint64_t* keys, WrBvhStats* stats) {
    using namespace bvh;
    return guarded([&] {
        Bvh& b = *static_cast<Bvh*>(handle);
        auto wall = std::chrono::steady_clock::now();
        *stats = WrBvhStats{};
        if (n_rays == 0) return;
        b.rays.resize(n_rays);
        check(cudaMemcpy(b.rays.p, rays, n_rays * sizeof(Ray), cudaMemcpyHostToDevice), "upload rays");
        b.keys.resize(n_rays);
        b.counters.resize(2);
        check(cudaMemset(b.counters.p, 0, 2 * sizeof(unsigned long long)), "clear counters");
        TraceArgs a = {b.view(slab_widen, grow), b.rays.p, b.keys.p, b.counters.p, b.counters.p + 1, n_rays, any_hit};
        EventTimer timer;
        stats->trace_ms = timer.time([&] {
            trace<<<Bvh::grid_of(n_rays), BLOCK>>>(a);
            Bvh::launched("bvh::trace");
        });
        check(cudaMemcpy(keys, b.keys.p, n_rays * sizeof(uint64_t), cudaMemcpyDeviceToHost), "download keys");
        unsigned long long c[2];
        check(cudaMemcpy(c, b.counters.p, sizeof c, cudaMemcpyDeviceToHost), "download counters");
        stats->tests = c[0];
        stats->visits = c[1];
        stats->call_ms = ms_since(wall);
    });
}
