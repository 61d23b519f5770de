//! Directional albedos by sampling: a white Lambertian under a clear coat (index 1.5),
//! and perfect rough conductors (energy kept by single-scattering GGX).
use warpray::bsdf::TransportMode;
use warpray::glam::Vec3;
use warpray::sampling::Rng;
use warpray::scene::{Coat, LayerBase, Layered, Material};
fn albedo(m: &Material, wo: Vec3) -> f64 {
    let mut rng = Rng::for_sample(1, 2, 3);
    let n = 2_000_000;
    let mut acc = 0.0f64;
    for _ in 0..n {
        if let Some(s) = m.sample_f(wo, rng.uniform(), rng.uniform2(), TransportMode::Importance) {
            acc += s.weight.x as f64;
        }
    }
    acc / n as f64
}

fn main() {
    for alpha in [0.05f32, 0.1, 0.3, 0.6] {
        let metal = Material::Conductor { eta: Vec3::ONE, k: Vec3::splat(1000.0), roughness: alpha };
        println!("perfect conductor, alpha {alpha}: albedo at normal incidence {:.4}", albedo(&metal, Vec3::Z));
    }
    let m = Material::Layered(Layered {
        coats: [Coat { ior: 1.5, roughness: 0.0, absorption: Vec3::ZERO }; 2],
        coat_count: 1,
        base: LayerBase::Diffuse { albedo: Vec3::ONE },
    });
    for theta in [0.0f32, 45.0, 75.0] {
        let wo = Vec3::new(theta.to_radians().sin(), 0.0, theta.to_radians().cos());
        println!("clear coat over white diffuse, theta {theta}: albedo {:.3}", albedo(&m, wo));
    }
}
