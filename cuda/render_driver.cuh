// Whole GPU renders of one pass: CIS-LBDPT as a stream of named kernels and LVC-BDPT as
// megakernels, the twins of src/render/integrators/cis/ (mod.rs, light/mod.rs) and
// src/render/integrators/megakernel/, kernel for kernel and stage for stage, over the
// device code of render_device.cuh and cis_device.cuh.
//
// The file is written against a small backend that the including file defines first
// (render.cu for CUDA, cis_host_check.cpp for a CPU build that CI runs): `Mem<T>` (a
// growable device array with `p`, `n` and `resize`), `launch<A, K>(name, n, a)` (kernel
// `K(a, i)` for every i < n), `select_flagged` (the indices of non-zero flags, in order),
// `sort_pairs` (a stable radix sort), `exclusive_sum` (returns the total), `download`,
// `upload`, `copy_on_device`, `fill_zero`, `Tracer` with `trace(tracer, ray, any_hit)`
// (a closest-hit key of geometry/hit_key.rs, or 0 when blocked) and `Clock`.
//
// About 550 lines: the two integrators share every stage but their subpath loops, and
// read best side by side with the Rust files they twin.

#pragma once

#include <algorithm>
#include <vector>

#include "render_api.h"
#include "render_device.cuh"

namespace render {

using namespace cis;

// ---------------------------------------------------------------- records

// cis::light::kernels::LightSlot
struct LightSlot {
    Rng rng;
    Ray ray;
    V3 beta;
    uint32_t path, len, bounces, alive;
    float rr_scale;
};
// cache::kernels::SplatData
struct SplatData {
    Ray ray;
    V3 value;
    V2 film;
    uint32_t state;  // 0 empty, 1 waiting for its shadow ray, 2 visible
};

// Everything a kernel reads: the scene, the tracer, the pools and the stage's scalars.
// One record for every kernel of the file, passed by value (a few hundred bytes).
struct K {
    Scene sc;
    Tracer tracer;
    uint64_t seed;
    uint32_t pass, iteration, stride, first, n_light, miss_key;
    uint32_t share[2];   // the subpath numbers whose splats join this camera pass
    double splat_paths;  // StrategyCounts::splat_paths
    // camera pool
    Slot* slots;
    Vertex* cam_vertices;
    PendingData* pending;
    float* estimates;  // 3 per pixel
    // light pool and cache
    LightSlot* light_slots;
    Vertex* staging;
    Vertex* cache_vertices;
    uint32_t* cache_entries;  // [start, s]
    uint32_t* cache_paths;    // [number, start, len]
    uint32_t* done;           // [slot, number, len]
    uint32_t cache_bases[3];
    // lists and scratch
    uint32_t *active, *list, *spare, *order, *keys, *flags, *counts_v, *counts_e, *offsets_v, *offsets_e, *blocked;
    Hit* hits;
    SplatData* splats;
    V3* splat_out;  // film (x, y, 0) and value, two per visible splat, from `first`
};

// ---------------------------------------------------------------- kernels shared by both

template <class S>
HD void extend_slot(const K& k, S* slots, size_t i) {
    Ray r = slots[k.active[i]].ray;
    k.hits[i] = hit_of(k.sc, r, trace(k.tracer, r, false));
}
// cis::gather_rays with the caster's closest hit
HD void extend_camera(const K& k, size_t i) { extend_slot(k, k.slots, i); }
// cis::light_gather_rays with the caster's closest hit
HD void extend_light(const K& k, size_t i) { extend_slot(k, k.light_slots, i); }
// cis::material_keys / cis::light_material_keys
HD void material_keys(const K& k, size_t i) {
    Hit h = k.hits[i];
    k.keys[i] = h.prim != NONE ? k.sc.material_of[h.prim] : k.miss_key;
    k.order[i] = (uint32_t)i;
}
// spare[i] = active[list[i]]: the kept positions of the active list as slot numbers
HD void kept_slots(const K& k, size_t i) { k.spare[i] = k.active[k.list[i]]; }
// cis::cache_counts
HD void cache_counts(const K& k, size_t f) {
    uint32_t slot = k.done[3 * f], len = k.done[3 * f + 2];
    uint32_t entries = 0;
    for (uint32_t j = 0; j < len; j++) entries += cached(k.sc, k.staging[(size_t)slot * k.stride + j]) ? 1 : 0;
    k.counts_v[f] = len;
    k.counts_e[f] = entries;
}
// cis::cache_store
HD void cache_store(const K& k, size_t f) {
    uint32_t slot = k.done[3 * f], path = k.done[3 * f + 1], len = k.done[3 * f + 2];
    uint32_t start = k.cache_bases[0] + k.offsets_v[f];
    size_t entry = k.cache_bases[1] + k.offsets_e[f];
    for (uint32_t j = 0; j < len; j++) {
        Vertex v = k.staging[(size_t)slot * k.stride + j];
        k.cache_vertices[start + j] = v;
        if (cached(k.sc, v)) {
            k.cache_entries[2 * entry] = start;
            k.cache_entries[2 * entry + 1] = j + 1;
            entry++;
        }
    }
    uint32_t* p = k.cache_paths + 3 * ((size_t)k.cache_bases[2] + f);
    p[0] = path;
    p[1] = start;
    p[2] = len;
}
// The camera splats of cache subpath `first + p` into its `stride` entries, if its
// number is in the pass's share; `visible` decides each one's state (0: left out).
template <class V>
HD void splat_entries(const K& k, size_t p, V visible) {
    const uint32_t* path = k.cache_paths + 3 * (k.first + p);
    size_t next = 0;
    if (path[0] >= k.share[0] && path[0] < k.share[1]) {
        VertexList verts, full;
        for (uint32_t j = 0; j < path[2]; j++) verts.push(k.cache_vertices[path[1] + j]);
        auto sink = [&](Ray ray, V3 value, V2 film) {
            uint32_t state = visible(ray);
            if (state != 0) k.splats[p * k.stride + next++] = {ray, value, film, state};
        };
        light_splats(k.sc, verts.v, verts.len, k.splat_paths, full, sink);
    }
    for (size_t j = next; j < k.stride; j++) k.splats[p * k.stride + j] = SplatData{};
}
HD void splat_waiting_flags(const K& k, size_t i) { k.flags[i] = k.splats[i].state == 1; }
HD void splat_visible_flags(const K& k, size_t i) { k.flags[i] = k.splats[i].state == 2; }
// cis::splat_visibility, the shadow ray cast here
HD void splat_shadow(const K& k, size_t i) {
    SplatData& s = k.splats[k.list[i]];
    s.state = trace(k.tracer, s.ray, true) == 0 ? 0 : 2;
}
// the visible splats, compacted for the host's film
HD void splat_gather(const K& k, size_t i) {
    const SplatData& s = k.splats[k.list[i]];
    k.splat_out[2 * (k.first + i)] = v3(s.film.x, s.film.y, 0.0f);
    k.splat_out[2 * (k.first + i) + 1] = s.value;
}

// ---------------------------------------------------------------- CIS-LBDPT's light stream (light/kernels.rs)

HD void light_free_flags(const K& k, size_t s) { k.flags[s] = k.light_slots[s].alive == 0; }
HD LightSlot light_slot(const Walker& w, uint32_t path, uint32_t len) {
    return {w.rng, w.ray, w.beta, path, len, w.bounces, w.live ? 1u : 0u, w.rr_scale};
}
// cis::light_generate
HD void light_generate(const K& k, size_t i) {
    uint32_t slot = k.list[i], path = k.first + (uint32_t)i;
    Vertex origin;
    Walker w;
    bool ok = start_light_subpath(k.sc, rng_for_sample(k.seed ^ 0x4c564321ull, path, k.iteration), (int)k.stride, origin, w);
    if (ok) k.staging[(size_t)slot * k.stride] = origin;
    k.light_slots[slot] = light_slot(w, path, ok ? 1 : 0);
}
// cis::light_shade
HD void light_shade(const K& k, size_t j) {
    size_t i = k.order[j];
    uint32_t slot_id = k.active[i];
    LightSlot slot = k.light_slots[slot_id];
    if (slot.alive == 0) return;
    Walker w = {slot.ray, slot.beta, slot.rng, slot.bounces, true, slot.rr_scale};
    Vertex v;
    uint32_t len = slot.len;
    if (step(k.sc, w, k.hits[i], (int)len, false, (int)k.stride, v)) {
        k.staging[(size_t)slot_id * k.stride + len] = v;
        len++;
    }
    k.light_slots[slot_id] = light_slot(w, slot.path, len);
}
HD void light_ended_flags(const K& k, size_t i) { k.flags[i] = k.light_slots[k.active[i]].alive == 0; }
HD void light_alive_flags(const K& k, size_t i) { k.flags[i] = k.light_slots[k.active[i]].alive != 0; }
// cis::finished, from the ended positions in `list`
HD void finished(const K& k, size_t i) {
    uint32_t slot = k.active[k.list[i]];
    const LightSlot& s = k.light_slots[slot];
    k.done[3 * i] = slot;
    k.done[3 * i + 1] = s.path;
    k.done[3 * i + 2] = s.len;
}
// cis::light_splat
HD void light_splat(const K& k, size_t p) {
    splat_entries(k, p, [](Ray) { return 1u; });
}

// ---------------------------------------------------------------- CIS-LBDPT's camera stream (cis/kernels.rs)

HD void camera_free_flags(const K& k, size_t s) { k.flags[s] = k.slots[s].alive == 0; }
// cis::generate
HD void generate(const K& k, size_t i) {
    uint32_t slot = k.list[i], pixel = k.first + (uint32_t)i;
    Rng rng = rng_for_sample(k.seed, pixel, k.pass);
    Ray ray = generate_ray(k.sc, camera_film(k.seed, pixel, k.sc.width, k.pass));
    k.cam_vertices[(size_t)slot * MAX_CAMERA_VERTICES] = camera_vertex(k.sc);
    Slot s;
    s.rng = rng;
    s.ray = ray;
    s.beta = splat(1.0f);
    s.radiance = splat(0.0f);
    s.pixel = pixel;
    s.depth = 1;
    s.alive = 1;
    s.pad = 0;
    k.slots[slot] = s;
}
// cis::shade
HD void shade_sample(const K& k, size_t j) {
    shade(k.sc, k.order, k.active, k.hits, k.slots, k.cam_vertices, k.pending, j);
}
// the waiting pending entries of the active samples (cis::gather_shadow_rays' list)
HD void pending_waiting_flags(const K& k, size_t j) {
    k.flags[j] = k.pending[(size_t)k.active[j / PENDING_PER_SLOT] * PENDING_PER_SLOT + j % PENDING_PER_SLOT].state == 1;
}
// cis::scatter_blocked, the shadow ray cast here
HD void pending_shadow(const K& k, size_t i) {
    uint32_t j = k.list[i];
    size_t at = (size_t)k.active[j / PENDING_PER_SLOT] * PENDING_PER_SLOT + j % PENDING_PER_SLOT;
    k.blocked[at] = trace(k.tracer, k.pending[at].ray, true) == 0;
}
// cis::accumulate
HD void accumulate(const K& k, size_t i) {
    uint32_t slot_id = k.active[i];
    Slot slot = k.slots[slot_id];
    size_t base = (size_t)slot_id * PENDING_PER_SLOT;
    for (int j = 0; j < PENDING_PER_SLOT; j++) {
        const PendingData& p = k.pending[base + j];
        if (p.state == 2 || (p.state == 1 && k.blocked[base + j] == 0)) slot.radiance += p.value;
    }
    k.slots[slot_id] = slot;
}
// cis::retire
HD void retire(const K& k, size_t i) {
    const Slot& s = k.slots[k.active[i]];
    if (s.alive != 0) return;
    k.estimates[3 * (size_t)s.pixel] = s.radiance.x;
    k.estimates[3 * (size_t)s.pixel + 1] = s.radiance.y;
    k.estimates[3 * (size_t)s.pixel + 2] = s.radiance.z;
}
HD void camera_alive_flags(const K& k, size_t i) { k.flags[i] = k.slots[k.active[i]].alive != 0; }

// ---------------------------------------------------------------- LVC-BDPT's megakernels (megakernel/kernels.rs)

// megakernel::walk: the subpath extended until its walker stops, one traced ray a bounce.
HD void walk(const K& k, Walker& w, VertexList& verts, bool radiance, int max_vertices) {
    w.live = w.live && verts.len < max_vertices;
    while (w.live) {
        Hit hit = hit_of(k.sc, w.ray, trace(k.tracer, w.ray, false));
        Vertex v;
        if (step(k.sc, w, hit, verts.len, radiance, max_vertices, v)) verts.push(v);
    }
}
// lvc::light_path
HD void mk_light_path(const K& k, size_t i) {
    uint32_t path = k.first + (uint32_t)i;
    Vertex origin;
    Walker w;
    VertexList verts;
    if (start_light_subpath(k.sc, rng_for_sample(k.seed ^ 0x4c564321ull, path, k.iteration), (int)k.stride, origin, w)) {
        verts.push(origin);
        walk(k, w, verts, false, (int)k.stride);
    }
    for (int j = 0; j < verts.len; j++) k.staging[i * k.stride + j] = verts.v[j];
    k.done[3 * i] = (uint32_t)i;
    k.done[3 * i + 1] = path;
    k.done[3 * i + 2] = (uint32_t)verts.len;
}
// lvc::splat
HD void mk_splat(const K& k, size_t p) {
    splat_entries(k, p, [&](Ray ray) { return trace(k.tracer, ray, true) == 0 ? 0u : 2u; });
}
// lvc::camera_path
HD void mk_camera_path(const K& k, size_t pixel) {
    VertexList cam, path, light;
    cam.push(camera_vertex(k.sc));
    Rng rng = rng_for_sample(k.seed, pixel, k.pass);
    Walker w = walker_new(generate_ray(k.sc, camera_film(k.seed, (uint32_t)pixel, k.sc.width, k.pass)), splat(1.0f), rng);
    walk(k, w, cam, true, (int)k.sc.max_depth + 2);
    rng = w.rng;
    V3 estimate = splat(0.0f);
    auto sink = [&](bool has_ray, Ray ray, V3 value) {
        if (!has_ray || trace(k.tracer, ray, true) != 0) estimate += value;
    };
    for (int t = 2; t <= cam.len; t++) vertex_strategies(k.sc, cam.v, t, rng, path, light, sink);
    k.estimates[3 * pixel] = estimate.x;
    k.estimates[3 * pixel + 1] = estimate.y;
    k.estimates[3 * pixel + 2] = estimate.z;
}

// ---------------------------------------------------------------- the host's loops

struct Renderer {
    K k{};
    WrRenderSettings set{};
    Mem<Slot> slots;
    Mem<Vertex> cam_vertices, staging, cache_vertices;
    Mem<PendingData> pending;
    Mem<float> estimates;
    Mem<LightSlot> light_slots;
    Mem<uint32_t> cache_entries, cache_paths, done, active, list, order, keys, flags, counts_v, counts_e, offsets_v,
        offsets_e, blocked, spare;
    Mem<Hit> hits;
    Mem<SplatData> splats;
    Mem<V3> splat_out;
    size_t n_splats = 0;              // visible splats in splat_out
    uint32_t cached = UINT32_MAX;     // the iteration whose light pass the cache holds
    std::vector<float> host_splats;  // x, y, r, g, b per visible splat, after the pass
    WrRenderStats stats{};

    // Points the kernel record at the buffers (after any resize).
    void bind() {
        k.slots = slots.p, k.cam_vertices = cam_vertices.p, k.pending = pending.p, k.estimates = estimates.p;
        k.light_slots = light_slots.p, k.staging = staging.p, k.cache_vertices = cache_vertices.p;
        k.cache_entries = cache_entries.p, k.cache_paths = cache_paths.p, k.done = done.p, k.active = active.p;
        k.list = list.p, k.spare = spare.p, k.order = order.p, k.keys = keys.p, k.flags = flags.p, k.counts_v = counts_v.p;
        k.counts_e = counts_e.p, k.offsets_v = offsets_v.p, k.offsets_e = offsets_e.p, k.blocked = blocked.p;
        k.hits = hits.p, k.splats = splats.p, k.splat_out = splat_out.p;
        k.sc.cache_vertices = cache_vertices.p;
        k.sc.cache_entries = cache_entries.p;
    }
    template <void (*F)(const K&, size_t)>
    void run(const char* name, size_t n) {
        if (n == 0) return;
        bind();
        launch<K, F>(name, n, k);
    }
    // The positions i < n whose flag kernel F sets, into `list`; returns how many.
    template <void (*F)(const K&, size_t)>
    size_t select(const char* name, size_t n) {
        flags.resize(n);
        list.resize(n);
        run<F>(name, n);
        return n == 0 ? 0 : select_flagged(flags.p, n, list.p);
    }
    // Regenerate: up to `total - next` new subpaths (kernel Gen, numbered from `next`)
    // in the pool's free slots (flag kernel Free), appended to the active list; returns
    // the next number.
    template <void (*Free)(const K&, size_t), void (*Gen)(const K&, size_t)>
    uint32_t regenerate(const char* free_name, const char* gen_name, size_t pool, uint32_t next, size_t total) {
        size_t m = std::min<size_t>(select<Free>(free_name, pool), total - next);
        k.first = next;
        run<Gen>(gen_name, m);
        append_active(m);
        return next + (uint32_t)m;
    }
    // Appends list[0..m) to the active list.
    void append_active(size_t m) {
        size_t n = active.n;
        spare.resize(n + m);
        if (n) copy_on_device(spare.p, active.p, n);
        if (m) copy_on_device(spare.p + n, list.p, m);
        active.swap(spare);
        active.n = n + m;
    }
    // The active list cut to the positions in list[0..m).
    void keep_active(size_t m) {
        spare.resize(m);
        run<kept_slots>("cis::compact", m);
        active.swap(spare);
        active.n = m;
    }
    // Extend, then the material order (sorted or not) of the n active samples' hits.
    template <void (*Extend)(const K&, size_t)>
    void extend_and_order(const char* extend, const char* keys_name, size_t n) {
        hits.resize(n);
        keys.resize(n);
        order.resize(n);
        run<Extend>(extend, n);
        stats.rays += n;
        run<material_keys>(keys_name, n);
        if (set.sort) sort_pairs(keys.p, order.p, n, 32 - __builtin_clz(k.miss_key | 1));
    }
    // cache/device.rs append_paths: the m subpaths in `done` appended to the cache.
    void append_paths(size_t m) {
        if (m == 0) return;
        for (Mem<uint32_t>* b : {&counts_v, &counts_e, &offsets_v, &offsets_e}) b->resize(m);
        run<cache_counts>("cis::cache_counts", m);
        uint32_t nv = exclusive_sum(counts_v.p, offsets_v.p, m), ne = exclusive_sum(counts_e.p, offsets_e.p, m);
        k.cache_bases[0] = (uint32_t)cache_vertices.n, k.cache_bases[1] = (uint32_t)(cache_entries.n / 2);
        k.cache_bases[2] = (uint32_t)(cache_paths.n / 3);
        grow_keep(cache_vertices, cache_vertices.n + nv);
        grow_keep(cache_entries, cache_entries.n + 2 * (size_t)ne);
        grow_keep(cache_paths, cache_paths.n + 3 * m);
        run<cache_store>("cis::cache_store", m);
    }
    // Resizes a buffer that is appended to, keeping its contents.
    template <class T>
    void grow_keep(Mem<T>& b, size_t m) {
        if (m <= b.cap) {
            b.n = m;
            return;
        }
        Mem<T> bigger;
        bigger.resize(std::max(m, 2 * b.cap));
        if (b.n) copy_on_device(bigger.p, b.p, b.n);
        bigger.n = m;
        b.swap(bigger);
    }
    void start_cache() {
        cache_vertices.resize(0), cache_entries.resize(0), cache_paths.resize(0);
    }
    // The cache's MIS counts once complete (StrategyCounts::new) with n_c connections.
    void set_counts(uint32_t n_c) {
        double pixels = (double)k.sc.width * (double)k.sc.height;
        size_t entries = cache_entries.n / 2;
        k.splat_paths = (double)k.n_light / (double)std::max<uint32_t>(set.per_iteration, 1);
        k.sc.count_splat = k.splat_paths / pixels;
        k.sc.count_connection = entries == 0 ? 0.0 : (double)n_c * (double)k.n_light / (double)entries;
        k.sc.n_entries = entries;
        stats.cache_entries += entries;
    }
    // The visible splats (state 2) of `m` splat entries, appended to splat_out.
    void collect_splats(size_t m) {
        size_t v = select<splat_visible_flags>("cis::visible_flags", m);
        grow_keep(splat_out, 2 * (n_splats + v));
        k.first = (uint32_t)n_splats;
        run<splat_gather>("cis::gather_splats", v);
        n_splats += v;
    }
    // splat_out to the host as (x, y, r, g, b) records.
    void download_splats() {
        std::vector<V3> out(2 * n_splats);
        if (n_splats) download(out.data(), splat_out.p, 2 * n_splats);
        host_splats.resize(5 * n_splats);
        for (size_t i = 0; i < n_splats; i++) {
            const float f[5] = {out[2 * i].x, out[2 * i].y, out[2 * i + 1].x, out[2 * i + 1].y, out[2 * i + 1].z};
            std::copy(f, f + 5, host_splats.begin() + 5 * i);
        }
    }

    // CIS-LBDPT's light pass (light/mod.rs light_pass).
    void cis_light_pass(size_t pool) {
        uint32_t n_light = k.n_light;
        pool = std::max<size_t>(32, std::min<size_t>(pool, std::max<uint32_t>(n_light, 32)));
        light_slots.resize(pool);
        fill_zero(light_slots.p, pool);
        staging.resize(pool * k.stride);
        active.resize(0);
        start_cache();
        uint32_t next = 0;
        while (true) {
            if (next < n_light)
                next = regenerate<light_free_flags, light_generate>("cis::light_free_flags", "cis::light_generate",
                                                                    pool, next, n_light);
            size_t n = active.n;
            if (n == 0) break;
            extend_and_order<extend_light>("cis::light_extend", "cis::light_material_keys", n);
            run<light_shade>("cis::light_shade", n);
            size_t ended = select<light_ended_flags>("cis::light_ended_flags", n);
            done.resize(3 * ended);
            run<finished>("cis::finished", ended);
            append_paths(ended);
            keep_active(select<light_alive_flags>("cis::light_alive_flags", n));
        }
    }
    // The camera splats of the pass's share of the cached subpaths, `pool` at a time
    // (light/mod.rs splat_stream).
    void cis_splats(size_t pool) {
        pool = std::max<size_t>(32, std::min<size_t>(pool, std::max<uint32_t>(k.n_light, 32)));
        size_t paths = cache_paths.n / 3;
        for (size_t first = 0; first < paths; first += pool) {
            size_t m = std::min(pool, paths - first);
            k.first = (uint32_t)first;
            splats.resize(m * k.stride);
            run<light_splat>("cis::light_splat", m);
            size_t waiting = select<splat_waiting_flags>("cis::splat_waiting_flags", m * k.stride);
            run<splat_shadow>("cis::splat_visibility", waiting);
            stats.rays += waiting;
            collect_splats(m * k.stride);
        }
    }

    // CIS-LBDPT's camera pass (cis/mod.rs render_pass after the light pass).
    void cis_camera_pass(size_t pixels, size_t pool) {
        pool = std::max<size_t>(32, std::min<size_t>(pool, std::max<size_t>(pixels, 32)));
        slots.resize(pool);
        fill_zero(slots.p, pool);
        cam_vertices.resize(pool * MAX_CAMERA_VERTICES);
        pending.resize(pool * PENDING_PER_SLOT);
        blocked.resize(pool * PENDING_PER_SLOT);
        active.resize(0);
        uint32_t next = 0;
        while (true) {
            if (next < pixels && (set.regenerate || active.n == 0))
                next = regenerate<camera_free_flags, generate>("cis::free_flags", "cis::generate", pool, next, pixels);
            size_t n = active.n;
            if (n == 0) break;
            extend_and_order<extend_camera>("cis::extend", "cis::material_keys", n);
            run<shade_sample>(set.sort ? "cis::shade_sorted" : "cis::shade_unsorted", n);
            size_t waiting = select<pending_waiting_flags>("cis::pending_waiting_flags", n * PENDING_PER_SLOT);
            run<pending_shadow>("cis::scatter_blocked", waiting);
            stats.rays += waiting;
            run<accumulate>("cis::accumulate", n);
            run<retire>("cis::retire", n);
            size_t kept = select<camera_alive_flags>("cis::alive_flags", n);
            stats.bounces++;
            if (set.regenerate || kept == 0) keep_active(kept);
        }
    }

    // LVC-BDPT's light megakernel (megakernel/mod.rs light_paths), all light subpaths
    // in one launch, cached in number order.
    void megakernel_light() {
        start_cache();
        staging.resize((size_t)k.n_light * k.stride);
        done.resize(3 * (size_t)k.n_light);
        k.first = 0;
        run<mk_light_path>("lvc::light_path", k.n_light);
        append_paths(k.n_light);
    }
    // The splat megakernel over the pass's share of the cached subpaths
    // (megakernel/mod.rs render_pass).
    void megakernel_splats() {
        size_t m = k.share[1] - k.share[0];
        splats.resize(m * k.stride);
        k.first = k.share[0];
        run<mk_splat>("lvc::splat", m);
        collect_splats(m * k.stride);
    }

    // One pass of `set.method` into `estimates` and `splat_out` (download_splats reads
    // them): the light pass at the first of its iteration's passes (Iterations in
    // render/options.rs), the pass's share of the splats, the camera pass.
    void pass(uint32_t number) {
        stats = WrRenderStats{};
        n_splats = 0;
        splat_out.resize(0);
        size_t pixels = (size_t)k.sc.width * k.sc.height;
        uint32_t per = std::max<uint32_t>(set.per_iteration, 1);
        k.pass = number;
        k.iteration = number / per;
        k.stride = k.sc.max_depth + 1;
        k.n_light = set.light_paths == 0 ? (uint32_t)pixels : set.light_paths;
        uint64_t j = number % per;
        k.share[0] = (uint32_t)((j * k.n_light + per - 1) / per);
        k.share[1] = (uint32_t)(((j + 1) * k.n_light + per - 1) / per);
        estimates.resize(3 * pixels);
        fill_zero(estimates.p, 3 * pixels);
        Clock all, light;
        all.start();
        light.start();
        bool fresh = cached != k.iteration;
        cached = UINT32_MAX;
        if (set.method == 0) {
            k.sc.resampled = set.resampled, k.sc.candidates = set.candidates, k.sc.draws = set.draws;
            if (fresh) cis_light_pass(set.pool);
            set_counts(set.draws);
            cis_splats(set.pool);
            stats.light_ms = light.stop_ms();
            cis_camera_pass(pixels, set.pool);
        } else {
            k.sc.resampled = 0, k.sc.candidates = 0, k.sc.draws = set.draws;
            if (fresh) megakernel_light();
            set_counts(set.draws);
            megakernel_splats();
            stats.light_ms = light.stop_ms();
            run<mk_camera_path>("lvc::camera_path", pixels);
        }
        cached = k.iteration;
        stats.pass_ms = all.stop_ms();
        stats.splats = n_splats;
    }
};

}  // namespace render
