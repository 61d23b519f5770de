// The device code of CIS-LBDPT's GPU twins (see cis.cu): the ports of the vectors,
// sampling, BSDFs, lights, bidirectional strategies and `cis::shade`, in namespace
// `cis`. Plain C++ apart from `__device__`, so `cuda/cis_host_check.cpp` can also build
// it for the CPU and check the port without a GPU.
//
// About 1,000 lines: the ports read best next to one another, as the Rust modules do.

#pragma once

#include <cmath>
#include <cstdint>

#include "cis_api.h"

namespace cis {

#define HD __device__ __forceinline__
// The layered stack recurses over its coats: not inlined.
#define HDR static __device__

// ---------------------------------------------------------------- vectors (glam's order of operations)

struct V3 {
    float x, y, z;
};
HD V3 v3(float x, float y, float z) { return {x, y, z}; }
HD V3 splat(float s) { return {s, s, s}; }
HD V3 operator+(V3 a, V3 b) { return {a.x + b.x, a.y + b.y, a.z + b.z}; }
HD V3 operator-(V3 a, V3 b) { return {a.x - b.x, a.y - b.y, a.z - b.z}; }
HD V3 operator-(V3 a) { return {-a.x, -a.y, -a.z}; }
HD V3 operator*(V3 a, V3 b) { return {a.x * b.x, a.y * b.y, a.z * b.z}; }
HD V3 operator*(V3 a, float s) { return {a.x * s, a.y * s, a.z * s}; }
HD V3 operator*(float s, V3 a) { return {s * a.x, s * a.y, s * a.z}; }
HD V3 operator/(V3 a, float s) { return {a.x / s, a.y / s, a.z / s}; }
HD V3& operator+=(V3& a, V3 b) { return a = a + b; }
HD V3& operator*=(V3& a, V3 b) { return a = a * b; }
HD bool operator==(V3 a, V3 b) { return a.x == b.x && a.y == b.y && a.z == b.z; }
HD float dot(V3 a, V3 b) { return a.x * b.x + a.y * b.y + a.z * b.z; }
HD V3 cross(V3 a, V3 b) { return {a.y * b.z - b.y * a.z, a.z * b.x - b.z * a.x, a.x * b.y - b.x * a.y}; }
HD float length_squared(V3 a) { return dot(a, a); }
HD float length(V3 a) { return sqrtf(dot(a, a)); }
HD V3 normalize(V3 a) { return a * (1.0f / length(a)); }
HD V3 normalize_or_zero(V3 a) {
    float r = 1.0f / length(a);
    return (isfinite(r) && r > 0.0f) ? a * r : splat(0.0f);
}
// Rust's f32::max / min: NaN-ignoring, as fmaxf / fminf.
HD float max_element(V3 a) { return fmaxf(fmaxf(a.x, a.y), a.z); }
HD bool is_finite(V3 a) { return isfinite(a.x) && isfinite(a.y) && isfinite(a.z); }
HD V3 vexp(V3 a) { return {expf(a.x), expf(a.y), expf(a.z)}; }
HD float comp(V3 a, int i) { return i == 0 ? a.x : (i == 1 ? a.y : a.z); }
HD float clampf(float x, float lo, float hi) { return fminf(fmaxf(x, lo), hi); }

constexpr float PI = 3.14159265358979323846f;
constexpr float FRAC_1_PI = 0.318309886183790671538f;
constexpr float FRAC_PI_2 = 1.57079632679489661923f;
constexpr float FRAC_PI_4 = 0.785398163397448309616f;
constexpr float SMOOTH = 1e-3f;
constexpr uint32_t NONE = 0xffffffffu;

// ---------------------------------------------------------------- the Rust records

struct Ray {
    V3 origin, dir;
    float t_min, t_max;
};
struct Hit {
    float t;
    uint32_t prim;
    float u, v;
};
struct Rng {
    uint64_t key, counter;
};
enum VertexKind : uint32_t { CAMERA = 0, LIGHT = 1, SURFACE = 2 };
struct Vertex {
    uint32_t kind;
    V3 p, n;
    uint32_t tri;
    V3 beta, le;
    uint8_t delta, pad[3];
};
struct Slot {
    Rng rng;
    Ray ray;
    V3 beta, radiance;
    uint32_t pixel, depth, alive, pad;
};
struct PendingData {
    Ray ray;
    V3 value;
    uint32_t state;
};
static_assert(sizeof(Ray) == 32 && sizeof(Hit) == 16 && sizeof(Vertex) == 60, "layouts");
static_assert(sizeof(Slot) == 88 && sizeof(PendingData) == 48 && sizeof(WrMaterial) == 84, "layouts");
static_assert(sizeof(WrLight) == 48, "layouts");

constexpr int MAX_PATH = 64;                        // limits::MAX_PATH_VERTICES
constexpr int MAX_CAMERA_VERTICES = MAX_PATH / 2;   // cis::kernels
constexpr int MAX_DRAWS = 8;
constexpr int PENDING_PER_SLOT = 2 + MAX_DRAWS;
constexpr int MAX_CANDIDATES = 32;                  // lvc

HD Vertex make_vertex(uint32_t kind, V3 p, V3 n, uint32_t tri, V3 beta, bool delta, V3 le) {
    Vertex v;
    v.kind = kind;
    v.p = p;
    v.n = n;
    v.tri = tri;
    v.beta = beta;
    v.le = le;
    v.delta = delta;
    v.pad[0] = v.pad[1] = v.pad[2] = 0;
    return v;
}
HD bool is_point_light(const Vertex& v) { return v.kind == LIGHT && v.n == splat(0.0f); }

struct VertexList {
    Vertex v[MAX_PATH];
    int len = 0;
    HD void clear() { len = 0; }
    HD void push(const Vertex& x) { v[len++] = x; }
};

// ---------------------------------------------------------------- sampling.rs

HD uint64_t mix64(uint64_t z) {
    z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ull;
    z = (z ^ (z >> 27)) * 0x94d049bb133111ebull;
    return z ^ (z >> 31);
}
HD float uniform(Rng& r) {
    r.counter += 1;
    uint64_t bits = mix64(r.key + r.counter * 0x9e3779b97f4a7c15ull);
    return (float)(bits >> 40) * (1.0f / (float)(1ull << 24));
}
struct V2 {
    float x, y;
};
HD V2 uniform2(Rng& r) {
    float a = uniform(r);
    float b = uniform(r);
    return {a, b};
}

struct Frame {
    V3 s, t, n;
};
HD Frame from_normal(V3 n) {
    float sign = copysignf(1.0f, n.z);
    float a = -1.0f / (sign + n.z);
    float b = n.x * n.y * a;
    return {v3(1.0f + sign * n.x * n.x * a, sign * b, -sign * n.x), v3(b, sign + n.y * n.y * a, -n.y), n};
}
HD V3 to_local(const Frame& f, V3 v) { return v3(dot(v, f.s), dot(v, f.t), dot(v, f.n)); }
HD V3 to_world(const Frame& f, V3 v) { return f.s * v.x + f.t * v.y + f.n * v.z; }

// sampling.rs `sin_cos_quarter`: sine and cosine on [-pi/4, pi/4], the same
// polynomials in the same order.
HD V2 sin_cos_quarter(float x) {
    float z = x * x;
    float s = ((-1.9515296e-4f * z + 8.3321609e-3f) * z - 1.6666655e-1f) * z * x + x;
    float c = ((2.4433157e-5f * z - 1.3887316e-3f) * z + 4.1666646e-2f) * z * z - 0.5f * z + 1.0f;
    return {s, c};
}
HD V2 concentric_disk(V2 u) {
    V2 o = {2.0f * u.x - 1.0f, 2.0f * u.y - 1.0f};
    if (o.x == 0.0f && o.y == 0.0f) return {0.0f, 0.0f};
    if (fabsf(o.x) > fabsf(o.y)) {
        V2 sc = sin_cos_quarter(FRAC_PI_4 * (o.y / o.x));
        return {sc.y * o.x, sc.x * o.x};
    }
    // At pi/2 - t: the cosine is t's sine and the sine its cosine.
    V2 sc = sin_cos_quarter(FRAC_PI_4 * (o.x / o.y));
    return {sc.x * o.y, sc.y * o.y};
}
HD V3 cosine_hemisphere(V2 u) {
    V2 d = concentric_disk(u);
    return v3(d.x, d.y, sqrtf(fmaxf(1.0f - (d.x * d.x + d.y * d.y), 0.0f)));
}

HD float luminance(V3 c) { return 0.2126f * c.x + 0.7152f * c.y + 0.0722f * c.z; }

// ---------------------------------------------------------------- microfacet.rs

struct Ggx {
    float alpha;
};
HD float ggx_d(Ggx g, V3 wm) {
    if (wm.z <= 0.0f) return 0.0f;
    float a2 = g.alpha * g.alpha;
    float c2 = wm.z * wm.z;
    float denom = c2 * (a2 - 1.0f) + 1.0f;
    return a2 / (PI * denom * denom);
}
HD float ggx_lambda(Ggx g, V3 w) {
    float c2 = w.z * w.z;
    if (c2 == 0.0f) return INFINITY;
    float tan2 = fmaxf((1.0f - c2) / c2, 0.0f);
    return 0.5f * (sqrtf(1.0f + g.alpha * g.alpha * tan2) - 1.0f);
}
HD float ggx_g1(Ggx g, V3 w) { return 1.0f / (1.0f + ggx_lambda(g, w)); }
HD float ggx_g2(Ggx g, V3 wo, V3 wi) { return 1.0f / (1.0f + ggx_lambda(g, wo) + ggx_lambda(g, wi)); }
HD float visible_pdf(Ggx g, V3 wo, V3 wm) { return ggx_g1(g, wo) * fmaxf(dot(wo, wm), 0.0f) * ggx_d(g, wm) / wo.z; }
HD V3 sample_visible(Ggx g, V3 wo, V2 u) {
    float a = g.alpha;
    V3 vh = normalize(v3(a * wo.x, a * wo.y, wo.z));
    float len2 = vh.x * vh.x + vh.y * vh.y;
    V3 t1 = len2 > 0.0f ? v3(-vh.y, vh.x, 0.0f) / sqrtf(len2) : v3(1.0f, 0.0f, 0.0f);
    V3 t2 = cross(vh, t1);
    float r = sqrtf(u.x);
    float phi = 2.0f * PI * u.y;
    float p1 = r * cosf(phi);
    float s = 0.5f * (1.0f + vh.z);
    float p2 = (1.0f - s) * sqrtf(fmaxf(1.0f - p1 * p1, 0.0f)) + s * r * sinf(phi);
    V3 nh = t1 * p1 + t2 * p2 + vh * sqrtf(fmaxf(1.0f - p1 * p1 - p2 * p2, 0.0f));
    return normalize(v3(a * nh.x, a * nh.y, fmaxf(nh.z, 1e-6f)));
}
// reflection(): value, pdf and wm, or false.
HD bool ggx_reflection(Ggx g, V3 wo, V3 wi, float& value, float& pdf, V3& wm) {
    if (wo.z <= 0.0f || wi.z <= 0.0f) return false;
    wm = normalize_or_zero(wo + wi);
    if (wm == splat(0.0f)) return false;
    value = ggx_d(g, wm) * ggx_g2(g, wo, wi) / (4.0f * wo.z * wi.z);
    pdf = visible_pdf(g, wo, wm) / (4.0f * dot(wo, wm));
    return true;
}
HD float fresnel_dielectric(float cos_i, float eta) {
    cos_i = clampf(cos_i, 0.0f, 1.0f);
    float sin2_t = (1.0f - cos_i * cos_i) / (eta * eta);
    if (sin2_t >= 1.0f) return 1.0f;
    float cos_t = sqrtf(1.0f - sin2_t);
    float r_par = (eta * cos_i - cos_t) / (eta * cos_i + cos_t);
    float r_perp = (cos_i - eta * cos_t) / (cos_i + eta * cos_t);
    return 0.5f * (r_par * r_par + r_perp * r_perp);
}
HD float fresnel_conductor1(float c, float c2, float s2, float eta, float k) {
    float t0 = eta * eta - k * k - s2;
    float a2b2 = sqrtf(fmaxf(t0 * t0 + 4.0f * eta * eta * k * k, 0.0f));
    float t1 = a2b2 + c2;
    float a = sqrtf(fmaxf(0.5f * (a2b2 + t0), 0.0f));
    float t2 = 2.0f * c * a;
    float rs = (t1 - t2) / (t1 + t2);
    float t3 = c2 * a2b2 + s2 * s2;
    float t4 = t2 * s2;
    float rp = rs * (t3 - t4) / (t3 + t4);
    return clampf(0.5f * (rp + rs), 0.0f, 1.0f);
}
HD V3 fresnel_conductor(float cos_i, V3 eta, V3 k) {
    float c = clampf(cos_i, 0.0f, 1.0f);
    float c2 = c * c, s2 = 1.0f - c * c;
    return v3(fresnel_conductor1(c, c2, s2, eta.x, k.x), fresnel_conductor1(c, c2, s2, eta.y, k.y),
              fresnel_conductor1(c, c2, s2, eta.z, k.z));
}
HD bool refract(V3 w, V3 n, float eta, V3& out) {
    float cos_i = dot(n, w);
    float sin2_t = fmaxf(1.0f - cos_i * cos_i, 0.0f) / (eta * eta);
    if (sin2_t >= 1.0f) return false;
    float cos_t = sqrtf(1.0f - sin2_t);
    out = -w / eta + n * (cos_i / eta - cos_t);
    return true;
}
// rough_dielectric(): (value, pdf) for wo.z > 0. radiance: TransportMode::Radiance.
HD void rough_dielectric(Ggx g, float eta, V3 wo, V3 wi, bool radiance, float& value, float& pdf) {
    value = pdf = 0.0f;
    float cos_o = wo.z, cos_i = wi.z;
    if (cos_o <= 0.0f || cos_i == 0.0f) return;
    bool reflect = cos_i > 0.0f;
    float etap = reflect ? 1.0f : eta;
    V3 wm = wi * etap + wo;
    if (length_squared(wm) == 0.0f) return;
    wm = normalize(wm);
    if (wm.z < 0.0f) wm = -wm;
    if (dot(wm, wi) * cos_i < 0.0f || dot(wm, wo) * cos_o < 0.0f) return;
    float fr = fresnel_dielectric(dot(wo, wm), eta);
    float vis = visible_pdf(g, wo, wm);
    if (reflect) {
        value = ggx_d(g, wm) * ggx_g2(g, wo, wi) * fr / (4.0f * cos_o * cos_i);
        pdf = vis / (4.0f * dot(wo, wm)) * fr;
    } else {
        float denom = dot(wi, wm) + dot(wo, wm) / etap;
        float denom2 = denom * denom;
        value = ggx_d(g, wm) * (1.0f - fr) * ggx_g2(g, wo, wi) *
                fabsf(dot(wi, wm) * dot(wo, wm) / (cos_i * cos_o * denom2));
        if (radiance) value /= etap * etap;
        pdf = vis * (fabsf(dot(wi, wm)) / denom2) * (1.0f - fr);
    }
}
HD bool sample_rough_dielectric(Ggx g, float eta, V3 wo, float u_lobe, V2 u, V3& wi) {
    V3 wm = sample_visible(g, wo, u);
    float fr = fresnel_dielectric(dot(wo, wm), eta);
    if (u_lobe < fr) {
        wi = 2.0f * dot(wo, wm) * wm - wo;
        return wi.z > 0.0f;
    }
    if (!refract(wo, wm, eta, wi)) return false;
    return wi.z < 0.0f;
}

// ---------------------------------------------------------------- bsdf/mod.rs and layered.rs

struct BsdfSample {
    V3 wi, f;
    float pdf;
    V3 weight;
    bool delta;
};
HD V3 flip(V3 w) { return v3(w.x, w.y, -w.z); }
HD V3 reflect_z(V3 w) { return v3(-w.x, -w.y, w.z); }
HD bool continuous(V3 wi, V3 f, float pdf, BsdfSample& s) {
    if (!(pdf > 0.0f && wi.z != 0.0f)) return false;
    s = {wi, f, pdf, f * fabsf(wi.z) / pdf, false};
    return true;
}
HD V3 ma(const WrMaterial& m) { return v3(m.a[0], m.a[1], m.a[2]); }
HD V3 mb(const WrMaterial& m) { return v3(m.b[0], m.b[1], m.b[2]); }
HD bool is_dielectric(const WrMaterial& m) { return m.kind == 3 || m.kind == 5; }
HD bool layered_is_delta(const WrMaterial& m) {
    for (uint32_t c = 0; c < m.coat_count; c++)
        if (!(m.coat_roughness[c] < SMOOTH)) return false;
    return m.base_kind == 1 && m.roughness < SMOOTH;
}
HD bool is_delta(const WrMaterial& m) {
    switch (m.kind) {
        case 2: case 3: return true;
        case 4: case 5: return m.roughness < SMOOTH;
        case 6: return layered_is_delta(m);
        default: return false;
    }
}
HD float specular_weight(V3 d, V3 s) {
    float ld = luminance(d), ls = luminance(s);
    return ld + ls > 0.0f ? ls / (ld + ls) : 0.0f;
}

// layered.rs
HD V3 into_film(V3 w, float ior) {
    float tx = w.x / ior, ty = w.y / ior;
    return v3(tx, ty, sqrtf(fmaxf(1.0f - (tx * tx + ty * ty), 0.0f)));
}
HD bool out_of_film(V3 w, float ior, V3& out) {
    float tx = w.x * ior, ty = w.y * ior;
    float s2 = tx * tx + ty * ty;
    if (!(s2 < 1.0f)) return false;
    out = v3(tx, ty, sqrtf(1.0f - s2));
    return true;
}
HD V3 attenuation(const WrMaterial& m, int c, V3 wo, V3 wi) {
    V3 ab = v3(m.coat_absorption[c][0], m.coat_absorption[c][1], m.coat_absorption[c][2]);
    return vexp(-ab * (1.0f / fmaxf(wo.z, 1e-6f) + 1.0f / fmaxf(wi.z, 1e-6f)));
}
HD V3 base_f(const WrMaterial& m, V3 wo, V3 wi) {
    if (m.base_kind == 0) return ma(m) * FRAC_1_PI;
    if (m.roughness >= SMOOTH) {
        float v, p;
        V3 wm;
        if (!ggx_reflection({m.roughness}, wo, wi, v, p, wm)) return splat(0.0f);
        return fresnel_conductor(dot(wo, wm), ma(m), mb(m)) * v;
    }
    return splat(0.0f);
}
HD float base_pdf(const WrMaterial& m, V3 wo, V3 wi) {
    if (m.base_kind == 0) return wi.z * FRAC_1_PI;
    if (m.roughness >= SMOOTH) {
        float v, p;
        V3 wm;
        return ggx_reflection({m.roughness}, wo, wi, v, p, wm) ? p : 0.0f;
    }
    return 0.0f;
}
HD bool base_sample(const WrMaterial& m, V3 wo, V2 u, BsdfSample& s) {
    if (m.base_kind == 0) {
        V3 wi = cosine_hemisphere(u);
        float pdf = wi.z * FRAC_1_PI;
        if (!(pdf > 0.0f)) return false;
        s = {wi, ma(m) * FRAC_1_PI, pdf, ma(m), false};
        return true;
    }
    if (m.roughness >= SMOOTH) {
        Ggx g = {m.roughness};
        V3 wm = sample_visible(g, wo, u);
        V3 wi = 2.0f * dot(wo, wm) * wm - wo;
        float v, pdf;
        V3 wm2;
        if (!ggx_reflection(g, wo, wi, v, pdf, wm2)) return false;
        V3 f = fresnel_conductor(dot(wo, wm), ma(m), mb(m)) * v;
        if (!(pdf > 0.0f)) return false;
        s = {wi, f, pdf, f * wi.z / pdf, false};
        return true;
    }
    V3 wi = v3(-wo.x, -wo.y, wo.z);
    V3 fr = fresnel_conductor(wo.z, ma(m), mb(m));
    s = {wi, fr / wi.z, 1.0f, fr, true};
    return true;
}
HDR V3 f_stack(const WrMaterial& m, int c, V3 wo, V3 wi) {
    if (wo.z <= 0.0f || wi.z <= 0.0f) return splat(0.0f);
    if (c >= (int)m.coat_count) return base_f(m, wo, wi);
    float ior = m.coat_ior[c], rough = m.coat_roughness[c];
    float top = 0.0f;
    if (rough >= SMOOTH) {
        float v, p;
        V3 wm;
        if (ggx_reflection({rough}, wo, wi, v, p, wm)) top = v * fresnel_dielectric(dot(wo, wm), ior);
    }
    V3 wo2 = into_film(wo, ior), wi2 = into_film(wi, ior);
    float trans = (1.0f - fresnel_dielectric(wo.z, ior)) * (1.0f - fresnel_dielectric(wi.z, ior)) / (ior * ior);
    return splat(top) + attenuation(m, c, wo2, wi2) * f_stack(m, c + 1, wo2, wi2) * trans;
}
HDR float pdf_stack(const WrMaterial& m, int c, V3 wo, V3 wi) {
    if (wo.z <= 0.0f || wi.z <= 0.0f) return 0.0f;
    if (c >= (int)m.coat_count) return base_pdf(m, wo, wi);
    float ior = m.coat_ior[c], rough = m.coat_roughness[c];
    float p_coat = fresnel_dielectric(wo.z, ior);
    float top = 0.0f;
    if (rough >= SMOOTH) {
        float v, p;
        V3 wm;
        if (ggx_reflection({rough}, wo, wi, v, p, wm)) top = p;
    }
    V3 wo2 = into_film(wo, ior), wi2 = into_film(wi, ior);
    float jacobian = wi.z / (ior * ior * fmaxf(wi2.z, 1e-9f));
    return p_coat * top + (1.0f - p_coat) * pdf_stack(m, c + 1, wo2, wi2) * jacobian;
}
HDR bool sample_stack(const WrMaterial& m, int c, V3 wo, float u_lobe, V2 u, BsdfSample& s) {
    if (c >= (int)m.coat_count) return base_sample(m, wo, u, s);
    float ior = m.coat_ior[c], rough = m.coat_roughness[c];
    float p_coat = fresnel_dielectric(wo.z, ior);
    if (u_lobe < p_coat) {
        if (rough >= SMOOTH) {
            V3 wm = sample_visible({rough}, wo, u);
            V3 wi = 2.0f * dot(wo, wm) * wm - wo;
            if (!(wi.z > 0.0f)) return false;
            s = {wi, splat(0.0f), 0.0f, splat(0.0f), false};
            return true;
        }
        V3 wi = v3(-wo.x, -wo.y, wo.z);
        s = {wi, splat(p_coat / wi.z), p_coat, splat(1.0f), true};
        return true;
    }
    u_lobe = clampf((u_lobe - p_coat) / (1.0f - p_coat), 0.0f, 1.0f - 1.1920929e-7f);
    V3 wo2 = into_film(wo, ior);
    BsdfSample below;
    if (!sample_stack(m, c + 1, wo2, u_lobe, u, below)) return false;
    if (below.wi.z <= 0.0f) return false;
    V3 wi;
    if (!out_of_film(below.wi, ior, wi)) return false;
    if (!below.delta) {
        s = below;
        s.wi = wi;
        return true;
    }
    V3 weight = below.weight * attenuation(m, c, wo2, below.wi) * (1.0f - fresnel_dielectric(wi.z, ior));
    float pdf = (1.0f - p_coat) * below.pdf;
    s = {wi, weight * pdf / wi.z, pdf, weight, true};
    return true;
}

// Rough glass from either side: `wo` brought to +z, the index inverted from below.
HD void rough_glass(const WrMaterial& m, V3 wo, V3 wi, bool radiance, float& v, float& p) {
    float eta = m.ior;
    if (wo.z < 0.0f) {
        wo = flip(wo);
        wi = flip(wi);
        eta = 1.0f / m.ior;
    }
    rough_dielectric({m.roughness}, eta, wo, wi, radiance, v, p);
}

HD V3 bsdf_f(const WrMaterial& m, V3 wo, V3 wi, bool radiance) {
    if (m.kind == 5) {
        if (m.roughness < SMOOTH) return splat(0.0f);
        float v, p;
        rough_glass(m, wo, wi, radiance, v, p);
        return wo.z * wi.z < 0.0f ? ma(m) * v : splat(v);
    }
    if (wo.z < 0.0f) {
        wo = flip(wo);
        wi = flip(wi);
    }
    if (wi.z <= 0.0f || wo.z <= 0.0f) return splat(0.0f);
    switch (m.kind) {
        case 0: return ma(m) * FRAC_1_PI;
        case 1: {
            float v = 0.0f, p;
            V3 wm;
            if (!ggx_reflection({m.roughness}, wo, wi, v, p, wm)) v = 0.0f;
            return ma(m) * FRAC_1_PI + mb(m) * v;
        }
        case 4: {
            if (!(m.roughness >= SMOOTH)) return splat(0.0f);
            float v, p;
            V3 wm;
            if (!ggx_reflection({m.roughness}, wo, wi, v, p, wm)) return splat(0.0f);
            return fresnel_conductor(dot(wo, wm), ma(m), mb(m)) * v;
        }
        case 6: return f_stack(m, 0, wo, wi);
        default: return splat(0.0f);
    }
}
HD float bsdf_pdf(const WrMaterial& m, V3 wo, V3 wi) {
    if (m.kind == 5) {
        if (m.roughness < SMOOTH) return 0.0f;
        float v, p;
        rough_glass(m, wo, wi, true, v, p);
        return p;
    }
    if (wo.z < 0.0f) {
        wo = flip(wo);
        wi = flip(wi);
    }
    if (wi.z <= 0.0f || wo.z <= 0.0f) return 0.0f;
    switch (m.kind) {
        case 0: return wi.z * FRAC_1_PI;
        case 1: {
            float ws = specular_weight(ma(m), mb(m));
            float v, spec = 0.0f;
            V3 wm;
            if (!ggx_reflection({m.roughness}, wo, wi, v, spec, wm)) spec = 0.0f;
            return (1.0f - ws) * wi.z * FRAC_1_PI + ws * spec;
        }
        case 4: {
            if (!(m.roughness >= SMOOTH)) return 0.0f;
            float v, p;
            V3 wm;
            return ggx_reflection({m.roughness}, wo, wi, v, p, wm) ? p : 0.0f;
        }
        case 6: return pdf_stack(m, 0, wo, wi);
        default: return 0.0f;
    }
}
HD bool sample_f(const WrMaterial& m, V3 wo, float u_lobe, V2 u, bool radiance, BsdfSample& s) {
    if (wo.z == 0.0f) return false;
    float side = wo.z < 0.0f ? -1.0f : 1.0f;
    V3 wo_up = v3(wo.x, wo.y, wo.z * side);
    auto to_side = [&](V3 w) { return v3(w.x, w.y, w.z * side); };
    switch (m.kind) {
        case 0:
        case 1: {
            V3 wi_up;
            if (m.kind == 1 && u_lobe < specular_weight(ma(m), mb(m))) {
                V3 wm = sample_visible({m.roughness}, wo_up, u);
                wi_up = 2.0f * dot(wo_up, wm) * wm - wo_up;
            } else {
                wi_up = cosine_hemisphere(u);
            }
            if (wi_up.z <= 0.0f) return false;
            V3 wi = to_side(wi_up);
            return continuous(wi, bsdf_f(m, wo, wi, radiance), bsdf_pdf(m, wo, wi), s);
        }
        case 4: {
            if (m.roughness < SMOOTH) {
                V3 wi = reflect_z(wo);
                V3 fr = fresnel_conductor(wo_up.z, ma(m), mb(m));
                s = {wi, fr / fabsf(wi.z), 1.0f, fr, true};
                return true;
            }
            V3 wm = sample_visible({m.roughness}, wo_up, u);
            V3 wi_up = 2.0f * dot(wo_up, wm) * wm - wo_up;
            if (wi_up.z <= 0.0f) return false;
            V3 wi = to_side(wi_up);
            return continuous(wi, bsdf_f(m, wo, wi, radiance), bsdf_pdf(m, wo, wi), s);
        }
        case 6: {
            BsdfSample l;
            if (!sample_stack(m, 0, wo_up, u_lobe, u, l)) return false;
            if (!l.delta) {
                // Layered::sample: continuous samples carry the whole stack's value and density.
                V3 f = f_stack(m, 0, wo_up, l.wi);
                float pdf = pdf_stack(m, 0, wo_up, l.wi);
                if (!(pdf > 0.0f)) return false;
                l = {l.wi, f, pdf, f * l.wi.z / pdf, false};
            }
            s = l;
            s.wi = to_side(l.wi);
            return true;
        }
        case 2: {
            V3 wi = reflect_z(wo);
            s = {wi, ma(m) / fabsf(wi.z), 1.0f, ma(m), true};
            return true;
        }
        default: break;  // glass and rough glass below
    }
    if (m.kind == 5 && m.roughness >= SMOOTH) {
        float eta = wo.z > 0.0f ? m.ior : 1.0f / m.ior;
        V3 wi_up;
        if (!sample_rough_dielectric({m.roughness}, eta, wo_up, u_lobe, u, wi_up)) return false;
        V3 wi = to_side(wi_up);
        return continuous(wi, bsdf_f(m, wo, wi, radiance), bsdf_pdf(m, wo, wi), s);
    }
    bool entering = wo.z > 0.0f;
    float eta = entering ? m.ior : 1.0f / m.ior;
    float fr = fresnel_dielectric(fabsf(wo.z), eta);
    if (u_lobe < fr) {
        V3 wi = reflect_z(wo);
        s = {wi, splat(fr / fabsf(wi.z)), fr, splat(1.0f), true};
        return true;
    }
    float cos_i = fabsf(wo.z);
    float sin2_t = (1.0f - cos_i * cos_i) / (eta * eta);
    float cos_t = sqrtf(fmaxf(1.0f - sin2_t, 0.0f));
    V3 wi = v3(-wo.x / eta, -wo.y / eta, -side * cos_t);
    float scale = radiance ? 1.0f / (eta * eta) : 1.0f;
    V3 ft = ma(m) * ((1.0f - fr) * scale / fmaxf(cos_t, 1e-12f));
    s = {wi, ft, 1.0f - fr, ma(m) * scale, true};
    return true;
}

// ---------------------------------------------------------------- the scene on the device

struct Scene {
    const float* tris;
    const uint32_t* material_of;
    const WrMaterial* materials;
    const uint32_t* two_sided;
    const float* emission;
    const WrLight* lights;
    const float* light_cdf;
    const uint32_t* light_of_tri;
    uint32_t n_lights;
    V3 cam_position, cam_forward, cam_right, cam_up;
    float tan_half, margin;
    uint32_t width, height, max_depth;
    uint32_t resampled, candidates, draws;
    const Vertex* cache_vertices;
    const uint32_t* cache_entries;
    uint64_t n_entries;
    double count_splat, count_connection;
};

HD void vertices_of(const Scene& sc, uint32_t tri, V3& a, V3& b, V3& c) {
    const float* t = sc.tris + 9 * (size_t)tri;
    a = v3(t[0], t[1], t[2]);
    b = v3(t[3], t[4], t[5]);
    c = v3(t[6], t[7], t[8]);
}
HD V3 emission_of(const Scene& sc, uint32_t tri) {
    const float* e = sc.emission + 3 * (size_t)sc.material_of[tri];
    return v3(e[0], e[1], e[2]);
}
__device__ const WrMaterial BLACK = {0, 0, 0, 0.0f, 0.0f, {0, 0, 0}, {0, 0, 0}, {0, 0}, {0, 0}, {{0, 0, 0}, {0, 0, 0}}};
// Scene::bsdf: the material, or black behind a one-sided opaque surface.
HD const WrMaterial& scene_bsdf(const Scene& sc, uint32_t tri, V3 wo_local) {
    uint32_t m = sc.material_of[tri];
    if (wo_local.z < 0.0f && !sc.two_sided[m] && !is_dielectric(sc.materials[m])) return BLACK;
    return sc.materials[m];
}

// lights.rs
struct LightSample {
    V3 position, normal, emitted;
    float pdf;
    bool is_delta;
    uint32_t tri;
};
HD float select_pdf(const Scene& sc, uint32_t i) { return sc.light_cdf[i] - (i == 0 ? 0.0f : sc.light_cdf[i - 1]); }
HD bool light_sample(const Scene& sc, float u_select, V2 u, LightSample& ls) {
    if (sc.n_lights == 0) return false;
    uint32_t lo = 0, hi = sc.n_lights;  // partition_point(c <= u_select)
    while (lo < hi) {
        uint32_t mid = (lo + hi) / 2;
        if (sc.light_cdf[mid] <= u_select) lo = mid + 1;
        else hi = mid;
    }
    uint32_t i = lo < sc.n_lights - 1 ? lo : sc.n_lights - 1;
    float p_sel = select_pdf(sc, i);
    if (p_sel <= 0.0f) return false;
    const WrLight& l = sc.lights[i];
    if (l.kind == 0) {
        V3 a, b, c;
        vertices_of(sc, l.tri, a, b, c);
        float su = sqrtf(u.x);
        float b1 = su * (1.0f - u.y), b2 = su * u.y;
        V3 position = a * (1.0f - b1 - b2) + b * b1 + c * b2;
        ls = {position, v3(l.normal[0], l.normal[1], l.normal[2]), v3(l.value[0], l.value[1], l.value[2]),
              p_sel / l.area, false, l.tri};
    } else {
        ls = {v3(l.position[0], l.position[1], l.position[2]), splat(0.0f), v3(l.value[0], l.value[1], l.value[2]),
              p_sel, true, NONE};
    }
    return true;
}
HD float point_select_pdf(const Scene& sc, V3 position) {
    for (uint32_t i = 0; i < sc.n_lights; i++) {
        const WrLight& l = sc.lights[i];
        if (l.kind == 1 && v3(l.position[0], l.position[1], l.position[2]) == position) return select_pdf(sc, i);
    }
    return 0.0f;
}
HD float light_pdf_area(const Scene& sc, uint32_t tri) {
    uint32_t i = sc.light_of_tri[tri];
    if (i == NONE || sc.lights[i].kind != 0) return 0.0f;
    return select_pdf(sc, i) / sc.lights[i].area;
}

// ---------------------------------------------------------------- bidir.rs

// camera_importance: (We, pdf); false outside the image grown by the margin.
HD bool camera_importance(const Scene& sc, V3 w, float& we, float& pdf) {
    float cos = dot(w, sc.cam_forward);
    if (cos <= 0.0f) return false;
    float aspect = (float)sc.width / (float)sc.height;
    V3 p = w / cos;
    float sx = dot(p, sc.cam_right) / (sc.tan_half * aspect), sy = dot(p, sc.cam_up) / sc.tan_half;
    float fx = (sx + 1.0f) * 0.5f * (float)sc.width, fy = (1.0f - sy) * 0.5f * (float)sc.height;
    auto inside = [&](float v, uint32_t n) { return v >= -sc.margin && v <= (float)n + sc.margin; };
    if (!(inside(fx, sc.width) && inside(fy, sc.height))) return false;
    float area = 4.0f * sc.tan_half * sc.tan_half * aspect;
    float cos2 = cos * cos;
    we = 1.0f / (area * cos2 * cos2);
    pdf = 1.0f / (area * cos2 * cos);
    return true;
}
HD float cos_at(const Vertex& v, V3 w) { return (v.kind == LIGHT && v.n == splat(0.0f)) ? 1.0f : fabsf(dot(v.n, w)); }
HD float pdf_area(const Scene& sc, const Vertex* prev, const Vertex& cur, const Vertex& next) {
    V3 d = next.p - cur.p;
    float d2 = length_squared(d);
    if (d2 == 0.0f) return 0.0f;
    V3 w = d / sqrtf(d2);
    float pdf_dir;
    if (cur.kind == CAMERA) {
        float we, pdf;
        pdf_dir = camera_importance(sc, w, we, pdf) ? pdf : 0.0f;
    } else if (cur.kind == LIGHT && cur.n == splat(0.0f)) {
        pdf_dir = 1.0f / (4.0f * PI);
    } else if (cur.kind == LIGHT) {
        pdf_dir = fmaxf(dot(cur.n, w), 0.0f) * FRAC_1_PI;
    } else {
        if (cur.delta) return 1.0f;
        if (!prev) return 0.0f;
        Frame f = from_normal(cur.n);
        V3 wo = to_local(f, normalize(prev->p - cur.p));
        pdf_dir = bsdf_pdf(scene_bsdf(sc, cur.tri, wo), wo, to_local(f, w));
    }
    float cos_next = next.kind == CAMERA ? fabsf(dot(w, next.n)) : cos_at(next, w);
    return pdf_dir * cos_next / d2;
}
HD float light_origin_pdf(const Scene& sc, const Vertex& v) {
    return v.n == splat(0.0f) ? point_select_pdf(sc, v.p) : light_pdf_area(sc, v.tri);
}
HD double strategy_count(const Scene& sc, int s, int t) {
    if (t == 1) return sc.count_splat;
    if (s >= 2) return sc.count_connection;
    return 1.0;
}
HD bool connectible_v(const Vertex& v) { return v.kind != SURFACE || !v.delta; }
// mis_weight_counts over `path` (k + 1 vertices), strategy s, LVC's counts.
HD float mis_weight(const Scene& sc, const VertexList& path, int s) {
    int k = path.len - 1;
    double pl[MAX_PATH], pc[MAX_PATH];
    for (int i = 0; i <= k; i++) {
        pl[i] = i == 0 ? (double)light_origin_pdf(sc, path.v[0])
                       : (double)pdf_area(sc, i >= 2 ? &path.v[i - 2] : nullptr, path.v[i - 1], path.v[i]);
        pc[i] = i == k ? 1.0 : (double)pdf_area(sc, i + 2 <= k ? &path.v[i + 2] : nullptr, path.v[i + 1], path.v[i]);
    }
    auto valid = [&](int s) {
        int t = k + 1 - s;
        if (t == 0) return false;
        if (s == 0) return !is_point_light(path.v[0]);
        if (s == 1 && t == 1 && is_point_light(path.v[0])) return false;
        return connectible_v(path.v[s - 1]) && connectible_v(path.v[s]);
    };
    auto p = [&](int s) {
        double a = 1.0, b = 1.0;
        for (int i = 0; i < s; i++) a *= pl[i];
        for (int i = s; i <= k; i++) b *= pc[i];
        return strategy_count(sc, s, k + 1 - s) * a * b;
    };
    double total = 0.0;
    for (int i = 0; i <= k; i++)
        if (valid(i)) total += p(i);
    return (total > 0.0 && valid(s)) ? (float)(p(s) / total) : 0.0f;
}
HD V3 vertex_f(const Scene& sc, const Vertex& v, const Vertex* prev, V3 toward, bool radiance) {
    V3 w = normalize(toward - v.p);
    if (v.kind == LIGHT) return (v.n == splat(0.0f) || dot(v.n, w) > 0.0f) ? v.le : splat(0.0f);
    if (v.kind == SURFACE) {
        if (!prev) return splat(0.0f);
        Frame f = from_normal(v.n);
        V3 wo = to_local(f, normalize(prev->p - v.p));
        return bsdf_f(scene_bsdf(sc, v.tri, wo), wo, to_local(f, w), radiance);
    }
    return splat(0.0f);
}
// geometry::offset_ray_origin
HD V3 offset_ray_origin(V3 p, V3 n) {
    const float NEAR_ORIGIN = 1.0f / 32.0f, FLOAT_STEP = 1.0f / 65536.0f, ULP_STEP = 256.0f;
    float in[3] = {p.x, p.y, p.z}, nn[3] = {n.x, n.y, n.z}, out[3];
    for (int a = 0; a < 3; a++) {
        int ulps = (int)(ULP_STEP * nn[a]);
        int bits = __float_as_int(in[a]);
        float stepped = __int_as_float(in[a] < 0.0f ? bits - ulps : bits + ulps);
        out[a] = fabsf(in[a]) < NEAR_ORIGIN ? in[a] + FLOAT_STEP * nn[a] : stepped;
    }
    return v3(out[0], out[1], out[2]);
}
HD Ray shadow_ray(const Vertex& a, const Vertex& b) {
    auto off = [](const Vertex& v, V3 toward) {
        if (v.kind == CAMERA || v.n == splat(0.0f)) return v.p;
        V3 n = dot(v.n, toward - v.p) > 0.0f ? v.n : -v.n;
        return offset_ray_origin(v.p, n);
    };
    V3 pa = off(a, b.p), pb = off(b, a.p);
    return {pa, pb - pa, 0.0f, 1.0f - 1e-4f};
}
HD bool connectible(const Scene& sc, const Vertex& v) {
    return v.kind != SURFACE || !is_delta(sc.materials[sc.material_of[v.tri]]);
}
HD void full_path(const Vertex* light, const Vertex* cam, int s, int t, VertexList& out) {
    out.clear();
    for (int i = 0; i < s; i++) out.push(light[i]);
    for (int i = t - 1; i >= 0; i--) out.push(cam[i]);
    if (s > 0) out.v[s - 1].delta = is_point_light(out.v[s - 1]);
    if (t > 0) out.v[s].delta = false;
}
HD bool strategy_emitter(const Vertex* cam, int t, VertexList& path, V3& l) {
    const Vertex& v = cam[t - 1];
    if (max_element(v.le) <= 0.0f || dot(v.n, cam[t - 2].p - v.p) <= 0.0f) return false;
    full_path(nullptr, cam, 0, t, path);
    path.v[0].kind = LIGHT;
    l = v.beta * v.le;
    return true;
}
HD bool strategy_light_sample(const Scene& sc, const Vertex* cam, int t, Rng& rng, VertexList& path, V3& l, Ray& ray) {
    const Vertex& c = cam[t - 1];
    if (!connectible(sc, c)) return false;
    float u_sel = uniform(rng);
    V2 u = uniform2(rng);
    LightSample ls;
    if (!light_sample(sc, u_sel, u, ls)) return false;
    Vertex lv = make_vertex(LIGHT, ls.position, ls.normal, ls.tri, splat(1.0f / ls.pdf), ls.is_delta, ls.emitted);
    V3 d = lv.p - c.p;
    float d2 = length_squared(d);
    if (d2 == 0.0f) return false;
    V3 wdir = d / sqrtf(d2);
    V3 le = vertex_f(sc, lv, nullptr, c.p, false);
    V3 f = vertex_f(sc, c, t >= 2 ? &cam[t - 2] : nullptr, lv.p, true);
    float g = cos_at(c, wdir) * cos_at(lv, wdir) / d2;
    l = c.beta * f * le * lv.beta * g;
    if (max_element(l) <= 0.0f) return false;
    path.clear();
    path.push(lv);
    for (int i = t - 1; i >= 0; i--) path.push(cam[i]);
    path.v[1].delta = false;
    ray = shadow_ray(c, lv);
    return true;
}
HD bool connect_contribution(const Scene& sc, const Vertex& lv, const Vertex* lv_prev, const Vertex* cam, int t, V3& l) {
    const Vertex& c = cam[t - 1];
    if (!connectible(sc, lv) || !connectible(sc, c)) return false;
    V3 d = lv.p - c.p;
    float d2 = length_squared(d);
    if (d2 == 0.0f) return false;
    V3 wdir = d / sqrtf(d2);
    V3 fl = vertex_f(sc, lv, lv_prev, c.p, false);
    V3 fc = vertex_f(sc, c, t >= 2 ? &cam[t - 2] : nullptr, lv.p, true);
    float g = cos_at(lv, wdir) * cos_at(c, wdir) / d2;
    l = lv.beta * fl * g * fc * c.beta;
    return max_element(l) > 0.0f;
}

// ---------------------------------------------------------------- lvc.rs: vertex_strategies

// CacheRead::subpath: entry e's subpath up to its vertex into `light` (with tail, only
// its last two vertices); returns s.
HD int subpath(const Scene& sc, size_t e, VertexList& light, bool tail) {
    uint32_t start = sc.cache_entries[2 * e], s = sc.cache_entries[2 * e + 1];
    light.clear();
    uint32_t from = tail ? (s >= 2 ? s - 2 : 0) : 0;
    for (uint32_t k = from; k < s; k++) light.push(sc.cache_vertices[start + k]);
    return (int)s;
}
HD size_t uniform_entry(size_t cache_len, Rng& rng) {
    size_t e = (size_t)(uniform(rng) * (float)cache_len);
    return e < cache_len - 1 ? e : cache_len - 1;
}

struct Sink {
    PendingData* out;
    int next;
    HD void operator()(bool has_ray, Ray ray, V3 value) {
        if (next < PENDING_PER_SLOT) {
            PendingData p;
            p.ray = has_ray ? ray : Ray{splat(0.0f), splat(0.0f), 0.0f, 0.0f};
            p.value = value;
            p.state = has_ray ? 1 : 2;
            out[next++] = p;
        }
    }
};

// `sink(has_ray, ray, value)` receives each contribution: the stream's pending entries
// (Sink), or the megakernel's shadow ray traced at once.
template <class S>
__device__ void vertex_strategies(const Scene& sc, const Vertex* cam, int t, Rng& rng, VertexList& path,
                                  VertexList& light, S& sink) {
    int max_depth = (int)sc.max_depth;
    V3 l;
    Ray ray = {};
    if (t - 2 <= max_depth && strategy_emitter(cam, t, path, l)) sink(false, ray, l * mis_weight(sc, path, 0));
    if (t - 1 <= max_depth && strategy_light_sample(sc, cam, t, rng, path, l, ray))
        sink(true, ray, l * mis_weight(sc, path, 1));
    size_t cache_len = sc.n_entries;
    if (cache_len == 0 || sc.draws == 0 || t > max_depth) return;
    auto connect = [&](size_t e, float extra) {
        int s = subpath(sc, e, light, false);
        if (s + t - 2 > max_depth) return;
        const Vertex& lv = light.v[s - 1];
        V3 c;
        if (!connect_contribution(sc, lv, s >= 2 ? &light.v[s - 2] : nullptr, cam, t, c)) return;
        full_path(light.v, cam, s, t, path);
        Ray r = shadow_ray(lv, cam[t - 1]);
        float w = mis_weight(sc, path, s);
        sink(true, r, c * (w * extra / (float)sc.count_connection));
    };
    if (!sc.resampled) {
        for (uint32_t i = 0; i < sc.draws; i++) connect(uniform_entry(cache_len, rng), 1.0f);
        return;
    }
    int n = (int)sc.candidates;
    n = n < 1 ? 1 : (n > MAX_CANDIDATES ? MAX_CANDIDATES : n);
    size_t entry[MAX_CANDIDATES];
    float target[MAX_CANDIDATES];
    float total = 0.0f;
    for (int k = 0; k < n; k++) {
        entry[k] = uniform_entry(cache_len, rng);
        int s = subpath(sc, entry[k], light, true);
        target[k] = 0.0f;
        if (light.len >= 1 && s + t - 2 <= max_depth) {
            const Vertex& lv = light.v[light.len - 1];
            const Vertex* prev = light.len == 2 ? &light.v[0] : nullptr;
            V3 c;
            if (connect_contribution(sc, lv, prev, cam, t, c)) target[k] = fmaxf(luminance(c), 0.0f);
        }
        total += target[k];
    }
    if (total <= 0.0f) return;
    float mean = total / (float)n;
    for (uint32_t d = 0; d < sc.draws; d++) {
        float u = uniform(rng) * total;
        int k = 0;
        while (k + 1 < n && (u >= target[k] || target[k] == 0.0f)) {
            u -= target[k];
            k += 1;
        }
        if (target[k] > 0.0f) connect(entry[k], mean / target[k]);
    }
}

// ---------------------------------------------------------------- kernels

// `cis::shade`, the sample at sorted position j (see kernels.rs::shade).
__device__ inline void shade(const Scene& sc, const uint32_t* order, const uint32_t* active, const Hit* hits, Slot* slots,
                      Vertex* vertices, PendingData* pending, size_t j) {
    size_t i = order[j];
    size_t slot_id = active[i];
    Slot slot = slots[slot_id];
    size_t base = slot_id * PENDING_PER_SLOT;
    for (int k = 0; k < PENDING_PER_SLOT; k++) pending[base + k] = PendingData{};
    if (slot.alive == 0) return;
    Hit hit = hits[i];
    if (hit.prim == NONE) {
        slot.alive = 0;
        slots[slot_id] = slot;
        return;
    }
    V3 p0, p1, p2;
    vertices_of(sc, hit.prim, p0, p1, p2);
    V3 n = normalize_or_zero(cross(p1 - p0, p2 - p0));
    if (n == splat(0.0f)) {
        slot.alive = 0;
        slots[slot_id] = slot;
        return;
    }
    V3 p = p0 * (1.0f - hit.u - hit.v) + p1 * hit.u + p2 * hit.v;
    size_t vbase = slot_id * MAX_CAMERA_VERTICES;
    int depth = (int)slot.depth;
    Vertex cam[MAX_CAMERA_VERTICES];
    for (int k = 0; k < depth; k++) cam[k] = vertices[vbase + k];
    cam[depth] = make_vertex(SURFACE, p, n, hit.prim, slot.beta, false, emission_of(sc, hit.prim));
    int t_len = depth + 1;

    VertexList path, light;
    Sink sink = {pending + base, 0};
    vertex_strategies(sc, cam, t_len, slot.rng, path, light, sink);

    int max_vertices = (int)sc.max_depth + 2;
    Frame frame = from_normal(n);
    V3 wo = to_local(frame, -normalize(slot.ray.dir));
    BsdfSample s;
    bool sampled = false;
    if (!(t_len >= max_vertices || t_len >= MAX_CAMERA_VERTICES)) {
        float u_lobe = uniform(slot.rng);
        V2 u = uniform2(slot.rng);
        sampled = sample_f(scene_bsdf(sc, hit.prim, wo), wo, u_lobe, u, true, s);
    }
    cam[t_len - 1].delta = sampled && s.delta;
    vertices[vbase + depth] = cam[t_len - 1];
    slot.depth += 1;
    if (sampled) {
        slot.beta *= s.weight;
        if (t_len > 4) {
            float q = fminf(max_element(slot.beta), 0.95f);
            if (uniform(slot.rng) >= q) slot.alive = 0;
            slot.beta = slot.beta / q;
        }
        if (!is_finite(slot.beta) || max_element(slot.beta) <= 0.0f) slot.alive = 0;
        V3 wi = to_world(frame, s.wi);
        slot.ray = {offset_ray_origin(p, dot(wi, n) > 0.0f ? n : -n), wi, 0.0f, INFINITY};
    } else {
        slot.alive = 0;
    }
    slots[slot_id] = slot;
}

// ---------------------------------------------------------------- the scene from the interface (host code)

// Fills `sc` from the interface's record; `keep(pointer, count)` returns the copy of
// an array that the kernel reads (a device copy on the GPU, a host one in the check).
template <class Keep>
void make_scene(Scene& sc, const WrCisScene* s, Keep&& keep) {
    sc.tris = keep(s->tris, 9 * s->n_tris);
    sc.material_of = keep(s->material_of, s->n_tris);
    sc.materials = keep(s->materials, s->n_materials);
    sc.two_sided = keep(s->two_sided, s->n_materials);
    sc.emission = keep(s->emission, 3 * s->n_materials);
    sc.lights = keep(s->lights, s->n_lights);
    sc.light_cdf = keep(s->light_cdf, s->n_lights);
    sc.light_of_tri = keep(s->light_of_tri, s->n_tris);
    sc.n_lights = (uint32_t)s->n_lights;
    auto vec = [](const float* f) { return V3{f[0], f[1], f[2]}; };
    sc.cam_position = vec(s->cam_position);
    sc.cam_forward = vec(s->cam_forward);
    sc.cam_right = vec(s->cam_right);
    sc.cam_up = vec(s->cam_up);
    sc.tan_half = s->tan_half;
    sc.margin = s->margin;
    sc.width = s->width;
    sc.height = s->height;
    sc.max_depth = s->max_depth;
    sc.resampled = s->resampled;
    sc.candidates = s->candidates;
    sc.draws = s->draws;
    sc.cache_vertices = keep((const Vertex*)s->cache_vertices, s->n_cache_vertices);
    sc.cache_entries = keep(s->cache_entries, 2 * s->n_entries);
    sc.n_entries = s->n_entries;
    sc.count_splat = s->count_splat;
    sc.count_connection = s->count_connection;
}

}  // namespace cis
