//! Pool bookkeeping that both CIS passes share: free slots and regeneration into them,
//! the active list and its compaction, each bounce's batch of rays, and the implicit
//! material queues, and the launch of a kernel that runs shared shading code. Host
//! stages: each is a few launches and primitives.

use super::kernels::material_key;
use crate::geometry::{Hit, Ray};
use crate::render::context::Context;
use crate::render::walk::{ARITHMETIC_REGION, SHADE_REGIONS};
use simt::{Device, DeviceBuffer, DeviceCopy, LaunchConfig, LaunchRecord, Thread};

/// The indices of the elements of `items` that `pred` accepts, in order (`copy_if`):
/// a pool's free slots, a list's waiting entries.
pub(crate) fn indices_where<S: DeviceCopy>(
    dev: &Device,
    items: &DeviceBuffer<S>,
    pred: impl Fn(S) -> bool + Sync + Copy,
) -> DeviceBuffer<u32> {
    let mut all = dev.alloc_pooled::<u32>(items.len());
    simt::sequence(dev, &mut all, 0, 1);
    let mut free = dev.alloc_pooled::<u32>(items.len());
    let n = simt::copy_if_stencil(dev, &all, items, &mut free, pred);
    free.resize(n);
    free
}

/// The active list followed by the first `k` free slots (newly generated work).
pub(crate) fn append_active(
    dev: &Device,
    name: &'static str,
    active: &DeviceBuffer<u32>,
    free: &DeviceBuffer<u32>,
    k: usize,
) -> DeviceBuffer<u32> {
    let mut grown = dev.alloc_pooled::<u32>(active.len() + k);
    let (av, fv, gv) = (active.view(), free.view(), grown.view_mut());
    let n_old = active.len();
    dev.for_each(name, n_old + k, |t, i| {
        let v = if i < n_old { t.load(&av, i) } else { t.load(&fv, i - n_old) };
        t.store(&gv, i, v);
    });
    grown
}

/// Extend: the active slots' rays gathered (`name`) and cast through the caster as one
/// batch; their hits, in active order.
pub(crate) fn extend<S: DeviceCopy>(
    dev: &Device,
    ctx: &Context,
    name: &'static str,
    active: &DeviceBuffer<u32>,
    slots: &DeviceBuffer<S>,
    ray_of: impl Fn(S) -> Ray + Sync,
) -> DeviceBuffer<Hit> {
    let n = active.len();
    // Buffers the kernels fully overwrite come from the device's pool unfilled.
    let mut rays = dev.alloc_pooled::<Ray>(n);
    {
        let (av, sv, rv) = (active.view(), slots.view(), rays.view_mut());
        dev.for_each(name, n, |t, i| t.store(&rv, i, ray_of(t.load(&sv, t.load(&av, i) as usize))));
    }
    let mut hits = dev.alloc_pooled::<Hit>(n);
    ctx.caster.closest(rays.as_slice(), hits.as_mut_slice());
    hits
}

/// Implicit queues: each hit's material (misses last) as its key (`name`), and the
/// active positions in material order when `sort` (arrival order otherwise), with the
/// queue length per material.
pub(crate) fn material_queues(
    dev: &Device,
    ctx: &Context,
    name: &'static str,
    hits: &DeviceBuffer<Hit>,
    sort: bool,
) -> (DeviceBuffer<u32>, Vec<(u32, u32)>) {
    let n = hits.len();
    let n_materials = ctx.scene.materials.len() as u32;
    let key_bits = 32 - n_materials.leading_zeros();
    let mut keys = dev.alloc_pooled::<u32>(n);
    let mut order = dev.alloc_pooled::<u32>(n);
    {
        let (hv, kv, ov) = (hits.view(), keys.view_mut(), order.view_mut());
        let material_of = &ctx.scene.material_of;
        dev.for_each(name, n, |t, i| material_key(t, i, &hv, material_of, n_materials, &kv, &ov));
    }
    if sort {
        simt::sort_by_key_bits(dev, &mut keys, &mut order, 0, key_bits.max(1));
    }
    let queues = queue_lengths(dev, &keys, sort);
    (order, queues)
}

/// The active slots whose flag (the field `alive` picks) is non-zero when `keep`, zero
/// otherwise, in active order (flags by `name`, then `copy_flagged`).
pub(crate) fn survivors<S: DeviceCopy>(
    dev: &Device,
    name: &'static str,
    active: &DeviceBuffer<u32>,
    slots: &DeviceBuffer<S>,
    alive: fn(&S) -> &u32,
    keep: bool,
) -> DeviceBuffer<u32> {
    let n = active.len();
    let mut flags = dev.alloc_pooled::<u32>(n);
    {
        let (av, sv, lv) = (active.view(), slots.view(), flags.view_mut());
        // Only the flag is loaded, as compiled code does (`Thread::load_field`).
        dev.for_each(name, n, |t, i| {
            t.store(&lv, i, ((t.load_field(&sv, t.load(&av, i) as usize, alive) != 0) == keep) as u32)
        });
    }
    let mut kept = dev.alloc_pooled::<u32>(n);
    let m = simt::copy_flagged(dev, active, &flags, &mut kept);
    kept.resize(m);
    kept
}

/// Queue length per key (run lengths of the sorted keys; unsorted keys give runs, which
/// are merged per key here on the host-readable result).
fn queue_lengths(dev: &Device, keys: &DeviceBuffer<u32>, sorted: bool) -> Vec<(u32, u32)> {
    let n = keys.len();
    let ones = dev.alloc_filled(n, 1u32);
    let (mut rk, mut rv) = (dev.alloc_pooled::<u32>(n), dev.alloc_pooled::<u32>(n));
    let runs = simt::reduce_by_key(dev, keys, &ones, &mut rk, &mut rv, 0, |a, b| a + b);
    let mut out: Vec<(u32, u32)> =
        rk.as_slice()[..runs].iter().copied().zip(rv.as_slice()[..runs].iter().copied()).collect();
    if !sorted {
        out.sort_by_key(|x| x.0);
        out.dedup_by(|b, a| {
            if a.0 == b.0 {
                a.1 += b.1;
                true
            } else {
                false
            }
        });
    }
    out
}

/// [`Device::for_each`] for a kernel that runs the code it shares with the CPU
/// integrators (a camera sample, starting a light subpath, shading a light vertex,
/// splatting light vertices onto the film): the shading regions named and that code's declared
/// arithmetic counted as each lane's, as `cis::shade` and the megakernels count theirs.
pub(crate) fn for_each_shading<F>(dev: &Device, name: &'static str, n: usize, f: F) -> LaunchRecord
where
    F: Fn(&Thread, usize) + Sync,
{
    dev.for_each_in(name, SHADE_REGIONS, n, |t, i| t.ambient(ARITHMETIC_REGION, || f(t, i)))
}

/// [`for_each_shading`] for a kernel whose GPU twin the time model needs to know: `n`
/// lanes in blocks of 128 threads, as the twin launches them, stating the twin's
/// registers a thread and the bytes of its code (`twin`).
pub(crate) fn launch_shading<F>(dev: &Device, name: &'static str, n: usize, twin: (u32, u32), f: F) -> LaunchRecord
where
    F: Fn(&Thread, usize) + Sync,
{
    let cfg = LaunchConfig::linear(n, 128).with_regions(SHADE_REGIONS).with_registers(twin.0).with_code_bytes(twin.1);
    dev.launch(name, cfg, |blk| {
        blk.for_each_thread(|t| {
            let j = t.global_idx();
            if j < n {
                t.ambient(ARITHMETIC_REGION, || f(t, j))
            }
        })
    })
    .expect("a linear launch of 128-thread blocks is valid")
}
