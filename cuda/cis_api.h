/* The C interface of CIS-LBDPT's GPU twins (cuda/cis.cu), mirrored in src/gpu/cis_ffi.rs.
 * Part of libwarpray_cuda; every function returns 0 on success, wr_cis_last_error() says why not.
 * The records below have the layouts of the Rust #[repr(C)] types named beside them. */
#ifndef WARPRAY_CIS_API_H
#define WARPRAY_CIS_API_H

#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

/* A material, flattened from the Rust enum. kind: 0 diffuse, 1 glossy, 2 mirror, 3 glass,
 * 4 conductor, 5 rough glass, 6 layered. a: albedo | diffuse | reflectance | tint | eta |
 * tint | base albedo or eta; b: specular | k | base k. Layered: base_kind 0 diffuse,
 * 1 conductor (roughness = the base's). */
typedef struct WrMaterial {
    uint32_t kind;
    uint32_t coat_count;
    uint32_t base_kind;
    float roughness;
    float ior;
    float a[3];
    float b[3];
    float coat_ior[2];
    float coat_roughness[2];
    float coat_absorption[2][3];
} WrMaterial;

/* A light: kind 0 area (tri, area, normal, value = radiance), 1 point (position, value =
 * intensity). */
typedef struct WrLight {
    uint32_t kind;
    uint32_t tri;
    float area;
    float normal[3];
    float value[3];
    float position[3];
} WrLight;

/* Everything cis::shade reads besides the pool: the scene, its lights, the camera and
 * the options, and one pass's light vertex cache. */
typedef struct WrCisScene {
    const float* tris; /* 9 floats per triangle */
    const uint32_t* material_of;
    uint64_t n_tris;
    const WrMaterial* materials;
    const uint32_t* two_sided;
    const float* emission; /* 3 floats per material */
    uint64_t n_materials;
    const WrLight* lights;
    const float* light_cdf;
    const uint32_t* light_of_tri;
    uint64_t n_lights;
    float cam_position[3], cam_forward[3], cam_right[3], cam_up[3];
    float tan_half; /* tan(vfov / 2), computed on the host as the Rust code does */
    float margin;   /* the filter's reach in pixels */
    uint32_t width, height, max_depth;
    uint32_t resampled; /* 1: resampled connections (candidates, draws); 0: uniform (draws) */
    uint32_t candidates, draws;
    const void* cache_vertices; /* bidir::Vertex, 60 bytes */
    uint64_t n_cache_vertices;
    const uint32_t* cache_entries; /* [start, s] per entry */
    uint64_t n_entries;
    double count_splat, count_connection;
} WrCisScene;

int wr_cis_create(const WrCisScene* scene, void** handle);
/* One cis::shade launch (named cis::shade_sorted or cis::shade_unsorted for the profiler)
 * over n active samples: order, active and hits (geometry::Hit) as the emulator's launch
 * reads them; slots (cis::Slot, 88 bytes) and vertices (Vertex) of the whole pool are
 * read and written back; pending (cis::PendingData, 48 bytes) is written. ms: GPU time. */
int wr_cis_shade(void* handle, int sorted, uint64_t n, const uint32_t* order, const uint32_t* active,
                 const void* hits, uint64_t pool, void* slots, void* vertices, void* pending, double* ms);
/* The compaction: cis::alive_flags, then CUB's DeviceSelect::Flagged; kept receives the
 * active slots still alive, n_kept their number. */
int wr_cis_compact(void* handle, uint64_t n, const uint32_t* active, uint64_t pool, const void* slots, uint32_t* kept,
                   uint64_t* n_kept, double* ms);
void wr_cis_destroy(void* handle);
const char* wr_cis_last_error(void);

#ifdef __cplusplus
}
#endif

#endif
