//! Mitsuba 3 XML scenes: the common subset (docs/scene-format.md has the table), read
//! so that the same file renders the same image here as in Mitsuba: its `max_depth`
//! counts segments (ours counts scattering events: one less), its opaque BSDFs are
//! one-sided unless wrapped in `twosided`, its area emitters emit on the normal's side,
//! its default filter is a Gaussian. Anything outside the subset is an error naming
//! the element and its line, never a silent approximation.

mod bsdfs;
mod shapes;
mod xml;

use super::camera::Camera;
use super::data::{PointLight, Scene};
use super::desc::{RenderSettings, SceneDesc};
use super::material::Material;
use super::obj::{ObjOptions, load_obj};
use crate::error::{Error, Location, Result};
use crate::filter::Filter;
use crate::limits::check_triangles;
use glam::Vec3;
use roxmltree::Node;
use std::collections::HashMap;
use std::path::Path;
use xml::{Doc, Props, is_property};

/// The largest `max_depth` (ours) every integrator supports; Mitsuba's −1 (no limit)
/// becomes this.
const UNLIMITED_DEPTH: u32 = (crate::limits::MAX_PATH_VERTICES - 2) as u32;

/// A BSDF as warpray stores it: the material and whether it is two-sided.
#[derive(Clone, Copy)]
struct Bsdf {
    material: Material,
    two_sided: bool,
}

/// Parses a Mitsuba 3 XML scene; `path` locates meshes and names the file in errors.
pub fn parse_mitsuba(path: &Path, text: &str) -> Result<SceneDesc> {
    let document = roxmltree::Document::parse(text).map_err(|e| Error::SceneFile {
        at: Location::new(path, e.pos().row as usize),
        msg: format!("malformed XML: {e}"),
    })?;
    let root = document.root_element();
    let mut doc = Doc { path, text, defaults: HashMap::new() };
    if root.tag_name().name() != "scene" {
        return Err(doc.err(root, "the root element must be <scene>"));
    }
    for d in root.children().filter(|c| c.is_element() && c.tag_name().name() == "default") {
        let (name, value) = (doc.need(d, "name")?, doc.need(d, "value")?);
        doc.defaults.insert(name, value);
    }
    let mut b =
        Builder { doc: &doc, scene: Scene::empty(path), settings: RenderSettings::default(), ids: HashMap::new() };
    b.settings.filter = Some(Filter::mitsuba_gaussian());
    // Mitsuba's film splats camera samples and normalises by the summed weights.
    b.settings.filter_mode = Some(crate::filter::FilterMode::Splat);
    let mut camera = None;
    // BSDFs with an id, in document order, so a shape can refer to any of them.
    for c in root.children().filter(|c| c.is_element() && c.tag_name().name() == "bsdf") {
        let id = doc.need(c, "id").map_err(|_| doc.err(c, "a top-level <bsdf> needs an id"))?;
        let bsdf = b.bsdf(c)?;
        if b.ids.contains_key(&id) {
            // Mitsuba refuses it too; silently, the later one won.
            return Err(doc.err(c, format!("a second <bsdf id=\"{id}\">: ids must be unique")));
        }
        b.ids.insert(id, (bsdf, None));
    }
    for c in root.children().filter(Node::is_element) {
        match c.tag_name().name() {
            "default" | "bsdf" => {}
            "integrator" => b.integrator(c)?,
            "sensor" => {
                if camera.is_some() {
                    return Err(doc.err(c, "only one <sensor> is supported"));
                }
                camera = Some(b.sensor(c)?);
            }
            "shape" => b.shape(c)?,
            "emitter" => b.emitter(c)?,
            _ => return Err(doc.err(c, "element not supported (see docs/scene-format.md)")),
        }
    }
    let Builder { mut scene, settings, .. } = b;
    match camera {
        Some(cam) => scene.camera = cam,
        None if scene.triangle_count() > 0 => scene.frame_camera(),
        None => {}
    }
    scene.validate()?;
    Ok(SceneDesc { scene, settings })
}

struct Builder<'d, 'a> {
    doc: &'d Doc<'a>,
    scene: Scene,
    settings: RenderSettings,
    /// BSDFs by id, with the scene material they became (created on first use).
    ids: HashMap<String, (Bsdf, Option<u32>)>,
}

impl Builder<'_, '_> {
    fn integrator(&mut self, node: Node) -> Result<()> {
        let doc = self.doc;
        let kind = doc.need(node, "type")?;
        let name = match kind.as_str() {
            "path" | "volpath" => "path",
            "ptracer" => "light",
            _ => return Err(doc.err(node, "integrator not supported (path, volpath or ptracer)")),
        };
        if let Some(c) = node.children().find(|c| c.is_element() && !is_property(*c)) {
            return Err(doc.err(c, "nested plugins in an integrator are not supported"));
        }
        let mut p = Props::of(doc, node)?;
        let depth = p.number_or("max_depth", -1.0)?;
        self.settings.max_depth = Some(match depth {
            -1.0 => UNLIMITED_DEPTH,
            d if d >= 1.0 && d.fract() == 0.0 => ((d - 1.0) as u32).min(UNLIMITED_DEPTH),
            d => return Err(doc.err(node, format!("max_depth {d}: expected -1 or an integer of at least 1"))),
        });
        if p.bool_or("hide_emitters", false)? {
            return Err(doc.err(node, "hide_emitters is not supported"));
        }
        // Russian roulette's start changes noise, not the expected image: taken, so
        // that the noise is Mitsuba's too.
        let rr = p.number_or("rr_depth", 5.0)?;
        if !(rr >= 1.0 && rr.fract() == 0.0 && rr <= u32::MAX as f64) {
            return Err(doc.err(node, format!("rr_depth {rr}: expected an integer of at least 1")));
        }
        self.settings.rr_depth = Some(rr as u32);
        p.ignore(&["samples_per_pass", "timeout"]);
        p.finish()?;
        self.settings.integrator = Some(name.to_string());
        Ok(())
    }

    fn sensor(&mut self, node: Node) -> Result<Camera> {
        let doc = self.doc;
        let kind = doc.need(node, "type")?;
        if kind != "perspective" && kind != "thinlens" {
            return Err(doc.err(node, "sensor not supported (perspective or thinlens)"));
        }
        let (mut width, mut height) = (768u32, 576u32);
        for c in node.children().filter(|c| c.is_element() && !is_property(*c)) {
            match c.tag_name().name() {
                "film" => (width, height) = self.film(c)?,
                "sampler" => {
                    let mut p = Props::of(doc, c)?;
                    if let Some(n) = p.number("sample_count")? {
                        if !(n >= 1.0 && n <= u32::MAX as f64 && n.fract() == 0.0) {
                            return Err(doc.err(c, format!("sample_count {n} must be a whole number of at least 1")));
                        }
                        self.settings.spp = Some(n as u32);
                    }
                    if let Some(seed) = p.number("seed")? {
                        if !(seed >= 0.0 && seed <= u64::MAX as f64 && seed.fract() == 0.0) {
                            return Err(doc.err(c, format!("seed {seed} must be a whole number of at least 0")));
                        }
                        self.settings.seed = Some(seed as u64);
                    }
                    // Every sampler type is accepted: warpray draws its own numbers.
                    p.ignore(&["jitter", "scramble_seed", "dimension"]);
                    p.finish()?;
                }
                _ => return Err(doc.err(c, "not supported inside a <sensor>")),
            }
        }
        let mut p = Props::of(doc, node)?;
        let m = p.world_transform()?;
        let fov = match (p.number("fov")?, p.text("focal_length")?) {
            (Some(f), None) => f,
            (None, focal) => {
                let text = focal.unwrap_or_else(|| "50mm".into());
                let mm: f64 =
                    text.trim_end_matches("mm").parse().map_err(|_| doc.err(node, format!("focal_length '{text}'")))?;
                // Mitsuba measures the focal length against a 36 mm wide film.
                2.0 * (18.0 / mm).atan().to_degrees()
            }
            (Some(_), Some(_)) => return Err(doc.err(node, "give fov or focal_length, not both")),
        };
        let axis = if p.text("focal_length")?.is_some() {
            "x".to_string()
        } else {
            p.text("fov_axis")?.unwrap_or_else(|| "x".into())
        };
        let (w, h) = (width as f64, height as f64);
        // tan(vertical half angle) = tan(given half angle) · (film height / that axis' length)
        let ratio = match axis.as_str() {
            "x" => h / w,
            "y" => 1.0,
            "diagonal" => h / (w * w + h * h).sqrt(),
            "smaller" => {
                if w < h {
                    h / w
                } else {
                    1.0
                }
            }
            "larger" => {
                if w > h {
                    h / w
                } else {
                    1.0
                }
            }
            a => return Err(doc.err(node, format!("fov_axis '{a}' (x, y, diagonal, smaller, larger)"))),
        };
        if !(fov > 0.0 && fov < 180.0) {
            return Err(doc.err(node, format!("fov {fov} must lie in (0, 180) degrees")));
        }
        let vfov = 2.0 * ((fov.to_radians() * 0.5).tan() * ratio).atan().to_degrees();
        let (aperture, focus) = (p.number_or("aperture_radius", 0.0)?, p.number("focus_distance")?);
        if kind == "perspective" && aperture != 0.0 {
            return Err(doc.err(node, "aperture_radius needs a thinlens sensor"));
        }
        for off in ["principal_point_offset_x", "principal_point_offset_y"] {
            if p.number_or(off, 0.0)? != 0.0 {
                return Err(doc.err(node, format!("{off} is not supported")));
            }
        }
        p.ignore(&["near_clip", "far_clip", "shutter_open", "shutter_close", "srf"]);
        p.finish()?;
        // Mitsuba's camera looks down local +z with +y up and +x to the image's left.
        let origin = m.transform_point3(Vec3::ZERO);
        let forward = m.transform_vector3(Vec3::Z).normalize_or_zero();
        let up = m.transform_vector3(Vec3::Y).normalize_or_zero();
        let left = m.transform_vector3(Vec3::X);
        let mut cam = Camera::look_at(origin, origin + forward, up, vfov as f32);
        if forward == Vec3::ZERO || cam.right.dot(left) > 0.0 {
            return Err(doc.err(node, "the sensor's to_world is degenerate or mirrors the image (not supported)"));
        }
        if kind == "thinlens" {
            let focus = focus.ok_or_else(|| doc.err(node, "a thinlens sensor needs focus_distance"))?;
            cam = cam.with_lens(aperture as f32, focus as f32);
        }
        cam.validate().map_err(|msg| doc.err(node, msg))?;
        Ok(cam)
    }

    fn film(&mut self, node: Node) -> Result<(u32, u32)> {
        let doc = self.doc;
        if doc.need(node, "type")? != "hdrfilm" {
            return Err(doc.err(node, "film not supported (hdrfilm)"));
        }
        let mut p = Props::of(doc, node)?;
        let size = |v: f64, what: &str| {
            if v >= 1.0 && v <= crate::film::MAX_SIDE as f64 && v.fract() == 0.0 {
                Ok(v as u32)
            } else {
                Err(doc.err(node, format!("{what} {v} must be a whole number in [1, {}]", crate::film::MAX_SIDE)))
            }
        };
        let width = size(p.number_or("width", 768.0)?, "width")?;
        let height = size(p.number_or("height", 576.0)?, "height")?;
        for crop in ["crop_offset_x", "crop_offset_y", "crop_width", "crop_height"] {
            if p.number(crop)?.is_some() {
                return Err(doc.err(node, format!("{crop} is not supported")));
            }
        }
        p.ignore(&["pixel_format", "component_format", "file_format", "banner", "sample_border", "compensate"]);
        p.finish()?;
        if let Some(f) = node.children().find(|c| c.is_element() && !is_property(*c)) {
            if f.tag_name().name() != "rfilter" {
                return Err(doc.err(f, "not supported inside a <film>"));
            }
            let mut q = Props::of(doc, f)?;
            let filter = match doc.need(f, "type")?.as_str() {
                "box" => Filter::Box,
                "gaussian" => {
                    let s = q.number_or("stddev", 0.5)?;
                    // Mitsuba cuts its Gaussian off at four standard deviations and
                    // evaluates it from a table of 31 steps.
                    Filter::mitsuba(s as f32).map_err(|m| doc.err(f, m))?
                }
                _ => return Err(doc.err(f, "filter not supported (box or gaussian)")),
            };
            if matches!(filter, Filter::Box) && q.number_or("radius", 0.5)? != 0.5 {
                return Err(doc.err(f, "only a box of radius 0.5 is supported"));
            }
            q.finish()?;
            self.settings.filter = Some(filter);
        }
        self.settings.width = Some(width);
        self.settings.height = Some(height);
        Ok((width, height))
    }

    /// The scene material for a shape: its BSDF (nested, referenced, or Mitsuba's
    /// default, a one-sided 0.5 grey) with its emission.
    fn shape_material(&mut self, node: Node, emission: Vec3) -> Result<u32> {
        let doc = self.doc;
        let mut chosen: Option<(Bsdf, Option<String>)> = None;
        for c in node.children().filter(|c| c.is_element() && matches!(c.tag_name().name(), "bsdf" | "ref")) {
            if chosen.is_some() {
                return Err(doc.err(c, "a shape takes one BSDF"));
            }
            chosen = Some(match c.tag_name().name() {
                "bsdf" => (self.bsdf(c)?, None),
                _ => (self.reference(c)?, Some(doc.need(c, "id")?)),
            });
        }
        let default = Bsdf { material: Material::Diffuse { albedo: Vec3::splat(0.5) }, two_sided: false };
        let (bsdf, id) = chosen.unwrap_or((default, None));
        // Shapes sharing a referenced BSDF (and emitting nothing) share one material.
        if emission == Vec3::ZERO
            && let Some(id) = &id
            && let Some(&(_, Some(m))) = self.ids.get(id)
        {
            return Ok(m);
        }
        let name = match (&id, node.attribute("id")) {
            (Some(id), _) if emission == Vec3::ZERO => id.clone(),
            (_, Some(shape)) => shape.to_string(),
            (Some(id), None) => format!("{id} (line {})", doc.line(node)),
            (None, None) => format!("shape at line {}", doc.line(node)),
        };
        let m = self.scene.add_material(name, bsdf.material, emission);
        self.scene.two_sided[m as usize] = bsdf.two_sided;
        if emission == Vec3::ZERO
            && let Some(id) = id
        {
            self.ids.insert(id, (bsdf, Some(m)));
        }
        Ok(m)
    }

    fn shape(&mut self, node: Node) -> Result<()> {
        let doc = self.doc;
        let kind = doc.need(node, "type")?;
        let mut emission = Vec3::ZERO;
        for c in node.children().filter(|c| c.is_element() && !is_property(*c)) {
            match c.tag_name().name() {
                "bsdf" | "ref" => {}
                "emitter" => {
                    if doc.need(c, "type")? != "area" {
                        return Err(doc.err(c, "only area emitters can sit on a shape"));
                    }
                    let mut p = Props::of(doc, c)?;
                    emission = p.color_or("radiance", Vec3::ONE)?;
                    p.finish()?;
                    if !(emission.is_finite() && emission.min_element() >= 0.0) {
                        return Err(doc.err(c, "radiance must be finite and non-negative"));
                    }
                }
                _ => return Err(doc.err(c, "not supported inside a <shape>")),
            }
        }
        let mut p = Props::of(doc, node)?;
        let m = p.world_transform()?;
        let flip = p.bool_or("flip_normals", false)?;
        let mesh = match kind.as_str() {
            "rectangle" => shapes::place(shapes::rectangle(), m, true, flip),
            "cube" => shapes::place(shapes::cube(), m, true, flip),
            "sphere" => {
                let center = p.point("center")?.unwrap_or(Vec3::ZERO);
                let radius = p.number_or("radius", 1.0)? as f32;
                if !(radius > 0.0 && radius.is_finite()) {
                    return Err(doc.err(node, format!("radius {radius} must be positive")));
                }
                shapes::place(shapes::sphere(center, radius), m, true, flip)
            }
            "obj" | "ply" => {
                let file = p.text("filename")?.ok_or_else(|| doc.err(node, "filename is missing"))?;
                let dir = doc.path.parent().unwrap_or(Path::new(""));
                let full = dir.join(&file);
                // Mitsuba ignores materials in the file (mtllib) and smooths or keeps
                // normals for shading; warpray shades with face normals either way.
                p.ignore(&["face_normals", "maxSmoothAngle"]);
                let mesh = if kind == "obj" {
                    let s = load_obj(&full, &ObjOptions { ignore_materials: true, ..Default::default() })?;
                    (s.positions, s.triangles)
                } else {
                    let s = super::ply::load_ply(&full)?;
                    (s.positions, s.triangles)
                };
                shapes::place(mesh, m, false, flip)
            }
            _ => return Err(doc.err(node, "shape not supported (obj, ply, rectangle, cube, sphere)")),
        };
        p.finish()?;
        // Each shape's triangles pass the memory budget before they join the scene (a
        // 170 kB file of 1,000 spheres made 20.5 million triangles and 6.2 GB).
        let total = (self.scene.triangles.len() + mesh.1.len()) as u64;
        check_triangles(total)
            .map_err(|over| doc.err(node, format!("the scene's {total} triangles with this shape {over}")))?;
        let material = self.shape_material(node, emission)?;
        let base = self.scene.positions.len() as u32;
        if mesh.0.iter().any(|v| !v.is_finite()) {
            return Err(doc.err(node, "a transformed vertex is not finite"));
        }
        self.scene.positions.extend(mesh.0);
        self.scene.triangles.extend(mesh.1.iter().map(|t| t.map(|i| i + base)));
        self.scene.material_of.extend(std::iter::repeat_n(material, mesh.1.len()));
        Ok(())
    }

    fn emitter(&mut self, node: Node) -> Result<()> {
        let doc = self.doc;
        if doc.need(node, "type")? != "point" {
            return Err(doc.err(node, "emitter not supported at the top level (point; area emitters sit on shapes)"));
        }
        let mut p = Props::of(doc, node)?;
        let m = p.world_transform()?;
        let position = p.point("position")?.unwrap_or(Vec3::ZERO);
        let intensity = p.color_or("intensity", Vec3::ONE)?;
        p.finish()?;
        if !(intensity.is_finite() && intensity.min_element() >= 0.0) {
            return Err(doc.err(node, "intensity must be finite and non-negative"));
        }
        self.scene.point_lights.push(PointLight { position: m.transform_point3(position), intensity });
        Ok(())
    }
}
