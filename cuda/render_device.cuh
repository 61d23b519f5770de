// The device code that whole GPU renders add to the shading twin's (cis_device.cuh):
// camera samples, light subpaths, one bounce of a subpath, the camera splats of a light
// subpath and the cache's rule, ported from the Rust functions named beside each in the
// same order of operations (random numbers drawn in the same order), and the hit of a
// traced key. Plain C++ apart from `__device__`, so cis_host_check.cpp builds it too.

#pragma once

#include "cis_device.cuh"
#include "geometry.cuh"

namespace cis {

// ---------------------------------------------------------------- sampling.rs

// Rng::for_sample
HD Rng rng_for_sample(uint64_t seed, uint64_t pixel, uint64_t sample) {
    uint64_t key = mix64((mix64(seed ^ 0x51574d3c8a2b9e11ull) + pixel) ^ mix64(sample + 0x9e3779b9ull));
    return {key, 0};
}
// Rng::derive
HD Rng rng_derive(const Rng& r, uint64_t tag) { return {mix64(r.key ^ mix64(tag + 0xd1b54a32d192ed03ull)), 0}; }
// sampling::uniform_sphere
HD V3 uniform_sphere(V2 u) {
    float z = 1.0f - 2.0f * u.x;
    float r = sqrtf(fmaxf(1.0f - z * z, 0.0f));
    float phi = 2.0f * PI * u.y;
    return v3(r * cosf(phi), r * sinf(phi), z);
}

// ---------------------------------------------------------------- the camera (scene/camera.rs, filter.rs)

// What a render adds to the shading scene: the seed and the camera sample's rule.
struct RenderScene {
    Scene sc;
    uint64_t seed;
    float magnitude;  // geometry::batch_slack's bound for every ray of the render
};

// filter::pixel_offset, then Filter::camera_sample for the box filter (sampled) or any
// filter (splatted): the film position at the pixel's corner plus the offset, weight 1.
HD V2 camera_film(uint64_t seed, uint32_t pixel, uint32_t width, uint32_t pass) {
    Rng r = rng_derive(rng_for_sample(seed, pixel, pass), 0x66696c6dull);
    V2 u = uniform2(r);
    return {(float)(pixel % width) + u.x, (float)(pixel / width) + u.y};
}
// Camera::generate_ray for a pinhole camera.
HD Ray generate_ray(const Scene& sc, V2 film) {
    float aspect = (float)sc.width / (float)sc.height;
    float sx = (2.0f * film.x / (float)sc.width - 1.0f) * sc.tan_half * aspect;
    float sy = (1.0f - 2.0f * film.y / (float)sc.height) * sc.tan_half;
    V3 dir = normalize(sc.cam_forward + sc.cam_right * sx + sc.cam_up * sy);
    return {sc.cam_position, dir, 0.0f, INFINITY};
}
// bidir::camera_vertex
HD Vertex camera_vertex(const Scene& sc) {
    return make_vertex(CAMERA, sc.cam_position, sc.cam_forward, NONE, splat(1.0f), false, splat(0.0f));
}

// ---------------------------------------------------------------- walk.rs

// walk::Walker (the slot of its batch is the host's business, not a kernel's).
struct Walker {
    Ray ray;
    V3 beta;
    Rng rng;
    uint32_t bounces;
    bool live;
    float rr_scale;  // 1, or 1 / the largest component of a light subpath's starting beta
};
HD Walker walker_new(Ray ray, V3 beta, Rng rng) { return {ray, beta, rng, 0, true, 1.0f}; }
HD Walker walker_done(Rng rng) { return {{splat(0.0f), v3(0.0f, 0.0f, 1.0f), 0.0f, INFINITY}, splat(0.0f), rng, 0, false, 1.0f}; }

// walk::start_light_subpath: the light vertex (false: no light to sample) and the
// walker that continues it.
HD bool start_light_subpath(const Scene& sc, Rng rng, int max_vertices, Vertex& origin, Walker& w) {
    float u_sel = uniform(rng);
    V2 u = uniform2(rng);
    LightSample ls;
    if (!light_sample(sc, u_sel, u, ls)) {
        w = walker_done(rng);
        return false;
    }
    origin = make_vertex(LIGHT, ls.position, ls.normal, ls.tri, splat(1.0f / ls.pdf), ls.is_delta, ls.emitted);
    V3 dir;
    float pdf_dir, cos;
    if (ls.is_delta) {
        dir = uniform_sphere(uniform2(rng));
        pdf_dir = 1.0f / (4.0f * PI);
        cos = 1.0f;
    } else {
        V3 local = cosine_hemisphere(uniform2(rng));
        dir = to_world(from_normal(ls.normal), local);
        pdf_dir = local.z * FRAC_1_PI;
        cos = local.z;
    }
    if (pdf_dir <= 0.0f || max_vertices < 2) {
        w = walker_done(rng);
        return true;
    }
    V3 beta = origin.beta * ls.emitted * cos / pdf_dir;
    V3 start = ls.is_delta ? ls.position : offset_ray_origin(ls.position, ls.normal);
    w = walker_new({start, dir, 0.0f, INFINITY}, beta, rng);
    float largest = max_element(beta);
    w.rr_scale = largest > 0.0f ? 1.0f / largest : 1.0f;
    return true;
}

// walk::step: the hit becomes the subpath's vertex `len` (false: a miss or a degenerate
// triangle), then the BSDF picks the next ray or the walker stops.
HD bool step(const Scene& sc, Walker& w, const Hit& hit, int len, bool radiance, int max_vertices, Vertex& out) {
    w.live = false;
    if (hit.prim == NONE) return false;
    V3 a, b, c;
    vertices_of(sc, hit.prim, a, b, c);
    V3 n = normalize_or_zero(cross(b - a, c - a));
    if (n == splat(0.0f)) return false;
    V3 p = a * (1.0f - hit.u - hit.v) + b * hit.u + c * hit.v;
    out = make_vertex(SURFACE, p, n, hit.prim, w.beta, false, emission_of(sc, hit.prim));
    if (len + 1 >= max_vertices) return true;
    Frame frame = from_normal(n);
    V3 wo = to_local(frame, -normalize(w.ray.dir));
    float u_lobe = uniform(w.rng);
    V2 u = uniform2(w.rng);
    BsdfSample s;
    if (!sample_f(scene_bsdf(sc, hit.prim, wo), wo, u_lobe, u, radiance, s)) return true;
    out.delta = s.delta;
    w.beta *= s.weight;
    w.bounces += 1;
    if (w.bounces > 3) {
        float q = fminf(max_element(w.beta) * w.rr_scale, 0.95f);
        if (uniform(w.rng) >= q) return true;
        w.beta = w.beta / q;
    }
    if (!is_finite(w.beta) || max_element(w.beta) <= 0.0f) return true;
    V3 wi = to_world(frame, s.wi);
    w.ray = {offset_ray_origin(p, dot(wi, n) > 0.0f ? n : -n), wi, 0.0f, INFINITY};
    w.live = true;
    return true;
}

// ---------------------------------------------------------------- cache/host.rs and bidir.rs

// The cache's rule (cache/kernels.rs `cached`): surface vertices that can connect.
HD bool cached(const Scene& sc, const Vertex& v) { return v.kind == SURFACE && connectible(sc, v); }

// camera_importance's film position (the bounds test is camera_importance's own).
HD V2 film_of(const Scene& sc, V3 w) {
    float cos = dot(w, sc.cam_forward);
    float aspect = (float)sc.width / (float)sc.height;
    V3 p = w / cos;
    float sx = dot(p, sc.cam_right) / (sc.tan_half * aspect), sy = dot(p, sc.cam_up) / sc.tan_half;
    return {(sx + 1.0f) * 0.5f * (float)sc.width, (1.0f - sy) * 0.5f * (float)sc.height};
}

// bidir::connect_to_camera: light vertex s - 1 seen by the camera: value, film position
// and shadow ray.
HD bool connect_to_camera(const Scene& sc, const Vertex* light, int s, const Vertex& cam, V3& l, V2& film, Ray& ray) {
    const Vertex& v = light[s - 1];
    if (!connectible(sc, v) || (s == 1 && is_point_light(v))) return false;
    V3 d = v.p - cam.p;
    float d2 = length_squared(d);
    V3 w = d / sqrtf(d2);
    float we, pdf;
    if (!camera_importance(sc, w, we, pdf)) return false;
    film = film_of(sc, w);
    float cos_cam = dot(w, cam.n);
    V3 f = vertex_f(sc, v, s >= 2 ? &light[s - 2] : nullptr, cam.p, false);
    l = v.beta * f * cos_at(v, -w) * we * cos_cam / d2;
    if (!(max_element(l) > 0.0f)) return false;
    ray = shadow_ray(v, cam);
    return true;
}

// cache::host::light_splats: every camera splat of one light subpath of `len` vertices,
// in vertex order, given to `sink(ray, value, film)`.
template <class S>
HD void light_splats(const Scene& sc, const Vertex* verts, int len, double splat_paths, VertexList& path, S& sink) {
    Vertex cam = camera_vertex(sc);
    float scale = (float)((double)(sc.width * sc.height) / splat_paths);
    for (int s = 1; s <= len; s++) {
        V3 l;
        V2 film;
        Ray ray;
        if (!connect_to_camera(sc, verts, s, cam, l, film, ray)) continue;
        full_path(verts, &cam, s, 1, path);
        float w = mis_weight(sc, path, s);
        sink(ray, l * w * scale, film);
    }
}

// ---------------------------------------------------------------- hits

// The closest-hit key of geometry/hit_key.rs back to a hit: the watertight test run
// again on the winner up to just past its distance, for the barycentrics (as the CPU
// casters do).
HD Hit hit_of(const Scene& sc, const Ray& r, uint64_t key) {
    if (key == wr::NO_HIT) return {INFINITY, NONE, 0.0f, 0.0f};
    uint32_t prim = (uint32_t)key;
    float t = __int_as_float((int)(uint32_t)(key >> 32)), again, u, w;
    const wr::Ray& q = reinterpret_cast<const wr::Ray&>(r);
    const float* v = sc.tris + 9 * (size_t)prim;
    if (!wr::hit_triangle_uv(q.o, wr::make_shear(q.d), v, r.t_min, nextafterf(t, INFINITY), again, u, w))
        return {t, prim, 0.0f, 0.0f};
    return {t, prim, u, w};
}

}  // namespace cis
