//! The scene itself: triangles, their materials, emission and lights, and the camera
//! (`Scene`), with the folder the standard models are read from. The scene module's
//! other files build a `Scene` from files or code; this file imports none of them but
//! the camera and the material table.

use super::camera::Camera;
use super::material::Material;
use crate::error::{Error, Location, Result};
use crate::geometry::{Aabb, triangle_normal};
use glam::Vec3;
use std::path::{Path, PathBuf};

/// An isotropic point light: `intensity` is radiant intensity (W/sr) per channel.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PointLight {
    /// Position.
    pub position: Vec3,
    /// Radiant intensity, W/sr per channel.
    pub intensity: Vec3,
}

#[derive(Clone, Debug)]
/// A scene as flat arrays: triangles, per-triangle materials, emission, point lights and a camera.
pub struct Scene {
    /// Vertex positions.
    pub positions: Vec<Vec3>,
    /// Triangles as three indices into `positions`.
    pub triangles: Vec<[u32; 3]>,
    /// Per triangle: index into `materials`.
    pub material_of: Vec<u32>,
    /// The materials.
    pub materials: Vec<Material>,
    /// Per material: its name (from the MTL or scene file).
    pub material_names: Vec<String>,
    /// Per material: emitted radiance from the front face (the side the winding's
    /// normal points to). Zero for non-emitters.
    pub emission: Vec<Vec3>,
    /// Per material: whether it scatters on both sides (warpray's and pbrt's
    /// convention, `true`) or only on the front, the winding's side (Mitsuba's opaque
    /// BSDFs outside a `twosided` wrapper): seen from behind such a surface is black.
    /// Dielectrics always use both sides.
    pub two_sided: Vec<bool>,
    /// Point lights.
    pub point_lights: Vec<PointLight>,
    /// The camera.
    pub camera: Camera,
    /// Where the scene came from, for error messages (`<built-in>` for the Cornell box).
    pub source: PathBuf,
}

impl Scene {
    /// Triangles.
    pub fn triangle_count(&self) -> usize {
        self.triangles.len()
    }

    /// The three corners of triangle `i`.
    #[inline]
    pub fn vertices(&self, i: u32) -> [Vec3; 3] {
        use crate::cost::read;
        let [a, b, c] = read!(self.triangles, i as usize);
        [read!(self.positions, a as usize), read!(self.positions, b as usize), read!(self.positions, c as usize)]
    }

    /// The unit geometric normal of triangle `i`, following its winding (zero for a
    /// degenerate triangle).
    #[inline]
    pub fn unit_normal(&self, i: u32) -> Vec3 {
        let [a, b, c] = self.vertices(i);
        crate::geometry::triangle_normal(a, b, c).normalize_or_zero()
    }

    /// [`Scene::unit_normal`] of every triangle, in scene order: what a render computes
    /// once so that its hits read a triangle's normal instead of working it out (12
    /// bytes a triangle).
    pub fn unit_normals(&self) -> Vec<Vec3> {
        use rayon::prelude::*;
        (0..self.triangles.len() as u32).into_par_iter().map(|i| self.unit_normal(i)).collect()
    }

    /// All triangles as corner triples, in scene order (what the casters consume).
    pub fn triangle_vertices(&self) -> Vec<[Vec3; 3]> {
        (0..self.triangles.len() as u32).map(|i| self.vertices(i)).collect()
    }

    /// Unnormalised geometric normal of triangle `i`.
    #[inline]
    pub fn normal(&self, i: u32) -> Vec3 {
        let [a, b, c] = self.vertices(i);
        triangle_normal(a, b, c)
    }

    #[inline]
    /// The material of a triangle.
    pub fn material(&self, tri: u32) -> &Material {
        &self.materials[crate::cost::read!(self.material_of, tri as usize) as usize]
    }

    /// What scatters at triangle `tri` for outgoing direction `wo_local` (in the frame
    /// whose `+z` is the winding normal): its material, or black when the material is
    /// one-sided and `wo` lies behind it.
    #[inline]
    pub fn bsdf(&self, tri: u32, wo_local: Vec3) -> &Material {
        self.bsdf_facing(tri, wo_local.z)
    }

    /// [`Scene::bsdf`] from the cosine of the outgoing direction with the triangle's
    /// normal alone.
    #[inline]
    pub fn bsdf_facing(&self, tri: u32, cos_o: f32) -> &Material {
        const BLACK: Material = Material::Diffuse { albedo: Vec3::ZERO };
        use crate::cost::read;
        let m = read!(self.material_of, tri as usize) as usize;
        if cos_o < 0.0 && !read!(self.two_sided, m) && !self.materials[m].is_dielectric() {
            &BLACK
        } else {
            &self.materials[m]
        }
    }

    /// Appends a material (two-sided) and returns its index.
    pub fn add_material(&mut self, name: impl Into<String>, material: Material, emission: Vec3) -> u32 {
        self.materials.push(material);
        self.material_names.push(name.into());
        self.emission.push(emission);
        self.two_sided.push(true);
        self.materials.len() as u32 - 1
    }

    #[inline]
    /// Radiance a triangle emits from its front face.
    pub fn emission_of(&self, tri: u32) -> Vec3 {
        use crate::cost::read;
        read!(self.emission, read!(self.material_of, tri as usize) as usize)
    }

    /// The box around every vertex.
    pub fn bounds(&self) -> Aabb {
        self.triangles.iter().flat_map(|t| t.iter().map(|&i| self.positions[i as usize])).fold(Aabb::EMPTY, Aabb::grow)
    }

    /// Bytes held by the scene's arrays (what the memory tables count as "scene").
    pub fn memory_bytes(&self) -> usize {
        use std::mem::size_of;
        self.positions.len() * size_of::<Vec3>()
            + self.triangles.len() * size_of::<[u32; 3]>()
            + self.material_of.len() * size_of::<u32>()
            + self.materials.len() * size_of::<Material>()
            + self.emission.len() * size_of::<Vec3>()
            + self.two_sided.len()
            + self.material_names.iter().map(|n| n.len()).sum::<usize>()
            + self.point_lights.len() * size_of::<PointLight>()
    }

    /// Whether anything emits: a point light of positive intensity, or an emissive
    /// triangle of positive area (a degenerate emitter cannot be sampled, so a scene
    /// lit only by those would render black).
    pub fn has_emitters(&self) -> bool {
        self.point_lights.iter().any(|l| l.intensity.max_element() > 0.0)
            || (0..self.triangle_count() as u32).any(|tri| self.area_emitter(tri).is_some())
    }

    /// A triangle that is an area light: its (unnormalised) winding normal and its
    /// area, when it emits and its area is positive and finite. The one rule for what
    /// the lights are ([`crate::lights::Lights::new`]) and for whether a scene has any.
    pub fn area_emitter(&self, tri: u32) -> Option<(Vec3, f32)> {
        if self.emission_of(tri).max_element() <= 0.0 {
            return None;
        }
        let [a, b, c] = self.vertices(tri);
        let n = crate::geometry::triangle_normal(a, b, c);
        let area = 0.5 * n.length();
        (area > 0.0 && area.is_finite()).then_some((n, area))
    }

    /// Checks what every caster needs: at least one triangle, finite coordinates, indices
    /// in range, a material per triangle. Loaders call this; so should code that builds
    /// a scene by hand.
    pub fn validate(&self) -> Result<()> {
        let at = || Location::file(&self.source);
        if self.triangles.is_empty() {
            return Err(Error::EmptyMesh { at: at() });
        }
        if self.material_of.len() != self.triangles.len() {
            return Err(Error::SceneFile { at: at(), msg: "one material index per triangle is required".into() });
        }
        let n = self.materials.len();
        if self.material_names.len() != n || self.emission.len() != n || self.two_sided.len() != n {
            return Err(Error::SceneFile { at: at(), msg: "material table arrays differ in length".into() });
        }
        let nv = self.positions.len() as u32;
        if let Some((i, t)) = self.triangles.iter().enumerate().find(|(_, t)| t.iter().any(|&v| v >= nv)) {
            return Err(Error::IndexOutOfRange {
                at: at(),
                msg: format!("triangle {i} uses vertex {:?} but there are {nv} vertices", t),
            });
        }
        if let Some(i) = self.material_of.iter().position(|&m| m as usize >= self.materials.len()) {
            return Err(Error::IndexOutOfRange { at: at(), msg: format!("triangle {i} names a missing material") });
        }
        if let Some(i) = self.positions.iter().position(|p| !p.is_finite()) {
            return Err(Error::NonFinite { at: at(), what: format!("vertex {}", i + 1) });
        }
        for (i, m) in self.materials.iter().enumerate() {
            m.validate().map_err(|msg| Error::SceneFile {
                at: at(),
                msg: format!("material '{}': {msg}", self.material_names[i]),
            })?;
            if !self.emission[i].is_finite() || self.emission[i].min_element() < 0.0 {
                return Err(Error::NonFinite { at: at(), what: format!("emission of '{}'", self.material_names[i]) });
            }
        }
        for l in &self.point_lights {
            if !l.position.is_finite() || !l.intensity.is_finite() {
                return Err(Error::NonFinite { at: at(), what: "point light".into() });
            }
        }
        self.camera.validate().map_err(|msg| Error::SceneFile { at: at(), msg })?;
        Ok(())
    }

    /// What rendering needs beyond [`Scene::validate`]: something that emits light.
    pub fn check_renderable(&self) -> Result<()> {
        self.validate()?;
        if !self.has_emitters() {
            return Err(Error::NoEmitters { at: Location::file(&self.source) });
        }
        Ok(())
    }

    /// Appends another scene's triangles and materials (its camera and source are
    /// dropped). Used by scene files that name several meshes.
    pub fn append(&mut self, other: Scene) {
        let v0 = self.positions.len() as u32;
        let m0 = self.materials.len() as u32;
        self.positions.extend(other.positions);
        self.triangles.extend(other.triangles.iter().map(|t| t.map(|i| i + v0)));
        self.material_of.extend(other.material_of.iter().map(|m| m + m0));
        self.materials.extend(other.materials);
        self.material_names.extend(other.material_names);
        self.emission.extend(other.emission);
        self.two_sided.extend(other.two_sided);
        self.point_lights.extend(other.point_lights);
    }

    /// An empty scene whose errors name `source`.
    pub fn empty(source: impl AsRef<Path>) -> Scene {
        Scene {
            positions: Vec::new(),
            triangles: Vec::new(),
            material_of: Vec::new(),
            materials: Vec::new(),
            material_names: Vec::new(),
            emission: Vec::new(),
            two_sided: Vec::new(),
            point_lights: Vec::new(),
            camera: Camera::default(),
            source: source.as_ref().to_path_buf(),
        }
    }

    /// Points the camera at the whole scene from the front (+z), as a fallback for
    /// plain OBJ files that carry no camera.
    pub fn frame_camera(&mut self) {
        let b = self.bounds();
        let c = b.center();
        let r = (b.extent().length() * 0.5).max(1e-6);
        let fov = 40.0f32;
        let dist = r / (fov.to_radians() * 0.5).sin();
        self.camera = Camera::look_at(c + Vec3::new(0.0, 0.0, dist), c, Vec3::Y, fov);
    }
}

/// The folder that holds the standard models: `$WARPRAY_MODELS`, or `assets/models`.
pub fn models_dir() -> PathBuf {
    std::env::var_os("WARPRAY_MODELS").map(PathBuf::from).unwrap_or_else(|| PathBuf::from("assets/models"))
}

/// Path of a standard model by stem (`"bunny"` → `$WARPRAY_MODELS/bunny.obj.gz`), if present.
pub fn find_model(stem: &str) -> Option<PathBuf> {
    let dir = models_dir();
    [".obj.gz", ".obj"].iter().map(|ext| dir.join(format!("{stem}{ext}"))).find(|p| p.is_file())
}
