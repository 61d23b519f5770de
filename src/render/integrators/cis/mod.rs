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
//! 5. *connect*: the active samples' pending shadow rays are compacted (`copy_if`),
//!    cast as one batch, and `cis::accumulate` adds the visible contributions;
//! 6. `cis::retire` writes finished samples to their pixels; dead samples are compacted
//!    out of the active list (`copy_if`) and their slots regenerated.
//!
//! Switches turn each idea off on its own: sorting (shade in arrival order),
//! importance sampling (uniform connections), and compaction/regeneration (dead samples
//! stay in the pool as idle lanes until the whole pool is done).

mod capture;
pub(crate) mod kernels;
pub(crate) mod light;
mod pool;

pub use capture::{ShadeCapture, ShadeObserver};

use crate::cast::CastStats;
use crate::film::Film;
use crate::geometry::{Hit, Ray};
use crate::render::bidir::Vertex;
use crate::render::cache::device::DeviceCache;
use crate::render::cache::host::{Connections, LightVertexCache, StrategyCounts};
use crate::render::cache::kernels::CacheRead;
use crate::render::context::{Context, Passes};
use crate::render::options::CisParams;
use kernels::*;
use pool::{append_active, extend, for_each_shading, indices_where, material_queues, survivors};
use simt::{Device, DeviceBuffer, DeviceConfig};

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
    /// The cache of the last iteration, with its number, for its next camera passes.
    cache: Option<(u32, DeviceCache)>,
    observer: Option<ShadeObserver>,
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
        CisLbdpt { params, dev, records: Vec::new(), cache: None, observer: None }
    }

    /// Calls `f` after every bounce with what `cis::shade` and the compaction read and
    /// wrote (the GPU check's inputs). The pool is copied before each shading launch
    /// while an observer is set.
    pub fn observe(&mut self, f: ShadeObserver) {
        self.observer = Some(f);
    }

    /// The emulated device: kernel statistics and memory.
    pub fn device(&self) -> &Device {
        &self.dev
    }

    /// Adds the passes of `span` to `film`, one at a time.
    pub(crate) fn render_passes(&mut self, ctx: &Context, span: Passes, film: &mut Film) -> CastStats {
        span.numbers().fold(CastStats::default(), |stats, pass| stats.merge(self.render_pass(ctx, pass, film)))
    }

    /// Renders one pass into `film`: at the iteration's first, the light pass streams
    /// its light subpaths into the cache (`light`); the pass's share of their camera
    /// splats; then the camera pass streams one sample per pixel through the pool,
    /// bounce by bounce.
    fn render_pass(&mut self, ctx: &Context, pass: u32, film: &mut Film) -> CastStats {
        let dev = &self.dev;
        let p = self.params;
        let pixels = ctx.opts.width * ctx.opts.height;
        let connections = if p.importance {
            Connections::Resampled { candidates: p.candidates, draws: p.draws.min(MAX_DRAWS as u32) }
        } else {
            Connections::Uniform { n: p.draws.min(MAX_DRAWS as u32) }
        };
        let n_light = if p.light_paths == 0 { pixels } else { p.light_paths };
        // The iteration's light pass, once for all its camera passes; then this camera
        // pass's share of its splats.
        let (iterations, number) = (p.iterations(), p.iterations().of(pass));
        let (cache, mut rays) = match self.cache.take().filter(|(n, _)| *n == number) {
            Some((_, cache)) => (cache, 0),
            None => light::light_pass(dev, ctx, number, n_light, p.pool as usize, p.sort),
        };
        let counts = cache.counts(ctx, connections.per_vertex(), iterations);
        let share = iterations.splat_range(pass, cache.light_paths);
        let chunk = (p.pool as usize).clamp(32, (n_light as usize).max(32));
        let (splats, splat_rays) = light::splat_stream(dev, ctx, &cache, (counts, share), chunk);
        rays += splat_rays;
        film.add_splats(splats);

        let mut cam = CameraPool::new(dev, p.pool.clamp(32, pixels.max(32)) as usize, pixels as usize);
        let (mut next_pixel, mut bounce) = (0u32, 0);
        loop {
            if next_pixel < pixels && (p.regenerate || cam.active.is_empty()) {
                next_pixel += cam.regenerate(ctx, pass, next_pixel, pixels - next_pixel);
            }
            let n = cam.active.len();
            if n == 0 {
                break;
            }
            let hits = extend(dev, ctx, "cis::gather_rays", &cam.active, &cam.slots, |s: Slot| s.ray);
            rays += n;
            let (order, queues) = material_queues(dev, ctx, "cis::material_keys", &hits, p.sort);
            let before = self.observer.is_some().then(|| (cam.slots.to_vec(), cam.vertices.to_vec()));
            let shade = cam.shade(ctx, &order, &hits, &cache, counts, connections);
            // Kept for the observer only (otherwise freed here, as before it existed).
            let shaded =
                before.map(|b| (b, cam.slots.to_vec(), cam.vertices.to_vec(), cam.pending.to_vec(), hits, order));
            rays += cam.connect(ctx);
            cam.retire();
            let kept = survivors(dev, "cis::alive_flags", &cam.active, &cam.slots, |s: &Slot| &s.alive, true);
            if let (Some(observe), Some(((slots_before, vertices_before), slots, vertices, pending, hits, order))) =
                (self.observer.as_mut(), shaded)
            {
                observe(&ShadeCapture {
                    pass,
                    bounce,
                    sorted: p.sort,
                    order: order.as_slice(),
                    active: cam.active.as_slice(),
                    hits: hits.as_slice(),
                    slots_before: &slots_before,
                    vertices_before: &vertices_before,
                    slots: &slots,
                    vertices: &vertices,
                    pending: &pending,
                    slots_compacted: cam.slots.as_slice(),
                    kept: kept.as_slice(),
                    cache_vertices: cache.vertices.as_slice(),
                    cache_entries: cache.entries.as_slice(),
                    counts,
                    connections,
                });
            }
            let survival = kept.len() as f32 / n as f32;
            if p.regenerate || kept.is_empty() {
                cam.active = kept;
            }
            self.records.push(QueueRecord {
                pass,
                bounce,
                active: n,
                queues,
                survival,
                shade_simd: shade.simd_efficiency(),
                shade_dispatch_simd: shade.region_efficiency("shade"),
            });
            bounce += 1;
        }
        let est: Vec<glam::Vec3> = cam.estimates.as_slice().iter().map(|&e| glam::Vec3::from_array(e)).collect();
        film.add_pass(pass, &est);
        self.cache = Some((number, cache));
        CastStats { rays, peak_working_bytes: dev.memory().peak, ..Default::default() }
    }

    /// The light vertex cache of the last pass, copied to the host with its subpaths in
    /// the order of their numbers (the host light pass's order).
    pub fn light_cache(&self) -> Option<LightVertexCache> {
        self.cache.as_ref().map(|(_, cache)| cache.to_host())
    }
}

/// The camera pass's pool: samples, their camera vertices and pending contributions,
/// the active list, and the pixel estimates.
struct CameraPool<'d> {
    dev: &'d Device,
    slots: DeviceBuffer<Slot>,
    vertices: DeviceBuffer<Vertex>,
    pending: DeviceBuffer<PendingData>,
    estimates: DeviceBuffer<[f32; 3]>,
    active: DeviceBuffer<u32>,
}

impl<'d> CameraPool<'d> {
    fn new(dev: &'d Device, pool: usize, pixels: usize) -> Self {
        CameraPool {
            dev,
            slots: dev.alloc(pool),
            // Pooled, not zero-filled: a slot's vertices are written (the camera's by
            // `generate`, the others by `shade`) before `shade` reads them. (The pending
            // entries are not: the connect step scans all of them.)
            vertices: dev.alloc_pooled(pool * MAX_CAMERA_VERTICES),
            pending: dev.alloc(pool * PENDING_PER_SLOT),
            estimates: dev.alloc(pixels),
            active: dev.alloc(0),
        }
    }

    /// Regenerate: samples for up to `left` pixels from `first` into the free slots,
    /// appended to the active list; returns how many started.
    fn regenerate(&mut self, ctx: &Context, pass: u32, first: u32, left: u32) -> u32 {
        let dev = self.dev;
        let free = indices_where(dev, &self.slots, |s: Slot| s.alive == 0);
        let k = free.len().min(left as usize);
        if k == 0 {
            return 0;
        }
        let (fv, sv, vv) = (free.view(), self.slots.view_mut(), self.vertices.view_mut());
        let (o, cam, proj) = (ctx.opts, ctx.scene.camera, ctx.projection);
        for_each_shading(dev, "cis::generate", k, |t, i| {
            generate(t, i, &fv, first, pass, o.seed, (&cam, o.filter, o.filter_mode), &proj, &sv, &vv)
        });
        self.active = append_active(dev, "cis::append_active", &self.active, &free, k);
        k as u32
    }

    /// Shade: every active sample, in `order`, meets its hit (`cis::shade`).
    fn shade(
        &mut self,
        ctx: &Context,
        order: &DeviceBuffer<u32>,
        hits: &DeviceBuffer<Hit>,
        cache: &DeviceCache,
        counts: StrategyCounts,
        connections: Connections,
    ) -> simt::LaunchRecord {
        let n = order.len();
        let args = ShadeArgs {
            order: order.view(),
            active: self.active.view(),
            hits: hits.view(),
            slots: self.slots.view_mut(),
            vertices: self.vertices.view_mut(),
            pending: self.pending.view_mut(),
            cache: CacheRead { vertices: cache.vertices.view(), entries: cache.entries.view(), counts, connections },
        };
        // 240 registers per thread in the GPU twin (`shade_sorted`, Nsight Compute on the
        // H200: docs/measured/h200-time-model/ncu-cis-shading-compaction-3-scenes-128.csv.gz)
        // and 639,488 bytes of SASS (docs/measured/cuda-kernel-code-bytes-sm90.tsv).
        let cfg = simt::LaunchConfig::linear(n, 128)
            .with_regions(kernels::SHADE_REGIONS)
            .with_registers(240)
            .with_code_bytes(639_488);
        self.dev
            .launch("cis::shade", cfg, |blk| {
                blk.for_each_thread(|t| {
                    let j = t.global_idx();
                    if j < n {
                        shade(t, ctx, &args, j)
                    }
                })
            })
            .expect("shade launch shape is valid")
    }

    /// Connect: the active samples' pending shadow rays compacted, cast as one batch,
    /// and the visible contributions accumulated (`cis::accumulate`); returns the rays
    /// cast. Only the active samples' entries are read: a sample that left the list
    /// keeps its last bounce's entries until its slot is regenerated.
    fn connect(&mut self, ctx: &Context) -> usize {
        let dev = self.dev;
        let (n, per) = (self.active.len(), PENDING_PER_SLOT);
        let mut blocked = dev.alloc::<u32>(self.pending.len());
        let mut waiting_flags = dev.alloc_pooled::<u32>(n * per);
        {
            let (av, pv, fv) = (self.active.view(), self.pending.view(), waiting_flags.view_mut());
            dev.for_each("cis::pending_waiting_flags", n * per, |t, j| {
                let entry = t.load(&av, j / per) as usize * per + j % per;
                t.store(&fv, j, u32::from(t.load(&pv, entry).state == 1))
            });
        }
        let waiting = indices_where(dev, &waiting_flags, |f: u32| f != 0);
        let m = waiting.len();
        let mut shadow = dev.alloc_pooled::<Ray>(m);
        let mut entries = dev.alloc_pooled::<u32>(m);
        {
            let (iv, av, pv) = (waiting.view(), self.active.view(), self.pending.view());
            let (sv, ev) = (shadow.view_mut(), entries.view_mut());
            dev.for_each("cis::gather_shadow_rays", m, |t, i| {
                let j = t.load(&iv, i) as usize;
                let entry = t.load(&av, j / per) as usize * per + j % per;
                t.store(&ev, i, entry as u32);
                t.store(&sv, i, t.load(&pv, entry).ray)
            });
        }
        let mut occluded = vec![false; m];
        ctx.caster.occluded(shadow.as_slice(), &mut occluded);
        let flags = dev.alloc_vec(occluded.into_iter().map(u32::from).collect::<Vec<u32>>());
        {
            let (ev, fv, bv) = (entries.view(), flags.view(), blocked.view_mut());
            dev.for_each("cis::scatter_blocked", m, |t, i| t.store(&bv, t.load(&ev, i) as usize, t.load(&fv, i)));
        }
        let (av, pv, bv, sv) = (self.active.view(), self.pending.view(), blocked.view(), self.slots.view_mut());
        dev.for_each("cis::accumulate", self.active.len(), |t, i| accumulate(t, i, &av, &pv, &bv, &sv));
        m
    }

    /// Retire: finished samples write their radiance to their pixels (`cis::retire`).
    fn retire(&mut self) {
        let (av, sv, ev) = (self.active.view(), self.slots.view(), self.estimates.view_mut());
        self.dev.for_each("cis::retire", self.active.len(), |t, i| retire(t, i, &av, &sv, &ev));
    }
}
