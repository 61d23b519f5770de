//! `warpray-inspector [SCENE] [--start]`: the egui inspector (needs the `inspector`
//! feature). `--start` begins rendering at once.
//! `cargo run --release --features inspector --bin warpray-inspector`

use warpray::inspector::Inspector;

struct App(Inspector);

impl eframe::App for App {
    fn ui(&mut self, ui: &mut egui::Ui, _frame: &mut eframe::Frame) {
        self.0.ui(ui);
    }
}

fn main() -> eframe::Result {
    let mut inspector = Inspector::new();
    let mut start = false;
    for arg in std::env::args().skip(1) {
        match arg.as_str() {
            "--start" => start = true,
            "-h" | "--help" => {
                println!(
                    "warpray-inspector [SCENE] [--start]\n\nSCENE: a .toml scene file or an .obj/.obj.gz (default: the built-in Cornell box)"
                );
                return Ok(());
            }
            scene => inspector.add_scene(scene.into()),
        }
    }
    if start {
        inspector.start();
    }
    let options = eframe::NativeOptions {
        viewport: egui::ViewportBuilder::default().with_inner_size([1280.0, 800.0]).with_title("warpray inspector"),
        ..Default::default()
    };
    eframe::run_native("warpray inspector", options, Box::new(|_| Ok(Box::new(App(inspector)))))
}
