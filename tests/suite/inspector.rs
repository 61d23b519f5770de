//! Headless UI tests of the inspector (egui_kittest, no display or GPU needed).
#![cfg(feature = "inspector")]

use egui_kittest::Harness;
use egui_kittest::kittest::Queryable;
use std::time::{Duration, Instant};
use warpray::inspector::{Inspector, Panel};

fn harness() -> Harness<'static, Inspector> {
    let mut app = Inspector::new();
    app.size = 24;
    app.spp = 100_000;
    Harness::new_ui_state(|ui, app: &mut Inspector| app.ui(ui), app)
}

/// Steps the UI until `done` holds (the worker runs on its own thread).
fn step_until(h: &mut Harness<'static, Inspector>, what: &str, done: impl Fn(&Inspector) -> bool) {
    let start = Instant::now();
    while !done(h.state()) {
        assert!(start.elapsed() < Duration::from_secs(120), "timed out waiting for {what}");
        h.step();
        std::thread::sleep(Duration::from_millis(20));
    }
    h.step();
}

#[test]
fn every_panel_opens() {
    let mut h = harness();
    h.step();
    for p in Panel::ALL {
        h.get_by_label(p.label()).click();
        h.step();
        h.step();
        assert_eq!(h.state().panel, p);
    }
}

#[test]
fn start_stop_and_select_a_level() {
    let mut h = harness();
    h.step();
    h.get_by_label("Start").click();
    h.step();
    step_until(&mut h, "the first passes", |a| a.shared.lock().unwrap().passes >= 2);
    assert!(h.state().running(), "still rendering with a large budget");
    {
        let s = h.state().shared.lock().unwrap();
        assert_eq!(s.image.len(), 24 * 24);
        assert!(s.image.iter().any(|c| c.max_element() > 0.0));
        assert!(!s.levels.is_empty() && !s.analysis_kernels.is_empty());
        // Path tracing through the BVH runs nothing on the simt device: the render's own
        // table stays empty instead of showing the analysis' kernels.
        assert!(s.kernels.is_empty(), "{:?}", s.kernels.iter().map(|k| k.name).collect::<Vec<_>>());
        assert!(s.status.contains("spp"), "{}", s.status);
        assert_eq!(s.series.len(), 1);
    }
    // The UI stays responsive while the worker renders: panels switch at once.
    h.get_by_label("Kernels").click();
    h.step();
    h.get_by_label("Stop").click();
    h.step();
    step_until(&mut h, "the render to stop", |a| !a.running());
    assert!(h.state().shared.lock().unwrap().status.contains("stopped"));
    // Select a level: its boxes are drawn over the image.
    h.get_by_label("Recursion levels").click();
    h.step();
    h.step();
    h.get_by_label("level 0").click();
    h.step();
    assert_eq!(h.state().selected_level, Some(0));
    h.get_by_label("Image").click();
    h.step();
    h.step();
}

#[test]
fn queue_panel_shows_cis_records() {
    let mut h = harness();
    h.state_mut().integrator = warpray::render::Variant::parse("cis").unwrap();
    h.state_mut().spp = 2;
    h.step();
    h.get_by_label("Start").click();
    h.step();
    step_until(&mut h, "the CIS render", |a| !a.running() && a.shared.lock().unwrap().passes == 2);
    {
        let s = h.state().shared.lock().unwrap();
        assert!(!s.queues.is_empty(), "queue records");
        let (unsorted, sorted) = s.sorting_effect.expect("sorting effect measured");
        assert!(sorted >= unsorted, "{sorted} vs {unsorted}");
        assert!(s.kernels.iter().any(|k| k.name == "cis::shade"));
        assert!(!s.kernels.iter().any(|k| k.name.starts_with("pdacrt::")), "the analysis' kernels are kept apart");
        assert!(s.material_names.iter().any(|n| n == "light"), "{:?}", s.material_names);
        // The render runs as the command line runs it, unmeasured (issue 42 found the
        // measured render's CIS passes about 12x slower): no SIMD figure per bounce, only the
        // records of the last pass.
        assert!(s.queues.iter().all(|r| r.shade_simd.is_none() && r.pass == 1), "an unmeasured render's records");
    }
    h.get_by_label("Queues").click();
    h.step();
    h.step();
    // Asked for, the render is measured and each bounce has its shading SIMD efficiency.
    h.get_by_label("measure the render").click();
    h.step();
    assert!(h.state().measure);
    h.get_by_label("Start").click();
    h.step();
    step_until(&mut h, "the measured CIS render", |a| !a.running() && a.shared.lock().unwrap().passes == 2);
    let s = h.state().shared.lock().unwrap();
    assert!(!s.queues.is_empty() && s.queues.iter().all(|r| r.shade_simd.is_some()));
    assert!(s.series.last().unwrap().label.ends_with(", measured"), "{}", s.series.last().unwrap().label);
}

#[test]
fn preparing_shows_its_step_and_progress_instead_of_press_start() {
    let mut h = harness();
    h.step();
    h.get_by_label("Press Start to render.");
    // The worker's state while it prepares (set here, so the check does not race it).
    {
        let mut s = h.state().shared.lock().unwrap();
        s.running = true;
        s.status = "preparing (step 4 of 4): rendering the reference (path tracing): 64/256 spp".into();
        s.progress = Some(0.25);
    }
    h.step();
    h.get_by_label_contains("Preparing the render: preparing (step 4 of 4)");
    h.get_by_label("25 % of this step");
    assert!(h.query_by_label("Press Start to render.").is_none());
    // An error ends the preparation in the panel, not only in the status line.
    {
        let mut s = h.state().shared.lock().unwrap();
        s.running = false;
        s.progress = None;
        s.status = "error: no such scene".into();
    }
    h.step();
    assert!(h.query_by_label("Press Start to render.").is_none());
    h.get_by_label("error: no such scene");
}

#[test]
fn each_convergence_line_names_its_scene_and_settings() {
    let mut h = harness();
    h.state_mut().spp = 3;
    h.step();
    h.get_by_label("Start").click();
    h.step();
    step_until(&mut h, "a short render", |a| !a.running() && a.shared.lock().unwrap().passes == 3);
    {
        let s = h.state().shared.lock().unwrap();
        assert_eq!(s.progress, None, "no progress bar once the render runs");
        let series = s.series.last().unwrap();
        assert_eq!(series.label, "path / bvh4: cornell (built-in), 24x24, max depth 8");
        assert_eq!(series.points.len(), 3, "one point per pass of the path tracer");
        assert!(series.points.windows(2).all(|w| w[1].0 > w[0].0), "time grows: {:?}", series.points);
    }
    h.get_by_label("Convergence").click();
    h.step();
    h.step();
}

#[test]
fn scene_list_needs_no_working_directory_and_lists_a_scene_once() {
    // Run from elsewhere: the list is the same.
    let here = std::env::current_dir().unwrap();
    std::env::set_current_dir(std::env::temp_dir()).unwrap();
    let mut app = Inspector::new();
    std::env::set_current_dir(here).unwrap();
    let names: Vec<&str> = app.scenes.iter().map(|(_, p)| p.to_str().unwrap()).collect();
    for n in ["cornell", "bunny", "dragon", "conference", "dabrovic-sponza"] {
        assert!(names.contains(&n), "{n} missing from {names:?}");
    }
    assert!(app.scenes.iter().any(|(l, _)| l.contains("slit.toml")), "assets/scenes files are listed");
    assert!(app.scenes.iter().any(|(l, _)| l.contains("mitsuba-cbox.xml")), "Mitsuba XML scenes are listed too");
    let before = app.scenes.len();
    app.add_scene("bunny".into());
    assert_eq!((app.scenes.len(), app.scenes[app.scene].1.to_str()), (before, Some("bunny")));
    let slit = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("assets/scenes/../scenes/slit.toml");
    app.add_scene(slit);
    assert_eq!(app.scenes.len(), before, "the same file by another path is not listed twice");
    assert!(app.scenes[app.scene].0.contains("slit.toml"));
    app.add_scene("assets/scenes/cornell-obj.toml".into());
    app.add_scene("my-scene.toml".into());
    assert_eq!(app.scenes.len(), before + 1);
}

#[test]
fn inspector_command_line_goes_through_clap() {
    let bin = env!("CARGO_BIN_EXE_warpray-inspector");
    let out = std::process::Command::new(bin).arg("--version").output().unwrap();
    assert!(out.status.success() && String::from_utf8_lossy(&out.stdout).contains("warpray-inspector"));
    let out = std::process::Command::new(bin).arg("--help").output().unwrap();
    let help = String::from_utf8_lossy(&out.stdout);
    assert!(help.contains("--start") && help.contains("--integrator"), "{help}");
    // A bad scene is reported before any window opens.
    let out = std::process::Command::new(bin).arg("/no/such/scene.toml").output().unwrap();
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("/no/such/scene.toml"));
    let out = std::process::Command::new(bin).args(["--spp", "0"]).output().unwrap();
    assert!(!out.status.success());
}
