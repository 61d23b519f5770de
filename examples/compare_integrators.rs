//! Renders one scene with every integrator at the same sample count and prints the
//! image means and the relative MSE between each pair: a quick consistency check.
//! `cargo run --release --example compare_integrators -- [SCENE] [SPP] [SIZE]`
use warpray::prelude::*;
use warpray::render::IntegratorKind;
fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let scene = load_scene(args.first().map(String::as_str).unwrap_or("cornell")).unwrap().scene;
    let spp: u32 = args.get(1).and_then(|s| s.parse().ok()).unwrap_or(64);
    let size: u32 = args.get(2).and_then(|s| s.parse().ok()).unwrap_or(64);
    let caster = BvhCaster::new(&scene);
    let mut images = Vec::new();
    for kind in IntegratorKind::ALL {
        let opts = RenderOptions {
            width: size,
            height: size,
            budget: Budget::Samples(spp),
            integrator: kind,
            max_depth: 8,
            ..Default::default()
        };
        let (film, stats) = render(&scene, &caster, &opts, |_, _| true).unwrap();
        println!(
            "{:>6}: mean {:?} ({:.2} s, rejected {})",
            kind.name(),
            film.image_mean(),
            stats.seconds,
            film.rejected
        );
        images.push((kind, film.mean()));
    }
    for i in 0..images.len() {
        for j in i + 1..images.len() {
            let (a, b) = (&images[i].1, &images[j].1);
            let rel: f64 = a
                .iter()
                .zip(b)
                .map(|(x, y)| {
                    let d = (*x - *y).length_squared() as f64;
                    d / ((*y).length_squared() as f64 + 1e-2)
                })
                .sum::<f64>()
                / a.len() as f64;
            println!("relMSE {} vs {}: {rel:.4}", images[i].0.name(), images[j].0.name());
        }
    }
}
