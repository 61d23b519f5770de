//! OBJ + MTL: the input is an OBJ, optionally followed by `\n%%MTL%%\n` and the text of
//! `m.mtl` (which the OBJ may name with `mtllib m.mtl`). A first byte of `0x1f` writes the
//! OBJ gzip-compressed as `.obj.gz`, so the decompression path is fuzzed too. A loaded
//! scene must pass its own validation; any panic, hang or runaway allocation is a bug.
#![no_main]

mod common;

use libfuzzer_sys::fuzz_target;
use std::io::Write;
use warpray::scene::{ObjOptions, load_obj};

fuzz_target!(|data: &[u8]| {
    let dir = common::scratch();
    let (gz, data) = match data.split_first() {
        Some((0x1f, rest)) => (true, rest),
        _ => (false, data),
    };
    let (obj, mtl) = common::split(data, b"\n%%MTL%%\n");
    std::fs::write(dir.join("m.mtl"), mtl).unwrap();
    let path = if gz {
        let p = dir.join("f.obj.gz");
        let file = std::fs::File::create(&p).unwrap();
        let mut enc = flate2::write::GzEncoder::new(file, flate2::Compression::fast());
        enc.write_all(obj).unwrap();
        drop(enc);
        p
    } else {
        let p = dir.join("f.obj");
        std::fs::write(&p, obj).unwrap();
        p
    };
    // 4 MiB after decompression: the limit itself is under test, and libFuzzer's RSS
    // limit catches anything that grows past what the limit allows.
    let opts = ObjOptions { max_bytes: Some(4 << 20), ..Default::default() };
    if let Ok(scene) = load_obj(&path, &opts) {
        scene.validate().expect("a loaded scene validates");
        assert!(scene.bounds().min.is_finite() && scene.bounds().max.is_finite());
    }
});
