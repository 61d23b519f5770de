//! PDACRT (Ravichandran and Narayanan 2013): divide-and-conquer ray tracing breadth
//! first, as a pipeline of kernels on the `simt` emulator. Per level:
//!
//! 1. `split_nodes`: every node's box is split at the spatial median of its longest axis;
//! 2. `filter_triangles`, `filter_rays`: every element gets a status code, its node id
//!    with L, B, R or N packed into a `u32` (rays test the child boxes up to their
//!    closest hit so far: early termination);
//! 3. a segmented `sort_by_key` of element ids by status code (the node id in the high
//!    bits keeps segments apart; only the bits in use are sorted);
//! 4. `reduce_by_key` of the codes gives the L/B/R/N counts of every node;
//! 5. `classify_children` and two scans place every child: dropped (no rays or no
//!    triangles), terminal (small, at the depth cap, or no smaller than its parent), or
//!    a node of the next level;
//! 6. `scatter_rays`, `scatter_triangles` build the next level's id arrays and the
//!    terminal buffer (elements coded B go to both children);
//! 7. `brute_force` solves the terminal buffer: one block per chunk of a terminal node's
//!    rays, its triangles staged through shared memory, closest hits merged with a
//!    64-bit `atomic_min` of (distance bits, triangle id).
//!
//! Each level leaves a [`LevelRecord`] (nodes, rays, triangle references, terminal
//! nodes, bytes of id arrays, and time and SIMD efficiency per kernel).

pub mod kernels;

use crate::cast::{CastStats, RayCaster};
use crate::geometry::{Aabb, Hit, Ray, inv_dir};
use crate::scene::Scene;
use kernels::*;
use simt::{Device, DeviceBuffer, DeviceConfig, LaunchConfig};
use std::sync::Mutex;
use std::time::Instant;

/// Tunables of [`Pdacrt`] (defaults chosen by measurement, see `docs/dacrt.md`).
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
}

impl Default for PdacrtParams {
    fn default() -> Self {
        PdacrtParams { leaf_rays: 64, leaf_triangles: 32, max_depth: 40, brute_force_block: 128, measure: false }
    }
}

/// Time and SIMD efficiency of one kernel within one level.
#[derive(Clone, Debug, PartialEq)]
pub struct KernelTime {
    pub name: &'static str,
    pub launches: u32,
    pub seconds: f64,
    pub simd_efficiency: Option<f64>,
}

/// What one breadth-first level did.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct LevelRecord {
    pub level: u32,
    pub nodes: usize,
    /// Ray references alive at this level.
    pub rays: usize,
    pub triangle_refs: usize,
    /// Children of this level's nodes that went to the brute-force stage.
    pub terminal_nodes: usize,
    pub terminal_rays: usize,
    pub terminal_triangles: usize,
    /// Bytes of the level's id arrays (ray and triangle ids with their node ids).
    pub id_bytes: usize,
    pub seconds: f64,
    pub kernels: Vec<KernelTime>,
    /// The level's node boxes (what the inspector draws over the image).
    pub boxes: Vec<Aabb>,
}

pub struct Pdacrt {
    dev: Device,
    tris: DeviceBuffer<[f32; 9]>,
    scene_box: Aabb,
    pub params: PdacrtParams,
    levels: Mutex<Vec<LevelRecord>>,
    visits: Mutex<Vec<u32>>,
}

/// One level's nodes and element id arrays.
struct Level {
    nodes: DeviceBuffer<NodeData>,
    ray_ids: DeviceBuffer<u32>,
    ray_node: DeviceBuffer<u32>,
    tri_ids: DeviceBuffer<u32>,
    tri_node: DeviceBuffer<u32>,
}

fn add3(a: Triple, b: Triple) -> Triple {
    [a[0] + b[0], a[1] + b[1], a[2] + b[2]]
}

impl Pdacrt {
    pub fn new(scene: &Scene) -> Self {
        Self::from_triangles(&scene.triangle_vertices(), PdacrtParams::default())
    }

    pub fn from_triangles(tris: &[[glam::Vec3; 3]], params: PdacrtParams) -> Self {
        let dev = Device::new(DeviceConfig { measure: params.measure, ..Default::default() });
        let flat: Vec<[f32; 9]> = tris
            .iter()
            .map(|t| {
                let [a, b, c] = t.map(|v| v.to_array());
                [a[0], a[1], a[2], b[0], b[1], b[2], c[0], c[1], c[2]]
            })
            .collect();
        let scene_box = tris.iter().fold(Aabb::EMPTY, |b, t| b.union(Aabb::from_points(t)));
        Pdacrt {
            tris: dev.alloc_vec(flat),
            dev,
            scene_box,
            params,
            levels: Mutex::new(Vec::new()),
            visits: Mutex::new(Vec::new()),
        }
    }

    /// The emulated device: its kernel statistics and memory accounting.
    pub fn device(&self) -> &Device {
        &self.dev
    }

    /// Per ray of the most recent trace call: how many terminal nodes tested it.
    pub fn visits(&self) -> Vec<u32> {
        self.visits.lock().unwrap_or_else(|e| e.into_inner()).clone()
    }

    /// The levels of the most recent trace call.
    pub fn levels(&self) -> Vec<LevelRecord> {
        self.levels.lock().unwrap_or_else(|e| e.into_inner()).clone()
    }

    /// Runs the breadth-first recursion; returns the hit keys and rays on the device.
    fn trace(&self, rays: &[Ray], any_hit: bool) -> (DeviceBuffer<u64>, DeviceBuffer<RayData>, usize) {
        let dev = &self.dev;
        dev.reset_peak_memory();
        let resident = dev.memory().current;
        let n = rays.len();
        // Upload (a format conversion, as a cudaMemcpy of a struct array would be).
        let mut ray_buf = dev.alloc_vec(
            rays.iter()
                .map(|r| RayData {
                    origin: r.origin.to_array(),
                    dir: r.dir.to_array(),
                    inv_dir: [0.0; 3],
                    t_min: r.t_min,
                    t_max: r.t_max,
                    _pad: 0.0,
                })
                .collect(),
        );
        {
            let rv = ray_buf.view_mut();
            dev.for_each("pdacrt::prepare_rays", n, |t, i| {
                let mut r = t.load(&rv, i);
                let ray = Ray { origin: r.origin.into(), dir: r.dir.into(), t_min: r.t_min, t_max: r.t_max };
                r.inv_dir = inv_dir(ray.dir).to_array();
                if !ray.is_valid() {
                    r.t_max = f32::NEG_INFINITY; // enters nothing
                }
                t.store(&rv, i, r);
            });
        }
        let mut keys = dev.alloc_filled(n, NO_HIT);
        let mut visits = dev.alloc::<u32>(n);
        let scene_box = self.scene_box;
        let tri_count = self.tris.len();

        // Level 0: one node holding every triangle and every ray that enters the scene.
        let mut all = dev.alloc::<u32>(n);
        simt::sequence(dev, &mut all, 0, 1);
        let mut ray_ids = dev.alloc::<u32>(n);
        let r0 = simt::copy_if_stencil(dev, &all, &ray_buf, &mut ray_ids, |r: RayData| {
            scene_box.intersect(r.origin.into(), r.inv_dir.into(), r.t_min, r.t_max).is_some()
        });
        drop(all);
        let compacted = dev.alloc_from(&ray_ids.as_slice()[..r0]);
        drop(ray_ids);
        let ray_ids = compacted;
        let mut tri_ids = dev.alloc::<u32>(tri_count);
        simt::sequence(dev, &mut tri_ids, 0, 1);
        let root = NodeData {
            bounds: BoxData::from_aabb(scene_box),
            ray_start: 0,
            ray_count: r0 as u32,
            tri_start: 0,
            tri_count: tri_count as u32,
        };
        let mut level = Level {
            nodes: dev.alloc_from(&[root]),
            ray_node: dev.alloc(r0),
            ray_ids,
            tri_node: dev.alloc(tri_count),
            tri_ids,
        };
        let mut records = Vec::new();
        let mut depth = 0;
        while !level.nodes.is_empty() && !level.ray_ids.is_empty() && !level.tri_ids.is_empty() {
            let (next, record) = self.level(level, &ray_buf, &mut keys, &mut visits, depth, any_hit);
            records.push(record);
            level = next;
            depth += 1;
        }
        *self.levels.lock().unwrap_or_else(|e| e.into_inner()) = records;
        *self.visits.lock().unwrap_or_else(|e| e.into_inner()) = visits.to_vec();
        let peak = dev.memory().peak.saturating_sub(resident);
        (keys, ray_buf, peak)
    }

    /// One breadth-first level: returns the next level and this level's record.
    fn level(
        &self,
        lv: Level,
        rays: &DeviceBuffer<RayData>,
        keys: &mut DeviceBuffer<u64>,
        visits: &mut DeviceBuffer<u32>,
        depth: u32,
        any_hit: bool,
    ) -> (Level, LevelRecord) {
        let dev = &self.dev;
        let start = Instant::now();
        let mark = dev.launch_mark();
        let (n_nodes, n_rays, n_tris) = (lv.nodes.len(), lv.ray_ids.len(), lv.tri_ids.len());
        let Level { nodes, ray_ids, ray_node, tri_ids, tri_node } = lv;

        let boxes: Vec<Aabb> = nodes.as_slice().iter().map(|n| n.bounds.aabb()).collect();
        let mut child_boxes = dev.alloc::<BoxData>(2 * n_nodes);
        {
            let (nv, cv) = (nodes.view(), child_boxes.view_mut());
            dev.for_each("pdacrt::split_nodes", n_nodes, |t, i| split_node(t, &nv, &cv, i));
        }
        let mut tri_codes = dev.alloc::<u32>(n_tris);
        {
            let (ids, nd, tv, cb, out) =
                (tri_ids.view(), tri_node.view(), self.tris.view(), child_boxes.view(), tri_codes.view_mut());
            dev.for_each("pdacrt::filter_triangles", n_tris, |t, i| filter_triangle(t, &ids, &nd, &tv, &cb, &out, i));
        }
        let mut ray_codes = dev.alloc::<u32>(n_rays);
        {
            let (ids, nd, rv, kv, cb, out) =
                (ray_ids.view(), ray_node.view(), rays.view(), keys.view(), child_boxes.view(), ray_codes.view_mut());
            dev.for_each("pdacrt::filter_rays", n_rays, |t, i| {
                filter_ray(t, &ids, &nd, &rv, &kv, &cb, any_hit, &out, i)
            });
        }
        drop((ray_node, tri_node));

        // Segmented sort: the node id in the high bits keeps each node's elements together.
        let bits = 2 + (usize::BITS - (n_nodes - 1).leading_zeros());
        let (mut ray_ids, mut tri_ids) = (ray_ids, tri_ids);
        simt::sort_by_key_bits(dev, &mut ray_codes, &mut ray_ids, 0, bits);
        simt::sort_by_key_bits(dev, &mut tri_codes, &mut tri_ids, 0, bits);

        let ray_counts = self.code_counts(&ray_codes, n_nodes);
        let tri_counts = self.code_counts(&tri_codes, n_nodes);

        let n_children = 2 * n_nodes;
        let mut children = dev.alloc::<ChildData>(n_children);
        let mut inner = dev.alloc::<Triple>(n_children);
        let mut terminal = dev.alloc::<Triple>(n_children);
        {
            let rule = LeafRule {
                leaf_rays: self.params.leaf_rays,
                leaf_tris: self.params.leaf_triangles,
                at_max_depth: depth + 1 >= self.params.max_depth,
            };
            let (nv, rc, tc) = (nodes.view(), ray_counts.view(), tri_counts.view());
            let (cv, iv, tv) = (children.view_mut(), inner.view_mut(), terminal.view_mut());
            dev.for_each("pdacrt::classify_children", n_children, |t, c| {
                classify_child(t, &nv, &rc, &tc, rule, &cv, &iv, &tv, c)
            });
        }
        let total = |flags: &DeviceBuffer<Triple>, scan: &DeviceBuffer<Triple>| {
            add3(scan.as_slice()[n_children - 1], flags.as_slice()[n_children - 1])
        };
        let mut inner_scan = dev.alloc::<Triple>(n_children);
        simt::exclusive_scan(dev, &inner, &mut inner_scan, [0; 3], [0; 3], add3);
        let mut terminal_scan = dev.alloc::<Triple>(n_children);
        simt::exclusive_scan(dev, &terminal, &mut terminal_scan, [0; 3], [0; 3], add3);
        let [next_nodes_n, next_rays_n, next_tris_n] = total(&inner, &inner_scan);
        let [term_n, term_rays_n, term_tris_n] = total(&terminal, &terminal_scan);
        drop((inner, terminal));

        let mut next_nodes = dev.alloc::<NodeData>(next_nodes_n as usize);
        let mut term_nodes = dev.alloc::<NodeData>(term_n as usize);
        {
            let (cb, is, ts) = (child_boxes.view(), inner_scan.view(), terminal_scan.view());
            let (cv, nn, tn) = (children.view_mut(), next_nodes.view_mut(), term_nodes.view_mut());
            dev.for_each("pdacrt::emit_children", n_children, |t, c| emit_child(t, &cb, &is, &ts, &cv, &nn, &tn, c));
        }
        drop((inner_scan, terminal_scan, child_boxes));

        let mut next = Level {
            nodes: next_nodes,
            ray_ids: dev.alloc(next_rays_n as usize),
            ray_node: dev.alloc(next_rays_n as usize),
            tri_ids: dev.alloc(next_tris_n as usize),
            tri_node: dev.alloc(next_tris_n as usize),
        };
        let mut term_ray_ids = dev.alloc::<u32>(term_rays_n as usize);
        let mut term_tri_ids = dev.alloc::<u32>(term_tris_n as usize);
        {
            let cv = children.view();
            let (sc, si) = (ray_codes.view(), ray_ids.view());
            let dest = Destinations {
                next_ids: next.ray_ids.view_mut(),
                next_node: next.ray_node.view_mut(),
                terminal_ids: term_ray_ids.view_mut(),
            };
            dev.for_each("pdacrt::scatter_rays", n_rays, |t, i| scatter_ref(t, &sc, &si, &cv, true, &dest, i));
            let (sc, si) = (tri_codes.view(), tri_ids.view());
            let dest = Destinations {
                next_ids: next.tri_ids.view_mut(),
                next_node: next.tri_node.view_mut(),
                terminal_ids: term_tri_ids.view_mut(),
            };
            dev.for_each("pdacrt::scatter_triangles", n_tris, |t, i| scatter_ref(t, &sc, &si, &cv, false, &dest, i));
        }
        drop((children, ray_codes, tri_codes, ray_ids, tri_ids));

        if term_n > 0 {
            self.solve_terminals(&term_nodes, &term_ray_ids, &term_tri_ids, rays, keys, visits, any_hit);
        }

        let record = LevelRecord {
            level: depth,
            nodes: n_nodes,
            rays: n_rays,
            triangle_refs: n_tris,
            terminal_nodes: term_n as usize,
            terminal_rays: term_rays_n as usize,
            terminal_triangles: term_tris_n as usize,
            id_bytes: (n_rays + n_tris) * 8,
            seconds: start.elapsed().as_secs_f64(),
            kernels: kernel_times(&dev.launches_since(mark)),
            boxes,
        };
        (next, record)
    }

    /// L/B/R/N counts per node, as a table `counts[node * 4 + code]`, by reduce-by-key
    /// over the sorted codes.
    fn code_counts(&self, sorted_codes: &DeviceBuffer<u32>, n_nodes: usize) -> DeviceBuffer<u32> {
        let dev = &self.dev;
        let n = sorted_codes.len();
        let mut table = dev.alloc::<u32>(4 * n_nodes);
        if n == 0 {
            return table;
        }
        let ones = dev.alloc_filled(n, 1u32);
        let (mut run_keys, mut run_counts) = (dev.alloc::<u32>(n), dev.alloc::<u32>(n));
        let runs = simt::reduce_by_key(dev, sorted_codes, &ones, &mut run_keys, &mut run_counts, 0, |a, b| a + b);
        let (kv, cv, tv) = (run_keys.view(), run_counts.view(), table.view_mut());
        dev.for_each("pdacrt::count_codes", runs, |t, k| scatter_count(t, &kv, &cv, &tv, k));
        table
    }

    #[allow(clippy::too_many_arguments)]
    fn solve_terminals(
        &self,
        terminals: &DeviceBuffer<NodeData>,
        ray_ids: &DeviceBuffer<u32>,
        tri_ids: &DeviceBuffer<u32>,
        rays: &DeviceBuffer<RayData>,
        keys: &mut DeviceBuffer<u64>,
        visits: &mut DeviceBuffer<u32>,
        any_hit: bool,
    ) {
        let dev = &self.dev;
        let k = terminals.len();
        let block = self.params.brute_force_block;
        let mut chunks = dev.alloc::<u32>(k);
        {
            let (tv, cv) = (terminals.view(), chunks.view_mut());
            dev.for_each("pdacrt::count_chunks", k, |t, i| t.store(&cv, i, t.load(&tv, i).ray_count.div_ceil(block)));
        }
        let mut chunk_start = dev.alloc::<u32>(k);
        simt::exclusive_scan(dev, &chunks, &mut chunk_start, 0, 0, |a, b| a + b);
        let grid = chunk_start.as_slice()[k - 1] + chunks.as_slice()[k - 1];
        let args = BruteForceArgs {
            terminals: terminals.view(),
            chunk_start: chunk_start.view(),
            terminal_count: k,
            ray_ids: ray_ids.view(),
            tri_ids: tri_ids.view(),
            rays: rays.view(),
            tris: self.tris.view(),
            keys: keys.view_mut(),
            visits: visits.view_mut(),
            any_hit,
        };
        let cfg = LaunchConfig { grid, block, shared_bytes: STAGE * 36, regions: &["tests"] };
        dev.launch("pdacrt::brute_force", cfg, |blk| brute_force(blk, &args))
            .expect("brute-force launch shape is valid");
    }
}

/// Per-kernel totals of a level's launches, in order of first launch.
fn kernel_times(launches: &[simt::LaunchRecord]) -> Vec<KernelTime> {
    let mut out: Vec<(KernelTime, simt::RegionStats)> = Vec::new();
    for r in launches {
        let all = r.all_regions();
        match out.iter_mut().find(|(k, _)| k.name == r.name) {
            Some((k, acc)) => {
                k.launches += 1;
                k.seconds += r.seconds;
                acc.add(&all);
            }
            None => {
                out.push((KernelTime { name: r.name, launches: 1, seconds: r.seconds, simd_efficiency: None }, all))
            }
        }
    }
    out.into_iter().map(|(k, acc)| KernelTime { simd_efficiency: acc.simd_efficiency(), ..k }).collect()
}

impl RayCaster for Pdacrt {
    fn name(&self) -> &'static str {
        "pdacrt"
    }

    fn closest(&self, rays: &[Ray], hits: &mut [Hit]) -> CastStats {
        assert_eq!(rays.len(), hits.len(), "one hit slot per ray");
        let start = Instant::now();
        let (keys, ray_buf, peak) = self.trace(rays, false);
        let mut out = self.dev.alloc::<HitData>(rays.len());
        {
            let (rv, tv, kv, ov) = (ray_buf.view(), self.tris.view(), keys.view(), out.view_mut());
            self.dev.for_each("pdacrt::resolve_hits", rays.len(), |t, i| resolve_hit(t, &rv, &tv, &kv, &ov, i));
        }
        for (h, d) in hits.iter_mut().zip(out.as_slice()) {
            *h = Hit { t: d.t, prim: d.prim, u: d.u, v: d.v };
        }
        CastStats { rays: rays.len(), seconds: start.elapsed().as_secs_f64(), peak_working_bytes: peak }
    }

    fn occluded(&self, rays: &[Ray], out: &mut [bool]) -> CastStats {
        assert_eq!(rays.len(), out.len(), "one result slot per ray");
        let start = Instant::now();
        let (keys, _, peak) = self.trace(rays, true);
        for (o, &k) in out.iter_mut().zip(keys.as_slice()) {
            *o = k == BLOCKED;
        }
        CastStats { rays: rays.len(), seconds: start.elapsed().as_secs_f64(), peak_working_bytes: peak }
    }

    fn memory_bytes(&self) -> usize {
        self.tris.bytes()
    }
}
