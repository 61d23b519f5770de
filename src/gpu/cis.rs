//! CIS-LBDPT's shading kernel and compaction on the GPU: `cuda/cis.cu`, the twins of
//! `cis::shade` (sorted and unsorted) and of `cis::alive_flags` with its selection. They
//! run on the inputs a CPU render captured ([`ShadeCapture`]), and what they write is
//! compared with what the emulator wrote (`docs/gpu-check.md`).

use super::ffi::{CisFns, Library, library_path};
use super::scene::{SceneTables, WrCisScene};
use crate::cast::RayCaster;
use crate::error::{Error, Result};
use crate::render::bidir::Vertex;
use crate::render::cache::Connections;
use crate::render::cis::ShadeCapture;
use crate::render::cis::kernels::{MAX_CAMERA_VERTICES, PENDING_PER_SLOT, PendingData, Slot};
use crate::render::{Budget, RenderOptions, Renderer};
use crate::scene::Scene;
use glam::Vec3;
use std::ffi::c_void;
use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex};

/// What the GPU's shading launch wrote, against what the emulator's wrote.
#[derive(Clone, Debug, Default)]
pub struct ShadeCheck {
    /// Samples shaded.
    pub lanes: usize,
    /// Samples whose slot, new vertex or pending contributions differ beyond rounding
    /// (1e-3 relative): a different random choice, or a porting error.
    pub differ: usize,
    /// Of those, the samples whose random stream advanced differently (a different
    /// branch taken).
    pub diverged: usize,
    /// The first difference, described.
    pub first: Option<String>,
    /// GPU time of the launch, milliseconds (CUDA events).
    pub gpu_ms: f64,
}

/// One bounce of a CIS-LBDPT render run again on the twins ([`check_render`]).
#[derive(Clone, Debug)]
pub struct BounceCheck {
    /// The pass and the bounce within it.
    pub pass: u32,
    /// The wavefront iteration within the pass.
    pub bounce: u32,
    /// The shading launch against the emulator's.
    pub shade: ShadeCheck,
    /// Samples the emulator's compaction kept, of those active.
    pub kept: usize,
    /// Samples active in the bounce.
    pub active: usize,
    /// Whether the twin's compacted list equals the emulator's.
    pub compaction_same: bool,
    /// GPU time of the compaction, milliseconds.
    pub compaction_ms: f64,
}

/// Renders `scene` with CIS-LBDPT as `opts` says (`opts.integrator` must be `cis`, the
/// budget a sample count) and runs every bounce's shading and compaction again on the
/// twins of the library at `library`, on the inputs the render captured: one check per
/// bounce, in order. The GPU-check program and the twin tests both use it.
pub fn check_render(
    library: &Path,
    scene: &Scene,
    caster: &dyn RayCaster,
    opts: &RenderOptions,
) -> Result<Vec<BounceCheck>> {
    let Budget::Samples(passes) = opts.budget else {
        return Err(Error::BadSetting("the CIS twin check renders a number of samples, not a time".into()));
    };
    let mut r = Renderer::new(scene, caster, opts)?;
    let cis = r.cis_mut().ok_or_else(|| Error::BadSetting("the CIS twin check needs the cis integrator".into()))?;
    let out: Arc<Mutex<Result<Vec<BounceCheck>>>> = Arc::new(Mutex::new(Ok(Vec::new())));
    let (lib, s, o, sink) = (library.to_path_buf(), scene.clone(), opts.clone(), out.clone());
    let mut gpu: Option<(u32, GpuCis)> = None;
    cis.observe(Box::new(move |cap| {
        let mut out = sink.lock().unwrap_or_else(|e| e.into_inner());
        let Ok(checks) = out.as_mut() else { return };
        let check = (|| {
            if gpu.as_ref().is_none_or(|(pass, _)| *pass != cap.pass) {
                gpu = Some((cap.pass, GpuCis::with_library(&lib, &s, &o, cap)?));
            }
            let g = gpu.as_ref().map(|(_, g)| g).expect("made above");
            let shade = g.shade(cap)?;
            let (compaction_same, compaction_ms) = g.compact(cap)?;
            let (pass, bounce, kept, active) = (cap.pass, cap.bounce, cap.kept(), cap.active_samples());
            Ok(BounceCheck { pass, bounce, shade, kept, active, compaction_same, compaction_ms })
        })();
        match check {
            Ok(c) => checks.push(c),
            Err(e) => *out = Err(e),
        }
    }));
    let mut film = r.film()?;
    r.passes(0, passes, &mut film);
    drop(r);
    let mut out = out.lock().unwrap_or_else(|e| e.into_inner());
    std::mem::replace(&mut *out, Ok(Vec::new()))
}

/// CIS-LBDPT's twins on the GPU for one scene and one pass's light vertex cache.
pub struct GpuCis {
    handle: *mut c_void,
    lib: Library,
}

// SAFETY: the handle is used by one `&self` call at a time of its owner (the calls take
// no lock inside the library and it keeps no thread state besides its error string),
// and the CUDA runtime allows a context to be used from any host thread.
unsafe impl Send for GpuCis {}

impl Drop for GpuCis {
    fn drop(&mut self) {
        // SAFETY: `handle` came from `wr_cis_create` and is dropped once, before `lib`.
        unsafe { (self.lib.cis.destroy)(self.handle) }
    }
}

impl GpuCis {
    /// Uploads `scene`, its lights, the camera and options of `opts`, and the light vertex
    /// cache of `cap`'s pass, to the GPU of the library at [`crate::gpu::library_path`].
    pub fn new(scene: &Scene, opts: &RenderOptions, cap: &ShadeCapture) -> Result<GpuCis> {
        Self::with_library(library_path(), scene, opts, cap)
    }

    /// As [`GpuCis::new`], with the library at `path`.
    pub fn with_library(
        path: impl Into<PathBuf>,
        scene: &Scene,
        opts: &RenderOptions,
        cap: &ShadeCapture,
    ) -> Result<GpuCis> {
        if opts.strategy.is_some() {
            return Err(Error::BadSetting(
                "the GPU shading twin renders every strategy; strategy images are not ported".into(),
            ));
        }
        let lib = Library::open(path.into())?;
        let tables = SceneTables::new(scene, "the GPU shading twin")?;
        let connections = match cap.connections {
            Connections::Resampled { candidates, draws } => (1, candidates, draws),
            Connections::Uniform { n } => (0, 0, n),
        };
        let s = WrCisScene {
            cache_vertices: cap.cache_vertices.as_ptr().cast(),
            n_cache_vertices: cap.cache_vertices.len() as u64,
            cache_entries: cap.cache_entries.as_ptr().cast(),
            n_entries: cap.cache_entries.len() as u64,
            count_splat: cap.counts.splat,
            count_connection: cap.counts.connection,
            ..tables.record(scene, opts, connections)
        };
        let mut handle = std::ptr::null_mut();
        // SAFETY: every pointer in `s` points into a vector alive for the call, with the
        // counts given; the library copies what it keeps.
        if unsafe { (lib.cis.create)((&s as *const WrCisScene).cast(), &mut handle) } != 0 {
            return Err(lib.error_from(lib.cis.last_error, "uploading the scene for CIS"));
        }
        Ok(GpuCis { handle, lib })
    }

    fn fns(&self) -> &CisFns {
        &self.lib.cis
    }

    /// Runs the GPU's `cis::shade` on `cap`'s inputs and compares what it writes with
    /// what the emulator wrote.
    pub fn shade(&self, cap: &ShadeCapture) -> Result<ShadeCheck> {
        let (mut slots, mut vertices) = (cap.slots_before.to_vec(), cap.vertices_before.to_vec());
        let pool = slots.len();
        assert_eq!(vertices.len(), pool * MAX_CAMERA_VERTICES);
        let mut pending = vec![PendingData::default(); pool * PENDING_PER_SLOT];
        let mut ms = 0.0;
        let n = cap.order.len();
        // SAFETY: the arrays have the lengths the header asks for (n, n, n; pool slots,
        // pool × MAX_CAMERA_VERTICES vertices, pool × PENDING_PER_SLOT pending) and the
        // layouts asserted above.
        let rc = unsafe {
            (self.fns().shade)(
                self.handle,
                cap.sorted as i32,
                n as u64,
                cap.order.as_ptr(),
                cap.active.as_ptr(),
                cap.hits.as_ptr().cast(),
                pool as u64,
                slots.as_mut_ptr().cast(),
                vertices.as_mut_ptr().cast(),
                pending.as_mut_ptr().cast(),
                &mut ms,
            )
        };
        if rc != 0 {
            return Err(self.lib.error_from(self.fns().last_error, "cis::shade"));
        }
        let mut check = ShadeCheck { lanes: n, gpu_ms: ms, ..Default::default() };
        for j in 0..n {
            let slot = cap.active[cap.order[j] as usize] as usize;
            let depth = cap.slots_before[slot].depth as usize;
            let v = slot * MAX_CAMERA_VERTICES + depth.min(MAX_CAMERA_VERTICES - 1);
            let p = slot * PENDING_PER_SLOT..(slot + 1) * PENDING_PER_SLOT;
            let diff = slot_diff(&slots[slot], &cap.slots[slot])
                .or_else(|| vertex_diff(&vertices[v], &cap.vertices[v]))
                .or_else(|| pending[p.clone()].iter().zip(&cap.pending[p]).find_map(|(a, b)| pending_diff(a, b)));
            if let Some(d) = diff {
                check.differ += 1;
                check.diverged += (slots[slot].rng.counter() != cap.slots[slot].rng.counter()) as usize;
                check.first.get_or_insert_with(|| format!("sample at sorted position {j} (slot {slot}): {d}"));
            }
        }
        Ok(check)
    }

    /// Runs the GPU's compaction (`cis::alive_flags` and CUB's flagged selection) on
    /// `cap`'s pool; returns whether its list equals the emulator's, and the GPU time.
    pub fn compact(&self, cap: &ShadeCapture) -> Result<(bool, f64)> {
        let n = cap.active.len();
        let mut kept = vec![0u32; n];
        let (mut m, mut ms) = (0u64, 0.0);
        // SAFETY: `active` has n entries, `slots` the pool's, `kept` room for n.
        let rc = unsafe {
            (self.fns().compact)(
                self.handle,
                n as u64,
                cap.active.as_ptr(),
                cap.slots_compacted.len() as u64,
                cap.slots_compacted.as_ptr().cast(),
                kept.as_mut_ptr(),
                &mut m,
                &mut ms,
            )
        };
        if rc != 0 {
            return Err(self.lib.error_from(self.fns().last_error, "cis::alive_flags"));
        }
        kept.truncate(m as usize);
        Ok((kept == cap.kept, ms))
    }
}

fn close(a: f32, b: f32) -> bool {
    a == b || (a - b).abs() <= 1e-3 * a.abs().max(b.abs()).max(1e-6) || (a.is_nan() && b.is_nan())
}

fn close3(a: Vec3, b: Vec3) -> bool {
    close(a.x, b.x) && close(a.y, b.y) && close(a.z, b.z)
}

fn slot_diff(gpu: &Slot, cpu: &Slot) -> Option<String> {
    let same = gpu.alive == cpu.alive
        && gpu.depth == cpu.depth
        && gpu.rng.counter() == cpu.rng.counter()
        && close3(gpu.beta, cpu.beta)
        && (cpu.alive == 0 || (close3(gpu.ray.origin, cpu.ray.origin) && close3(gpu.ray.dir, cpu.ray.dir)));
    (!same).then(|| format!("slot: GPU {gpu:?}, emulator {cpu:?}"))
}

fn vertex_diff(gpu: &Vertex, cpu: &Vertex) -> Option<String> {
    let same = gpu.kind == cpu.kind && gpu.delta == cpu.delta && close3(gpu.p, cpu.p) && close3(gpu.n, cpu.n);
    (!same).then(|| format!("new vertex: GPU {gpu:?}, emulator {cpu:?}"))
}

fn pending_diff(gpu: &PendingData, cpu: &PendingData) -> Option<String> {
    let same = gpu.state == cpu.state
        && close3(gpu.value, cpu.value)
        && (cpu.state != 1 || (close3(gpu.ray.origin, cpu.ray.origin) && close3(gpu.ray.dir, cpu.ray.dir)));
    (!same).then(|| format!("pending: GPU {gpu:?}, emulator {cpu:?}"))
}
