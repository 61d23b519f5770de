/* The C interface of the whole GPU renders (cuda/render.cu, render_driver.cuh), mirrored
 * in src/gpu/render.rs: one pass of CIS-LBDPT's stream or of the LVC-BDPT megakernels at
 * a time, the scene described as for the shading twin (cis_api.h, without its cache).
 * Part of libwarpray_cuda (WR_API_VERSION in pdacrt_api.h covers it); every function
 * returns 0 on success, wr_render_last_error() says why not. */
#ifndef WARPRAY_RENDER_API_H
#define WARPRAY_RENDER_API_H

#include <stdint.h>

#include "cis_api.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef struct WrRenderSettings {
    uint32_t method;     /* 0: CIS-LBDPT (stream of kernels), 1: LVC-BDPT (megakernels) */
    uint32_t sort;       /* CIS: sort by material before shading */
    uint32_t resampled;  /* CIS: resampled connections (candidates, draws); 0: uniform (draws) */
    uint32_t regenerate; /* CIS: compaction and regeneration */
    uint32_t candidates;
    uint32_t draws;       /* CIS: connections drawn per camera vertex; LVC: n_c */
    uint32_t light_paths; /* per iteration; 0: one per pixel */
    uint32_t pool;        /* CIS: slots of the light and camera pools */
    uint64_t seed;
    float widen; /* geometry::SLAB_WIDEN */
    float grow;  /* geometry::hit_slack for every ray of the render */
    uint32_t per_iteration; /* camera passes per iteration (light pass); 0 counts as 1 */
} WrRenderSettings;

typedef struct WrRenderStats {
    double build_ms;   /* create: the BVH build (GPU time) */
    double pass_ms;    /* pass: GPU time of the pass, before the estimates and splats are read back */
    double light_ms;   /* pass: of which the light pass (at an iteration's first pass) and the pass's camera splats */
    double readback_ms; /* pass: reading back the estimates and splats (host wall time) */
    uint64_t rays;     /* pass: rays the stream cast (the megakernels' are not counted) */
    uint64_t bounces;  /* pass: camera-stream bounces */
    uint64_t cache_entries;
    uint64_t splats;   /* visible camera splats */
} WrRenderStats;

int wr_render_create(const WrCisScene* scene, const WrRenderSettings* settings, void** handle, WrRenderStats* stats);
/* One pass: estimates receives 3 floats per pixel; *splats points at n_splats records of
 * (film x, film y, r, g, b), owned by the handle until its next call. */
int wr_render_pass(void* handle, uint32_t pass, float* estimates, const float** splats, uint64_t* n_splats,
                   WrRenderStats* stats);
void wr_render_destroy(void* handle);
const char* wr_render_last_error(void);

#ifdef __cplusplus
}
#endif

#endif
