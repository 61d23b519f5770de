/* The C interface of the GPU BVH baseline (cuda/bvh.cu), mirrored in src/gpu/ffi.rs.
 * Part of libwarpray_cuda: WR_API_VERSION (cuda/pdacrt_api.h) covers it too. Every
 * function returns 0 on success; on failure, wr_bvh_last_error() says why. */
#ifndef WARPRAY_BVH_API_H
#define WARPRAY_BVH_API_H

#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

/* What one build or trace call did; a call fills the fields it names. */
typedef struct WrBvhStats {
    /* build: host-to-device copy of the triangles (host wall time, synchronous copy). */
    double upload_ms;
    /* build: GPU time of the build with the triangles resident (CUDA events). */
    double build_ms;
    /* trace: GPU time of the traversal with the rays resident (CUDA events). */
    double trace_ms;
    /* both: host wall time of the whole call, transfers included. */
    double call_ms;
    /* trace: ray-triangle tests and inner nodes visited. */
    uint64_t tests;
    uint64_t visits;
    /* build: inner nodes, and device bytes of the structure (nodes, reordered
     * triangles, their ids) without the build's scratch. */
    uint64_t nodes;
    uint64_t bytes;
} WrBvhStats;

int wr_bvh_create(void** handle);
/* Uploads n_tris triangles (9 floats each) and builds the LBVH over them, replacing
 * whatever the handle held. */
int wr_bvh_build(void* handle, const float* tris, uint64_t n_tris, WrBvhStats* stats);
/* As wr_pdacrt_trace: keys[i] receives (distance bits << 32 | triangle id),
 * UINT64_MAX for a miss, or for any_hit 0 when blocked; slab_widen is
 * geometry::SLAB_WIDEN, so the box test rounds as the Rust one does, and grow
 * geometry::batch_slack of the rays, by which node boxes are grown. */
int wr_bvh_trace(void* handle, const void* rays, uint64_t n_rays, int any_hit, float slab_widen, float grow,
                 uint64_t* keys, WrBvhStats* stats);
void wr_bvh_destroy(void* handle);
const char* wr_bvh_last_error(void);

#ifdef __cplusplus
}
#endif

#endif
