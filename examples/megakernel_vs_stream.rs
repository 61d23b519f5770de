//! LVC-BDPT as a megakernel against CIS-LBDPT as a stream, both on the `simt` device,
//! for the whole render (light pass and camera pass): SIMD efficiency measured from
//! what the lanes executed, global memory traffic, launches, and time.
//!
//! * SIMD efficiency is thread instructions over 32 x warp instructions, summed over
//!   every measured launch. Both sides count the same things: the memory operations
//!   their lanes make through `simt` and one declared instruction per shading on its
//!   material's arm. The megakernel also declares one instruction per ray it traces
//!   (its lanes trace inline); the stream's rays go to the caster in compacted batches
//!   outside any kernel. So the table gives the efficiency without the trace
//!   instructions (comparable on both sides) and, for the megakernel, the occupancy of
//!   its trace instructions. The primitives (sort, scans, compaction) run on their CPU
//!   backend and are not measured.
//! * Times come from a second render with measurement off (what renders run).
//!
//! `cargo run --release --example megakernel_vs_stream -- [SCENE...] [--size 64]
//! [--spp 2] [--time-spp 16] [--json]` (SCENE: `cornell` or a scene file).

use clap::Parser;
use std::path::PathBuf;
use std::process::ExitCode;
use std::time::Instant;
use warpray::prelude::*;
use warpray::render::CisParams;
use warpray::render::{LvcParams, Renderer};

#[derive(Parser)]
#[command(about = "LVC-BDPT megakernel against CIS-LBDPT stream: SIMD efficiency, traffic, time")]
struct Args {
    /// Scenes, as for `warpray render`.
    #[arg(default_values = ["cornell"])]
    scenes: Vec<PathBuf>,
    /// Image width and height.
    #[arg(long, default_value_t = 64, value_parser = clap::value_parser!(u32).range(1..=1024))]
    size: u32,
    /// Samples per pixel of the measured render.
    #[arg(long, default_value_t = 2, value_parser = clap::value_parser!(u32).range(1..=1024))]
    spp: u32,
    /// Samples per pixel of the timed render (measurement off).
    #[arg(long, default_value_t = 16, value_parser = clap::value_parser!(u32).range(1..=65536))]
    time_spp: u32,
    /// Print JSON instead of a table.
    #[arg(long)]
    json: bool,
}

/// What one method's render showed.
#[derive(Default)]
struct Figures {
    /// Per pass (light, camera, whole): (active, issued) without the trace region.
    work: [(u64, u64); 3],
    /// The trace region's (active, issued).
    trace: (u64, u64),
    /// Global load and store sectors.
    sectors: (u64, u64),
    launches: u64,
    seconds: f64,
    rays: u64,
}

fn efficiency((active, issued): (u64, u64)) -> Option<f64> {
    (issued > 0).then(|| active as f64 / (32.0 * issued as f64))
}

/// Whether kernel `name` belongs to the light pass.
fn light_pass(name: &str) -> bool {
    ["light", "cache", "splat", "finished"].iter().any(|k| name.contains(k))
}

fn options(size: u32, spp: u32, megakernel: bool, measure: bool) -> RenderOptions {
    RenderOptions {
        width: size,
        height: size,
        budget: Budget::Samples(spp),
        max_depth: 8,
        integrator: if megakernel { IntegratorKind::LvcMegakernel } else { IntegratorKind::Cis },
        lvc: LvcParams { measure, ..Default::default() },
        cis: CisParams { measure, ..Default::default() },
        ..Default::default()
    }
}

fn measure(scene: &Scene, caster: &dyn RayCaster, args: &Args, megakernel: bool) -> Result<Figures> {
    let mut f = Figures::default();
    let mut r = Renderer::new(scene, caster, &options(args.size, args.spp, megakernel, true))?;
    let mut film = r.film()?;
    for pass in 0..args.spp {
        r.pass(pass, &mut film);
    }
    let dev = r.device().expect("both methods run on the device");
    for k in dev.kernel_stats().iter().filter(|k| k.measured_launches > 0) {
        let mut work = (k.ops.active, k.ops.issued);
        for region in &k.regions {
            if region.name == "trace" {
                f.trace.0 += region.active;
                f.trace.1 += region.issued;
            } else {
                work.0 += region.active;
                work.1 += region.issued;
            }
        }
        for which in [if light_pass(k.name) { 0 } else { 1 }, 2] {
            f.work[which].0 += work.0;
            f.work[which].1 += work.1;
        }
        f.sectors.0 += k.loads.sectors;
        f.sectors.1 += k.stores.sectors;
    }
    f.launches = dev.kernel_stats().iter().map(|k| k.launches).sum();
    let timed = options(args.size, args.time_spp, megakernel, false);
    let start = Instant::now();
    let (_, stats) = render(scene, caster, &timed, |_, _| true)?;
    f.seconds = start.elapsed().as_secs_f64();
    f.rays = stats.rays;
    Ok(f)
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

fn show(x: Option<f64>) -> String {
    x.map_or("-".into(), |v| format!("{v:.3}"))
}

fn json(x: Option<f64>) -> String {
    x.map_or("null".into(), |v| format!("{v:.4}"))
}

fn run(args: Args) -> Result<()> {
    let threads = rayon::current_num_threads();
    let mut out = Vec::new();
    for path in &args.scenes {
        let scene = load_scene(path)?.scene;
        let caster = BvhCaster::new(&scene);
        let mk = measure(&scene, &caster, &args, true)?;
        let st = measure(&scene, &caster, &args, false)?;
        let name = path.display().to_string();
        if args.json {
            let one = |f: &Figures| {
                format!(
                    "{{\"simd_light\": {}, \"simd_camera\": {}, \"simd_whole\": {}, \"trace_occupancy\": {}, \"load_sectors\": {}, \"store_sectors\": {}, \"launches\": {}, \"seconds\": {:.4}, \"rays\": {}}}",
                    json(efficiency(f.work[0])),
                    json(efficiency(f.work[1])),
                    json(efficiency(f.work[2])),
                    json(efficiency(f.trace)),
                    f.sectors.0,
                    f.sectors.1,
                    f.launches,
                    f.seconds,
                    f.rays
                )
            };
            out.push(format!(
                "{{\"scene\": \"{name}\", \"size\": {}, \"spp\": {}, \"time_spp\": {}, \"threads\": {threads}, \"megakernel\": {}, \"stream\": {}}}",
                args.size,
                args.spp,
                args.time_spp,
                one(&mk),
                one(&st)
            ));
            continue;
        }
        println!(
            "{name}: {0}x{0}, measured {1} spp, timed {2} spp, {threads} threads",
            args.size, args.spp, args.time_spp
        );
        println!("{:<44} {:>14} {:>14}", "", "LVC megakernel", "CIS stream");
        let rows: [(&str, String, String); 9] = [
            ("SIMD efficiency, light pass", show(efficiency(mk.work[0])), show(efficiency(st.work[0]))),
            ("SIMD efficiency, camera pass", show(efficiency(mk.work[1])), show(efficiency(st.work[1]))),
            ("SIMD efficiency, whole render", show(efficiency(mk.work[2])), show(efficiency(st.work[2]))),
            ("occupancy of trace instructions", show(efficiency(mk.trace)), "(batches)".into()),
            (
                "global load sectors (millions)",
                format!("{:.2}", mk.sectors.0 as f64 / 1e6),
                format!("{:.2}", st.sectors.0 as f64 / 1e6),
            ),
            (
                "global store sectors (millions)",
                format!("{:.2}", mk.sectors.1 as f64 / 1e6),
                format!("{:.2}", st.sectors.1 as f64 / 1e6),
            ),
            ("launches (measured render)", mk.launches.to_string(), st.launches.to_string()),
            ("seconds (timed render)", format!("{:.3}", mk.seconds), format!("{:.3}", st.seconds)),
            (
                "rays (timed render, millions)",
                format!("{:.2}", mk.rays as f64 / 1e6),
                format!("{:.2}", st.rays as f64 / 1e6),
            ),
        ];
        for (label, a, b) in rows {
            println!("{label:<44} {a:>14} {b:>14}");
        }
        println!();
    }
    if args.json {
        println!("[{}]", out.join(",\n "));
    }
    Ok(())
}
