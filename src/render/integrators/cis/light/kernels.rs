//! Kernels of the light pass on the device: CIS-LBDPT's stream of light subpaths, and
//! the device light vertex cache that the LVC-BDPT megakernel shares. Plain functions of
//! a thread and `Copy` data; none allocates, forks, launches or casts rays (the host in
//! `mod.rs` casts each bounce's rays as one batch between launches).

use crate::bsdf::TransportMode;
use crate::geometry::{Hit, Ray};
use crate::render::bidir::Vertex;
use crate::render::cache::host::light_path_rng;
use crate::render::context::Context;
use crate::render::walk::{SHADE_REGION, Walker, start_light_subpath, step};
use crate::sampling::Rng;
use glam::Vec3;
use simt::{DeviceCopy, Global, GlobalMut, Thread};

/// One light subpath in the pool.
#[derive(Clone, Copy, Debug, Default)]
#[repr(C)]
pub struct LightSlot {
    /// The subpath's random stream.
    pub rng: Rng,
    /// The ray to cast next.
    pub ray: Ray,
    /// Throughput so far.
    pub beta: Vec3,
    /// Which light subpath of the iteration it is.
    pub path: u32,
    /// Vertices stored so far (in the slot's staging area).
    pub len: u32,
    /// Bounces made (Russian roulette starts after 3).
    pub bounces: u32,
    /// 1 while the subpath goes on.
    pub alive: u32,
    /// The walker's Russian-roulette scale ([`Walker::rr_scale`]).
    pub rr_scale: f32,
}

// SAFETY: #[repr(C)], 4- and 8-byte fields laid out without padding.
unsafe impl DeviceCopy for LightSlot {}

impl LightSlot {
    fn new(w: &Walker, path: u32, len: u32) -> LightSlot {
        LightSlot {
            rng: w.rng,
            ray: w.ray,
            beta: w.beta,
            path,
            len,
            bounces: w.bounces,
            alive: w.live as u32,
            rr_scale: w.rr_scale,
        }
    }

    fn walker(&self) -> Walker {
        Walker::resume(self.ray, self.beta, self.rng, self.bounces, self.alive != 0, self.rr_scale)
    }
}

/// `cis::light_generate`: light subpath `first_path + i` starts in free slot `free[i]`:
/// its light vertex goes to the slot's staging area (`stride` vertices per slot).
#[allow(clippy::too_many_arguments)]
pub fn light_generate(
    t: &Thread,
    ctx: &Context,
    i: usize,
    free: &Global<u32>,
    (first_path, pass): (u32, u32),
    stride: usize,
    slots: &GlobalMut<LightSlot>,
    staging: &GlobalMut<Vertex>,
) {
    let slot = t.load(free, i) as usize;
    let path = first_path + i as u32;
    let (origin, walker) = start_light_subpath(ctx, light_path_rng(ctx, path, pass), stride);
    if let Some(v) = origin {
        t.store(staging, slot * stride, v);
    }
    t.store(slots, slot, LightSlot::new(&walker, path, origin.is_some() as u32));
}

/// What the light shading kernel reads and writes.
#[derive(Clone, Copy)]
pub struct LightShadeArgs<'a> {
    /// Active slots in material order.
    pub order: Global<'a, u32>,
    /// The active list.
    pub active: Global<'a, u32>,
    /// Per active slot: its ray's hit.
    pub hits: Global<'a, Hit>,
    /// The pool.
    pub slots: GlobalMut<'a, LightSlot>,
    /// Staged vertices, `stride` per slot.
    pub staging: GlobalMut<'a, Vertex>,
    /// Vertices per subpath at most.
    pub stride: usize,
}

/// `cis::light_shade`: the subpath at sorted position `j` meets its hit: the vertex is
/// staged, and the BSDF (in importance mode) chooses the next ray or ends the subpath.
pub fn light_shade(t: &Thread, ctx: &Context, a: &LightShadeArgs, j: usize) {
    let i = t.load(&a.order, j) as usize;
    let slot_id = t.load(&a.active, i) as usize;
    let mut slot = t.load(&a.slots, slot_id);
    if slot.alive == 0 {
        return; // ended when it started (no light to sample): an idle lane
    }
    let hit = t.load(&a.hits, i);
    if hit.is_hit() {
        t.work(SHADE_REGION, ctx.scene.material(hit.prim).kind().index(), 1);
    }
    let mut walker = slot.walker();
    let len = slot.len as usize;
    if let Some(v) = step(ctx, &mut walker, &hit, len, TransportMode::Importance, a.stride) {
        t.store(&a.staging, slot_id * a.stride + len, v);
        slot.len += 1;
    }
    let len = slot.len;
    slot = LightSlot::new(&walker, slot.path, len);
    t.store(&a.slots, slot_id, slot);
}

/// `cis::finished`: entry `i` of the finished list as (slot, subpath, vertices).
pub fn finished(t: &Thread, i: usize, done: &Global<u32>, slots: &Global<LightSlot>, out: &GlobalMut<[u32; 3]>) {
    let slot = t.load(done, i);
    let s = t.load(slots, slot as usize);
    t.store(out, i, [slot, s.path, s.len]);
}
