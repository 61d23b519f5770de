//! Scene files (TOML): meshes, materials, point lights, camera and render settings.
//! `assets/scenes/cornell-obj.toml` is a commented example; `docs/scene-format.md`
//! describes every key. Unknown keys are errors, so a typo never passes silently.
//! The format and every check of its values are in this file, so a reader finds each
//! key and its error; `load.rs` decides which reader a path goes to.

use super::camera::Camera;
use super::cornell::cornell_box;
use super::data::{PointLight, Scene, models_dir};
use super::desc::{RenderSettings, SceneDesc, line_of};
use super::material::{Coat, LayerBase, Layered, Material, metals};
use super::obj::{ObjOptions, load_obj};
use crate::error::{Error, Location, Result};
use glam::Vec3;
use serde::Deserialize;
use std::collections::{HashMap, HashSet};
use std::path::{Path, PathBuf};

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct FileCamera {
    position: [f32; 3],
    look_at: [f32; 3],
    #[serde(default = "default_up")]
    up: [f32; 3],
    #[serde(default = "default_fov")]
    fov: f32,
    #[serde(default)]
    aperture_radius: f32,
    focus_distance: Option<f32>,
}

fn default_up() -> [f32; 3] {
    [0.0, 1.0, 0.0]
}
fn default_fov() -> f32 {
    40.0
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct FileMesh {
    file: PathBuf,
    /// Uniform scale (1 when unset); 0, negative or non-finite is an error.
    scale: Option<f32>,
    #[serde(default)]
    translate: [f32; 3],
    material: Option<String>,
}

/// A `[[material]]` table. Which keys apply depends on `type`; see docs/scene-format.md.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct FileMaterial {
    /// Required for top-level materials; a layered material's base needs none.
    #[serde(default)]
    name: String,
    #[serde(rename = "type")]
    kind: String,
    #[serde(default)]
    emission: [f32; 3],
    albedo: Option<[f32; 3]>,
    diffuse: Option<[f32; 3]>,
    specular: Option<[f32; 3]>,
    roughness: Option<f32>,
    reflectance: Option<[f32; 3]>,
    ior: Option<f32>,
    tint: Option<[f32; 3]>,
    /// Conductors: a metal's name, or `eta` and `k`.
    metal: Option<String>,
    eta: Option<[f32; 3]>,
    k: Option<[f32; 3]>,
    /// Layered: the coats, top first, over a base.
    coats: Option<Vec<FileCoat>>,
    base: Option<Box<FileMaterial>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct FileCoat {
    #[serde(default = "default_ior")]
    ior: f32,
    #[serde(default)]
    roughness: f32,
    #[serde(default)]
    absorption: [f32; 3],
}

fn default_ior() -> f32 {
    1.5
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct FilePointLight {
    position: [f32; 3],
    intensity: [f32; 3],
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct FileScene {
    /// `"cornell"` starts from the built-in Cornell box.
    base: Option<String>,
    camera: Option<FileCamera>,
    #[serde(default)]
    render: RenderSettings,
    #[serde(default)]
    mesh: Vec<FileMesh>,
    #[serde(default)]
    material: Vec<FileMaterial>,
    #[serde(default)]
    point_light: Vec<FilePointLight>,
}

impl FileMaterial {
    fn to_material(&self) -> Result<Material, String> {
        let v = Vec3::from_array;
        let need = |x: Option<[f32; 3]>, key: &str| x.map(v).ok_or(format!("material '{}' needs '{key}'", self.name));
        let used: &[(&str, bool)] = &[
            ("albedo", self.albedo.is_some()),
            ("diffuse", self.diffuse.is_some()),
            ("specular", self.specular.is_some()),
            ("roughness", self.roughness.is_some()),
            ("reflectance", self.reflectance.is_some()),
            ("ior", self.ior.is_some()),
            ("tint", self.tint.is_some()),
            ("metal", self.metal.is_some()),
            ("eta", self.eta.is_some()),
            ("k", self.k.is_some()),
            ("coats", self.coats.is_some()),
            ("base", self.base.is_some()),
        ];
        let allowed: &[&str] = match self.kind.as_str() {
            "diffuse" => &["albedo"],
            "glossy" => &["diffuse", "specular", "roughness"],
            "mirror" => &["reflectance"],
            "glass" => &["ior", "tint"],
            "roughglass" => &["ior", "tint", "roughness"],
            "conductor" => &["metal", "eta", "k", "roughness"],
            "layered" => &["coats", "base"],
            other => {
                return Err(format!(
                    "material '{}': unknown type '{other}' (diffuse, glossy, mirror, glass, roughglass, conductor, layered)",
                    self.name
                ));
            }
        };
        if let Some((key, _)) = used.iter().find(|(k, set)| *set && !allowed.contains(k)) {
            return Err(format!("material '{}' of type {} takes no '{key}'", self.name, self.kind));
        }
        Ok(match self.kind.as_str() {
            "diffuse" => Material::Diffuse { albedo: need(self.albedo, "albedo")? },
            "glossy" => Material::Glossy {
                diffuse: need(self.diffuse, "diffuse")?,
                specular: need(self.specular, "specular")?,
                roughness: self.roughness.ok_or(format!("material '{}' needs 'roughness'", self.name))?,
            },
            "mirror" => Material::Mirror { reflectance: self.reflectance.map_or(Vec3::ONE, v) },
            "glass" => Material::Glass { ior: self.ior.unwrap_or(1.5), tint: self.tint.map_or(Vec3::ONE, v) },
            "roughglass" => Material::RoughGlass {
                ior: self.ior.unwrap_or(1.5),
                roughness: self.roughness.unwrap_or(0.1),
                tint: self.tint.map_or(Vec3::ONE, v),
            },
            "conductor" => {
                let (eta, k) = self.conductor_indices()?;
                Material::Conductor { eta, k, roughness: self.roughness.unwrap_or(0.0) }
            }
            _ => {
                let coats = self.coats.as_deref().unwrap_or(&[]);
                if coats.is_empty() || coats.len() > 2 {
                    return Err(format!("layered material '{}' needs one or two coats", self.name));
                }
                let mut c = [Coat { ior: 1.5, roughness: 0.0, absorption: Vec3::ZERO }; 2];
                for (dst, src) in c.iter_mut().zip(coats) {
                    *dst = Coat { ior: src.ior, roughness: src.roughness, absorption: v(src.absorption) };
                }
                let base = self.base.as_deref().ok_or(format!("layered material '{}' needs a base", self.name))?;
                let base = match base.to_material()? {
                    Material::Diffuse { albedo } => LayerBase::Diffuse { albedo },
                    Material::Conductor { eta, k, roughness } => LayerBase::Conductor { eta, k, roughness },
                    _ => return Err(format!("layered material '{}': the base is diffuse or conductor", self.name)),
                };
                Material::Layered(Layered { coats: c, coat_count: coats.len() as u32, base })
            }
        })
    }

    fn conductor_indices(&self) -> Result<(Vec3, Vec3), String> {
        match (&self.metal, self.eta, self.k) {
            (Some(name), None, None) => {
                metals::by_name(name).ok_or(format!("unknown metal '{name}' (gold, copper, silver, aluminium)"))
            }
            (None, Some(eta), Some(k)) => Ok((Vec3::from_array(eta), Vec3::from_array(k))),
            _ => Err(format!("conductor '{}' needs either 'metal' or both 'eta' and 'k'", self.name)),
        }
    }
}

/// A PLY mesh's triangles, of the default material, positions × `scale` + `translate`.
pub(super) fn ply_part(path: &Path, scale: f32, translate: Vec3) -> Result<Scene> {
    let mesh = super::ply::load_ply(path)?;
    let mut scene = Scene::empty(path);
    scene.add_material("default", Material::DEFAULT, Vec3::ZERO);
    scene.material_of = vec![0; mesh.triangles.len()];
    scene.positions = mesh.positions.into_iter().map(|p| p * scale + translate).collect();
    scene.triangles = mesh.triangles;
    if scene.triangles.is_empty() {
        return Err(Error::EmptyMesh { at: Location::file(path) });
    }
    Ok(scene)
}

/// Parses scene-file text; `path` locates meshes and names the file in errors.
/// Every array of numbers in a scene file is a 3-vector: serde would quietly drop a
/// fourth number, so a list of any other length is an error at its key's line.
fn check_vectors(path: &Path, text: &str) -> Result<()> {
    fn walk(v: &toml::Value, key: &str, bad: &mut Option<(String, usize)>) {
        match v {
            toml::Value::Array(items) => {
                let numbers = items.iter().all(|x| x.is_integer() || x.is_float());
                if numbers && !items.is_empty() && items.len() != 3 && bad.is_none() {
                    *bad = Some((key.to_string(), items.len()));
                }
                items.iter().for_each(|x| walk(x, key, bad));
            }
            toml::Value::Table(t) => t.iter().for_each(|(k, x)| walk(x, k, bad)),
            _ => {}
        }
    }
    let Ok(table) = text.parse::<toml::Table>() else { return Ok(()) };
    let mut bad = None;
    table.iter().for_each(|(k, v)| walk(v, k, &mut bad));
    match bad {
        None => Ok(()),
        Some((key, n)) => {
            let line = text
                .lines()
                .position(|l| l.split('=').next().is_some_and(|k| k.trim() == key) || l.contains(&format!(" {key} =")))
                .map_or(0, |i| i + 1);
            Err(Error::SceneFile {
                at: Location::new(path, line),
                msg: format!("{key}: expected three numbers, found {n}"),
            })
        }
    }
}

/// Parses scene-file text; `path` locates meshes and names the file in errors.
pub fn parse_scene_file(path: &Path, text: &str) -> Result<SceneDesc> {
    check_vectors(path, text)?;
    let file: FileScene = toml::from_str(text).map_err(|e| Error::SceneFile {
        at: Location::new(path, e.span().map_or(0, |s| line_of(text, s.start))),
        msg: e.message().to_string(),
    })?;
    let err = |msg: String| Error::SceneFile { at: Location::file(path), msg };
    // An error at the first line that sets `key` (the file's start when none does).
    let err_at = |key: &str, msg: String| {
        let line = text.lines().position(|l| l.trim_start().starts_with(key)).map_or(0, |i| i + 1);
        Error::SceneFile { at: Location::new(path, line), msg }
    };
    let dir = path.parent().map(Path::to_path_buf).unwrap_or_default();
    if let Some(t) = file.render.seconds
        && !(t > 0.0 && t <= crate::limits::MAX_SECONDS)
    {
        let max = crate::limits::MAX_SECONDS;
        return Err(err_at("seconds", format!("render.seconds = {t}: must be positive and at most {max:e}")));
    }

    let mut scene = match file.base.as_deref() {
        None => Scene::empty(path),
        Some("cornell") => Scene { source: path.to_path_buf(), ..cornell_box() },
        Some(other) => {
            return Err(err(format!("unknown base scene '{other}' (known: cornell)")));
        }
    };
    if let Some(m) = file.material.iter().find(|m| m.name.is_empty()) {
        return Err(err(format!("a [[material]] of type '{}' has no name", m.kind)));
    }
    // Name → index into `named` (by hash: a file may hold many thousands of tables).
    let mut by_name: HashMap<&str, usize> = HashMap::with_capacity(file.material.len());
    for (i, m) in file.material.iter().enumerate() {
        if by_name.insert(m.name.as_str(), i).is_some() {
            return Err(err(format!("two [[material]] tables are named '{}'", m.name)));
        }
    }
    let named = file
        .material
        .iter()
        .map(|m| Ok((m.name.clone(), m.to_material().map_err(&err)?, Vec3::from_array(m.emission))))
        .collect::<Result<Vec<(String, Material, Vec3)>>>()?;

    for mesh in &file.mesh {
        let local = dir.join(&mesh.file);
        let found = if local.exists() { local } else { models_dir().join(&mesh.file) };
        if found.exists() {
            // A device, FIFO or folder is refused by name, not reported as missing.
            drop(super::input::open_regular(&found)?);
        } else {
            return Err(Error::io(
                &mesh.file,
                std::io::Error::new(
                    std::io::ErrorKind::NotFound,
                    format!(
                        "mesh named by {} not found next to it or in {} (set WARPRAY_MODELS)",
                        path.display(),
                        models_dir().display()
                    ),
                ),
            ));
        }
        let scale = mesh.scale.unwrap_or(1.0);
        if !(scale.is_finite() && scale > 0.0) {
            return Err(err(format!("mesh {}: scale {scale} must be positive and finite", mesh.file.display())));
        }
        let translate = Vec3::from_array(mesh.translate);
        // A mesh is read by its extension: PLY, or else OBJ (`.obj`, `.obj.gz`).
        let mut part = if found.extension().is_some_and(|e| e.eq_ignore_ascii_case("ply")) {
            ply_part(&found, scale, translate)?
        } else {
            load_obj(&found, &ObjOptions { scale, translate, ..Default::default() })?
        };
        if let Some(mname) = &mesh.material {
            let (_, m, e) = by_name.get(mname.as_str()).map(|&i| &named[i]).ok_or_else(|| {
                err(format!("mesh {} names material '{mname}', which no [[material]] defines", mesh.file.display()))
            })?;
            part.materials = vec![*m];
            part.material_names = vec![mname.clone()];
            part.emission = vec![*e];
            part.two_sided = vec![true];
            part.material_of.iter_mut().for_each(|id| *id = 0);
        }
        scene.append(part);
    }
    // A [[material]] whose name matches a loaded material replaces it; one that matches
    // none (a typo) is an error rather than ignored.
    let loaded: HashSet<&str> = scene.material_names.iter().map(String::as_str).collect();
    for (name, ..) in &named {
        if !loaded.contains(name.as_str()) {
            let mut known: Vec<&str> = scene.material_names.iter().map(String::as_str).collect();
            known.sort_unstable();
            known.dedup();
            return Err(err(format!(
                "[[material]] '{name}' names no material of the scene (its materials: {})",
                known.join(", ")
            )));
        }
    }
    for i in 0..scene.materials.len() {
        if let Some(&k) = by_name.get(scene.material_names[i].as_str()) {
            let (_, m, e) = &named[k];
            scene.materials[i] = *m;
            scene.emission[i] = *e;
        }
    }
    scene.point_lights.extend(
        file.point_light
            .iter()
            .map(|l| PointLight { position: Vec3::from_array(l.position), intensity: Vec3::from_array(l.intensity) }),
    );
    if scene.triangles.is_empty() {
        return Err(Error::EmptyMesh { at: Location::file(path) });
    }
    match &file.camera {
        Some(c) => {
            let (eye, target, up) = (Vec3::from_array(c.position), Vec3::from_array(c.look_at), Vec3::from_array(c.up));
            // A camera with no view direction, or no up that is not along it, would be
            // made up silently by `Camera::look_at`.
            let view = target - eye;
            // Written so that NaN coordinates fail both tests.
            #[allow(clippy::neg_cmp_op_on_partial_ord)]
            let no_view = !(view.length() > 1e-6 * eye.abs().max_element().max(1.0));
            if no_view {
                return Err(err_at(
                    "look_at",
                    format!("camera.look_at {target} is the camera's position: no view direction"),
                ));
            }
            #[allow(clippy::neg_cmp_op_on_partial_ord)]
            let no_up = !(view.normalize().cross(up.normalize_or_zero()).length() > 1e-4);
            if no_up {
                return Err(err_at("up", format!("camera.up {up} is zero or along the view direction {view}")));
            }
            let cam = Camera::look_at(eye, target, up, c.fov);
            let focus = c.focus_distance.unwrap_or((target - eye).length());
            scene.camera = cam.with_lens(c.aperture_radius, focus);
        }
        None if file.base.is_none() => scene.frame_camera(),
        None => {}
    }
    scene.validate()?;
    Ok(SceneDesc { scene, settings: file.render })
}
