//! Renders one scene with every integrator at the same sample count and prints the
//! image means and the relative MSE between each pair: a quick consistency check.
//! `cargo run --release --example compare_integrators -- [SCENE] [SPP] [SIZE]`
use clap::Parser;
use std::path::PathBuf;
use std::process::ExitCode;
use warpray::prelude::*;
use warpray::render::IntegratorKind;

#[derive(Parser)]
#[command(about = "Every integrator on one scene: image means and relMSE between each pair")]
struct Args {
    /// Scene, as for `warpray render`.
    #[arg(default_value = "cornell")]
    scene: PathBuf,
    /// Samples per pixel.
    #[arg(default_value_t = 64, value_parser = clap::value_parser!(u32).range(1..=65536))]
    spp: u32,
    /// Image width and height.
    #[arg(default_value_t = 64, value_parser = clap::value_parser!(u32).range(1..=4096))]
    size: u32,
}

fn main() -> ExitCode {
    match run(Args::parse()) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e}");
            ExitCode::FAILURE
        }
    }
}

fn run(args: Args) -> Result<()> {
    let (spp, size) = (args.spp, args.size);
    let scene = load_scene(&args.scene)?.scene;
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
        let (film, stats) = render(&scene, &caster, &opts, |_, _| true)?;
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
    Ok(())
}
