//! What every caster shares, one floor below the casters: the [`RayCaster`] trait and
//! its [`CastStats`], the triangle list, the brute-force loops over listed triangles
//! that the oracle, the BVH's outliers and Embree's fallback call, and the counting
//! wrapper. `cast/mod.rs` re-exports these and dispatches; the casters import from here.

use crate::geometry::{Hit, Ray, RayShear, intersect_triangle};
use glam::Vec3;
use std::sync::atomic::{AtomicBool, AtomicU64, AtomicUsize, Ordering::Relaxed};
use std::time::Instant;

/// What one batch call did.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct CastStats {
    /// Rays in the batch.
    pub rays: usize,
    /// Wall time of the call, seconds.
    pub seconds: f64,
    /// Peak bytes the caster allocated for this call beyond its own structure
    /// (id lists, queues); 0 for casters that work in per-thread stack space.
    pub peak_working_bytes: usize,
    /// Ray–triangle intersection tests made: the algorithm's cost, independent of the
    /// machine.
    pub tests: u64,
}

impl CastStats {
    /// Rays per second.
    pub fn rays_per_second(&self) -> f64 {
        if self.seconds > 0.0 { self.rays as f64 / self.seconds } else { 0.0 }
    }

    /// Ray–triangle tests per ray.
    pub fn tests_per_ray(&self) -> f64 {
        if self.rays > 0 { self.tests as f64 / self.rays as f64 } else { 0.0 }
    }

    /// Peak working bytes per ray of the call.
    pub fn bytes_per_ray(&self) -> f64 {
        if self.rays > 0 { self.peak_working_bytes as f64 / self.rays as f64 } else { 0.0 }
    }

    /// Sums two calls (peak memory is the larger of the two).
    pub fn merge(self, o: CastStats) -> CastStats {
        CastStats {
            rays: self.rays + o.rays,
            seconds: self.seconds + o.seconds,
            peak_working_bytes: self.peak_working_bytes.max(o.peak_working_bytes),
            tests: self.tests + o.tests,
        }
    }
}

/// Every ray caster: BVH, brute force, serial DACRT, PDACRT.
pub trait RayCaster: Send + Sync {
    /// Short name for tables and the command line (`"bvh"`, `"brute"`, …).
    fn name(&self) -> &'static str;
    /// Closest hit of every ray; `hits.len()` must equal `rays.len()`.
    fn closest(&self, rays: &[Ray], hits: &mut [Hit]) -> CastStats;
    /// Whether anything lies on each ray within `(t_min, t_max)`; `out.len() == rays.len()`.
    fn occluded(&self, rays: &[Ray], out: &mut [bool]) -> CastStats;
    /// Bytes of the caster's persistent structure (BVH nodes, indices, its triangle copy).
    fn memory_bytes(&self) -> usize;
    /// The last call's seconds by stage, in order, for casters that time their stages
    /// (DACRT: `filter`, `prepare` with its two halves run side by side, the shared
    /// top's `top_plan`, `top_route` and `top_gather`, `groups` with the groups' summed
    /// and longest times, `back`); empty for the others. [`phases_json`] writes them.
    fn phase_seconds(&self) -> Vec<(&'static str, f64)> {
        Vec::new()
    }
    /// Seconds spent building the structure (0 for casters with none).
    fn build_seconds(&self) -> f64 {
        0.0
    }
    /// The emulated GPU the caster runs on, for casters that run on one (PDACRT). A
    /// render hands it to integrators that stream on `simt` too, so that one device
    /// holds the render's whole kernel table and memory peak.
    fn device(&self) -> Option<&simt::Device> {
        None
    }
    /// A traversal that one kernel thread runs itself, for casters that have one (the
    /// GPU BVH's twin): the LVC megakernel traces its rays through it inside its
    /// threads, as a GPU megakernel does, rather than one caster call per ray.
    fn in_thread(&self) -> Option<&dyn InThread> {
        None
    }
    /// Whether the caster suits rays cast one at a time (the LVC megakernel's): true
    /// for casters with a stored structure traversed per ray, false for the
    /// divide-and-conquer casters, which build their work from the batch, for the
    /// emulated GPU casters and for the GPU casters, whose calls are launches.
    fn casts_single_rays(&self) -> bool {
        true
    }
    /// The closest hit of one ray and the tests made, untimed: for callers that cast
    /// their rays one at a time (the LVC megakernel's threads), where timing each call
    /// would cost about as much as the traversal. The default is a one-ray batch.
    fn closest_single(&self, ray: &Ray) -> (Hit, u64) {
        let mut hit = [Hit::MISS];
        let s = self.closest(std::slice::from_ref(ray), &mut hit);
        (hit[0], s.tests)
    }
    /// Whether anything lies on one ray, and the tests made, untimed (see
    /// [`RayCaster::closest_single`]).
    fn occluded_single(&self, ray: &Ray) -> (bool, u64) {
        let mut blocked = [false];
        let s = self.occluded(std::slice::from_ref(ray), &mut blocked);
        (blocked[0], s.tests)
    }
}

/// A caster's traversal run by one thread of a `simt` kernel, its work counted as that
/// thread's, declared in the launch's region `region` (`RayCaster::in_thread`).
pub trait InThread: Send + Sync {
    /// The closest hit of `ray`.
    fn closest_in_thread(&self, t: &simt::Thread, ray: &Ray, region: usize) -> Hit;
    /// Whether anything lies on `ray` within `(t_min, t_max)`.
    fn occluded_in_thread(&self, t: &simt::Thread, ray: &Ray, region: usize) -> bool;
}

/// Triangle corners in scene order, as the casters store them.
pub type Triangles = Vec<[Vec3; 3]>;

/// Bytes of a triangle array.
pub(crate) fn triangles_bytes(tris: &Triangles) -> usize {
    tris.len() * std::mem::size_of::<[Vec3; 3]>()
}

/// Runs `f` timing it, and fills in the ray count; `f` returns the tests it made.
pub(crate) fn timed(rays: usize, peak_working_bytes: usize, f: impl FnOnce() -> u64) -> CastStats {
    let start = Instant::now();
    let tests = f();
    CastStats { rays, seconds: start.elapsed().as_secs_f64(), peak_working_bytes, tests }
}

/// Answers every ray of a batch in parallel with `one` (its answer and the tests it
/// made), timed: the loop of the casters that take rays one at a time.
pub(crate) fn per_ray<T: Send>(rays: &[Ray], out: &mut [T], one: impl Fn(&Ray) -> (T, u64) + Sync + Send) -> CastStats {
    assert_eq!(rays.len(), out.len(), "one result slot per ray");
    timed(rays.len(), 0, || {
        use rayon::prelude::*;
        rays.par_iter()
            .zip(out.par_iter_mut())
            .with_min_len(64)
            .map(|(ray, o)| {
                let (answer, tests) = one(ray);
                *o = answer;
                tests
            })
            .sum()
    })
}

/// Answers every ray of a batch in parallel, `width` rays at a time, with `packet`
/// (which writes the answers of its rays and returns the tests it made), timed: the
/// loop of the casters that trace packets.
pub(crate) fn per_packet<T: Send>(
    rays: &[Ray],
    out: &mut [T],
    width: usize,
    packet: impl Fn(&[Ray], &mut [T]) -> u64 + Sync + Send,
) -> CastStats {
    assert_eq!(rays.len(), out.len(), "one result slot per ray");
    timed(rays.len(), 0, || {
        use rayon::prelude::*;
        rays.par_chunks(width).zip(out.par_chunks_mut(width)).with_min_len(64 / width).map(|(r, o)| packet(r, o)).sum()
    })
}

/// Wraps a caster and adds up every call made through it, from any thread: what a
/// render reports as rays cast, seconds inside the caster (summed over calls, so calls
/// made in parallel each count their own wall time), tests and peak working bytes.
/// Single-ray calls are counted, untimed, on a counter per worker thread (one shared
/// counter would be contended by every ray of every thread).
pub struct CountingCaster<'a> {
    inner: &'a dyn RayCaster,
    singles: Box<[SingleRays]>,
    rays: AtomicU64,
    tests: AtomicU64,
    nanos: AtomicU64,
    peak: AtomicUsize,
    shadow: AtomicU64,
    calls: AtomicU64,
    /// Calls running now, and whether two ever ran at once.
    in_flight: AtomicUsize,
    overlapped: AtomicBool,
}

impl<'a> CountingCaster<'a> {
    /// A counter around `inner`, starting at zero.
    pub fn new(inner: &'a dyn RayCaster) -> Self {
        CountingCaster {
            inner,
            singles: (0..=rayon::current_num_threads()).map(|_| SingleRays::default()).collect(),
            rays: AtomicU64::new(0),
            tests: AtomicU64::new(0),
            nanos: AtomicU64::new(0),
            peak: AtomicUsize::new(0),
            shadow: AtomicU64::new(0),
            calls: AtomicU64::new(0),
            in_flight: AtomicUsize::new(0),
            overlapped: AtomicBool::new(false),
        }
    }

    /// Rays sent through `occluded` or `occluded_single` (shadow and connection rays) so
    /// far; the rest of [`CastStats::rays`] went through `closest` or `closest_single`.
    pub fn shadow_rays(&self) -> u64 {
        self.shadow.load(Relaxed) + self.singles.iter().map(|c| c.shadow.load(Relaxed)).sum::<u64>()
    }

    /// Caster calls (batches) with at least one ray so far: rays per call is how
    /// batch-friendly the caller is.
    pub fn calls(&self) -> u64 {
        self.calls.load(Relaxed) + self.single_rays()
    }

    /// Rays cast one at a time (`closest_single`, `occluded_single`) so far: counted
    /// in [`CastStats::rays`], but not in its seconds.
    pub fn single_rays(&self) -> u64 {
        self.singles.iter().map(|c| c.rays.load(Relaxed)).sum()
    }

    /// The calling worker thread's single-ray counters.
    fn single(&self, tests: u64, shadow: bool) {
        let c = &self.singles[rayon::current_thread_index().map_or(0, |i| i + 1) % self.singles.len()];
        c.rays.fetch_add(1, Relaxed);
        c.tests.fetch_add(tests, Relaxed);
        c.shadow.fetch_add(shadow as u64, Relaxed);
    }

    /// Whether two calls ever ran at the same time (an integrator casting from
    /// several threads at once): then the summed seconds count overlapping wall times
    /// and are no longer a part of the render's wall time.
    pub fn overlapped(&self) -> bool {
        self.overlapped.load(Relaxed)
    }

    /// Runs one call of the inner caster, noting whether another was running.
    fn call(&self, f: impl FnOnce() -> CastStats) -> CastStats {
        if self.in_flight.fetch_add(1, Relaxed) > 0 {
            self.overlapped.store(true, Relaxed);
        }
        let s = f();
        self.in_flight.fetch_sub(1, Relaxed);
        self.add(s)
    }

    /// Everything counted so far.
    pub fn stats(&self) -> CastStats {
        CastStats {
            rays: (self.rays.load(Relaxed) + self.single_rays()) as usize,
            seconds: self.nanos.load(Relaxed) as f64 * 1e-9,
            peak_working_bytes: self.peak.load(Relaxed),
            tests: self.tests.load(Relaxed) + self.singles.iter().map(|c| c.tests.load(Relaxed)).sum::<u64>(),
        }
    }

    fn add(&self, s: CastStats) -> CastStats {
        self.rays.fetch_add(s.rays as u64, Relaxed);
        self.tests.fetch_add(s.tests, Relaxed);
        self.nanos.fetch_add((s.seconds * 1e9) as u64, Relaxed);
        self.peak.fetch_max(s.peak_working_bytes, Relaxed);
        self.calls.fetch_add((s.rays > 0) as u64, Relaxed);
        s
    }
}

impl RayCaster for CountingCaster<'_> {
    fn name(&self) -> &'static str {
        self.inner.name()
    }
    fn closest(&self, rays: &[Ray], hits: &mut [Hit]) -> CastStats {
        self.call(|| self.inner.closest(rays, hits))
    }
    fn occluded(&self, rays: &[Ray], out: &mut [bool]) -> CastStats {
        self.shadow.fetch_add(rays.len() as u64, Relaxed);
        self.call(|| self.inner.occluded(rays, out))
    }
    fn memory_bytes(&self) -> usize {
        self.inner.memory_bytes()
    }
    fn build_seconds(&self) -> f64 {
        self.inner.build_seconds()
    }
    fn casts_single_rays(&self) -> bool {
        self.inner.casts_single_rays()
    }
    /// The inner caster's (rays traced in a kernel's threads are not counted here).
    fn in_thread(&self) -> Option<&dyn InThread> {
        self.inner.in_thread()
    }
    fn closest_single(&self, ray: &Ray) -> (Hit, u64) {
        let (hit, tests) = self.inner.closest_single(ray);
        self.single(tests, false);
        (hit, tests)
    }
    fn occluded_single(&self, ray: &Ray) -> (bool, u64) {
        let (blocked, tests) = self.inner.occluded_single(ray);
        self.single(tests, true);
        (blocked, tests)
    }
}

/// One worker thread's counts of single-ray calls, on a cache line of its own.
#[derive(Default)]
#[repr(align(64))]
struct SingleRays {
    rays: AtomicU64,
    tests: AtomicU64,
    shadow: AtomicU64,
}

/// A triangle list as the shared leaf tests read it: three corners by id. The casters
/// keep `[Vec3; 3]` per triangle ([`Triangles`]); PDACRT's device keeps nine floats.
pub trait TriangleCorners {
    /// The corners of triangle `id`.
    fn corners(&self, id: u32) -> [Vec3; 3];
}

impl TriangleCorners for [[Vec3; 3]] {
    #[inline]
    fn corners(&self, id: u32) -> [Vec3; 3] {
        self[id as usize]
    }
}

impl TriangleCorners for Triangles {
    #[inline]
    fn corners(&self, id: u32) -> [Vec3; 3] {
        self[id as usize]
    }
}

impl TriangleCorners for [[f32; 9]] {
    #[inline]
    fn corners(&self, id: u32) -> [Vec3; 3] {
        super::flat::corners(self[id as usize])
    }
}

/// Tests one ray against a list of triangle ids, shrinking `best` to the closest hit
/// (of equal distances the first listed: the smaller id when ids ascend). Shared by
/// every caster's brute-force stage (brute force itself, the outliers of obvhs, BVH4's
/// builder and Embree, PDACRT's tiny batches) so all of them decide hits identically.
#[inline]
pub fn intersect_ids<T: TriangleCorners + ?Sized>(
    tris: &T,
    ids: impl IntoIterator<Item = u32>,
    ray: &Ray,
    shear: &RayShear,
    best: &mut Hit,
) {
    for id in ids {
        let [a, b, c] = tris.corners(id);
        if let Some((t, u, v)) = intersect_triangle(ray.origin, shear, a, b, c, ray.t_min, best.t.min(ray.t_max)) {
            *best = Hit { t, prim: id, u, v };
        }
    }
}

/// Whether any of the listed triangles lies on the ray within its interval, and how
/// many were tested before the answer was known.
#[inline]
pub fn any_hit_ids<T: TriangleCorners + ?Sized>(
    tris: &T,
    ids: impl IntoIterator<Item = u32>,
    ray: &Ray,
    shear: &RayShear,
) -> (bool, u64) {
    let mut tests = 0;
    for id in ids {
        tests += 1;
        let [a, b, c] = tris.corners(id);
        if intersect_triangle(ray.origin, shear, a, b, c, ray.t_min, ray.t_max).is_some() {
            return (true, tests);
        }
    }
    (false, tests)
}

/// A call's [`RayCaster::phase_seconds`] as a JSON object of milliseconds by stage,
/// `{"filter":1.234,...}` (`{}` for a caster that times none), as the benchmarks'
/// `--json` rows carry them.
pub fn phases_json(phases: &[(&str, f64)]) -> String {
    let items: Vec<String> = phases.iter().map(|(k, s)| format!("\"{k}\":{:.3}", s * 1e3)).collect();
    format!("{{{}}}", items.join(","))
}

#[cfg(test)]
mod phases_tests {
    use super::phases_json;

    /// Seconds in, milliseconds out, in order, as JSON that parses.
    #[test]
    fn phases_are_written_as_milliseconds_by_stage() {
        let json = phases_json(&[("filter", 0.001_25), ("groups", 2.5)]);
        let v: serde_json::Value = serde_json::from_str(&json).expect("valid JSON");
        assert_eq!(v["filter"].as_f64(), Some(1.25), "{json}");
        assert_eq!(v["groups"].as_f64(), Some(2500.0), "{json}");
        assert!(json.find("filter") < json.find("groups"), "{json}");
        assert_eq!(phases_json(&[]), "{}");
    }
}
