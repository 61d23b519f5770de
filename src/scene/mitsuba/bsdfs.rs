//! Mitsuba BSDF plugins as warpray materials (the table in docs/scene-format.md):
//! `diffuse`, `conductor`/`roughconductor` (named metals or η, k), `dielectric`/
//! `roughdielectric`, `plastic`/`roughplastic` (Mitsuba's own model, `bsdf::plastic`)
//! and the `twosided` wrapper. Rough lobes must say `distribution="ggx"`:
//! warpray has no Beckmann lobe, and quietly swapping one for the other would change
//! the image.

use super::xml::{Props, is_property};
use super::{Bsdf, Builder};
use crate::error::Result;
use crate::scene::material::{Material, Plastic, metals};
use glam::Vec3;
use roxmltree::Node;

/// Mitsuba's index of air, its default `ext_ior`.
const AIR: f64 = 1.000277;

/// Refractive indices Mitsuba accepts by name (its `int_ior`/`ext_ior` table).
const IORS: &[(&str, f64)] = &[
    ("vacuum", 1.0),
    ("helium", 1.00004),
    ("hydrogen", 1.00013),
    ("air", AIR),
    ("carbon dioxide", 1.00045),
    ("water", 1.3330),
    ("acetone", 1.36),
    ("ethanol", 1.361),
    ("carbon tetrachloride", 1.461),
    ("glycerol", 1.4729),
    ("benzene", 1.501),
    ("silicone oil", 1.52045),
    ("bromine", 1.661),
    ("water ice", 1.31),
    ("fused quartz", 1.458),
    ("pyrex", 1.470),
    ("acrylic glass", 1.49),
    ("polypropylene", 1.49),
    ("bk7", 1.5046),
    ("sodium chloride", 1.544),
    ("amber", 1.55),
    ("pet", 1.575),
    ("diamond", 2.419),
];

impl Builder<'_, '_> {
    pub(super) fn ior(&self, p: &mut Props, node: Node, name: &str, default: f64) -> Result<f64> {
        match p.number_or_name(name)? {
            None => Ok(default),
            Some(Ok(v)) if v > 0.0 => Ok(v),
            Some(Ok(v)) => Err(self.doc.err(node, format!("{name} {v} must be positive"))),
            Some(Err(s)) => IORS.iter().find(|(n, _)| n.eq_ignore_ascii_case(&s)).map(|(_, v)| *v).ok_or_else(|| {
                self.doc.err(node, format!("{name}: unknown material '{s}' (give a number, or one of {})", names(IORS)))
            }),
        }
    }

    /// GGX roughness of a rough plugin: `alpha` (or equal `alpha_u`/`alpha_v`).
    pub(super) fn roughness(&self, p: &mut Props, node: Node) -> Result<f32> {
        let dist = p.text("distribution")?.unwrap_or_else(|| "beckmann".into());
        if dist != "ggx" {
            return Err(self.doc.err(
                node,
                format!("distribution '{dist}' (Mitsuba's default is beckmann) is not supported: warpray's rough lobes are GGX; set <string name=\"distribution\" value=\"ggx\"/>"),
            ));
        }
        let alpha = match (p.number("alpha")?, p.number("alpha_u")?, p.number("alpha_v")?) {
            (Some(a), None, None) => a,
            (None, Some(u), Some(v)) if u == v => u,
            (None, None, None) => 0.1,
            _ => return Err(self.doc.err(node, "anisotropic roughness is not supported")),
        };
        if !(0.0..=1.0).contains(&alpha) {
            return Err(self.doc.err(node, format!("alpha {alpha} must lie in [0, 1]")));
        }
        p.ignore(&["sample_visible"]);
        Ok(alpha as f32)
    }

    pub(super) fn bsdf(&self, node: Node) -> Result<Bsdf> {
        let doc = self.doc;
        let kind = doc.need(node, "type")?;
        let nested: Vec<Node> = node.children().filter(|c| c.is_element() && !is_property(*c)).collect();
        if kind == "twosided" {
            let [inner] = nested.as_slice() else {
                return Err(
                    doc.err(node, "twosided takes exactly one nested <bsdf> (different sides are not supported)")
                );
            };
            let b = match inner.tag_name().name() {
                // One level only: a twosided inside a twosided means nothing more, and
                // refusing it keeps the parse from recursing once per nesting level
                // (30,000 of them overflowed the stack).
                "bsdf" if inner.attribute("type") == Some("twosided") => {
                    return Err(doc.err(*inner, "a twosided <bsdf> inside a twosided <bsdf> (one is enough)"));
                }
                "bsdf" => self.bsdf(*inner)?,
                "ref" => self.reference(*inner)?,
                _ => return Err(doc.err(*inner, "expected a <bsdf> or <ref>")),
            };
            Props::of(doc, node)?.finish()?;
            return Ok(Bsdf { two_sided: true, ..b });
        }
        if let Some(c) = nested.iter().find(|c| c.tag_name().name() != "texture") {
            return Err(doc.err(*c, "not supported inside this <bsdf>"));
        }
        let mut p = Props::of(doc, node)?;
        let material = match kind.as_str() {
            "diffuse" => Material::Diffuse { albedo: p.color_or("reflectance", Vec3::splat(0.5))? },
            "conductor" | "roughconductor" => {
                let roughness = if kind == "roughconductor" { self.roughness(&mut p, node)? } else { 0.0 };
                let specular = p.color_or("specular_reflectance", Vec3::ONE)?;
                let (eta, k) = (p.color_or("eta", Vec3::NAN)?, p.color_or("k", Vec3::NAN)?);
                let name = p.text("material")?;
                let (eta, k) = if eta.is_finite() || k.is_finite() {
                    if !(eta.is_finite() && k.is_finite()) || name.is_some() {
                        return Err(doc.err(node, "give both eta and k, or a material name"));
                    }
                    (eta, k)
                } else {
                    match name.as_deref().unwrap_or("none") {
                        "none" if roughness == 0.0 => {
                            p.finish()?;
                            return Ok(Bsdf { material: Material::Mirror { reflectance: specular }, two_sided: false });
                        }
                        "Au" => metals::GOLD,
                        "Cu" => metals::COPPER,
                        "Ag" => metals::SILVER,
                        "Al" => metals::ALUMINIUM,
                        other => {
                            return Err(doc.err(node, format!("conductor material '{other}': supported are Au, Cu, Ag, Al, none (smooth only), or eta and k")));
                        }
                    }
                };
                if specular != Vec3::ONE {
                    return Err(
                        doc.err(node, "specular_reflectance other than 1 is not supported for Fresnel conductors")
                    );
                }
                Material::Conductor { eta, k, roughness }
            }
            "dielectric" | "roughdielectric" => {
                let roughness = if kind == "roughdielectric" { Some(self.roughness(&mut p, node)?) } else { None };
                let ior = self.ior(&mut p, node, "int_ior", 1.5046)? / self.ior(&mut p, node, "ext_ior", AIR)?;
                if p.color_or("specular_reflectance", Vec3::ONE)? != Vec3::ONE {
                    return Err(doc.err(node, "specular_reflectance other than 1 is not supported for dielectrics"));
                }
                let tint = p.color_or("specular_transmittance", Vec3::ONE)?;
                match roughness {
                    None => Material::Glass { ior: ior as f32, tint },
                    Some(r) => Material::RoughGlass { ior: ior as f32, roughness: r, tint },
                }
            }
            "plastic" | "roughplastic" => {
                let roughness = if kind == "roughplastic" { self.roughness(&mut p, node)? } else { 0.0 };
                let (int_ior, ext_ior) =
                    (self.ior(&mut p, node, "int_ior", 1.49)?, self.ior(&mut p, node, "ext_ior", AIR)?);
                if int_ior == ext_ior {
                    return Err(doc.err(
                        node,
                        format!("int_ior and ext_ior are both {int_ior}: a plastic's coat needs two different indices"),
                    ));
                }
                let diffuse = p.color_or("diffuse_reflectance", Vec3::splat(0.5))?;
                let specular = p.color_or("specular_reflectance", Vec3::ONE)?;
                let nonlinear = p.bool_or("nonlinear", false)?;
                Material::Plastic(Plastic::new(diffuse, specular, (int_ior / ext_ior) as f32, roughness, nonlinear))
            }
            _ => return Err(doc.err(node, "BSDF not supported (see docs/scene-format.md)")),
        };
        p.finish()?;
        material.validate().map_err(|m| doc.err(node, m))?;
        Ok(Bsdf { material, two_sided: false })
    }

    pub(super) fn reference(&self, node: Node) -> Result<Bsdf> {
        let id = self.doc.need(node, "id")?;
        self.ids.get(&id).map(|(b, _)| *b).ok_or_else(|| self.doc.err(node, format!("no <bsdf id=\"{id}\"> defined")))
    }
}

fn names(table: &[(&str, f64)]) -> String {
    table.iter().map(|(n, _)| *n).collect::<Vec<_>>().join(", ")
}
