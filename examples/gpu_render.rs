//! The CIS-LBDPT paper's runtime table on a real GPU: CIS-LBDPT's stream of kernels
//! against the LVC-BDPT megakernels (and the stream without sorting), whole renders on
//! the GPU (`warpray::gpu::GpuRender`, `cuda/render.cu`), per scene: milliseconds per
//! pass, and the time each needs to reach the same error.
//!
//! ```text
//! sh cuda/build.sh      # on the GPU machine
//! cargo run --release --features cuda,cli --example gpu_render -- \
//!     [--scenes cornell,white-room,bedroom] [--integrators lvc-mk,cis,cis-nosort] \
//!     [--size 512] [--max-depth 8] [--passes 8] [--rounds 5] [--cpu-passes 0] [--json]
//! ```
//!
//! Each pass is one sample per pixel with its own light pass (N light subpaths for N
//! pixels), as the CPU integrators render it by default (`gpu_convergence` compares
//! several passes per light pass, to equal RMSE against a reference). Rounds interleave the integrators, each
//! rendering `--passes` passes per round onto its own film; times are medians over
//! rounds of the per-pass GPU time (CUDA events, from the first launch to the last, the
//! estimates still on the GPU), with the read-back of estimates and splats apart.
//!
//! **Time to equal error.** Every integrator here is unbiased (the CPU integrators they
//! port agree with Mitsuba 3, and the port gives their images pixel for pixel: see
//! `tests/suite/gpu_render.rs`), so an N-pass image's expected squared error is the
//! per-pixel variance of one pass over N. The film keeps each pixel's variance across
//! passes; the time to reach a given RMSE is then proportional to (time per pass) ×
//! (mean per-pixel variance), and the speed-up of an integrator over the first one is
//! the ratio of those products. No reference image is needed, and none of its noise
//! enters the ratio.
//!
//! With `--cpu-passes K`, the same integrators also render K passes on the CPU (the
//! BVH4 caster, every core) for the CPU's time per pass at the same settings.

use clap::Parser;
use std::time::Instant;
use warpray::cast::RayCaster;
use warpray::gpu::{GpuRender, GpuRenderStats};
use warpray::machine::{Machine, median};
use warpray::render::{Budget, RenderOptions, Renderer};
use warpray::scene::Scene;

#[path = "gpu_scenes/mod.rs"]
mod gpu_scenes;

#[derive(Parser)]
struct Args {
    #[command(flatten)]
    common: gpu_scenes::Common,
    /// Passes per integrator and round.
    #[arg(long, default_value_t = 8, value_parser = clap::value_parser!(u32).range(1..=10_000))]
    passes: u32,
    /// Timed rounds (after one untimed pass each).
    #[arg(long, default_value_t = 5, value_parser = clap::value_parser!(u32).range(1..=1000))]
    rounds: u32,
    /// CIS-LBDPT's pool of samples in flight (0: one slot per pixel).
    #[arg(long, default_value_t = 0)]
    pool: u32,
    /// Passes each integrator also renders on the CPU (0: none).
    #[arg(long, default_value_t = 0, value_parser = clap::value_parser!(u32).range(0..=1000))]
    cpu_passes: u32,
    /// One JSON object per row instead of the table.
    #[arg(long)]
    json: bool,
}

/// One integrator's run on one scene.
struct Row {
    scene: String,
    integrator: String,
    spp: u32,
    /// Medians over rounds, per pass (ms).
    pass_ms: f64,
    light_ms: f64,
    readback_ms: f64,
    wall_ms: f64,
    /// Mean over pixels and channels of the per-pass variance.
    variance: f64,
    image_mean: f64,
    build_ms: f64,
    cache_entries: f64,
    bounces: f64,
    cpu_pass_ms: Option<f64>,
}

impl Row {
    /// Proportional to the time this integrator needs to reach a given error: the time
    /// per pass times the variance of one pass.
    fn cost(&self) -> f64 {
        self.pass_ms * self.variance
    }
}

fn options(a: &Args, label: &str) -> Result<RenderOptions, String> {
    gpu_scenes::options(&a.common, label, 1, a.pool)
}

fn mean_of(v: impl Iterator<Item = f64>) -> f64 {
    let (s, n) = v.fold((0.0, 0usize), |(s, n), x| (s + x, n + 1));
    s / n.max(1) as f64
}

fn cpu_pass_ms(scene: &Scene, opts: &RenderOptions, passes: u32) -> Result<f64, String> {
    let caster = warpray::cast::Bvh4::new(scene);
    let opts = RenderOptions { budget: Budget::Samples(passes), ..opts.clone() };
    let mut r = Renderer::new(scene, &caster as &dyn RayCaster, &opts).map_err(|e| e.to_string())?;
    let mut film = r.film().map_err(|e| e.to_string())?;
    r.pass(1_000_000, &mut film); // warm-up
    let t = Instant::now();
    r.passes(0, passes, &mut film);
    Ok(t.elapsed().as_secs_f64() * 1e3 / passes as f64)
}

fn run_scene(a: &Args, name: &str, rows: &mut Vec<Row>, device: &mut String) -> Result<(), String> {
    let scene = gpu_scenes::load(name)?;
    let mut runs = Vec::new();
    for label in &a.common.integrators {
        let opts = options(a, label)?;
        let mut gpu = GpuRender::new(&scene, &opts).map_err(|e| e.to_string())?;
        if device.is_empty() {
            *device = gpu.device_name().map_err(|e| e.to_string())?;
            eprintln!("GPU: {device}");
        }
        let mut warm = opts.film().map_err(|e| e.to_string())?;
        gpu.render_pass(1_000_000, &mut warm).map_err(|e| e.to_string())?;
        let film = opts.film().map_err(|e| e.to_string())?;
        runs.push((label.clone(), opts, gpu, film, Vec::<[f64; 4]>::new(), Vec::<GpuRenderStats>::new()));
    }
    let mut pass = 0;
    for round in 0..a.rounds {
        for (_, _, gpu, film, times, stats) in runs.iter_mut() {
            let mut sum = [0.0; 4];
            for p in 0..a.passes {
                let t = Instant::now();
                let s = gpu.render_pass(round * a.passes + p, film).map_err(|e| e.to_string())?;
                sum[3] += t.elapsed().as_secs_f64() * 1e3;
                sum[0] += s.pass_ms;
                sum[1] += s.light_ms;
                sum[2] += s.readback_ms;
                stats.push(s);
            }
            times.push(sum.map(|x| x / a.passes as f64));
        }
        pass += a.passes;
        eprintln!("{name}: round {} of {} ({pass} passes each)", round + 1, a.rounds);
    }
    for (label, opts, gpu, film, times, stats) in runs {
        let m = |k: usize| median(times.iter().map(|t| t[k]).collect());
        let var = film.variance();
        let cpu = if a.cpu_passes > 0 { Some(cpu_pass_ms(&scene, &opts, a.cpu_passes)?) } else { None };
        rows.push(Row {
            scene: name.to_string(),
            integrator: label,
            spp: film.passes,
            pass_ms: m(0),
            light_ms: m(1),
            readback_ms: m(2),
            wall_ms: m(3),
            variance: mean_of(var.iter().map(|v| ((v.x + v.y + v.z) / 3.0) as f64)),
            image_mean: mean_of(film.mean().iter().map(|v| ((v.x + v.y + v.z) / 3.0) as f64)),
            build_ms: gpu.setup().build_ms,
            cache_entries: mean_of(stats.iter().map(|s| s.cache_entries as f64)),
            bounces: mean_of(stats.iter().map(|s| s.bounces as f64)),
            cpu_pass_ms: cpu,
        });
    }
    Ok(())
}

fn print(a: &Args, rows: &[Row], device: &str, machine: &Machine) {
    for scene in &a.common.scenes {
        let ours: Vec<&Row> = rows.iter().filter(|r| &r.scene == scene).collect();
        let Some(first) = ours.first() else { continue };
        let base = first.cost();
        if a.json {
            for r in &ours {
                println!(
                    "{{\"scene\":\"{}\",\"integrator\":\"{}\",\"size\":{},\"max_depth\":{},\"spp\":{},\"pass_ms\":{:.4},\"light_ms\":{:.4},\"readback_ms\":{:.4},\"wall_ms\":{:.4},\"variance\":{:.6e},\"image_mean\":{:.6e},\"speedup_equal_error\":{:.4},\"bvh_build_ms\":{:.4},\"cache_entries\":{:.0},\"bounces\":{:.2},\"cpu_pass_ms\":{},\"gpu\":\"{}\",\"machine\":{}}}",
                    r.scene,
                    r.integrator,
                    a.common.size,
                    a.common.max_depth,
                    r.spp,
                    r.pass_ms,
                    r.light_ms,
                    r.readback_ms,
                    r.wall_ms,
                    r.variance,
                    r.image_mean,
                    base / r.cost(),
                    r.build_ms,
                    r.cache_entries,
                    r.bounces,
                    r.cpu_pass_ms.map_or("null".into(), |c| format!("{c:.3}")),
                    device.replace('"', "'"),
                    machine.json()
                );
            }
            continue;
        }
        println!("\n{scene}, {0}x{0}, max depth {1}, {2} passes each:", a.common.size, a.common.max_depth, first.spp);
        println!(
            "| integrator | GPU ms/pass | of which light | read-back ms | wall ms/pass | variance/pass | image mean | speed-up at equal error | CPU ms/pass |"
        );
        println!("|---|---:|---:|---:|---:|---:|---:|---:|---:|");
        for r in &ours {
            println!(
                "| {} | {:.2} | {:.2} | {:.2} | {:.2} | {:.4e} | {:.5} | {:.2}× | {} |",
                r.integrator,
                r.pass_ms,
                r.light_ms,
                r.readback_ms,
                r.wall_ms,
                r.variance,
                r.image_mean,
                base / r.cost(),
                r.cpu_pass_ms.map_or("-".into(), |c| format!("{c:.1}"))
            );
        }
    }
    if !a.json {
        println!("\nGPU: {device}; host: {machine}");
    }
}

fn run(a: Args) -> Result<(), String> {
    let machine = Machine::this();
    eprintln!("host: {machine}");
    let (mut rows, mut device) = (Vec::new(), String::new());
    for name in &a.common.scenes {
        run_scene(&a, name, &mut rows, &mut device)?;
    }
    print(&a, &rows, &device, &machine);
    Ok(())
}

fn main() {
    if let Err(e) = run(Args::parse()) {
        eprintln!("error: {e}");
        std::process::exit(1);
    }
}
