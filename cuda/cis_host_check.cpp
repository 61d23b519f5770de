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

#include <chrono>
#include <cstdio>
#include <cstring>
#include <string>
#include <type_traits>
#include <vector>

#define __device__
#define __forceinline__ inline
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
#include "pdacrt_api.h"

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
}
