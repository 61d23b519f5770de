//! Where a CIS-LBDPT render spends its time, beside LVC-BDPT on the same scene and
//! sample count: total seconds, rays cast, and the `simt` kernel table of the stream
//! (measurement off, so the times are the CPU's). The stream's launches run one after
//! another, so their seconds add up to wall time; what is left of the total is the
//! caster's batches, the light pass and host code.
//!
//! `cargo run --release --example cis_kernels -- [SCENE] [--spp 16] [--size 128]`
//! (SCENE: `cornell` or a scene file; default `cornell`).

use clap::Parser;
use std::path::PathBuf;
use std::process::ExitCode;
use std::time::Instant;
use warpray::prelude::*;
use warpray::render::Renderer;

#[derive(Parser)]
#[command(about = "CIS-LBDPT's kernel table beside LVC-BDPT on one scene")]
struct Args {
    /// Scene, as for `warpray render`.
    #[arg(default_value = "cornell")]
    scene: PathBuf,
    /// Samples per pixel.
    #[arg(long, default_value_t = 16, value_parser = clap::value_parser!(u32).range(1..=65536))]
    spp: u32,
    /// Image width and height.
    #[arg(long, default_value_t = 128, value_parser = clap::value_parser!(u32).range(1..=4096))]
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
    println!("{size}x{size}, {spp} spp, {} threads", rayon::current_num_threads());
    println!("{:<6} {:>9} {:>12}", "", "total s", "rays");
    let mut table = None;
    for integrator in [IntegratorKind::Lvc, IntegratorKind::Cis] {
        let opts = RenderOptions {
            width: size,
            height: size,
            budget: Budget::Samples(spp),
            integrator,
            max_depth: 8,
            ..Default::default()
        };
        let mut r = Renderer::new(&scene, &caster, &opts)?;
        let mut film = r.film()?;
        let start = Instant::now();
        let mut rays = 0;
        for pass in 0..spp {
            rays += r.pass(pass, &mut film).rays;
        }
        let total = start.elapsed().as_secs_f64();
        println!("{:<6} {total:>9.3} {rays:>12}", integrator.name());
        if let Some(dev) = r.device() {
            let mut k = dev.kernel_stats();
            k.sort_by(|a, b| b.seconds.total_cmp(&a.seconds));
            let kernels: f64 = k.iter().map(|k| k.seconds).sum();
            table = Some((simt::stats::format_table(&k), kernels, total));
        }
    }
    if let Some((t, kernels, total)) = table {
        println!(
            "\ncis: kernels and primitives {kernels:.3} s; caster batches, light pass and host code {:.3} s",
            total - kernels
        );
        print!("{t}");
    }
    Ok(())
}
