//! The material table and how Wavefront MTL entries map onto it.
//!
//! | MTL                                  | warpray material                               |
//! |--------------------------------------|------------------------------------------------|
//! | `illum 5`                            | [`Material::Mirror`], reflectance `Ks` (1 if absent) |
//! | `illum 7`, or `d < 1` (dissolve)     | [`Material::Glass`], index `Ni` (1.5 if absent), tint `Tf` (white if absent) |
//! | `Ks` non-zero (any other `illum`)    | [`Material::Glossy`]: Lambertian `Kd` plus a GGX lobe of reflectance `Ks`, roughness α = √(2/(Ns+2)) |
//! | otherwise                            | [`Material::Diffuse`] with albedo `Kd` (0.8 grey if absent) |
//! | `Ke` (any of the above)              | emitted radiance from the front face           |
//!
//! The Ns → α conversion equates the Blinn–Phong exponent with a microfacet
//! distribution of the same width (Walter et al. 2007, eq. 35 with α_b² = 2/(Ns+2)).
//! Where `Kd + Ks` exceeds 1 in a channel both are scaled down so the surface never
//! reflects more than it receives. `Ka`, textures and `Ni` of opaque materials are ignored.

pub use crate::bsdf::layered::{Coat, LayerBase, Layered};
pub use crate::bsdf::plastic::Plastic;
use glam::Vec3;

/// Complex refractive indices (η, k) at roughly 650, 550 and 450 nm of common metals
/// (tabulated optical constants, as renderers usually ship them).
pub mod metals {
    use glam::Vec3;
    /// Gold.
    pub const GOLD: (Vec3, Vec3) = (Vec3::new(0.143, 0.374, 1.442), Vec3::new(3.983, 2.385, 1.603));
    /// Copper.
    pub const COPPER: (Vec3, Vec3) = (Vec3::new(0.200, 0.924, 1.102), Vec3::new(3.912, 2.452, 2.142));
    /// Silver.
    pub const SILVER: (Vec3, Vec3) = (Vec3::new(0.155, 0.117, 0.138), Vec3::new(4.828, 3.122, 2.147));
    /// Aluminium.
    pub const ALUMINIUM: (Vec3, Vec3) = (Vec3::new(1.657, 0.880, 0.521), Vec3::new(9.224, 6.270, 4.837));

    /// By name (`gold`, `copper`, `silver`, `aluminium`/`aluminum`).
    pub fn by_name(name: &str) -> Option<(Vec3, Vec3)> {
        match name {
            "gold" => Some(GOLD),
            "copper" => Some(COPPER),
            "silver" => Some(SILVER),
            "aluminium" | "aluminum" => Some(ALUMINIUM),
            _ => None,
        }
    }
}

#[derive(Clone, Copy, Debug, PartialEq)]
/// What a surface does with light.
pub enum Material {
    /// Lambertian reflector.
    Diffuse {
        /// Reflectance.
        albedo: Vec3,
    },
    /// Lambertian base plus a GGX specular lobe (no Fresnel: `specular` is the lobe's
    /// reflectance at all angles, as in the MTL model it comes from).
    Glossy {
        /// Lambertian reflectance.
        diffuse: Vec3,
        /// Reflectance of the GGX lobe.
        specular: Vec3,
        /// GGX α of the lobe.
        roughness: f32,
    },
    /// Perfect specular reflector.
    Mirror {
        /// Reflectance.
        reflectance: Vec3,
    },
    /// Smooth dielectric interface with Fresnel reflection and refraction.
    Glass {
        /// Index of refraction.
        ior: f32,
        /// Transmission colour.
        tint: Vec3,
    },
    /// Conductor with complex index `eta + i k`: GGX of roughness α, smooth below 1e-3.
    Conductor {
        /// Real part of the refractive index.
        eta: Vec3,
        /// Imaginary part (absorption).
        k: Vec3,
        /// GGX α (below 1e-3: a smooth mirror).
        roughness: f32,
    },
    /// Rough dielectric interface (GGX reflection and transmission, Walter et al. 2007).
    RoughGlass {
        /// Index of refraction.
        ior: f32,
        /// GGX α.
        roughness: f32,
        /// Transmission colour.
        tint: Vec3,
    },
    /// One or two dielectric coats over a diffuse or conductor base (see
    /// [`crate::bsdf::layered`] for the model and its energy behaviour).
    Layered(Layered),
    /// Mitsuba 3's `plastic` and `roughplastic`: a Lambertian base under a smooth or
    /// GGX coat, internal reflections in closed form ([`crate::bsdf::plastic`]). Scenes
    /// from Mitsuba XML use it, so that they render as Mitsuba renders them.
    Plastic(Plastic),
}

/// The kinds of [`Material`], in the order of their typed index ([`MaterialKind::index`]):
/// the branch arm a shading kernel's lane takes, for the emulator's SIMD accounting.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum MaterialKind {
    /// [`Material::Diffuse`].
    Diffuse,
    /// [`Material::Glossy`].
    Glossy,
    /// [`Material::Mirror`].
    Mirror,
    /// [`Material::Glass`].
    Glass,
    /// [`Material::Conductor`].
    Conductor,
    /// [`Material::RoughGlass`].
    RoughGlass,
    /// [`Material::Layered`].
    Layered,
    /// [`Material::Plastic`].
    Plastic,
}

impl MaterialKind {
    /// The kind's index, 0 to 7.
    pub fn index(self) -> usize {
        self as usize
    }

    /// Its short name.
    pub fn name(self) -> &'static str {
        match self {
            MaterialKind::Diffuse => "diffuse",
            MaterialKind::Glossy => "glossy",
            MaterialKind::Mirror => "mirror",
            MaterialKind::Glass => "glass",
            MaterialKind::Conductor => "conductor",
            MaterialKind::RoughGlass => "roughglass",
            MaterialKind::Layered => "layered",
            MaterialKind::Plastic => "plastic",
        }
    }
}

impl Material {
    /// What surfaces without a material get: 0.8 grey Lambertian.
    pub const DEFAULT: Material = Material::Diffuse { albedo: Vec3::splat(0.8) };

    /// Its kind: the branch a shading kernel takes for it.
    pub fn kind(&self) -> MaterialKind {
        match self {
            Material::Diffuse { .. } => MaterialKind::Diffuse,
            Material::Glossy { .. } => MaterialKind::Glossy,
            Material::Mirror { .. } => MaterialKind::Mirror,
            Material::Glass { .. } => MaterialKind::Glass,
            Material::Conductor { .. } => MaterialKind::Conductor,
            Material::RoughGlass { .. } => MaterialKind::RoughGlass,
            Material::Layered(_) => MaterialKind::Layered,
            Material::Plastic(_) => MaterialKind::Plastic,
        }
    }

    /// Short kind name, for statistics and the inspector's material queues.
    pub fn kind_name(&self) -> &'static str {
        self.kind().name()
    }

    /// Checks every number (finite and in range).
    pub fn validate(&self) -> Result<(), String> {
        let colour_ok = |c: Vec3| c.is_finite() && c.min_element() >= 0.0 && c.max_element() <= 1.0;
        match *self {
            Material::Diffuse { albedo } if !colour_ok(albedo) => Err("albedo must lie in [0, 1]".into()),
            Material::Glossy { diffuse, specular, roughness } => {
                if !colour_ok(diffuse) || !colour_ok(specular) || !colour_ok(diffuse + specular) {
                    Err("diffuse, specular and their sum must lie in [0, 1]".into())
                } else if !(roughness > 0.0 && roughness <= 1.0) {
                    Err(format!("roughness {roughness} must lie in (0, 1]"))
                } else {
                    Ok(())
                }
            }
            Material::Mirror { reflectance } if !colour_ok(reflectance) => Err("reflectance must lie in [0, 1]".into()),
            Material::Glass { ior, tint } | Material::RoughGlass { ior, tint, .. } => {
                if !(ior.is_finite() && ior > 0.0) {
                    Err(format!("index of refraction {ior} must be positive"))
                } else if !colour_ok(tint) {
                    Err("glass tint must lie in [0, 1]".into())
                } else {
                    roughness_ok(self)
                }
            }
            Material::Conductor { eta, k, .. } => {
                if !(eta.is_finite() && k.is_finite() && eta.min_element() > 0.0 && k.min_element() >= 0.0) {
                    Err("conductor eta must be positive and k non-negative".into())
                } else {
                    roughness_ok(self)
                }
            }
            Material::Layered(l) => {
                if l.coat_count == 0 || l.coat_count > 2 {
                    return Err("a layered material has one or two coats".into());
                }
                for c in l.coats() {
                    if !(c.ior.is_finite() && c.ior > 0.0 && (0.0..=1.0).contains(&c.roughness)) {
                        return Err("coat ior must be positive and roughness in [0, 1]".into());
                    }
                    if !(c.absorption.is_finite() && c.absorption.min_element() >= 0.0) {
                        return Err("coat absorption must be finite and non-negative".into());
                    }
                }
                match l.base {
                    LayerBase::Diffuse { albedo } if !colour_ok(albedo) => Err("base albedo must lie in [0, 1]".into()),
                    LayerBase::Conductor { roughness, .. } if !(0.0..=1.0).contains(&roughness) => {
                        Err("base roughness must lie in [0, 1]".into())
                    }
                    _ => Ok(()),
                }
            }
            Material::Plastic(p) => {
                if !colour_ok(p.diffuse) || !colour_ok(p.specular) {
                    Err("plastic diffuse and specular reflectance must lie in [0, 1]".into())
                } else if !(p.eta.is_finite() && p.eta > 0.0 && p.eta != 1.0) {
                    Err(format!("plastic relative index {} must be positive and differ from 1", p.eta))
                } else if !(0.0..=1.0).contains(&p.roughness) {
                    Err(format!("plastic roughness {} must lie in [0, 1] (0: smooth)", p.roughness))
                } else {
                    Ok(())
                }
            }
            _ => Ok(()),
        }
    }

    /// Maps one MTL entry (see the module table). Returns the material and its emission.
    pub fn from_mtl(m: &tobj::Material) -> (Material, Vec3) {
        let v = |c: Option<[f32; 3]>| c.map(Vec3::from_array);
        let kd = v(m.diffuse).unwrap_or(Vec3::splat(0.8)).clamp(Vec3::ZERO, Vec3::ONE);
        let ks = v(m.specular).unwrap_or(Vec3::ZERO).clamp(Vec3::ZERO, Vec3::ONE);
        let ke = v(m.emissive).or_else(|| parse_vec3(m.unknown_param.get("Ke"))).unwrap_or(Vec3::ZERO);
        let illum = m.illumination_model.unwrap_or(2);
        let dissolve = m.dissolve.unwrap_or(1.0);
        let tf = parse_vec3(m.unknown_param.get("Tf")).unwrap_or(Vec3::ONE).clamp(Vec3::ZERO, Vec3::ONE);
        let material = if illum == 5 {
            Material::Mirror { reflectance: if ks.max_element() > 0.0 { ks } else { Vec3::ONE } }
        } else if illum == 7 || dissolve < 1.0 {
            Material::Glass { ior: m.optical_density.filter(|n| *n > 0.0).unwrap_or(1.5), tint: tf }
        } else if ks.max_element() > 0.0 {
            let ns = m.shininess.unwrap_or(10.0).max(0.0);
            let roughness = (2.0 / (ns + 2.0)).sqrt().clamp(1e-3, 1.0);
            // Keep kd + ks <= 1 per channel.
            let scale = 1.0 / (kd + ks).max_element().max(1.0);
            Material::Glossy { diffuse: kd * scale, specular: ks * scale, roughness }
        } else {
            Material::Diffuse { albedo: kd }
        };
        (material, ke.max(Vec3::ZERO))
    }
}

fn roughness_ok(m: &Material) -> Result<(), String> {
    match *m {
        Material::Conductor { roughness, .. } | Material::RoughGlass { roughness, .. }
            if !(0.0..=1.0).contains(&roughness) =>
        {
            Err(format!("roughness {roughness} must lie in [0, 1] (0: smooth)"))
        }
        _ => Ok(()),
    }
}

fn parse_vec3(s: Option<&String>) -> Option<Vec3> {
    let mut it = s?.split_whitespace().map(|w| w.parse::<f32>());
    let x = it.next()?.ok()?;
    let y = it.next().and_then(|r| r.ok()).unwrap_or(x);
    let z = it.next().and_then(|r| r.ok()).unwrap_or(x);
    Some(Vec3::new(x, y, z))
}
