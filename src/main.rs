//! The `warpray` command. With no arguments it renders the built-in Cornell box to
//! `out.png` and `out.exr`.

use clap::{Args, Parser, Subcommand};
use indicatif::{ProgressBar, ProgressStyle};
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::time::Duration;
use warpray::cast::CasterKind;
use warpray::error::{Error, Result};
use warpray::render::{Budget, IntegratorKind, RenderOptions, render};
use warpray::scene::{SceneDesc, find_model, load_scene};

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

#[derive(Subcommand)]
enum Command {
    /// Render a scene to PNG and/or EXR (the default command).
    Render(RenderArgs),
}

#[derive(Args)]
struct RenderArgs {
    /// Scene: a .toml scene file, an .obj/.obj.gz file, a model name found in
    /// $WARPRAY_MODELS (e.g. `cornell-box`), or `cornell` for the built-in box.
    #[arg(default_value = "cornell")]
    scene: PathBuf,
    /// Light-transport algorithm [default: path].
    #[arg(long, value_enum)]
    integrator: Option<IntegratorKind>,
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
    /// Worker threads [default: all cores].
    #[arg(long)]
    threads: Option<usize>,
    /// Random seed; the same seed gives the same image at any thread count.
    #[arg(long)]
    seed: Option<u64>,
    /// Ray caster.
    #[arg(long, value_enum, default_value = "bvh")]
    caster: CasterKind,
    /// Output files; the extension (.png or .exr) picks the format. May be repeated.
    #[arg(short, long = "output", default_values = ["out.png", "out.exr"])]
    output: Vec<PathBuf>,
    /// Exposure multiplier applied before the PNG tone map (EXR stays linear).
    #[arg(long, default_value_t = 1.0)]
    exposure: f32,
    /// No progress bar.
    #[arg(long, short)]
    quiet: bool,
}

fn parse_size(s: &str) -> std::result::Result<(u32, u32), String> {
    let (w, h) = s.split_once(['x', 'X']).ok_or("expected WIDTHxHEIGHT, e.g. 640x480")?;
    let w = w.trim().parse::<u32>().map_err(|e| format!("width: {e}"))?;
    let h = h.trim().parse::<u32>().map_err(|e| format!("height: {e}"))?;
    Ok((w, h))
}

/// A scene argument: a file, a model name in $WARPRAY_MODELS, or `cornell`.
fn resolve_scene(arg: &Path) -> Result<SceneDesc> {
    if arg.as_os_str() == "cornell" || arg.exists() {
        return load_scene(arg);
    }
    if let Some(p) = arg.to_str().and_then(find_model) {
        return load_scene(p);
    }
    load_scene(arg)
}

fn run_render(args: RenderArgs) -> Result<()> {
    let desc = resolve_scene(&args.scene)?;
    let s = &desc.settings;
    let (width, height) = args.size.unwrap_or((s.width.unwrap_or(512), s.height.unwrap_or(512)));
    let integrator = match (args.integrator, &s.integrator) {
        (Some(i), _) => i,
        (None, Some(name)) => name.parse()?,
        (None, None) => IntegratorKind::Path,
    };
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
    let opts = RenderOptions {
        width,
        height,
        budget,
        max_depth: args.max_depth.or(s.max_depth).unwrap_or(8),
        seed: args.seed.or(s.seed).unwrap_or(0),
        integrator,
    };
    for out in &args.output {
        match out.extension().and_then(|e| e.to_str()).map(str::to_ascii_lowercase).as_deref() {
            Some("png") | Some("exr") => {}
            _ => {
                return Err(Error::Output { path: out.clone(), msg: "use a .png or .exr file name".into() });
            }
        }
    }
    warpray::film::check_size(width, height)?;
    desc.scene.check_renderable()?;

    let mut pool = rayon::ThreadPoolBuilder::new();
    if let Some(n) = args.threads {
        if n == 0 {
            return Err(Error::BadSetting("--threads must be at least 1".into()));
        }
        pool = pool.num_threads(n);
    }
    let pool = pool.build().map_err(|e| Error::BadSetting(format!("thread pool: {e}")))?;
    let threads = pool.current_num_threads();

    pool.install(|| {
        let caster = args.caster.build(&desc.scene);
        let bar = if args.quiet { ProgressBar::hidden() } else { progress_bar(budget) };
        let start = std::time::Instant::now();
        let (film, stats) = render(&desc.scene, caster.as_ref(), &opts, |pass, _| {
            match budget {
                Budget::Samples(_) => bar.set_position(pass as u64),
                Budget::Seconds(_) => bar.set_position(start.elapsed().as_millis() as u64),
            }
            bar.set_message(format!("{pass} spp"));
            true
        })?;
        bar.finish_and_clear();
        for out in &args.output {
            film.write(out, args.exposure)?;
        }
        let outs: Vec<String> = args.output.iter().map(|p| p.display().to_string()).collect();
        println!(
            "{}: {} triangles, {}x{}, {} spp, {} + {} on {} threads: {:.2} s, {:.2} Mrays/s (build {:.3} s); wrote {}",
            desc.scene.source.display(),
            desc.scene.triangle_count(),
            width,
            height,
            stats.passes,
            integrator.name(),
            caster.name(),
            threads,
            stats.seconds,
            stats.rays_per_second() / 1e6,
            caster.build_seconds(),
            outs.join(", ")
        );
        if film.rejected > 0 {
            eprintln!("warning: {} sample estimates were NaN, infinite or negative and were dropped", film.rejected);
        }
        Ok(())
    })
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
        Command::Render(args) => run_render(args),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e}");
            ExitCode::FAILURE
        }
    }
}
