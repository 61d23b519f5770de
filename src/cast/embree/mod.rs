//! Embree (Intel's CPU ray-tracing kernels) as a caster: the tool a CPU user would pick
//! instead of DACRT, here so that every table measures both on the same rays
//! (cargo feature `embree`).
//!
//! The library is opened at run time (`ffi.rs`): Embree 3 from Debian
//! (`apt-get install libembree-dev`) or any Embree 4 build named by `WARPRAY_EMBREE`.
//! Embree chooses its SSE/AVX2/AVX-512 kernels itself, at run time.
//!
//! * **Presets** ([`EmbreeParams`]): [`EmbreeParams::default`] is Embree's own default
//!   (medium build quality, single rays); [`EmbreeParams::fastest`] is the setting for
//!   a structure rebuilt every frame (low quality, dynamic scene, 16-ray packets);
//!   [`EmbreeParams::refit`] keeps the first build's topology and only refits its boxes
//!   when [`EmbreeCaster::update`] moves the vertices. `robust` turns on Embree's
//!   watertight mode, which the brute-force comparison needs on adversarial input.
//! * **Hits**: Embree finds the closest triangle; its distance and barycentrics are
//!   then taken from warpray's own watertight test on that triangle (as DACRT does), so
//!   every caster reports hits by one rule. A triangle Embree cannot represent (a
//!   coordinate beyond [`OUTLIER_COORDINATE`], or not finite) is tested by brute force
//!   against every ray, as in the BVH caster.
//! * **Threads**: Embree builds with the calling rayon pool's thread count; rays are
//!   traced by rayon, 16 at a time.
//! * Embree does not report its ray–triangle tests: [`CastStats::tests`] counts only
//!   the tests warpray makes itself.

mod ffi;

pub use ffi::LIBRARY_ENV;

use super::caster::{CastStats, RayCaster, Triangles, intersect_ids, timed, triangles_bytes};
use crate::cast::bvh::OUTLIER_COORDINATE;
use crate::error::{Error, Result};
use crate::geometry::{Hit, Ray, RayShear, intersect_triangle};
use crate::scene::Scene;
use ffi::{Handle, Library, Query, RayHit1, RayHit16, Valid16};
use rayon::prelude::*;
use std::ffi::c_void;
use std::sync::atomic::{AtomicIsize, Ordering::Relaxed};
use std::time::Instant;

/// Embree's build quality (`RTC_BUILD_QUALITY_*`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "cli", derive(clap::ValueEnum))]
pub enum BuildQuality {
    /// Fast build (Morton codes), for structures rebuilt every frame.
    Low = 0,
    /// Embree's default: a binned SAH build.
    #[default]
    Medium = 1,
    /// Spatial splits: slowest build, fastest traversal.
    High = 2,
}

/// How the Embree scene is built and traced.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct EmbreeParams {
    /// Build quality.
    pub quality: BuildQuality,
    /// `RTC_SCENE_FLAG_DYNAMIC`: the scene is expected to change (faster builds).
    pub dynamic: bool,
    /// `RTC_SCENE_FLAG_ROBUST`: watertight triangle tests, no missed edges.
    pub robust: bool,
    /// Trace 16-ray packets (`rtcIntersect16`) instead of single rays.
    pub packets: bool,
    /// On [`EmbreeCaster::update`], refit the first build's boxes instead of rebuilding.
    pub refit: bool,
}

impl Default for EmbreeParams {
    /// Embree's defaults: medium quality, a static scene, single rays.
    fn default() -> Self {
        EmbreeParams { quality: BuildQuality::Medium, dynamic: false, robust: false, packets: false, refit: false }
    }
}

impl EmbreeParams {
    /// The fastest rebuild: low quality, dynamic scene, 16-ray packets.
    pub fn fastest() -> Self {
        EmbreeParams { quality: BuildQuality::Low, dynamic: true, packets: true, ..Default::default() }
    }

    /// A dynamic scene whose updates refit the first build (medium quality).
    pub fn refit() -> Self {
        EmbreeParams { dynamic: true, refit: true, packets: true, ..Default::default() }
    }

    /// The same setting with Embree's watertight mode.
    pub fn robust(self) -> Self {
        EmbreeParams { robust: true, ..self }
    }

    /// The setting a [`label`](Self::label) names (`None` for any other text).
    pub fn by_label(label: &str) -> Option<EmbreeParams> {
        let (base, robust) = match label.strip_suffix("-robust") {
            Some(b) => (b, true),
            None => (label, false),
        };
        let p = match base {
            "embree" => EmbreeParams::default(),
            "embree-fast" => EmbreeParams::fastest(),
            "embree-refit" => EmbreeParams::refit(),
            _ => return None,
        };
        Some(if robust { p.robust() } else { p })
    }

    /// A short label for tables: `embree`, `embree-fast`, `embree-refit`, plus `-robust`.
    pub fn label(&self) -> &'static str {
        match (self.refit, self.quality == BuildQuality::Low && self.dynamic, self.robust) {
            (true, _, false) => "embree-refit",
            (true, _, true) => "embree-refit-robust",
            (false, true, false) => "embree-fast",
            (false, true, true) => "embree-fast-robust",
            (false, false, false) => "embree",
            (false, false, true) => "embree-robust",
        }
    }
}

/// Embree's BVH over a triangle soup (see the module docs).
pub struct EmbreeCaster {
    lib: &'static Library,
    device: Handle,
    scene: Handle,
    geometry: Handle,
    /// Embree's vertex buffer: three float3 per triangle, owned by the geometry.
    vertices: *mut f32,
    params: EmbreeParams,
    tris: Triangles,
    /// Triangles Embree cannot take, tested by brute force.
    outliers: Vec<u32>,
    /// Bytes Embree holds now, from its memory monitor (boxed: Embree keeps the pointer).
    memory: Box<AtomicIsize>,
    build_seconds: f64,
}

// SAFETY: Embree allows queries on a committed scene from any number of threads at
// once; the scene is only changed through `&mut self` (`update`).
unsafe impl Send for EmbreeCaster {}
// SAFETY: as above.
unsafe impl Sync for EmbreeCaster {}

/// Embree's memory monitor: keeps the running total of its allocations.
unsafe extern "C" fn count_memory(user: *mut c_void, bytes: isize, _post: bool) -> bool {
    // SAFETY: `user` is the caster's boxed counter, which outlives the device.
    let total = unsafe { &*(user as *const AtomicIsize) };
    total.fetch_add(bytes, Relaxed);
    true
}

/// Embree's `tnear` for a ray: Embree accepts hits at `t = tnear`, warpray's casters
/// only beyond `t_min`, so the next float up (a ray leaving a surface then does not hit
/// that surface at `t = 0`, as in every other caster). Embree takes no negative `tnear`.
#[inline]
fn tnear(r: &Ray) -> f32 {
    r.t_min.max(0.0).next_up()
}

/// A packet of up to 16 rays and its valid mask (-1 for each valid ray).
fn packet(rays: &[Ray]) -> (RayHit16, Valid16) {
    let mut p = RayHit16::empty();
    let mut valid = Valid16::default();
    for (i, r) in rays.iter().enumerate().filter(|(_, r)| r.is_valid()) {
        p.set(i, r.origin.to_array(), r.dir.to_array(), tnear(r), r.t_max);
        valid.0[i] = -1;
    }
    (p, valid)
}

/// Whether Embree can represent the triangle (its builder drops the others).
fn regular(t: &[glam::Vec3; 3]) -> bool {
    t.iter().all(|v| v.is_finite() && v.abs().max_element() <= OUTLIER_COORDINATE)
}

impl EmbreeCaster {
    /// Embree's default build of the scene's triangles.
    pub fn new(scene: &Scene) -> Result<Self> {
        Self::from_triangles(scene.triangle_vertices(), EmbreeParams::default())
    }

    /// Builds the scene of a triangle list with the given settings.
    pub fn from_triangles(tris: Triangles, params: EmbreeParams) -> Result<Self> {
        let lib = ffi::library()?;
        let fail = |msg: String| Error::Embree { library: lib.path.clone(), msg };
        let config = std::ffi::CString::new(format!("threads={},set_affinity=0", rayon::current_num_threads()))
            .expect("no NUL in the configuration");
        // SAFETY: a valid configuration string.
        let device = unsafe { lib.new_device(&config) };
        if device.is_null() {
            return Err(fail("rtcNewDevice failed".into()));
        }
        let memory = Box::new(AtomicIsize::new(0));
        // SAFETY: a live device and a counter that outlives it (dropped after it in Drop).
        unsafe { lib.set_memory_monitor(device, count_memory, &*memory as *const AtomicIsize as *mut c_void) };
        let n = tris.len();
        // SAFETY: the device is live; each handle is released in Drop.
        let (scene, geometry, vertices) = unsafe {
            let scene = lib.new_scene(device);
            let flags = if params.dynamic { ffi::SCENE_FLAG_DYNAMIC } else { 0 }
                | if params.robust { ffi::SCENE_FLAG_ROBUST } else { 0 };
            lib.set_scene_flags(scene, flags);
            lib.set_scene_quality(scene, params.quality as i32);
            let geometry = lib.new_geometry(device);
            lib.set_geometry_quality(geometry, params.quality as i32);
            let vertices = lib.new_buffer(geometry, ffi::BUFFER_TYPE_VERTEX, ffi::FORMAT_FLOAT3, 12, 3 * n.max(1));
            let index = lib.new_buffer(geometry, ffi::BUFFER_TYPE_INDEX, ffi::FORMAT_UINT3, 12, n.max(1)) as *mut u32;
            if vertices.is_null() || index.is_null() {
                let e = lib.error(device).unwrap_or_default();
                lib.release_geometry(geometry);
                lib.release_scene(scene);
                lib.release_device(device);
                return Err(fail(format!("no geometry buffers for {n} triangles: {e}")));
            }
            // Triangle i is vertices 3i..3i+3; a scene with no triangles gets one
            // degenerate triangle at the origin, which Embree drops.
            std::slice::from_raw_parts_mut(index, 3 * n.max(1))
                .par_iter_mut()
                .enumerate()
                .for_each(|(k, v)| *v = k as u32);
            (scene, geometry, vertices as *mut f32)
        };
        let mut caster = EmbreeCaster {
            lib,
            device,
            scene,
            geometry,
            vertices,
            params,
            tris: Vec::new(),
            outliers: Vec::new(),
            memory,
            build_seconds: 0.0,
        };
        caster.commit(tris, true)?;
        Ok(caster)
    }

    /// The settings it was built with.
    pub fn params(&self) -> EmbreeParams {
        self.params
    }

    /// Embree's version, as it writes it (40400 for 4.4.0).
    pub fn version(&self) -> u32 {
        self.lib.version
    }

    /// Moves the triangles (same count, same order) and rebuilds, or refits with
    /// [`EmbreeParams::refit`]; the time goes to [`RayCaster::build_seconds`].
    pub fn update(&mut self, tris: Triangles) -> Result<()> {
        if tris.len() != self.tris.len() {
            return Err(Error::Embree {
                library: self.lib.path.clone(),
                msg: format!("update with {} triangles, built with {}", tris.len(), self.tris.len()),
            });
        }
        self.commit(tris, false)
    }

    /// Writes the vertex buffer and commits geometry and scene, timing it all.
    fn commit(&mut self, tris: Triangles, first: bool) -> Result<()> {
        let start = Instant::now();
        let n = tris.len();
        // SAFETY: the buffer holds 3 float3 per triangle (3 for an empty scene).
        let v = unsafe { std::slice::from_raw_parts_mut(self.vertices, 9 * n.max(1)) };
        if n == 0 {
            v.fill(0.0);
        }
        // Embree skips a triangle with any coordinate it cannot take; such triangles
        // are collapsed to the origin's point and listed, to be tested apart.
        self.outliers = v
            .par_chunks_mut(9)
            .zip(tris.par_iter())
            .enumerate()
            .filter_map(|(i, (dst, t))| {
                let keep = regular(t);
                for (k, p) in t.iter().enumerate() {
                    let p = if keep { *p } else { glam::Vec3::ZERO };
                    dst[3 * k..3 * k + 3].copy_from_slice(&p.to_array());
                }
                (!keep).then_some(i as u32)
            })
            .collect();
        let lib = self.lib;
        // SAFETY: live handles; the buffer was written above.
        unsafe {
            if !first {
                lib.update_buffer(self.geometry, ffi::BUFFER_TYPE_VERTEX);
                if self.params.refit {
                    lib.set_geometry_quality(self.geometry, ffi::BUILD_QUALITY_REFIT);
                }
            }
            lib.commit_geometry(self.geometry);
            if first {
                lib.attach(self.scene, self.geometry);
            }
            lib.commit_scene(self.scene);
        }
        if let Some(e) = lib.error(self.device) {
            return Err(Error::Embree { library: lib.path.clone(), msg: format!("building {n} triangles: {e}") });
        }
        self.tris = tris;
        self.build_seconds = start.elapsed().as_secs_f64();
        Ok(())
    }

    /// warpray's hit on triangle `prim`, which Embree found at `t`; Embree's own
    /// distance and barycentrics where the watertight test disagrees by a rounding.
    fn hit(&self, ray: &Ray, shear: &RayShear, prim: u32, t: f32, u: f32, v: f32) -> Hit {
        let [a, b, c] = self.tris[prim as usize];
        intersect_triangle(ray.origin, shear, a, b, c, ray.t_min, ray.t_max)
            .map_or(Hit { t, prim, u, v }, |(t, u, v)| Hit { t, prim, u, v })
    }

    /// Closest hits of up to 16 rays; returns the tests warpray made itself.
    fn closest_chunk(&self, rays: &[Ray], hits: &mut [Hit]) -> u64 {
        let lib = self.lib;
        let mut args = lib.args(false);
        let mut tests = 0;
        if self.params.packets {
            let (mut p, valid) = packet(rays);
            // SAFETY: a committed scene.
            unsafe { lib.query16(Query::Intersect, &valid, self.scene, &mut p, &mut args) };
            for (i, (r, h)) in rays.iter().zip(hits.iter_mut()).enumerate() {
                *h = Hit::MISS;
                if valid.0[i] != 0 && p.geom_id[i] != ffi::INVALID_ID {
                    *h = self.hit(r, &RayShear::new(r.dir), p.prim_id[i], p.tfar[i], p.u[i], p.v[i]);
                }
            }
        } else {
            for (r, h) in rays.iter().zip(hits.iter_mut()) {
                *h = Hit::MISS;
                if !r.is_valid() {
                    continue;
                }
                let mut q = RayHit1::new(r.origin.to_array(), r.dir.to_array(), tnear(r), r.t_max);
                // SAFETY: a committed scene.
                unsafe { lib.query1(Query::Intersect, self.scene, &mut q, &mut args) };
                if q.geom_id != ffi::INVALID_ID {
                    *h = self.hit(r, &RayShear::new(r.dir), q.prim_id, q.tfar, q.u, q.v);
                }
            }
        }
        if !self.outliers.is_empty() {
            for (r, h) in rays.iter().zip(hits.iter_mut()).filter(|(r, _)| r.is_valid()) {
                intersect_ids(&self.tris, self.outliers.iter().copied(), r, &RayShear::new(r.dir), h);
                tests += self.outliers.len() as u64;
            }
        }
        tests
    }

    /// Occlusion of up to 16 rays; returns the tests warpray made itself.
    fn occluded_chunk(&self, rays: &[Ray], out: &mut [bool]) -> u64 {
        let lib = self.lib;
        let mut args = lib.args(false);
        if self.params.packets {
            let (mut p, valid) = packet(rays);
            // SAFETY: a committed scene; `RayHit16` starts with `RTCRay16`.
            unsafe { lib.query16(Query::Occluded, &valid, self.scene, &mut p, &mut args) };
            for (i, o) in out.iter_mut().enumerate() {
                *o = valid.0[i] != 0 && p.tfar[i] == f32::NEG_INFINITY;
            }
        } else {
            for (r, o) in rays.iter().zip(out.iter_mut()) {
                *o = false;
                if r.is_valid() {
                    let mut q = RayHit1::new(r.origin.to_array(), r.dir.to_array(), tnear(r), r.t_max);
                    // SAFETY: a committed scene; `RayHit1` starts with `RTCRay`.
                    unsafe { lib.query1(Query::Occluded, self.scene, &mut q, &mut args) };
                    *o = q.tfar == f32::NEG_INFINITY;
                }
            }
        }
        let mut tests = 0;
        if !self.outliers.is_empty() {
            for (r, o) in rays.iter().zip(out.iter_mut()).filter(|(r, o)| r.is_valid() && !**o) {
                let (hit, n) =
                    super::caster::any_hit_ids(&self.tris, self.outliers.iter().copied(), r, &RayShear::new(r.dir));
                *o = hit;
                tests += n;
            }
        }
        tests
    }
}

impl Drop for EmbreeCaster {
    fn drop(&mut self) {
        // SAFETY: each handle released once, the device last.
        unsafe {
            self.lib.release_geometry(self.geometry);
            self.lib.release_scene(self.scene);
            self.lib.release_device(self.device);
        }
    }
}

impl RayCaster for EmbreeCaster {
    fn name(&self) -> &'static str {
        self.params.label()
    }

    fn closest(&self, rays: &[Ray], hits: &mut [Hit]) -> CastStats {
        assert_eq!(rays.len(), hits.len(), "one hit slot per ray");
        timed(rays.len(), 0, || {
            rays.par_chunks(16).zip(hits.par_chunks_mut(16)).map(|(r, h)| self.closest_chunk(r, h)).sum()
        })
    }

    fn occluded(&self, rays: &[Ray], out: &mut [bool]) -> CastStats {
        assert_eq!(rays.len(), out.len(), "one result slot per ray");
        timed(rays.len(), 0, || {
            rays.par_chunks(16).zip(out.par_chunks_mut(16)).map(|(r, o)| self.occluded_chunk(r, o)).sum()
        })
    }

    fn memory_bytes(&self) -> usize {
        self.memory.load(Relaxed).max(0) as usize + triangles_bytes(&self.tris)
    }

    fn build_seconds(&self) -> f64 {
        self.build_seconds
    }
}
