//! The GPU BVH baseline (`cuda/bvh.cu`, `warpray::gpu::GpuBvh`) on the `simt` emulator:
//! a linear BVH rebuilt from Morton codes (Karras 2012) and traversed one ray per
//! thread with a stack, kernel for kernel the CUDA twin's, so that the emulator can
//! predict what PDACRT's rival costs on a GPU (`docs/simt.md`). Build:
//!
//! 1. `centroid_bounds`: the triangles' centroids reduced to a box (a transform-reduce,
//!    CUB's reduce over a transform iterator in the twin);
//! 2. `morton_codes`: each triangle's 30-bit code in that box;
//! 3. `sort_codes`: a stable radix sort of the codes' 30 bits, carrying the ids;
//! 4. `gather_triangles`: triangles in code order, and their boxes;
//! 5. `emit_hierarchy`: one thread per inner node finds its range and split;
//! 6. `fit_boxes`: one thread per leaf climbs, the second arrival at a node going on,
//!    the whole block a level at a time (as the GPU's lanes and warps climb).
//!
//! Then `trace`: one thread per ray, nearer child first, closest hit as the smallest key
//! (`geometry::hit_key`) or any hit. One triangle per leaf; the keys equal brute
//! force's, bit for bit, as the twin's do.

pub(crate) mod kernels;
#[cfg(test)]
mod tests;

use crate::cast::caster::{CastStats, InThread, RayCaster};
use crate::cast::flat::{flatten, hit_of_key, hits_of_keys};
use crate::geometry::hit_key::{BLOCKED, NONE, prim_of};
use crate::geometry::{Aabb, Hit, Ray, batch_slack, hit_slack};
use crate::scene::Scene;
use kernels::*;
use rayon::prelude::*;
use simt::{Device, DeviceBuffer, DeviceConfig, LaunchConfig};
use std::time::Instant;

/// Threads per block of every kernel (the twin's `BLOCK`).
const BLOCK: u32 = 256;

/// The GPU BVH on the emulator; [`Lbvh::rebuild`] replaces the triangles (a new frame)
/// and builds again.
pub struct Lbvh {
    dev: Device,
    tris: DeviceBuffer<[f32; 9]>,
    magnitude: f32,
    /// The triangles in code order, their original ids, and the inner nodes.
    sorted: DeviceBuffer<[f32; 9]>,
    ids: DeviceBuffer<u32>,
    nodes: DeviceBuffer<Node>,
}

impl Lbvh {
    /// The scene's triangles, built on a device of its own.
    pub fn new(scene: &Scene) -> Self {
        Self::on_device(&scene.triangle_vertices(), Device::new(DeviceConfig::default()))
    }

    /// A triangle list built on `dev` (shared with whatever else runs on it; turn its
    /// measurement on to count the build and the traces).
    pub fn on_device(tris: &[[glam::Vec3; 3]], dev: Device) -> Self {
        let mut bvh = Lbvh {
            tris: dev.alloc(0),
            magnitude: 0.0,
            sorted: dev.alloc(0),
            ids: dev.alloc(0),
            nodes: dev.alloc(0),
            dev,
        };
        bvh.rebuild(tris);
        bvh
    }

    /// The emulated device: its kernel statistics and memory accounting.
    pub fn device(&self) -> &Device {
        &self.dev
    }

    /// Replaces the triangles and builds the tree again.
    pub fn rebuild(&mut self, tris: &[[glam::Vec3; 3]]) {
        let (flat, _, magnitude) = flatten(tris);
        self.tris = self.dev.alloc_vec(flat);
        self.magnitude = magnitude;
        self.build();
    }

    /// The build's stages, as the module's header lists them.
    fn build(&mut self) {
        let dev = &self.dev;
        let n = self.tris.len();
        if n == 0 {
            (self.sorted, self.ids, self.nodes) = (dev.alloc(0), dev.alloc(0), dev.alloc(0));
            return;
        }
        let bounds = simt::transform_reduce(dev, &self.tris, centroid_box, Aabb::EMPTY, Aabb::EMPTY, Aabb::union);
        let bounds = dev.alloc_from(&[bounds]);
        let (mut codes, mut ids) = (dev.alloc::<u32>(n), dev.alloc::<u32>(n));
        {
            let (tv, bv, cv, iv) = (self.tris.view(), bounds.view(), codes.view_mut(), ids.view_mut());
            dev.for_each_in("bvh::morton_codes", &["code"], n, |t, i| morton_code(t, &tv, &bv, &cv, &iv, i));
        }
        simt::sort_by_key_bits(dev, &mut codes, &mut ids, 0, 30);
        let (mut sorted, mut leaf_boxes) = (dev.alloc::<[f32; 9]>(n), dev.alloc::<Aabb>(n));
        {
            let (tv, iv, sv, bv) = (self.tris.view(), ids.view(), sorted.view_mut(), leaf_boxes.view_mut());
            dev.for_each_in("bvh::gather_triangles", &["gather"], n, |t, i| gather_triangle(t, &tv, &iv, &sv, &bv, i));
        }
        let mut nodes = dev.alloc::<Node>(n - 1);
        if n > 1 {
            let (mut inner_parent, mut leaf_parent) = (dev.alloc::<u32>(n - 1), dev.alloc::<u32>(n));
            {
                let (cv, nv, ip, lp) =
                    (codes.view(), nodes.view_mut(), inner_parent.view_mut(), leaf_parent.view_mut());
                dev.for_each_in("bvh::emit_hierarchy", &["search"], n - 1, |t, i| emit_node(t, &cv, &nv, &ip, &lp, i));
            }
            let mut arrivals = dev.alloc_filled::<u32>(n - 1, 0);
            let (bv, lp, ip, nv, av) =
                (leaf_boxes.view(), leaf_parent.view(), inner_parent.view(), nodes.view_mut(), arrivals.view_mut());
            let cfg = LaunchConfig::linear(n, BLOCK).with_regions(&["climb"]);
            let fit = dev.launch("bvh::fit_boxes", cfg, |blk| fit_boxes(blk, &bv, &lp, &ip, &nv, &av, n));
            fit.expect("the fit's launch shape is valid");
        }
        (self.sorted, self.ids, self.nodes) = (sorted, ids, nodes);
    }

    /// The tree as one ray's traversal reads it, inside another kernel.
    fn tree(&self, ray: &Ray, region: usize) -> TreeView<'_> {
        let origin = ray.origin.abs().max_element();
        TreeView {
            nodes: self.nodes.view(),
            tris: self.sorted.view(),
            ids: self.ids.view(),
            root: self.root(),
            grow: hit_slack(self.magnitude, if origin.is_finite() { origin } else { 0.0 }),
            region,
        }
    }

    fn root(&self) -> i32 {
        match self.sorted.len() {
            0 => EMPTY_TREE,
            1 => !0,
            _ => 0,
        }
    }

    /// Every ray's key (closest hit, or [`BLOCKED`] with `any_hit`), and the
    /// ray–triangle tests and inner-node visits made.
    pub fn trace_keys(&self, rays: &[Ray], any_hit: bool) -> (Vec<u64>, u64, u64) {
        let dev = &self.dev;
        let n = rays.len();
        if n == 0 {
            return (Vec::new(), 0, 0);
        }
        let grow = batch_slack(self.magnitude, rays.par_iter().map(|r| r.origin));
        let rays_dev = dev.alloc_from(rays);
        let mut keys = dev.alloc_filled::<u64>(n, NONE);
        let mut counters = dev.alloc_filled::<u64>(2, 0);
        {
            let tree = TreeView {
                nodes: self.nodes.view(),
                tris: self.sorted.view(),
                ids: self.ids.view(),
                root: self.root(),
                grow,
                region: 0,
            };
            let (rv, kv, cv) = (rays_dev.view(), keys.view_mut(), counters.view_mut());
            // The twin's trace kernel uses 48 registers per thread (Nsight Compute on the
            // H200: docs/measured/h200-time-model/ncu-bvh-*-1024-primary-shadow.csv.gz).
            let cfg = LaunchConfig::linear(n, BLOCK).with_regions(&["traverse"]).with_registers(48);
            dev.launch("bvh::trace", cfg, |blk| {
                blk.for_each_warp(|w| {
                    let (mut tests, mut visits) = ([0u32; 32], [0u32; 32]);
                    w.for_each_lane(|t| {
                        let i = t.global_idx();
                        if i < n {
                            let (key, made, seen) = trace_key(t, &tree, RayAt::Loaded(&rv, i), any_hit);
                            t.store(&kv, i, key);
                            t.work(0, 0, TRACE_TAIL);
                            (tests[t.lane_id() as usize], visits[t.lane_id() as usize]) = (made, seen);
                        }
                    });
                    add_warp(w, &tests, &cv, 0, TRACE_TAIL_LANE0[0]);
                    add_warp(w, &visits, &cv, 1, TRACE_TAIL_LANE0[1]);
                });
            })
            .expect("the trace's launch shape is valid");
        }
        let c = counters.as_slice();
        (keys.into_vec(), c[0], c[1])
    }

    /// Working bytes of a trace: the rays and their keys on the device.
    fn cast_stats(&self, rays: usize, start: Instant, tests: u64) -> CastStats {
        CastStats { rays, seconds: start.elapsed().as_secs_f64(), peak_working_bytes: 40 * rays, tests }
    }
}

/// The traversal inside another kernel's threads (the LVC megakernel's): the tree's
/// views, boxes grown for the one ray.
impl InThread for Lbvh {
    fn closest_in_thread(&self, t: &simt::Thread, ray: &Ray, region: usize) -> Hit {
        let (key, _, _) = trace_key(t, &self.tree(ray, region), RayAt::Held(*ray), false);
        let tri = if key == NONE { [0.0; 9] } else { t.load(&self.tris.view(), prim_of(key) as usize) };
        hit_of_key(ray, key, tri)
    }

    fn occluded_in_thread(&self, t: &simt::Thread, ray: &Ray, region: usize) -> bool {
        trace_key(t, &self.tree(ray, region), RayAt::Held(*ray), true).0 == BLOCKED
    }
}

impl RayCaster for Lbvh {
    fn name(&self) -> &'static str {
        "lbvh"
    }

    fn casts_single_rays(&self) -> bool {
        false
    }

    fn device(&self) -> Option<&Device> {
        Some(&self.dev)
    }

    fn in_thread(&self) -> Option<&dyn InThread> {
        Some(self)
    }

    fn closest(&self, rays: &[Ray], hits: &mut [Hit]) -> CastStats {
        assert_eq!(rays.len(), hits.len(), "one hit slot per ray");
        let start = Instant::now();
        let (keys, tests, _) = self.trace_keys(rays, false);
        hits_of_keys(self.tris.as_slice(), rays, &keys, hits);
        self.cast_stats(rays.len(), start, tests)
    }

    fn occluded(&self, rays: &[Ray], out: &mut [bool]) -> CastStats {
        assert_eq!(rays.len(), out.len(), "one result slot per ray");
        let start = Instant::now();
        let (keys, tests, _) = self.trace_keys(rays, true);
        out.par_iter_mut().zip(keys).for_each(|(o, k)| *o = k == BLOCKED);
        self.cast_stats(rays.len(), start, tests)
    }

    fn memory_bytes(&self) -> usize {
        self.tris.bytes() + self.sorted.bytes() + self.ids.bytes() + self.nodes.bytes()
    }
}
