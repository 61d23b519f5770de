//! CIS-LBDPT's kernels: plain functions of a thread and `Copy` data (views, the scene
//! and light tables by reference). None allocates, forks, launches or casts rays; the
//! host in `mod.rs` does the ray casting through the caster trait between launches.

use crate::filter::{Filter, FilterMode};
use crate::geometry::{Hit, Ray, barycentric_point, offset_ray_origin};
use crate::render::bidir::{MAX_PATH, Pending, Vertex, VertexKind, VertexList};
use crate::render::cache::kernels::{CacheRead, known_densities, load_vertices};
use crate::render::context::Context;
use crate::render::walk::SHADE_REGION;
use crate::sampling::{Frame, Rng};
use crate::scene::{Camera, Projection};
use glam::{Vec2, Vec3};
use simt::{DeviceCopy, Global, GlobalMut, Thread};

/// The part of the code this module's declared arithmetic counts as ([`crate::cost::Part`]).
const COST_PART: crate::cost::Part = crate::cost::Part::Kernel;

/// Camera vertices kept per pool slot (`max_depth + 2` at most).
pub const MAX_CAMERA_VERTICES: usize = MAX_PATH / 2;
/// Pending contributions per slot and bounce: emitter, light sample, and connections.
pub const MAX_DRAWS: usize = 8;
/// Pending contributions per pool slot.
pub const PENDING_PER_SLOT: usize = 2 + MAX_DRAWS;

/// One camera sample in the pool.
#[derive(Clone, Copy, Debug, Default)]
#[repr(C)]
pub struct Slot {
    /// The sample's random stream.
    pub rng: Rng,
    /// The ray to cast next.
    pub ray: Ray,
    /// Throughput so far.
    pub beta: Vec3,
    /// Radiance gathered so far.
    pub radiance: Vec3,
    /// The pixel it belongs to.
    pub pixel: u32,
    /// Camera vertices stored so far (the camera itself is vertex 0).
    pub depth: u32,
    /// 1 while the path goes on.
    pub alive: u32,
    /// Padding to a 16-byte multiple.
    pub _pad: u32,
}

/// A contribution waiting for its shadow ray (`state` 1), needing none (2), or empty (0).
#[derive(Clone, Copy, Debug, Default)]
#[repr(C)]
pub struct PendingData {
    /// The shadow ray to test.
    pub ray: Ray,
    /// What it adds when unblocked.
    pub value: Vec3,
    /// 0 empty, 1 waiting for its shadow ray, 2 needs none.
    pub state: u32,
}

// SAFETY: #[repr(C)], 4- and 8-byte fields laid out without padding.
unsafe impl DeviceCopy for Slot {}
unsafe impl DeviceCopy for PendingData {}

impl Default for Ray {
    fn default() -> Self {
        Ray { origin: Vec3::ZERO, dir: Vec3::ZERO, t_min: 0.0, t_max: 0.0 }
    }
}

/// `cis::generate`: a new camera sample for pixel `first_pixel + i` in free slot
/// `free[i]`. Its random numbers come from (seed, pixel, pass), never from the slot.
#[allow(clippy::too_many_arguments)]
pub fn generate(
    t: &Thread,
    i: usize,
    free: &Global<u32>,
    first_pixel: u32,
    pass: u32,
    seed: u64,
    (cam, filter, mode): (&Camera, Filter, FilterMode),
    proj: &Projection,
    slots: &GlobalMut<Slot>,
    vertices: &GlobalMut<Vertex>,
) {
    let slot = t.load(free, i) as usize;
    let pixel = first_pixel + i as u32;
    let rng = Rng::for_sample(seed, pixel as u64, pass as u64);
    let width = proj.width;
    let (film, weight) = filter.camera_sample(mode, seed, (pixel % width, pixel / width), width, pass);
    let ray = cam.ray(proj, film, Vec2::ZERO);
    let v0 = Vertex::new(VertexKind::Camera, cam.position, cam.forward, u32::MAX, Vec3::ONE, false, Vec3::ZERO);
    t.store(vertices, slot * MAX_CAMERA_VERTICES, v0);
    t.store(
        slots,
        slot,
        Slot { rng, ray, beta: Vec3::splat(weight), radiance: Vec3::ZERO, pixel, depth: 1, alive: 1, _pad: 0 },
    );
}

/// `cis::material_keys`: the queue key of active sample `i` (its hit's material, or
/// `miss_key`), and its position.
pub fn material_key(
    t: &Thread,
    i: usize,
    hits: &Global<Hit>,
    material_of: &[u32],
    miss_key: u32,
    keys: &GlobalMut<u32>,
    order: &GlobalMut<u32>,
) {
    let h = t.load(hits, i);
    t.store(keys, i, if h.is_hit() { material_of[h.prim as usize] } else { miss_key });
    t.store(order, i, i as u32);
}

/// What the shading kernel reads and writes.
#[derive(Clone, Copy)]
pub struct ShadeArgs<'a> {
    /// Active slots in material order.
    pub order: Global<'a, u32>,
    /// The active list.
    pub active: Global<'a, u32>,
    /// Per active slot: its ray's hit.
    pub hits: Global<'a, Hit>,
    /// The pool.
    pub slots: GlobalMut<'a, Slot>,
    /// Camera vertices, `MAX_CAMERA_VERTICES` per slot.
    pub vertices: GlobalMut<'a, Vertex>,
    /// Pending contributions, `PENDING_PER_SLOT` per slot.
    pub pending: GlobalMut<'a, PendingData>,
    /// The light vertex cache and how camera vertices connect to it.
    pub cache: CacheRead<'a>,
}

pub use crate::render::walk::{ARITHMETIC_REGION, SHADE_REGIONS};

/// `cis::shade`: the sample at sorted position `j` meets its hit: the vertex joins its
/// camera subpath, every strategy at it is evaluated into the pending slots, and the
/// BSDF chooses the next ray (or the path ends).
pub fn shade(t: &Thread, ctx: &Context, a: &ShadeArgs, j: usize) {
    if !t.is_measured() {
        prefetch_lanes(a, j);
    }
    t.ambient(ARITHMETIC_REGION, || shade_lane(t, ctx, a, j))
}

/// Lanes ahead of the shading lane whose first reads [`prefetch_lanes`] starts; each
/// of its three stages reads what the stage before it fetched.
const LANES_AHEAD: usize = 4;

/// A hint for the host CPU, not part of the kernel: the emulator runs a block's lanes
/// one after another, and each begins with dependent misses (its active entry, its
/// slot, its camera vertices; the sorted order scatters them) that a GPU's resident
/// warps would overlap. So lane `j` starts them for the lanes ahead, in stages (an
/// index read where the stage before fetched it), and their misses overlap. Nothing of
/// it is counted, and a measured launch skips it.
fn prefetch_lanes(a: &ShadeArgs, j: usize) {
    use simt::Readable;
    let sorted = |k: usize| (k < a.order.len()).then(|| a.order.read(k) as usize);
    if let Some(i) = sorted(j + 3 * LANES_AHEAD) {
        a.active.prefetch(i, 1);
        a.hits.prefetch(i, 1);
    }
    if let Some(i) = sorted(j + 2 * LANES_AHEAD) {
        a.slots.prefetch(a.active.read(i) as usize, 1);
    }
    if let Some(i) = sorted(j + LANES_AHEAD) {
        let slot = a.active.read(i) as usize;
        let depth = a.slots.read(slot).depth as usize;
        a.vertices.prefetch(slot * MAX_CAMERA_VERTICES, depth);
        a.pending.prefetch(slot * PENDING_PER_SLOT, PENDING_PER_SLOT);
    }
}

fn shade_lane(t: &Thread, ctx: &Context, a: &ShadeArgs, j: usize) {
    use crate::cost::{BRANCH, CROSS, DOT, NORMALIZE, NORMALIZE_OR_ZERO, V3, V3_DIV, VERTEX_COPY};
    let i = t.load(&a.order, j) as usize;
    let slot_id = t.load(&a.active, i) as usize;
    let mut slot = t.load(&a.slots, slot_id);
    let base = slot_id * PENDING_PER_SLOT;
    for k in 0..PENDING_PER_SLOT {
        t.store(&a.pending, base + k, PendingData::default());
    }
    if slot.alive == 0 {
        return; // a dead sample still in the pool: an idle lane
    }
    let hit = t.load(&a.hits, i);
    if !hit.is_hit() {
        slot.alive = 0;
        return t.store(&a.slots, slot_id, slot);
    }
    let scene = ctx.scene;
    let material = scene.material(hit.prim);
    t.work(SHADE_REGION, material.kind().index(), 1);
    crate::cost::declare!(2 * V3 + CROSS + NORMALIZE_OR_ZERO + 4);
    let [p0, p1, p2] = scene.vertices(hit.prim);
    let n = (p1 - p0).cross(p2 - p0).normalize_or_zero();
    if n == Vec3::ZERO {
        slot.alive = 0;
        return t.store(&a.slots, slot_id, slot);
    }
    // The hit point, and the camera subpath copied into a vertex list with the new
    // vertex (the loads are the kernel's own).
    crate::cost::declare!(2 + 3 * V3 + 2 * V3 + (slot.depth + 1) * VERTEX_COPY);
    let p = barycentric_point([p0, p1, p2], hit.u, hit.v);
    let vbase = slot_id * MAX_CAMERA_VERTICES;
    let depth = slot.depth as usize;
    let mut cam = VertexList::default();
    load_vertices(t, &a.vertices, vbase..vbase + depth, &mut cam);
    cam.push(Vertex::new(VertexKind::Surface, p, n, hit.prim, slot.beta, false, scene.emission_of(hit.prim)));
    let t_len = depth + 1;

    // Every strategy at this vertex, into this slot's pending entries.
    let mut path = VertexList::default();
    let mut next = 0;
    let mut sink = |(ray, value, _): Pending| {
        if next < PENDING_PER_SLOT {
            let state = if ray.is_some() { 1 } else { 2 };
            t.store(&a.pending, base + next, PendingData { ray: ray.unwrap_or_default(), value, state });
            next += 1;
        }
    };
    let known = known_densities(t, ctx, &cam);
    a.cache.strategies(t, ctx, (&cam, &known), t_len, &mut slot.rng, &mut path, &mut sink);

    // Continue the subpath.
    let max_vertices = ctx.opts.max_depth as usize + 2;
    crate::cost::declare!(NORMALIZE + 3 + 2 * BRANCH);
    let frame = Frame::from_normal(n);
    let wo = frame.to_local(-slot.ray.dir.normalize());
    let sample = if t_len >= max_vertices || t_len >= MAX_CAMERA_VERTICES {
        None
    } else {
        scene.bsdf(hit.prim, wo).sample_f(
            wo,
            slot.rng.uniform(),
            slot.rng.uniform2(),
            crate::bsdf::TransportMode::Radiance,
        )
    };
    cam[t_len - 1].delta = sample.is_some_and(|s| s.delta);
    t.store(&a.vertices, vbase + depth, cam[t_len - 1]);
    slot.depth += 1;
    match sample {
        Some(s) => {
            // Throughput, the finiteness tests, the next ray off the surface.
            crate::cost::declare!(V3 + BRANCH + 8 + DOT + BRANCH + 15 + 10);
            slot.beta *= s.weight;
            if t_len > 4 {
                crate::cost::declare!(3 + BRANCH + V3_DIV);
                let q = slot.beta.max_element().min(0.95);
                if slot.rng.uniform() >= q {
                    slot.alive = 0;
                }
                slot.beta /= q;
            }
            if !slot.beta.is_finite() || slot.beta.max_element() <= 0.0 {
                slot.alive = 0;
            }
            let wi = frame.to_world(s.wi);
            slot.ray = Ray::new(offset_ray_origin(p, if wi.dot(n) > 0.0 { n } else { -n }), wi);
        }
        None => slot.alive = 0,
    }
    t.store(&a.slots, slot_id, slot);
}

/// `cis::accumulate`: adds the visible pending contributions of active sample `i` to
/// its radiance, in pending order.
pub fn accumulate(
    t: &Thread,
    i: usize,
    active: &Global<u32>,
    pending: &Global<PendingData>,
    blocked: &Global<u32>,
    slots: &GlobalMut<Slot>,
) {
    let slot_id = t.load(active, i) as usize;
    let mut slot = t.load(slots, slot_id);
    let base = slot_id * PENDING_PER_SLOT;
    for k in 0..PENDING_PER_SLOT {
        let p = t.load(pending, base + k);
        let visible = p.state == 2 || (p.state == 1 && t.load(blocked, base + k) == 0);
        if visible {
            slot.radiance += p.value;
        }
    }
    t.store(slots, slot_id, slot);
}

/// `cis::retire`: a finished sample writes its radiance to its pixel's estimate.
pub fn retire(t: &Thread, i: usize, active: &Global<u32>, slots: &Global<Slot>, estimates: &GlobalMut<[f32; 3]>) {
    let slot = t.load(slots, t.load(active, i) as usize);
    if slot.alive == 0 {
        t.store(estimates, slot.pixel as usize, slot.radiance.to_array());
    }
}

#[cfg(test)]
mod tests {
    use super::{ARITHMETIC_REGION, SHADE_REGIONS};
    use crate::cost::Part;

    #[test]
    fn the_shading_regions_name_the_parts_of_the_code_in_their_order() {
        for part in Part::ALL {
            let name = SHADE_REGIONS[ARITHMETIC_REGION + part.index()];
            match part {
                Part::Kernel => assert_eq!(name, "arithmetic"),
                _ => assert_eq!(name, format!("arithmetic: {}", part.name())),
            }
        }
        assert_eq!(SHADE_REGIONS.len(), ARITHMETIC_REGION + Part::ALL.len());
    }
}
