//! The `warpray` command as a user runs it.
//!
//! About 660 lines on purpose: one test per command-line promise (each subcommand's
//! output, its errors naming the file and the option), all driving the built binary
//! through the same helpers.

use std::path::PathBuf;
use std::process::Command;

fn warpray() -> Command {
    Command::new(env!("CARGO_BIN_EXE_warpray"))
}

fn scratch(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("warpray-cli-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

#[test]
fn render_writes_png_and_exr_and_a_summary() {
    let dir = scratch("ok");
    let (png, exr) = (dir.join("a.png"), dir.join("a.exr"));
    let out = warpray()
        .args(["render", "--size", "40x30", "--spp", "2", "--threads", "1", "-q", "-o"])
        .arg(&png)
        .arg("-o")
        .arg(&exr)
        .output()
        .unwrap();
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success(), "stdout: {stdout}\nstderr: {}", String::from_utf8_lossy(&out.stderr));
    assert!(stdout.contains("32 triangles") && stdout.contains("2 spp") && stdout.contains("a.png"), "{stdout}");
    let img = image::open(&png).unwrap();
    assert_eq!((img.width(), img.height()), (40, 30));
    let read = exr::prelude::read_first_rgba_layer_from_file(
        &exr,
        |res, _| vec![0f32; res.width() * res.height()],
        |px: &mut Vec<f32>, pos, (r, _g, _b, _a): (f32, f32, f32, f32)| px[pos.y() * 40 + pos.x()] = r,
    )
    .unwrap();
    let red: f32 = read.layer_data.channel_data.pixels.iter().sum();
    assert!(red > 0.0 && red.is_finite());
}

#[test]
fn bad_arguments_fail_with_a_message_and_write_nothing() {
    let dir = scratch("bad");
    let png = dir.join("never.png");
    let cases: [&[&str]; 14] = [
        &["render", "/no/such/scene.obj"],
        &["render", "--spp-per-iteration", "2", "--integrator", "cis", "--aov", "variance"],
        &["render", "--spp-per-iteration", "0", "--integrator", "lvc"],
        &["render", "--spp-per-iteration", "4", "--integrator", "bdpt"],
        &["render", "--size", "0x10"],
        &["render", "--size", "20000x20000"],
        &["render", "--threads", "0"],
        &["render", "--threads", "20000"],
        &["render", "--spp", "0"],
        &["render", "--seconds", "1e30"],
        &["render", "--seconds", "nan"],
        &["render", "--exposure", "inf"],
        &["render", "--exposure", "nan"],
        &["render", "--exposure=-2"],
    ];
    for args in cases {
        let start = std::time::Instant::now();
        let out = warpray().args(args).arg("-o").arg(&png).arg("-q").output().unwrap();
        assert!(start.elapsed().as_secs() < 60, "{args:?} took {:?}", start.elapsed());
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert!(!out.status.success(), "{args:?} should fail");
        assert!(stderr.contains("error"), "{args:?}: {stderr}");
        assert!(!png.exists(), "{args:?} wrote an image");
    }
    let out = warpray().args(["converge", "--spp-per-iteration", "0", "-o"]).arg(dir.join("c")).output().unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success() && stderr.contains("--spp-per-iteration"), "{stderr}");
    let out = warpray().args(["converge", "--seconds", "1e30", "-o"]).arg(dir.join("c")).output().unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success() && stderr.contains("--seconds"), "{stderr}");
    // A reference of 0 spp is black: errors against it would measure nothing.
    let out = warpray().args(["converge", "--reference-spp", "0", "-o"]).arg(dir.join("c")).output().unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success() && stderr.contains("--reference-spp"), "{stderr}");
    let out = warpray().args(["render", "-o"]).arg(dir.join("x.jpg")).output().unwrap();
    assert!(!out.status.success());
    assert!(std::fs::read_dir(&dir).unwrap().next().is_none(), "nothing may be left behind");
}

#[test]
fn help_lists_the_options() {
    let out = warpray().args(["render", "--help"]).output().unwrap();
    let text = String::from_utf8_lossy(&out.stdout);
    for flag in ["--integrator", "--spp", "--seconds", "--size", "--max-depth", "--threads", "--seed", "--output"] {
        assert!(text.contains(flag), "--help lacks {flag}");
    }
}

#[test]
fn converge_writes_csv_and_charts_and_reads_a_reference() {
    let dir = scratch("converge");
    let prefix = dir.join("c");
    let out = warpray()
        .args(["converge", "--seconds", "0.3", "--size", "24x16", "--reference-spp", "16", "--checkpoints", "4", "-o"])
        .arg(&prefix)
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let csv = std::fs::read_to_string(dir.join("c.csv")).unwrap();
    let mut lines = csv.lines();
    assert_eq!(lines.next(), Some("integrator,seconds,spp,rmse,relmse"));
    let rows: Vec<Vec<&str>> = lines.map(|l| l.split(',').collect()).collect();
    for name in ["path", "light", "bdpt"] {
        let mine: Vec<&Vec<&str>> = rows.iter().filter(|r| r[0] == name).collect();
        assert!(mine.len() >= 2, "{name}: {} checkpoints", mine.len());
        let secs: Vec<f64> = mine.iter().map(|r| r[1].parse().unwrap()).collect();
        assert!(secs.windows(2).all(|w| w[0] <= w[1]), "{name}: times not increasing");
        assert!(mine.iter().all(|r| r[3].parse::<f64>().unwrap().is_finite()));
    }
    let svg = std::fs::read_to_string(dir.join("c.svg")).unwrap();
    assert!(svg.contains("<svg") && svg.contains("bdpt"));
    assert!(image::open(dir.join("c.png")).is_ok());
    // The rendered reference can be given back as --reference.
    let out = warpray()
        .args(["converge", "--seconds", "0.1", "--size", "24x16", "--integrators", "bdpt", "--reference"])
        .arg(dir.join("c-reference.exr"))
        .arg("-o")
        .arg(dir.join("d"))
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    // The cache integrators with four camera passes per light pass.
    let out = warpray()
        .args(["converge", "--seconds", "0.1", "--size", "24x16", "--integrators", "lvc,cis", "--spp-per-iteration"])
        .args(["4", "--reference"])
        .arg(dir.join("c-reference.exr"))
        .arg("-o")
        .arg(dir.join("k"))
        .output()
        .unwrap();
    let csv = std::fs::read_to_string(dir.join("k.csv")).unwrap_or_default();
    assert!(out.status.success() && csv.contains("\nlvc,") && csv.contains("\ncis,"), "{csv}");
    // A reference of the wrong size is an error.
    let out = warpray()
        .args(["converge", "--seconds", "0.1", "--size", "32x32", "--reference"])
        .arg(dir.join("c-reference.exr"))
        .arg("-o")
        .arg(dir.join("e"))
        .output()
        .unwrap();
    assert!(!out.status.success() && String::from_utf8_lossy(&out.stderr).contains("24x16"));
    // --replot redraws the charts and prints the table from the CSV alone.
    let out =
        warpray().args(["converge", "--replot"]).arg(dir.join("c.csv")).arg("-o").arg(dir.join("r")).output().unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let table = String::from_utf8_lossy(&out.stdout);
    assert!(table.contains("| integrator | spp reached | ms per spp |") && table.contains("| bdpt |"), "{table}");
    assert!(
        image::open(dir.join("r.png")).is_ok() && std::fs::read_to_string(dir.join("r.svg")).unwrap().contains("<svg")
    );
    // It renders nothing, so rendering options conflict with it.
    let out = warpray().args(["converge", "--seconds", "2", "--replot"]).arg(dir.join("c.csv")).output().unwrap();
    assert!(!out.status.success() && String::from_utf8_lossy(&out.stderr).contains("cannot be used with"));
}

#[test]
fn converge_renders_a_scene_files_image_as_render_does() {
    // A Mitsuba scene sets a Gaussian filter, Mitsuba's splatting film and a depth of
    // 7: converge's reference must be the image `render` makes of the same file (it
    // was once rendered with the defaults instead: box filter, depth 8).
    let dir = scratch("converge-xml");
    let scene = concat!(env!("CARGO_MANIFEST_DIR"), "/assets/scenes/mitsuba-cbox.xml");
    let out = warpray()
        .args(["converge", scene, "--seconds", "0.05", "--size", "24x16", "--reference-spp", "4"])
        .args(["--integrators", "path", "--checkpoints", "2", "-o"])
        .arg(dir.join("c"))
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    // The reference's seed is converge's seed (0) xor 0x5eed0f7ef.
    let out = warpray()
        .args(["render", scene, "--size", "24x16", "--spp", "4", "--seed", "25481508847", "-o"])
        .arg(dir.join("r.exr"))
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let (_, _, reference) = warpray::converge::read_exr(&dir.join("c-reference.exr")).unwrap();
    let (_, _, rendered) = warpray::converge::read_exr(&dir.join("r.exr")).unwrap();
    assert_eq!(reference, rendered, "converge's reference is not the image render makes of the same file");
}

/// The `warpray.KEY` attributes of an EXR, as a map.
fn metadata(path: &std::path::Path) -> std::collections::HashMap<String, String> {
    warpray::film::read_exr_metadata(path).unwrap().into_iter().collect()
}

#[test]
fn the_exr_says_how_it_was_rendered() {
    let dir = scratch("meta");
    let exr = dir.join("m.exr");
    let out = warpray()
        .args(["--size", "16x16", "--spp", "3", "--seed", "7", "--integrator", "bdpt", "-q", "-o"])
        .arg(&exr)
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let m = metadata(&exr);
    assert_eq!(m["spp"], "3");
    assert_eq!(m["seed"], "7");
    assert_eq!(m["integrator"], "bdpt");
    assert_eq!(m["caster"], "bvh4");
    assert_eq!(m["interrupted"], "false");
    assert_eq!(m["version"], env!("CARGO_PKG_VERSION"));
    assert!(m["seconds"].parse::<f64>().unwrap() >= 0.0 && m.contains_key("scene") && m.contains_key("max_depth"));
}

#[test]
fn outputs_and_names_are_checked_before_any_work() {
    let dir = scratch("early");
    // The dragon would take seconds to load; a bad output path must fail before that.
    for (args, says) in [
        (vec!["render", "cornell", "-o", "/nonexistent-warpray-dir/x.png"], "does not exist"),
        (vec!["render", "cornell", "-o", "picture.jpg"], ".png or .exr"),
        (vec!["render", "cornell", "--megakernel", "-o", "m.png"], "needs --integrator lvc"),
        (
            vec!["render", "cornell", "--integrator", "lvc", "--megakernel", "--caster", "pdacrt", "-o", "m.png"],
            "one at a time",
        ),
        // The registry's labels: the megakernel by label, and an unknown one listed against them.
        (vec!["render", "cornell", "--integrator", "lvc-mk", "--caster", "dacrt", "-o", "m.png"], "one at a time"),
        (vec!["render", "cornell", "--integrator", "pt", "-o", "m.png"], "known: path, light, bdpt, lvc, lvc-mk, cis"),
    ] {
        let start = std::time::Instant::now();
        let out = warpray().args(&args).arg("-q").current_dir(&dir).output().unwrap();
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert!(!out.status.success() && stderr.contains(says), "{args:?}: {stderr}");
        assert!(start.elapsed().as_secs() < 10, "{args:?} took {:?}", start.elapsed());
    }
    // A folder given as the output file.
    std::fs::create_dir(dir.join("d.png")).unwrap();
    let out = warpray().args(["render", "-q", "-o"]).arg(dir.join("d.png")).output().unwrap();
    assert!(String::from_utf8_lossy(&out.stderr).contains("is a folder"));
    // converge: an unknown integrator is named before the 4096-spp reference is rendered.
    let start = std::time::Instant::now();
    let out = warpray()
        .args(["converge", "--integrators", "path,foo", "--reference-spp", "100000", "-o"])
        .arg(dir.join("c"))
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success() && stderr.contains("foo"), "{stderr}");
    assert!(start.elapsed().as_secs() < 10, "took {:?}", start.elapsed());
    assert!(!dir.join("c-reference.exr").exists());
    let out = warpray().args(["converge", "-o", "/nonexistent-warpray-dir/c"]).output().unwrap();
    assert!(String::from_utf8_lossy(&out.stderr).contains("does not exist"));
}

#[cfg(unix)]
/// Sends SIGINT to `child` after `ms` milliseconds and waits for it: a command that
/// ignores Ctrl-C fails the test within 60 s rather than hanging it.
fn ctrl_c_after(mut child: std::process::Child, ms: u64) -> std::process::Output {
    std::thread::sleep(std::time::Duration::from_millis(ms));
    // SAFETY: kill(2) on our own child.
    assert_eq!(unsafe { libc::kill(child.id() as libc::pid_t, libc::SIGINT) }, 0);
    let deadline = std::time::Instant::now() + std::time::Duration::from_secs(60);
    while child.try_wait().unwrap().is_none() {
        if std::time::Instant::now() > deadline {
            child.kill().unwrap();
            panic!("the command did not stop within 60 s of Ctrl-C");
        }
        std::thread::sleep(std::time::Duration::from_millis(50));
    }
    child.wait_with_output().unwrap()
}

#[cfg(unix)]
#[test]
fn ctrl_c_finishes_the_pass_and_writes_what_was_rendered() {
    let dir = scratch("sigint");
    let (exr, png) = (dir.join("i.exr"), dir.join("i.png"));
    // Far more passes than can finish: only Ctrl-C ends this render.
    let child = warpray()
        .args(["--size", "32x32", "--spp", "10000000", "--threads", "1", "-q", "-o"])
        .arg(&exr)
        .arg("-o")
        .arg(&png)
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    let out = ctrl_c_after(child, 1500);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(130), "did not stop on Ctrl-C within 60 s? {stderr}");
    assert!(stderr.contains("interrupted after"), "{stderr}");
    let m = metadata(&exr);
    let spp: u32 = m["spp"].parse().unwrap();
    assert!((1..10_000_000).contains(&spp), "{spp}");
    assert_eq!(m["interrupted"], "true");
    let (w, h, px) = warpray::converge::read_exr(&exr).unwrap();
    assert_eq!((w, h, px.len()), (32, 32, 1024));
    assert!(px.iter().all(|p| p.is_finite()) && px.iter().any(|p| p.max_element() > 0.0));
    assert_eq!(image::open(&png).unwrap().width(), 32);
    // No temporary files left beside the images.
    let names: Vec<String> =
        std::fs::read_dir(&dir).unwrap().map(|e| e.unwrap().file_name().to_string_lossy().into_owned()).collect();
    assert_eq!(names.len(), 2, "{names:?}");
}

#[test]
fn a_built_in_scene_renders_by_name_from_any_folder() {
    let dir = scratch("named");
    let models =
        std::fs::canonicalize(warpray::scene::models_dir()).expect("WARPRAY_MODELS must name the models folder");
    let out = warpray()
        .args(["render", "bunny", "--size", "12x12", "--spp", "1", "-q", "-o", "b.png"])
        .env("WARPRAY_MODELS", &models)
        .current_dir(&dir)
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    assert!(String::from_utf8_lossy(&out.stdout).contains("69483 triangles"));
    assert!(dir.join("b.png").is_file());
}

/// A `w`×`h` EXR of one colour.
fn flat_exr(path: &std::path::Path, w: u32, h: u32, c: warpray::glam::Vec3) {
    let mut film = warpray::film::Film::new(w, h).unwrap();
    film.add_pass(0, &vec![c; (w * h) as usize]);
    film.write(path, 1.0).unwrap();
}

/// The number after `"key":` in a one-line JSON object.
fn json_number(json: &str, key: &str) -> f64 {
    let rest = &json[json.find(&format!("\"{key}\":")).unwrap_or_else(|| panic!("{key} in {json}")) + key.len() + 3..];
    rest[..rest.find([',', '}']).unwrap()].parse().unwrap()
}

#[test]
fn diff_reports_known_differences() {
    use warpray::glam::Vec3;
    let dir = scratch("diff");
    let (a, b, c, small) = (dir.join("a.exr"), dir.join("b.exr"), dir.join("c.exr"), dir.join("s.exr"));
    flat_exr(&a, 4, 2, Vec3::new(1.0, 0.5, 0.25));
    flat_exr(&b, 4, 2, Vec3::new(1.1, 0.5, 0.25));
    flat_exr(&c, 4, 2, Vec3::new(1.0, 0.5, 0.25));
    flat_exr(&small, 2, 2, Vec3::ONE);
    let run =
        |args: &[&std::path::Path], extra: &[&str]| warpray().arg("diff").args(args).args(extra).output().unwrap();
    let out = run(&[&a, &b], &["--json"]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let j = String::from_utf8_lossy(&out.stdout).to_string();
    // One channel of three is off by 0.1 in every pixel: RMSE = sqrt(0.01 / 3).
    // Relative tolerance 1e-5 (the inputs are f32): a 1 % error anywhere, in ε too, fails.
    let close = |x: f64, want: f64| (x - want).abs() < 1e-5 * want;
    assert!(close(json_number(&j, "rmse"), (0.01f64 / 3.0).sqrt()), "{j}");
    // relMSE = (0.01 / (1 + ε)) / 3 with ε = 0.01.
    assert!(close(json_number(&j, "relmse"), 0.01 / 1.01 / 3.0), "{j}");
    assert!(close(json_number(&j, "max_abs"), 0.1), "{j}");
    assert_eq!(json_number(&j, "differing_pixels"), 8.0);
    assert!(j.contains("\"mean_test\":[1.1"), "{j}");
    // Identical images: zeros; the table form names the ε.
    let out = run(&[&a, &c], &[]);
    let t = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success() && t.contains("RMSE      0.000000e0") && t.contains("ε = 0.01"), "{t}");
    // --fail-above: status 1 above the limit, 0 below.
    assert_eq!(run(&[&a, &b], &["--fail-above", "0.01"]).status.code(), Some(1));
    assert_eq!(run(&[&a, &b], &["--fail-above", "0.1"]).status.code(), Some(0));
    // Different sizes, a missing file, a non-image: errors that name the files.
    let e = String::from_utf8_lossy(&run(&[&a, &small], &[]).stderr).to_string();
    assert!(e.contains("4x2") && e.contains("2x2"), "{e}");
    let e = String::from_utf8_lossy(&run(&[&a, &dir.join("none.exr")], &[]).stderr).to_string();
    assert!(e.contains("none.exr"), "{e}");
    std::fs::write(dir.join("t.exr"), b"text").unwrap();
    let out = run(&[&a, &dir.join("t.exr")], &[]);
    assert!(!out.status.success() && String::from_utf8_lossy(&out.stderr).contains("t.exr"));
    // Could not compare (status 2) is not "differs" (status 1), even under a gate.
    assert_eq!(run(&[&a, &small], &["--fail-above", "0.1"]).status.code(), Some(2));
}

/// A `w`×`h` EXR whose pixel `i` (row by row) has every channel `value(i)`, written
/// as it is (NaN and infinities included, which a film would refuse).
fn raw_exr(path: &std::path::Path, w: usize, h: usize, value: impl Fn(usize) -> f32 + Sync) {
    exr::prelude::write_rgb_file(path, w, h, |x, y| {
        let v = value(y * w + x);
        (v, v, v)
    })
    .unwrap();
}

#[test]
fn diff_gates_fail_on_broken_images_and_say_so_in_valid_json() {
    let dir = scratch("diff-gate");
    let (good, nan, inf, huge) = (dir.join("g.exr"), dir.join("n.exr"), dir.join("i.exr"), dir.join("h.exr"));
    raw_exr(&good, 4, 2, |_| 0.5);
    raw_exr(&nan, 4, 2, |_| f32::NAN);
    raw_exr(&inf, 4, 2, |i| if i % 2 == 0 { f32::INFINITY } else { 0.5 });
    raw_exr(&huge, 4, 2, |i| if i == 0 { 3e38 } else { 0.5 });
    let run = |test: &std::path::Path, extra: &[&str]| {
        warpray().arg("diff").arg(&good).arg(test).args(extra).output().unwrap()
    };
    // An all-NaN image and a half-infinite one fail the gate, however small their
    // RMSE over the pixels left (none, or the identical half).
    for broken in [&nan, &inf] {
        assert_eq!(run(broken, &["--fail-above", "0.001"]).status.code(), Some(1), "{}", broken.display());
    }
    assert_eq!(run(&good, &["--fail-above", "0.001"]).status.code(), Some(0));
    // Unless told to judge the finite pixels alone; an image with none still fails.
    assert_eq!(run(&inf, &["--fail-above", "0.001", "--ignore-nonfinite"]).status.code(), Some(0));
    assert_eq!(run(&nan, &["--fail-above", "0.001", "--ignore-nonfinite"]).status.code(), Some(1));
    // The JSON stays JSON: an RMSE of no pixels is null, not `inf` or `NaN`.
    let j = String::from_utf8_lossy(&run(&nan, &["--json"]).stdout).to_string();
    let parsed: serde_json::Value = serde_json::from_str(&j).unwrap_or_else(|e| panic!("{e}: {j}"));
    assert!(parsed["rmse"].is_null() && parsed["compared_pixels"] == 0 && parsed["non_finite_test"] == 8, "{j}");
    // A pixel of 3e38 against 0.5: its squared difference overflows f32, not f64.
    let j = String::from_utf8_lossy(&run(&huge, &["--json"]).stdout).to_string();
    let parsed: serde_json::Value = serde_json::from_str(&j).unwrap_or_else(|e| panic!("{e}: {j}"));
    let rmse = parsed["rmse"].as_f64().unwrap_or_else(|| panic!("{j}"));
    let want = (3e38f32 as f64 - 0.5) / 8f64.sqrt(); // one pixel of 8 off by d in all 3 channels
    assert!((rmse - want).abs() < 1e-6 * want, "{rmse} against {want}");
    // A limit no RMSE can exceed is refused before any image is read.
    for limit in ["nan", "inf", "-1"] {
        let out = run(&good, &[&format!("--fail-above={limit}")]);
        let e = String::from_utf8_lossy(&out.stderr);
        assert!(out.status.code() == Some(2) && e.contains("--fail-above must be a finite RMSE"), "{limit}: {e}");
    }
}

/// Runs `cmd`, failing the test if it takes more than `limit` (a hang).
fn output_within(mut cmd: Command, limit: std::time::Duration) -> std::process::Output {
    let mut child = cmd.stdout(std::process::Stdio::piped()).stderr(std::process::Stdio::piped()).spawn().unwrap();
    let start = std::time::Instant::now();
    while child.try_wait().unwrap().is_none() {
        if start.elapsed() > limit {
            child.kill().unwrap();
            panic!("still running after {limit:?}: {cmd:?}");
        }
        std::thread::sleep(std::time::Duration::from_millis(20));
    }
    child.wait_with_output().unwrap()
}

#[test]
fn converge_refuses_broken_references_and_charts_any_range() {
    let dir = scratch("converge-hostile");
    let limit = std::time::Duration::from_secs(60);
    // A reference with one +Inf pixel rendered, wrote the CSV, then never finished the
    // chart; an all-black one measured against nothing. Both are refused up front.
    let (inf, black) = (dir.join("inf.exr"), dir.join("black.exr"));
    raw_exr(&inf, 24, 16, |i| if i == 5 { f32::INFINITY } else { 0.5 });
    raw_exr(&black, 24, 16, |_| 0.0);
    for (reference, says) in [(&inf, "1 NaN or infinite pixel(s) of 384"), (&black, "black in every pixel")] {
        let mut cmd = warpray();
        cmd.args(["converge", "--seconds", "0.1", "--size", "24x16", "--integrators", "path", "--reference"])
            .arg(reference)
            .arg("-o")
            .arg(dir.join("x"));
        let out = output_within(cmd, limit);
        let e = String::from_utf8_lossy(&out.stderr);
        assert!(out.status.code() == Some(2) && e.contains(says), "{}: {e}", reference.display());
        assert!(!dir.join("x.csv").exists(), "nothing is written for a refused reference");
    }
    // A CSV whose errors span more than 1e308 (never finished before): the charts finish.
    let csv = dir.join("wide.csv");
    std::fs::write(
        &csv,
        "integrator,seconds,spp,rmse,relmse\npath,0.1,1,1e-300,1e-300\npath,1,2,1e300,1e300\nbdpt,0.5,1,0.5,0.25\n",
    )
    .unwrap();
    let mut cmd = warpray();
    cmd.args(["converge", "--replot"]).arg(&csv).arg("-o").arg(dir.join("w"));
    let out = output_within(cmd, limit);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    assert!(image::open(dir.join("w.png")).is_ok());
}

#[test]
fn diff_checks_a_png_header_before_decoding() {
    // A PNG of a few dozen bytes whose header claims 20,000 × 20,000 1-bit pixels (a
    // 31 kB one decoded to 3.7 GB): refused by its header, naming the size, with
    // "cannot read" (reading an image said "cannot write image").
    let dir = scratch("png-bomb");
    let bomb = dir.join("bomb.png");
    let chunk = |kind: &[u8], data: &[u8]| {
        let mut body = kind.to_vec();
        body.extend_from_slice(data);
        let mut crc = flate2::Crc::new();
        crc.update(&body);
        let mut out = (data.len() as u32).to_be_bytes().to_vec();
        out.extend(body);
        out.extend(crc.sum().to_be_bytes());
        out
    };
    let mut ihdr = 20_000u32.to_be_bytes().to_vec();
    ihdr.extend(20_000u32.to_be_bytes());
    ihdr.extend([1, 0, 0, 0, 0]); // 1-bit greyscale, no interlacing
    let mut png = vec![137, 80, 78, 71, 13, 10, 26, 10];
    png.extend(chunk(b"IHDR", &ihdr));
    // One row's worth of compressed zeros: enough for a decoder to reach the pixels.
    let mut z = flate2::write::ZlibEncoder::new(Vec::new(), flate2::Compression::best());
    std::io::Write::write_all(&mut z, &[0u8; 2501]).unwrap();
    png.extend(chunk(b"IDAT", &z.finish().unwrap()));
    png.extend(chunk(b"IEND", &[]));
    std::fs::write(&bomb, png).unwrap();
    let out = warpray().arg("diff").arg(&bomb).arg(&bomb).output().unwrap();
    let e = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{e}");
    assert!(e.contains("cannot read image") && e.contains("20000x20000"), "{e}");
}

/// Renders and scenes beyond the memory budget are refused before their large
/// allocations, with the input, the estimate and the budget; just inside, they run.
#[test]
fn inputs_beyond_the_memory_budget_are_refused_before_allocating() {
    let dir = scratch("budget");
    let render = |budget: &str, size: &str, out: &std::path::Path| {
        warpray()
            .env("WARPRAY_MEMORY_BUDGET", budget)
            .args(["render", "--integrator", "path", "--size", size, "--spp", "1", "--threads", "1", "-q", "-o"])
            .arg(out)
            .output()
            .unwrap()
    };
    // 8192² (the largest size allowed) with path tracing needs about 33 GiB: refused at
    // once under 16 GiB, and nothing is written.
    let big = dir.join("big.exr");
    let start = std::time::Instant::now();
    let out = render("16G", "8192x8192", &big);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success() && !big.exists(), "{err}");
    assert!(err.contains("8192x8192 render with path") && err.contains("16.0 GiB"), "{err}");
    assert!(err.contains("WARPRAY_MEMORY_BUDGET"), "{err}");
    assert!(start.elapsed().as_secs() < 10, "refused before rendering");
    // 512²: 256 MiB + 512² × 520 B = 386 MiB. Refused at 380 MiB, rendered at 400 MiB.
    let small = dir.join("small.exr");
    let out = render("380M", "512x512", &small);
    assert!(!out.status.success() && !small.exists(), "{}", String::from_utf8_lossy(&out.stderr));
    let out = render("400M", "512x512", &small);
    assert!(out.status.success() && small.exists(), "{}", String::from_utf8_lossy(&out.stderr));
    // A budget that is not a size is an error naming the variable.
    let out = render("lots", "16x16", &small);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success() && err.contains("WARPRAY_MEMORY_BUDGET=\"lots\""), "{err}");

    // A 1,000-sphere Mitsuba file (20.5 million triangles, about 9 GiB) under a 1 GiB
    // budget stops at the sphere that crosses it (the 110th: 2,252,800 triangles), named
    // by file and line, before tessellating the rest.
    let spheres: String = (0..1000)
        .map(|i| format!("<shape type=\"sphere\"><point name=\"center\" value=\"{i}, 0, 0\"/></shape>\n"))
        .collect();
    let xml = dir.join("spheres.xml");
    std::fs::write(
        &xml,
        format!(
            "<scene version=\"3.0.0\">\n<emitter type=\"point\"><point name=\"position\" value=\"0, 5, 0\"/></emitter>\n{spheres}</scene>\n"
        ),
    )
    .unwrap();
    let start = std::time::Instant::now();
    let out = warpray()
        .env("WARPRAY_MEMORY_BUDGET", "1G")
        .args(["render"])
        .arg(&xml)
        .args(["--size", "16x16", "--spp", "1", "-q", "-o"])
        .arg(dir.join("spheres.exr"))
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success(), "{err}");
    assert!(err.contains("spheres.xml:112") && err.contains("2252800 triangles") && err.contains("1.0 GiB"), "{err}");
    assert!(start.elapsed().as_secs() < 30, "stopped at the budget");
}

/// Ctrl-C in `converge` ends the integrator under way after its pass and writes the CSV
/// and charts of what was measured (the integrators still to come are left out), with
/// status 130.
#[cfg(unix)]
#[test]
fn ctrl_c_in_converge_writes_what_was_measured() {
    let dir = scratch("converge-sigint");
    let prefix = dir.join("c");
    // Ten minutes per integrator: only Ctrl-C ends this in time.
    let child = warpray()
        .args(["converge", "--seconds", "600", "--size", "24x16", "--reference-spp", "4", "--threads", "1"])
        .args(["--integrators", "path,bdpt", "-o"])
        .arg(&prefix)
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    let out = ctrl_c_after(child, 2500);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(130), "{stderr}");
    assert!(stderr.contains("interrupted: writing the"), "{stderr}");
    let csv = std::fs::read_to_string(dir.join("c.csv")).unwrap();
    let rows: Vec<&str> = csv.lines().skip(1).collect();
    assert!(!rows.is_empty() && rows.iter().all(|r| r.starts_with("path,")), "{csv}");
    assert!(std::fs::read_to_string(dir.join("c.svg")).unwrap().contains("<svg"));
    assert!(image::open(dir.join("c.png")).is_ok());
}

/// `converge` reuses the reference it rendered for the same scene and settings, and
/// renders a new one when a setting that changes it differs.
#[test]
fn converge_reuses_its_reference_for_the_same_scene_and_settings() {
    let dir = scratch("converge-cache");
    let run = |spp: &str| {
        let out = warpray()
            .args(["converge", "--seconds", "0.1", "--size", "16x12", "--integrators", "path", "--reference-spp", spp])
            .arg("-o")
            .arg(dir.join("c"))
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&out.stderr).into_owned();
        assert!(out.status.success(), "{err}");
        err
    };
    let reference = dir.join("c-reference.exr");
    assert!(run("8").contains("rendering the reference: path at 8 spp"));
    let first = std::fs::read(&reference).unwrap();
    let key = metadata(&reference)["reference_key"].clone();
    let again = run("8");
    assert!(again.contains("reusing") && !again.contains("rendering the reference"), "{again}");
    assert_eq!(std::fs::read(&reference).unwrap(), first, "the reused reference is left as it was");
    let other = run("9");
    assert!(other.contains("rendering the reference: path at 9 spp"), "{other}");
    assert_ne!(metadata(&reference)["reference_key"], key);
}

#[test]
fn a_gpu_profile_adds_predicted_gpu_time_to_the_kernel_table() {
    let dir = scratch("gpu-profile");
    let png = dir.join("cis.png");
    let records = dir.join("cis-launches.tsv");
    let out = warpray()
        .args(["render", "--integrator", "cis", "--size", "24x24", "--spp", "1", "--threads", "1", "-q"])
        .args(["--gpu-profile", "h200", "--launch-records"])
        .arg(&records)
        .arg("-o")
        .arg(&png)
        .output()
        .unwrap();
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success(), "{stdout}\n{}", String::from_utf8_lossy(&out.stderr));
    assert!(stdout.contains("GPU ms") && stdout.contains("cis::shade"), "{stdout}");
    let line = stdout.lines().find(|l| l.contains("GPU time predicted on NVIDIA H200")).expect("a total line");
    let ms: f64 = line.split(": ").nth(1).and_then(|r| r.split(' ').next()).and_then(|v| v.parse().ok()).unwrap();
    assert!(ms > 0.0 && ms.is_finite(), "{line}");
    // The launch records are the render's launches: predicted one by one on the same
    // profile, they sum to the table's total.
    let launches = simt::records_from_tsv(&std::fs::read_to_string(&records).unwrap()).unwrap();
    assert!(launches.iter().any(|r| r.name == "cis::shade"), "{launches:?}");
    let h200 = simt::GpuProfile::named("h200").unwrap();
    let sum: f64 = launches.iter().filter_map(|r| simt::timing::predict(r, &h200)).map(|t| t.seconds * 1e3).sum();
    assert!((sum - ms).abs() <= 1e-3 * ms.max(1.0), "records {sum} ms against the table's {ms} ms");
    // Records need the measurement (--gpu-profile) and a .tsv name.
    for (args, says) in [
        (vec!["--launch-records", "r.tsv"], "--gpu-profile"),
        (vec!["--gpu-profile", "h200", "--launch-records", "r.txt"], ".tsv"),
    ] {
        let out = warpray()
            .args(["render", "--integrator", "cis", "--size", "8x8", "--spp", "1", "-q", "-o"])
            .arg(dir.join("r.png"))
            .args(&args)
            .output()
            .unwrap();
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert!(!out.status.success() && stderr.contains(says), "{args:?}: {stderr}");
    }
    // An unknown profile, and a render that launches no emulated kernel: refused, nothing written.
    for (args, says) in [
        (vec!["--integrator", "cis", "--gpu-profile", "h100x"], "known: h200"),
        (vec!["--integrator", "path", "--gpu-profile", "h200"], "launches none"),
    ] {
        let bad = dir.join("bad.png");
        let out = warpray()
            .args(["render", "--size", "8x8", "--spp", "1", "-q"])
            .args(&args)
            .arg("-o")
            .arg(&bad)
            .output()
            .unwrap();
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert!(!out.status.success() && stderr.contains(says), "{args:?}: {stderr}");
        assert!(!bad.exists(), "{args:?} wrote {}", bad.display());
    }
}

#[test]
fn the_cis_pool_is_cis_lbdpts_and_any_pool_holding_every_pixel_renders_the_same_image() {
    let dir = scratch("cis-pool");
    let render = |pool: &str, integrator: &str, out: &str| {
        warpray()
            .args(["render", "--integrator", integrator, "--size", "16x16", "--spp", "1", "-q", "--cis-pool", pool])
            .arg("-o")
            .arg(dir.join(out))
            .output()
            .unwrap()
    };
    // 256 pixels: a pool of 256 and one of a million both hold every pixel at once.
    for (pool, out) in [("256", "a.exr"), ("1000000", "b.exr")] {
        let o = render(pool, "cis", out);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    }
    let diff = warpray().arg("diff").arg(dir.join("a.exr")).arg(dir.join("b.exr")).output().unwrap();
    let report = String::from_utf8_lossy(&diff.stdout);
    assert!(report.lines().any(|l| l.starts_with("RMSE") && l.ends_with(" 0.000000e0")), "{report}");
    // A smaller pool streams the pixels through in more bounces: more caster calls.
    let calls = |pool: &str| -> u64 {
        let o = warpray()
            .args(["render", "--integrator", "cis", "--size", "16x16", "--spp", "1", "--stats", "--cis-pool", pool])
            .arg("-o")
            .arg(dir.join("c.exr"))
            .output()
            .unwrap();
        let stdout = String::from_utf8_lossy(&o.stdout).into_owned();
        let line = stdout.lines().find(|l| l.trim_start().starts_with("rays")).unwrap_or_else(|| panic!("{stdout}"));
        line.split(" in ").nth(1).and_then(|r| r.split(' ').next()).and_then(|n| n.parse().ok()).unwrap()
    };
    assert!(calls("64") > calls("256"), "a pool of 64 against one of 256");
    // Other integrators have no pool, and a pool of none is refused; nothing is written.
    for (pool, integrator, says) in [("64", "path", "has no pool"), ("0", "cis", "0 is not in 1..")] {
        let o = render(pool, integrator, "bad.exr");
        let stderr = String::from_utf8_lossy(&o.stderr);
        assert!(!o.status.success() && stderr.contains(says), "{pool} {integrator}: {stderr}");
        assert!(!dir.join("bad.exr").exists());
    }
}
