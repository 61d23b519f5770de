//! The inspector's worker: one render request (`Job`) run on its own thread, with the
//! PDACRT and CIS analyses and the cached reference the panels show.

use super::shared::{Series, Shared, lock};
use crate::cast::pdacrt::{Pdacrt, PdacrtParams};
use crate::cast::{Bvh4, CasterKind, RayCaster};
use crate::converge::rmse;
use crate::geometry::Hit;
use crate::render::CisParams;
use crate::render::{Budget, IntegratorKind, RenderOptions, Renderer, Variant};
use crate::scene::{Scene, load_scene};
use glam::Vec3;
use simt::KernelSummary;
use std::path::PathBuf;
use std::sync::Mutex;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Instant;

/// One render request, run on the worker thread.
pub(super) struct Job {
    pub(super) name: String,
    pub(super) path: PathBuf,
    pub(super) integrator: Variant,
    pub(super) caster: CasterKind,
    pub(super) spp: u32,
    pub(super) size: u32,
    /// Measure the render's kernels as a GPU would (SIMD efficiency, sectors): the
    /// CIS integrator's per-bounce figures, at several times the render's time.
    pub(super) measure: bool,
}

/// The GPU the inspector's measured kernels are predicted on (the Kernels panel's
/// "GPU ms" column): the shipped H200 profile.
pub(super) fn inspector_gpu_profile() -> Option<simt::GpuProfile> {
    simt::GpuProfile::named("h200").ok()
}

/// The steps before the first pass, in order (the status line names them, the image
/// panel shows their progress).
const PREPARING_STEPS: u32 = 4;

/// Says what the worker prepares: step `step` of [`PREPARING_STEPS`], with the step's
/// own progress from 0 to 1.
fn preparing(shared: &Mutex<Shared>, step: u32, what: &str, fraction: f32) {
    let mut s = lock(shared);
    s.status = format!("preparing (step {step} of {PREPARING_STEPS}): {what}");
    s.progress = Some(fraction.clamp(0.0, 1.0));
}

impl Job {
    pub(super) fn run(&self, shared: &Mutex<Shared>, stop: &AtomicBool) -> crate::error::Result<()> {
        let set_status = |msg: String| lock(shared).status = msg;
        preparing(shared, 1, &format!("loading {}", self.name), 0.0);
        let desc = load_scene(&self.path)?;
        let scene = desc.scene;
        scene.check_renderable()?;
        let (w, h) = (self.size, self.size);
        self.analyse(&scene, shared)?;
        let reference = self.reference(&scene, &desc.settings, shared, stop)?;
        let caster = self.caster.build(&scene)?;
        // The scene file's depth and filter, as `warpray render` uses them.
        let mut opts = self.integrator.apply(RenderOptions::for_scene(
            &desc.settings,
            RenderOptions { width: w, height: h, budget: Budget::Samples(self.spp), ..Default::default() },
        ));
        // The command line's options: measuring only when asked (it slows the render).
        opts.cis.measure = self.measure;
        let mut renderer = Renderer::new(&scene, caster.as_ref(), &opts)?;
        // A measured render's kernels, if it launches any, are also predicted on the GPU.
        if let Some(dev) = renderer.device().filter(|_| self.measure) {
            dev.set_measure(true);
            dev.set_gpu_profile(inspector_gpu_profile());
        }
        let mut film = renderer.film()?;
        {
            let mut s = lock(shared);
            let label = format!(
                "{} / {}: {}, {}x{}, max depth {}{}",
                self.integrator.label,
                caster.name(),
                self.name,
                w,
                h,
                opts.max_depth,
                if self.measure { ", measured" } else { "" }
            );
            s.series.push(Series { label, points: Vec::new() });
            s.progress = None;
            s.status = format!("rendering {} with {}: 0/{} spp", self.name, self.integrator.label, self.spp);
            s.passes = 0;
            s.width = w;
            s.height = h;
            s.kernels.clear();
            s.queues.clear();
            s.material_names = scene.material_names.clone();
        }
        let start = Instant::now();
        let mut render_time = 0.0;
        let mut done = 0;
        while done < self.spp {
            if stop.load(Ordering::Relaxed) {
                set_status("stopped".into());
                return Ok(());
            }
            // Passes in the command line's groups (several passes share the caster's
            // batches for the wavefront integrators on small images); only the render
            // is timed, not what the panels are given between groups.
            let group = renderer.pass_group().min(self.spp - done);
            let t0 = Instant::now();
            renderer.passes(done, group, &mut film);
            render_time += t0.elapsed().as_secs_f64();
            done += group;
            let mean = film.mean();
            let err = reference.as_ref().map(|r| rmse(&mean, r));
            let mut s = lock(shared);
            s.image = mean;
            s.passes = film.passes;
            s.status =
                format!("rendering {} with {}: {}/{} spp", self.name, self.integrator.label, film.passes, self.spp);
            if let (Some(e), Some(series)) = (err, s.series.last_mut()) {
                series.points.push((render_time, e));
            }
            if let Some(cis) = renderer.cis_mut() {
                // The last pass's records; the integrator's list is emptied so that it
                // does not grow with the render.
                let last = done - 1;
                s.queues = cis.records.drain(..).filter(|r| r.pass == last).collect();
            }
            if let Some(dev) = renderer.device() {
                // The render's own device: the caster's kernels and the integrator's.
                s.kernels = dev.kernel_stats();
            }
        }
        set_status(format!("done in {:.3} s", start.elapsed().as_secs_f64()));
        Ok(())
    }

    /// PDACRT on the primary rays (levels, work heat map, kernel statistics), and one
    /// CIS pass sorted and unsorted (what sorting does to the shading kernel).
    fn analyse(&self, scene: &Scene, shared: &Mutex<Shared>) -> crate::error::Result<()> {
        preparing(shared, 2, "analysing PDACRT on the primary rays (measured)", 0.0);
        let (w, h) = (self.size, self.size);
        let rays = crate::cast::batches::primary_rays(&scene.camera, w, h);
        let pd = Pdacrt::from_triangles(
            &scene.triangle_vertices(),
            PdacrtParams { measure: true, inspect: true, ..PdacrtParams::default() },
        );
        pd.device().set_gpu_profile(inspector_gpu_profile());
        let mut hits = vec![Hit::MISS; rays.len()];
        pd.closest(&rays, &mut hits);
        let mut kernels = pd.device().kernel_stats();
        let mut effect = None;
        if scene.camera.aperture_radius == 0.0 {
            preparing(shared, 3, "analysing one CIS-LBDPT pass, unsorted and sorted (measured)", 0.0);
            let bvh = Bvh4::new(scene);
            let mut eff = [0.0; 2];
            for (k, sort) in [false, true].into_iter().enumerate() {
                lock(shared).progress = Some(k as f32 / 2.0);
                let o = RenderOptions {
                    width: 32,
                    height: 32,
                    integrator: IntegratorKind::Cis,
                    cis: CisParams { sort, measure: true, pool: 1024, ..CisParams::default() },
                    gpu_profile: inspector_gpu_profile(),
                    ..Default::default()
                };
                let mut renderer = Renderer::new(scene, &bvh, &o)?;
                let mut f = renderer.film()?;
                renderer.pass(0, &mut f);
                let st = renderer.device().map(|d| d.kernel_stats()).unwrap_or_default();
                // Measured over everything the lanes executed, not the declared region.
                eff[k] = st.iter().find(|x| x.name == "cis::shade").and_then(|x| x.simd_efficiency()).unwrap_or(0.0);
                if sort {
                    merge_kernels(&mut kernels, st);
                }
            }
            effect = Some((eff[0], eff[1]));
        }
        let mut s = lock(shared);
        s.levels = pd.levels();
        s.visits = pd.visits();
        s.camera = Some(scene.camera);
        s.analysis_kernels = kernels;
        s.sorting_effect = effect;
        Ok(())
    }

    /// A path-traced reference for the convergence panel (cached per scene and size).
    fn reference(
        &self,
        scene: &Scene,
        settings: &crate::scene::RenderSettings,
        shared: &Mutex<Shared>,
        stop: &AtomicBool,
    ) -> crate::error::Result<Option<Vec<Vec3>>> {
        if let Some(r) = lock(shared).references.iter().find(|r| r.0 == self.name && r.1 == self.size) {
            return Ok(Some(r.2.clone()));
        }
        let what = |pass: u32| format!("rendering the reference (path tracing): {pass}/{REFERENCE_SPP} spp");
        preparing(shared, 4, &what(0), 0.0);
        let bvh = Bvh4::new(scene);
        let o = RenderOptions::for_scene(
            settings,
            RenderOptions {
                width: self.size,
                height: self.size,
                budget: Budget::Samples(REFERENCE_SPP),
                seed: REFERENCE_SEED,
                ..Default::default()
            },
        );
        let (film, _) = crate::render::render(scene, &bvh, &o, |pass, _| {
            preparing(shared, 4, &what(pass), pass as f32 / REFERENCE_SPP as f32);
            !stop.load(Ordering::Relaxed)
        })?;
        if stop.load(Ordering::Relaxed) {
            return Ok(None);
        }
        let mean = film.mean();
        lock(shared).references.push((self.name.clone(), self.size, mean.clone()));
        Ok(Some(mean))
    }
}

/// Samples per pixel and seed of the convergence panel's path-traced reference.
pub(super) const REFERENCE_SPP: u32 = 256;
pub(super) const REFERENCE_SEED: u64 = 77;

/// Replaces the summaries of the kernels in `new` (by name) and keeps the others.
fn merge_kernels(all: &mut Vec<KernelSummary>, new: Vec<KernelSummary>) {
    for k in new {
        match all.iter_mut().find(|x| x.name == k.name) {
            Some(x) => *x = k,
            None => all.push(k),
        }
    }
}
