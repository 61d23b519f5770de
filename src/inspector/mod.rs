//! The egui inspector: the converging image (zoom, pan, exposure, a heat map of PDACRT
//! work per pixel), PDACRT's recursion levels (with a level's node boxes drawn over the
//! image), CIS-LBDPT's material queues, the `simt` kernel statistics, and error against
//! time for every render since the inspector started.
//!
//! Rendering runs on a worker thread; the UI only reads what the worker shares, so it
//! stays responsive. `cargo run --release --features inspector --bin warpray-inspector`.

use crate::cast::pdacrt::{LevelRecord, Pdacrt, PdacrtParams};
use crate::cast::{BvhCaster, CasterKind, RayCaster};
use crate::converge::rmse;
use crate::film::encode_srgb8;
use crate::geometry::{Aabb, Hit};
use crate::render::cis::{CisParams, QueueRecord};
use crate::render::{Budget, IntegratorKind, RenderOptions, Renderer, Variant};
use crate::scene::{Scene, load_scene};
use egui::{Color32, ColorImage, RichText, TextureHandle, TextureOptions, Ui};
use glam::{Vec2, Vec3};
use simt::KernelSummary;
use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::thread::JoinHandle;
use std::time::Instant;

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

/// One render's error curve.
#[derive(Clone, Debug, Default)]
pub struct Series {
    /// `integrator / caster`.
    pub label: String,
    /// (seconds, RMSE against the reference)
    pub points: Vec<(f64, f64)>,
}

/// What the worker shares with the UI.
#[derive(Default)]
pub struct Shared {
    /// The mean image so far.
    pub image: Vec<Vec3>,
    /// Image width.
    pub width: u32,
    /// Image height.
    pub height: u32,
    /// Passes done.
    pub passes: u32,
    /// Whether the worker is busy (analysing, rendering the reference, or rendering).
    pub running: bool,
    /// What the worker is doing, with its progress.
    pub status: String,
    /// Error curves, one per render since the inspector started.
    pub series: Vec<Series>,
    /// PDACRT's levels on the primary rays.
    pub levels: Vec<LevelRecord>,
    /// Per pixel: PDACRT terminal nodes that tested its primary ray.
    pub visits: Vec<u32>,
    /// The scene's camera (to draw level boxes over the image).
    pub camera: Option<crate::scene::Camera>,
    /// CIS-LBDPT queue records of the last pass.
    pub queues: Vec<QueueRecord>,
    /// Material names of the scene, by index (for the queue panel).
    pub material_names: Vec<String>,
    /// `cis::shade` SIMD efficiency of one pass, unsorted and sorted.
    pub sorting_effect: Option<(f64, f64)>,
    /// Kernels of the chosen render's own device (PDACRT casting, CIS-LBDPT); empty
    /// when the render runs nothing on one.
    pub kernels: Vec<KernelSummary>,
    /// Kernels of the analysis before the render (PDACRT on the primary rays, one CIS
    /// pass sorted), kept apart from the render's.
    pub analysis_kernels: Vec<KernelSummary>,
    references: Vec<(String, u32, Vec<Vec3>)>,
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

fn lock(s: &Mutex<Shared>) -> std::sync::MutexGuard<'_, Shared> {
    s.lock().unwrap_or_else(|e| e.into_inner())
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
            caster: CasterKind::Bvh,
            spp: 64,
            size: 128,
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
        let job =
            Job { name, path, integrator: self.integrator, caster: self.caster, spp: self.spp.max(1), size: self.size };
        let (shared, stop) = (self.shared.clone(), self.stop.clone());
        lock(&shared).running = true;
        self.selected_level = None;
        self.worker = Some(std::thread::spawn(move || {
            let result = job.run(&shared, &stop);
            let mut s = lock(&shared);
            s.running = false;
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
                    for k in [CasterKind::Bvh, CasterKind::Dacrt, CasterKind::Pdacrt, CasterKind::Brute] {
                        ui.selectable_value(&mut self.caster, k, format!("{k:?}").to_lowercase());
                    }
                })
                .response
                .labelled_by(label.id);
            let label = ui.label("spp");
            ui.add(egui::DragValue::new(&mut self.spp).range(1..=100_000)).labelled_by(label.id);
            let label = ui.label("size");
            ui.add(egui::DragValue::new(&mut self.size).range(16..=1024)).labelled_by(label.id);
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

    fn refresh_texture(&mut self, ui: &Ui) {
        let s = lock(&self.shared);
        if s.image.is_empty() {
            return;
        }
        let key = (s.passes, self.heat_map, self.exposure.to_bits());
        if self.texture.as_ref().is_some_and(|t| (t.1, t.2, t.3) == key) {
            return;
        }
        let (w, h) = (s.width as usize, s.height as usize);
        let pixels: Vec<Color32> = if self.heat_map && s.visits.len() == w * h {
            let max = s.visits.iter().copied().max().unwrap_or(1).max(1) as f32;
            s.visits.iter().map(|&v| heat(v as f32 / max)).collect()
        } else {
            s.image
                .iter()
                .map(|c| {
                    let c = *c * self.exposure;
                    Color32::from_rgb(encode_srgb8(c.x), encode_srgb8(c.y), encode_srgb8(c.z))
                })
                .collect()
        };
        drop(s);
        let image = ColorImage::new([w, h], pixels);
        let tex = ui.ctx().load_texture("render", image, TextureOptions::NEAREST);
        self.texture = Some((tex, key.0, key.1, key.2));
    }

    fn image_panel(&mut self, ui: &mut Ui) {
        ui.horizontal(|ui| {
            ui.add(egui::Slider::new(&mut self.exposure, 0.05..=16.0).logarithmic(true).text("exposure"));
            ui.add(egui::Slider::new(&mut self.zoom, 0.5..=16.0).logarithmic(true).text("zoom"));
            ui.checkbox(&mut self.heat_map, "heat map: terminal nodes per primary ray (PDACRT)");
        });
        if self.heat_map {
            let max = lock(&self.shared).visits.iter().copied().max().unwrap_or(0);
            heat_legend(ui, max);
        }
        self.refresh_texture(ui);
        let Some((tex, ..)) = &self.texture else {
            ui.label("Press Start to render.");
            return;
        };
        let size = tex.size_vec2() * self.zoom;
        let tex_id = tex.id();
        let selected = self.selected_level;
        let shared = self.shared.clone();
        egui::ScrollArea::both().show(ui, |ui| {
            let (rect, response) = ui.allocate_exact_size(size, egui::Sense::drag());
            // Pan: dragging the image scrolls it (the scroll bars and wheel work too).
            if response.dragged() {
                ui.scroll_with_delta(response.drag_delta());
            }
            ui.painter().image(
                tex_id,
                rect,
                egui::Rect::from_min_max(egui::pos2(0.0, 0.0), egui::pos2(1.0, 1.0)),
                Color32::WHITE,
            );
            let s = lock(&shared);
            if let (Some(level), Some(cam)) = (selected, s.camera)
                && let Some(rec) = s.levels.get(level)
            {
                for b in rec.boxes.iter().take(4096) {
                    if let Some(r) = project_box(&cam, b, s.width, s.height) {
                        let scale = egui::vec2(rect.width() / s.width as f32, rect.height() / s.height as f32);
                        let min = rect.min + egui::vec2(r.0.x * scale.x, r.0.y * scale.y);
                        let max = rect.min + egui::vec2(r.1.x * scale.x, r.1.y * scale.y);
                        ui.painter().rect_stroke(
                            egui::Rect::from_min_max(min, max),
                            0.0,
                            egui::Stroke::new(1.0, Color32::from_rgb(255, 200, 0)),
                            egui::StrokeKind::Middle,
                        );
                    }
                }
            }
        });
    }

    fn levels_panel(&mut self, ui: &mut Ui) {
        let levels = lock(&self.shared).levels.clone();
        if levels.is_empty() {
            ui.label("PDACRT levels appear once a render has started (primary rays of the scene).");
            return;
        }
        ui.label("Select a level to draw its node boxes over the image.");
        egui::Grid::new("levels").striped(true).show(ui, |ui| {
            for h in ["level", "nodes", "rays", "triangle refs", "terminal nodes", "id bytes", "ms", "slowest kernel"] {
                ui.label(RichText::new(h).strong());
            }
            ui.end_row();
            for (i, l) in levels.iter().enumerate() {
                if ui.selectable_label(self.selected_level == Some(i), format!("level {}", l.level)).clicked() {
                    self.selected_level = Some(i);
                }
                ui.label(l.nodes.to_string());
                ui.label(l.rays.to_string());
                ui.label(l.triangle_refs.to_string());
                ui.label(l.terminal_nodes.to_string());
                ui.label(l.id_bytes.to_string());
                ui.label(format!("{:.2}", l.seconds * 1e3));
                let slow = l.kernels.iter().max_by(|a, b| a.seconds.total_cmp(&b.seconds));
                ui.label(slow.map_or(String::new(), |k| {
                    format!(
                        "{} {:.2} ms, SIMD {}",
                        k.name,
                        k.seconds * 1e3,
                        k.simd_efficiency.map_or("-".into(), |e| format!("{e:.2}"))
                    )
                }));
                ui.end_row();
            }
        });
        // Counts span orders of magnitude (a few rays against millions of triangle
        // references), so the chart is log10.
        let bars = |offset: f64, count: fn(&LevelRecord) -> usize| -> Vec<egui_plot::Bar> {
            levels
                .iter()
                .map(|l| egui_plot::Bar::new(l.level as f64 + offset, (count(l).max(1) as f64).log10()).width(0.27))
                .collect()
        };
        egui_plot::Plot::new("level_chart")
            .height(240.0)
            .legend(egui_plot::Legend::default())
            .x_axis_label("recursion level")
            .y_axis_label("log10 count")
            .show(ui, |p| {
                p.bar_chart(egui_plot::BarChart::new("rays", bars(-0.28, |l| l.rays)));
                p.bar_chart(egui_plot::BarChart::new("triangle refs", bars(0.0, |l| l.triangle_refs)));
                p.bar_chart(egui_plot::BarChart::new("nodes", bars(0.28, |l| l.nodes)));
            });
    }

    fn queues_panel(&mut self, ui: &mut Ui) {
        let (records, effect, names) = {
            let s = lock(&self.shared);
            (s.queues.clone(), s.sorting_effect, s.material_names.clone())
        };
        if let Some((unsorted, sorted)) = effect {
            ui.label(format!(
                "cis::shade SIMD efficiency on this scene (one pass): unsorted {unsorted:.3}, sorted by material {sorted:.3}"
            ));
        }
        if records.is_empty() {
            ui.label("Queue records appear when the cis integrator renders.");
            return;
        }
        egui::ScrollArea::vertical().show(ui, |ui| {
            egui::Grid::new("queues").striped(true).show(ui, |ui| {
                for h in
                    ["pass", "wavefront iteration", "active", "queues (material: length)", "surviving", "shade SIMD"]
                {
                    ui.label(RichText::new(h).strong());
                }
                ui.end_row();
                for r in records.iter().rev().take(200) {
                    ui.label(r.pass.to_string());
                    ui.label(r.bounce.to_string());
                    ui.label(r.active.to_string());
                    let q: Vec<String> = r
                        .queues
                        .iter()
                        .map(|(m, n)| {
                            if *m == u32::MAX || *m as usize >= 1 << 20 {
                                format!("miss: {n}")
                            } else {
                                names.get(*m as usize).map_or(format!("#{m}: {n}"), |name| format!("{name}: {n}"))
                            }
                        })
                        .collect();
                    ui.label(q.join("  "));
                    ui.label(format!("{:.0} %", r.survival * 100.0));
                    ui.label(r.shade_simd.map_or("-".into(), |e| format!("{e:.3}")));
                    ui.end_row();
                }
            });
        });
    }

    fn kernels_panel(&mut self, ui: &mut Ui) {
        ui.horizontal(|ui| {
            ui.selectable_value(&mut self.analysis_table, false, "This render's kernels");
            ui.selectable_value(
                &mut self.analysis_table,
                true,
                "Analysis kernels (PDACRT primary rays, CIS sorting probe)",
            );
        });
        let mut rows = {
            let s = lock(&self.shared);
            if self.analysis_table { s.analysis_kernels.clone() } else { s.kernels.clone() }
        };
        if rows.is_empty() {
            ui.label(if self.analysis_table {
                "Analysis kernels appear once a render has started."
            } else {
                "This render runs nothing on the simt device (choose the pdacrt caster or the cis integrator), or has not started."
            });
            return;
        }
        let (col, desc) = self.kernel_sort;
        let key = |k: &KernelSummary| -> f64 {
            match col {
                0 => 0.0,
                1 => k.launches as f64,
                2 => k.seconds,
                3 => k.simd_efficiency().unwrap_or(-1.0),
                4 => k.sectors_per_request().unwrap_or(-1.0),
                _ => k.shared_bytes as f64,
            }
        };
        if col == 0 {
            rows.sort_by(|a, b| a.name.cmp(b.name));
        } else {
            rows.sort_by(|a, b| key(a).total_cmp(&key(b)));
        }
        if desc {
            rows.reverse();
        }
        egui::ScrollArea::vertical().show(ui, |ui| {
            egui::Grid::new("kernels").striped(true).show(ui, |ui| {
                for (i, h) in ["kernel", "launches", "ms", "SIMD eff", "load sect/req", "shared B"].iter().enumerate() {
                    let arrow = if self.kernel_sort.0 == i { if self.kernel_sort.1 { " v" } else { " ^" } } else { "" };
                    if ui.button(format!("{h}{arrow}")).clicked() {
                        self.kernel_sort = (i, if self.kernel_sort.0 == i { !self.kernel_sort.1 } else { true });
                    }
                }
                ui.end_row();
                let opt = |x: Option<f64>, d: usize| x.map_or("-".to_string(), |v| format!("{v:.d$}"));
                for k in &rows {
                    ui.label(k.name);
                    ui.label(k.launches.to_string());
                    ui.label(format!("{:.3}", k.seconds * 1e3));
                    ui.label(opt(k.simd_efficiency(), 3));
                    ui.label(opt(k.sectors_per_request(), 2));
                    ui.label(k.shared_bytes.to_string());
                    ui.end_row();
                }
            });
        });
    }

    fn convergence_panel(&mut self, ui: &mut Ui) {
        let series = lock(&self.shared).series.clone();
        ui.label("RMSE against a path-traced reference (log10 axes), one line per render since the inspector started.");
        egui_plot::Plot::new("convergence")
            .legend(egui_plot::Legend::default())
            .x_axis_label("log10 seconds")
            .y_axis_label("log10 RMSE")
            .show(ui, |p| {
                for (i, s) in series.iter().enumerate() {
                    let pts: Vec<[f64; 2]> = s
                        .points
                        .iter()
                        .filter(|(t, e)| *t > 0.0 && *e > 0.0)
                        .map(|(t, e)| [t.log10(), e.log10()])
                        .collect();
                    p.line(egui_plot::Line::new(format!("{} #{}", s.label, i + 1), pts));
                }
            });
    }
}

/// The heat map's legend: the colour ramp from 0 to `max` terminal nodes.
fn heat_legend(ui: &mut Ui, max: u32) {
    ui.horizontal(|ui| {
        ui.label("0");
        let (rect, _) = ui.allocate_exact_size(egui::vec2(200.0, 12.0), egui::Sense::hover());
        let steps = 50;
        for i in 0..steps {
            let x0 = rect.min.x + rect.width() * i as f32 / steps as f32;
            let x1 = rect.min.x + rect.width() * (i + 1) as f32 / steps as f32;
            let r = egui::Rect::from_min_max(egui::pos2(x0, rect.min.y), egui::pos2(x1, rect.max.y));
            ui.painter().rect_filled(r, 0.0, heat((i as f32 + 0.5) / steps as f32));
        }
        ui.label(format!("{max} terminal nodes per primary ray"));
    });
}

/// Blue → red colour map.
fn heat(x: f32) -> Color32 {
    let x = x.clamp(0.0, 1.0);
    let r = (255.0 * (1.5 * x).min(1.0)) as u8;
    let g = (255.0 * (1.0 - (2.0 * x - 1.0).abs())) as u8;
    let b = (255.0 * (1.0 - 1.5 * x).max(0.0)) as u8;
    Color32::from_rgb(r, g, b)
}

/// The 2D pixel bounding rectangle of a box seen by a pinhole camera (corners behind the
/// camera make it `None`).
pub fn project_box(cam: &crate::scene::Camera, b: &Aabb, width: u32, height: u32) -> Option<(Vec2, Vec2)> {
    let tan_half = (cam.vfov_deg.to_radians() * 0.5).tan();
    let aspect = width as f32 / height as f32;
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

/// One render request, run on the worker thread.
struct Job {
    name: String,
    path: PathBuf,
    integrator: Variant,
    caster: CasterKind,
    spp: u32,
    size: u32,
}

impl Job {
    fn run(&self, shared: &Mutex<Shared>, stop: &AtomicBool) -> crate::error::Result<()> {
        let set_status = |msg: String| lock(shared).status = msg;
        set_status(format!("loading {}", self.name));
        let desc = load_scene(&self.path)?;
        let scene = desc.scene;
        scene.check_renderable()?;
        let (w, h) = (self.size, self.size);
        self.analyse(&scene, shared)?;
        let reference = self.reference(&scene, &desc.settings, shared, stop)?;
        let caster = self.caster.build(&scene);
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
            let bvh = BvhCaster::new(scene);
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
        let bvh = BvhCaster::new(scene);
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
