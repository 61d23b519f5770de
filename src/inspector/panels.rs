//! The inspector's panels: image (and PDACRT heat map), recursion levels, CIS queues,
//! kernel statistics and error against time. The methods live beside `Inspector`'s
//! controls in `mod.rs`; this file only draws.

use super::job::{REFERENCE_SEED, REFERENCE_SPP};
use super::shared::lock;
use super::{Inspector, project_box};
use crate::cast::pdacrt::LevelRecord;
use crate::film::encode_srgb8;
use egui::{Color32, ColorImage, RichText, TextureOptions, Ui};
use simt::KernelSummary;

impl Inspector {
    pub(super) fn refresh_texture(&mut self, ui: &Ui) {
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

    pub(super) fn image_panel(&mut self, ui: &mut Ui) {
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
            let s = lock(&self.shared);
            match (s.running, s.progress) {
                (true, progress) => {
                    ui.label(format!("Preparing the render: {}", s.status));
                    let p = progress.unwrap_or(0.0);
                    ui.add(egui::ProgressBar::new(p).text(format!("{:.0} % of this step", p * 100.0)));
                }
                (false, _) if s.status.starts_with("error") => {
                    ui.label(s.status.clone());
                }
                _ => {
                    ui.label("Press Start to render.");
                }
            }
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

    pub(super) fn levels_panel(&mut self, ui: &mut Ui) {
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

    pub(super) fn queues_panel(&mut self, ui: &mut Ui) {
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

    pub(super) fn kernels_panel(&mut self, ui: &mut Ui) {
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
                5 => k.shared_bytes as f64,
                _ => k.gpu_seconds,
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
                // Measured kernels are predicted on the inspector's GPU profile too.
                let gpu = rows.iter().any(|k| k.gpu_seconds > 0.0);
                let gpu_head =
                    format!("GPU ms ({})", super::job::inspector_gpu_profile().map_or("?".to_string(), |p| p.name));
                let heads = ["kernel", "launches", "ms", "SIMD eff", "load sect/req", "shared B", gpu_head.as_str()];
                for (i, h) in heads.iter().take(if gpu { 7 } else { 6 }).enumerate() {
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
                    if gpu {
                        ui.label(format!("{:.3}", k.gpu_seconds * 1e3));
                    }
                    ui.end_row();
                }
            });
        });
    }

    pub(super) fn convergence_panel(&mut self, ui: &mut Ui) {
        let series = lock(&self.shared).series.clone();
        ui.label(format!(
            "RMSE of the mean image against a path-traced reference of the same scene and size ({REFERENCE_SPP} spp, \
             seed {REFERENCE_SEED}), over the render's own seconds (loading, analysis and reference left out). \
             Both axes logarithmic. One line per render since the inspector started."
        ));
        // The lines are drawn in log10 coordinates; the axes and the hover label show
        // the values themselves.
        egui_plot::Plot::new("convergence")
            .legend(egui_plot::Legend::default())
            .x_axis_label("render time, seconds")
            .y_axis_label("RMSE")
            .x_axis_formatter(|mark, _| real_units(mark.value, " s"))
            .y_axis_formatter(|mark, _| real_units(mark.value, ""))
            .label_formatter(|hover| {
                let (name, p) = match hover {
                    egui_plot::HoverPosition::NearDataPoint { plot_name, position, .. } => (*plot_name, position),
                    egui_plot::HoverPosition::Elsewhere { position } => ("", position),
                };
                Some(format!("{name}\n{}, RMSE {}", real_units(p.x, " s"), real_units(p.y, "")))
            })
            .show(ui, |p| {
                for (i, s) in series.iter().enumerate() {
                    let pts: Vec<[f64; 2]> = s
                        .points
                        .iter()
                        .filter(|(t, e)| *t > 0.0 && *e > 0.0)
                        .map(|(t, e)| [t.log10(), e.log10()])
                        .collect();
                    p.line(egui_plot::Line::new(format!("#{} {}", i + 1, s.label), pts));
                }
            });
    }
}

/// A value drawn at `log10` coordinate `x`, in its own units, labelled as the
/// converge charts label their axes (`converge::tick`: three significant digits).
fn real_units(x: f64, unit: &str) -> String {
    format!("{}{unit}", crate::converge::tick(10f64.powf(x)))
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

#[cfg(test)]
mod tests {
    use super::real_units;

    #[test]
    fn axes_show_values_in_their_own_units() {
        assert_eq!(real_units(0.0, " s"), "1 s");
        assert_eq!(real_units(-1.0, " s"), "0.1 s");
        assert_eq!(real_units(0.5, ""), "3.16");
        assert_eq!(real_units(2.5, " s"), "316 s");
        assert_eq!(real_units(-1.9030899869919435, ""), "0.0125");
        assert_eq!(real_units(-5.0, ""), "0.00001");
        assert_eq!(real_units(5.0, ""), "100000");
    }
}
