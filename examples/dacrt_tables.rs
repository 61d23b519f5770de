//! The paper's tables for this machine: ray casting without a stored structure (serial
//! DACRT, PDACRT) against the obvhs BVH (build and trace separately, and summed), on
//! primary, shadow (one point light), specular (mirror) and ambient-occlusion batches
//! (8 rays per primary hit), with peak memory; and thread scaling.
//!
//! ```text
//! WARPRAY_MODELS=../shared/models cargo run --release --example dacrt_tables -- \
//!     [--size 1024] [--scenes bunny,conference,dragon] [--casters bvh,dacrt,pdacrt] \
//!     [--threads N] [--scaling 1,2,4,8,16] [--ao 8] [--sweep]
//! ```

use warpray::cast::batches::interior_camera;
use warpray::cast::{BvhCaster, Dacrt, DacrtParams, RayCaster};
use warpray::geometry::{Hit, Ray};
use warpray::pdacrt::{Pdacrt, PdacrtParams};
use warpray::scene::{ObjOptions, Scene, find_model, load_obj, models_dir};

struct Args {
    size: u32,
    scenes: Vec<String>,
    casters: Vec<String>,
    threads: Option<usize>,
    scaling: Vec<usize>,
    ao: usize,
    sweep: bool,
}

fn parse() -> Args {
    let mut a = Args {
        size: 1024,
        scenes: vec!["bunny".into(), "conference".into(), "dragon".into()],
        casters: vec!["bvh".into(), "dacrt".into(), "pdacrt".into()],
        threads: None,
        scaling: Vec::new(),
        ao: 8,
        sweep: false,
    };
    let argv: Vec<String> = std::env::args().skip(1).collect();
    let list = |s: &str| s.split(',').map(str::to_string).collect::<Vec<_>>();
    let mut i = 0;
    while i < argv.len() {
        let v = argv.get(i + 1).cloned().unwrap_or_default();
        match argv[i].as_str() {
            "--size" => a.size = v.parse().expect("--size N"),
            "--scenes" => a.scenes = list(&v),
            "--casters" => a.casters = list(&v),
            "--threads" => a.threads = Some(v.parse().expect("--threads N")),
            "--scaling" => a.scaling = v.split(',').map(|x| x.parse().expect("--scaling 1,2,4")).collect(),
            "--ao" => a.ao = v.parse().expect("--ao N"),
            "--sweep" => {
                a.sweep = true;
                i -= 1;
            }
            other => panic!("unknown argument {other}"),
        }
        i += 2;
    }
    a
}

fn scene(name: &str) -> Scene {
    let path = find_model(name)
        .unwrap_or_else(|| panic!("{name} not found in {}: set WARPRAY_MODELS", models_dir().display()));
    let mut s = load_obj(path, &ObjOptions::default()).unwrap();
    if name == "conference" {
        interior_camera(&mut s);
    }
    s
}

/// The paper's four batches, named, with whether they are shadow rays.
fn batches(s: &Scene, size: u32, ao: usize) -> Vec<(&'static str, Vec<Ray>, bool)> {
    let b = warpray::cast::batches::batches(s, size, size, ao, 1);
    vec![
        ("primary", b.primary, false),
        ("shadow", b.shadow, true),
        ("specular", b.specular, false),
        ("ao", b.ambient, false),
    ]
}

struct Row {
    scene: String,
    caster: &'static str,
    build_ms: f64,
    /// (batch, rays, ms)
    batches: Vec<(&'static str, usize, f64)>,
    peak_mb: f64,
}

fn run_caster(c: &dyn RayCaster, build_ms: f64, scene_name: &str, batches: &[(&'static str, Vec<Ray>, bool)]) -> Row {
    let mut row = Row { scene: scene_name.into(), caster: c.name(), build_ms, batches: Vec::new(), peak_mb: 0.0 };
    let mut peak = 0usize;
    for (name, rays, shadow) in batches {
        let stats = if *shadow {
            let mut out = vec![false; rays.len()];
            c.occluded(rays, &mut out)
        } else {
            let mut out = vec![Hit::MISS; rays.len()];
            c.closest(rays, &mut out)
        };
        peak = peak.max(stats.peak_working_bytes);
        row.batches.push((name, rays.len(), stats.seconds * 1e3));
    }
    row.peak_mb = (peak + c.memory_bytes()) as f64 / 1e6;
    row
}

/// The caster and its build time (only the BVH builds a structure; the others just
/// copy the triangles).
fn build(name: &str, s: &Scene) -> (Box<dyn RayCaster>, f64) {
    let c: Box<dyn RayCaster> = match name {
        "bvh" => Box::new(BvhCaster::new(s)),
        "dacrt" => Box::new(Dacrt::new(s)),
        "pdacrt" => Box::new(Pdacrt::new(s)),
        other => panic!("unknown caster {other}"),
    };
    let ms = c.build_seconds() * 1e3;
    (c, ms)
}

/// Primary-ray time over a grid of leaf sizes, for choosing the defaults.
fn sweep(s: &Scene, primary: &[Ray]) {
    println!("\n## Leaf-size sweep: primary rays, trace ms\n");
    println!("| leaf rays | leaf triangles | dacrt ms | pdacrt ms |");
    println!("|---:|---:|---:|---:|");
    let tris = s.triangle_vertices();
    for (lr, lt) in [(4, 4), (8, 8), (12, 12), (16, 16), (32, 8), (32, 16), (64, 16), (64, 32), (128, 32)] {
        let mut hits = vec![Hit::MISS; primary.len()];
        let d = Dacrt::from_triangles(
            tris.clone(),
            DacrtParams { leaf_rays: lr, leaf_triangles: lt, ..Default::default() },
        );
        let t_d = (0..3).map(|_| d.closest(primary, &mut hits).seconds).fold(f64::MAX, f64::min);
        let p = Pdacrt::from_triangles(
            &tris,
            PdacrtParams { leaf_rays: lr as u32, leaf_triangles: lt as u32, ..Default::default() },
        );
        let t_p = (0..3).map(|_| p.closest(primary, &mut hits).seconds).fold(f64::MAX, f64::min);
        println!("| {lr} | {lt} | {:.1} | {:.1} |", t_d * 1e3, t_p * 1e3);
    }
}

fn print_tables(rows: &[Row], threads: usize) {
    println!("\n## Table 1: primary rays ({threads} threads)\n");
    println!("| scene | caster | build ms | trace ms | total ms | Mrays/s (trace) |");
    println!("|---|---|---:|---:|---:|---:|");
    for r in rows {
        let (_, n, ms) = r.batches[0];
        println!(
            "| {} | {} | {:.1} | {:.1} | {:.1} | {:.2} |",
            r.scene,
            r.caster,
            r.build_ms,
            ms,
            r.build_ms + ms,
            n as f64 / ms / 1e3
        );
    }
    println!("\n## Table 2: secondary rays, trace ms (Mrays/s) ({threads} threads)\n");
    println!("| scene | caster | shadow | specular | ambient occlusion |");
    println!("|---|---|---:|---:|---:|");
    for r in rows {
        let cell = |k: usize| {
            let (_, n, ms) = r.batches[k];
            format!("{ms:.1} ({:.2})", n as f64 / ms / 1e3)
        };
        println!("| {} | {} | {} | {} | {} |", r.scene, r.caster, cell(1), cell(2), cell(3));
    }
    println!("\n## Table 3: peak memory, MB (structure or working set, plus triangles)\n");
    println!("| scene | caster | peak MB |");
    println!("|---|---|---:|");
    for r in rows {
        println!("| {} | {} | {:.1} |", r.scene, r.caster, r.peak_mb);
    }
}

fn main() {
    let a = parse();
    let mut pool = rayon::ThreadPoolBuilder::new();
    if let Some(t) = a.threads {
        pool = pool.num_threads(t);
    }
    let pool = pool.build().unwrap();
    let threads = pool.current_num_threads();
    println!("# DACRT tables: {}x{} primary rays, {} AO rays per hit, {threads} threads", a.size, a.size, a.ao);
    let mut rows = Vec::new();
    for name in &a.scenes {
        let s = scene(name);
        let b = batches(&s, a.size, a.ao);
        if a.sweep {
            pool.install(|| sweep(&s, &b[0].1));
        }
        eprintln!(
            "{name}: {} triangles; rays: {}",
            s.triangle_count(),
            b.iter().map(|x| format!("{} {}", x.0, x.1.len())).collect::<Vec<_>>().join(", ")
        );
        for c in &a.casters {
            let row = pool.install(|| {
                let (caster, build_ms) = build(c, &s);
                run_caster(caster.as_ref(), build_ms, name, &b)
            });
            eprintln!("  {} done", row.caster);
            rows.push(row);
        }
        if !a.scaling.is_empty() {
            println!("\n## Thread scaling on {name}: primary + shadow rays, Mrays/s (BVH includes its build)\n");
            println!("| threads | {} |", a.casters.join(" | "));
            println!("|---:|{}|", a.casters.iter().map(|_| "---:").collect::<Vec<_>>().join("|"));
            for &t in &a.scaling {
                let pool = rayon::ThreadPoolBuilder::new().num_threads(t).build().unwrap();
                let mut cells = Vec::new();
                for c in &a.casters {
                    let mrays = pool.install(|| {
                        let (caster, build_ms) = build(c, &s);
                        let row = run_caster(caster.as_ref(), build_ms, name, &b[..2]);
                        let rays: usize = row.batches.iter().map(|x| x.1).sum();
                        let ms: f64 = row.batches.iter().map(|x| x.2).sum::<f64>() + row.build_ms;
                        rays as f64 / ms / 1e3
                    });
                    cells.push(format!("{mrays:.2}"));
                }
                println!("| {t} | {} |", cells.join(" | "));
            }
        }
    }
    print_tables(&rows, threads);
}
