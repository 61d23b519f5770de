// Microbenchmarks that calibrate simt's GPU time model (simt/src/timing.rs): one kernel
// per quantity of a GPU profile (simt/profiles/*.toml), each launched PROBE_LAUNCHES
// times. Nothing is timed here: cuda/microbench.sh runs this program under Nsight
// Compute, whose per-launch duration, instruction, cache and DRAM counters are what
// `gpu_check calibrate` turns into the profile. This program prints one line per probe
// with the work it did (hops of a pointer chase, barriers, atomic lanes), which the
// counters do not give.
//
// The probes are deliberately unlike the checked kernels (PDACRT, CIS): the model is
// calibrated on these only, then checked on those.
//
// About 1,190 lines on purpose: one probe per profile quantity, each with its launch, in
// one program that `cuda/microbench.sh` profiles in one pass.
//
//   nvcc -std=c++17 -O3 -arch=sm_90 -o target/cuda/microbench cuda/microbench.cu
//   target/cuda/microbench          every probe
//   target/cuda/microbench fences   the atomic-latency and fence probes alone
//   target/cuda/microbench rounds   rounds of loads issued together, alone
//   target/cuda/microbench start    the start of a short kernel: stores, parameters, cold code
//   target/cuda/microbench grid     a short kernel by its blocks (1 to 4 a SM)
//   target/cuda/microbench scan     CUB's single-pass scan by its tiles (1 to 1,024)
//   target/cuda/microbench hbm      HBM read at random, a sector at a time
//   target/cuda/microbench stream   first touches in order: chases through fresh memory
//   target/cuda/microbench icache   instruction fetch: straight-line and branchy code
//   target/cuda/microbench l2size   load latency by the size of the data chased
//   target/cuda/microbench fencemix fences under load: by sectors waited for, and a fit's climb
//   target/cuda/microbench slots    whether a block's slot waits for its slowest warp
//   target/cuda/microbench overlap  how an L2 bound and an issue bound combine
//   target/cuda/microbench inflight L2 bandwidth by the loads each warp keeps in flight
#include <algorithm>
#include <cstdint>
#include <cstdio>
#include <string>
#include <vector>

#include <cub/device/device_scan.cuh>

#define CHECK(x)                                                                        \
    do {                                                                                \
        cudaError_t e_ = (x);                                                           \
        if (e_ != cudaSuccess) {                                                        \
            fprintf(stderr, "microbench: %s: %s\n", #x, cudaGetErrorString(e_));        \
            return 1;                                                                   \
        }                                                                               \
    } while (0)

static const int PROBE_LAUNCHES = 3;

namespace micro {

// An empty kernel: the duration of a launch that does nothing (one block), and with
// many blocks, what dispatching a block costs.
__global__ void empty() {}
__global__ void empty_blocks() {}

// Issue rate of a mix of independent float and integer arithmetic (8 chains per thread,
// no memory), with every SM full of warps.
__global__ void alu_mix(float* out, int iters) {
    float f[4];
    uint32_t u[4];
    for (int k = 0; k < 4; ++k) {
        f[k] = threadIdx.x * 0.001f + k;
        u[k] = threadIdx.x * 2654435761u + k;
    }
#pragma unroll 4
    for (int i = 0; i < iters; ++i) {
#pragma unroll
        for (int k = 0; k < 4; ++k) {
            f[k] = fmaf(f[k], 0.9999f, 0.0001f);
            u[k] = (u[k] ^ (u[k] >> 7)) + 0x9e3779b9u;
        }
    }
    float s = 0;
    for (int k = 0; k < 4; ++k) s += f[k] + (float)(u[k] & 1);
    if (s == 12345.0f) out[threadIdx.x] = s;  // keeps the work alive
}

// Latency of dependent arithmetic: one warp per SM, one chain.
__global__ void alu_chain(float* out, int iters) {
    float x = threadIdx.x * 0.001f;
#pragma unroll 8
    for (int i = 0; i < iters; ++i) x = fmaf(x, 0.9999f, 0.0001f);
    if (x == 12345.0f) out[threadIdx.x] = x;
}

// Bandwidth of device memory: a read and a write of a buffer much larger than L2.
__global__ void hbm_read(const float4* __restrict__ a, size_t n, float* out) {
    float s = 0;
    for (size_t i = blockIdx.x * (size_t)blockDim.x + threadIdx.x; i < n; i += (size_t)gridDim.x * blockDim.x) {
        float4 v = a[i];
        s += v.x + v.y + v.z + v.w;
    }
    if (s == 12345.0f) out[threadIdx.x] = s;
}
__global__ void hbm_write(float4* a, size_t n) {
    for (size_t i = blockIdx.x * (size_t)blockDim.x + threadIdx.x; i < n; i += (size_t)gridDim.x * blockDim.x)
        a[i] = make_float4(1, 2, 3, 4);
}

// Bandwidth of L2: passes over a buffer that fits in it, past L1 (ld.global.cg).
__global__ void l2_read(const float4* __restrict__ a, size_t n, int passes, float* out) {
    float s = 0;
    for (int p = 0; p < passes; ++p)
        for (size_t i = blockIdx.x * (size_t)blockDim.x + threadIdx.x; i < n; i += (size_t)gridDim.x * blockDim.x) {
            float4 v = __ldcg(&a[i]);
            s += v.x + v.w;
        }
    if (s == 12345.0f) out[threadIdx.x] = s;
}

// Scattered 4-byte loads from an L2-resident buffer: one sector per lane.
__global__ void l2_scatter(const float* __restrict__ a, uint32_t mask, int iters, float* out) {
    uint32_t h = (blockIdx.x * blockDim.x + threadIdx.x) * 2654435761u;
    float s = 0;
    for (int i = 0; i < iters; ++i) {
        h = h * 1664525u + 1013904223u;
        s += __ldcg(&a[(h >> 3) & mask]);
    }
    if (s == 12345.0f) out[threadIdx.x] = s;
}

// L1 bandwidth: each block reads its own 16 KiB again and again (hits after the first).
__global__ void l1_read(const float4* __restrict__ a, int passes, float* out) {
    const float4* mine = a + blockIdx.x * 1024;
    float s = 0;
    for (int p = 0; p < passes; ++p)
        for (int i = threadIdx.x; i < 1024; i += blockDim.x) {
            float4 v = mine[i];
            s += v.x + v.w;
        }
    if (s == 12345.0f) out[threadIdx.x] = s;
}

// Load latency: one thread follows a chain of indices (each load's address is the
// previous load's value). `cg` keeps the loads out of L1 for the L2 and HBM chases.
template <bool CG>
__device__ uint32_t chase(const uint32_t* a, int hops) {
    uint32_t i = 0;
    for (int h = 0; h < hops; ++h) i = CG ? __ldcg(&a[i]) : a[i];
    return i;
}
__global__ void chase_hbm(const uint32_t* a, int hops, uint32_t* out) { out[0] = chase<true>(a, hops); }
__global__ void chase_l2(const uint32_t* a, int hops, uint32_t* out) { out[0] = chase<true>(a, hops); }
__global__ void chase_l1(const uint32_t* a, int hops, uint32_t* out) { out[0] = chase<false>(a, hops); }

// Latency of an atomic whose old value is used (ATOMG, waited for; an atomic whose value
// is unused compiles to RED, which is not): one thread, each atomic's address the value
// the previous one returned. Adding 0 keeps the chain.
__global__ void chase_atomic(uint32_t* a, int hops, uint32_t* out) {
    uint32_t i = 0;
    for (int h = 0; h < hops; ++h) i = atomicAdd(&a[i], 0u);
    out[0] = i;
}

// Latency of __threadfence() (MEMBAR.SC.GPU on sm_90): one thread stores a word and
// fences, again and again (the fence waits for the store to reach L2); and fences with
// no store before it.
__global__ void fence_store(uint32_t* a, int iters) {
    for (int k = 0; k < iters; ++k) {
        a[k & 2047] = k;
        __threadfence();
    }
}
// Fence throughput: every thread of a full grid stores its own word and fences, again
// and again.
__global__ void fence_many(uint32_t* a, int iters) {
    uint32_t i = blockIdx.x * blockDim.x + threadIdx.x;
    for (int k = 0; k < iters; ++k) {
        a[i] = k;
        __threadfence();
    }
}
// Fences after scattered stores: each lane stores three 8-byte values, each in a sector
// of its own (lanes 192 bytes apart), then fences: 96 sectors outstanding per warp
// fence. One warp alone (the latency), and every SM full (the rate).
__device__ void scattered_then_fence(uint2* a, int iters) {
    uint32_t t = blockIdx.x * blockDim.x + threadIdx.x;
    for (int k = 0; k < iters; ++k) {
        for (int j = 0; j < 3; ++j) a[(t * 3 + j) * 8] = make_uint2(k, j);
        __threadfence();
    }
}
__global__ void fence_scattered_warp(uint2* a, int iters) { scattered_then_fence(a, iters); }
__global__ void fence_scattered_many(uint2* a, int iters) { scattered_then_fence(a, iters); }
// Fences under load (`microbench fencemix`): every SM full (8 blocks of 256 threads),
// each lane storing, then fencing, again and again, by what its warp's fence waits for.
// Lanes STRIDE 8-byte words apart (1: a warp's store fills two 128-byte lines; 4: a
// sector a lane, four lanes a line; 16: a line a lane), STORES such stores a lane
// before each fence, ACTIVE lanes of each 32 storing and fencing (the rest return);
// FRESH: each pass writes memory no pass wrote before (first touches in L2; Nsight
// flushes the caches before each launch), else the same words again.
template <int STRIDE, int STORES, int ACTIVE, bool FRESH>
__device__ void fence_mix(uint2* a, int iters) {
    const size_t t = blockIdx.x * (size_t)blockDim.x + threadIdx.x;
    const size_t threads = (size_t)gridDim.x * blockDim.x;
    if ((int)(threadIdx.x & 31) >= ACTIVE) return;
    for (int k = 0; k < iters; ++k) {
        const size_t base = FRESH ? (size_t)k * STORES * threads * STRIDE : 0;
        for (int j = 0; j < STORES; ++j) a[base + ((size_t)j * threads + t) * STRIDE] = make_uint2(k, j);
        __threadfence();
    }
}
// One kernel a form, so that each has a name of its own in Nsight's report.
__global__ void fence_mix_1_line(uint2* a, int n) { fence_mix<4, 1, 4, false>(a, n); }
__global__ void fence_mix_2_lines(uint2* a, int n) { fence_mix<1, 1, 32, false>(a, n); }
__global__ void fence_mix_3_lines(uint2* a, int n) { fence_mix<4, 3, 4, false>(a, n); }
__global__ void fence_mix_8_lines(uint2* a, int n) { fence_mix<4, 1, 32, false>(a, n); }
__global__ void fence_mix_24_lines(uint2* a, int n) { fence_mix<4, 3, 32, false>(a, n); }
__global__ void fence_mix_32_lines(uint2* a, int n) { fence_mix<16, 1, 32, false>(a, n); }
__global__ void fence_mix_96_lines(uint2* a, int n) { fence_mix<16, 3, 32, false>(a, n); }
__global__ void fence_mix_4_lines(uint2* a, int n) { fence_mix<16, 1, 4, false>(a, n); }
__global__ void fence_mix_4_lines_16_sectors(uint2* a, int n) { fence_mix<4, 1, 16, false>(a, n); }
__global__ void fence_mix_8_lines_8_sectors(uint2* a, int n) { fence_mix<16, 1, 8, false>(a, n); }
__global__ void fence_mix_8_lines_16_sectors(uint2* a, int n) { fence_mix<8, 1, 16, false>(a, n); }
__global__ void fence_mix_12_lines(uint2* a, int n) { fence_mix<16, 1, 12, false>(a, n); }
__global__ void fence_mix_3_lines_fresh(uint2* a, int n) { fence_mix<4, 3, 4, true>(a, n); }
__global__ void fence_mix_8_lines_fresh(uint2* a, int n) { fence_mix<4, 1, 32, true>(a, n); }
// The climb of a BVH's fit without its tree: each lane, level after level, stores a
// 24-byte box into a node picked at random from `nodes` 64-byte nodes, fences, adds one
// to the node's arrival count (its old value used), fences, and reads the node's other
// box past L1, as `fit_boxes` in cuda/bvh.cu does at each level; every lane climbs all
// the levels. ATOMIC and READ false leave the atomic or the read out (the fences stay).
template <bool ATOMIC, bool READ>
__device__ void climb(float* nodes, uint32_t* arrivals, int levels, uint32_t n_nodes, uint32_t* out) {
    const uint32_t t = blockIdx.x * blockDim.x + threadIdx.x;
    uint32_t acc = 0;
    float sum = 0.f;
    for (int l = 0; l < levels; ++l) {
        const uint32_t p = (t * 2654435761u + (uint32_t)l * 40503u) % n_nodes;
        float2* box = (float2*)(nodes + (size_t)p * 16);
        box[0] = make_float2((float)l, (float)t);
        box[1] = make_float2((float)t, (float)l);
        box[2] = make_float2(1.f, 2.f);
        __threadfence();
        if (ATOMIC) acc += atomicAdd(&arrivals[p], 1u);
        __threadfence();
        if (READ) {
            const volatile float* o = nodes + (size_t)p * 16 + 8;
            sum += o[0] + o[1] + o[2] + o[3] + o[4] + o[5];
        }
    }
    if (acc == 0xffffffffu && sum == 1.f) out[0] = acc;
}
__global__ void fence_climb(float* nodes, uint32_t* arrivals, int levels, uint32_t n_nodes, uint32_t* out) {
    climb<true, true>(nodes, arrivals, levels, n_nodes, out);
}
__global__ void fence_climb_no_read(float* nodes, uint32_t* arrivals, int levels, uint32_t n_nodes, uint32_t* out) {
    climb<true, false>(nodes, arrivals, levels, n_nodes, out);
}
__global__ void fence_climb_stores(float* nodes, uint32_t* arrivals, int levels, uint32_t n_nodes, uint32_t* out) {
    climb<false, false>(nodes, arrivals, levels, n_nodes, out);
}
__global__ void fence_alone(uint32_t* a, int iters) {
    uint32_t x = 0;
    for (int k = 0; k < iters; ++k) {
        x = x * 1664525u + 1013904223u;
        __threadfence();
    }
    a[0] = x;
}

// Atomic throughput: every lane adds to its own word (coalesced), or every thread of the
// grid to one word.
__global__ void atomic_distinct(uint32_t* a, uint32_t words, int iters) {
    uint32_t i = (blockIdx.x * blockDim.x + threadIdx.x) % words;
    for (int k = 0; k < iters; ++k) atomicAdd(&a[i], 1u);
}
__global__ void atomic_same(uint32_t* a, int iters) {
    for (int k = 0; k < iters; ++k) atomicAdd(&a[0], 1u);
}

// Shared memory: loads and stores of a block's own words (no bank conflicts).
__global__ void shared_rw(float* out, int iters) {
    __shared__ float s[1024];
    for (int i = threadIdx.x; i < 1024; i += blockDim.x) s[i] = i;
    __syncthreads();
    float acc = 0;
    int j = threadIdx.x;
    for (int k = 0; k < iters; ++k) {
        acc += s[j];
        s[(j + 32) & 1023] = acc;
        j = (j + 64) & 1023;
    }
    if (acc == 12345.0f) out[threadIdx.x] = acc;
}

// Barriers: a loop of __syncthreads() in blocks of 256 threads.
__global__ void barrier(float* out, int iters) {
    __shared__ float s[256];
    float acc = threadIdx.x;
    for (int k = 0; k < iters; ++k) {
        s[threadIdx.x] = acc;
        __syncthreads();
        acc += s[255 - threadIdx.x];
        __syncthreads();
    }
    if (acc == 12345.0f) out[threadIdx.x] = acc;
}


// Rounds of loads issued together: each thread follows its own chain through records
// of 9 words (36 bytes, a triangle's size), loading `W` words of the current record
// back to back (one load instruction each, none waiting for another) and summing them
// into the next record's index. `cg` keeps the loads out of L1, as in the L2 chase;
// the records (4,096, 144 KiB) stay in L2. The chase's cycles are read with clock64
// after `warm` steps, so the first touches (from HBM) are left out. One thread
// (`W` requests of one sector), one warp of scattered lanes (`W` requests of about 32
// sectors each), and 8 or 64 such warps on every SM.
template <int W, uint32_t MASK = 4095u, bool CG = true>
__device__ uint32_t round_chase(const uint32_t* a, int warm, int steps, long long* cycles) {
    uint32_t t = blockIdx.x * blockDim.x + threadIdx.x;
    uint32_t r = (t * 2654435761u) & MASK;
    long long t0 = 0;
    for (int s = 0; s < warm + steps; ++s) {
        if (s == warm) t0 = clock64();
        const uint32_t* p = a + r * 9;
        uint32_t v[W];
#pragma unroll
        for (int w = 0; w < W; ++w) v[w] = CG ? __ldcg(&p[w]) : p[w];
        uint32_t sum = 0;
#pragma unroll
        for (int w = 0; w < W; ++w) sum ^= v[w];
        r = (r * 1664525u + sum) & MASK;
    }
    if (t == 0) cycles[0] = clock64() - t0;
    return r;
}
__global__ void round_lane_1(const uint32_t* a, int warm, int steps, long long* c, uint32_t* out) { out[1 + threadIdx.x] = round_chase<1>(a, warm, steps, c); }
__global__ void round_lane_9(const uint32_t* a, int warm, int steps, long long* c, uint32_t* out) { out[1 + threadIdx.x] = round_chase<9>(a, warm, steps, c); }
__global__ void round_warp_1(const uint32_t* a, int warm, int steps, long long* c, uint32_t* out) { out[1 + threadIdx.x] = round_chase<1>(a, warm, steps, c); }
__global__ void round_warp_9(const uint32_t* a, int warm, int steps, long long* c, uint32_t* out) { out[1 + threadIdx.x] = round_chase<9>(a, warm, steps, c); }
__global__ void round_sm_9(const uint32_t* a, int warm, int steps, long long* c, uint32_t* out) { out[1 + (threadIdx.x & 255)] = round_chase<9>(a, warm, steps, c); }
__global__ void round_full_9(const uint32_t* a, int warm, int steps, long long* c, uint32_t* out) { out[1 + (threadIdx.x & 255)] = round_chase<9>(a, warm, steps, c); }
__global__ void round_sm_9_wide(const uint32_t* a, int warm, int steps, long long* c, uint32_t* out) { out[1 + (threadIdx.x & 255)] = round_chase<9, (1u << 20) - 1>(a, warm, steps, c); }
__global__ void round_full_9_wide(const uint32_t* a, int warm, int steps, long long* c, uint32_t* out) { out[1 + (threadIdx.x & 255)] = round_chase<9, (1u << 20) - 1>(a, warm, steps, c); }
__global__ void round_sm_1_wide(const uint32_t* a, int warm, int steps, long long* c, uint32_t* out) { out[1 + (threadIdx.x & 255)] = round_chase<1, (1u << 20) - 1>(a, warm, steps, c); }
// One thread chasing a chain that steps 33 words (a new 128-byte line each hop) over
// 2 MiB: past L1, within L2. With the kernels' default caching (`ca`: each load misses
// L1, which allocates) and with `cg`, timed with clock64 after a warm-up pass.
template <bool CG>
__device__ uint32_t chase_timed(const uint32_t* a, int warm, int hops, long long* cycles) {
    uint32_t i = 0;
    long long t0 = 0;
    for (int h = 0; h < warm + hops; ++h) {
        if (h == warm) t0 = clock64();
        i = CG ? __ldcg(&a[i]) : a[i];
    }
    cycles[0] = clock64() - t0;
    return i;
}
__global__ void chase_l2_ca(const uint32_t* a, int warm, int hops, long long* c, uint32_t* out) { out[0] = chase_timed<false>(a, warm, hops, c); }
__global__ void chase_l2_cg(const uint32_t* a, int warm, int hops, long long* c, uint32_t* out) { out[0] = chase_timed<true>(a, warm, hops, c); }

// The same with the kernels' default caching (L1 allocates): 65,536 records (2.4 MB,
// past L1, in L2) for one thread and for one warp.
__global__ void round_lane_1_ca(const uint32_t* a, int warm, int steps, long long* c, uint32_t* out) { out[1 + threadIdx.x] = round_chase<1, 65535u, false>(a, warm, steps, c); }
__global__ void round_lane_9_ca(const uint32_t* a, int warm, int steps, long long* c, uint32_t* out) { out[1 + threadIdx.x] = round_chase<9, 65535u, false>(a, warm, steps, c); }
__global__ void round_warp_9_ca(const uint32_t* a, int warm, int steps, long long* c, uint32_t* out) { out[1 + threadIdx.x] = round_chase<9, 65535u, false>(a, warm, steps, c); }
__global__ void round_lane_1_cg(const uint32_t* a, int warm, int steps, long long* c, uint32_t* out) { out[1 + threadIdx.x] = round_chase<1, 65535u, true>(a, warm, steps, c); }
__global__ void round_full_1_wide(const uint32_t* a, int warm, int steps, long long* c, uint32_t* out) { out[1 + (threadIdx.x & 255)] = round_chase<1, (1u << 20) - 1>(a, warm, steps, c); }

// The start of a short kernel (`microbench start`): what a launch costs beyond the empty
// kernel's when it stores, reads its parameters, or runs code the SM has not cached.
// One warp each. `start_store`: every lane stores a word (the store drains before the
// kernel ends). `start_params`: eight pointer parameters read (constant-bank loads, cold
// after the previous kernel), one word stored. `start_code<N>`: a dependent chain of N
// multiply-adds in straight-line code (N·16 bytes of instructions, each fetched once),
// against `start_loop`: the same N in a loop of 64 (the loop's body fetched once).
__global__ void start_store(uint32_t* a) { a[threadIdx.x] = threadIdx.x; }
// The grid probes: a word stored, or read and stored, by every thread of a grid.
__global__ void grid_store(uint32_t* a) { a[blockIdx.x * blockDim.x + threadIdx.x] = threadIdx.x; }
__global__ void grid_copy(const uint32_t* __restrict__ b, uint32_t* a) {
    const unsigned i = blockIdx.x * blockDim.x + threadIdx.x;
    a[i] = b[i] + 1u;
}
__global__ void start_params(uint32_t* a, const uint32_t* p1, const uint32_t* p2, const uint32_t* p3,
                             const uint32_t* p4, const uint32_t* p5, const uint32_t* p6, const uint32_t* p7) {
    uintptr_t x = (uintptr_t)p1 ^ (uintptr_t)p2 ^ (uintptr_t)p3 ^ (uintptr_t)p4 ^ (uintptr_t)p5 ^ (uintptr_t)p6 ^
                  (uintptr_t)p7;
    a[threadIdx.x] = (uint32_t)x;
}
template <int N>
__global__ void start_code(float* out, float m, float b) {
    float x = threadIdx.x;
#pragma unroll
    for (int i = 0; i < N; ++i) x = x * m + b;
    out[threadIdx.x] = x;
}
template <int N>
__global__ void start_loop(float* out, float m, float b) {
    float x = threadIdx.x;
    for (int i = 0; i < N / 64; ++i) {
#pragma unroll
        for (int k = 0; k < 64; ++k) x = x * m + b;
    }
    out[threadIdx.x] = x;
}

// HBM read at random (`microbench hbm`): every thread of a full grid reads 32-byte
// records (one sector each, 8 words, loaded word by word as PDACRT loads a ray) at
// random over 1 GiB, caches cold: the DRAM bandwidth of scattered sectors, against
// `hbm_read`'s streaming one. `hbm_random_word`: one 4-byte word per random sector.
__global__ void hbm_random_sector(const uint32_t* __restrict__ a, uint32_t mask, int iters, uint32_t* out) {
    uint32_t h = (blockIdx.x * blockDim.x + threadIdx.x) * 2654435761u + 12345u, s = 0;
    for (int i = 0; i < iters; ++i) {
        h = h * 1664525u + 1013904223u;
        const uint32_t* p = a + (size_t)((h >> 2) & mask) * 8;
#pragma unroll
        for (int w = 0; w < 8; ++w) s += p[w];
    }
    if (s == 12345u) out[0] = s;
}
__global__ void hbm_random_word(const uint32_t* __restrict__ a, uint32_t mask, int iters, uint32_t* out) {
    uint32_t h = (blockIdx.x * blockDim.x + threadIdx.x) * 2654435761u + 12345u, s = 0;
    for (int i = 0; i < iters; ++i) {
        h = h * 1664525u + 1013904223u;
        s += a[(size_t)((h >> 2) & mask) * 8];
    }
    if (s == 12345u) out[0] = s;
}

// Instruction fetch shared by an SM's warps (`microbench icache`): one block a SM of W
// warps, each running passes over K pieces of code, every piece its own dependent chain
// of 256 multiply-adds (4 KiB of instructions, called, not inlined); warp w starts at
// piece w mod K, so the warps of an SM run different code at once, as the warps of a
// large kernel do. The code they share is K · 4 KiB; cycles per instruction a warp
// (clock64 of each block's thread 0 over the instructions its warp ran) against K = 1
// tell what fetching instructions costs when that code does not stay cached.
template <int J>
__device__ __noinline__ float icache_piece(float x, float m, float b) {
    const float c = b + (float)J;
#pragma unroll
    for (int i = 0; i < 256; ++i) x = x * m + c;
    return x;
}
template <int LO, int HI>
__device__ __forceinline__ float icache_call(int k, float x, float m, float b) {
    if constexpr (HI - LO == 1) {
        return icache_piece<LO>(x, m, b);
    } else {
        constexpr int MID = (LO + HI) / 2;
        return k < MID ? icache_call<LO, MID>(k, x, m, b) : icache_call<MID, HI>(k, x, m, b);
    }
}
template <int K>
__global__ void icache(float* out, float m, float b, int passes, long long* cycles) {
    float x = threadIdx.x;
    const int w = threadIdx.x / 32;
    const long long start = clock64();
    for (int p = 0; p < passes; ++p)
        for (int s = 0; s < K; ++s) x = icache_call<0, K>((s + w) % K, x, m, b);
    const long long end = clock64();
    out[blockIdx.x * blockDim.x + threadIdx.x] = x;
    if (threadIdx.x == 0) cycles[blockIdx.x] = end - start;
}


// The same with jumps (`microbench icache`, rows `icache_jump`): K pieces of 16
// multiply-adds each, inlined at the leaves of a binary tree of branches on the piece's
// number; every warp runs pieces in its own pseudo-random order (the same for its
// lanes), as the warps of a branchy kernel jump about its code. nvcc 13 shares the
// leaves' chain (they differ in a constant), so the code is mostly the tree: 1.9 KiB
// for 16 pieces, 20 KiB for 256, 77 KiB for 1,024, 153 KiB for 2,048 (sm_90). Cycles
// per piece a warp (clock64, as above).
template <int J>
__device__ __forceinline__ float jump_piece(float x, float m, float b) {
    const float c = b + (float)J;
#pragma unroll
    for (int i = 0; i < 16; ++i) x = x * m + c;
    return x;
}
template <int LO, int HI>
__device__ __forceinline__ float jump_call(int k, float x, float m, float b) {
    if constexpr (HI - LO == 1) {
        return jump_piece<LO>(x, m, b);
    } else {
        constexpr int MID = (LO + HI) / 2;
        return k < MID ? jump_call<LO, MID>(k, x, m, b) : jump_call<MID, HI>(k, x, m, b);
    }
}
template <int K>
__global__ void icache_jump(float* out, float m, float b, int pieces, long long* cycles) {
    float x = threadIdx.x;
    uint32_t h = (threadIdx.x / 32 + 1) * 2654435761u + blockIdx.x;
    const long long start = clock64();
    for (int p = 0; p < pieces; ++p) {
        h = h * 1664525u + 1013904223u;
        x = jump_call<0, K>((int)((h >> 8) % K), x, m, b);
    }
    const long long end = clock64();
    out[blockIdx.x * blockDim.x + threadIdx.x] = x;
    if (threadIdx.x == 0) cycles[blockIdx.x] = end - start;
}

// First touches in order (`microbench stream`): each lane follows its own chain through
// a fresh buffer, every load's address the value the previous one returned, so each
// step is one waited-for load, as in the HBM chase; only the chain's layout differs.
// `stream_lane`: one thread stepping a sector at a time (a new sector each step, the
// next one in memory); `stream_line`: one warp stepping a 128-byte line at a time, its
// lanes' words of one line per step (a coalesced request of four new sectors, the next
// line in memory); `stream_far`: the same warp stepping 8,320 bytes (a new DRAM page a
// step, as the HBM chase); `stream_sm`: one such sequential warp a SM, each in its own
// part of the buffer.
__global__ void stream_chase(const uint32_t* __restrict__ a, int steps, uint32_t* out) {
    uint32_t i = blockIdx.x * (uint32_t)steps * 32u + threadIdx.x;
    for (int s = 0; s < steps; ++s) i = __ldcg(&a[i]);
    if (i == 12345u) out[0] = i;
}


// Shared-memory latency (`microbench shared`): one thread chases indices through a block's
// shared words (each load's address is the load before it), timed by clock64 after a
// warm-up; and a block's barrier in a loop whose every trip stores a word, waits at the
// barrier and loads a neighbour's word (the dependent step a tile's scan takes).
__global__ void shared_chain(int warm, int hops, long long* cycles, uint32_t* out) {
    __shared__ uint32_t s[4096];
    for (int i = threadIdx.x; i < 4096; i += blockDim.x) s[i] = (uint32_t)((i + 33) & 4095);
    __syncthreads();
    uint32_t j = 0;
    long long t0 = 0;
    for (int k = 0; k < warm + hops; ++k) {
        if (k == warm) t0 = clock64();
        j = s[j];
    }
    if (threadIdx.x == 0) cycles[0] = clock64() - t0;
    out[threadIdx.x] = j;
}
__global__ void barrier_chain(int warm, int rounds, long long* cycles, uint32_t* out) {
    __shared__ uint32_t s[1024];
    uint32_t v = threadIdx.x;
    long long t0 = 0;
    for (int k = 0; k < warm + rounds; ++k) {
        if (k == warm) t0 = clock64();
        s[threadIdx.x] = v;
        __syncthreads();
        v += s[(threadIdx.x + 1) % blockDim.x];
        __syncthreads();
    }
    if (threadIdx.x == 0) cycles[0] = clock64() - t0;
    out[threadIdx.x] = v;
}
}  // namespace micro

// A chain over `n` words whose next index is `stride` words on (mod n): every hop
// a new sector, and for the HBM chase a new DRAM page.
static std::vector<uint32_t> chain(size_t n, size_t stride) {
    std::vector<uint32_t> v(n);
    for (size_t i = 0; i < n; ++i) v[i] = (uint32_t)((i + stride) % n);
    return v;
}

// The atomic-latency and fence probes: part of every run, and alone (`microbench
// fences`) to add these quantities to a profile calibrated from an earlier full run.
static int atomic_and_fence_probes(int sms) {
    uint32_t *buf, *out, *words;
    uint2* scattered;
    const int full_grid = sms * 8, threads = 256, many_iters = 256;
    CHECK(cudaMalloc(&words, (size_t)full_grid * threads * 4));
    CHECK(cudaMalloc(&scattered, (size_t)full_grid * threads * 24 * sizeof(uint2)));
    CHECK(cudaMalloc(&buf, 8 << 10));
    CHECK(cudaMalloc(&out, 64));
    const int hops = 200000, iters = 100000;
    // The same 8 KiB chain as the L2 chase: 2,048 words, each naming the one 33 on.
    std::vector<uint32_t> v(2048);
    for (size_t i = 0; i < v.size(); ++i) v[i] = (uint32_t)((i + 33) % v.size());
    CHECK(cudaMemcpy(buf, v.data(), v.size() * 4, cudaMemcpyHostToDevice));
    for (int r = 0; r < PROBE_LAUNCHES; ++r) micro::chase_atomic<<<1, 1>>>(buf, hops, out);
    CHECK(cudaDeviceSynchronize());
    for (int r = 0; r < PROBE_LAUNCHES; ++r) {
        micro::fence_store<<<1, 1>>>(buf, iters);  // 2,048 words, as it indexes
        micro::fence_alone<<<1, 1>>>(out, iters);
        micro::fence_many<<<full_grid, threads>>>(words, many_iters);
        micro::fence_scattered_warp<<<1, 32>>>(scattered, iters / 10);
        micro::fence_scattered_many<<<full_grid, threads>>>(scattered, many_iters);
    }
    CHECK(cudaDeviceSynchronize());
    printf("probe\tchase_atomic\thops\t%d\n", hops);
    printf("probe\tfence_store\tfences\t%d\n", iters);
    printf("probe\tfence_alone\tfences\t%d\n", iters);
    printf("probe\tfence_many\twarp_fences\t%lld\n", (long long)full_grid * (threads / 32) * many_iters);
    printf("probe\tfence_scattered_warp\tfences\t%d\n", iters / 10);
    printf("probe\tfence_scattered_many\twarp_fences\t%lld\n", (long long)full_grid * (threads / 32) * many_iters);
    cudaFree(scattered);
    cudaFree(words);
    cudaFree(buf);
    cudaFree(out);
    return 0;
}

// The fences-under-load probes (`microbench fencemix`): `fence_mix` by the 128-byte lines
// (and sectors) a fence waits for, 1 to 96, lanes active, and first touches;
// `fence_climb` over nodes that fit L2 (16 MiB) and that do not (256 MiB). Each line
// gives the warp fences and the sectors and lines they wait for (stored since the
// warp's last fence, counted per store instruction).
static int fence_mix_probes(int sms) {
    const int grid = sms * 8, threads = 256, hot_iters = 64, fresh_iters = 16, levels = 16;
    const size_t lanes = (size_t)grid * threads;
    uint2* a;
    CHECK(cudaMalloc(&a, lanes * 16 * 3 * sizeof(uint2) + lanes * 4 * 3 * fresh_iters * sizeof(uint2)));
    struct Mix {
        const char* name;
        void (*kernel)(uint2*, int);
        int stride, stores, active;
        bool fresh;
    } mixes[] = {
        {"fence_mix_1_line", micro::fence_mix_1_line, 4, 1, 4, false},
        {"fence_mix_2_lines", micro::fence_mix_2_lines, 1, 1, 32, false},
        {"fence_mix_3_lines", micro::fence_mix_3_lines, 4, 3, 4, false},
        {"fence_mix_8_lines", micro::fence_mix_8_lines, 4, 1, 32, false},
        {"fence_mix_24_lines", micro::fence_mix_24_lines, 4, 3, 32, false},
        {"fence_mix_32_lines", micro::fence_mix_32_lines, 16, 1, 32, false},
        {"fence_mix_96_lines", micro::fence_mix_96_lines, 16, 3, 32, false},
        {"fence_mix_4_lines", micro::fence_mix_4_lines, 16, 1, 4, false},
        {"fence_mix_4_lines_16_sectors", micro::fence_mix_4_lines_16_sectors, 4, 1, 16, false},
        {"fence_mix_8_lines_8_sectors", micro::fence_mix_8_lines_8_sectors, 16, 1, 8, false},
        {"fence_mix_8_lines_16_sectors", micro::fence_mix_8_lines_16_sectors, 8, 1, 16, false},
        {"fence_mix_12_lines", micro::fence_mix_12_lines, 16, 1, 12, false},
        {"fence_mix_3_lines_fresh", micro::fence_mix_3_lines_fresh, 4, 3, 4, true},
        {"fence_mix_8_lines_fresh", micro::fence_mix_8_lines_fresh, 4, 1, 32, true},
    };
    for (auto& m : mixes) {
        const int iters = m.fresh ? fresh_iters : hot_iters;
        for (int r = 0; r < PROBE_LAUNCHES; ++r) m.kernel<<<grid, threads>>>(a, iters);
        CHECK(cudaDeviceSynchronize());
        const long long warp_fences = (long long)grid * (threads / 32) * iters;
        const int bytes = m.active * m.stride * 8;  // a store instruction's span
        const int sectors = m.stride == 1 ? (bytes + 31) / 32 : m.active;
        const int lines = (bytes + 127) / 128;
        printf("probe\t%s\twarp_fences\t%lld\n", m.name, warp_fences);
        printf("probe\t%s\tfenced_sectors\t%lld\n", m.name, warp_fences * sectors * m.stores);
        printf("probe\t%s\tfenced_lines\t%lld\n", m.name, warp_fences * lines * m.stores);
    }
    float* nodes;
    uint32_t *arrivals, *out;
    const uint32_t sizes[] = {1u << 18, 1u << 22};
    CHECK(cudaMalloc(&nodes, (size_t)sizes[1] * 64));
    CHECK(cudaMalloc(&arrivals, (size_t)sizes[1] * 4));
    CHECK(cudaMalloc(&out, 64));
    CHECK(cudaMemset(nodes, 0, (size_t)sizes[1] * 64));
    const long long warp_fences = 2LL * grid * (threads / 32) * levels;
    for (uint32_t n : sizes) {
        for (int r = 0; r < PROBE_LAUNCHES; ++r) micro::fence_climb<<<grid, threads>>>(nodes, arrivals, levels, n, out);
        CHECK(cudaDeviceSynchronize());
        const char* name = n == sizes[0] ? "fence_climb_16_mib" : "fence_climb_256_mib";
        printf("probe\t%s\twarp_fences\t%lld\n", name, warp_fences);
        printf("probe\t%s\tatomic_lanes\t%lld\n", name, (long long)lanes * levels);
    }
    // The 16 MiB climb less its read, then less its atomic too.
    for (int r = 0; r < PROBE_LAUNCHES; ++r) {
        micro::fence_climb_no_read<<<grid, threads>>>(nodes, arrivals, levels, sizes[0], out);
        micro::fence_climb_stores<<<grid, threads>>>(nodes, arrivals, levels, sizes[0], out);
    }
    CHECK(cudaDeviceSynchronize());
    printf("probe\tfence_climb_no_read_16_mib\twarp_fences\t%lld\n", warp_fences);
    printf("probe\tfence_climb_stores_16_mib\twarp_fences\t%lld\n", warp_fences);
    cudaFree(a);
    cudaFree(nodes);
    cudaFree(arrivals);
    cudaFree(out);
    return 0;
}

// The random HBM probes (`microbench hbm`): each touches 2^22 random sectors of a 1 GiB
// buffer per launch (about 1 in 8 of them twice), caches cold under Nsight.
static int hbm_probes(int sms) {
    uint32_t *a, *out;
    const size_t bytes = (size_t)1 << 30;
    CHECK(cudaMalloc(&a, bytes));
    CHECK(cudaMemset(a, 1, bytes));
    CHECK(cudaMalloc(&out, 64));
    const uint32_t mask = (uint32_t)(bytes / 32 - 1);
    const int threads = 256, grid = sms * 8, iters = 16;
    for (int r = 0; r < PROBE_LAUNCHES; ++r) {
        micro::hbm_random_sector<<<grid, threads>>>(a, mask, iters, out);
        micro::hbm_random_word<<<grid, threads>>>(a, mask, iters, out);
    }
    CHECK(cudaDeviceSynchronize());
    printf("probe\thbm_random_sector\tsectors\t%lld\n", (long long)grid * threads * iters);
    printf("probe\thbm_random_word\tsectors\t%lld\n", (long long)grid * threads * iters);
    cudaFree(a);
    cudaFree(out);
    return 0;
}

// The first-touches-in-order probes (`microbench stream`), each launch on a buffer just
// written by the host (Nsight flushes the caches before each kernel); ncu's durations
// over the steps are the latencies.
static int stream_probes(int sms) {
    const int steps = 20000;
    // Enough for the widest form: a warp a SM (steps lines each) or 2,080 words a step.
    const size_t words = std::max((size_t)sms * steps * 32, (size_t)steps * 2080) + 64;
    uint32_t *a, *out;
    CHECK(cudaMalloc(&a, words * 4));
    CHECK(cudaMalloc(&out, 64));
    struct Form {
        const char* name;
        size_t stride;  // words from a lane's word to its next
        int blocks, threads;
    } forms[] = {{"stream_lane", 8, 1, 1}, {"stream_line", 32, 1, 32}, {"stream_far", 2080, 1, 32}, {"stream_sm", 32, sms, 32}};
    std::vector<uint32_t> v(words);
    for (auto& f : forms) {
        // Block b's lanes start at b * steps * 32 (+ lane); each word names the one
        // `stride` on.
        for (size_t k = 0; k < words; ++k) v[k] = (uint32_t)std::min(k + f.stride, words - 1);
        for (int r = 0; r < PROBE_LAUNCHES; ++r) {
            CHECK(cudaMemcpy(a, v.data(), words * 4, cudaMemcpyHostToDevice));
            micro::stream_chase<<<f.blocks, f.threads>>>(a, steps, out);
            CHECK(cudaDeviceSynchronize());
        }
        printf("probe\t%s\tsteps\t%d\n", f.name, steps);
    }
    cudaFree(a);
    cudaFree(out);
    return 0;
}

// The start probes (`microbench start`), each launched PROBE_LAUNCHES times between
// empty kernels; ncu's durations are what they measure.
static int start_probes() {
    uint32_t* a;
    float* f;
    CHECK(cudaMalloc(&a, 4096));
    CHECK(cudaMalloc(&f, 4096));
    for (int r = 0; r < PROBE_LAUNCHES; ++r) {
        micro::empty<<<1, 32>>>();
        micro::start_store<<<1, 32>>>(a);
        micro::start_params<<<1, 32>>>(a, a + 1, a + 2, a + 3, a + 4, a + 5, a + 6, a + 7);
        micro::start_code<256><<<1, 32>>>(f, 1.0001f, 0.5f);
        micro::start_loop<256><<<1, 32>>>(f, 1.0001f, 0.5f);
        micro::start_code<2048><<<1, 32>>>(f, 1.0001f, 0.5f);
        micro::start_loop<2048><<<1, 32>>>(f, 1.0001f, 0.5f);
        micro::start_code<8192><<<1, 32>>>(f, 1.0001f, 0.5f);
        micro::start_loop<8192><<<1, 32>>>(f, 1.0001f, 0.5f);
    }
    CHECK(cudaDeviceSynchronize());
    for (const char* n : {"empty", "start_store", "start_params"}) printf("probe\t%s\tblocks\t1\n", n);
    for (int n : {256, 2048, 8192}) {
        printf("probe\tstart_code<%d>\tdependent_fma\t%d\n", n, n);
        printf("probe\tstart_loop<%d>\tdependent_fma\t%d\n", n, n);
    }
    cudaFree(a);
    cudaFree(f);
    return 0;
}

// The grid probes (`microbench grid`): what a short kernel costs by the blocks it has,
// from one block to four a SM: empty, a word stored a thread, a word read and stored.
static int grid_probes(int sms) {
    const int grids[] = {1, 2, 3, 4, 8, 16, 33, 66, 132, 264, 528};
    const size_t words = (size_t)4 * sms * 256;
    uint32_t *a, *b;
    CHECK(cudaMalloc(&a, words * 4));
    CHECK(cudaMalloc(&b, words * 4));
    CHECK(cudaMemset(b, 0, words * 4));
    for (int g : grids) {
        const int blocks = g > 4 ? g * sms / 132 : g;
        for (int r = 0; r < PROBE_LAUNCHES; ++r) {
            micro::empty<<<blocks, 256>>>();
            micro::grid_store<<<blocks, 256>>>(a);
            micro::grid_copy<<<blocks, 256>>>(b, a);
        }
    }
    CHECK(cudaDeviceSynchronize());
    for (int g : grids) {
        const int blocks = g > 4 ? g * sms / 132 : g;
        for (const char* n : {"empty", "grid_store", "grid_copy"}) printf("probe\t%s\tblocks\t%d\n", n, blocks);
    }
    cudaFree(a);
    cudaFree(b);
    return 0;
}

// The slot probes (`microbench slots`): does a block hold its SM's slot until its
// slowest warp ends? Four waves of blocks of 256 threads whose warps sleep (no issue,
// no memory): every warp for `naps` naps of 1 µs; one warp a block for that long and
// the other seven not at all; no warp at all. If an ended warp's slot went to the next
// block, the second would take about an eighth of the first.
__global__ void slots_sleep(int naps, int sleepers) {
    if ((int)(threadIdx.x / 32) >= sleepers) return;
    for (int k = 0; k < naps; ++k) __nanosleep(1000);
}
static int slot_probes(int sms) {
    const int blocks = 4 * 8 * sms, naps = 20;
    const struct {
        const char* name;
        int sleepers;
    } forms[] = {{"slots_every_warp_sleeps", 8}, {"slots_one_warp_a_block_sleeps", 1}, {"slots_no_warp_sleeps", 0}};
    for (const auto& f : forms) {
        for (int r = 0; r < PROBE_LAUNCHES; ++r) slots_sleep<<<blocks, 256>>>(naps, f.sleepers);
        CHECK(cudaDeviceSynchronize());
        printf("probe\t%s\tblocks\t%d\n", f.name, blocks);
        printf("probe\t%s\tsleeping_warps_a_block\t%d\n", f.name, f.sleepers);
        printf("probe\t%s\tnaps_of_1_us\t%d\n", f.name, naps);
    }
    return 0;
}

// The overlap probes (`microbench overlap`): how a memory bound and an arithmetic bound
// combine. Two shapes, each with the loads alone, the arithmetic alone and both:
//
// - free-running: one wave of 512-thread blocks filling every SM (64 warps), streaming
//   8 MiB from L2 (`ld.global.cg`, as `l2_read`) 64 times, each 16-byte load followed by
//   `ALU` rounds of `alu_mix`'s body (4 multiply-adds and 4 integer steps) on its value;
//   the warps drift apart, so one warp's loads can hide under another's arithmetic;
// - phased: `B` blocks of 384 threads a SM (as CUB's sort passes), each alternating a
//   load phase (8 independent 16-byte L2 loads a thread, one round) and an arithmetic
//   phase, with a barrier after each, so a block's warps are all in one phase at once.
//
// Where the two alone take equal times, perfect overlap gives their larger, none their
// sum. With LOAD false the loaded value is replaced by a register; the forms `none`
// (neither loads nor arithmetic rounds) time what the loop and the barriers cost alone.
template <int ALU>
__device__ __forceinline__ void overlap_rounds(float (&f)[4], uint32_t (&u)[4], float y) {
#pragma unroll
    for (int j = 0; j < ALU; ++j) {
#pragma unroll
        for (int k = 0; k < 4; ++k) {
            f[k] = fmaf(f[k], 0.9999f, y);
            u[k] = (u[k] ^ (u[k] >> 7)) + 0x9e3779b9u;
        }
    }
}
template <int ALU, bool LOAD>
__global__ void __launch_bounds__(512, 4) overlap_free(const float4* __restrict__ a, size_t n, int passes, float* out) {
    float f[4];
    uint32_t u[4];
    for (int k = 0; k < 4; ++k) {
        f[k] = threadIdx.x * 0.001f + k;
        u[k] = threadIdx.x * 2654435761u + k;
    }
    float s = 0;
    for (int p = 0; p < passes; ++p)
        for (size_t i = blockIdx.x * (size_t)blockDim.x + threadIdx.x; i < n; i += (size_t)gridDim.x * blockDim.x) {
            const float4 v = LOAD ? __ldcg(&a[i]) : make_float4(f[0], 1.f, f[1], f[2]);
            // Every word used, so that every form loads it as one 16-byte load (with
            // `v.x + v.w` alone the loads-alone form loaded two words apart, twice the
            // L1 sectors of the forms with arithmetic).
            s += (v.x + v.y) + (v.z + v.w);
            overlap_rounds<ALU>(f, u, v.y);
        }
    for (int k = 0; k < 4; ++k) s += f[k] + (float)(u[k] & 1);
    if (s == 12345.0f) out[threadIdx.x] = s;  // keeps the work alive
}
template <int ALU, bool LOAD>
__global__ void __launch_bounds__(384, 4) overlap_phased(const float2* __restrict__ a, size_t n, int iters, float* out) {
    float f[4];
    uint32_t u[4];
    for (int k = 0; k < 4; ++k) {
        f[k] = threadIdx.x * 0.001f + k;
        u[k] = threadIdx.x * 2654435761u + k;
    }
    const size_t tile = (size_t)blockDim.x * 8, tiles = n / tile;
    float s = 0;
    for (int it = 0; it < iters; ++it) {
        const size_t base = ((blockIdx.x + (size_t)it * gridDim.x) % tiles) * tile;
        float2 v[8];
#pragma unroll
        for (int k = 0; k < 8; ++k)
            v[k] = LOAD ? __ldcg(&a[base + k * blockDim.x + threadIdx.x]) : make_float2(f[k & 3], s);
        float y = 0;
#pragma unroll
        for (int k = 0; k < 8; ++k) y += v[k].x + v[k].y;
        __syncthreads();
        overlap_rounds<ALU>(f, u, y);
        s += y;
        __syncthreads();
    }
    for (int k = 0; k < 4; ++k) s += f[k] + (float)(u[k] & 1);
    if (s == 12345.0f) out[threadIdx.x] = s;  // keeps the work alive
}
// One overlap form: its name, its kernel, arithmetic rounds (a load or a phase), loads.
template <typename Kernel>
struct OverlapForm {
    const char* name;
    Kernel kernel;
    int alu;
    bool load;
};
// The zeroed 8 MiB (`n` 16-byte words) a stream probe reads from L2, and the words that
// keep its work alive.
static int stream_buffers(float4** a, float** out, size_t n) {
    CHECK(cudaMalloc(a, n * 16));
    CHECK(cudaMalloc(out, 1 << 16));
    CHECK(cudaMemset(*a, 0, n * 16));
    return 0;
}
static int overlap_probes(int sms) {
    const size_t n = (8u << 20) / 16;
    const int passes = 64, iters = 256;
    float4* a;
    float* out;
    if (stream_buffers(&a, &out, n)) return 1;
    using Free = void (*)(const float4*, size_t, int, float*);
    using Phased = void (*)(const float2*, size_t, int, float*);
    const OverlapForm<Free> free_forms[] = {
        {"overlap_free_none", overlap_free<0, false>, 0, false},
        {"overlap_free_load", overlap_free<0, true>, 0, true},
        {"overlap_free_load_alu_2", overlap_free<2, true>, 2, true},
        {"overlap_free_load_alu_4", overlap_free<4, true>, 4, true},
        {"overlap_free_load_alu_8", overlap_free<8, true>, 8, true},
        {"overlap_free_load_alu_16", overlap_free<16, true>, 16, true},
        {"overlap_free_alu_2", overlap_free<2, false>, 2, false},
        {"overlap_free_alu_4", overlap_free<4, false>, 4, false},
        {"overlap_free_alu_8", overlap_free<8, false>, 8, false},
        {"overlap_free_alu_16", overlap_free<16, false>, 16, false},
    };
    const OverlapForm<Phased> phased_forms[] = {
        {"none", overlap_phased<0, false>, 0, false},
        {"load", overlap_phased<0, true>, 0, true},
        {"load_alu_8", overlap_phased<8, true>, 8, true},
        {"load_alu_16", overlap_phased<16, true>, 16, true},
        {"load_alu_32", overlap_phased<32, true>, 32, true},
        {"alu_8", overlap_phased<8, false>, 8, false},
        {"alu_16", overlap_phased<16, false>, 16, false},
        {"alu_32", overlap_phased<32, false>, 32, false},
    };
    for (const auto& f : free_forms) {
        const int blocks = sms * 4;
        for (int r = 0; r < PROBE_LAUNCHES; ++r) f.kernel<<<blocks, 512>>>(a, n, passes, out);
        CHECK(cudaDeviceSynchronize());
        printf("probe\t%s\tblocks_a_sm\t4\n", f.name);
        printf("probe\t%s\talu_rounds_a_load\t%d\n", f.name, f.alu);
        printf("probe\t%s\tl2_bytes\t%lld\n", f.name, f.load ? (long long)n * 16 * passes : 0LL);
    }
    const int blocks_a_sm[] = {1, 2, 4};
    for (int b : blocks_a_sm)
        for (const auto& f : phased_forms) {
            char name[64];
            snprintf(name, sizeof name, "overlap_phased_%d_%s", b, f.name);
            for (int r = 0; r < PROBE_LAUNCHES; ++r) f.kernel<<<sms * b, 384>>>((const float2*)a, 2 * n, iters, out);
            CHECK(cudaDeviceSynchronize());
            printf("probe\t%s\tblocks_a_sm\t%d\n", name, b);
            printf("probe\t%s\talu_rounds_a_phase\t%d\n", name, f.alu);
            printf("probe\t%s\tl2_bytes\t%lld\n", name, f.load ? (long long)sms * b * 384 * 8 * 8 * iters : 0LL);
        }
    cudaFree(a);
    cudaFree(out);
    return 0;
}

// The in-flight probes (`microbench inflight`): L2's bandwidth by the loads a warp
// keeps in flight. Every SM holds B blocks of 512 threads (16, 32 or 64 warps) that
// stream 8 MiB from L2 (`ld.global.cg`) 64 times, each warp issuing U independent
// 16-byte loads, then waiting for them, then the next U: no arithmetic between. The
// overlap probes' free-running loads alone (U = 1, 64 warps) reached half of
// `l2_read`'s bandwidth; these map where that starts.
template <int U>
__global__ void __launch_bounds__(512, 4) l2_inflight(const float4* __restrict__ a, size_t n, int passes, float* out) {
    float s = 0;
    const size_t stride = (size_t)gridDim.x * blockDim.x;
    for (int p = 0; p < passes; ++p)
        for (size_t i = blockIdx.x * (size_t)blockDim.x + threadIdx.x; i < n; i += U * stride) {
            float4 v[U];
#pragma unroll
            for (int u = 0; u < U; ++u) {
                const size_t j = i + u * stride;
                v[u] = j < n ? __ldcg(&a[j]) : make_float4(0.f, 0.f, 0.f, 0.f);
            }
#pragma unroll
            for (int u = 0; u < U; ++u) s += v[u].x + v[u].w;
        }
    if (s == 12345.0f) out[threadIdx.x] = s;  // keeps the work alive
}
static int inflight_probes(int sms) {
    const size_t n = (8u << 20) / 16;
    const int passes = 64;
    float4* a;
    float* out;
    if (stream_buffers(&a, &out, n)) return 1;
    using Kernel = void (*)(const float4*, size_t, int, float*);
    const struct {
        int loads;
        Kernel kernel;
    } forms[] = {{1, l2_inflight<1>}, {2, l2_inflight<2>}, {4, l2_inflight<4>}, {8, l2_inflight<8>}};
    // `l2_read` on the same card first, the bandwidth the profile takes.
    for (int r = 0; r < PROBE_LAUNCHES; ++r) micro::l2_read<<<sms * 16, 512>>>(a, n, 16, out);
    CHECK(cudaDeviceSynchronize());
    printf("probe\tl2_read_reference\tl2_bytes\t%lld\n", (long long)n * 16 * 16);
    const int blocks_a_sm[] = {1, 2, 4};
    for (int b : blocks_a_sm)
        for (const auto& f : forms) {
            char name[64];
            snprintf(name, sizeof name, "l2_inflight_%d_loads_%d_blocks", f.loads, b);
            for (int r = 0; r < PROBE_LAUNCHES; ++r) f.kernel<<<sms * b, 512>>>(a, n, passes, out);
            CHECK(cudaDeviceSynchronize());
            printf("probe\t%s\tblocks_a_sm\t%d\n", name, b);
            printf("probe\t%s\tloads_in_flight_a_warp\t%d\n", name, f.loads);
            printf("probe\t%s\tl2_bytes\t%lld\n", name, (long long)n * 16 * passes);
        }
    cudaFree(a);
    cudaFree(out);
    return 0;
}

// A three-word value summed word by word (as PDACRT scans three counts at once).
struct Add3 {
    __host__ __device__ uint3 operator()(const uint3& a, const uint3& b) const {
        return make_uint3(a.x + b.x, a.y + b.y, a.z + b.z);
    }
};

// The single-pass scan probes (`microbench scan`): CUB's DeviceScan, a library primitive
// whose tiles learn their prefix by a decoupled look-back, over 1 to 1,024 tiles of one
// and of three 4-byte words (nominal tiles of 1,920 and 640 elements; ncu's grid sizes
// say how many tiles ran): what a scan launch costs by its tiles.
static int scan_probes() {
    const int tiles[] = {1, 2, 3, 4, 8, 16, 32, 64, 128, 256, 512, 1024};
    const size_t max_n = (size_t)1024 * 1920;
    uint32_t *in, *out;
    uint3 *in3, *out3;
    CHECK(cudaMalloc(&in, max_n * 4));
    CHECK(cudaMalloc(&out, max_n * 4));
    CHECK(cudaMalloc(&in3, max_n * 12));
    CHECK(cudaMalloc(&out3, max_n * 12));
    CHECK(cudaMemset(in, 1, max_n * 4));
    CHECK(cudaMemset(in3, 1, max_n * 12));
    size_t bytes = 0, bytes3 = 0;
    CHECK(cub::DeviceScan::ExclusiveSum(nullptr, bytes, in, out, (int)max_n));
    CHECK(cub::DeviceScan::ExclusiveScan(nullptr, bytes3, in3, out3, Add3(), make_uint3(0, 0, 0), (int)max_n));
    const size_t most = std::max(bytes, bytes3);
    void* temp;
    CHECK(cudaMalloc(&temp, most));
    for (int g : tiles) {
        for (int r = 0; r < PROBE_LAUNCHES; ++r) {
            size_t t = most;
            CHECK(cub::DeviceScan::ExclusiveSum(temp, t, in, out, g * 1920));
            t = most;
            CHECK(cub::DeviceScan::ExclusiveScan(temp, t, in3, out3, Add3(), make_uint3(0, 0, 0), g * 640));
        }
    }
    CHECK(cudaDeviceSynchronize());
    for (int g : tiles) {
        printf("probe\tscan_u32\telements\t%d\n", g * 1920);
        printf("probe\tscan_u32x3\telements\t%d\n", g * 640);
    }
    cudaFree(temp);
    cudaFree(in);
    cudaFree(out);
    cudaFree(in3);
    cudaFree(out3);
    return 0;
}

// The rounds probes (`microbench rounds`): what a round of loads issued together costs
// one warp, by the loads and sectors in it, alone and with its SM full. Prints each
// probe's steps and the cycles of its chase (clock64 of thread 0, after warm-up): the
// chase's time for one thread, one warp or one block a SM; for a grid of several blocks
// a SM, thread 0 may finish first, so Nsight's kernel time over the steps is the one.
static int round_probes(int sms) {
    uint32_t *recs, *out;
    long long* cycles;
    CHECK(cudaMalloc(&recs, (size_t(1) << 20) * 9 * 4));
    CHECK(cudaMalloc(&out, 4096 * 4));
    CHECK(cudaMalloc(&cycles, 8 * 16));
    std::vector<uint32_t> v((size_t(1) << 20) * 9);
    uint32_t h = 12345;
    for (auto& x : v) x = (h = h * 1664525u + 1013904223u) >> 7;
    CHECK(cudaMemcpy(recs, v.data(), v.size() * 4, cudaMemcpyHostToDevice));
    const int warm = 4000, steps = 20000, many = 2000;
    using RoundKernel = void (*)(const uint32_t*, int, int, long long*, uint32_t*);
    // Launches `kernel` over `data` PROBE_LAUNCHES times; prints its steps (`unit`) and
    // each launch's cycles a timed step.
    auto timed = [&](const char* name, const char* unit, RoundKernel kernel, const uint32_t* data, int grid,
                     int block, int warm, int steps) -> int {
        std::vector<long long> c(PROBE_LAUNCHES);
        for (int l = 0; l < PROBE_LAUNCHES; ++l) kernel<<<grid, block>>>(data, warm, steps, cycles + l, out);
        CHECK(cudaDeviceSynchronize());
        CHECK(cudaMemcpy(c.data(), cycles, PROBE_LAUNCHES * 8, cudaMemcpyDeviceToHost));
        printf("probe\t%s\t%s\t%d\n", name, unit, warm + steps);
        for (int l = 0; l < PROBE_LAUNCHES; ++l) printf("timed\t%s\tcycles_per_step\t%.2f\n", name, (double)c[l] / steps);
        return 0;
    };
    struct Round {
        const char* name;
        RoundKernel kernel;
        int grid, block, warm, steps;
    } rounds[] = {{"round_lane_1", micro::round_lane_1, 1, 1, warm, steps},
                  {"round_lane_9", micro::round_lane_9, 1, 1, warm, steps},
                  {"round_warp_1", micro::round_warp_1, 1, 32, warm, steps},
                  {"round_warp_9", micro::round_warp_9, 1, 32, warm, steps},
                  {"round_sm_9", micro::round_sm_9, sms, 256, 200, many},
                  {"round_full_9", micro::round_full_9, sms * 8, 256, 200, many},
                  {"round_sm_9_wide", micro::round_sm_9_wide, sms, 256, 200, many},
                  {"round_full_9_wide", micro::round_full_9_wide, sms * 8, 256, 200, many},
                  {"round_sm_1_wide", micro::round_sm_1_wide, sms, 256, 200, many},
                  {"round_full_1_wide", micro::round_full_1_wide, sms * 8, 256, 200, many},
                  {"round_lane_1_ca", micro::round_lane_1_ca, 1, 1, 200000, steps},
                  {"round_lane_9_ca", micro::round_lane_9_ca, 1, 1, 200000, steps},
                  {"round_warp_9_ca", micro::round_warp_9_ca, 1, 32, 20000, steps},
                  {"round_lane_1_cg", micro::round_lane_1_cg, 1, 1, 200000, steps}};
    for (auto& r : rounds)
        if (timed(r.name, "steps", r.kernel, recs, r.grid, r.block, r.warm, r.steps)) return 1;
    {
        // The chases past L1: 2^19 words, each naming the one 33 on.
        uint32_t* chain_buf;
        const size_t words = (size_t)1 << 19;
        CHECK(cudaMalloc(&chain_buf, words * 4));
        auto v = chain(words, 33);
        CHECK(cudaMemcpy(chain_buf, v.data(), words * 4, cudaMemcpyHostToDevice));
        if (timed("chase_l2_ca", "hops", micro::chase_l2_ca, chain_buf, 1, 1, 40000, steps)) return 1;
        if (timed("chase_l2_cg", "hops", micro::chase_l2_cg, chain_buf, 1, 1, 40000, steps)) return 1;
        cudaFree(chain_buf);
    }
    // The wait of a round against the warps waiting beside it: one block a SM of 1 to
    // 32 warps, each lane chasing nine (or one) scattered loads a step over 37.7 MB.
    for (int nine = 0; nine < 2; ++nine)
        for (int warps = 1; warps <= 32; warps *= 2) {
            char name[32];
            snprintf(name, sizeof name, "round_sweep_%d_w%d", nine ? 9 : 1, warps);
            RoundKernel k = nine ? micro::round_sm_9_wide : micro::round_sm_1_wide;
            if (timed(name, "steps", k, recs, sms, 32 * warps, 200, many)) return 1;
        }
    cudaFree(recs);
    cudaFree(out);
    cudaFree(cycles);
    return 0;
}


// The instruction-fetch probes (`microbench icache`): for every K (pieces of 4 KiB) and
// W (warps a SM), prints the cycles per multiply-add of a warp, the mean over the SMs'
// first warps (clock64), each probe once after a warm-up launch.
template <int K>
static int icache_row(int sms, float* out, long long* cycles, int warps) {
    const int passes = 2048 / K;  // 512K multiply-adds a warp
    micro::icache<K><<<sms, 32 * warps>>>(out, 1.0001f, 0.5f, passes, cycles);  // warm-up
    micro::icache<K><<<sms, 32 * warps>>>(out, 1.0001f, 0.5f, passes, cycles);
    CHECK(cudaDeviceSynchronize());
    std::vector<long long> c(sms);
    CHECK(cudaMemcpy(c.data(), cycles, sms * sizeof(long long), cudaMemcpyDeviceToHost));
    double mean = 0;
    for (long long v : c) mean += (double)v / sms;
    const double fmas = 256.0 * K * passes;
    printf("timed\ticache\tcode_kib\t%d\twarps_per_sm\t%d\tcycles_per_fma\t%.3f\n", 4 * K, warps, mean / fmas);
    return 0;
}

template <int K>
static int icache_jump_row(int sms, float* out, long long* cycles, int warps) {
    const int pieces = 16384;
    micro::icache_jump<K><<<sms, 32 * warps>>>(out, 1.0001f, 0.5f, pieces, cycles);  // warm-up
    micro::icache_jump<K><<<sms, 32 * warps>>>(out, 1.0001f, 0.5f, pieces, cycles);
    CHECK(cudaDeviceSynchronize());
    std::vector<long long> c(sms);
    CHECK(cudaMemcpy(c.data(), cycles, sms * sizeof(long long), cudaMemcpyDeviceToHost));
    double mean = 0;
    for (long long v : c) mean += (double)v / sms;
    printf("timed\ticache_jump\tpieces\t%d\twarps_per_sm\t%d\tcycles_per_piece\t%.3f\n", K, warps, mean / pieces);
    return 0;
}
static int icache_probes(int sms) {
    float* out;
    long long* cycles;
    CHECK(cudaMalloc(&out, (size_t)sms * 1024 * 4));
    CHECK(cudaMalloc(&cycles, (size_t)sms * 8));
    for (int warps : {1, 4, 8, 12, 16, 32}) {
        if (icache_row<1>(sms, out, cycles, warps) || icache_row<2>(sms, out, cycles, warps) ||
            icache_row<4>(sms, out, cycles, warps) || icache_row<8>(sms, out, cycles, warps) ||
            icache_row<16>(sms, out, cycles, warps) || icache_row<32>(sms, out, cycles, warps) ||
            icache_row<64>(sms, out, cycles, warps))
            return 1;
    }
    for (int warps : {1, 4, 8, 12, 16, 24, 32}) {
        if (icache_jump_row<16>(sms, out, cycles, warps) || icache_jump_row<64>(sms, out, cycles, warps) ||
            icache_jump_row<256>(sms, out, cycles, warps) || icache_jump_row<1024>(sms, out, cycles, warps) ||
            icache_jump_row<2048>(sms, out, cycles, warps))
            return 1;
    }
    cudaFree(out);
    cudaFree(cycles);
    return 0;
}

// The L2-latency-by-size probes (`microbench l2size`): one thread chases a chain that
// steps 33 words (a new 128-byte line each hop) over 8 KiB to 56 MiB with `cg` (past
// L1), and 64 MiB to 1 GiB (past L2), timed with clock64 after two passes over the
// lines, so what is timed is the latency of a hit in L2 (or of HBM past it) for
// data of that size. Prints each size's cycles a hop, PROBE_LAUNCHES times, and for
// sizes within L2 the nanoseconds a hop of the profile's `chase_l2` form (no clock read
// in the loop), timed by CUDA events, to tell the form from the size.
// The shared-memory probes (`microbench shared`): one thread's chase through shared
// memory (cycles a hop), then one block's store-barrier-load round at 32 to 1,024
// threads (cycles a round, two barriers each), each PROBE_LAUNCHES times.
static int shared_probes() {
    uint32_t* out;
    long long* cycles;
    CHECK(cudaMalloc(&out, 1024 * 4));
    CHECK(cudaMalloc(&cycles, 8 * PROBE_LAUNCHES));
    const int warm = 2000, hops = 20000, rounds = 20000;
    std::vector<long long> c(PROBE_LAUNCHES);
    for (int l = 0; l < PROBE_LAUNCHES; ++l) micro::shared_chain<<<1, 1>>>(warm, hops, cycles + l, out);
    CHECK(cudaDeviceSynchronize());
    CHECK(cudaMemcpy(c.data(), cycles, PROBE_LAUNCHES * 8, cudaMemcpyDeviceToHost));
    printf("probe\tshared_chain\thops\t%d\n", warm + hops);
    for (int l = 0; l < PROBE_LAUNCHES; ++l) printf("timed\tshared_chain\tcycles_per_hop\t%.2f\n", (double)c[l] / hops);
    for (int threads : {32, 128, 384, 1024}) {
        for (int l = 0; l < PROBE_LAUNCHES; ++l) micro::barrier_chain<<<1, threads>>>(warm, rounds, cycles + l, out);
        CHECK(cudaDeviceSynchronize());
        CHECK(cudaMemcpy(c.data(), cycles, PROBE_LAUNCHES * 8, cudaMemcpyDeviceToHost));
        printf("probe\tbarrier_chain\tthreads\t%d\n", threads);
        for (int l = 0; l < PROBE_LAUNCHES; ++l)
            printf("timed\tbarrier_chain\tthreads\t%d\tcycles_per_round\t%.2f\n", threads, (double)c[l] / rounds);
    }
    cudaFree(out);
    cudaFree(cycles);
    return 0;
}

static int l2size_probes() {
    const size_t max_words = (size_t)1 << 28;  // 1 GiB
    uint32_t *buf, *out;
    long long* cycles;
    CHECK(cudaMalloc(&buf, max_words * 4));
    CHECK(cudaMalloc(&out, 64));
    CHECK(cudaMalloc(&cycles, 8 * PROBE_LAUNCHES));
    const int hops = 20000;
    const size_t sizes_kib[] = {8,     32,    128,   512,   1024,  2048,  4096,   8192,   16384,
                                24576, 32768, 40960, 49152, 57344, 65536, 131072, 262144, 1048576};
    for (size_t kib : sizes_kib) {
        const size_t words = kib * 256;
        auto v = chain(words, 33);
        CHECK(cudaMemcpy(buf, v.data(), words * 4, cudaMemcpyHostToDevice));
        // Two passes over the lines (2 words / 33 hops), at most 2M hops, warm the chain.
        const int warm = (int)std::min<size_t>(2 * words / 33 + 64, (size_t)2 << 20);
        const int timed = kib > (64u << 10) ? hops / 4 : hops;
        for (int l = 0; l < PROBE_LAUNCHES; ++l) micro::chase_l2_cg<<<1, 1>>>(buf, warm, timed, cycles + l, out);
        CHECK(cudaDeviceSynchronize());
        std::vector<long long> c(PROBE_LAUNCHES);
        CHECK(cudaMemcpy(c.data(), cycles, PROBE_LAUNCHES * 8, cudaMemcpyDeviceToHost));
        for (int l = 0; l < PROBE_LAUNCHES; ++l)
            printf("timed\tchase_cg\tkib\t%zu\tcycles_per_hop\t%.2f\n", kib, (double)c[l] / timed);
        // The profile's own form (`chase_l2`: no clock in the loop), timed by events
        // over 200,000 hops after a warm-up launch, for the sizes within L2.
        if (kib <= (16u << 10)) {
            const int many = 200000;
            cudaEvent_t e0, e1;
            CHECK(cudaEventCreate(&e0));
            CHECK(cudaEventCreate(&e1));
            micro::chase_l2<<<1, 1>>>(buf, many, out);
            for (int l = 0; l < PROBE_LAUNCHES; ++l) {
                CHECK(cudaEventRecord(e0));
                micro::chase_l2<<<1, 1>>>(buf, many, out);
                CHECK(cudaEventRecord(e1));
                CHECK(cudaEventSynchronize(e1));
                float ms = 0;
                CHECK(cudaEventElapsedTime(&ms, e0, e1));
                printf("timed\tchase_l2_events\tkib\t%zu\tns_per_hop\t%.2f\n", kib, ms * 1e6 / many);
            }
            cudaEventDestroy(e0);
            cudaEventDestroy(e1);
        }
        fflush(stdout);
    }
    cudaFree(buf);
    cudaFree(out);
    cudaFree(cycles);
    return 0;
}

int main(int argc, char** argv) {
    cudaDeviceProp p;
    CHECK(cudaGetDeviceProperties(&p, 0));
    // The modes that run one family of probes alone, by name.
    const int n_sms = p.multiProcessorCount;
    const struct {
        const char* name;
        int (*run)(int sms);
    } modes[] = {
        {"fences", atomic_and_fence_probes},
        {"hbm", hbm_probes},
        {"stream", stream_probes},
        {"start", [](int) { return start_probes(); }},
        {"scan", [](int) { return scan_probes(); }},
        {"grid", grid_probes},
        {"icache", icache_probes},
        {"shared", [](int) { return shared_probes(); }},
        {"fencemix", fence_mix_probes},
        {"l2size", [](int) { return l2size_probes(); }},
        {"rounds", round_probes},
        {"slots", slot_probes},
        {"overlap", overlap_probes},
        {"inflight", inflight_probes},
    };
    if (argc > 1) {
        for (const auto& m : modes) {
            if (std::string(argv[1]) != m.name) continue;
            printf("device\tname\t%s\n", p.name);
            return m.run(n_sms);
        }
        fprintf(stderr, "microbench: no mode '%s'\n", argv[1]);
        return 2;
    }
    const int sms = p.multiProcessorCount;
    int clock_khz = 0, mem_khz = 0, bus_bits = 0;
    cudaDeviceGetAttribute(&clock_khz, cudaDevAttrClockRate, 0);
    cudaDeviceGetAttribute(&mem_khz, cudaDevAttrMemoryClockRate, 0);
    cudaDeviceGetAttribute(&bus_bits, cudaDevAttrGlobalMemoryBusWidth, 0);
    // What the device says of itself (the calibration records these as "device query").
    printf("device\tname\t%s\n", p.name);
    printf("device\tsms\t%d\n", sms);
    printf("device\tclock_ghz\t%.3f\n", clock_khz / 1e6);
    printf("device\tmax_warps_per_sm\t%d\n", p.maxThreadsPerMultiProcessor / 32);
    printf("device\tmax_blocks_per_sm\t%d\n", p.maxBlocksPerMultiProcessor);
    printf("device\tshared_per_sm_bytes\t%zu\n", p.sharedMemPerMultiprocessor);
    printf("device\tregisters_per_sm\t%d\n", p.regsPerMultiprocessor);
    printf("device\tl2_bytes\t%d\n", p.l2CacheSize);
    printf("device\thbm_bus_bits\t%d\n", bus_bits);
    printf("device\thbm_clock_ghz\t%.3f\n", mem_khz / 1e6);

    float* out;
    CHECK(cudaMalloc(&out, 1 << 20));
    const size_t big = (size_t)1 << 30;  // 1 GiB, far past L2
    float4* hbm;
    CHECK(cudaMalloc(&hbm, big));
    CHECK(cudaMemset(hbm, 0, big));
    const size_t l2n = (size_t)8 << 20;  // 8 MiB: fits L2 (and its near partition)
    float4* l2buf;
    CHECK(cudaMalloc(&l2buf, l2n));
    CHECK(cudaMemset(l2buf, 0, l2n));
    float4* l1buf;
    CHECK(cudaMalloc(&l1buf, (size_t)sms * 4 * 16384));
    CHECK(cudaMemset(l1buf, 0, (size_t)sms * 4 * 16384));

    const int full_grid = sms * 8, threads = 256;  // 2,048 threads per SM: full
    for (int r = 0; r < PROBE_LAUNCHES; ++r) {
        micro::empty<<<1, 32>>>();
        micro::empty_blocks<<<sms * 256, 256>>>();
        micro::alu_mix<<<full_grid, threads>>>(out, 4096);
        micro::alu_chain<<<sms, 32>>>(out, 1 << 16);
        micro::hbm_read<<<sms * 16, 512>>>(hbm, big / 16, out);
        micro::hbm_write<<<sms * 16, 512>>>(hbm, big / 16);
        micro::l2_read<<<sms * 16, 512>>>(l2buf, l2n / 16, 16, out);
        micro::l2_scatter<<<sms * 16, 512>>>((const float*)l2buf, (uint32_t)(l2n / 4 - 1) & ~7u, 256, out);
        micro::l1_read<<<sms * 4, 256>>>(l1buf, 256, out);
        micro::shared_rw<<<full_grid, threads>>>(out, 4096);
        micro::barrier<<<full_grid, threads>>>(out, 1024);
    }
    CHECK(cudaDeviceSynchronize());
    printf("probe\tempty\tblocks\t1\n");
    printf("probe\tempty_blocks\tblocks\t%d\n", sms * 256);
    printf("probe\talu_mix\tthreads\t%d\n", full_grid * threads);
    printf("probe\talu_chain\tdependent_fma\t%d\n", 1 << 16);
    printf("probe\tl1_read\tblocks\t%d\n", sms * 4);
    printf("probe\tbarrier\tblock_barriers\t%lld\n", (long long)full_grid * 1024 * 2);

    // Latency chases (one thread; hops counted here). The HBM chase steps 8,212 bytes
    // (a new sector each hop, 160 MB in all: past L2, within few 2 MB pages); the L1 and
    // L2 chases cycle over 8 KiB, whose 256 sectors miss once (0.1 % of the hops).
    uint32_t* chase_buf;
    const size_t hbm_words = big / 4;
    CHECK(cudaMalloc(&chase_buf, big));
    struct Chase {
        const char* name;
        size_t words, stride;
        int hops;
    } chases[] = {{"chase_hbm", hbm_words, 2053, 20000}, {"chase_l2", 2048, 33, 200000}, {"chase_l1", 2048, 33, 200000}};
    for (auto& c : chases) {
        auto v = chain(c.words, c.stride);
        CHECK(cudaMemcpy(chase_buf, v.data(), c.words * 4, cudaMemcpyHostToDevice));
        for (int r = 0; r < PROBE_LAUNCHES; ++r) {
            if (c.name[6] == 'h') micro::chase_hbm<<<1, 1>>>(chase_buf, c.hops, (uint32_t*)out);
            else if (c.name[7] == '2') micro::chase_l2<<<1, 1>>>(chase_buf, c.hops, (uint32_t*)out);
            else micro::chase_l1<<<1, 1>>>(chase_buf, c.hops, (uint32_t*)out);
        }
        CHECK(cudaDeviceSynchronize());
        printf("probe\t%s\thops\t%d\n", c.name, c.hops);
    }

    // Atomics.
    const int at_iters = 256;
    CHECK(cudaMemset(chase_buf, 0, 64 << 20));
    for (int r = 0; r < PROBE_LAUNCHES; ++r) {
        micro::atomic_distinct<<<full_grid, threads>>>(chase_buf, 16u << 20, at_iters);
        micro::atomic_same<<<sms, 256>>>(chase_buf, 16);
    }
    CHECK(cudaDeviceSynchronize());
    printf("probe\tatomic_distinct\tatomic_lanes\t%lld\n", (long long)full_grid * threads * at_iters);
    printf("probe\tatomic_same\tatomic_lanes\t%lld\n", (long long)sms * 256 * 16);
    printf("probe\tshared_rw\tthreads\t%d\n", full_grid * threads);
    cudaFree(chase_buf);
    cudaFree(l1buf);
    cudaFree(l2buf);
    cudaFree(hbm);
    cudaFree(out);
    return atomic_and_fence_probes(sms);
}
