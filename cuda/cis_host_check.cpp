// CIS-LBDPT's GPU twin built for the CPU: the device code of cis_device.cuh compiled
// by a host C++ compiler behind the library's C interface (cis_api.h, plus stubs for
// PDACRT's and the GPU BVH's entry points, which report that they are absent), so that the port can be
// compared with the emulator on a machine with no GPU:
//
//   g++ -std=c++17 -O2 -ffp-contract=off -shared -fPIC -o target/cuda/libwarpray_cuda_host.so cuda/cis_host_check.cpp
//   WARPRAY_CUDA_LIB=target/cuda/libwarpray_cuda_host.so target/release/examples/gpu_check cis --size 64
//
// Here sin, cos and exp are glibc's, as in the Rust build, so the results should agree
// to rounding everywhere; on the GPU a few lanes may not (see cis.cu). Kernels run
// sequentially, thread by thread; times are wall times of that loop.

#include <math.h>

#include <algorithm>
#include <new>
#include <utility>

#include <chrono>
#include <cstdio>
#include <cstring>
#include <string>
#include <type_traits>
#include <vector>

#define __device__
#define __host__
#define __forceinline__ inline
static inline unsigned __float_as_uint(float f) {
    unsigned i;
    memcpy(&i, &f, 4);
    return i;
}
static inline float __uint_as_float(unsigned i) {
    float f;
    memcpy(&f, &i, 4);
    return f;
}
static inline int __float_as_int(float f) {
    int i;
    memcpy(&i, &f, 4);
    return i;
}
static inline float __int_as_float(int i) {
    float f;
    memcpy(&f, &i, 4);
    return f;
}

#include "bvh_api.h"
#include "cis_device.cuh"
#include "geometry.cuh"
#include "pdacrt_api.h"

// The backend of render_driver.cuh on the CPU: host arrays, kernels as loops, the
// primitives sequential, and brute force over every triangle in place of the GPU BVH
// (the same watertight test and key, so the same hits).
namespace render {

template <class T>
struct Mem {
    T* p = nullptr;
    size_t n = 0, cap = 0;
    void resize(size_t m) {
        if (m > cap) {
            free(p);
            cap = m + m / 4 + 16;
            p = (T*)calloc(cap, sizeof(T));
            if (!p) throw std::bad_alloc();
        }
        n = m;
    }
    void swap(Mem& o) {
        std::swap(p, o.p);
        std::swap(n, o.n);
        std::swap(cap, o.cap);
    }
    Mem() = default;
    Mem(const Mem&) = delete;
    Mem& operator=(const Mem&) = delete;
    ~Mem() { free(p); }
};
template <class A, void (*F)(const A&, size_t)>
void launch(const char*, size_t n, const A& a) {
    for (size_t i = 0; i < n; i++) F(a, i);
}
inline size_t select_flagged(const uint32_t* flags, size_t n, uint32_t* out) {
    size_t m = 0;
    for (size_t i = 0; i < n; i++)
        if (flags[i]) out[m++] = (uint32_t)i;
    return m;
}
inline void sort_pairs(uint32_t* keys, uint32_t* vals, size_t n, int) {
    std::vector<std::pair<uint32_t, uint32_t>> kv(n);
    for (size_t i = 0; i < n; i++) kv[i] = {keys[i], vals[i]};
    std::stable_sort(kv.begin(), kv.end(), [](auto& a, auto& b) { return a.first < b.first; });
    for (size_t i = 0; i < n; i++) keys[i] = kv[i].first, vals[i] = kv[i].second;
}
inline uint32_t exclusive_sum(const uint32_t* in, uint32_t* out, size_t n) {
    uint32_t total = 0;
    for (size_t i = 0; i < n; i++) out[i] = total, total += in[i];
    return total;
}
template <class T>
void download(T* host, const T* dev, size_t n) {
    memcpy(host, dev, n * sizeof(T));
}
template <class T>
void upload(T* dev, const T* host, size_t n) {
    memcpy(dev, host, n * sizeof(T));
}
template <class T>
void copy_on_device(T* dst, const T* src, size_t n) {
    memmove(dst, src, n * sizeof(T));
}
template <class T>
void fill_zero(T* p, size_t n) {
    memset((void*)p, 0, n * sizeof(T));
}
struct Tracer {
    const wr::Tri* tris;
    size_t n;
};
inline uint64_t trace(const Tracer& t, const cis::Ray& ray, bool any_hit) {
    const wr::Ray& r = reinterpret_cast<const wr::Ray&>(ray);
    uint64_t key = wr::NO_HIT;
    if (!wr::ray_valid(r)) return key;
    wr::Shear sh = wr::make_shear(r.d);
    for (size_t i = 0; i < t.n; i++) {
        float th;
        if (!wr::hit_triangle(r.o, sh, t.tris[i].v, r.t_min, r.t_max, th)) continue;
        if (any_hit) return wr::BLOCKED;
        key = std::min(key, wr::pack_hit(th, (uint32_t)i));
    }
    return key;
}
struct Clock {
    std::chrono::steady_clock::time_point t;
    void start() { t = std::chrono::steady_clock::now(); }
    double stop_ms() {
        return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t).count();
    }
};

}  // namespace render

#include "render_driver.cuh"

using namespace cis;

namespace {
std::string last_error;

struct HostHandle {
    Scene sc;
    // The copies the scene points into (8-byte aligned: vectors of u64).
    std::vector<std::vector<uint64_t>> owned;
};

double ms_since(std::chrono::steady_clock::time_point t) {
    return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t).count();
}
}  // namespace

extern "C" {
int wr_api_version(void) { return WR_API_VERSION; }
int wr_device_name(char* buf, uint32_t len) {
    snprintf(buf, len, "CPU (cuda/cis_host_check.cpp)");
    return 0;
}
const char* wr_last_error(void) { return "PDACRT is not part of the host check"; }
int wr_pdacrt_create(const float*, uint64_t, const float*, void**) { return 1; }
int wr_pdacrt_trace(void*, const void*, uint64_t, int, const WrParams*, uint64_t*, WrStats*) { return 1; }
int wr_pdacrt_set_triangles(void*, const float*, uint64_t, const float*) { return 1; }
void wr_pdacrt_destroy(void*) {}
const char* wr_bvh_last_error(void) { return "the GPU BVH is not part of the host check"; }
int wr_bvh_create(void**) { return 1; }
int wr_bvh_build(void*, const float*, uint64_t, WrBvhStats*) { return 1; }
int wr_bvh_trace(void*, const void*, uint64_t, int, float, float, uint64_t*, WrBvhStats*) { return 1; }
void wr_bvh_destroy(void*) {}
const char* wr_cis_last_error(void) { return last_error.c_str(); }

int wr_cis_create(const WrCisScene* s, void** handle) {
    HostHandle* h = new HostHandle();
    make_scene(h->sc, s, [&](auto* p, size_t n) {
        using T = std::remove_const_t<std::remove_pointer_t<decltype(p)>>;
        h->owned.emplace_back(n * sizeof(T) / 8 + 1);
        if (n) memcpy(h->owned.back().data(), p, n * sizeof(T));
        return (const T*)h->owned.back().data();
    });
    *handle = h;
    return 0;
}

int wr_cis_shade(void* handle, int, uint64_t n, const uint32_t* order, const uint32_t* active, const void* hits,
                 uint64_t pool, void* slots, void* vertices, void* pending, double* ms) {
    HostHandle* h = (HostHandle*)handle;
    memset(pending, 0, pool * PENDING_PER_SLOT * sizeof(PendingData));
    auto t = std::chrono::steady_clock::now();
    for (uint64_t j = 0; j < n; j++)
        shade(h->sc, order, active, (const Hit*)hits, (Slot*)slots, (Vertex*)vertices, (PendingData*)pending, j);
    *ms = ms_since(t);
    return 0;
}

int wr_cis_compact(void*, uint64_t n, const uint32_t* active, uint64_t, const void* slots, uint32_t* kept,
                   uint64_t* n_kept, double* ms) {
    auto t = std::chrono::steady_clock::now();
    uint64_t m = 0;
    for (uint64_t i = 0; i < n; i++)
        if (((const Slot*)slots)[active[i]].alive != 0) kept[m++] = active[i];
    *n_kept = m;
    *ms = ms_since(t);
    return 0;
}

void wr_cis_destroy(void* handle) { delete (HostHandle*)handle; }

// ---------------------------------------------------------------- whole renders (render_api.h)

namespace {
struct RenderHandle {
    render::Renderer r;
    std::vector<std::vector<uint64_t>> owned;
};
std::string render_error;
}  // namespace

const char* wr_render_last_error(void) { return render_error.c_str(); }

int wr_render_create(const WrCisScene* s, const WrRenderSettings* set, void** handle, WrRenderStats* stats) {
    RenderHandle* h = new RenderHandle();
    make_scene(h->r.k.sc, s, [&](auto* p, size_t n) {
        using T = std::remove_const_t<std::remove_pointer_t<decltype(p)>>;
        h->owned.emplace_back(n * sizeof(T) / 8 + 1);
        if (n) memcpy(h->owned.back().data(), p, n * sizeof(T));
        return (const T*)h->owned.back().data();
    });
    h->r.set = *set;
    h->r.k.seed = set->seed;
    h->r.k.miss_key = (uint32_t)s->n_materials;
    h->r.k.tracer = {(const wr::Tri*)h->r.k.sc.tris, (size_t)s->n_tris};
    *stats = WrRenderStats{};
    *handle = h;
    return 0;
}

int wr_render_pass(void* handle, uint32_t pass, float* estimates, const float** splats, uint64_t* n_splats,
                   WrRenderStats* stats) {
    render::Renderer& r = ((RenderHandle*)handle)->r;
    try {
        r.pass(pass);
    } catch (const std::exception& e) {
        render_error = e.what();
        return 1;
    }
    auto t = std::chrono::steady_clock::now();
    memcpy(estimates, r.estimates.p, r.estimates.n * sizeof(float));
    r.download_splats();
    r.stats.readback_ms = ms_since(t);
    *splats = r.host_splats.data();
    *n_splats = r.n_splats;
    *stats = r.stats;
    return 0;
}

void wr_render_destroy(void* handle) { delete (RenderHandle*)handle; }
}
