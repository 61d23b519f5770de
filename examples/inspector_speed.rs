//! The inspector's render against the command line's, same scene, integrator, caster,
//! size and samples: the inspector must not slow the render it shows.
//!
//! For each integrator, in interleaved rounds: `render()` as `warpray render` calls it
//! (its `seconds`), then the inspector run headless (no window) on the same settings.
//! The inspector's figures are the seconds its passes took (the convergence panel's
//! time axis) and its whole render loop (the passes plus handing the image, the error
//! against the reference and the tables to the panels after each group of passes);
//! its preparation (analysis, reference) comes before both and is not counted.
//!
//! `cargo run --release --features inspector,cli --example inspector_speed --
//! [--scene cornell] [--integrators path,bdpt,lvc-mk,cis] [--size 128] [--spp 64]
//! [--rounds 3] [--json]`

use clap::Parser;
use std::path::PathBuf;
use std::process::ExitCode;
use std::time::Duration;
use warpray::inspector::Inspector;
use warpray::prelude::*;
use warpray::render::Variant;

#[derive(Parser)]
#[command(about = "The inspector's render time against the command line's, same settings")]
struct Args {
    /// Scene, as for `warpray render`.
    #[arg(long, default_value = "cornell")]
    scene: PathBuf,
    /// Integrators (registry names, as for `warpray render --integrator`).
    #[arg(long, value_delimiter = ',', default_values = ["path", "bdpt", "lvc-mk", "cis"])]
    integrators: Vec<String>,
    /// Image width and height.
    #[arg(long, default_value_t = 128, value_parser = clap::value_parser!(u32).range(16..=1024))]
    size: u32,
    /// Samples per pixel.
    #[arg(long, default_value_t = 64, value_parser = clap::value_parser!(u32).range(1..=65536))]
    spp: u32,
    /// Interleaved rounds; each cell is the median.
    #[arg(long, default_value_t = 3, value_parser = clap::value_parser!(u32).range(1..=100))]
    rounds: u32,
    /// One JSON object per integrator instead of a table.
    #[arg(long)]
    json: bool,
}

/// The command line's render time for these settings.
fn command_line(desc: &SceneDesc, variant: Variant, size: u32, spp: u32) -> Result<f64> {
    let caster = CasterKind::Bvh4.build(&desc.scene)?;
    let opts = variant.apply(RenderOptions::for_scene(
        &desc.settings,
        RenderOptions { width: size, height: size, budget: Budget::Samples(spp), ..Default::default() },
    ));
    let (_, stats) = render(&desc.scene, caster.as_ref(), &opts, |_, _| true)?;
    Ok(stats.seconds)
}

/// The inspector's (passes, whole render loop) seconds for these settings.
fn inspector(app: &mut Inspector, variant: Variant) -> std::result::Result<(f64, f64), String> {
    app.integrator = variant;
    app.start();
    while app.running() {
        std::thread::sleep(Duration::from_millis(5));
    }
    let s = app.shared.lock().unwrap_or_else(|e| e.into_inner());
    let passes = s.series.last().and_then(|l| l.points.last()).map(|p| p.0);
    // The worker's last status is "done in X s" (its render loop), or the error.
    let whole = s.status.strip_prefix("done in ").and_then(|t| t.trim_end_matches(" s").parse::<f64>().ok());
    match (passes, whole) {
        (Some(p), Some(w)) => Ok((p, w)),
        _ => Err(format!("the inspector's render did not finish: {}", s.status)),
    }
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

fn run(args: &Args) -> std::result::Result<(), String> {
    let desc = load_scene(&args.scene).map_err(|e| e.to_string())?;
    let variants: Vec<Variant> =
        args.integrators.iter().map(|n| Variant::parse(n)).collect::<Result<_>>().map_err(|e| e.to_string())?;
    let mut app = Inspector::new();
    app.add_scene(args.scene.clone());
    (app.size, app.spp, app.caster) = (args.size, args.spp, CasterKind::Bvh4);
    let mut cells = vec![(Vec::new(), Vec::new(), Vec::new()); variants.len()];
    for round in 0..args.rounds {
        for (v, cell) in variants.iter().zip(&mut cells) {
            cell.0.push(command_line(&desc, *v, args.size, args.spp).map_err(|e| e.to_string())?);
            let (passes, whole) = inspector(&mut app, *v)?;
            cell.1.push(passes);
            cell.2.push(whole);
            eprintln!("round {} of {}: {} done", round + 1, args.rounds, v.label);
        }
    }
    if !args.json {
        println!(
            "{}, {}x{}, {} spp, bvh4 caster, {} threads; medians of {} interleaved rounds\n",
            args.scene.display(),
            args.size,
            args.size,
            args.spp,
            rayon::current_num_threads(),
            args.rounds
        );
        println!(
            "| integrator | command line s | inspector passes s | inspector render loop s | loop ÷ command line |"
        );
        println!("|---|---:|---:|---:|---:|");
    }
    for (v, (cli, passes, whole)) in variants.iter().zip(cells) {
        let (cli, passes, whole) = (median(cli), median(passes), median(whole));
        if args.json {
            println!(
                "{{\"scene\":{:?},\"integrator\":{:?},\"size\":{},\"spp\":{},\"threads\":{},\"rounds\":{},\
                 \"command_line_s\":{cli:.4},\"inspector_passes_s\":{passes:.4},\"inspector_loop_s\":{whole:.4}}}",
                args.scene.display().to_string(),
                v.label,
                args.size,
                args.spp,
                rayon::current_num_threads(),
                args.rounds
            );
        } else {
            println!("| {} | {cli:.3} | {passes:.3} | {whole:.3} | {:.2}× |", v.label, whole / cli);
        }
    }
    Ok(())
}

fn main() -> ExitCode {
    let args = Args::parse();
    match run(&args) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("inspector_speed: {e}");
            ExitCode::FAILURE
        }
    }
}
