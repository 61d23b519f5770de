//! What every target shares: a private directory on a RAM disk for the files a loader
//! must open by path (the loaders refuse anything but regular files, so the input is
//! written out rather than handed over as a pipe).

use std::path::PathBuf;
use warpray::prelude::*;

/// A directory of this process's own, created once.
pub fn scratch() -> PathBuf {
    static DIR: std::sync::OnceLock<PathBuf> = std::sync::OnceLock::new();
    DIR.get_or_init(|| {
        let base = if std::path::Path::new("/dev/shm").is_dir() { PathBuf::from("/dev/shm") } else { std::env::temp_dir() };
        let dir = base.join(format!("warpray-fuzz-{}", std::process::id()));
        std::fs::create_dir_all(&dir).expect("scratch directory");
        dir
    })
    .clone()
}

#[allow(dead_code)] // not every target splits its input
/// Splits `data` at the first `sep`: (before, after); all of it before when absent.
pub fn split<'a>(data: &'a [u8], sep: &[u8]) -> (&'a [u8], &'a [u8]) {
    match data.windows(sep.len()).position(|w| w == sep) {
        Some(i) => (&data[..i], &data[i + sep.len()..]),
        None => (data, &[]),
    }
}

#[allow(dead_code)] // not every target renders
/// What every loaded scene must satisfy: it validates, and when renderable and small
/// (under 10k triangles) a 4×4, one-sample render with path tracing and BDPT gives
/// finite pixels (the loader's validation must keep NaN and panics out of the
/// integrators).
pub fn check_scene(scene: &Scene) {
    scene.validate().expect("a loaded scene validates");
    if scene.check_renderable().is_err() || scene.triangle_count() > 10_000 {
        return;
    }
    let caster = Bvh4::new(scene);
    for integrator in [IntegratorKind::Path, IntegratorKind::Bdpt] {
        let opts = RenderOptions {
            width: 4,
            height: 4,
            budget: Budget::Samples(1),
            max_depth: 4,
            integrator,
            ..Default::default()
        };
        if let Ok((film, _)) = render(scene, &caster, &opts, |_, _| true) {
            assert!(film.mean().iter().all(|p| p.is_finite()), "{integrator:?} made a non-finite pixel");
        }
    }
}
