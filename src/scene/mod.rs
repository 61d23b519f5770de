//! The scene model: flat arrays of triangles, one material index per triangle, a
//! material table with per-material emission, point lights and a camera. Nothing else:
//! no scene graph, no per-vertex attribute that nothing reads (vertex normals and
//! texture coordinates in OBJ files are ignored; shading uses geometric normals).

mod camera;
mod cornell;
mod data;
mod desc;
mod file;
pub mod input;
mod load;
mod material;
mod mitsuba;
mod obj;
mod ply;

pub use camera::{Camera, Projection};
pub use cornell::cornell_box;
pub use data::{PointLight, Scene, find_model, models_dir};
pub use desc::{RenderSettings, SceneDesc};
pub use file::parse_scene_file;
pub use load::{NAMED_SCENES, load_scene};
pub use material::{Coat, LayerBase, Layered, Material, MaterialKind, Plastic, metals};
pub use mitsuba::parse_mitsuba;
pub use obj::{ObjOptions, load_obj};
