//! `warpray-inspector [SCENE]`: the egui inspector (needs the `inspector` feature).
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
    if let Some(scene) = std::env::args().nth(1) {
        inspector.add_scene(scene.into());
    }
    let options = eframe::NativeOptions {
        viewport: egui::ViewportBuilder::default().with_inner_size([1280.0, 800.0]).with_title("warpray inspector"),
        ..Default::default()
    };
    eframe::run_native("warpray inspector", options, Box::new(|_| Ok(Box::new(App(inspector)))))
}
