//! The `warpray` command. With no arguments it renders the built-in Cornell box to
//! `out.png` and `out.exr`.
//!
//! Longer than the 400-line guide (about 850 lines) on purpose: this is the whole
//! command line, `render`, `converge` and `diff` with every flag's checks made before
//! any work starts, so a reader finds each flag and its validation in one place; the
//! library holds the rest.

use clap::{Args, Parser, Subcommand};
use indicatif::{ProgressBar, ProgressStyle};
use std::path::PathBuf;
use std::process::ExitCode;
use std::time::Duration;
use warpray::cast::{BvhCaster, CasterKind, RayCaster, Traversal};
use warpray::error::{Error, Result};
use warpray::render::{Budget, IntegratorKind, RenderOptions, Variant, render};
use warpray::scene::load_scene;

#[derive(Parser)]
#[command(name = "warpray", version, about = "GPU ray-tracing algorithms on CPUs, measured as a GPU would be")]
#[command(args_conflicts_with_subcommands = true)]
struct Cli {
    #[command(subcommand)]
    command: Option<Command>,
    /// With no subcommand, `warpray [OPTIONS] [SCENE]` is `warpray render [OPTIONS] [SCENE]`.
    #[command(flatten)]
    render: RenderArgs,
}

// Parsed once per run: the render arguments' size does not matter.
#[allow(clippy::large_enum_variant)]
#[derive(Subcommand)]
enum Command {
    /// Render a scene to PNG and/or EXR (the default command).
    Render(RenderArgs),
    /// Speed against accuracy: error against a reference over time, per integrator,
    /// written as CSV and a log-log chart.
    Converge(ConvergeArgs),
    /// Compare two images (EXR or PNG, same size): per-channel means, RMSE, relMSE,
    /// largest difference.
    Diff(DiffArgs),
}

#[derive(Args)]
struct DiffArgs {
    /// The reference image.
    reference: PathBuf,
    /// The image to compare with it.
    test: PathBuf,
    /// relMSE offset: (x − r)² / (r² + EPSILON).
    #[arg(long, default_value_t = warpray::diff::DEFAULT_EPSILON)]
    epsilon: f64,
    /// Print one JSON object instead of the table.
    #[arg(long)]
    json: bool,
    /// Exit with status 1 when the RMSE is above this, or when the test image has a
    /// NaN or infinite pixel (unless --ignore-nonfinite), or no pixel could be
    /// compared; status 2 means the images could not be compared at all.
    #[arg(long)]
    fail_above: Option<f64>,
    /// With --fail-above: NaN and infinite pixels of the test image (still counted
    /// and reported) do not fail the gate by themselves.
    #[arg(long, requires = "fail_above")]
    ignore_nonfinite: bool,
}

/// `warpray diff`; `Ok(true)` when `--fail-above` was exceeded.
fn run_diff(args: DiffArgs) -> Result<bool> {
    if let Some(limit) = args.fail_above {
        warpray::diff::check_limit(limit)?;
    }
    let d = warpray::diff::diff(&args.reference, &args.test, args.epsilon)?;
    if args.json {
        println!("{}", d.to_json());
    } else {
        let m = |v: [f64; 3]| format!("{:.6} {:.6} {:.6}", v[0], v[1], v[2]);
        println!("{}x{} pixels", d.width, d.height);
        println!("mean RGB  reference {}  test {}", m(d.mean_reference), m(d.mean_test));
        println!("RMSE      {:.6e}", d.rmse);
        println!("relMSE    {:.6e}  (ε = {})", d.relmse, d.epsilon);
        println!("max |Δ|   {:.6e}  in {} differing pixels", d.max_abs, d.differing_pixels);
        if d.non_finite != (0, 0) {
            println!("NaN/Inf   {} in the reference, {} in the test (left out)", d.non_finite.0, d.non_finite.1);
        }
        if d.compared == 0 {
            println!("no pixel is finite in both images: nothing was compared");
        }
    }
    match args.fail_above {
        Some(limit) => d.fails(limit, args.ignore_nonfinite),
        None => Ok(false),
    }
}

#[derive(Args)]
struct ConvergeArgs {
    /// Scene, as for `render`.
    #[arg(default_value = "cornell")]
    scene: PathBuf,
    /// Integrators to compare, comma-separated: path, light, bdpt, lvc, lvc-mk (LVC-BDPT
    /// as megakernels on the simt device), cis, and the CIS ablations cis-nosort,
    /// cis-nois, cis-nocompact.
    #[arg(long, value_delimiter = ',', default_value = "path,light,bdpt")]
    integrators: Vec<String>,
    /// Time budget of each integrator, seconds.
    #[arg(long, default_value_t = 10.0)]
    seconds: f64,
    /// Log-spaced error checkpoints per integrator.
    #[arg(long, default_value_t = 24)]
    checkpoints: usize,
    /// Reference image (linear EXR of the same size). Without it, one is rendered.
    #[arg(long)]
    reference: Option<PathBuf>,
    /// Samples per pixel of a rendered reference (at least 1).
    #[arg(long, default_value_t = 4096, value_parser = clap::value_parser!(u32).range(1..))]
    reference_spp: u32,
    /// Integrator of a rendered reference.
    #[arg(long, value_enum, default_value = "path")]
    reference_integrator: IntegratorKind,
    /// Camera samples per pixel against each light pass of the integrators with a light
    /// vertex cache (lvc, lvc-mk, cis and its ablations; path, light and bdpt have none).
    #[arg(long, default_value_t = 1, value_parser = clap::value_parser!(u32).range(1..=1024))]
    spp_per_iteration: u32,
    /// Image size as WIDTHxHEIGHT.
    #[arg(long, value_parser = parse_size, default_value = "128x128")]
    size: (u32, u32),
    /// Largest number of bounces (default: the scene file's, else 8).
    #[arg(long)]
    max_depth: Option<u32>,
    /// Bounces after which the path tracer's Russian roulette starts (default: the
    /// scene file's, else 4).
    #[arg(long, value_parser = clap::value_parser!(u32).range(1..))]
    rr_depth: Option<u32>,
    #[arg(long, default_value_t = 0)]
    seed: u64,
    #[arg(long)]
    threads: Option<usize>,
    /// Render nothing: read the checkpoints from this CSV (written by an earlier run)
    /// and write PREFIX.svg and PREFIX.png from them, with the summary table.
    #[arg(long, conflicts_with_all = ["reference", "integrators", "seconds"])]
    replot: Option<PathBuf>,
    /// Output prefix: writes PREFIX.csv, PREFIX.svg, PREFIX.png (and
    /// PREFIX-reference.exr when the reference is rendered here).
    #[arg(short, long, default_value = "converge")]
    output: PathBuf,
}

#[derive(Args)]
struct RenderArgs {
    /// Scene: a .toml scene file, an .obj/.obj.gz file, a built-in scene (bunny, dragon,
    /// conference, dabrovic-sponza: their models come from $WARPRAY_MODELS), a model
    /// name found in $WARPRAY_MODELS (e.g. `cornell-box`), or `cornell` for the
    /// built-in box.
    #[arg(default_value = "cornell")]
    scene: PathBuf,
    /// Light-transport algorithm [default: path, or the scene file's]: path, light,
    /// bdpt, lvc, lvc-mk (LVC-BDPT as megakernels on the simt device), cis, and the CIS
    /// ablations cis-nosort, cis-nois, cis-nocompact (the labels `converge` takes).
    #[arg(long, value_parser = parse_variant)]
    integrator: Option<Variant>,
    /// Samples per pixel [default: 64, or the scene file's].
    #[arg(long, conflicts_with = "seconds")]
    spp: Option<u32>,
    /// Render for this many seconds instead of a sample count.
    #[arg(long)]
    seconds: Option<f64>,
    /// Image size as WIDTHxHEIGHT [default: 512x512, or the scene file's].
    #[arg(long, value_parser = parse_size)]
    size: Option<(u32, u32)>,
    /// Largest number of bounces (0: emitters only, 1: direct light) [default: 8].
    #[arg(long)]
    max_depth: Option<u32>,
    /// Bounces after which the path tracer's Russian roulette starts (Mitsuba's
    /// rr_depth) [default: 4, or the scene file's; Mitsuba scenes: their rr_depth or 5].
    #[arg(long, value_parser = clap::value_parser!(u32).range(1..))]
    rr_depth: Option<u32>,
    /// Pixel filter: box, gaussian (sigma 0.5, radius 2, from Mitsuba's 31-step table) or
    /// gaussian:SIGMA:RADIUS (the exact Gaussian), RADIUS in [0.5, 16] and SIGMA in [0.01, 16 × RADIUS]
    /// [default: box, or the scene file's].
    #[arg(long)]
    filter: Option<warpray::filter::Filter>,
    /// How camera samples meet the filter: sample (drawn from the filter and weighted,
    /// pbrt-v4) or splat (spread over the pixels it covers and normalised, Mitsuba 3)
    /// [default: sample, or the scene file's; Mitsuba XML scenes: splat].
    #[arg(long)]
    filter_mode: Option<warpray::filter::FilterMode>,
    /// Worker threads [default: all cores].
    #[arg(long)]
    threads: Option<usize>,
    /// Random seed; the same seed gives the same image at any thread count.
    #[arg(long)]
    seed: Option<u64>,
    /// LVC-BDPT and CIS-LBDPT (lvc, lvc-mk, cis and its ablations): camera samples per
    /// pixel rendered against each iteration's light pass, which they share (the
    /// CIS-LBDPT paper renders 4–8) [default: 1].
    #[arg(long, value_parser = clap::value_parser!(u32).range(1..=1024))]
    spp_per_iteration: Option<u32>,
    /// CIS-LBDPT (cis and its ablations): samples in flight, the camera pass's pool and
    /// the light pass's batch [default: 65536]. A pool of the image's pixels or more
    /// holds every pixel at once, as the GPU renders that docs/simt.md measures do.
    #[arg(long, value_name = "N", value_parser = clap::value_parser!(u32).range(1..))]
    cis_pool: Option<u32>,
    /// Ray caster: `bvh4`, warpray's own BVH, by default (docs/bvh.md).
    #[arg(long, value_enum, default_value = "bvh4")]
    caster: CasterKind,
    /// With `--integrator lvc`: the same as `--integrator lvc-mk`, LVC-BDPT as
    /// megakernels on the simt device (one thread per subpath, rays traced one at a
    /// time); the image is the same.
    #[arg(long)]
    megakernel: bool,
    /// How the obvhs BVH caster (`--caster bvh`) traverses: `fast` is obvhs' traversal over boxes padded so
    /// that its rounding never rejects a box a ray enters (docs/bvh.md); `checked`
    /// also re-checks every miss and unblocked shadow ray with the robust traversal;
    /// `robust` is the robust traversal for every ray.
    #[arg(long, value_enum, default_value = "fast")]
    bvh_traversal: Traversal,
    /// Output files; the extension (.png or .exr) picks the format. May be repeated.
    #[arg(short, long = "output", default_values = ["out.png", "out.exr"])]
    output: Vec<PathBuf>,
    /// Exposure multiplier applied before the PNG tone map (EXR stays linear): finite
    /// and not negative.
    #[arg(long, default_value_t = 1.0, value_parser = parse_exposure)]
    exposure: f32,
    /// No progress bar.
    #[arg(long, short)]
    quiet: bool,
    /// Auxiliary images to add to the EXR output as extra channels, comma-separated:
    /// albedo (Albedo.R/G/B), normal (N.X/Y/Z), depth (Z), variance (Variance.R/G/B).
    /// The first three come from 16 extra camera rays per pixel.
    #[arg(long, value_enum, value_delimiter = ',')]
    aov: Vec<warpray::aov::Aov>,
    /// At the end, print what the render did: rays by kind, Mrays/s, cast against
    /// shade time, memory, and the simt kernel table of the GPU methods.
    #[arg(long)]
    stats: bool,
    /// Predict the GPU time of the render's emulated kernels (CIS-LBDPT, the LVC
    /// megakernel, the PDACRT caster) on a GPU: a shipped profile's name (h200) or a
    /// profile file (simt/profiles/). Turns the emulator's measurement on, which slows
    /// the render, and prints the kernel table with a predicted GPU ms column.
    #[arg(long, value_parser = simt::GpuProfile::load)]
    gpu_profile: Option<simt::GpuProfile>,
    /// With --gpu-profile: write the emulated kernels' launch records to FILE (.tsv), one
    /// row a launch (grid, block, the meter's instructions, requests, sectors and
    /// chains), the records `gpu_check time --records` predicts from (docs/gpu-check.md).
    #[arg(long, value_name = "FILE", requires = "gpu_profile")]
    launch_records: Option<PathBuf>,
    /// Render on an NVIDIA GPU (cargo feature `cuda`, the library of `sh cuda/build.sh`):
    /// CIS-LBDPT (`--integrator cis` and its ablations) or the LVC-BDPT megakernels
    /// (`lvc-mk`), whole passes on the device over its own BVH (docs/gpu-check.md).
    #[cfg(feature = "cuda")]
    #[arg(long, conflicts_with_all = ["aov", "gpu_profile", "threads"])]
    gpu: bool,
}

/// `--integrator`: a label of the integrator registry.
fn parse_exposure(s: &str) -> std::result::Result<f32, String> {
    match s.parse::<f32>() {
        Ok(x) if x.is_finite() && x >= 0.0 => Ok(x),
        Ok(x) => Err(format!("{x} is not a finite multiplier of 0 or more")),
        Err(_) => Err(format!("'{s}' is not a number")),
    }
}

fn parse_variant(s: &str) -> std::result::Result<Variant, String> {
    Variant::parse(s).map_err(|e| e.to_string())
}

fn parse_size(s: &str) -> std::result::Result<(u32, u32), String> {
    let (w, h) = s.split_once(['x', 'X']).ok_or("expected WIDTHxHEIGHT, e.g. 640x480")?;
    let w = w.trim().parse::<u32>().map_err(|e| format!("width: {e}"))?;
    let h = h.trim().parse::<u32>().map_err(|e| format!("height: {e}"))?;
    Ok((w, h))
}

/// Ctrl-C during a render or `converge`: the first asks the render loop to stop after
/// the pass it is in (the image, or what `converge` measured, is then written as usual,
/// and the command exits with status 130), the second exits at once with status 130.
/// Images are written under a temporary name and renamed, so neither leaves a
/// half-written file behind.
mod interrupt {
    use std::sync::atomic::{AtomicUsize, Ordering};

    static COUNT: AtomicUsize = AtomicUsize::new(0);

    #[cfg(unix)]
    extern "C" fn on_sigint(_: libc::c_int) {
        // Only async-signal-safe calls here: an atomic, write(2) and _exit(2).
        if COUNT.fetch_add(1, Ordering::SeqCst) == 0 {
            let msg = b"\ninterrupted: finishing this pass and writing what was done (Ctrl-C again to quit now)\n";
            // SAFETY: write(2) on stderr with a valid buffer.
            unsafe { libc::write(2, msg.as_ptr().cast(), msg.len()) };
        } else {
            // SAFETY: _exit(2) ends the process without running anything else.
            unsafe { libc::_exit(130) };
        }
    }

    /// Installs the handler (Unix; elsewhere Ctrl-C keeps its default meaning).
    pub fn install() {
        #[cfg(unix)]
        // SAFETY: the handler only touches an atomic and calls async-signal-safe functions.
        unsafe {
            libc::signal(libc::SIGINT, on_sigint as *const () as libc::sighandler_t);
        }
    }

    pub fn requested() -> bool {
        COUNT.load(Ordering::SeqCst) > 0
    }
}

/// Exit status of a render stopped by Ctrl-C (128 + SIGINT, as shells report it).
const INTERRUPTED: u8 = 130;

/// How a command that did not fail ended.
enum Stop {
    Done,
    /// Ctrl-C: the images hold the passes done.
    Interrupted,
    /// `diff --fail-above` was exceeded.
    Differs,
}

/// Every output path, checked before any work: a known extension, an existing folder,
/// and one we may create files in (a probe file is made and removed).
fn check_outputs(outputs: &[PathBuf], extensions: &[&str]) -> Result<()> {
    for out in outputs {
        let bad = |msg: String| Err(Error::Output { path: out.clone(), msg });
        let ext = out.extension().and_then(|e| e.to_str()).map(str::to_ascii_lowercase);
        if !ext.as_deref().is_some_and(|e| extensions.contains(&e)) {
            return bad(format!("use a file name ending in .{}", extensions.join(" or .")));
        }
        let dir = match out.parent() {
            Some(d) if !d.as_os_str().is_empty() => d.to_path_buf(),
            _ => PathBuf::from("."),
        };
        if !dir.is_dir() {
            return bad(format!("the folder {} does not exist", dir.display()));
        }
        if out.is_dir() {
            return bad("is a folder".into());
        }
        let probe = dir.join(format!(".warpray-probe.{}", std::process::id()));
        match std::fs::File::create(&probe) {
            Ok(_) => {
                let _ = std::fs::remove_file(&probe);
            }
            Err(e) => return bad(format!("cannot create files in {}: {e}", dir.display())),
        }
    }
    Ok(())
}

/// Renders; `Ok(true)` when Ctrl-C stopped it early (the image was still written).
/// `render --gpu`: the passes on the GPU, then the outputs and a summary line.
#[cfg(feature = "cuda")]
fn render_on_gpu(
    args: &RenderArgs,
    desc: &warpray::scene::SceneDesc,
    opts: &RenderOptions,
    label: &str,
) -> Result<bool> {
    let bar = if args.quiet { ProgressBar::hidden() } else { progress_bar(opts.budget) };
    let start = std::time::Instant::now();
    interrupt::install();
    let (film, run) = warpray::gpu::render_on_gpu(&desc.scene, opts, |pass| {
        match opts.budget {
            Budget::Samples(_) => bar.set_position(pass as u64),
            Budget::Seconds(_) => bar.set_position(start.elapsed().as_millis() as u64),
        }
        !interrupt::requested()
    })?;
    bar.finish_and_clear();
    let metadata = [
        ("scene", desc.scene.source.display().to_string()),
        ("integrator", label.to_string()),
        ("device", "gpu".to_string()),
        ("spp", run.passes.to_string()),
        ("seed", opts.seed.to_string()),
        ("max_depth", opts.max_depth.to_string()),
        ("seconds", format!("{:.3}", run.seconds)),
        ("version", env!("CARGO_PKG_VERSION").to_string()),
    ];
    for out in &args.output {
        film.write_with(out, args.exposure, &metadata)?;
    }
    let outs: Vec<String> = args.output.iter().map(|p| p.display().to_string()).collect();
    println!(
        "{}: {} triangles, {}x{}, {} spp, {label} on the GPU: {:.2} s ({:.2} ms GPU per pass, of which light {:.2}; read-back {:.2}; BVH build {:.2} ms); wrote {}",
        desc.scene.source.display(),
        desc.scene.triangle_count(),
        opts.width,
        opts.height,
        run.passes,
        run.seconds,
        run.gpu_ms / run.passes.max(1) as f64,
        run.light_ms / run.passes.max(1) as f64,
        run.readback_ms / run.passes.max(1) as f64,
        run.build_ms,
        outs.join(", ")
    );
    Ok(interrupt::requested())
}

fn run_render(args: RenderArgs) -> Result<bool> {
    check_outputs(&args.output, &["png", "exr"])?;
    if let Some(f) = &args.launch_records {
        check_outputs(std::slice::from_ref(f), &["tsv"])?;
    }
    let is_exr = |p: &PathBuf| p.extension().is_some_and(|e| e.eq_ignore_ascii_case("exr"));
    if !args.aov.is_empty() && !args.output.iter().any(is_exr) {
        return Err(Error::BadSetting("--aov adds channels to an EXR: give an -o FILE.exr output".into()));
    }
    let desc = load_scene(&args.scene)?;
    let s = &desc.settings;
    let (width, height) = args.size.unwrap_or((s.width.unwrap_or(512), s.height.unwrap_or(512)));
    let mut variant = match (args.integrator, &s.integrator) {
        (Some(v), _) => v,
        (None, Some(name)) => Variant::parse(name)?,
        (None, None) => Variant::of(IntegratorKind::Path),
    };
    if args.megakernel {
        if variant.kind != IntegratorKind::Lvc {
            return Err(Error::BadSetting(format!(
                "--megakernel runs LVC-BDPT on the device; it needs --integrator lvc, not {}",
                variant.label
            )));
        }
        variant = Variant::parse("lvc-mk")?;
    }
    let budget = match (args.spp, args.seconds, s.spp, s.seconds) {
        (Some(n), ..) => Budget::Samples(n),
        (None, Some(t), ..) => Budget::Seconds(t),
        (None, None, Some(n), _) => Budget::Samples(n),
        (None, None, None, Some(t)) => Budget::Seconds(t),
        _ => Budget::Samples(64),
    };
    if budget == Budget::Samples(0) {
        return Err(Error::BadSetting("--spp must be at least 1".into()));
    }
    if budget == Budget::Samples(1) && args.aov.contains(&warpray::aov::Aov::Variance) {
        return Err(Error::BadSetting(
            "--aov variance needs at least 2 samples per pixel (the variance of one estimate is undefined); \
             use --spp 2 or more"
                .into(),
        ));
    }
    // The scene file's depth and filter, unless a flag says otherwise.
    let mut opts = variant.apply(RenderOptions::for_scene(
        s,
        RenderOptions { width, height, budget, seed: args.seed.or(s.seed).unwrap_or(0), ..Default::default() },
    ));
    opts.max_depth = args.max_depth.unwrap_or(opts.max_depth);
    opts.rr_depth = args.rr_depth.unwrap_or(opts.rr_depth);
    opts.filter = args.filter.unwrap_or(opts.filter);
    opts.filter_mode = args.filter_mode.unwrap_or(opts.filter_mode);
    opts.gpu_profile = args.gpu_profile.clone();
    if let Some(k) = args.spp_per_iteration {
        if !matches!(opts.integrator, IntegratorKind::Lvc | IntegratorKind::LvcMegakernel | IntegratorKind::Cis) {
            return Err(Error::BadSetting(format!(
                "--spp-per-iteration sets how many passes share a light vertex cache; {} has none \
                 (it applies to lvc, lvc-mk and cis)",
                variant.label
            )));
        }
        if k > 1 && args.aov.contains(&warpray::aov::Aov::Variance) {
            return Err(Error::BadSetting(
                "--aov variance is the variance between independent passes; with --spp-per-iteration above 1 \
                 the passes of an iteration share a light vertex cache and are not independent"
                    .into(),
            ));
        }
        opts.set_samples_per_iteration(k);
    }
    if let Some(n) = args.cis_pool {
        if opts.integrator != IntegratorKind::Cis {
            return Err(Error::BadSetting(format!(
                "--cis-pool sets CIS-LBDPT's samples in flight; {} has no pool (it applies to cis and its ablations)",
                variant.label
            )));
        }
        opts.cis.pool = n;
    }
    warpray::film::check_size(width, height)?;
    desc.scene.check_renderable()?;

    #[cfg(feature = "cuda")]
    if args.gpu {
        return render_on_gpu(&args, &desc, &opts, variant.label);
    }
    let pool = thread_pool(args.threads)?;
    let threads = pool.current_num_threads();

    pool.install(|| {
        let caster: Box<dyn RayCaster> = match args.caster {
            CasterKind::Bvh => Box::new(BvhCaster::new(&desc.scene).with_traversal(args.bvh_traversal)),
            kind => kind.build(&desc.scene)?,
        };
        let bar = if args.quiet { ProgressBar::hidden() } else { progress_bar(budget) };
        let start = std::time::Instant::now();
        interrupt::install();
        let (film, stats) = render(&desc.scene, caster.as_ref(), &opts, |pass, _| {
            match budget {
                Budget::Samples(_) => bar.set_position(pass as u64),
                Budget::Seconds(_) => bar.set_position(start.elapsed().as_millis() as u64),
            }
            bar.set_message(format!("{pass} spp"));
            !interrupt::requested()
        })?;
        bar.finish_and_clear();
        let interrupted = interrupt::requested();
        let metadata = [
            ("scene", desc.scene.source.display().to_string()),
            ("integrator", variant.label.to_string()),
            ("caster", caster.name().to_string()),
            ("spp", stats.passes.to_string()),
            ("seed", opts.seed.to_string()),
            ("max_depth", opts.max_depth.to_string()),
            ("rr_depth", opts.rr_depth.to_string()),
            ("filter", format!("{:?}", opts.filter)),
            ("filter_mode", opts.filter_mode.name().to_string()),
            ("seconds", format!("{:.3}", stats.seconds)),
            ("interrupted", interrupted.to_string()),
            ("version", env!("CARGO_PKG_VERSION").to_string()),
        ];
        let aovs = if args.aov.is_empty() {
            Vec::new()
        } else {
            let geometric = args.aov.iter().any(|a| *a != warpray::aov::Aov::Variance);
            let gbuffer = if geometric {
                Some(warpray::aov::render_gbuffer(&desc.scene, caster.as_ref(), width, height, AOV_SAMPLES, opts.seed)?)
            } else {
                None
            };
            warpray::aov::channels(&args.aov, &film, gbuffer.as_ref())
        };
        for out in &args.output {
            if is_exr(out) {
                film.write_exr_aovs(out, &metadata, &aovs)?;
            } else {
                film.write_with(out, args.exposure, &metadata)?;
            }
        }
        if interrupted {
            eprintln!("interrupted after {} passes; the images hold those passes", stats.passes);
        }
        let outs: Vec<String> = args.output.iter().map(|p| p.display().to_string()).collect();
        println!(
            "{}: {} triangles, {}x{}, {} spp, {} + {} on {} threads: {:.2} s, {:.2} Mrays/s (build {:.3} s); wrote {}",
            desc.scene.source.display(),
            desc.scene.triangle_count(),
            width,
            height,
            stats.passes,
            variant.label,
            caster.name(),
            threads,
            stats.seconds,
            stats.rays_per_second() / 1e6,
            caster.build_seconds(),
            outs.join(", ")
        );
        if args.stats || args.gpu_profile.is_some() {
            print!("{}", stats_report(&stats, caster.as_ref(), &desc.scene, &film, threads));
        }
        if let (Some(p), Some((kernels, _))) = (&args.gpu_profile, &stats.device) {
            let gpu: f64 = kernels.iter().map(|k| k.gpu_seconds).sum();
            let cpu: f64 = kernels.iter().map(|k| k.seconds).sum();
            println!(
                "  GPU time predicted on {} (simt/profiles, docs/simt.md): {:.3} ms of kernels, against {:.3} ms emulated (measured) on {threads} CPU threads",
                p.name,
                gpu * 1e3,
                cpu * 1e3
            );
            if !cfg!(feature = "model-arithmetic") {
                eprintln!(
                    "warning: this build does not count the arithmetic of the code the kernels share with the CPU integrators (BSDFs, sampling, connections), so CIS shading and the megakernels are predicted short; build with --features model-arithmetic (or cuda)"
                );
            }
        }
        if let Some(path) = &args.launch_records {
            write_launch_records(path, &stats.launches)?;
        }
        if film.rejected > 0 {
            eprintln!("warning: {} sample estimates were NaN, infinite or negative and were dropped", film.rejected);
        }
        Ok(interrupted)
    })
}

/// `--launch-records`: the device's launch log as the TSV `gpu_check time --records`
/// reads, written whole or not at all; says so when the log no longer holds the first.
fn write_launch_records(path: &std::path::Path, (log, made): &(Vec<simt::LaunchRecord>, u64)) -> Result<()> {
    if (log.len() as u64) < *made {
        eprintln!(
            "warning: the render made {made} kernel launches; the device's log keeps the last {}, which {} holds",
            log.len(),
            path.display()
        );
    }
    let text = simt::records_to_tsv(log);
    warpray::film::atomic_write(path, |tmp| std::fs::write(tmp, &text).map_err(|e| e.to_string()))?;
    println!("wrote {} launch records to {}", log.len(), path.display());
    Ok(())
}

/// `--stats`: what the render did, as a few aligned lines and the kernel table.
fn stats_report(
    stats: &warpray::render::RenderStats,
    caster: &dyn RayCaster,
    scene: &warpray::scene::Scene,
    film: &warpray::film::Film,
    threads: usize,
) -> String {
    use std::fmt::Write;
    let mb = |b: usize| {
        if b < 1_000_000 { format!("{:.1} kB", b as f64 / 1e3) } else { format!("{:.1} MB", b as f64 / 1e6) }
    };
    let closest = stats.rays - stats.shadow_rays;
    let per_call = if stats.cast_calls > 0 { stats.rays as f64 / stats.cast_calls as f64 } else { 0.0 };
    let mut s = String::from("statistics\n");
    let _ = writeln!(s, "  passes      {} ({} samples per pixel)", stats.passes, stats.passes);
    let _ = writeln!(
        s,
        "  rays        {} = {} closest-hit (camera, bounce, light) + {} shadow/connection, in {} caster calls ({:.0} rays per call)",
        stats.rays, closest, stats.shadow_rays, stats.cast_calls, per_call
    );
    let _ = writeln!(
        s,
        "  speed       {:.2} Mrays/s over the render's wall time; {:.2} ray-triangle tests per ray",
        stats.rays_per_second() / 1e6,
        if stats.rays > 0 { stats.tests as f64 / stats.rays as f64 } else { 0.0 }
    );
    // Calls made in parallel each count their own wall time, so the caster's sum can
    // exceed the render's wall time; shading is what remains only when it does not.
    let cast = stats.cast_seconds;
    let shade = if stats.single_rays > 0 {
        format!("{} rays cast one at a time in kernel threads, untimed, in the rest", stats.single_rays)
    } else if cast <= stats.seconds && !stats.cast_overlapped {
        format!("{:.3} s shading and the rest", stats.seconds - cast)
    } else {
        format!("casts overlapped on {threads} threads, so shading time is not the difference")
    };
    let _ = writeln!(
        s,
        "  time        {:.3} s wall: {:.3} s inside the caster (summed over calls), {shade}; caster build {:.3} s",
        stats.seconds,
        cast,
        caster.build_seconds()
    );
    let _ = writeln!(
        s,
        "  memory      scene {}, caster structure {}, film {}, caster working peak {}{}",
        mb(scene.memory_bytes()),
        mb(caster.memory_bytes()),
        mb(film.memory_bytes()),
        mb(stats.peak_working_bytes),
        peak_rss().map_or(String::new(), |b| format!(", process peak RSS {}", mb(b)))
    );
    if let Some((kernels, peak)) = &stats.device {
        let _ = writeln!(s, "  simt device peak memory {}; kernels:", mb(*peak));
        if kernels.iter().all(|k| k.measured_launches == 0) {
            let _ = writeln!(
                s,
                "    (measurement off, as renders run it for speed: SIMD efficiency and sectors per request are shown by the inspector and the kernel examples)"
            );
        }
        let mut rows = kernels.clone();
        rows.sort_by(|a, b| b.seconds.total_cmp(&a.seconds));
        for line in simt::stats::format_table(&rows).lines() {
            let _ = writeln!(s, "    {line}");
        }
    }
    s
}

/// The process's peak resident memory (Linux: `VmHWM` of /proc/self/status).
fn peak_rss() -> Option<usize> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = status.lines().find(|l| l.starts_with("VmHWM:"))?;
    let kb: usize = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kb * 1024)
}

/// Camera rays per pixel of the geometric AOVs (albedo, normal, depth).
const AOV_SAMPLES: u32 = 16;

/// Most worker threads `--threads` accepts (thousands of OS threads only thrash).
const MAX_THREADS: usize = 1024;

fn thread_pool(threads: Option<usize>) -> Result<rayon::ThreadPool> {
    let mut pool = rayon::ThreadPoolBuilder::new();
    if let Some(n) = threads {
        if n == 0 || n > MAX_THREADS {
            return Err(Error::BadSetting(format!("--threads must be between 1 and {MAX_THREADS}, not {n}")));
        }
        pool = pool.num_threads(n);
    }
    pool.build().map_err(|e| Error::BadSetting(format!("thread pool: {e}")))
}

/// `converge`; true when Ctrl-C stopped it (what was measured is written all the same).
fn run_converge(args: ConvergeArgs) -> Result<bool> {
    use warpray::converge::{
        ConvergeOptions, common_target, labels, read_csv, read_exr, reference_key, run, summarize, summary_table,
        write_chart, write_csv,
    };
    let with_ext = |ext: &str| {
        let mut name = args.output.clone().into_os_string();
        name.push(ext);
        PathBuf::from(name)
    };
    let finish = |rows: &[warpray::converge::Checkpoint], labels: &[&str], title: &str| -> Result<()> {
        write_chart(&with_ext(".svg"), rows, title)?;
        write_chart(&with_ext(".png"), rows, title)?;
        // The time each integrator needs to reach the worst final RMSE of them all, and
        // the paper-style table against the first integrator listed.
        println!("time to reach RMSE {:.5}:", common_target(rows, labels));
        let summaries = summarize(rows, labels);
        for s in &summaries {
            match s.seconds_to_target {
                Some(t) => println!("  {:>13}: {t:.2} s", s.integrator),
                None => println!("  {:>13}: not reached", s.integrator),
            }
        }
        print!("{}", summary_table(&summaries));
        Ok(())
    };
    if let Some(csv) = &args.replot {
        check_outputs(&[with_ext(".svg")], &["svg"])?;
        check_outputs(&[with_ext(".png")], &["png"])?;
        let rows = read_csv(csv)?;
        let labels = labels(&rows);
        finish(&rows, &labels, &format!("{}: error against time", args.scene.display()))?;
        println!("wrote {}, {}", with_ext(".svg").display(), with_ext(".png").display());
        return Ok(false);
    }
    let desc = load_scene(&args.scene)?;
    let (width, height) = args.size;
    warpray::film::check_size(width, height)?;
    if !(args.seconds > 0.0 && args.seconds <= warpray::render::MAX_SECONDS) {
        return Err(Error::BadSetting(format!(
            "--seconds must be positive and at most {:e}, not {}",
            warpray::render::MAX_SECONDS,
            args.seconds
        )));
    }
    // Everything that can be wrong is found before the reference is rendered.
    let integrators = args.integrators.iter().map(|n| Variant::parse(n)).collect::<Result<Vec<_>>>()?;
    check_outputs(&[with_ext(".csv")], &["csv"])?;
    check_outputs(&[with_ext(".svg")], &["svg"])?;
    check_outputs(&[with_ext(".png")], &["png"])?;
    match &args.reference {
        Some(r) if !r.is_file() => {
            return Err(Error::BadSetting(format!("--reference {}: no such file", r.display())));
        }
        Some(_) => {}
        None => check_outputs(&[with_ext("-reference.exr")], &["exr"])?,
    }
    // What the image means (depth, filter) comes from the scene file unless a flag says.
    let mut image = RenderOptions::for_scene(&desc.settings, RenderOptions { width, height, ..Default::default() });
    if let Some(d) = args.max_depth {
        image.max_depth = d;
    }
    image.rr_depth = args.rr_depth.unwrap_or(image.rr_depth);
    let pool = thread_pool(args.threads)?;
    interrupt::install();
    pool.install(|| {
        let caster = warpray::cast::Bvh4::new(&desc.scene);
        let reference = match &args.reference {
            Some(path) => {
                let (w, h, px) = read_exr(path)?;
                if (w, h) != (width, height) {
                    return Err(Error::BadSetting(format!(
                        "{} is {w}x{h}; the render is {width}x{height}",
                        path.display()
                    )));
                }
                px
            }
            None => {
                let opts = RenderOptions {
                    budget: Budget::Samples(args.reference_spp),
                    seed: args.seed ^ 0x5_eed0_f7ef,
                    integrator: args.reference_integrator,
                    ..image.clone()
                };
                // A reference this command rendered before for the same scene and
                // settings is read back instead of rendered again.
                let (cached, key) = (with_ext("-reference.exr"), reference_key(&desc.scene, &opts));
                let same = |m: Vec<(String, String)>| m.iter().any(|(k, v)| k == "reference_key" && *v == key);
                let reuse = cached.is_file() && warpray::film::read_exr_metadata(&cached).is_ok_and(same);
                match reuse.then(|| read_exr(&cached)).transpose()? {
                    Some((w, h, px)) if (w, h) == (width, height) => {
                        eprintln!("reusing {} (same scene and settings; delete it to render again)", cached.display());
                        px
                    }
                    _ => {
                        eprintln!(
                            "rendering the reference: {} at {} spp ...",
                            opts.integrator.name(),
                            args.reference_spp
                        );
                        match render_reference(&desc.scene, &caster, &opts, &cached, key)? {
                            Some(px) => px,
                            None => return Ok(true),
                        }
                    }
                }
            }
        };
        let opts = ConvergeOptions {
            integrators,
            seconds: args.seconds,
            checkpoints: args.checkpoints,
            width,
            height,
            max_depth: image.max_depth,
            rr_depth: image.rr_depth,
            seed: args.seed,
            filter: image.filter,
            filter_mode: image.filter_mode,
            samples_per_iteration: args.spp_per_iteration,
        };
        let rows = run(
            &desc.scene,
            &caster,
            &reference,
            &opts,
            |r| {
                eprintln!(
                    "{:>6} {:8.2} s {:6} spp  RMSE {:.5}  relMSE {:.5}",
                    r.integrator, r.seconds, r.spp, r.rmse, r.relmse
                )
            },
            interrupt::requested,
        )?;
        let interrupted = interrupt::requested();
        if interrupted {
            eprintln!("interrupted: writing the {} measurements made", rows.len());
        }
        write_csv(&with_ext(".csv"), &rows)?;
        // The integrators measured (all of them unless Ctrl-C came first).
        let labels: Vec<&str> =
            opts.integrators.iter().map(|k| k.label).filter(|l| rows.iter().any(|r| r.integrator == *l)).collect();
        finish(&rows, &labels, &format!("{}: error against time", desc.scene.source.display()))?;
        println!(
            "wrote {}, {}, {}",
            with_ext(".csv").display(),
            with_ext(".svg").display(),
            with_ext(".png").display()
        );
        Ok(interrupted)
    })
}

/// Renders `converge`'s reference with `opts`, writes it to `path` with its `key`
/// (`converge::reference_key`) and returns its pixels; `None` when Ctrl-C stopped it: a
/// partial reference would make every error against it wrong, so nothing is written.
fn render_reference(
    scene: &warpray::scene::Scene,
    caster: &dyn RayCaster,
    opts: &RenderOptions,
    path: &std::path::Path,
    key: String,
) -> Result<Option<Vec<warpray::glam::Vec3>>> {
    let bar = progress_bar(opts.budget);
    let (film, _) = render(scene, caster, opts, |p, _| {
        bar.set_position(p as u64);
        !interrupt::requested()
    })?;
    bar.finish_and_clear();
    if interrupt::requested() {
        eprintln!("interrupted while rendering the reference; nothing was measured or written");
        return Ok(None);
    }
    film.write_with(path, 1.0, &[("reference_key", key)])?;
    Ok(Some(film.mean()))
}

fn progress_bar(budget: Budget) -> ProgressBar {
    let (len, style) = match budget {
        Budget::Samples(n) => (n as u64, "{spinner} [{elapsed_precise}] {bar:40} {pos}/{len} spp, eta {eta}"),
        Budget::Seconds(s) => ((s * 1000.0) as u64, "{spinner} [{elapsed_precise}] {bar:40} {msg}"),
    };
    let bar = ProgressBar::new(len);
    bar.set_style(ProgressStyle::with_template(style).unwrap_or_else(|_| ProgressStyle::default_bar()));
    bar.enable_steady_tick(Duration::from_millis(200));
    bar
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    // No subcommand: `warpray` alone renders the built-in scene with the defaults.
    let command = cli.command.unwrap_or(Command::Render(cli.render));
    let result = match command {
        Command::Render(args) => run_render(args).map(|i| if i { Stop::Interrupted } else { Stop::Done }),
        Command::Converge(args) => run_converge(args).map(|i| if i { Stop::Interrupted } else { Stop::Done }),
        Command::Diff(args) => run_diff(args).map(|over| if over { Stop::Differs } else { Stop::Done }),
    };
    match result {
        Ok(Stop::Done) => ExitCode::SUCCESS,
        Ok(Stop::Interrupted) => ExitCode::from(INTERRUPTED),
        Ok(Stop::Differs) => ExitCode::from(1),
        Err(e) => {
            eprintln!("error: {e}");
            // The chain of causes (those the message above does not already quote).
            let mut shown = e.to_string();
            let mut cause = std::error::Error::source(&e);
            while let Some(c) = cause {
                let text = c.to_string();
                if !shown.contains(&text) {
                    eprintln!("  caused by: {text}");
                }
                shown = text;
                cause = c.source();
            }
            ExitCode::from(2)
        }
    }
}
