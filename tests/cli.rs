//! The `warpray` command as a user runs it.

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
    let cases: [&[&str]; 8] = [
        &["render", "/no/such/scene.obj"],
        &["render", "--size", "0x10"],
        &["render", "--size", "20000x20000"],
        &["render", "--threads", "0"],
        &["render", "--threads", "20000"],
        &["render", "--spp", "0"],
        &["render", "--seconds", "1e30"],
        &["render", "--seconds", "nan"],
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
    let out = warpray().args(["converge", "--seconds", "1e30", "-o"]).arg(dir.join("c")).output().unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success() && stderr.contains("--seconds"), "{stderr}");
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
    // A reference of the wrong size is an error.
    let out = warpray()
        .args(["converge", "--seconds", "0.1", "--size", "32x32", "--reference"])
        .arg(dir.join("c-reference.exr"))
        .arg("-o")
        .arg(dir.join("e"))
        .output()
        .unwrap();
    assert!(!out.status.success() && String::from_utf8_lossy(&out.stderr).contains("24x16"));
}
