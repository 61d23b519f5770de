/* The C interface of libwarpray_cuda (cuda/pdacrt.cu), mirrored in src/gpu/ffi.rs.
 * Every function returns 0 on success; on failure, wr_last_error() says why. */
#ifndef WARPRAY_PDACRT_API_H
#define WARPRAY_PDACRT_API_H

#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

/* Bumped whenever a struct or signature below changes. */
#define WR_API_VERSION 7

/* PdacrtParams, plus what the kernels need from the Rust side. */
typedef struct WrParams {
    uint32_t leaf_rays;
    uint32_t leaf_triangles;
    uint32_t max_depth;
    uint32_t brute_force_block;
    /* PdacrtParams::leaf_pairs(): DACRT's leaf rule, 4 * leaf_rays * leaf_triangles. */
    uint64_t leaf_pairs;
    /* Rays per pass of the pipeline (0: the whole batch). */
    uint64_t chunk_rays;
    /* geometry::SLAB_WIDEN, so the slab test rounds as the Rust one does. */
    float slab_widen;
    /* geometry::batch_slack of the call's rays: how far the ray tests grow boxes. */
    float grow;
} WrParams;

/* What one trace call did. */
typedef struct WrStats {
    /* GPU time of the pipeline with the rays on the device (CUDA events; transfers excluded). */
    double trace_ms;
    /* Host wall time of the whole call, transfers included. */
    double call_ms;
    uint64_t tests;
    uint32_t levels;
    uint32_t launches;
    /* Largest device allocation of the call's buffers (bytes), triangles excluded. */
    uint64_t peak_bytes;
    /* Host synchronisations that read totals back (per level: the scans' totals, then
     * the brute-force grid; per pass: the rays that enter the scene's box). */
    uint32_t read_backs;
    uint32_t reserved;
} WrStats;

int wr_api_version(void);
/* The GPU's name and compute capability into buf (NUL-terminated). */
int wr_device_name(char* buf, uint32_t len);
/* Uploads n_tris triangles (9 floats each) with their bounding box (min xyz, max xyz). */
int wr_pdacrt_create(const float* tris, uint64_t n_tris, const float* scene_box, void** handle);
/* Traces n_rays rays (32-byte Ray records: origin, dir, t_min, t_max); keys[i] receives
 * (distance bits << 32 | triangle id), UINT64_MAX for a miss, or for any_hit 0 when blocked. */
int wr_pdacrt_trace(void* handle, const void* rays, uint64_t n_rays, int any_hit, const WrParams* params,
                    uint64_t* keys, WrStats* stats);
/* Replaces the handle's triangles (a new frame), keeping its working buffers. */
int wr_pdacrt_set_triangles(void* handle, const float* tris, uint64_t n_tris, const float* scene_box);
void wr_pdacrt_destroy(void* handle);
const char* wr_last_error(void);

#ifdef __cplusplus
}
#endif

#endif
