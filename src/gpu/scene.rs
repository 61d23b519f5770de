//! The scene as the CUDA twins read it (`cuda/cis_api.h`): the triangles, materials,
//! lights, camera and options flattened into `#[repr(C)]` records, owned here while a
//! library call copies them. The shading twin ([`super::GpuCis`]) and the whole GPU
//! renders ([`super::GpuRender`]) both send it.

use crate::bsdf::layered::LayerBase;
use crate::error::{Error, Result};
use crate::lights::{Light, Lights};
use crate::render::RenderOptions;
use crate::render::bidir::Vertex;
use crate::render::cis::kernels::{PendingData, Slot};
use crate::scene::{Material, Scene};
use glam::Vec3;
use std::ffi::c_void;

/// `WrMaterial` of `cuda/cis_api.h`.
#[repr(C)]
#[derive(Clone, Copy, Default)]
pub(crate) struct WrMaterial {
    kind: u32,
    coat_count: u32,
    base_kind: u32,
    roughness: f32,
    ior: f32,
    a: [f32; 3],
    b: [f32; 3],
    coat_ior: [f32; 2],
    coat_roughness: [f32; 2],
    coat_absorption: [[f32; 3]; 2],
}

/// `WrLight` of `cuda/cis_api.h`.
#[repr(C)]
#[derive(Clone, Copy, Default)]
pub(crate) struct WrLight {
    kind: u32,
    tri: u32,
    area: f32,
    normal: [f32; 3],
    value: [f32; 3],
    position: [f32; 3],
}

/// `WrCisScene` of `cuda/cis_api.h`.
#[repr(C)]
pub(crate) struct WrCisScene {
    pub(crate) tris: *const f32,
    pub(crate) material_of: *const u32,
    pub(crate) n_tris: u64,
    pub(crate) materials: *const WrMaterial,
    pub(crate) two_sided: *const u32,
    pub(crate) emission: *const f32,
    pub(crate) n_materials: u64,
    pub(crate) lights: *const WrLight,
    pub(crate) light_cdf: *const f32,
    pub(crate) light_of_tri: *const u32,
    pub(crate) n_lights: u64,
    pub(crate) cam: [[f32; 3]; 4],
    pub(crate) tan_half: f32,
    pub(crate) margin: f32,
    pub(crate) width: u32,
    pub(crate) height: u32,
    pub(crate) max_depth: u32,
    pub(crate) resampled: u32,
    pub(crate) candidates: u32,
    pub(crate) draws: u32,
    pub(crate) cache_vertices: *const c_void,
    pub(crate) n_cache_vertices: u64,
    pub(crate) cache_entries: *const u32,
    pub(crate) n_entries: u64,
    pub(crate) count_splat: f64,
    pub(crate) count_connection: f64,
}

const _: () = assert!(std::mem::size_of::<WrMaterial>() == 84);
const _: () = assert!(std::mem::size_of::<WrLight>() == 48);
const _: () = assert!(std::mem::size_of::<Vertex>() == 60);
const _: () = assert!(std::mem::size_of::<Slot>() == 88);
const _: () = assert!(std::mem::size_of::<PendingData>() == 48);

/// The twin's record of a material; `None` for one the twin has no kernel for.
fn material(m: &Material) -> Option<WrMaterial> {
    let mut w = WrMaterial::default();
    let set = |v: Vec3| v.to_array();
    match *m {
        Material::Diffuse { albedo } => w.a = set(albedo),
        Material::Glossy { diffuse, specular, roughness } => {
            (w.kind, w.a, w.b, w.roughness) = (1, set(diffuse), set(specular), roughness)
        }
        Material::Mirror { reflectance } => (w.kind, w.a) = (2, set(reflectance)),
        Material::Glass { ior, tint } => (w.kind, w.ior, w.a) = (3, ior, set(tint)),
        Material::Conductor { eta, k, roughness } => (w.kind, w.a, w.b, w.roughness) = (4, set(eta), set(k), roughness),
        Material::RoughGlass { ior, roughness, tint } => {
            (w.kind, w.ior, w.roughness, w.a) = (5, ior, roughness, set(tint))
        }
        Material::Layered(l) => {
            (w.kind, w.coat_count) = (6, l.coat_count.min(2));
            for (c, coat) in l.coats().iter().enumerate() {
                (w.coat_ior[c], w.coat_roughness[c], w.coat_absorption[c]) =
                    (coat.ior, coat.roughness, set(coat.absorption));
            }
            match l.base {
                LayerBase::Diffuse { albedo } => w.a = set(albedo),
                LayerBase::Conductor { eta, k, roughness } => {
                    (w.base_kind, w.a, w.b, w.roughness) = (1, set(eta), set(k), roughness)
                }
            }
        }
        Material::Plastic(_) => return None,
    }
    Some(w)
}

fn light(l: &Light) -> WrLight {
    match *l {
        Light::Area { tri, area, normal, radiance } => {
            WrLight { kind: 0, tri, area, normal: normal.to_array(), value: radiance.to_array(), position: [0.0; 3] }
        }
        Light::Point { position, intensity } => WrLight {
            kind: 1,
            tri: u32::MAX,
            area: 0.0,
            normal: [0.0; 3],
            value: intensity.to_array(),
            position: position.to_array(),
        },
    }
}

/// The scene's tables in the twins' layouts, kept alive for [`SceneTables::record`].
pub(crate) struct SceneTables {
    tris: Vec<[f32; 9]>,
    materials: Vec<WrMaterial>,
    two_sided: Vec<u32>,
    emission: Vec<f32>,
    lights: Vec<WrLight>,
    cdf: Vec<f32>,
    light_of_tri: Vec<u32>,
    material_of: Vec<u32>,
}

impl SceneTables {
    /// The tables of `scene`; `what` names the caller in the error for a material the
    /// twins have no kernel for.
    pub fn new(scene: &Scene, what: &str) -> Result<SceneTables> {
        let tris =
            scene.triangle_vertices().iter().map(|[a, b, c]| [a.x, a.y, a.z, b.x, b.y, b.z, c.x, c.y, c.z]).collect();
        let materials = scene.materials.iter().map(material).collect::<Option<_>>().ok_or_else(|| {
            Error::BadSetting(format!("{what} has no kernel for Mitsuba's plastic (scenes from XML)"))
        })?;
        let lights = Lights::new(scene);
        let (cdf, light_of_tri) = lights.tables();
        Ok(SceneTables {
            tris,
            materials,
            two_sided: scene.two_sided.iter().map(|&b| b as u32).collect(),
            emission: scene.emission.iter().flat_map(|e| e.to_array()).collect(),
            lights: lights.lights.iter().map(light).collect(),
            cdf: cdf.to_vec(),
            light_of_tri: light_of_tri.to_vec(),
            material_of: scene.material_of.clone(),
        })
    }

    /// The record of the scene with `scene`'s camera and `opts`' size, depth and filter
    /// reach; connections `(resampled, candidates, draws)`; no light vertex cache. Its
    /// pointers borrow `self`.
    pub fn record(
        &self,
        scene: &Scene,
        opts: &RenderOptions,
        (resampled, candidates, draws): (u32, u32, u32),
    ) -> WrCisScene {
        let cam = &scene.camera;
        WrCisScene {
            tris: self.tris.as_ptr().cast(),
            material_of: self.material_of.as_ptr(),
            n_tris: self.tris.len() as u64,
            materials: self.materials.as_ptr(),
            two_sided: self.two_sided.as_ptr(),
            emission: self.emission.as_ptr(),
            n_materials: self.materials.len() as u64,
            lights: self.lights.as_ptr(),
            light_cdf: self.cdf.as_ptr(),
            light_of_tri: self.light_of_tri.as_ptr(),
            n_lights: self.lights.len() as u64,
            cam: [cam.position, cam.forward, cam.right, cam.up].map(|v| v.to_array()),
            tan_half: cam.projection(opts.width, opts.height).tan_half,
            margin: opts.filter.margin(),
            width: opts.width,
            height: opts.height,
            max_depth: opts.max_depth,
            resampled,
            candidates,
            draws,
            cache_vertices: std::ptr::null(),
            n_cache_vertices: 0,
            cache_entries: std::ptr::null(),
            n_entries: 0,
            count_splat: 0.0,
            count_connection: 0.0,
        }
    }
}
