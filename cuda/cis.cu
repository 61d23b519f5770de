// CIS-LBDPT's shading kernel and compaction on a real GPU: the twins of `cis::shade`
// (src/render/cis/kernels.rs) and of the compaction in src/render/cis/pool.rs
// (`cis::alive_flags`, then a flagged selection, CUB's here). The kernel needs the whole
// bidirectional core in device code, in `cis_device.cuh`: the BSDFs of src/bsdf
// (mod.rs, microfacet.rs, layered.rs), light sampling (src/lights.rs), the strategies
// and MIS weights of src/render/bidir.rs and LVC's `vertex_strategies`
// (src/render/lvc.rs), each ported function named as in Rust and kept in the same order
// of operations, so that with `-fmad=false` most results round alike (sin, cos, exp and
// tan come from CUDA's library, not glibc's, so a few lanes may differ in the last bits
// and, rarely, in a random choice; the checks allow for that).

#include <cub/device/device_select.cuh>

#include <cstring>
#include <string>
#include <vector>

#include "cis_device.cuh"
#include "guarded.h"

namespace cis {

struct ShadeArgs {
    Scene sc;
    const uint32_t *order, *active;
    const Hit* hits;
    Slot* slots;
    Vertex* vertices;
    PendingData* pending;
    size_t n;
};
// Two names for one kernel, so that the profiler tells the sorted launches from the
// unsorted ones.
__global__ void shade_sorted(ShadeArgs a) {
    size_t j = (size_t)blockIdx.x * blockDim.x + threadIdx.x;
    if (j < a.n) shade(a.sc, a.order, a.active, a.hits, a.slots, a.vertices, a.pending, j);
}
__global__ void shade_unsorted(ShadeArgs a) {
    size_t j = (size_t)blockIdx.x * blockDim.x + threadIdx.x;
    if (j < a.n) shade(a.sc, a.order, a.active, a.hits, a.slots, a.vertices, a.pending, j);
}
// `cis::alive_flags` (pool.rs::survivors with keep = true).
__global__ void alive_flags(const uint32_t* active, const Slot* slots, uint32_t* flags, size_t n) {
    size_t i = (size_t)blockIdx.x * blockDim.x + threadIdx.x;
    if (i < n) flags[i] = slots[active[i]].alive != 0;
}

// ---------------------------------------------------------------- host side

using wr::CudaError;
static void check(cudaError_t e, const char* what) {
    if (e != cudaSuccess) throw CudaError{std::string(what) + ": " + cudaGetErrorString(e)};
}
template <class T>
static T* upload(const T* src, size_t n, const char* what) {
    T* p = nullptr;
    check(cudaMalloc(&p, (n ? n : 1) * sizeof(T)), what);
    if (n) check(cudaMemcpy(p, src, n * sizeof(T), cudaMemcpyHostToDevice), what);
    return p;
}

struct Handle {
    Scene sc;
    std::vector<void*> owned;
    template <class T>
    const T* keep(const T* src, size_t n, const char* what) {
        T* p = upload(src, n, what);
        owned.push_back(p);
        return p;
    }
    ~Handle() {
        for (void* p : owned) cudaFree(p);
    }
};

static thread_local std::string last_error;
template <class F>
static int guarded(F f) {
    return wr::guarded(last_error, f);
}

// Times `launch` with CUDA events.
template <class F>
static double timed(F launch) {
    cudaEvent_t a, b;
    check(cudaEventCreate(&a), "cudaEventCreate");
    check(cudaEventCreate(&b), "cudaEventCreate");
    check(cudaEventRecord(a), "cudaEventRecord");
    launch();
    check(cudaGetLastError(), "launch");
    check(cudaEventRecord(b), "cudaEventRecord");
    check(cudaEventSynchronize(b), "cudaEventSynchronize");
    float ms = 0.0f;
    check(cudaEventElapsedTime(&ms, a, b), "cudaEventElapsedTime");
    cudaEventDestroy(a);
    cudaEventDestroy(b);
    return ms;
}

}  // namespace cis

using namespace cis;

extern "C" const char* wr_cis_last_error(void) { return cis::last_error.c_str(); }

extern "C" int wr_cis_create(const WrCisScene* s, void** handle) {
    return guarded([&] {
        Handle* h = new Handle();
        try {
            Scene& sc = h->sc;
            make_scene(sc, s, [&](auto* p, size_t n) { return h->keep(p, n, "upload the scene"); });
            // Deep recursion and 64-vertex lists on the stack: give each thread room.
            check(cudaDeviceSetLimit(cudaLimitStackSize, 16 * 1024), "cudaDeviceSetLimit");
        } catch (...) {
            delete h;
            throw;
        }
        *handle = h;
    });
}

extern "C" int wr_cis_shade(void* handle, int sorted, uint64_t n, const uint32_t* order, const uint32_t* active,
                            const void* hits, uint64_t pool, void* slots, void* vertices, void* pending, double* ms) {
    return guarded([&] {
        Handle* h = (Handle*)handle;
        ShadeArgs a;
        a.sc = h->sc;
        a.n = n;
        std::vector<void*> tmp;
        auto up = [&](const void* src, size_t bytes) {
            void* p = nullptr;
            check(cudaMalloc(&p, bytes ? bytes : 1), "cudaMalloc");
            tmp.push_back(p);
            if (src && bytes) check(cudaMemcpy(p, src, bytes, cudaMemcpyHostToDevice), "upload");
            return p;
        };
        try {
            a.order = (const uint32_t*)up(order, n * 4);
            a.active = (const uint32_t*)up(active, n * 4);
            a.hits = (const Hit*)up(hits, n * sizeof(Hit));
            a.slots = (Slot*)up(slots, pool * sizeof(Slot));
            a.vertices = (Vertex*)up(vertices, pool * MAX_CAMERA_VERTICES * sizeof(Vertex));
            a.pending = (PendingData*)up(nullptr, pool * PENDING_PER_SLOT * sizeof(PendingData));
            check(cudaMemset(a.pending, 0, pool * PENDING_PER_SLOT * sizeof(PendingData)), "cudaMemset");
            unsigned grid = (unsigned)((n + 127) / 128);
            *ms = n == 0 ? 0.0 : timed([&] {
                if (sorted) shade_sorted<<<grid, 128>>>(a);
                else shade_unsorted<<<grid, 128>>>(a);
            });
            check(cudaMemcpy(slots, a.slots, pool * sizeof(Slot), cudaMemcpyDeviceToHost), "download slots");
            check(cudaMemcpy(vertices, a.vertices, pool * MAX_CAMERA_VERTICES * sizeof(Vertex), cudaMemcpyDeviceToHost),
                  "download vertices");
            check(cudaMemcpy(pending, a.pending, pool * PENDING_PER_SLOT * sizeof(PendingData), cudaMemcpyDeviceToHost),
                  "download pending");
        } catch (...) {
            for (void* p : tmp) cudaFree(p);
            throw;
        }
        for (void* p : tmp) cudaFree(p);
    });
}

extern "C" int wr_cis_compact(void* handle, uint64_t n, const uint32_t* active, uint64_t pool, const void* slots,
                              uint32_t* kept, uint64_t* n_kept, double* ms) {
    (void)handle;
    return guarded([&] {
        uint32_t *d_active = nullptr, *d_flags = nullptr, *d_kept = nullptr;
        Slot* d_slots = nullptr;
        int* d_count = nullptr;
        void* temp = nullptr;
        size_t temp_bytes = 0;
        auto release = [&] {
            cudaFree(d_active);
            cudaFree(d_flags);
            cudaFree(d_kept);
            cudaFree(d_slots);
            cudaFree(d_count);
            cudaFree(temp);
        };
        try {
            d_active = upload(active, n, "upload active");
            d_slots = upload((const Slot*)slots, pool, "upload slots");
            check(cudaMalloc(&d_flags, (n ? n : 1) * 4), "cudaMalloc");
            check(cudaMalloc(&d_kept, (n ? n : 1) * 4), "cudaMalloc");
            check(cudaMalloc(&d_count, sizeof(int)), "cudaMalloc");
            check(cub::DeviceSelect::Flagged(nullptr, temp_bytes, d_active, d_flags, d_kept, d_count, (int)n),
                  "DeviceSelect::Flagged");
            check(cudaMalloc(&temp, temp_bytes ? temp_bytes : 1), "cudaMalloc");
            unsigned grid = (unsigned)((n + 255) / 256);
            *ms = n == 0 ? 0.0 : timed([&] {
                alive_flags<<<grid, 256>>>(d_active, d_slots, d_flags, n);
                check(cub::DeviceSelect::Flagged(temp, temp_bytes, d_active, d_flags, d_kept, d_count, (int)n),
                      "DeviceSelect::Flagged");
            });
            int count = 0;
            check(cudaMemcpy(&count, d_count, sizeof(int), cudaMemcpyDeviceToHost), "download count");
            *n_kept = (uint64_t)count;
            if (count) check(cudaMemcpy(kept, d_kept, count * 4, cudaMemcpyDeviceToHost), "download kept");
        } catch (...) {
            release();
            throw;
        }
        release();
    });
}

extern "C" void wr_cis_destroy(void* handle) { delete (Handle*)handle; }
