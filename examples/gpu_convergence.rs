//! The CIS-LBDPT paper's runtime table to equal error on a real GPU: CIS-LBDPT's
//! stream against the LVC-BDPT megakernels (and the stream without sorting), rendered
//! progressively on the GPU for the same GPU time each, their RMSE against a reference
//! measured after every pass, and the time each needs to reach a common RMSE.
//!
//! ```text
//! sh cuda/build.sh      # on the GPU machine
//! cargo run --release --features cuda,cli --example gpu_convergence -- \
//!     [--scenes cornell,white-room,bedroom] [--integrators lvc-mk,cis,cis-nosort] \
//!     [--size 512] [--per-iteration 1,4,8] [--seconds 2] [--reference-passes 1024] \
//!     [--bdpt-spp 16] [--json]
//! ```
//!
//! **The reference.** Both GPU integrators, seeded apart from the timed runs,
//! `--reference-passes` passes each (one pass per iteration), averaged. Its own
//! expected squared error (the mean per-pixel variance of one pass over the passes) is
//! printed and subtracted from every measured MSE: the timed images and the reference
//! are independent, so a measured MSE is the image's MSE plus the reference's, and the
//! difference is unbiased. **Checked against BDPT**: with `--bdpt-spp S`, the CPU's
//! BDPT (`warpray render --integrator bdpt`, BVH4, every core) renders S samples per
//! pixel; its MSE against the reference should be its own variance over S plus the
//! reference's, and the ratio of measured to expected is printed (1 within noise when
//! the reference is BDPT's image; a bias in either shows as a ratio above 1), with the
//! relative difference of the image means.
//!
//! **The timed runs.** Each integrator renders progressively, `--per-iteration` camera
//! passes per light pass (the paper renders 4–8 samples per pixel per iteration), in
//! blocks of whole iterations interleaved between the integrators, until its GPU time
//! (CUDA events, the sum of its passes' times, read-backs left out) reaches
//! `--seconds`. After every pass the film's image is compared with the reference (not
//! timed). Per scene and setting, the table gives samples per pixel reached, ms per
//! sample, the final RMSE, the GPU seconds to the common RMSE (the worst final RMSE of
//! the integrators, log-log interpolated between passes, as `warpray converge` does)
//! and the speed-ups over the first integrator.

use clap::Parser;
use std::time::Instant;
use warpray::cast::RayCaster;
use warpray::converge::{Checkpoint, relmse, rmse, summarize};
use warpray::film::Film;
use warpray::glam::Vec3;
use warpray::gpu::GpuRender;
use warpray::machine::Machine;
use warpray::render::{Budget, IntegratorKind, RenderOptions, Renderer, Variant};
use warpray::scene::Scene;

#[path = "gpu_scenes/mod.rs"]
mod gpu_scenes;

#[derive(Parser)]
struct Args {
    #[command(flatten)]
    common: gpu_scenes::Common,
    /// Camera passes per iteration to compare (comma-separated).
    #[arg(long, value_delimiter = ',', default_value = "1,4,8", value_parser = clap::value_parser!(u32).range(1..=1024))]
    per_iteration: Vec<u32>,
    /// GPU seconds each integrator renders, per scene and setting (above 0, at most 3600).
    #[arg(long, default_value_t = 2.0, value_parser = parse_seconds)]
    seconds: f64,
    /// Passes of each reference integrator (lvc-mk and cis).
    #[arg(long, default_value_t = 1024, value_parser = clap::value_parser!(u32).range(2..=1_000_000))]
    reference_passes: u32,
    /// Samples per pixel of the CPU BDPT render that checks the reference (0: none).
    #[arg(long, default_value_t = 0, value_parser = clap::value_parser!(u32).range(0..=65_536))]
    bdpt_spp: u32,
    /// One JSON object per row instead of the tables.
    #[arg(long)]
    json: bool,
}

fn parse_seconds(s: &str) -> Result<f64, String> {
    match s.parse::<f64>() {
        Ok(t) if t > 0.0 && t <= 3600.0 => Ok(t),
        _ => Err(format!("{s}: seconds above 0, at most 3600")),
    }
}

fn options(a: &Args, label: &str, per_iteration: u32, seed: u64) -> Result<RenderOptions, String> {
    let mut o = gpu_scenes::options(&a.common, label, seed, 0)?;
    o.set_samples_per_iteration(per_iteration);
    Ok(o)
}

/// Mean over pixels and channels.
fn mean3(v: &[Vec3]) -> f64 {
    v.iter().map(|p| (p.x + p.y + p.z) as f64).sum::<f64>() / (3 * v.len().max(1)) as f64
}

/// The reference image and its expected squared error (the mean per-pixel variance of
/// one pass over the passes, averaged over the integrators that made it).
fn reference(a: &Args, scene: &Scene) -> Result<(Vec<Vec3>, f64), String> {
    let t = Instant::now();
    let mut images = Vec::new();
    let mut mse = 0.0;
    for (i, label) in ["lvc-mk", "cis"].iter().enumerate() {
        let opts = options(a, label, 1, 1_000_003 + i as u64)?;
        let mut gpu = GpuRender::new(scene, &opts).map_err(|e| e.to_string())?;
        let mut film = opts.film().map_err(|e| e.to_string())?;
        for pass in 0..a.reference_passes {
            gpu.render_pass(pass, &mut film).map_err(|e| e.to_string())?;
        }
        mse += mean3(&film.variance()) / a.reference_passes as f64;
        images.push(film.mean());
    }
    let n = images.len() as f64;
    let image: Vec<Vec3> =
        (0..images[0].len()).map(|p| images.iter().map(|im| im[p]).sum::<Vec3>() / n as f32).collect();
    eprintln!("reference: {} passes of lvc-mk and cis in {:.1} s", a.reference_passes, t.elapsed().as_secs_f64());
    // The average of n independent images: its variance is the mean one's over n.
    Ok((image, mse / n / n))
}

/// The CPU BDPT check of the reference: (measured MSE over expected, relative
/// difference of the image means, its standard error, seconds).
fn bdpt_check(a: &Args, scene: &Scene, reference: &[Vec3], ref_mse: f64) -> Result<[f64; 4], String> {
    let caster = warpray::cast::Bvh4::new(scene);
    let opts = RenderOptions {
        width: a.common.size,
        height: a.common.size,
        max_depth: a.common.max_depth,
        seed: 7,
        integrator: IntegratorKind::Bdpt,
        budget: Budget::Samples(a.bdpt_spp),
        ..Default::default()
    };
    let t = Instant::now();
    let mut r = Renderer::new(scene, &caster as &dyn RayCaster, &opts).map_err(|e| e.to_string())?;
    let mut film = r.film().map_err(|e| e.to_string())?;
    r.passes(0, a.bdpt_spp, &mut film);
    let seconds = t.elapsed().as_secs_f64();
    let (image, var) = (film.mean(), film.variance());
    let expected = mean3(&var) / a.bdpt_spp as f64 + ref_mse;
    let measured = rmse(&image, reference).powi(2);
    // The difference of the image means' standard error: pixels independent, each with
    // its variance over its samples, BDPT's and the reference's.
    let n = (3 * image.len()) as f64;
    let bdpt = var.iter().map(|v| (v.x + v.y + v.z) as f64).sum::<f64>() / a.bdpt_spp as f64;
    let se = (bdpt + ref_mse * n).sqrt() / n;
    let (m, r_mean) = (mean3(&image), mean3(reference));
    Ok([measured / expected, (m - r_mean) / r_mean, se / r_mean, seconds])
}

/// The checkpoints of every integrator's progressive run, and each one's label with its
/// light pass's GPU milliseconds per pass.
type Progress = (Vec<Checkpoint>, Vec<(&'static str, f64)>);

/// One integrator's progressive run.
struct Run {
    label: &'static str,
    gpu: GpuRender,
    film: Film,
    gpu_seconds: f64,
    passes: u32,
    light_ms: f64,
}

/// Renders every integrator for `a.seconds` of GPU time, `per_iteration` passes per
/// iteration, interleaved in blocks of whole iterations; the checkpoints after every
/// pass (RMSE with the reference's own MSE taken out).
fn progressive(
    a: &Args,
    scene: &Scene,
    per_iteration: u32,
    (reference, ref_mse): (&[Vec3], f64),
) -> Result<Progress, String> {
    let mut runs = Vec::new();
    for label in &a.common.integrators {
        let opts = options(a, label, per_iteration, 1)?;
        let mut gpu = GpuRender::new(scene, &opts).map_err(|e| e.to_string())?;
        let mut warm = opts.film().map_err(|e| e.to_string())?;
        gpu.render_pass(per_iteration * 1_000_000, &mut warm).map_err(|e| e.to_string())?;
        let label = Variant::parse(label).map_err(|e| e.to_string())?.label;
        let film = opts.film().map_err(|e| e.to_string())?;
        runs.push(Run { label, gpu, film, gpu_seconds: 0.0, passes: 0, light_ms: 0.0 });
    }
    let block = per_iteration * 4u32.div_ceil(per_iteration);
    let mut rows = Vec::new();
    while runs.iter().any(|r| r.gpu_seconds < a.seconds) {
        for run in runs.iter_mut().filter(|r| r.gpu_seconds < a.seconds) {
            for _ in 0..block {
                let s = run.gpu.render_pass(run.passes, &mut run.film).map_err(|e| e.to_string())?;
                run.passes += 1;
                run.gpu_seconds += s.pass_ms / 1e3;
                run.light_ms += s.light_ms;
                let image = run.film.mean();
                let mse = (rmse(&image, reference).powi(2) - ref_mse).max(0.0);
                rows.push(Checkpoint {
                    integrator: run.label,
                    seconds: run.gpu_seconds,
                    spp: run.passes,
                    rmse: mse.sqrt(),
                    relmse: relmse(&image, reference),
                });
            }
        }
    }
    let light = runs.iter().map(|r| (r.label, r.light_ms / r.passes.max(1) as f64)).collect();
    Ok((rows, light))
}

fn run(a: Args) -> Result<(), String> {
    let machine = Machine::this();
    eprintln!("host: {machine}");
    let mut device = String::new();
    for name in &a.common.scenes {
        let scene = gpu_scenes::load(name)?;
        if device.is_empty() {
            device = GpuRender::new(&scene, &options(&a, "cis", 1, 1)?)
                .and_then(|g| g.device_name())
                .map_err(|e| e.to_string())?;
            eprintln!("GPU: {device}");
        }
        let (reference, ref_mse) = reference(&a, &scene)?;
        let check = if a.bdpt_spp > 0 { Some(bdpt_check(&a, &scene, &reference, ref_mse)?) } else { None };
        let ref_rmse = ref_mse.sqrt();
        if !a.json {
            println!(
                "\n{name}, {0}x{0}, max depth {1}: reference RMSE {ref_rmse:.5} (estimated)",
                a.common.size, a.common.max_depth
            );
            if let Some([ratio, dm, se, s]) = check {
                println!(
                    "CPU BDPT, {} spp ({s:.0} s): MSE against the reference {ratio:.3}× the expected; image means differ by {:+.3} % (± {:.3} %)",
                    a.bdpt_spp,
                    100.0 * dm,
                    100.0 * se
                );
            }
        }
        for &k in &a.per_iteration {
            let (rows, light) = progressive(&a, &scene, k, (&reference, ref_mse))?;
            let labels: Vec<&str> = light.iter().map(|l| l.0).collect();
            let summaries = summarize(&rows, &labels);
            if a.json {
                for (s, (_, light_ms)) in summaries.iter().zip(&light) {
                    let check = check.map_or("null".into(), |c| {
                        format!("{{\"bdpt_spp\":{},\"mse_ratio\":{:.4},\"mean_diff\":{:.3e},\"mean_se\":{:.3e},\"seconds\":{:.1}}}", a.bdpt_spp, c[0], c[1], c[2], c[3])
                    });
                    println!(
                        "{{\"scene\":\"{name}\",\"integrator\":\"{}\",\"size\":{},\"max_depth\":{},\"per_iteration\":{k},\"gpu_seconds\":{:.4},\"spp\":{},\"ms_per_spp\":{:.4},\"light_ms_per_spp\":{light_ms:.4},\"rmse\":{:.6e},\"seconds_to_common_rmse\":{},\"speedup_per_spp\":{:.4},\"speedup_to_rmse\":{},\"reference_passes\":{},\"reference_rmse\":{ref_rmse:.6e},\"bdpt_check\":{check},\"gpu\":\"{}\",\"machine\":{}}}",
                        s.integrator,
                        a.common.size,
                        a.common.max_depth,
                        s.seconds,
                        s.spp,
                        s.ms_per_spp,
                        s.rmse,
                        s.seconds_to_target.map_or("null".into(), |v| format!("{v:.4}")),
                        s.speedup_per_spp,
                        s.speedup_to_target.map_or("null".into(), |v| format!("{v:.4}")),
                        2 * a.reference_passes,
                        device.replace('"', "'"),
                        machine.json()
                    );
                }
            } else {
                println!("\n{k} spp per iteration, {} GPU s each:", a.seconds);
                print!("{}", warpray::converge::summary_table(&summaries));
            }
        }
    }
    if !a.json {
        println!("\nGPU: {device}; host: {machine}");
    }
    Ok(())
}

fn main() {
    if let Err(e) = run(Args::parse()) {
        eprintln!("error: {e}");
        std::process::exit(1);
    }
}
