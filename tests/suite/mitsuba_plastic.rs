//! warpray's `Material::Plastic` against Mitsuba 3's own `plastic` and `roughplastic`,
//! evaluated by Mitsuba at fixed direction pairs (`tests/data/mitsuba/plastic_values.json`,
//! made by `docs/reproduce/mitsuba_plastic_values.py`): the BSDF value times the
//! sampled direction's cosine (Mitsuba's `eval`), the density, and for the smooth
//! plastic the probability and weight of its specular sample. The smooth model is the
//! same closed form, so it must agree to float rounding; the rough one tabulates its
//! coat's transmittance by quadrature as Mitsuba does but maps the quadrature square
//! to normals with warpray's own sampler, so it agrees to the quadrature's error.
//! Whole images against Mitsuba's are in `mitsuba_bsdfs.rs`.

use std::path::Path;
use warpray::bsdf::TransportMode;
use warpray::glam::{Vec2, Vec3};
use warpray::scene::{Material, Plastic};

/// Mitsuba's index of air, its default `ext_ior`.
const AIR: f64 = 1.000277;

fn vec3(v: &serde_json::Value) -> Vec3 {
    let a: Vec<f32> = v.as_array().unwrap().iter().map(|x| x.as_f64().unwrap() as f32).collect();
    Vec3::new(a[0], a[1], a[2])
}

/// The plastic a Mitsuba plugin dictionary describes (its defaults where it is silent).
fn plastic(spec: &serde_json::Value) -> Material {
    let colour = |key: &str, default: f32| spec.get(key).map_or(Vec3::splat(default), |c| vec3(&c["value"]));
    let eta = spec.get("int_ior").map_or(1.49, |v| v.as_f64().unwrap()) / AIR;
    let roughness = spec.get("alpha").map_or(0.0, |v| v.as_f64().unwrap() as f32);
    let nonlinear = spec.get("nonlinear").is_some_and(|v| v.as_bool().unwrap());
    Material::Plastic(Plastic::new(
        colour("diffuse_reflectance", 0.5),
        colour("specular_reflectance", 1.0),
        eta as f32,
        roughness,
        nonlinear,
    ))
}

/// Worst relative difference of warpray's values from Mitsuba's over every pair of one
/// material (a floor of 1e-4 absolute for values near zero).
fn worst_difference(name: &str, m: &serde_json::Value) -> f32 {
    let material = plastic(&m["spec"]);
    let rel = |a: f32, b: f32| (a - b).abs() / b.abs().max(1e-4);
    let mut worst = 0.0f32;
    for pair in m["pairs"].as_array().unwrap() {
        let (wo, wi) = (vec3(&pair["wo"]).normalize(), vec3(&pair["wi"]).normalize());
        let eval = material.f(wo, wi, TransportMode::Radiance) * wi.z;
        let want = vec3(&pair["eval"]);
        for c in 0..3 {
            worst = worst.max(rel(eval[c], want[c]));
        }
        worst = worst.max(rel(material.pdf(wo, wi), pair["pdf"].as_f64().unwrap() as f32));
        if let Some(p) = pair.get("specular_pdf") {
            // u_lobe = 0 picks the specular lobe, as Mitsuba's sample1 = 0 does.
            let s = material.sample_f(wo, 0.0, Vec2::splat(0.5), TransportMode::Radiance).unwrap();
            assert!(s.delta, "{name}: u_lobe 0 did not pick the specular lobe");
            worst = worst.max(rel(s.pdf, p.as_f64().unwrap() as f32));
            let want = vec3(&pair["specular_weight"]);
            for c in 0..3 {
                worst = worst.max(rel(s.weight[c], want[c]));
            }
        }
    }
    worst
}

fn values() -> serde_json::Value {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/mitsuba/plastic_values.json");
    let text = std::fs::read_to_string(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    serde_json::from_str(&text).unwrap()
}

#[test]
fn smooth_plastic_is_mitsubas_to_rounding() {
    let v = values();
    for name in ["plastic", "plastic-nonlinear"] {
        let worst = worst_difference(name, &v["materials"][name]);
        assert!(worst < 2e-5, "{name}: {worst:.2e} from Mitsuba's values");
    }
}

#[test]
fn rough_plastic_is_mitsubas_to_the_quadrature() {
    let v = values();
    for name in ["roughplastic", "roughplastic-wide"] {
        let worst = worst_difference(name, &v["materials"][name]);
        eprintln!("{name}: worst relative difference {worst:.2e}");
        assert!(worst < 2e-3, "{name}: {worst:.2e} from Mitsuba's values");
    }
}
