//! PDACRT's time per kernel (summed over levels and chunks) on one model's primary
//! rays, from the level records: where the pipeline spends its time.
//!
//! ```text
//! WARPRAY_MODELS=../shared/models cargo run --release --example pdacrt_kernels -- [--scene dragon] [--size 512] [--shadow]
//! ```

use clap::Parser;
use warpray::cast::RayCaster;
use warpray::geometry::Hit;
use warpray::pdacrt::{Pdacrt, PdacrtParams};
use warpray::scene::{ObjOptions, find_model, load_obj, models_dir};

#[derive(Parser)]
struct Args {
    #[arg(long, default_value = "dragon")]
    scene: String,
    #[arg(long, default_value_t = 512, value_parser = clap::value_parser!(u32).range(1..=8192))]
    size: u32,
    /// Shadow rays from the primary hits instead of primary rays.
    #[arg(long)]
    shadow: bool,
}

fn main() {
    let a = Args::parse();
    let Some(path) = find_model(&a.scene) else {
        eprintln!("error: model {} not found in {}: set WARPRAY_MODELS", a.scene, models_dir().display());
        std::process::exit(1);
    };
    let scene = match load_obj(path, &ObjOptions::default()) {
        Ok(s) => s,
        Err(e) => {
            eprintln!("error: {e}");
            std::process::exit(1);
        }
    };
    let b = warpray::cast::batches::batches(&scene, a.size, a.size, 0, 1);
    let p = Pdacrt::from_triangles(&scene.triangle_vertices(), PdacrtParams::default());
    let st = if a.shadow {
        p.occluded(&b.shadow, &mut vec![false; b.shadow.len()])
    } else {
        p.closest(&b.primary, &mut vec![Hit::MISS; b.primary.len()])
    };
    let levels = p.levels();
    let mut rows: Vec<(&'static str, u32, f64)> = Vec::new();
    for l in &levels {
        for k in &l.kernels {
            match rows.iter_mut().find(|r| r.0 == k.name) {
                Some(r) => {
                    r.1 += k.launches;
                    r.2 += k.seconds;
                }
                None => rows.push((k.name, k.launches, k.seconds)),
            }
        }
    }
    rows.sort_by(|x, y| y.2.total_cmp(&x.2));
    let total: f64 = levels.iter().map(|l| l.seconds).sum();
    println!(
        "# PDACRT on {} ({} rays, {} levels, {:.1} ms in levels, {:.1} ms call, {:.1} tests/ray, {} threads)\n",
        a.scene,
        st.rays,
        levels.len(),
        total * 1e3,
        st.seconds * 1e3,
        st.tests_per_ray(),
        rayon::current_num_threads()
    );
    println!("| kernel | launches | ms | share |");
    println!("|---|---:|---:|---:|");
    for (name, n, s) in rows {
        println!("| {name} | {n} | {:.1} | {:.1} % |", s * 1e3, s / total * 100.0);
    }
    let refs: usize = levels.iter().map(|l| l.triangle_refs).sum();
    let rays: usize = levels.iter().map(|l| l.rays).sum();
    println!("\ntriangle references over all levels: {refs}; ray references: {rays}");
}
