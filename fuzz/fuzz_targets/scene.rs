//! Scene files: the input is a TOML scene file, optionally followed by `\n%%OBJ%%\n` and
//! the text of `m.obj` (which the scene may name as a mesh). A scene that loads and
//! passes `check_renderable` is then rendered tiny (4×4, one sample, path tracing and
//! BDPT): the loader's validation must keep NaN and panics out of the integrators.
#![no_main]

mod common;

use libfuzzer_sys::fuzz_target;
use warpray::scene::parse_scene_file;

fuzz_target!(|data: &[u8]| {
    let dir = common::scratch();
    let (toml, obj) = common::split(data, b"\n%%OBJ%%\n");
    std::fs::write(dir.join("m.obj"), obj).unwrap();
    let Ok(text) = std::str::from_utf8(toml) else { return };
    let path = dir.join("s.toml");
    let Ok(desc) = parse_scene_file(&path, text) else { return };
    common::check_scene(&desc.scene);
});
