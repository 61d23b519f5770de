//! `warpray-inspector [SCENE]... [--start]`: the egui inspector (needs the `inspector`
//! feature). `cargo run --release --features inspector --bin warpray-inspector -- --start`

use clap::Parser;
use std::path::PathBuf;
use std::process::ExitCode;
use warpray::cast::CasterKind;
use warpray::inspector::Inspector;
use warpray::render::Variant;

#[derive(Parser)]
#[command(
    name = "warpray-inspector",
    version,
    about = "The warpray inspector: images, PDACRT levels, CIS queues, simt kernels"
)]
struct Cli {
    /// Scenes to add to the list, as for `warpray render`: a .toml scene file, an
    /// .obj/.obj.gz, a built-in scene name or a model in $WARPRAY_MODELS. The last is
    /// selected. Each is loaded once first, so a bad one is reported here.
    scenes: Vec<PathBuf>,
    /// Start rendering the selected scene at once.
    #[arg(long)]
    start: bool,
    /// Integrator to select: a label as `warpray render --integrator` takes (path, light,
    /// bdpt, lvc, lvc-mk, cis, cis-nosort, cis-nois, cis-nocompact).
    #[arg(long, value_parser = |s: &str| Variant::parse(s).map_err(|e| e.to_string()))]
    integrator: Option<Variant>,
    /// Caster to select.
    #[arg(long, value_enum)]
    caster: Option<CasterKind>,
    /// Samples per pixel of a render.
    #[arg(long, value_parser = clap::value_parser!(u32).range(1..=100_000))]
    spp: Option<u32>,
    /// Image width and height, pixels.
    #[arg(long, value_parser = clap::value_parser!(u32).range(16..=1024))]
    size: Option<u32>,
}

struct App(Inspector);

impl eframe::App for App {
    fn ui(&mut self, ui: &mut egui::Ui, _frame: &mut eframe::Frame) {
        self.0.ui(ui);
    }
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    let mut inspector = Inspector::new();
    for scene in &cli.scenes {
        if let Err(e) = warpray::scene::load_scene(scene) {
            eprintln!("error: {e}");
            return ExitCode::FAILURE;
        }
        inspector.add_scene(scene.clone());
    }
    if let Some(i) = cli.integrator {
        inspector.integrator = i;
    }
    if let Some(c) = cli.caster {
        inspector.caster = c;
    }
    inspector.spp = cli.spp.unwrap_or(inspector.spp);
    inspector.size = cli.size.unwrap_or(inspector.size);
    if cli.start {
        inspector.start();
    }
    let options = eframe::NativeOptions {
        viewport: egui::ViewportBuilder::default().with_inner_size([1280.0, 800.0]).with_title("warpray inspector"),
        ..Default::default()
    };
    match eframe::run_native("warpray inspector", options, Box::new(|_| Ok(Box::new(App(inspector))))) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: cannot open a window: {e}");
            ExitCode::FAILURE
        }
    }
}
