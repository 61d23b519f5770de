//! The egui inspector: the converging image (zoom, pan, exposure, a heat map of PDACRT
//! work per pixel), PDACRT's recursion levels (with a level's node boxes drawn over the
//! image), CIS-LBDPT's material queues, the `simt` kernel statistics, and error against
//! time for every render since the inspector started.
//!
//! Rendering runs on a worker thread; the UI only reads what the worker shares, so it
//! stays responsive. `cargo run --release --features inspector --bin warpray-inspector`.

use crate::cast::CasterKind;
use crate::geometry::Aabb;
use crate::render::{IntegratorKind, Variant};
use egui::{TextureHandle, Ui};
use glam::{Vec2, Vec3};
use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::thread::JoinHandle;

mod job;
mod panels;
mod shared;
use job::Job;
use shared::lock;
pub use shared::{Series, Shared};

/// The inspector's panels.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Panel {
    /// The converging image (or the PDACRT heat map).
    Image,
    /// PDACRT's recursion levels on the primary rays.
    Levels,
    /// CIS-LBDPT's material queues per wavefront iteration.
    Queues,
    /// The `simt` kernel tables.
    Kernels,
    /// Error against time of every render.
    Convergence,
}

impl Panel {
    /// Every panel, in tab order.
    pub const ALL: [Panel; 5] = [Panel::Image, Panel::Levels, Panel::Queues, Panel::Kernels, Panel::Convergence];
    /// The tab's label.
    pub fn label(self) -> &'static str {
        match self {
            Panel::Image => "Image",
            Panel::Levels => "Recursion levels",
            Panel::Queues => "Queues",
            Panel::Kernels => "Kernels",
            Panel::Convergence => "Convergence",
        }
    }
}

/// The inspector's state: the choices in its controls and what the worker shares.
pub struct Inspector {
    /// (label, what `load_scene` is given) of every scene in the list.
    pub scenes: Vec<(String, PathBuf)>,
    /// The selected scene.
    pub scene: usize,
    /// The selected integrator (a variant of the registry that the command line uses).
    pub integrator: Variant,
    /// The selected caster.
    pub caster: CasterKind,
    /// Samples per pixel of a render.
    pub spp: u32,
    /// Image width and height.
    pub size: u32,
    /// Whether the render itself is measured as a GPU would run it (per-bounce SIMD
    /// efficiency of CIS-LBDPT's shading; several times slower). Off: the render runs
    /// as `warpray render` runs it, at its speed.
    pub measure: bool,
    /// The open panel.
    pub panel: Panel,
    /// Exposure of the image panel.
    pub exposure: f32,
    /// Zoom of the image panel.
    pub zoom: f32,
    /// Whether the image panel shows the PDACRT heat map.
    pub heat_map: bool,
    /// The level whose boxes are drawn over the image.
    pub selected_level: Option<usize>,
    /// Kernel table sort: (column, descending).
    pub kernel_sort: (usize, bool),
    /// Which kernel table the panel shows: the render's (false) or the analysis' (true).
    pub analysis_table: bool,
    /// What the worker shares.
    pub shared: Arc<Mutex<Shared>>,
    stop: Arc<AtomicBool>,
    worker: Option<JoinHandle<()>>,
    texture: Option<(TextureHandle, u32, bool, u32)>,
}

impl Default for Inspector {
    fn default() -> Self {
        Self::new()
    }
}

impl Inspector {
    /// The built-in Cornell box, the built-in scenes of the shared models
    /// ([`crate::scene::NAMED_SCENES`], whose models come from `$WARPRAY_MODELS`), and the
    /// other scene files of this source tree's `assets/scenes/` when it is there. None
    /// of it depends on the working directory.
    pub fn new() -> Self {
        let mut scenes = vec![("cornell (built-in)".to_string(), PathBuf::from("cornell"))];
        for (name, _) in crate::scene::NAMED_SCENES {
            scenes.push((format!("{name} (built-in, model from WARPRAY_MODELS)"), PathBuf::from(name)));
        }
        let assets = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("assets/scenes");
        if let Ok(dir) = std::fs::read_dir(&assets) {
            let mut files: Vec<PathBuf> = dir
                .filter_map(|e| e.ok().map(|e| e.path()))
                .filter(|p| p.extension().is_some_and(|e| e == "toml" || e == "xml"))
                .filter(|p| {
                    let stem = p.file_stem().and_then(|s| s.to_str()).unwrap_or("");
                    !crate::scene::NAMED_SCENES.iter().any(|(n, _)| *n == stem)
                })
                .collect();
            files.sort();
            scenes.extend(
                files
                    .into_iter()
                    .map(|p| (format!("{} (assets/scenes)", p.file_name().unwrap_or_default().to_string_lossy()), p)),
            );
        }
        Inspector {
            scenes,
            scene: 0,
            integrator: Variant::of(IntegratorKind::Path),
            caster: CasterKind::Bvh4,
            spp: 64,
            size: 128,
            measure: false,
            panel: Panel::Image,
            exposure: 1.0,
            zoom: 3.0,
            heat_map: false,
            selected_level: None,
            kernel_sort: (2, true),
            analysis_table: false,
            shared: Arc::new(Mutex::new(Shared::default())),
            stop: Arc::new(AtomicBool::new(false)),
            worker: None,
            texture: None,
        }
    }

    /// Adds a scene (a file, or a name as `load_scene` resolves it) and selects it.
    /// A scene already listed (the same name, or the same file by its canonical path)
    /// is selected, not listed twice.
    pub fn add_scene(&mut self, path: PathBuf) {
        let canonical = |p: &PathBuf| std::fs::canonicalize(p).ok();
        let known = self
            .scenes
            .iter()
            .position(|(_, p)| *p == path || (canonical(p).is_some() && canonical(p) == canonical(&path)));
        self.scene = match known {
            Some(i) => i,
            None => {
                self.scenes.push((path.display().to_string(), path));
                self.scenes.len() - 1
            }
        };
    }

    /// Whether the worker is busy.
    pub fn running(&self) -> bool {
        lock(&self.shared).running
    }

    /// Starts rendering the chosen scene on a worker thread.
    pub fn start(&mut self) {
        if self.running() {
            return;
        }
        if let Some(w) = self.worker.take() {
            let _ = w.join();
        }
        self.stop.store(false, Ordering::Relaxed);
        let (name, path) = self.scenes[self.scene].clone();
        let job = Job {
            name,
            path,
            integrator: self.integrator,
            caster: self.caster,
            spp: self.spp.max(1),
            size: self.size,
            measure: self.measure,
        };
        let (shared, stop) = (self.shared.clone(), self.stop.clone());
        {
            let mut s = lock(&shared);
            s.running = true;
            s.progress = Some(0.0);
            s.status = "preparing".into();
        }
        self.selected_level = None;
        self.worker = Some(std::thread::spawn(move || {
            let result = job.run(&shared, &stop);
            let mut s = lock(&shared);
            s.running = false;
            s.progress = None;
            if let Err(e) = result {
                s.status = format!("error: {e}");
            }
        }));
    }

    /// Asks the worker to stop after the pass it is in.
    pub fn stop(&mut self) {
        self.stop.store(true, Ordering::Relaxed);
    }

    /// The whole UI, for eframe and for the headless tests.
    pub fn ui(&mut self, ui: &mut Ui) {
        let running = self.running();
        if running {
            ui.ctx().request_repaint_after(std::time::Duration::from_millis(100));
        }
        egui::Panel::top("controls").show(ui, |ui| self.controls(ui, running));
        egui::CentralPanel::default().show(ui, |ui| {
            ui.horizontal(|ui| {
                for p in Panel::ALL {
                    ui.selectable_value(&mut self.panel, p, p.label());
                }
            });
            ui.separator();
            match self.panel {
                Panel::Image => self.image_panel(ui),
                Panel::Levels => self.levels_panel(ui),
                Panel::Queues => self.queues_panel(ui),
                Panel::Kernels => self.kernels_panel(ui),
                Panel::Convergence => self.convergence_panel(ui),
            }
        });
    }

    fn controls(&mut self, ui: &mut Ui, running: bool) {
        ui.horizontal_wrapped(|ui| {
            // Every control is labelled (accessibility, and the headless tests find them so).
            let label = ui.label("Scene");
            let scene_name = self.scenes[self.scene].0.clone();
            egui::ComboBox::from_id_salt("scene")
                .selected_text(scene_name)
                .show_ui(ui, |ui| {
                    for (i, (name, _)) in self.scenes.iter().enumerate() {
                        ui.selectable_value(&mut self.scene, i, name);
                    }
                })
                .response
                .labelled_by(label.id);
            let label = ui.label("Integrator");
            egui::ComboBox::from_id_salt("integrator")
                .selected_text(self.integrator.label)
                .show_ui(ui, |ui| {
                    for v in Variant::all() {
                        ui.selectable_value(&mut self.integrator, v, v.label).on_hover_text(v.summary);
                    }
                })
                .response
                .labelled_by(label.id);
            let label = ui.label("Caster");
            egui::ComboBox::from_id_salt("caster")
                .selected_text(format!("{:?}", self.caster).to_lowercase())
                .show_ui(ui, |ui| {
                    for &k in CasterKind::all() {
                        ui.selectable_value(&mut self.caster, k, format!("{k:?}").to_lowercase());
                    }
                })
                .response
                .labelled_by(label.id);
            let label = ui.label("spp");
            ui.add(egui::DragValue::new(&mut self.spp).range(1..=100_000)).labelled_by(label.id);
            let label = ui.label("size");
            ui.add(egui::DragValue::new(&mut self.size).range(16..=1024)).labelled_by(label.id);
            ui.add_enabled(!running, egui::Checkbox::new(&mut self.measure, "measure the render"))
                .on_hover_text("Count what a GPU would (SIMD efficiency per CIS bounce); slower than the command line");
            if ui.add_enabled(!running, egui::Button::new("Start")).clicked() {
                self.start();
            }
            if ui.add_enabled(running, egui::Button::new("Stop")).clicked() {
                self.stop();
            }
            let s = lock(&self.shared);
            ui.label(format!("{} spp | {}", s.passes, s.status));
        });
    }
}

/// The 2D pixel bounding rectangle of a box seen by a pinhole camera (corners behind the
/// camera make it `None`).
pub fn project_box(cam: &crate::scene::Camera, b: &Aabb, width: u32, height: u32) -> Option<(Vec2, Vec2)> {
    let crate::scene::Projection { tan_half, aspect, .. } = cam.projection(width, height);
    let (mut lo, mut hi) = (Vec2::splat(f32::MAX), Vec2::splat(f32::MIN));
    for i in 0..8 {
        let c = Vec3::new(
            if i & 1 == 0 { b.min.x } else { b.max.x },
            if i & 2 == 0 { b.min.y } else { b.max.y },
            if i & 4 == 0 { b.min.z } else { b.max.z },
        );
        let d = c - cam.position;
        let z = d.dot(cam.forward);
        if z <= 1e-4 {
            return None;
        }
        let sx = d.dot(cam.right) / (z * tan_half * aspect);
        let sy = d.dot(cam.up) / (z * tan_half);
        let p = Vec2::new((sx + 1.0) * 0.5 * width as f32, (1.0 - sy) * 0.5 * height as f32);
        lo = lo.min(p);
        hi = hi.max(p);
    }
    Some((lo, hi))
}
