//! Mitsuba XML scenes: the input is an XML file, optionally followed by `\n%%PLY%%\n`
//! and the bytes of `m.ply` (which the scene may name in a `ply` shape). A scene that
//! loads passes the checks every loader's scenes pass (`common::check_scene`: it
//! validates, and a tiny render gives finite pixels).
#![no_main]

mod common;

use libfuzzer_sys::fuzz_target;
use warpray::scene::parse_mitsuba;

fuzz_target!(|data: &[u8]| {
    let dir = common::scratch();
    let (xml, ply) = common::split(data, b"\n%%PLY%%\n");
    std::fs::write(dir.join("m.ply"), ply).unwrap();
    let Ok(text) = std::str::from_utf8(xml) else { return };
    if let Ok(desc) = parse_mitsuba(&dir.join("s.xml"), text) {
        common::check_scene(&desc.scene);
    }
});
