// Whole GPU renders (render_api.h): the CUDA backend of render_driver.cuh. Kernels are
// one template instantiated per stage, so Nsight names each launch by its stage
// function (`render::launch_kernel<render::K, &render::light_shade>`); rays go through
// the GPU BVH of bvh.cu, built once per handle, whose traversal the megakernels run
// inside their threads.

#include <cub/device/device_radix_sort.cuh>
#include <cub/device/device_scan.cuh>
#include <cub/device/device_select.cuh>
#include <thrust/iterator/counting_iterator.h>

#include <chrono>
#include <string>
#include <vector>

#include "bvh_api.h"
#include "bvh_trace.cuh"
#include "device_buf.cuh"
#include "guarded.h"
#include "render_device.cuh"

namespace render {

template <class T>
using Mem = wr::Buf<T>;
using wr::check;

constexpr int BLOCK = 128;

template <class A, void (*F)(const A&, size_t)>
__global__ void launch_kernel(A a, size_t n) {
    size_t i = (size_t)blockIdx.x * blockDim.x + threadIdx.x;
    if (i < n) F(a, i);
}
template <class A, void (*F)(const A&, size_t)>
void launch(const char* name, size_t n, const A& a) {
    launch_kernel<A, F><<<(unsigned)((n + BLOCK - 1) / BLOCK), BLOCK>>>(a, n);
    check(cudaGetLastError(), name);
}

// Scratch for CUB's primitives, kept across calls.
static Mem<char>& scratch() {
    static thread_local Mem<char> s;
    return s;
}
static Mem<uint32_t>& scratch_u32(int k) {
    static thread_local Mem<uint32_t> s[3];
    return s[k];
}

inline size_t select_flagged(const uint32_t* flags, size_t n, uint32_t* out) {
    Mem<uint32_t>& count = scratch_u32(0);
    count.resize(1);
    thrust::counting_iterator<uint32_t> ids(0);
    size_t bytes = 0;
    check(cub::DeviceSelect::Flagged(nullptr, bytes, ids, flags, out, count.p, (int64_t)n), "select size");
    scratch().resize(bytes);
    check(cub::DeviceSelect::Flagged(scratch().p, bytes, ids, flags, out, count.p, (int64_t)n), "select");
    uint32_t m = 0;
    check(cudaMemcpy(&m, count.p, 4, cudaMemcpyDeviceToHost), "select count");
    return m;
}
inline void sort_pairs(uint32_t* keys, uint32_t* vals, size_t n, int bits) {
    Mem<uint32_t>&k2 = scratch_u32(1), &v2 = scratch_u32(2);
    k2.resize(n);
    v2.resize(n);
    size_t bytes = 0;
    check(cub::DeviceRadixSort::SortPairs(nullptr, bytes, keys, k2.p, vals, v2.p, (int64_t)n, 0, bits), "sort size");
    scratch().resize(bytes);
    check(cub::DeviceRadixSort::SortPairs(scratch().p, bytes, keys, k2.p, vals, v2.p, (int64_t)n, 0, bits), "sort");
    check(cudaMemcpyAsync(keys, k2.p, n * 4, cudaMemcpyDeviceToDevice), "sort copy");
    check(cudaMemcpyAsync(vals, v2.p, n * 4, cudaMemcpyDeviceToDevice), "sort copy");
}
inline uint32_t exclusive_sum(const uint32_t* in, uint32_t* out, size_t n) {
    size_t bytes = 0;
    check(cub::DeviceScan::ExclusiveSum(nullptr, bytes, in, out, (int64_t)n), "scan size");
    scratch().resize(bytes);
    check(cub::DeviceScan::ExclusiveSum(scratch().p, bytes, in, out, (int64_t)n), "scan");
    uint32_t last[2];
    check(cudaMemcpy(&last[0], out + n - 1, 4, cudaMemcpyDeviceToHost), "scan total");
    check(cudaMemcpy(&last[1], in + n - 1, 4, cudaMemcpyDeviceToHost), "scan total");
    return last[0] + last[1];
}
template <class T>
void download(T* host, const T* dev, size_t n) {
    check(cudaMemcpy(host, dev, n * sizeof(T), cudaMemcpyDeviceToHost), "download");
}
template <class T>
void upload(T* dev, const T* host, size_t n) {
    check(cudaMemcpy(dev, host, n * sizeof(T), cudaMemcpyHostToDevice), "upload");
}
template <class T>
void copy_on_device(T* dst, const T* src, size_t n) {
    check(cudaMemcpyAsync(dst, src, n * sizeof(T), cudaMemcpyDeviceToDevice), "copy");
}
template <class T>
void fill_zero(T* p, size_t n) {
    check(cudaMemsetAsync(p, 0, n * sizeof(T)), "clear");
}

// The rays of a render go through the GPU BVH.
using Tracer = bvh::View;
__device__ inline uint64_t trace(const Tracer& t, const cis::Ray& r, bool any_hit) {
    uint32_t tests = 0, visits = 0;
    return bvh::trace_key(t, reinterpret_cast<const wr::Ray&>(r), any_hit, tests, visits);
}

// GPU time between start and stop_ms (CUDA events on the default stream).
struct Clock {
    cudaEvent_t a{}, b{};
    Clock() {
        check(cudaEventCreate(&a), "event");
        check(cudaEventCreate(&b), "event");
    }
    ~Clock() {
        cudaEventDestroy(a);
        cudaEventDestroy(b);
    }
    void start() { check(cudaEventRecord(a), "event"); }
    double stop_ms() {
        check(cudaEventRecord(b), "event");
        check(cudaEventSynchronize(b), "synchronise");
        float ms = 0;
        check(cudaEventElapsedTime(&ms, a, b), "event time");
        return ms;
    }
};

}  // namespace render

#include "render_driver.cuh"

namespace render {

struct Handle {
    Renderer r;
    void* bvh = nullptr;
    std::vector<void*> owned;
    template <class T>
    const T* keep(const T* src, size_t n) {
        T* p = nullptr;
        check(cudaMalloc(&p, (n ? n : 1) * sizeof(T)), "upload the scene");
        owned.push_back(p);
        if (n) check(cudaMemcpy(p, src, n * sizeof(T), cudaMemcpyHostToDevice), "upload the scene");
        return p;
    }
    ~Handle() {
        for (void* p : owned) cudaFree(p);
        if (bvh) wr_bvh_destroy(bvh);
    }
};

static thread_local std::string last_error;

}  // namespace render

extern "C" const char* wr_render_last_error(void) { return render::last_error.c_str(); }

extern "C" int wr_render_create(const WrCisScene* s, const WrRenderSettings* set, void** handle,
                                WrRenderStats* stats) {
    using namespace render;
    return wr::guarded(last_error, [&] {
        Handle* h = new Handle();
        try {
            *stats = WrRenderStats{};
            Renderer& r = h->r;
            r.set = *set;
            cis::make_scene(r.k.sc, s, [&](auto* p, size_t n) { return h->keep(p, n); });
            r.k.seed = set->seed;
            r.k.miss_key = (uint32_t)s->n_materials;
            check(cudaDeviceSetLimit(cudaLimitStackSize, 32 * 1024), "cudaDeviceSetLimit");
            WrBvhStats b{};
            if (wr_bvh_create(&h->bvh) != 0 || wr_bvh_build(h->bvh, s->tris, s->n_tris, &b) != 0)
                throw wr::CudaError{std::string("the BVH: ") + wr_bvh_last_error()};
            r.k.tracer = bvh::view_of(h->bvh, set->widen, set->grow);
            stats->build_ms = b.build_ms;
        } catch (...) {
            delete h;
            throw;
        }
        *handle = h;
    });
}

extern "C" int wr_render_pass(void* handle, uint32_t pass, float* estimates, const float** splats,
                              uint64_t* n_splats, WrRenderStats* stats) {
    using namespace render;
    return wr::guarded(last_error, [&] {
        Renderer& r = static_cast<Handle*>(handle)->r;
        r.pass(pass);
        auto wall = std::chrono::steady_clock::now();
        download(estimates, r.estimates.p, r.estimates.n);
        r.download_splats();
        r.stats.readback_ms =
            std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - wall).count();
        *splats = r.host_splats.data();
        *n_splats = r.n_splats;
        *stats = r.stats;
    });
}

extern "C" void wr_render_destroy(void* handle) { delete static_cast<render::Handle*>(handle); }
