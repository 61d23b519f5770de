//! CIS-LBDPT: light-vertex-cache BDPT run as a stream of camera samples on the `simt`
//! emulator, with coherent shading and importance-sampled cache connections.
//!
//! Each iteration builds the light vertex cache (as LVC-BDPT does) and then advances a
//! pool of camera samples with named kernels, bounce by bounce:
//!
//! 1. `cis::generate` fills free slots with new samples (random numbers from the sample's
//!    pixel and pass, never from its slot or queue position);
//! 2. *extend*: the host casts the pool's rays as one batch through the caster trait;
//! 3. `cis::material_keys` + `sort_by_key`: samples sorted by the material they hit form
//!    implicit queues (segments of one material), counted with `reduce_by_key`;
//! 4. `cis::shade` walks the sorted order: every strategy at the new vertex (emitter,
//!    light sample, cache connections) goes to pending entries, and the BSDF picks the
//!    next ray;
//! 5. *connect*: the pending shadow rays are compacted (`copy_if`), cast as one batch,
//!    and `cis::accumulate` adds the visible contributions;
//! 6. `cis::retire` writes finished samples to their pixels; dead samples are compacted
//!    out of the active list (`copy_if`) and their slots regenerated.
//!
//! Switches turn each idea off on its own: sorting (shade in arrival order),
//! importance sampling (uniform connections), and compaction/regeneration (dead samples
//! stay in the pool as idle lanes until the whole pool is done).

pub mod kernels;

use crate::cast::CastStats;
use crate::film::Film;
use crate::geometry::{Hit, Ray};
use crate::render::Context;
use crate::render::bidir::Vertex;
use crate::render::lvc::{Connections, build_cache};
use kernels::*;
use simt::{Device, DeviceBuffer, DeviceConfig};

/// Parameters and switches of [`CisLbdpt`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CisParams {
    /// Camera samples in flight.
    pub pool: u32,
    /// Light subpaths per iteration (0: one per pixel).
    pub light_paths: u32,
    /// Candidates drawn uniformly from the cache per camera vertex (N).
    pub candidates: u32,
    /// Connections made per camera vertex (M), at most 8.
    pub draws: u32,
    /// Sort samples by material before shading.
    pub sort: bool,
    /// Resample the candidates by contribution (off: `draws` uniform connections).
    pub importance: bool,
    /// Compact dead samples and regenerate their slots at once.
    pub regenerate: bool,
    /// Record SIMD efficiency and memory traffic of the kernels (slower).
    pub measure: bool,
}

impl Default for CisParams {
    fn default() -> Self {
        CisParams {
            pool: 1 << 16,
            light_paths: 0,
            candidates: 8,
            draws: 2,
            sort: true,
            importance: true,
            regenerate: true,
            measure: false,
        }
    }
}

/// What one bounce of one iteration did: the inspector's queue panel.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct QueueRecord {
    /// The iteration (pass).
    pub pass: u32,
    /// The wavefront iteration within the pass (one per path vertex).
    pub bounce: u32,
    /// Samples in the active list when the bounce started.
    pub active: usize,
    /// Queue length per material index (misses under `u32::MAX`).
    pub queues: Vec<(u32, u32)>,
    /// Active samples still alive after the bounce, over those that started it.
    pub survival: f32,
    /// SIMD efficiency of the whole `cis::shade` launch, from what its lanes executed
    /// (memory operations of shading and connections, and the declared material arms;
    /// when measuring).
    pub shade_simd: Option<f64>,
    /// Efficiency of the declared material-dispatch region alone (when measuring).
    pub shade_dispatch_simd: Option<f64>,
}

/// CIS-LBDPT: LVC-BDPT as a stream of kernels on the `simt` device, with material-sorted queues, compaction and regeneration, and resampled cache connections.
pub struct CisLbdpt {
    /// Its switches and sizes.
    pub params: CisParams,
    dev: Device,
    /// One record per wavefront iteration of the last pass (the inspector's queue panel).
    pub records: Vec<QueueRecord>,
}

impl CisLbdpt {
    /// The integrator on a device of its own.
    pub fn new(params: CisParams) -> Self {
        Self::on_device(params, Device::new(DeviceConfig { measure: params.measure, ..Default::default() }))
    }

    /// The integrator on `dev` (a render passes the caster's device, so that one
    /// device holds every kernel). `params.measure` turns the device's measurement
    /// on; it never turns it off.
    pub fn on_device(params: CisParams, dev: Device) -> Self {
        if params.measure {
            dev.set_measure(true);
        }
        CisLbdpt { params, dev, records: Vec::new() }
    }

    /// The emulated device: kernel statistics and memory.
    pub fn device(&self) -> &Device {
        &self.dev
    }

    /// Renders one pass into `film`.
    pub fn render_pass(&mut self, ctx: &Context, pass: u32, film: &mut Film) -> CastStats {
        let dev = &self.dev;
        let p = self.params;
        let (w, h) = (ctx.opts.width, ctx.opts.height);
        let pixels = w * h;
        let pool = p.pool.clamp(32, pixels.max(32)) as usize;
        let connections = if p.importance {
            Connections::Resampled { candidates: p.candidates, draws: p.draws.min(MAX_DRAWS as u32) }
        } else {
            Connections::Uniform { n: p.draws.min(MAX_DRAWS as u32) }
        };
        let n_light = if p.light_paths == 0 { pixels } else { p.light_paths };
        let (cache, counts, splats, light_stats) =
            build_cache(ctx, pass, n_light, connections.per_vertex(), crate::render::walk::WAVE);
        let mut rays = light_stats.rays;
        film.add_splats(splats);
        let cache_vertices = dev.alloc_vec(cache.vertices);
        let cache_entries: DeviceBuffer<[u32; 2]> = dev.alloc_vec(cache.entries.iter().map(|&(a, b)| [a, b]).collect());

        let mut slots = dev.alloc::<Slot>(pool);
        let mut vertices = dev.alloc::<Vertex>(pool * MAX_CAMERA_VERTICES);
        let mut pending = dev.alloc::<PendingData>(pool * PENDING_PER_SLOT);
        let mut estimates = dev.alloc::<[f32; 3]>(pixels as usize);
        let mut active = dev.alloc::<u32>(0);
        let n_materials = ctx.scene.materials.len() as u32;
        let key_bits = 32 - n_materials.leading_zeros();
        let mut next_pixel = 0u32;
        let mut bounce = 0;
        loop {
            // Regenerate into free slots (all at once without compaction, when the pool is done).
            if next_pixel < pixels && (p.regenerate || active.is_empty()) {
                let mut all = dev.alloc_pooled::<u32>(pool);
                simt::sequence(dev, &mut all, 0, 1);
                let mut free = dev.alloc_pooled::<u32>(pool);
                let n_free = simt::copy_if_stencil(dev, &all, &slots, &mut free, |s: Slot| s.alive == 0);
                let k = (n_free as u32).min(pixels - next_pixel) as usize;
                if k > 0 {
                    let (fv, sv, vv) = (free.view(), slots.view_mut(), vertices.view_mut());
                    let cam = ctx.scene.camera;
                    let (first, seed) = (next_pixel, ctx.opts.seed);
                    dev.for_each("cis::generate", k, |t, i| {
                        generate(
                            t,
                            i,
                            &fv,
                            first,
                            pass,
                            seed,
                            (&cam, ctx.opts.filter, ctx.opts.filter_mode),
                            (w, h),
                            &sv,
                            &vv,
                        )
                    });
                    let mut grown = dev.alloc_pooled::<u32>(active.len() + k);
                    let (av, fv, gv) = (active.view(), free.view(), grown.view_mut());
                    let n_old = active.len();
                    dev.for_each("cis::append_active", n_old + k, |t, i| {
                        let v = if i < n_old { t.load(&av, i) } else { t.load(&fv, i - n_old) };
                        t.store(&gv, i, v);
                    });
                    active = grown;
                    next_pixel += k as u32;
                }
            }
            let n = active.len();
            if n == 0 {
                break;
            }
            // Extend: one batch of rays through the caster. (Buffers the kernels fully
            // overwrite, or read only as far as they were written, come from the device's
            // pool without zero-filling.)
            let mut ray_buf = dev.alloc_pooled::<Ray>(n);
            {
                let (av, sv, rv) = (active.view(), slots.view(), ray_buf.view_mut());
                dev.for_each("cis::gather_rays", n, |t, i| t.store(&rv, i, t.load(&sv, t.load(&av, i) as usize).ray));
            }
            let mut hits = dev.alloc_pooled::<Hit>(n);
            rays += n;
            // Dead samples kept in the pool (no compaction) carry invalid rays: they miss.
            ctx.caster.closest(ray_buf.as_slice(), hits.as_mut_slice());
            drop(ray_buf);

            // Implicit queues: sort by material.
            let mut keys = dev.alloc_pooled::<u32>(n);
            let mut order = dev.alloc_pooled::<u32>(n);
            {
                let (hv, kv, ov) = (hits.view(), keys.view_mut(), order.view_mut());
                let material_of = &ctx.scene.material_of;
                dev.for_each("cis::material_keys", n, |t, i| {
                    material_key(t, i, &hv, material_of, n_materials, &kv, &ov)
                });
            }
            if p.sort {
                simt::sort_by_key_bits(dev, &mut keys, &mut order, 0, key_bits.max(1));
            }
            let queues = queue_lengths(dev, &keys, p.sort);

            // Shade.
            let shade_record = {
                let args = ShadeArgs {
                    order: order.view(),
                    active: active.view(),
                    hits: hits.view(),
                    slots: slots.view_mut(),
                    vertices: vertices.view_mut(),
                    pending: pending.view_mut(),
                    cache_vertices: cache_vertices.view(),
                    cache_entries: cache_entries.view(),
                    counts,
                    connections,
                };
                let cfg = simt::LaunchConfig::linear(n, 128).with_regions(&["shade"]);
                dev.launch("cis::shade", cfg, |blk| {
                    blk.for_each_thread(|t| {
                        let j = t.global_idx();
                        if j < n {
                            shade(t, ctx, &args, j)
                        }
                    })
                })
                .expect("shade launch shape is valid")
            };
            drop((hits, keys, order));

            // Connect: compact the pending shadow rays, cast them, accumulate.
            let n_pending = pool * PENDING_PER_SLOT;
            let mut blocked = dev.alloc::<u32>(n_pending);
            {
                let mut all = dev.alloc_pooled::<u32>(n_pending);
                simt::sequence(dev, &mut all, 0, 1);
                let mut idx = dev.alloc_pooled::<u32>(n_pending);
                let m = simt::copy_if_stencil(dev, &all, &pending, &mut idx, |q: PendingData| q.state == 1);
                let mut shadow = dev.alloc_pooled::<Ray>(m);
                {
                    let (iv, pv, sv) = (idx.view(), pending.view(), shadow.view_mut());
                    dev.for_each("cis::gather_shadow_rays", m, |t, i| {
                        t.store(&sv, i, t.load(&pv, t.load(&iv, i) as usize).ray)
                    });
                }
                let mut occluded = vec![false; m];
                ctx.caster.occluded(shadow.as_slice(), &mut occluded);
                rays += m;
                let flags = dev.alloc_vec(occluded.into_iter().map(u32::from).collect::<Vec<u32>>());
                let (iv, fv, bv) = (idx.view(), flags.view(), blocked.view_mut());
                dev.for_each("cis::scatter_blocked", m, |t, i| t.store(&bv, t.load(&iv, i) as usize, t.load(&fv, i)));
            }
            {
                let (av, pv, bv, sv) = (active.view(), pending.view(), blocked.view(), slots.view_mut());
                dev.for_each("cis::accumulate", n, |t, i| accumulate(t, i, &av, &pv, &bv, &sv));
                let (av, sv, ev) = (active.view(), slots.view(), estimates.view_mut());
                dev.for_each("cis::retire", n, |t, i| retire(t, i, &av, &sv, &ev));
            }

            // Compact the dead out of the active list.
            let mut alive = dev.alloc_pooled::<u32>(n);
            {
                let (av, sv, lv) = (active.view(), slots.view(), alive.view_mut());
                dev.for_each("cis::alive_flags", n, |t, i| t.store(&lv, i, t.load(&sv, t.load(&av, i) as usize).alive));
            }
            let mut kept = dev.alloc_pooled::<u32>(n);
            let survivors = simt::copy_if_stencil(dev, &active, &alive, &mut kept, |a: u32| a != 0);
            if p.regenerate || survivors == 0 {
                active = dev.alloc_from(&kept.as_slice()[..survivors]);
            }
            self.records.push(QueueRecord {
                pass,
                bounce,
                active: n,
                queues,
                survival: survivors as f32 / n as f32,
                shade_simd: shade_record.simd_efficiency(),
                shade_dispatch_simd: shade_record.region_efficiency("shade"),
            });
            bounce += 1;
        }
        let est: Vec<glam::Vec3> = estimates.as_slice().iter().map(|&e| glam::Vec3::from_array(e)).collect();
        film.add_pass(pass, &est);
        CastStats { rays, peak_working_bytes: dev.memory().peak, ..Default::default() }
    }
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
