//! What a render reports and writes beyond the image: `--stats` and the EXR's AOV
//! channels, checked against values known without the renderer's help.

use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::process::Command;
use warpray::cast::{BvhCaster, RayCaster};
use warpray::film::Film;
use warpray::geometry::Hit;
use warpray::glam::{Vec2, Vec3};
use warpray::scene::{Material, cornell_box};

fn warpray() -> Command {
    Command::new(env!("CARGO_BIN_EXE_warpray"))
}

fn scratch(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("warpray-outputs-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// Runs `warpray render` with `args`; its stdout.
fn render(args: &[&str]) -> String {
    let out = warpray().arg("render").args(args).arg("-q").output().unwrap();
    let stdout = String::from_utf8_lossy(&out.stdout).to_string();
    assert!(out.status.success(), "{args:?}\nstdout: {stdout}\nstderr: {}", String::from_utf8_lossy(&out.stderr));
    stdout
}

/// (total, closest, shadow, calls) from the `rays` line of `--stats`.
fn ray_counts(stats: &str) -> (u64, u64, u64, u64) {
    let line = stats.lines().find(|l| l.trim_start().starts_with("rays ")).expect("a rays line");
    let numbers: Vec<u64> =
        line.split(|c: char| !c.is_ascii_digit()).filter(|t| !t.is_empty()).map(|t| t.parse().unwrap()).collect();
    (numbers[0], numbers[1], numbers[2], numbers[3])
}

#[test]
fn stats_count_rays_by_kind() {
    let dir = scratch("stats");
    let out = dir.join("s.png");
    let out = out.to_str().unwrap();
    // Depth 0 sees emitters only: exactly one camera ray per pixel and pass, no shadow rays.
    let s = render(&["--size", "12x10", "--spp", "3", "--max-depth", "0", "--stats", "-o", out]);
    let (total, closest, shadow, calls) = ray_counts(&s);
    assert_eq!((total, closest, shadow), (12 * 10 * 3, 12 * 10 * 3, 0), "{s}");
    assert_eq!(calls, 3, "one batch of camera rays per pass:\n{s}");
    // With bounces, next-event estimation casts one shadow ray per diffuse hit of a live
    // path: fewer than the closest-hit rays, and the two kinds make up the total.
    let s = render(&["--size", "12x10", "--spp", "3", "--max-depth", "3", "--stats", "-o", out]);
    let (total, closest, shadow, _) = ray_counts(&s);
    assert!(shadow > 0 && shadow <= closest && closest + shadow == total, "{s}");
    assert!(s.contains("Mrays/s") && s.contains("memory") && s.contains("inside the caster"), "{s}");
    assert!(!s.contains("kernels:"), "the BVH runs nothing on the simt device:\n{s}");
    // The GPU method prints its kernel table.
    let s = render(&["--size", "12x10", "--spp", "1", "--caster", "pdacrt", "--stats", "-o", out]);
    assert!(s.contains("kernels:") && s.contains("pdacrt::") && s.contains("SIMD eff"), "{s}");
}

/// Every channel of an EXR's first layer, by name.
fn channels(path: &Path) -> (usize, HashMap<String, Vec<f32>>) {
    use exr::prelude::*;
    let image = read_all_flat_layers_from_file(path).unwrap();
    let layer = &image.layer_data[0];
    let mut out = HashMap::new();
    for c in &layer.channel_data.list {
        out.insert(c.name.to_string(), c.sample_data.values_as_f32().collect());
    }
    (layer.size.width(), out)
}

#[test]
fn aov_channels_match_the_scene() {
    let dir = scratch("aov");
    let exr = dir.join("a.exr");
    let (w, h) = (24u32, 24u32);
    let size = format!("{w}x{h}");
    render(&["--size", &size, "--spp", "4", "--aov", "albedo,normal,depth,variance", "-o", exr.to_str().unwrap()]);
    let (width, ch) = channels(&exr);
    assert_eq!(width, w as usize);
    for name in ["R", "G", "B", "Albedo.R", "Albedo.G", "Albedo.B", "N.X", "N.Y", "N.Z", "Z", "Variance.R"] {
        assert_eq!(ch.get(name).map(Vec::len), Some((w * h) as usize), "channel {name}");
    }
    // The beauty image still reads as before.
    let (rw, rh, rgb) = warpray::converge::read_exr(&exr).unwrap();
    assert_eq!((rw, rh, rgb[5].x), (w, h, ch["R"][5]));

    // Pick a pixel that sees only the Cornell box's back wall (its corners and centre
    // hit one plane facing the camera square on): albedo, normal and depth are then
    // the same for every ray of the pixel and known from the scene alone.
    let scene = cornell_box();
    let caster = BvhCaster::new(&scene);
    let sees = |x: f32, y: f32| {
        let ray = scene.camera.generate_ray(Vec2::new(x, y), w, h, Vec2::ZERO);
        let mut hit = [Hit::MISS];
        caster.closest(&[ray], &mut hit);
        let [a, b, c] = scene.vertices(hit[0].prim);
        (ray, hit[0], (b - a).cross(c - a).normalize())
    };
    let square_on = |(px, py): (u32, u32)| {
        let (x, y) = (px as f32, py as f32);
        let probes = [(0.5, 0.5), (0.0, 0.0), (1.0, 0.0), (0.0, 1.0), (1.0, 1.0)].map(|(dx, dy)| sees(x + dx, y + dy));
        let z = |(r, hit, _): &(warpray::geometry::Ray, Hit, Vec3)| hit.t * r.dir.dot(scene.camera.forward);
        probes.iter().all(|p| p.1.is_hit() && p.2.dot(scene.camera.forward).abs() > 0.9999)
            && probes.iter().all(|p| (z(p) - z(&probes[0])).abs() < 1e-5)
    };
    let (px, py) =
        (0..h).flat_map(|y| (0..w).map(move |x| (x, y))).find(|&p| square_on(p)).expect("a pixel on the back wall");
    let (ray, hit, normal) = sees(px as f32 + 0.5, py as f32 + 0.5);
    let hit = [hit];
    let Material::Diffuse { albedo } = *scene.material(hit[0].prim) else { panic!("the back wall is diffuse") };
    let i = (py * w + px) as usize;
    let got = Vec3::new(ch["Albedo.R"][i], ch["Albedo.G"][i], ch["Albedo.B"][i]);
    assert!((got - albedo).abs().max_element() < 1e-5, "albedo {got} against {albedo}");
    let n = Vec3::new(ch["N.X"][i], ch["N.Y"][i], ch["N.Z"][i]);
    let facing = if normal.dot(ray.dir) < 0.0 { normal } else { -normal };
    assert!((n - facing).length() < 1e-5, "normal {n} against {facing}");
    let z = hit[0].t * ray.dir.dot(scene.camera.forward);
    assert!((ch["Z"][i] - z).abs() < 1e-4 * z, "depth {} against {z}", ch["Z"][i]);
    // The variance channel is the film's, which has its own exact test; here it must
    // be finite and non-negative everywhere, and non-zero somewhere.
    let var = &ch["Variance.R"];
    assert!(var.iter().all(|v| v.is_finite() && *v >= 0.0) && var.iter().any(|v| *v > 0.0));
}

#[test]
fn aovs_need_an_exr() {
    let dir = scratch("aov-png");
    let png = dir.join("a.png");
    let out = warpray().args(["render", "--aov", "depth", "-q", "-o"]).arg(&png).output().unwrap();
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("--aov"), "{}", String::from_utf8_lossy(&out.stderr));
    assert!(!png.exists());
    // The variance of one sample per pixel is undefined: refused before rendering
    // (it was written as zeros, which read as a converged pixel).
    let exr = dir.join("a.exr");
    let out = warpray().args(["render", "--aov", "variance", "--spp", "1", "-q", "-o"]).arg(&exr).output().unwrap();
    assert!(!out.status.success());
    assert!(
        String::from_utf8_lossy(&out.stderr).contains("at least 2 samples"),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(!exr.exists());
}

#[test]
fn film_variance_is_the_unbiased_sample_variance_of_each_pass() {
    let mut film = Film::new(2, 1).unwrap();
    // One pass has no variance: undefined, never a zero that looks like a converged pixel.
    film.add_pass(0, &[Vec3::ONE, Vec3::ONE]);
    assert!(film.variance().iter().all(|v| v.is_nan()));
    let mut film = Film::new(2, 1).unwrap();
    // Pixel 0: estimates 1, 2, 3, 6 (mean 3, sample variance 14/3). Pixel 1: the same
    // values arriving as splats, as light tracing delivers them.
    for (pass, x) in [1.0f32, 2.0, 3.0, 6.0].into_iter().enumerate() {
        film.add_splats([(Vec2::new(1.5, 0.5), Vec3::splat(x - 1.0)), (Vec2::new(1.2, 0.9), Vec3::splat(1.0))]);
        film.add_pass(pass as u32, &[Vec3::splat(x), Vec3::ZERO]);
    }
    let v = film.variance();
    assert!((v[0].x - 14.0 / 3.0).abs() < 1e-5, "{}", v[0]);
    assert!((v[1].x - 14.0 / 3.0).abs() < 1e-5, "{}", v[1]);
    // Splat-only passes (end_pass) count the same way.
    let mut film = Film::new(1, 1).unwrap();
    for x in [2.0f32, 4.0] {
        film.add_splats([(Vec2::new(0.5, 0.5), Vec3::splat(x))]);
        film.end_pass();
    }
    assert!((film.variance()[0].x - 2.0).abs() < 1e-6);
}
