//! CIS-LBDPT's light pass as a stream on the device: a pool of light subpaths advanced
//! bounce by bounce with named kernels, as the camera pass is.
//!
//! 1. *regenerate*: `cis::light_generate` starts the next subpaths (by number, each with
//!    its own random stream) in free slots, storing their light vertex;
//! 2. *extend*: the active subpaths' rays go to the caster as one batch;
//! 3. *sort by material*: `cis::light_material_keys` and `sort_by_key` (implicit queues);
//! 4. *shade*: `cis::light_shade` stages the new vertex and samples the BSDF;
//! 5. *store*: subpaths that ended are appended to the light vertex cache
//!    ([`append_paths`]: counts, two scans, `cis::cache_store`);
//! 6. *compact*: the ended leave the active list, freeing their slots.
//!
//! Each camera pass of the iteration then makes the camera splats of its share of the
//! cached subpaths (`cis::light_splat`, [`splat_stream`]), their shadow rays cast as one
//! batch per chunk of subpaths.
//!
//! The cache holds subpaths in the order they ended (bounce, then active order), which
//! depends on the subpaths' random numbers only, never on threads; its contents are
//! those of the host light pass (`lvc::build_cache`), subpath for subpath.

pub(crate) mod kernels;

use super::pool::{append_active, extend, for_each_shading, indices_where, launch_shading, material_queues, survivors};
use crate::geometry::Ray;
use crate::render::bidir::Vertex;
use crate::render::cache::device::{DeviceCache, append_paths, visible_splats};
use crate::render::cache::host::StrategyCounts;
use crate::render::cache::kernels::{SplatData, light_splat};
use crate::render::context::Context;
use glam::{Vec2, Vec3};
use kernels::*;
use simt::Device;

/// Iteration `number`'s `n_light` light subpaths streamed through a pool of `pool`
/// slots (sorted by material when `sort`): the cache, and the rays cast.
pub(crate) fn light_pass(
    dev: &Device,
    ctx: &Context,
    number: u32,
    n_light: u32,
    pool: usize,
    sort: bool,
) -> (DeviceCache, usize) {
    let stride = ctx.opts.max_depth as usize + 1;
    let pool = pool.clamp(32, (n_light as usize).max(32));
    let mut slots = dev.alloc::<LightSlot>(pool);
    // Every staged vertex is written before it is read (a subpath's first by
    // `light_generate`, the others by `light_shade`): pooled, not zero-filled.
    let mut staging = dev.alloc_pooled::<Vertex>(pool * stride);
    let mut cache = DeviceCache::new(dev, n_light);
    let mut active = dev.alloc::<u32>(0);
    let (mut next, mut rays) = (0u32, 0usize);
    loop {
        // Regenerate: the next subpaths into the free slots.
        if next < n_light {
            let free = indices_where(dev, &slots, |s: LightSlot| s.alive == 0);
            let k = free.len().min((n_light - next) as usize);
            let (fv, sv, gv) = (free.view(), slots.view_mut(), staging.view_mut());
            for_each_shading(dev, "cis::light_generate", k, |t, i| {
                light_generate(t, ctx, i, &fv, (next, number), stride, &sv, &gv)
            });
            active = append_active(dev, "cis::light_append_active", &active, &free, k);
            next += k as u32;
        }
        let n = active.len();
        if n == 0 {
            break;
        }
        let hits = extend(dev, ctx, "cis::light_gather_rays", &active, &slots, |s: LightSlot| s.ray);
        rays += n;
        let (order, _) = material_queues(dev, ctx, "cis::light_material_keys", &hits, sort);
        let args = LightShadeArgs {
            order: order.view(),
            active: active.view(),
            hits: hits.view(),
            slots: slots.view_mut(),
            staging: staging.view_mut(),
            stride,
        };
        // 120 registers per thread in the GPU twin (`light_shade`, Nsight Compute on the
        // H200: docs/measured/gpu-render-kernels-h200-bedroom-512.md) and 202,880 bytes
        // of SASS (docs/measured/cuda-kernel-code-bytes-sm90.tsv).
        launch_shading(dev, "cis::light_shade", n, (120, 202_880), |t, j| light_shade(t, ctx, &args, j));
        drop((hits, order));
        // Store the ended subpaths, then compact them out.
        let ended = survivors(dev, "cis::light_ended_flags", &active, &slots, |s: &LightSlot| &s.alive, false);
        let mut done = dev.alloc_pooled::<[u32; 3]>(ended.len());
        {
            let (ev, sv, dv) = (ended.view(), slots.view(), done.view_mut());
            dev.for_each("cis::finished", ended.len(), |t, i| finished(t, i, &ev, &sv, &dv));
        }
        append_paths(dev, ctx, &done, &staging, stride, &mut cache);
        active = survivors(dev, "cis::light_alive_flags", &active, &slots, |s: &LightSlot| &s.alive, true);
    }
    (cache, rays)
}

/// The camera splats of the cached subpaths whose numbers are in `share` (a camera
/// pass's, [`crate::render::Iterations::splat_range`]), `chunk` cached subpaths at a
/// time: splat entries (`cis::light_splat`), their shadow rays compacted and cast as
/// one batch, and the visible ones collected in cache and vertex order; with the rays
/// cast.
pub(crate) fn splat_stream(
    dev: &Device,
    ctx: &Context,
    cache: &DeviceCache,
    (counts, share): (StrategyCounts, (u32, u32)),
    chunk: usize,
) -> (Vec<(Vec2, Vec3)>, usize) {
    let stride = ctx.opts.max_depth as usize + 1;
    let (mut out, mut rays) = (Vec::new(), 0);
    for first in (0..cache.paths.len()).step_by(chunk.max(1)) {
        let m = chunk.min(cache.paths.len() - first);
        let mut splats = dev.alloc_pooled::<SplatData>(m * stride);
        {
            let (pv, vv, sv) = (cache.paths.slice(first, m), cache.vertices.view(), splats.view_mut());
            // 122 registers per thread in the GPU twin (`light_splat`, Nsight Compute on an
            // H100: docs/measured/ncu-gpu-render-kernels-3-scenes-128-512-h100.csv.gz) and
            // 129,792 bytes of SASS (docs/measured/cuda-kernel-code-bytes-sm90.tsv).
            launch_shading(dev, "cis::light_splat", m, (122, 129_792), |t, p| {
                light_splat(t, ctx, p, (&pv, &vv), (counts, share), stride, &sv)
            });
        }
        // Shadow rays of the waiting entries, as one batch.
        let waiting = indices_where(dev, &splats, |s: SplatData| s.state == 1);
        let mut shadow = dev.alloc_pooled::<Ray>(waiting.len());
        {
            let (wv, sv, rv) = (waiting.view(), splats.view(), shadow.view_mut());
            dev.for_each("cis::gather_splat_rays", waiting.len(), |t, i| {
                t.store(&rv, i, t.load(&sv, t.load(&wv, i) as usize).ray)
            });
        }
        let mut blocked = vec![false; waiting.len()];
        ctx.caster.occluded(shadow.as_slice(), &mut blocked);
        rays += waiting.len();
        let flags = dev.alloc_vec(blocked.into_iter().map(u32::from).collect::<Vec<u32>>());
        {
            let (wv, fv, sv) = (waiting.view(), flags.view(), splats.view_mut());
            dev.for_each("cis::splat_visibility", waiting.len(), |t, i| {
                let at = t.load(&wv, i) as usize;
                let mut s = t.load(&sv, at);
                s.state = if t.load(&fv, i) == 0 { 2 } else { 0 };
                t.store(&sv, at, s);
            });
        }
        out.extend(visible_splats(dev, &splats));
    }
    (out, rays)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::render::cache::host::{LightPass, build_caches};
    use crate::render::context::{Passes, TestSetup, WAVE};
    use crate::render::{Iterations, RenderOptions};
    use crate::scene::cornell_box;

    /// Splats as sortable bit patterns (the stream makes them in another order).
    fn sorted(splats: &[(Vec2, Vec3)]) -> Vec<[u32; 5]> {
        let mut v: Vec<[u32; 5]> = splats
            .iter()
            .map(|(f, l)| [f.x.to_bits(), f.y.to_bits(), l.x.to_bits(), l.y.to_bits(), l.z.to_bits()])
            .collect();
        v.sort_unstable();
        v
    }

    /// The streamed light pass, with small and large pools, sorted or not, caches the
    /// same subpaths vertex for vertex as the host light pass, with the same MIS
    /// counts, and each camera pass of the iteration gets the same splats (as sets: the
    /// stream makes them in ending order), whether it has one camera pass or three.
    #[test]
    fn the_stream_caches_what_the_host_light_pass_caches() {
        let scene = cornell_box();
        let opts = RenderOptions { width: 32, height: 24, seed: 11, max_depth: 6, ..Default::default() };
        let setup = TestSetup::new(&scene);
        let ctx = setup.ctx(&opts);
        let n_light = 32 * 24;
        for iterations in [Iterations(1), Iterations(3)] {
            let span = Passes { first: 2, count: 1, per_pass: n_light };
            let (mut host, _) = build_caches(&ctx, span, (3, iterations), WAVE);
            let LightPass { cache: host, counts: host_counts, splats: host_splats } = host.pop().expect("one pass");
            assert!(host.entries.len() > n_light as usize / 2);
            assert_eq!(host_splats.len(), iterations.0 as usize);
            assert!(host_splats.iter().all(|s| !s.is_empty()));
            for (pool, sort) in [(32, true), (100, false), (1 << 16, true)] {
                let dev = Device::default();
                let (cache, _) = light_pass(&dev, &ctx, 2, n_light, pool, sort);
                let copy = cache.to_host();
                assert_eq!(format!("{:?}", copy.vertices), format!("{:?}", host.vertices), "pool {pool}: vertices");
                assert_eq!(copy.entries, host.entries, "pool {pool}: entries");
                let counts = cache.counts(&ctx, 3, iterations);
                assert_eq!(counts.connection, host_counts.connection);
                assert_eq!((counts.splat, counts.splat_paths), (host_counts.splat, host_counts.splat_paths));
                for (j, want) in host_splats.iter().enumerate() {
                    let share = iterations.splat_range(2 * iterations.0 + j as u32, n_light);
                    let (splats, _) = splat_stream(&dev, &ctx, &cache, (counts, share), pool);
                    assert!(sorted(&splats) == sorted(want), "pool {pool}, camera pass {j}: splats");
                }
            }
        }
    }
}
