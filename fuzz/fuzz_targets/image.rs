//! Images read by `warpray diff` and `warpray converge --reference`: the first byte picks
//! the type (even: EXR, odd: PNG), the rest is the file.
#![no_main]

mod common;

use libfuzzer_sys::fuzz_target;

fuzz_target!(
    // One good EXR read first: exr decompresses on rayon's global pool, whose threads
    // (created on first use and kept) would otherwise be reported as a leak.
    init: {
        let path = common::scratch().join("warm-up.exr");
        let film = warpray::film::Film::new(64, 64).unwrap();
        film.write_exr(&path).unwrap();
        warpray::diff::read_image(&path).unwrap();
    },
    |data: &[u8]| {
    let Some((&kind, bytes)) = data.split_first() else { return };
    let path = common::scratch().join(if kind % 2 == 0 { "i.exr" } else { "i.png" });
    std::fs::write(&path, bytes).unwrap();
    if let Ok((w, h, px)) = warpray::diff::read_image(&path) {
        assert_eq!(px.len() as u64, w as u64 * h as u64);
    }
    let _ = warpray::film::read_exr_metadata(&path);
});
