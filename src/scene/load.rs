//! Loading a scene by path or name: the reader is chosen by what the path is (a
//! built-in name, a model in `$WARPRAY_MODELS`, or a file by its extension), and the
//! scene passes the memory budget before anything is built for it.

use super::cornell::cornell_box;
use super::data::{Scene, find_model, models_dir};
use super::desc::{RenderSettings, SceneDesc};
use super::file::{parse_scene_file, ply_part};
use super::mitsuba::parse_mitsuba;
use super::obj::{ObjOptions, load_obj};
use crate::error::{Error, Result};
use crate::limits::check_triangles;
use glam::Vec3;
use std::path::Path;

/// Scene files built into the library, by name, so that `warpray render dragon` (and
/// `load_scene("dragon")`) work from any folder: each puts one standard model
/// (`$WARPRAY_MODELS`) under lights and a camera. Their text is `assets/scenes/NAME.toml`.
pub const NAMED_SCENES: &[(&str, &str)] = &[
    ("bunny", include_str!("../../assets/scenes/bunny.toml")),
    ("dragon", include_str!("../../assets/scenes/dragon.toml")),
    ("conference", include_str!("../../assets/scenes/conference.toml")),
    ("dabrovic-sponza", include_str!("../../assets/scenes/dabrovic-sponza.toml")),
];

/// Loads a scene: a `.toml` scene file, an `.obj`/`.obj.gz` file, `cornell` (the
/// built-in box), the name of a built-in scene file ([`NAMED_SCENES`]: `bunny`,
/// `dragon`, `conference`, `dabrovic-sponza`), or the name of a model in
/// `$WARPRAY_MODELS` (`cornell-box`). An existing file wins over a name. The scene
/// passes the memory budget before a caster is built for it.
pub fn load_scene(path: impl AsRef<Path>) -> Result<SceneDesc> {
    let (path, desc) = (path.as_ref(), load_any_scene(path.as_ref())?);
    let n = desc.scene.triangle_count() as u64;
    let what = || format!("{}: {n} triangles", path.display());
    check_triangles(n).map(|_| desc).map_err(|over| Error::OverMemoryBudget { what: what(), over })
}

/// [`load_scene`] without the memory check.
fn load_any_scene(path: &Path) -> Result<SceneDesc> {
    if path.as_os_str() == "cornell" {
        return Ok(SceneDesc { scene: cornell_box(), settings: RenderSettings::default() });
    }
    if !path.exists()
        && let Some(name) = path.to_str()
    {
        if let Some((_, text)) = NAMED_SCENES.iter().find(|(n, _)| *n == name) {
            return parse_scene_file(Path::new(&format!("{name}.toml (built in)")), text);
        }
        if let Some(model) = find_model(name) {
            return load_any_scene(&model);
        }
        if !name.contains(['/', '\\', '.']) {
            let known: Vec<&str> = NAMED_SCENES.iter().map(|(n, _)| *n).collect();
            return Err(Error::io(
                path,
                std::io::Error::new(
                    std::io::ErrorKind::NotFound,
                    format!(
                        "no such file, built-in scene ({}, cornell) or model in {} (set WARPRAY_MODELS)",
                        known.join(", "),
                        models_dir().display()
                    ),
                ),
            ));
        }
    }
    let name = path.to_string_lossy().to_ascii_lowercase();
    if name.ends_with(".obj") || name.ends_with(".obj.gz") {
        let scene = load_obj(path, &ObjOptions::default())?;
        return Ok(SceneDesc { scene, settings: RenderSettings::default() });
    }
    if name.ends_with(".ply") {
        return Ok(SceneDesc { scene: ply_scene(path)?, settings: RenderSettings::default() });
    }
    let text = super::input::read_text(path, super::input::max_input_bytes())?;
    if name.ends_with(".xml") {
        return parse_mitsuba(path, &text);
    }
    parse_scene_file(path, &text).map_err(|e| match e {
        // A file of another kind read as TOML: say what was expected, not TOML's word.
        Error::SceneFile { at, msg } if !name.ends_with(".toml") => Error::SceneFile {
            at,
            msg: format!("not a scene file warpray knows (.toml, .xml, .obj, .obj.gz, .ply); read as TOML: {msg}"),
        },
        e => e,
    })
}

/// A PLY mesh as a scene: every triangle of the default material, the camera framed
/// on it (as for an OBJ file without materials).
fn ply_scene(path: &Path) -> Result<Scene> {
    let mut scene = ply_part(path, 1.0, Vec3::ZERO)?;
    scene.frame_camera();
    scene.validate()?;
    Ok(scene)
}
