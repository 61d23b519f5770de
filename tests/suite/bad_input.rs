//! Every kind of bad input gets its own typed error naming the file (and line where
//! known): no panic, no hang, no half-written output.

use std::fs;
use std::io::Write;
use std::path::{Path, PathBuf};
use warpray::cast::BvhCaster;
use warpray::error::Error;
use warpray::film::Film;
use warpray::glam::Vec3;
use warpray::render::{Budget, RenderOptions, render};
use warpray::scene::{Material, ObjOptions, load_obj, load_scene};

/// A fresh scratch folder for one test.
fn scratch(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("warpray-test-{}-{name}", std::process::id()));
    let _ = fs::remove_dir_all(&dir);
    fs::create_dir_all(&dir).unwrap();
    dir
}

fn write(dir: &Path, name: &str, text: &str) -> PathBuf {
    let p = dir.join(name);
    fs::write(&p, text).unwrap();
    p
}

const GOOD_MTL: &str = "newmtl white\nKd 0.5 0.5 0.5\nnewmtl lamp\nKd 0 0 0\nKe 10 10 10\n";

fn obj(body: &str) -> String {
    format!("mtllib scene.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nusemtl white\n{body}")
}

fn load(dir: &Path, obj_text: &str) -> Result<warpray::scene::Scene, Error> {
    write(dir, "scene.mtl", GOOD_MTL);
    let p = write(dir, "scene.obj", obj_text);
    load_obj(p, &ObjOptions::default())
}

#[test]
fn a_good_file_loads_and_maps_its_materials() {
    let dir = scratch("good");
    let s = load(&dir, &obj("f 1 2 3\nusemtl lamp\nf 1 3 2\n")).unwrap();
    assert_eq!(s.triangle_count(), 2);
    assert!(s.has_emitters());
    assert!(s.check_renderable().is_ok());
}

#[test]
fn missing_file() {
    let e = load_obj("/nonexistent/nothing.obj", &ObjOptions::default()).unwrap_err();
    assert!(matches!(&e, Error::Io { path, .. } if path.ends_with("nothing.obj")), "{e}");
    let e = load_scene("/nonexistent/scene.toml").unwrap_err();
    assert!(matches!(e, Error::Io { .. }), "{e}");
}

#[test]
fn malformed_obj_line_names_its_line() {
    let dir = scratch("malformed");
    let e = load(&dir, &obj("f 1 2 3\nv 1.0 zebra 2.0\nf 1 2 3\n")).unwrap_err();
    match &e {
        Error::MalformedObj { at, .. } => {
            assert!(at.path.ends_with("scene.obj"));
            assert_eq!(at.line, 7, "{e}");
        }
        other => panic!("wrong error: {other}"),
    }
    // A face with too few vertices.
    let e = load(&dir, &obj("f 1 2\n")).unwrap_err();
    assert!(matches!(&e, Error::MalformedObj { at, .. } if at.line == 6), "{e}");
}

#[test]
fn usemtl_of_an_unknown_material_names_its_line() {
    let dir = scratch("usemtl");
    // tobj reads an unknown name as "no material", so these faces would have been drawn
    // with the default material without a word.
    let e = load(&dir, &obj("f 1 2 3\nusemtl whyte\nf 1 3 2\n")).unwrap_err();
    assert!(
        matches!(&e, Error::MalformedObj { at, msg } if at.line == 7 && msg.contains("'whyte'") && msg.contains("white, lamp")),
        "{e}"
    );
    // No mtllib at all: the same, saying that none was loaded.
    let p = write(&dir, "bare.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nusemtl red\nf 1 2 3\n");
    let e = load_obj(&p, &ObjOptions::default()).unwrap_err();
    assert!(matches!(&e, Error::MalformedObj { at, msg } if at.line == 4 && msg.contains("no mtllib")), "{e}");
    // Asked to ignore materials, the file loads; a name like `usemtlx` is no usemtl.
    assert!(load_obj(&p, &ObjOptions { ignore_materials: true, ..Default::default() }).is_ok());
    let p = write(&dir, "odd.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nusemtlx red\nf 1 2 3\n");
    assert!(load_obj(&p, &ObjOptions::default()).is_ok());
}

#[test]
fn missing_mtl_names_the_obj_line() {
    let dir = scratch("nomtl");
    let p = write(&dir, "scene.obj", "# header\nmtllib absent.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n");
    let e = load_obj(p, &ObjOptions::default()).unwrap_err();
    match &e {
        Error::MissingMtl { at, mtl, .. } => {
            assert_eq!(mtl, "absent.mtl");
            assert_eq!(at.line, 2, "{e}");
        }
        other => panic!("wrong error: {other}"),
    }
}

#[test]
fn face_index_out_of_range_names_its_line() {
    let dir = scratch("range");
    let e = load(&dir, &obj("f 1 2 3\nf 1 2 9\n")).unwrap_err();
    match &e {
        Error::IndexOutOfRange { at, .. } => assert_eq!(at.line, 7, "{e}"),
        other => panic!("wrong error: {other}"),
    }
    let e = load(&dir, &obj("f -1 -2 -7\n")).unwrap_err();
    assert!(matches!(&e, Error::IndexOutOfRange { at, .. } if at.line == 6), "{e}");
}

#[test]
fn nan_and_inf_coordinates_name_their_line() {
    let dir = scratch("nan");
    for bad in ["v 0 nan 0", "v inf 0 0", "v 0 0 -inf"] {
        // (Vertices no face uses are never read, so the bad one is used here.)
        let e = load(&dir, &obj(&format!("{bad}\nf 1 2 4\n"))).unwrap_err();
        match &e {
            Error::NonFinite { at, .. } => assert_eq!(at.line, 6, "{bad}: {e}"),
            other => panic!("{bad}: wrong error: {other}"),
        }
    }
}

#[test]
fn empty_mesh() {
    let dir = scratch("empty");
    let e = load(&dir, "mtllib scene.mtl\nv 0 0 0\n").unwrap_err();
    assert!(matches!(e, Error::EmptyMesh { .. }), "{e}");
    let e = load(&dir, "").unwrap_err();
    assert!(matches!(e, Error::EmptyMesh { .. }), "{e}");
}

#[test]
fn no_emitters_refuses_to_render() {
    let dir = scratch("dark");
    let s = load(&dir, &obj("f 1 2 3\n")).unwrap();
    let e = s.check_renderable().unwrap_err();
    assert!(matches!(&e, Error::NoEmitters { at } if at.path.ends_with("scene.obj")), "{e}");
    let caster = BvhCaster::new(&s);
    let opts = RenderOptions { width: 4, height: 4, budget: Budget::Samples(1), ..Default::default() };
    assert!(matches!(render(&s, &caster, &opts, |_, _| true), Err(Error::NoEmitters { .. })));
}

#[test]
fn emitters_of_zero_area_or_intensity_do_not_count() {
    let dir = scratch("degenerate-lamp");
    // The lamp's triangle has two coincident corners; the lit scene differs in one vertex.
    let text = |c: &str| obj(&format!("f 1 2 3\nv 2 0 0\nv 3 0 0\nv {c}\nusemtl lamp\nf 4 5 6\n"));
    let s = load(&dir, &text("3 0 0")).unwrap();
    let e = s.check_renderable().unwrap_err();
    assert!(matches!(&e, Error::NoEmitters { at } if at.path.ends_with("scene.obj")), "{e}");
    assert!(e.to_string().contains("positive area"), "{e}");
    let caster = BvhCaster::new(&s);
    let opts = RenderOptions { width: 4, height: 4, budget: Budget::Samples(1), ..Default::default() };
    assert!(matches!(render(&s, &caster, &opts, |_, _| true), Err(Error::NoEmitters { .. })));
    load(&dir, &text("2 1 0")).unwrap().check_renderable().unwrap();
    // Finite corners whose area overflows f32 (built by hand: the OBJ loader already
    // refuses such a file, whose framed camera overflows): no light can be made of it.
    let mut s = load(&dir, &text("2 1 0")).unwrap();
    for (p, huge) in s.positions[3..6].iter_mut().zip([[0.0, 0.0], [3e19, 0.0], [0.0, 3e19]]) {
        *p = warpray::glam::Vec3::new(huge[0], huge[1], 0.0);
    }
    assert!(matches!(s.check_renderable(), Err(Error::NoEmitters { .. })));
    assert!(warpray::lights::Lights::new(&s).is_empty());
    // A point light of zero intensity lights nothing either.
    let mut s = load(&dir, &obj("f 1 2 3\n")).unwrap();
    s.point_lights
        .push(warpray::scene::PointLight { position: warpray::glam::Vec3::ONE, intensity: warpray::glam::Vec3::ZERO });
    assert!(matches!(s.check_renderable(), Err(Error::NoEmitters { .. })));
    s.point_lights[0].intensity = warpray::glam::Vec3::splat(1.0);
    s.check_renderable().unwrap();
}

#[test]
fn zero_and_absurd_image_sizes() {
    for (w, h) in [(0, 10), (10, 0), (0, 0), (100_000, 10), (16_000, 16_000), (u32::MAX, u32::MAX)] {
        let e = Film::new(w, h).unwrap_err();
        assert!(matches!(e, Error::BadImageSize { .. }), "{w}x{h}: {e}");
    }
    let s = warpray::scene::cornell_box();
    let caster = BvhCaster::new(&s);
    let opts = RenderOptions { width: 0, height: 64, budget: Budget::Samples(1), ..Default::default() };
    assert!(matches!(render(&s, &caster, &opts, |_, _| true), Err(Error::BadImageSize { .. })));
}

#[test]
fn scene_file_errors_name_their_line() {
    let dir = scratch("toml");
    let p =
        write(&dir, "a.toml", "base = \"cornell\"\n\n[camera]\nposition = [0, 1, 3]\nlook_at = [0, 1, 0]\nfovv = 30\n");
    let e = load_scene(&p).unwrap_err();
    match &e {
        Error::SceneFile { at, msg } => {
            assert!(at.line >= 3 && at.line <= 6, "{e}");
            assert!(msg.contains("fovv"), "{e}");
        }
        other => panic!("wrong error: {other}"),
    }
    let p = write(&dir, "b.toml", "[[mesh]]\nfile = \"no-such-mesh.obj\"\n");
    assert!(matches!(load_scene(&p).unwrap_err(), Error::Io { .. }));
    let p = write(
        &dir,
        "c.toml",
        "base = \"cornell\"\n[[material]]\nname = \"white\"\ntype = \"diffuse\"\nalbedo = [2, 0, 0]\n",
    );
    assert!(matches!(load_scene(&p).unwrap_err(), Error::SceneFile { .. }));
    let p = write(&dir, "d.toml", "base = \"cornell\"\n[camera]\nposition = [0, 1, 3]\nlook_at = [0, 1, 0]\nfov = 0\n");
    assert!(matches!(load_scene(&p).unwrap_err(), Error::SceneFile { .. }));
}

#[test]
fn malformed_mtl_and_corrupt_gzip() {
    let dir = scratch("mtl");
    write(&dir, "scene.mtl", "newmtl x\nKd 0.5 banana 0.5\n");
    let p = write(&dir, "scene.obj", &obj("f 1 2 3\n"));
    let e = load_obj(p, &ObjOptions::default()).unwrap_err();
    assert!(matches!(e, Error::MalformedMtl { .. }), "{e}");

    let p = dir.join("broken.obj.gz");
    fs::File::create(&p).unwrap().write_all(b"\x1f\x8b\x08\x00 definitely not deflate data").unwrap();
    let e = load_obj(&p, &ObjOptions::default()).unwrap_err();
    assert!(matches!(e, Error::MalformedObj { .. } | Error::Io { .. }), "{e}");
}

#[test]
fn failed_writes_leave_no_file_behind() {
    let dir = scratch("out");
    let film = Film::new(4, 4).unwrap();
    // Unknown extension: refused before anything is written.
    assert!(matches!(film.write(&dir.join("x.jpg"), 1.0), Err(Error::Output { .. })));
    // A folder that does not exist.
    let missing = dir.join("no-such-dir").join("x.png");
    assert!(film.write(&missing, 1.0).is_err());
    assert!(film.write(&dir.join("no-such-dir").join("x.exr"), 1.0).is_err());
    // Nothing at all was left in the scratch folder (no temporary files either).
    let left: Vec<_> = fs::read_dir(&dir).unwrap().collect();
    assert!(left.is_empty(), "left behind: {left:?}");
    // A good write replaces the target whole.
    film.write(&dir.join("ok.png"), 1.0).unwrap();
    film.write(&dir.join("ok.exr"), 1.0).unwrap();
    let names: Vec<String> =
        fs::read_dir(&dir).unwrap().map(|e| e.unwrap().file_name().into_string().unwrap()).collect();
    assert_eq!(names.len(), 2, "{names:?}");
}

/// Makes a FIFO with the system's `mkfifo`; a test that needs one says loudly when the
/// tool is missing.
#[cfg(unix)]
fn fifo(path: &Path) {
    let ok = std::process::Command::new("mkfifo").arg(path).status().map(|s| s.success());
    assert!(matches!(ok, Ok(true)), "this test needs `mkfifo` to make a FIFO: {ok:?}");
}

#[cfg(unix)]
#[test]
fn fifos_devices_and_directories_are_refused_without_reading() {
    let dir = scratch("special");
    // A FIFO with no writer would block a reader forever; /dev/zero never ends.
    let pipe = dir.join("pipe.obj");
    fifo(&pipe);
    let zero_link = dir.join("zero.obj");
    std::os::unix::fs::symlink("/dev/zero", &zero_link).unwrap();
    for p in [pipe.as_path(), Path::new("/dev/zero"), zero_link.as_path(), dir.as_path()] {
        let e = load_obj(p, &ObjOptions::default()).unwrap_err();
        assert!(matches!(&e, Error::NotRegularFile { path, .. } if path == p), "{}: {e}", p.display());
    }
    let e = load_scene(&pipe).unwrap_err();
    assert!(matches!(e, Error::NotRegularFile { .. }), "{e}");
    let toml = dir.join("pipe.toml");
    fifo(&toml);
    assert!(matches!(load_scene(&toml).unwrap_err(), Error::NotRegularFile { .. }));
    // An `mtllib` that names a device.
    let p = write(&dir, "scene.obj", "mtllib /dev/zero\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n");
    let e = load_obj(p, &ObjOptions::default()).unwrap_err();
    assert!(e.to_string().contains("/dev/zero") && e.to_string().contains("device"), "{e}");
}

#[test]
fn inputs_past_the_byte_limit_stop_there() {
    let dir = scratch("limit");
    write(&dir, "scene.mtl", GOOD_MTL);
    // A gzip bomb of newlines: 64 MB of text from 64 KB on disk.
    let p = dir.join("bomb.obj.gz");
    let mut gz = flate2::write::GzEncoder::new(fs::File::create(&p).unwrap(), flate2::Compression::best());
    let chunk = vec![b'\n'; 1 << 20];
    for _ in 0..64 {
        gz.write_all(&chunk).unwrap();
    }
    gz.finish().unwrap();
    assert!(fs::metadata(&p).unwrap().len() < 1 << 20);
    let opts = ObjOptions { max_bytes: Some(1 << 20), ..ObjOptions::default() };
    let start = std::time::Instant::now();
    let e = load_obj(&p, &opts).unwrap_err();
    assert!(matches!(&e, Error::TooLarge { path, limit: 1048576 } if path == &p), "{e}");
    assert!(e.to_string().contains("WARPRAY_MAX_INPUT_BYTES"), "{e}");
    assert!(start.elapsed().as_secs() < 10, "stopped at the limit, not at the end");
    // A plain file just under the limit loads; the same file one byte over does not.
    let text = obj("f 1 2 3\n");
    let p = write(&dir, "small.obj", &text);
    let exact = ObjOptions { max_bytes: Some(text.len() as u64), ..ObjOptions::default() };
    assert!(load_obj(&p, &exact).is_ok());
    let short = ObjOptions { max_bytes: Some(text.len() as u64 - 1), ..ObjOptions::default() };
    assert!(matches!(load_obj(&p, &short).unwrap_err(), Error::TooLarge { .. }));
}

#[test]
fn mtl_numbers_are_checked_with_file_line_and_field() {
    let dir = scratch("mtlnum");
    let p = write(&dir, "scene.obj", &obj("f 1 2 3\n"));
    let cases = [
        ("newmtl white\nKd 0.5 0.5\n", 2, "Kd"), // two components: a panic inside tobj before
        ("newmtl white\nKd 0.5 0.5 0.5\nKe -1 0 0\n", 3, "Ke"),
        ("newmtl white\nKe nan 1 1\n", 2, "Ke"),
        ("newmtl white\nNi 0\n", 2, "Ni"),
        ("newmtl white\nNi NaN\n", 2, "Ni"),
        ("newmtl white\nNs -3\n", 2, "Ns"),
        ("newmtl white\nd 1.5\n", 2, "d"),
        ("newmtl white\nKs 1 1 1 1\n", 2, "Ks"),
    ];
    for (mtl, line, field) in cases {
        write(&dir, "scene.mtl", mtl);
        let e = load_obj(&p, &ObjOptions::default()).unwrap_err();
        let msg = e.to_string();
        assert!(
            matches!(&e, Error::MalformedMtl { at, .. } if at.line == line && at.path.ends_with("scene.mtl")),
            "{mtl:?}: {msg}"
        );
        assert!(msg.contains(field), "{mtl:?}: {msg}");
    }
    // A comment after the values is fine (the shared Cornell box's MTL has them).
    write(&dir, "scene.mtl", "newmtl white\nKa 0.63 0.065 0.05 # Red\nKd 0.5 0.5 0.5\n");
    assert!(load_obj(&p, &ObjOptions::default()).is_ok());
    // One value is a grey (the MTL format allows it).
    write(&dir, "scene.mtl", "newmtl white\nKd 0.25\n");
    let s = load_obj(&p, &ObjOptions::default()).unwrap();
    let Material::Diffuse { albedo } = s.materials[0] else { panic!("{:?}", s.materials[0]) };
    assert_eq!(albedo, warpray::prelude::Vec3::splat(0.25));
}

#[test]
fn absurd_time_budgets_are_errors_not_overflows() {
    let s = warpray::scene::cornell_box();
    let caster = BvhCaster::new(&s);
    for t in [1e30, f64::INFINITY, f64::NAN, 0.0, -1.0] {
        let opts = RenderOptions { width: 4, height: 4, budget: Budget::Seconds(t), ..Default::default() };
        assert!(matches!(render(&s, &caster, &opts, |_, _| true), Err(Error::BadSetting(_))), "{t}");
    }
    let dir = scratch("seconds");
    let p = write(&dir, "s.toml", "base = \"cornell\"\n[render]\nseconds = 1e30\n");
    let e = load_scene(&p).unwrap_err();
    assert!(matches!(&e, Error::SceneFile { at, .. } if at.line == 3), "{e}");
}

#[test]
fn vectors_in_scene_files_have_exactly_three_numbers() {
    let dir = scratch("vec3");
    let cases = [
        ("base = \"cornell\"\n[[point_light]]\nposition = [0, 1, 0, 7]\nintensity = [1, 1, 1]\n", 3, "position"),
        ("base = \"cornell\"\n[camera]\nposition = [0, 1, 3]\nlook_at = [0, 1]\n", 4, "look_at"),
        (
            "base = \"cornell\"\n[[material]]\nname = \"m\"\ntype = \"diffuse\"\nalbedo = [0.5, 0.5, 0.5, 0.5]\n",
            5,
            "albedo",
        ),
    ];
    for (text, line, key) in cases {
        let p = write(&dir, "v.toml", text);
        let e = load_scene(&p).unwrap_err();
        assert!(matches!(&e, Error::SceneFile { at, .. } if at.line == line), "{text:?}: {e}");
        assert!(e.to_string().contains(key), "{e}");
    }
}

#[test]
fn a_ply_file_is_a_scene_and_an_unknown_kind_says_so() {
    let dir = scratch("kinds");
    let ply = "ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\nproperty float y\nproperty float z\n\
               element face 1\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n1 0 0\n1 1 0\n0 1 0\n4 0 1 2 3\n";
    // It was read as TOML ("key with no value").
    let s = load_scene(write(&dir, "quad.ply", ply)).unwrap().scene;
    assert_eq!(s.triangle_count(), 2);
    let e = load_scene(write(&dir, "notes.dat", "hello world\n")).unwrap_err();
    assert!(matches!(&e, Error::SceneFile { at, msg } if at.line == 1 && msg.contains(".ply")), "{e}");
    // A .toml file keeps TOML's own message.
    let e = load_scene(write(&dir, "bad.toml", "hello world\n")).unwrap_err();
    assert!(!e.to_string().contains("not a scene file"), "{e}");
    // A scene file's `[[mesh]]` reads a PLY as a PLY (it was read as OBJ: "no
    // triangles"), with the mesh's scale and translation.
    let toml = "[[mesh]]\nfile = \"quad.ply\"\nscale = 2\ntranslate = [0, 0, -3]\n\
                [[point_light]]\nposition = [0, 0, 3]\nintensity = [1, 1, 1]\n";
    let s = load_scene(write(&dir, "quad.toml", toml)).unwrap().scene;
    assert_eq!(s.triangle_count(), 2);
    let (lo, hi) = s.positions.iter().fold((Vec3::INFINITY, Vec3::NEG_INFINITY), |(l, h), &p| (l.min(p), h.max(p)));
    assert_eq!((lo, hi), (Vec3::new(0.0, 0.0, -3.0), Vec3::new(2.0, 2.0, -3.0)));
}

#[test]
fn degenerate_cameras_are_refused_at_their_line() {
    // `Camera::look_at` makes up a view direction or an up vector when given none; a
    // scene file that asks for a degenerate camera is a mistake, said at its line.
    let dir = scratch("camera");
    let cases = [
        ("base = \"cornell\"\n[camera]\nposition = [0, 1, 3]\nlook_at = [0, 1, 3]\n", 4, "no view direction"),
        (
            "base = \"cornell\"\n[camera]\nposition = [0, 1, 3]\nlook_at = [0, 1, 0]\nup = [0, 0, 2]\n",
            5,
            "along the view",
        ),
        ("base = \"cornell\"\n[camera]\nposition = [0, 1, 3]\nlook_at = [0, 1, 0]\nup = [0, 0, 0]\n", 5, "zero"),
        ("base = \"cornell\"\n[camera]\nposition = [0, 5, 0]\nlook_at = [0, 0, 0]\n", 0, "along the view"),
    ];
    for (text, line, words) in cases {
        let p = write(&dir, "c.toml", text);
        let e = load_scene(&p).unwrap_err();
        assert!(matches!(&e, Error::SceneFile { at, .. } if at.line == line), "{text:?}: {e}");
        assert!(e.to_string().contains(words), "{e}");
    }
    // Looking down with an up that is not along the view is fine.
    let p = write(
        &dir,
        "ok.toml",
        "base = \"cornell\"\n[camera]\nposition = [0, 5, 0]\nlook_at = [0, 0, 0]\nup = [0, 0, 1]\n",
    );
    assert!(load_scene(&p).is_ok());
}

/// Inputs the `image` fuzz target found (docs/fuzz.md): EXR headers claiming images of
/// terabytes, which the reader used to allocate before reading a pixel (an abort).
#[test]
fn exr_headers_claiming_huge_images_are_refused() {
    let data = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data");
    for name in ["fuzz-exr-huge-header.exr", "fuzz-exr-oom.exr"] {
        let path = data.join(name);
        let e = warpray::diff::read_image(&path).unwrap_err();
        assert!(matches!(&e, Error::Input { path: p, .. } if p == &path), "{e}");
        assert!(e.to_string().contains("not a readable EXR"), "{e}");
    }
}

/// A scene file of 100,000 `[[material]]` tables is checked in time linear in their
/// number: the duplicate-name check and the replacement of the scene's materials
/// compared every table with every other (20,000 tables took 1.5 s, 40,000 took 9 s,
/// 200,000 more than a minute: found by the held-out corpus, `docs/reproduce/hostile.py`).
#[test]
fn a_hundred_thousand_material_tables_are_checked_at_once() {
    let table = |name: &str| format!("[[material]]\nname = \"{name}\"\ntype = \"diffuse\"\nalbedo = [0.5, 0.5, 0.5]\n");
    let mut text = String::from("base = \"cornell\"\n");
    for i in 0..100_000 {
        text += &table(&format!("m{i}"));
    }
    text += &table("m0");
    let start = std::time::Instant::now();
    let e = warpray::scene::parse_scene_file(Path::new("s.toml"), &text).unwrap_err().to_string();
    assert!(e.contains("two [[material]] tables are named 'm0'"), "{e}");
    assert!(start.elapsed().as_secs() < 30, "{:?} for 100,000 tables: quadratic again", start.elapsed());
}

/// Scene-file mistakes that were accepted without a word: a `[[material]]` whose name
/// matches nothing (a typo: ignored), two of one name (the later won), a mesh scale of
/// 0 (taken as 1). Each is an error naming the file and what is wrong.
#[test]
fn scene_file_typos_duplicates_and_zero_scales_are_errors() {
    let parse = |text: &str| warpray::scene::parse_scene_file(Path::new("s.toml"), text);
    let white = "[[material]]\nname = \"white\"\ntype = \"diffuse\"\nalbedo = [0.5, 0.5, 0.5]\n";
    assert!(parse(&format!("base = \"cornell\"\n{white}")).is_ok(), "a name the scene has replaces it");
    let typo = "base = \"cornell\"\n[[material]]\nname = \"whte\"\ntype = \"diffuse\"\nalbedo = [0.5, 0.5, 0.5]\n";
    let e = parse(typo).unwrap_err().to_string();
    assert!(e.contains("s.toml") && e.contains("'whte' names no material") && e.contains("white"), "{e}");
    let e = parse(&format!("base = \"cornell\"\n{white}{white}")).unwrap_err().to_string();
    assert!(e.contains("two [[material]] tables are named 'white'"), "{e}");
    let dir = std::env::temp_dir().join(format!("warpray-scale-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    std::fs::write(dir.join("t.obj"), "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n").unwrap();
    for scale in ["0", "-1", "nan"] {
        let text = format!("[[mesh]]\nfile = \"t.obj\"\nscale = {scale}\n");
        let e = warpray::scene::parse_scene_file(&dir.join("s.toml"), &text).unwrap_err().to_string();
        assert!(e.contains("scale") && e.contains("must be positive"), "{scale}: {e}");
    }
    let ok = warpray::scene::parse_scene_file(&dir.join("s.toml"), "[[mesh]]\nfile = \"t.obj\"\n");
    assert!(ok.is_ok(), "no scale is 1: {:?}", ok.err());
}
