//! PLY meshes: the input is the bytes of a PLY file (ASCII or binary), loaded as a
//! scene the way `warpray render m.ply` loads it. A scene that loads passes the
//! checks every loader's scenes pass (`common::check_scene`).
#![no_main]

mod common;

use libfuzzer_sys::fuzz_target;
use warpray::prelude::*;

fuzz_target!(|data: &[u8]| {
    let path = common::scratch().join("m.ply");
    std::fs::write(&path, data).unwrap();
    if let Ok(desc) = load_scene(&path) {
        common::check_scene(&desc.scene);
    }
});
