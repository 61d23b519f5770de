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
}

impl Job {
    pub(super) fn run(&self, shared: &Mutex<Shared>, stop: &AtomicBool) -> crate::error::Result<()> {
        let set_status = |msg: String| lock(shared).status = msg;
        set_status(format!("loading {}", self.name));
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
        // Measured, with a pool that fills the inspector's small images.
        opts.cis = CisParams { measure: true, pool: 4096, ..opts.cis };
        let mut renderer = Renderer::new(&scene, caster.as_ref(), &opts)?;
        let mut film = renderer.film()?;
        {
            let mut s = lock(shared);
            s.series
                .push(Series { label: format!("{} / {}", self.integrator.label, caster.name()), points: Vec::new() });
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
        for pass in 0..self.spp {
            if stop.load(Ordering::Relaxed) {
                set_status("stopped".into());
                return Ok(());
            }
            let t0 = Instant::now();
            renderer.pass(pass, &mut film);
            render_time += t0.elapsed().as_secs_f64();
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
            if let Some(cis) = renderer.cis() {
                s.queues = cis.records.clone();
            }
            if let Some(dev) = renderer.device() {
                // The render's own device: the caster's kernels and the integrator's.
                s.kernels = dev.kernel_stats();
            }
        }
        set_status(format!("done in {:.2} s", start.elapsed().as_secs_f64()));
        Ok(())
    }

    /// PDACRT on the primary rays (levels, work heat map, kernel statistics), and one
    /// CIS pass sorted and unsorted (what sorting does to the shading kernel).
    fn analyse(&self, scene: &Scene, shared: &Mutex<Shared>) -> crate::error::Result<()> {
        lock(shared).status = "analysing (1 of 2): PDACRT on the primary rays".into();
        let (w, h) = (self.size, self.size);
        let rays = crate::cast::batches::primary_rays(&scene.camera, w, h);
        let pd = Pdacrt::from_triangles(
            &scene.triangle_vertices(),
            PdacrtParams { measure: true, inspect: true, ..PdacrtParams::default() },
        );
        let mut hits = vec![Hit::MISS; rays.len()];
        pd.closest(&rays, &mut hits);
        let mut kernels = pd.device().kernel_stats();
        let mut effect = None;
        if scene.camera.aperture_radius == 0.0 {
            lock(shared).status = "analysing (2 of 2): one CIS-LBDPT pass unsorted and sorted".into();
            let bvh = Bvh4::new(scene);
            let mut eff = [0.0; 2];
            for (k, sort) in [false, true].into_iter().enumerate() {
                let o = RenderOptions {
                    width: 32,
                    height: 32,
                    integrator: IntegratorKind::Cis,
                    cis: CisParams { sort, measure: true, pool: 1024, ..CisParams::default() },
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
        lock(shared).status = "rendering the reference (path tracing): 0/256 spp".into();
        let bvh = Bvh4::new(scene);
        let o = RenderOptions::for_scene(
            settings,
            RenderOptions {
                width: self.size,
                height: self.size,
                budget: Budget::Samples(256),
                seed: 77,
                ..Default::default()
            },
        );
        let (film, _) = crate::render::render(scene, &bvh, &o, |pass, _| {
            lock(shared).status = format!("rendering the reference (path tracing): {pass}/256 spp");
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

/// Replaces the summaries of the kernels in `new` (by name) and keeps the others.
fn merge_kernels(all: &mut Vec<KernelSummary>, new: Vec<KernelSummary>) {
    for k in new {
        match all.iter_mut().find(|x| x.name == k.name) {
            Some(x) => *x = k,
            None => all.push(k),
        }
    }
}
