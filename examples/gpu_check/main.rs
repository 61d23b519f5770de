//! The `simt` model checked against a real GPU (`docs/gpu-check.md`): PDACRT's kernels
//! measured by the emulator and by Nsight Compute on the same rays, and PDACRT's GPU
//! timings beside the CPU casters on the same machine.
//!
//! ```text
//! sh cuda/build.sh                                    # on the GPU machine: target/cuda/libwarpray_cuda.so
//! gpu_check simt --model bunny --batch primary --out simt.tsv
//! ncu --csv --page raw --print-units base --metrics "$(gpu_check metrics)" --log-file ncu.csv \
//!     gpu_check gpu --model bunny --batch primary --repeat 1
//! gpu_check report --simt simt.tsv --ncu ncu.csv
//! gpu_check gpu --model dragon,bunny,conference --batch primary,shadow,ao --size 1024 --repeat 5 --cpu bvh,dacrt
//! gpu_check calibrate --probes micro_probes.tsv --ncu micro_ncu.csv   # a GPU profile (cuda/microbench.sh)
//! gpu_check time --records rec.tsv --ncu ncu.csv --ncu-all ncutime.csv  # predicted GPU time against ncu's
//! gpu_check simt --caster lbvh --model bunny --batch primary,shadow --out s.tsv --launches rec.tsv  # the GPU BVH's twin
//! gpu_check gpu --gpu bvh --model bunny --batch primary,shadow --repeat 1   # the GPU BVH, keys against its twin
//! ```
//!
//! About 700 lines on purpose: one subcommand per step of the check, sharing the input options
//! (the GPU BVH's rows are in `gpu_bvh.rs`).
//!
//! `gpu` checks every GPU key against the CPU PDACRT's (bit for bit) and every 256th ray
//! against brute force, and exits non-zero when any differs.
//!
//! `cis` does the same for CIS-LBDPT's shading and compaction: with `--simt FILE` it
//! renders with measurement on (sorted, then unsorted) and writes the emulator's rows
//! (`cis::shade_sorted`, `cis::shade_unsorted`, `cis::alive_flags`); without, it renders
//! unmeasured and runs every bounce's shading and compaction again on the GPU, on the
//! inputs the render captured, and compares (run this one under ncu).

mod gpu_bvh;
mod source;
mod tsv;

use clap::{Parser, Subcommand};
use std::io::Write as _;
use std::time::Instant;
use warpray::cast::{BruteForce, BvhCaster, Dacrt, Lbvh, RayCaster, Traversal};
use warpray::geometry::{Hit, Ray};
use warpray::gpu::{GpuPdacrt, ncu};
use warpray::pdacrt::{Pdacrt, PdacrtParams};
use warpray::scene::{ObjOptions, Scene, find_model, load_obj, models_dir};

#[derive(Parser)]
struct Args {
    #[command(subcommand)]
    cmd: Cmd,
}

#[derive(clap::Args, Clone)]
pub(crate) struct Input {
    /// Models (from WARPRAY_MODELS), comma-separated.
    #[arg(long, value_delimiter = ',', default_value = "bunny")]
    model: Vec<String>,
    /// Batches: primary, shadow, specular, ao (comma-separated).
    #[arg(long, value_delimiter = ',', default_value = "primary")]
    batch: Vec<String>,
    #[arg(long, default_value_t = 1024, value_parser = clap::value_parser!(u32).range(1..=8192))]
    size: u32,
    /// Ambient-occlusion rays per primary hit.
    #[arg(long, default_value_t = 8, value_parser = clap::value_parser!(u32).range(0..=64))]
    ao: u32,
    /// PDACRT's rays per pass (0: the whole batch at once; default: PdacrtParams').
    #[arg(long)]
    chunk: Option<usize>,
}

#[derive(Subcommand)]
enum Cmd {
    /// Print the metrics `ncu --metrics` must collect.
    Metrics,
    /// PDACRT (or the GPU BVH's twin) on the emulator with measurement on: per-kernel
    /// summaries to a TSV file.
    Simt {
        #[command(flatten)]
        input: Input,
        /// `pdacrt`, or `lbvh`: the GPU BVH's build and trace, built again for each batch
        /// as `gpu --gpu bvh` does.
        #[arg(long, default_value = "pdacrt")]
        caster: String,
        #[arg(long)]
        out: std::path::PathBuf,
        /// Also write each launch's statistics, in launch order, to this file (for
        /// `source --simt-launches`).
        #[arg(long)]
        launches: Option<std::path::PathBuf>,
    },
    /// PDACRT on the GPU: checks, timings, and optionally CPU casters on the same rays.
    Gpu {
        #[command(flatten)]
        input: Input,
        #[arg(long, default_value_t = 5, value_parser = clap::value_parser!(u32).range(1..=100))]
        repeat: u32,
        /// CPU casters to time on the same rays (bvh, dacrt, pdacrt), comma-separated.
        #[arg(long, value_delimiter = ',')]
        cpu: Vec<String>,
        /// Brute-force check of every Nth ray (0: none).
        #[arg(long, default_value_t = 256)]
        brute_every: usize,
        /// Print one JSON object per row too.
        #[arg(long)]
        json: bool,
        /// GPU casters: `pdacrt`, and `bvh` (the BVH rebuilt for each batch, then traced
        /// `--repeat` times; its keys checked against the emulated twin `lbvh`),
        /// comma-separated.
        #[arg(long, value_delimiter = ',', default_value = "pdacrt")]
        gpu: Vec<String>,
    },
    /// CIS-LBDPT's shading and compaction: emulator statistics, or GPU runs and checks.
    Cis {
        /// Scenes, as for `warpray render` (`cornell` or a scene file), comma-separated.
        #[arg(long, value_delimiter = ',', default_value = "cornell")]
        scene: Vec<std::path::PathBuf>,
        #[arg(long, default_value_t = 128, value_parser = clap::value_parser!(u32).range(8..=2048))]
        size: u32,
        /// Write the emulator's measured statistics to this file instead of using the GPU.
        #[arg(long)]
        simt: Option<std::path::PathBuf>,
        /// With `--simt`: also write each launch's statistics, in launch order, to this
        /// file (for `source --simt-launches`).
        #[arg(long, requires = "simt")]
        simt_launches: Option<std::path::PathBuf>,
    },
    /// Split a kernel's memory instructions by the array they access, from an
    /// `ncu --page source --csv --print-source cuda,sass` export (plain or .gz), and set
    /// the accesses the emulator sees beside its statistics for the same launches.
    Source {
        #[arg(long)]
        csv: std::path::PathBuf,
        /// The emulator's statistics of the same launches: per launch (`cis
        /// --simt-launches`), or summed (`simt --out`) when every launch was profiled.
        #[arg(long)]
        simt_launches: Option<std::path::PathBuf>,
        /// How accesses are told apart: `cis` (pool, cache and scene arrays of the
        /// shading kernel; the emulator sees pool and cache) or `all` (one class).
        #[arg(long, default_value = "cis")]
        classes: String,
        /// Only the first N launches of each kernel in the export (a launch cut short
        /// by a time limit can be left out).
        #[arg(long)]
        first: Option<usize>,
        /// Also print each kernel's N busiest source lines (warp instructions, share,
        /// SIMD efficiency, static SASS instructions).
        #[arg(long)]
        lines: Option<usize>,
    },
    /// A GPU profile for simt's time model from the microbenchmarks' output and ncu's
    /// CSV of them (`cuda/microbench.sh`), to standard output.
    Calibrate {
        /// The probe program's output, one file per run (comma-separated).
        #[arg(long, value_delimiter = ',')]
        probes: Vec<std::path::PathBuf>,
        /// ncu's CSV of each run, in the same order.
        #[arg(long, value_delimiter = ',')]
        ncu: Vec<std::path::PathBuf>,
        /// Lines for the file's header comment (the machine, the date, the command).
        #[arg(long, default_value = "")]
        header: String,
    },
    /// simt's predicted GPU time against Nsight Compute's, kernel by kernel, from the
    /// emulator's launch records (`simt --launches`, `cis --simt-launches`) and ncu's CSV
    /// of the same launches; with `--ncu-all` (every kernel, CUB's too) the pipelines'
    /// totals as well.
    Time {
        #[arg(long, value_delimiter = ',')]
        records: Vec<std::path::PathBuf>,
        #[arg(long, value_delimiter = ',')]
        ncu: Vec<std::path::PathBuf>,
        #[arg(long, value_delimiter = ',')]
        ncu_all: Vec<std::path::PathBuf>,
        /// A shipped profile's name (`h200`) or a profile file.
        #[arg(long, default_value = "h200")]
        gpu_profile: String,
        /// Also print how the check moves when each profile value alone is scaled.
        #[arg(long)]
        sensitivity: bool,
        /// Also print each kernel's model terms (µs), to see which bound sets it.
        #[arg(long)]
        terms: bool,
        /// Also print this kernel launch by launch (predicted against measured).
        #[arg(long)]
        launches_of: Option<String>,
    },
    /// Join a `simt` TSV and an ncu CSV into the comparison table.
    Report {
        #[arg(long)]
        simt: std::path::PathBuf,
        #[arg(long)]
        ncu: std::path::PathBuf,
    },
}

fn main() {
    if let Err(e) = run(Args::parse()) {
        eprintln!("error: {e}");
        std::process::exit(1);
    }
}

fn load(name: &str) -> Result<Scene, String> {
    let path = find_model(name)
        .ok_or_else(|| format!("model {name} not found in {}: set WARPRAY_MODELS", models_dir().display()))?;
    load_obj(path, &ObjOptions::default()).map_err(|e| e.to_string())
}

/// The named batch and whether it is traced for occlusion (shadow rays).
fn batch(b: &warpray::cast::batches::Batches, name: &str) -> Result<(Vec<Ray>, bool), String> {
    Ok(match name {
        "primary" => (b.primary.clone(), false),
        "shadow" => (b.shadow.clone(), true),
        "specular" => (b.specular.clone(), false),
        "ao" => (b.ambient.clone(), false),
        other => return Err(format!("unknown batch {other} (known: primary, shadow, specular, ao)")),
    })
}

fn params(input: &Input) -> PdacrtParams {
    let mut p = PdacrtParams::default();
    if let Some(c) = input.chunk {
        p.chunk_rays = c;
    }
    p
}

/// One loaded (model, batch): the model's name, its scene, the batch's name, its rays,
/// and whether they are shadow rays.
pub(crate) type Loaded = (String, Scene, String, Vec<Ray>, bool);

/// Every (model, batch) of the input, loaded.
pub(crate) fn inputs(input: &Input) -> Result<Vec<Loaded>, String> {
    let mut out = Vec::new();
    for m in &input.model {
        let scene = load(m)?;
        let b = warpray::cast::batches::batches(&scene, input.size, input.size, input.ao as usize, 1);
        for name in &input.batch {
            let (rays, shadow) = batch(&b, name)?;
            out.push((m.clone(), scene.clone(), name.clone(), rays, shadow));
        }
    }
    Ok(out)
}

fn run(a: Args) -> Result<(), String> {
    match a.cmd {
        Cmd::Metrics => println!("{}", ncu::METRICS),
        Cmd::Simt { input, caster, out, launches } => simt_run(&input, &caster, &out, launches.as_deref())?,
        Cmd::Gpu { input, repeat, cpu, brute_every, json, gpu } => {
            for g in &gpu {
                if g != "pdacrt" && g != "bvh" {
                    return Err(format!("unknown GPU caster {g} (known: pdacrt, bvh)"));
                }
            }
            if gpu.iter().any(|g| g == "pdacrt") {
                gpu_run(&input, repeat, &cpu, brute_every, json)?;
            }
            if gpu.iter().any(|g| g == "bvh") {
                gpu_bvh::run(&input, repeat, brute_every)?;
            }
        }
        Cmd::Cis { scene, size, simt, simt_launches } => {
            cis_run(&scene, size, simt.as_deref(), simt_launches.as_deref())?
        }
        Cmd::Source { csv, simt_launches, classes, first, lines } => {
            source::source_run(&csv, simt_launches.as_deref(), &classes, first.unwrap_or(usize::MAX), lines)?
        }
        Cmd::Calibrate { probes, ncu: csv, header } => {
            let texts = |paths: &[std::path::PathBuf]| paths.iter().map(|p| read(p)).collect::<Result<Vec<_>, _>>();
            let (p, c) = (texts(&probes)?, texts(&csv)?);
            let names = |paths: &[std::path::PathBuf]| {
                paths.iter().map(|p| p.display().to_string()).collect::<Vec<_>>().join(",")
            };
            let (p, c): (Vec<&str>, Vec<&str>) =
                (p.iter().map(String::as_str).collect(), c.iter().map(String::as_str).collect());
            let c = warpray::gpu::calibrate::calibrate(&p, &c)
                .map_err(|e| format!("{} / {}: {e}", names(&probes), names(&csv)))?;
            print!("{}", c.to_text(&header));
        }
        Cmd::Time { records, ncu: csv, ncu_all, gpu_profile, sensitivity, terms, launches_of } => {
            time_run(&records, &csv, &ncu_all, &gpu_profile, sensitivity, terms, launches_of.as_deref())?
        }
        Cmd::Report { simt, ncu: csv } => {
            let simt = tsv::read(&read(&simt)?).map_err(|e| format!("{}: {e}", simt.display()))?;
            let gpu = ncu::parse_csv(&read(&csv)?).map_err(|e| format!("{}: {e}", csv.display()))?;
            let rows = ncu::compare(&simt, &gpu);
            println!("{}", ncu::table(&rows));
            println!("\nOther GPU kernels (CUB's scans and selection; the emulator's primitives have other names):\n");
            println!("| kernel | launches | SIMD eff. | ld sect/req | GPU ms |\n|---|---:|---:|---:|---:|");
            for g in gpu.iter().filter(|g| !simt.iter().any(|s| s.name == g.name)) {
                let f = |v: Option<f64>| v.map_or("–".to_string(), |x| format!("{x:.3}"));
                println!(
                    "| {} | {} | {} | {} | {:.3} |",
                    g.name,
                    g.launches,
                    f(g.simd_efficiency()),
                    f(g.loads.sectors_per_request()),
                    g.seconds * 1e3
                );
            }
        }
    }
    Ok(())
}

/// A text file, plain or gzip-compressed (`.gz`).
pub(crate) fn read(p: &std::path::Path) -> Result<String, String> {
    let bytes = std::fs::read(p).map_err(|e| format!("{}: {e}", p.display()))?;
    if p.extension().is_some_and(|e| e == "gz") {
        let mut s = String::new();
        std::io::Read::read_to_string(&mut flate2::read::GzDecoder::new(&bytes[..]), &mut s)
            .map_err(|e| format!("{}: {e}", p.display()))?;
        Ok(s)
    } else {
        String::from_utf8(bytes).map_err(|e| format!("{}: {e}", p.display()))
    }
}

fn time_run(
    records: &[std::path::PathBuf],
    csv: &[std::path::PathBuf],
    all: &[std::path::PathBuf],
    profile: &str,
    sensitivity: bool,
    terms: bool,
    launches_of: Option<&str>,
) -> Result<(), String> {
    use warpray::gpu::time_check;
    let p = simt::GpuProfile::load(profile)?;
    println!("Profile: {} ({profile}).\n", p.name);
    let (mut every, mut runs) = (Vec::new(), Vec::new());
    for (i, path) in records.iter().enumerate() {
        let recs = simt::records_from_tsv(&read(path)?).map_err(|e| format!("{}: {e}", path.display()))?;
        let mut run = time_check::CheckedRun { records: Vec::new(), kernels: Vec::new(), every: None };
        if let Some(c) = csv.get(i) {
            let gpu = ncu::parse_csv(&read(c)?).map_err(|e| format!("{}: {e}", c.display()))?;
            let rows = time_check::kernel_times(&recs, &gpu, &p);
            println!("{} against {}:\n\n{}", path.display(), c.display(), time_check::table(&rows));
            if terms {
                println!(
                    "Model terms, µs (the prediction is launch + the largest, or + the larger of memory and execution + exposed):\n\n{}",
                    time_check::terms_table(&rows)
                );
            }
            if let Some(k) = launches_of {
                // The kernel's own file first, then (a library primitive's kernel, CUB's
                // in the twin) the file of every kernel.
                let mut table = None;
                for f in [Some(c), all.get(i)].into_iter().flatten() {
                    let each = ncu::parse_launches(&read(f)?).map_err(|e| format!("{}: {e}", f.display()))?;
                    table = time_check::launch_table(&recs, &each, &p, k);
                    if table.is_some() {
                        break;
                    }
                }
                match table {
                    Some(t) => println!("{k}, launch by launch:\n\n{t}"),
                    None => println!("{k}: not launched the same number of times in both files\n"),
                }
            }
            every.extend(rows);
            run.kernels = gpu;
        }
        if let Some(a) = all.get(i) {
            let gpu = ncu::parse_csv(&read(a)?).map_err(|e| format!("{}: {e}", a.display()))?;
            let measured: f64 = gpu.iter().map(|g| g.seconds).sum();
            run.every = Some(measured);
            let primitives = time_check::primitives_table(&time_check::primitive_times(&recs, &gpu, &p));
            if !primitives.is_empty() {
                println!("The library primitives (emulated kernels against CUB's):\n\n{primitives}");
            }
            let predicted = time_check::predicted_total(&recs, &p);
            println!(
                "Pipeline: predicted {:.3} ms ({} launches), measured {:.3} ms ({} launches, every kernel): {:+.0} %\n",
                predicted * 1e3,
                recs.len(),
                measured * 1e3,
                gpu.iter().map(|g| g.launches).sum::<u64>(),
                (predicted - measured) / measured * 100.0
            );
        }
        run.records = recs;
        runs.push(run);
    }
    if csv.len() > 1 {
        let (mape, worst) = time_check::errors(&every);
        println!(
            "All files: mean absolute error {:.1} % over {} kernel rows; worst {}",
            mape * 100.0,
            every.len(),
            worst.map_or("-".into(), |w| format!("{} ({:+.0} %)", w.name, w.error() * 100.0))
        );
    }
    if sensitivity {
        println!(
            "\nEach profile value alone scaled: the kernels' mean absolute error; the pipelines' errors\n\n{}",
            time_check::sensitivity(&runs, &p)
        );
    }
    Ok(())
}

fn simt_run(
    input: &Input,
    kind: &str,
    out: &std::path::Path,
    launches: Option<&std::path::Path>,
) -> Result<(), String> {
    let mut p = params(input);
    p.measure = true;
    let (mut rows, mut each) = (Vec::new(), Vec::new());
    for (model, scene, name, rays, shadow) in inputs(input)? {
        // With a profile the launches also record what the time model reads.
        let dev = simt::Device::default();
        dev.set_measure(true);
        dev.set_gpu_profile(Some(simt::GpuProfile::named("h200")?));
        let start = Instant::now();
        let tris = scene.triangle_vertices();
        let caster: Box<dyn RayCaster> = match kind {
            "pdacrt" => Box::new(Pdacrt::on_device(&tris, p, dev)),
            "lbvh" => Box::new(Lbvh::on_device(&tris, dev)),
            other => return Err(format!("unknown emulated caster {other} (known: pdacrt, lbvh)")),
        };
        cast(caster.as_ref(), &rays, shadow);
        eprintln!("simt {kind} {model} {name}: {} rays, {:.1} s measured", rays.len(), start.elapsed().as_secs_f64());
        let dev = caster.device().expect("an emulated caster has a device");
        rows.extend(dev.kernel_stats());
        let log = dev.launch_log();
        if dev.launch_mark() > log.len() as u64 {
            return Err(format!("{model} {name}: more launches than the device's log keeps ({})", log.len()));
        }
        each.extend(log);
    }
    if let Some(path) = launches {
        std::fs::write(path, simt::records_to_tsv(&each)).map_err(|e| format!("{}: {e}", path.display()))?;
    }
    std::fs::write(out, tsv::write(&merge(rows))).map_err(|e| format!("{}: {e}", out.display()))
}

/// One CIS-LBDPT render per scene and order (sorted, unsorted): measured, with the
/// shading launches renamed by order, or checked bounce by bounce on the GPU.
fn cis_run(
    scenes: &[std::path::PathBuf],
    size: u32,
    simt: Option<&std::path::Path>,
    simt_launches: Option<&std::path::Path>,
) -> Result<(), String> {
    let (mut rows, mut launches, mut failed) = (Vec::new(), Vec::new(), 0usize);
    for path in scenes {
        let scene = warpray::scene::load_scene(path).map_err(|e| e.to_string())?.scene;
        let caster = BvhCaster::new(&scene);
        for sorted in [true, false] {
            let mut opts = warpray::render::RenderOptions {
                width: size,
                height: size,
                budget: warpray::render::Budget::Samples(1),
                integrator: warpray::render::IntegratorKind::Cis,
                max_depth: 8,
                ..Default::default()
            };
            (opts.cis.sort, opts.cis.measure) = (sorted, simt.is_some());
            if simt.is_some() {
                // With a profile the launches also record what the time model reads.
                opts.gpu_profile = Some(simt::GpuProfile::named("h200")?);
            }
            let name = format!("{} {}", path.display(), if sorted { "sorted" } else { "unsorted" });
            if simt.is_none() {
                let lib = warpray::gpu::library_path();
                let checks =
                    warpray::gpu::check_render(&lib, &scene, &caster, &opts).map_err(|e| format!("{name}: {e}"))?;
                for c in checks {
                    let s = &c.shade;
                    let bad = s.differ * 100 > s.lanes || !c.compaction_same;
                    failed += bad as usize;
                    println!(
                        "{} {name} bounce {}: {} samples, {} differ ({} took another branch), shade {:.3} ms; compaction {} of {} kept, {}, {:.3} ms{}",
                        if bad { "FAIL" } else { "ok" },
                        c.bounce,
                        s.lanes,
                        s.differ,
                        s.diverged,
                        s.gpu_ms,
                        c.kept,
                        c.active,
                        if c.compaction_same { "same list" } else { "LISTS DIFFER" },
                        c.compaction_ms,
                        s.first.as_ref().map_or(String::new(), |f| format!("; first: {f}"))
                    );
                }
                continue;
            }
            let mut r = warpray::render::Renderer::new(&scene, &caster, &opts).map_err(|e| e.to_string())?;
            let mut film = r.film().map_err(|e| e.to_string())?;
            r.passes(0, 1, &mut film);
            let log = r.device().map(|d| d.launch_log()).unwrap_or_default();
            if let Some(first) = log.iter().find(|l| l.name == "cis::shade") {
                print_parts(&name, first);
            }
            let order = if sorted { "cis::shade_sorted" } else { "cis::shade_unsorted" };
            let rename = |k: &mut simt::KernelSummary| match k.name {
                "cis::shade" => {
                    k.name = order;
                    true
                }
                name => name == "cis::alive_flags",
            };
            for mut k in r.device().map(|d| d.kernel_stats()).unwrap_or_default() {
                if rename(&mut k) {
                    rows.push(k);
                }
            }
            // The shading, and the compaction as the twin times it: the flags and the
            // selection launched right after them (CUB's init and sweep).
            let mut selection = 0;
            for mut l in r.device().map(|d| d.launch_log()).unwrap_or_default() {
                if l.name == "cis::shade" {
                    l.name = order;
                }
                if l.name == "cis::alive_flags" {
                    selection = 2;
                    launches.push(l);
                } else if l.name == order {
                    launches.push(l);
                } else if selection > 0 && matches!(l.name, "simt::select_init" | "simt::select_sweep") {
                    selection -= 1;
                    launches.push(l);
                } else {
                    selection = 0;
                }
            }
        }
    }
    if let Some(out) = simt {
        std::fs::write(out, tsv::write(&merge(rows))).map_err(|e| format!("{}: {e}", out.display()))?;
    }
    if let Some(out) = simt_launches {
        std::fs::write(out, simt::records_to_tsv(&launches)).map_err(|e| format!("{}: {e}", out.display()))?;
    }
    if failed > 0 {
        return Err(format!(
            "{failed} bounces differ between the GPU and the emulator (more than 1 % of samples, or the compacted list)"
        ));
    }
    Ok(())
}

/// A measured launch's instructions by part: its memory and intrinsic operations, then
/// each region's declared work (for the shading kernel: the dispatch, then the shared
/// arithmetic by part of the code), with its share of the issued instructions and its
/// SIMD efficiency: the emulator's side of `gpu_check source --lines`' table.
fn print_parts(name: &str, l: &simt::LaunchRecord) {
    let all = l.all_regions();
    let total = all.issued.max(1) as f64;
    println!(
        "{name}, first shading launch: {} warp instructions, SIMD efficiency {:.3}",
        all.issued,
        l.simd_efficiency().unwrap_or(0.0)
    );
    for r in std::iter::once(&l.ops).chain(&l.regions) {
        if r.issued > 0 {
            let simd = r.simd_efficiency().unwrap_or(0.0);
            let part = if std::ptr::eq(r, &l.ops) { "memory, intrinsics" } else { r.name };
            println!("  {part:<28} {:>6.1} %  SIMD {simd:.3}", 100.0 * r.issued as f64 / total);
        }
    }
}

/// Summaries of several runs, added up by kernel name.
pub(crate) fn merge(rows: Vec<simt::KernelSummary>) -> Vec<simt::KernelSummary> {
    let mut out: Vec<simt::KernelSummary> = Vec::new();
    for r in rows {
        match out.iter_mut().find(|o| o.name == r.name) {
            Some(o) => o.merge(&r),
            None => out.push(r),
        }
    }
    out
}

fn cast(c: &dyn RayCaster, rays: &[Ray], shadow: bool) -> (Vec<Hit>, Vec<bool>, f64) {
    let start = Instant::now();
    if shadow {
        let mut o = vec![false; rays.len()];
        c.occluded(rays, &mut o);
        (Vec::new(), o, start.elapsed().as_secs_f64())
    } else {
        let mut h = vec![Hit::MISS; rays.len()];
        c.closest(rays, &mut h);
        (h, Vec::new(), start.elapsed().as_secs_f64())
    }
}

pub(crate) fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

fn gpu_run(input: &Input, repeat: u32, cpu: &[String], brute_every: usize, json: bool) -> Result<(), String> {
    let p = params(input);
    let mut failed = 0usize;
    println!(
        "| model | batch | rays | GPU trace ms | GPU call ms | tests/ray | levels | keys = CPU PDACRT | brute-force sample | CPU casters (ms, {} threads) |",
        rayon::current_num_threads()
    );
    println!("|---|---|---:|---:|---:|---:|---:|---|---|---|");
    for (model, scene, name, rays, shadow) in inputs(input)? {
        let tris = scene.triangle_vertices();
        let gpu = GpuPdacrt::new(&tris, p).map_err(|e| e.to_string())?;
        let (mut trace, mut call) = (Vec::new(), Vec::new());
        let mut keys = Vec::new();
        for _ in 0..repeat {
            keys = gpu.trace_keys(&rays, shadow).map_err(|e| e.to_string())?;
            let s = gpu.last_stats();
            trace.push(s.trace_ms);
            call.push(s.call_ms);
        }
        let s = gpu.last_stats();
        // Bit for bit against the CPU PDACRT: the same kernels on the same data.
        let cpu_pdacrt = Pdacrt::from_triangles(&tris, p);
        let same = compare_keys(&gpu, &keys, &cpu_pdacrt, &rays, shadow);
        // Against brute force on a sample (by distance: equally valid ids may differ on shared edges).
        let brute = if brute_every > 0 {
            brute_check(&gpu, &BruteForce::new(&scene), &rays, shadow, brute_every)
        } else {
            (0, 0)
        };
        failed += same.1 + brute.1;
        let mut cpu_cells = vec![format!("pdacrt {:.1} (one run)", same.2 * 1e3)];
        for c in cpu {
            let caster: Box<dyn RayCaster> = match c.as_str() {
                "bvh" => Box::new(BvhCaster::new(&scene).with_traversal(Traversal::Fast)),
                "dacrt" => Box::new(Dacrt::new(&scene)),
                "pdacrt" => Box::new(Pdacrt::from_triangles(&tris, p)),
                other => return Err(format!("unknown CPU caster {other} (known: bvh, dacrt, pdacrt)")),
            };
            let ms = median((0..repeat.min(3)).map(|_| cast(caster.as_ref(), &rays, shadow).2 * 1e3).collect());
            cpu_cells.push(format!("{c} {ms:.1}"));
        }
        let (tm, cm) = (median(trace), median(call));
        println!(
            "| {model} | {name} | {} | {tm:.2} | {cm:.2} | {:.1} | {} | {} of {} differ | {} of {} differ | {} |",
            rays.len(),
            s.tests as f64 / rays.len().max(1) as f64,
            s.levels,
            same.1,
            same.0,
            brute.1,
            brute.0,
            cpu_cells.join(", ")
        );
        if json {
            println!(
                "{{\"device\":\"{}\",\"model\":\"{model}\",\"batch\":\"{name}\",\"rays\":{},\"trace_ms\":{tm:.3},\"call_ms\":{cm:.3},\"tests\":{},\"levels\":{},\"key_mismatches\":{},\"brute_checked\":{},\"brute_mismatches\":{},\"cpu\":\"{}\",\"threads\":{}}}",
                gpu.device_name(),
                rays.len(),
                s.tests,
                s.levels,
                same.1,
                brute.0,
                brute.1,
                cpu_cells.join(", "),
                rayon::current_num_threads()
            );
        }
        std::io::stdout().flush().ok();
    }
    if failed > 0 {
        return Err(format!("{failed} rays differ between the GPU and the CPU references"));
    }
    Ok(())
}

/// (rays compared, rays whose key differs) between the GPU's `keys` and the CPU PDACRT
/// (no second GPU trace, so a profiled run traces exactly once).
fn compare_keys(gpu: &GpuPdacrt, keys: &[u64], cpu: &Pdacrt, rays: &[Ray], shadow: bool) -> (usize, usize, f64) {
    let (ch, co, seconds) = cast(cpu, rays, shadow);
    let differ = if shadow {
        keys.iter().zip(&co).filter(|(k, b)| (**k == 0) != **b).count()
    } else {
        let mut gh = vec![Hit::MISS; rays.len()];
        gpu.hits_of_keys(rays, keys, &mut gh);
        gh.iter().zip(&ch).filter(|(a, b)| a.t.to_bits() != b.t.to_bits() || a.prim != b.prim).count()
    };
    (rays.len(), differ, seconds)
}

/// (rays checked, rays that disagree) against brute force, every `every`th ray.
pub(crate) fn brute_check(
    gpu: &dyn RayCaster,
    brute: &BruteForce,
    rays: &[Ray],
    shadow: bool,
    every: usize,
) -> (usize, usize) {
    let sample: Vec<Ray> = rays.iter().step_by(every).copied().collect();
    let (gh, go, _) = cast(gpu, &sample, shadow);
    let (bh, bo, _) = cast(brute, &sample, shadow);
    let differ = if shadow {
        go.iter().zip(&bo).filter(|(a, b)| a != b).count()
    } else {
        gh.iter()
            .zip(&bh)
            .filter(|(a, b)| a.is_hit() != b.is_hit() || (a.is_hit() && (a.t - b.t).abs() > 1e-5 * b.t.abs().max(1.0)))
            .count()
    };
    (sample.len(), differ)
}
