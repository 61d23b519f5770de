//! PDACRT (Ravichandran and Narayanan 2013): divide-and-conquer ray tracing breadth
//! first, as a pipeline of kernels on the `simt` emulator. Per level:
//!
//! 1. `node_bounds`, `split_nodes`: every node's box shrinks to its triangles' boxes
//!    and splits at the spatial median of its longest axis (of the next axis when an
//!    earlier plane separated nothing);
//! 2. `filter_triangles`, `filter_rays`: every element gets a status code, its node id
//!    with L, B, R or N packed into a `u32` (rays test the child boxes up to their
//!    closest hit so far: early termination);
//! 3. the segmented sort of element ids by status code, as a split: each node's
//!    elements are contiguous, so one `transform_exclusive_scan` of one-hot (L, B, R)
//!    vectors of the codes ranks every element within its node and code, which is all
//!    a stable sort by a 2-bit key within segments computes;
//! 4. `count_codes`: the L/B/R/N counts of every node (what reduce-by-key over the
//!    sorted codes gives) are differences of that scan at the node's two ends;
//! 5. `classify_children` and two scans place every child: dropped (no rays or no
//!    triangles), terminal (small or at the depth cap), a node of the next level, or,
//!    when the split separated nothing, the whole node again with the next axis
//!    (terminal once every axis has failed);
//! 6. `scatter_rays`, `scatter_triangles` write every element, in sorted order, into
//!    the next level's id arrays or the terminal buffer (elements coded B go to both
//!    children);
//! 7. `brute_force` solves the terminal buffer: one block per chunk of a terminal node's
//!    rays, its triangles staged through shared memory, closest hits merged with a
//!    64-bit `atomic_min` of (distance bits, triangle id).
//!
//! A call traces its batch in chunks of [`PdacrtParams::chunk_rays`] rays, which bounds
//! the working set; the level buffers are reused across levels and chunks. Batches of
//! fewer than [`PdacrtParams::tiny_batch`] rays (less than a warp: single rays from
//! path-at-a-time integrators) are tested against every triangle on the host, with no
//! launch. Each level leaves a [`LevelRecord`].

pub(crate) mod kernels;

use crate::cast::caster::{CastStats, RayCaster, any_hit_ids, intersect_ids};
use crate::cast::flat::{flatten, hit_of_key};
use crate::geometry::hit_key;
use crate::geometry::{Aabb, Hit, Ray, RayShear, batch_slack};
use crate::scene::Scene;
use kernels::*;
use rayon::prelude::*;
use simt::{Device, DeviceBuffer, DeviceConfig, LaunchRecord};
use std::sync::Mutex;
use std::time::Instant;

mod level;
mod record;
#[cfg(test)]
mod tests;

pub use kernels::BRUTE_FORCE_SHARED_BYTES;
pub use record::{KernelTime, LevelRecord};

/// Tunables of [`Pdacrt`] (defaults chosen by measurement, see `docs/history/dacrt-runs.md`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PdacrtParams {
    /// A child with at most this many rays is terminal.
    pub leaf_rays: u32,
    /// A child with at most this many triangles is terminal.
    pub leaf_triangles: u32,
    /// Children at this depth are terminal.
    pub max_depth: u32,
    /// Threads per block of the brute-force kernel (rays per chunk).
    pub brute_force_block: u32,
    /// Measure SIMD efficiency and memory traffic (slower).
    pub measure: bool,
    /// Rays traced per pass of the pipeline (bounds the working set; 0: the whole
    /// batch at once). The default, 196,608, keeps the dragon's 1024² primary rays
    /// under 100 MB including triangles (`docs/history/dacrt-runs.md`): about 34 MB of triangle-side
    /// buffers plus 140 bytes per ray of the chunk.
    pub chunk_rays: usize,
    /// Batches with fewer rays than this are tested against every triangle on the
    /// host, without a launch.
    pub tiny_batch: usize,
    /// Keep what the inspector shows: per ray, the terminal nodes that tested it, and
    /// every level's node boxes.
    pub inspect: bool,
}

impl PdacrtParams {
    /// The most ray–triangle pairs of a leaf with few rays (DACRT's rule), as the CUDA
    /// twin is given it.
    #[cfg_attr(not(feature = "cuda"), allow(dead_code))]
    pub(crate) fn leaf_pairs(&self) -> u64 {
        crate::cast::dacrt::leaf_pairs(self.leaf_rays as u64, self.leaf_triangles as u64)
    }
}

impl Default for PdacrtParams {
    fn default() -> Self {
        PdacrtParams {
            leaf_rays: 32,
            leaf_triangles: 16,
            max_depth: 40,
            brute_force_block: 128,
            measure: false,
            chunk_rays: 3 << 16,
            tiny_batch: 32,
            inspect: false,
        }
    }
}

/// Breadth-first divide-and-conquer ray tracing on the `simt` emulator.
pub struct Pdacrt {
    dev: Device,
    tris: DeviceBuffer<[f32; 9]>,
    scene_box: Aabb,
    /// The largest magnitude of the triangles' coordinates: with the rays' origins, how
    /// far the ray tests grow boxes (`geometry::batch_slack`, as DACRT).
    magnitude: f32,
    /// Tunables; may be changed between calls.
    pub params: PdacrtParams,
    levels: Mutex<Vec<LevelRecord>>,
    visits: Mutex<Vec<u32>>,
    /// Workspaces of finished calls, kept for the next ones: their buffers keep their
    /// allocations, so a call does not allocate and first-touch its working set again
    /// (on 16 threads that cost up to 0.15 ms per fill of a fresh 100 kB buffer).
    spare: Mutex<Vec<Workspace>>,
}

/// The buffers of one trace call, reused by every level and chunk ([`DeviceBuffer::resize`]
/// keeps an allocation that is large enough).
pub(crate) struct Workspace {
    /// The chunk's rays and their hit keys.
    pub rays: DeviceBuffer<Ray>,
    pub keys: DeviceBuffer<u64>,
    pub hits: DeviceBuffer<Hit>,
    pub visits: DeviceBuffer<u32>,
    /// The current level and the next one (swapped after each level).
    pub cur: LevelBuffers,
    pub next: LevelBuffers,
    pub ray_codes: DeviceBuffer<u32>,
    pub tri_codes: DeviceBuffer<u32>,
    pub tight: DeviceBuffer<u32>,
    pub child_boxes: DeviceBuffer<Aabb>,
    pub ray_counts: DeviceBuffer<u32>,
    pub tri_counts: DeviceBuffer<u32>,
    /// Exclusive scans of the one-hot code vectors, and each node's first rank.
    pub ray_ranks: DeviceBuffer<Triple>,
    pub tri_ranks: DeviceBuffer<Triple>,
    pub ray_base: DeviceBuffer<Triple>,
    pub tri_base: DeviceBuffer<Triple>,
    pub children: DeviceBuffer<ChildData>,
    pub inner: DeviceBuffer<Triple>,
    pub terminal: DeviceBuffer<Triple>,
    pub inner_scan: DeviceBuffer<Triple>,
    pub terminal_scan: DeviceBuffer<Triple>,
    pub term_nodes: DeviceBuffer<NodeData>,
    pub term_ray_ids: DeviceBuffer<u32>,
    pub term_tri_ids: DeviceBuffer<u32>,
    pub chunks: DeviceBuffer<u32>,
    pub chunk_start: DeviceBuffer<u32>,
    pub tests: DeviceBuffer<u64>,
    /// How far the call's ray tests grow boxes (`geometry::batch_slack` over all its
    /// rays, so that every chunk culls alike): no hit the watertight test reports just
    /// off a triangle is culled.
    pub grow: f32,
}

/// One level's nodes and element id arrays.
pub(crate) struct LevelBuffers {
    pub nodes: DeviceBuffer<NodeData>,
    pub ray_ids: DeviceBuffer<u32>,
    pub ray_node: DeviceBuffer<u32>,
    pub tri_ids: DeviceBuffer<u32>,
    pub tri_node: DeviceBuffer<u32>,
}

impl LevelBuffers {
    fn new(dev: &Device) -> Self {
        LevelBuffers {
            nodes: dev.alloc(0),
            ray_ids: dev.alloc(0),
            ray_node: dev.alloc(0),
            tri_ids: dev.alloc(0),
            tri_node: dev.alloc(0),
        }
    }
}

impl LevelBuffers {
    fn held_bytes(&self) -> usize {
        self.nodes.held_bytes()
            + self.ray_ids.held_bytes()
            + self.ray_node.held_bytes()
            + self.tri_ids.held_bytes()
            + self.tri_node.held_bytes()
    }
}

impl Workspace {
    /// Bytes its buffers hold.
    fn held_bytes(&self) -> usize {
        let w = self;
        [
            w.rays.held_bytes(),
            w.keys.held_bytes(),
            w.hits.held_bytes(),
            w.visits.held_bytes(),
            w.cur.held_bytes(),
            w.next.held_bytes(),
            w.ray_codes.held_bytes(),
            w.tri_codes.held_bytes(),
            w.tight.held_bytes(),
            w.child_boxes.held_bytes(),
            w.ray_counts.held_bytes(),
            w.tri_counts.held_bytes(),
            w.ray_ranks.held_bytes(),
            w.tri_ranks.held_bytes(),
            w.ray_base.held_bytes(),
            w.tri_base.held_bytes(),
            w.children.held_bytes(),
            w.inner.held_bytes(),
            w.terminal.held_bytes(),
            w.inner_scan.held_bytes(),
            w.terminal_scan.held_bytes(),
            w.term_nodes.held_bytes(),
            w.term_ray_ids.held_bytes(),
            w.term_tri_ids.held_bytes(),
            w.chunks.held_bytes(),
            w.chunk_start.held_bytes(),
            w.tests.held_bytes(),
        ]
        .iter()
        .sum()
    }

    fn new(dev: &Device) -> Self {
        Workspace {
            rays: dev.alloc_filled(0, Ray::new(glam::Vec3::ZERO, glam::Vec3::ZERO)),
            keys: dev.alloc(0),
            hits: dev.alloc(0),
            visits: dev.alloc(0),
            cur: LevelBuffers::new(dev),
            next: LevelBuffers::new(dev),
            ray_codes: dev.alloc(0),
            tri_codes: dev.alloc(0),
            tight: dev.alloc(0),
            child_boxes: dev.alloc(0),
            ray_counts: dev.alloc(0),
            tri_counts: dev.alloc(0),
            ray_ranks: dev.alloc(0),
            tri_ranks: dev.alloc(0),
            ray_base: dev.alloc(0),
            tri_base: dev.alloc(0),
            children: dev.alloc(0),
            inner: dev.alloc(0),
            terminal: dev.alloc(0),
            inner_scan: dev.alloc(0),
            terminal_scan: dev.alloc(0),
            term_nodes: dev.alloc(0),
            term_ray_ids: dev.alloc(0),
            term_tri_ids: dev.alloc(0),
            chunks: dev.alloc(0),
            chunk_start: dev.alloc(0),
            tests: dev.alloc(1),
            grow: 0.0,
        }
    }
}

/// What one chunk's trace leaves for the caller: per level, its record and launches.
type Levels = Vec<(LevelRecord, Vec<LaunchRecord>)>;

impl Pdacrt {
    /// A caster over the scene's triangles with the default parameters.
    pub fn new(scene: &Scene) -> Self {
        Self::from_triangles(&scene.triangle_vertices(), PdacrtParams::default())
    }

    /// A caster over a triangle list, on a device of its own.
    pub fn from_triangles(tris: &[[glam::Vec3; 3]], params: PdacrtParams) -> Self {
        Self::on_device(tris, params, Device::new(DeviceConfig { measure: params.measure, ..Default::default() }))
    }

    /// A caster over a triangle list on `dev` (shared with whatever else runs on it).
    /// `params.measure` turns the device's measurement on; it never turns it off.
    pub fn on_device(tris: &[[glam::Vec3; 3]], params: PdacrtParams, dev: Device) -> Self {
        if params.measure {
            dev.set_measure(true);
        }
        let (flat, scene_box, magnitude) = flatten(tris);
        Pdacrt {
            tris: dev.alloc_vec(flat),
            dev,
            scene_box,
            magnitude,
            params,
            levels: Mutex::new(Vec::new()),
            visits: Mutex::new(Vec::new()),
            spare: Mutex::new(Vec::new()),
        }
    }

    /// The emulated device: its kernel statistics and memory accounting.
    pub fn device(&self) -> &Device {
        &self.dev
    }

    /// Per ray of the most recent traced call: how many terminal nodes tested it
    /// (recorded only with [`PdacrtParams::inspect`]).
    pub fn visits(&self) -> Vec<u32> {
        self.visits.lock().unwrap_or_else(|e| e.into_inner()).clone()
    }

    /// The levels of the most recent traced call (chunks added up level by level).
    pub fn levels(&self) -> Vec<LevelRecord> {
        self.levels.lock().unwrap_or_else(|e| e.into_inner()).clone()
    }

    /// Traces `rays` chunk by chunk; `emit(first, ws)` reads each chunk's keys (and
    /// rays) from the workspace. Returns the peak working bytes and the tests made.
    fn trace(&self, rays: &[Ray], any_hit: bool, mut emit: impl FnMut(usize, &mut Workspace)) -> (usize, u64) {
        let dev = &self.dev;
        let spare = self.spare.lock().unwrap_or_else(|e| e.into_inner()).pop();
        let mut ws = spare.unwrap_or_else(|| Workspace::new(dev));
        ws.tests.as_mut_slice()[0] = 0;
        ws.grow = batch_slack(self.magnitude, rays.par_iter().map(|r| r.origin));
        // The working set counts the reused workspace's buffers as if allocated now.
        dev.reset_peak_memory();
        let resident = dev.memory().current - ws.held_bytes();
        let chunk = if self.params.chunk_rays == 0 { rays.len().max(1) } else { self.params.chunk_rays };
        let mut levels: Levels = Vec::new();
        let mut visits = Vec::new();
        for (c, part) in rays.chunks(chunk).enumerate() {
            ws.rays.resize(part.len());
            ws.rays.as_mut_slice().copy_from_slice(part);
            ws.keys.resize(part.len());
            simt::fill(dev, &mut ws.keys, NO_HIT);
            if self.params.inspect {
                ws.visits.resize(part.len());
                simt::fill(dev, &mut ws.visits, 0);
            }
            for (depth, lv) in self.trace_chunk(&mut ws, any_hit).into_iter().enumerate() {
                match levels.get_mut(depth) {
                    Some(acc) => record::merge(acc, lv),
                    None => levels.push(lv),
                }
            }
            if self.params.inspect {
                visits.extend_from_slice(ws.visits.as_slice());
            }
            emit(c * chunk, &mut ws);
        }
        let tests = ws.tests.as_slice()[0];
        let records = levels.into_iter().map(|(r, launches)| record::finish(r, &launches)).collect();
        *self.levels.lock().unwrap_or_else(|e| e.into_inner()) = records;
        *self.visits.lock().unwrap_or_else(|e| e.into_inner()) = visits;
        let peak = dev.memory().peak.saturating_sub(resident);
        self.spare.lock().unwrap_or_else(|e| e.into_inner()).push(ws);
        (peak, tests)
    }

    /// The breadth-first recursion over the chunk in `ws.rays`.
    fn trace_chunk(&self, ws: &mut Workspace, any_hit: bool) -> Levels {
        let dev = &self.dev;
        let n = ws.rays.len();
        // Level 0: one node holding every triangle and every ray that enters the scene.
        let (scene_box, grown) = (self.scene_box, self.scene_box.grown(ws.grow));
        ws.next.ray_ids.resize(n);
        simt::sequence(dev, &mut ws.next.ray_ids, 0, 1);
        ws.cur.ray_ids.resize(n);
        let r0 = simt::copy_if_stencil(dev, &ws.next.ray_ids, &ws.rays, &mut ws.cur.ray_ids, |r: Ray| {
            r.is_valid() && grown.intersect(r.origin, crate::geometry::inv_dir(r.dir), r.t_min, r.t_max).is_some()
        });
        ws.cur.ray_ids.resize(r0);
        ws.cur.ray_node.resize(r0);
        simt::fill(dev, &mut ws.cur.ray_node, 0);
        let tri_count = self.tris.len();
        ws.cur.tri_ids.resize(tri_count);
        simt::sequence(dev, &mut ws.cur.tri_ids, 0, 1);
        ws.cur.tri_node.resize(tri_count);
        simt::fill(dev, &mut ws.cur.tri_node, 0);
        ws.cur.nodes.resize(1);
        ws.cur.nodes.as_mut_slice()[0] = NodeData {
            bounds: scene_box,
            ray_start: 0,
            ray_count: r0 as u32,
            tri_start: 0,
            tri_count: tri_count as u32,
            tries: 0,
        };
        let mut levels = Vec::new();
        let mut depth = 0;
        while !ws.cur.nodes.is_empty() && !ws.cur.ray_ids.is_empty() && !ws.cur.tri_ids.is_empty() {
            let mark = dev.launch_mark();
            let record = self.level(ws, depth, any_hit);
            levels.push((record, dev.launches_since(mark)));
            std::mem::swap(&mut ws.cur, &mut ws.next);
            depth += 1;
        }
        levels
    }

    /// A batch too small for a launch: every ray against every triangle on the host,
    /// by brute force's own loops (`cast::caster::intersect_ids`, `any_hit_ids`), whose
    /// tie rule (the smaller id) is the kernels'.
    fn on_host(&self, rays: &[Ray], any_hit: bool, mut out: impl FnMut(usize, u64)) -> u64 {
        let tris = self.tris.as_slice();
        let n = tris.len() as u32;
        let mut tests = 0u64;
        for (i, r) in rays.iter().enumerate() {
            let key = if !r.is_valid() {
                NO_HIT
            } else if any_hit {
                let (blocked, made) = any_hit_ids(tris, 0..n, r, &RayShear::new(r.dir));
                tests += made;
                if blocked { BLOCKED } else { NO_HIT }
            } else {
                let mut hit = Hit::MISS;
                intersect_ids(tris, 0..n, r, &RayShear::new(r.dir), &mut hit);
                tests += n as u64;
                if hit.is_hit() { hit_key::pack(hit.t, hit.prim) } else { NO_HIT }
            };
            out(i, key);
        }
        tests
    }

    /// The hit a key stands for (host side of the tiny-batch path).
    fn resolve(&self, ray: &Ray, key: u64) -> Hit {
        let tri = if key == NO_HIT { [0.0; 9] } else { self.tris.as_slice()[hit_key::prim_of(key) as usize] };
        hit_of_key(ray, key, tri)
    }
}

impl RayCaster for Pdacrt {
    fn name(&self) -> &'static str {
        "pdacrt"
    }

    fn casts_single_rays(&self) -> bool {
        false
    }
    fn device(&self) -> Option<&Device> {
        Some(&self.dev)
    }

    fn closest(&self, rays: &[Ray], hits: &mut [Hit]) -> CastStats {
        assert_eq!(rays.len(), hits.len(), "one hit slot per ray");
        let start = Instant::now();
        let (peak, tests) = if rays.len() < self.params.tiny_batch {
            (0, self.on_host(rays, false, |i, key| hits[i] = self.resolve(&rays[i], key)))
        } else {
            self.trace(rays, false, |first, ws| {
                let n = ws.rays.len();
                ws.hits.resize(n);
                {
                    let (rv, kv, tv, hv) = (ws.rays.view(), ws.keys.view(), self.tris.view(), ws.hits.view_mut());
                    self.dev.for_each("pdacrt::resolve_hits", n, |t, i| resolve_hit(t, &rv, &tv, &kv, &hv, i));
                }
                hits[first..first + n].copy_from_slice(ws.hits.as_slice());
            })
        };
        CastStats { rays: rays.len(), seconds: start.elapsed().as_secs_f64(), peak_working_bytes: peak, tests }
    }

    fn occluded(&self, rays: &[Ray], out: &mut [bool]) -> CastStats {
        assert_eq!(rays.len(), out.len(), "one result slot per ray");
        let start = Instant::now();
        let (peak, tests) = if rays.len() < self.params.tiny_batch {
            (0, self.on_host(rays, true, |i, key| out[i] = key == BLOCKED))
        } else {
            self.trace(rays, true, |first, ws| {
                for (o, &k) in out[first..].iter_mut().zip(ws.keys.as_slice()) {
                    *o = k == BLOCKED;
                }
            })
        };
        CastStats { rays: rays.len(), seconds: start.elapsed().as_secs_f64(), peak_working_bytes: peak, tests }
    }

    fn memory_bytes(&self) -> usize {
        self.tris.bytes()
    }
}
