//! PDACRT on the GPU against what a GPU programmer would use instead for geometry that
//! changes every frame: a BVH rebuilt on the GPU each frame and traversed with a stack
//! (`warpray::gpu::GpuBvh`, `cuda/bvh.cu`). The DACRT paper's batches (primary, shadow,
//! specular, ambient occlusion) on each model, and the waving grid per frame.
//!
//! ```text
//! sh cuda/build.sh      # on the GPU machine
//! cargo run --release --features cuda,cli --example gpu_casting -- \
//!     [--models dragon,bunny,conference] [--batches primary,shadow,specular,ao] \
//!     [--size 1024] [--ao 8] [--rounds 5] [--grid 1000000] [--frames 5] [--json]
//! ```
//!
//! Times are GPU times (CUDA events) with the data resident; transfers are reported
//! apart (the triangles' upload, and each call's host wall time with the rays' upload
//! and the keys' download). Every round rebuilds the BVH before each batch, as a frame
//! of changing geometry would; PDACRT has nothing to build. Rounds interleave the two
//! casters; tables give medians over rounds. Before timing, every batch's keys are
//! compared between the two (they use the same triangle test and key rule, so they
//! must be equal bit for bit); the run fails on any difference.

use clap::Parser;
use warpray::cast::batches::{
    batches, interior_camera, primary_rays, waving_grid, waving_grid_camera, waving_grid_shadow_rays,
};
use warpray::cast::{BvhCaster, RayCaster};
use warpray::geometry::{Hit, Ray};
use warpray::gpu::{GpuBvh, GpuPdacrt};
use warpray::machine::median;
use warpray::scene::{ObjOptions, find_model, load_obj, models_dir};

#[derive(Parser)]
struct Args {
    /// Models (from WARPRAY_MODELS), comma-separated; none for the grid alone.
    #[arg(long, value_delimiter = ',', default_value = "dragon,bunny,conference")]
    models: Vec<String>,
    /// Batches: primary, shadow, specular, ao (comma-separated).
    #[arg(long, value_delimiter = ',', default_value = "primary,shadow,specular,ao")]
    batches: Vec<String>,
    /// Image side in pixels.
    #[arg(long, default_value_t = 1024, value_parser = clap::value_parser!(u32).range(1..=8192))]
    size: u32,
    /// Ambient-occlusion rays per primary hit.
    #[arg(long, default_value_t = 8, value_parser = clap::value_parser!(u32).range(1..=64))]
    ao: u32,
    /// Timed rounds per batch (after one untimed round that checks the keys).
    #[arg(long, default_value_t = 5, value_parser = clap::value_parser!(u32).range(1..=100))]
    rounds: u32,
    /// Triangles of the waving grid (0: no grid).
    #[arg(long, default_value_t = 1_000_000, value_parser = clap::value_parser!(u64).range(0..=20_000_000))]
    grid: u64,
    /// Frames of the grid (the geometry moves between frames).
    #[arg(long, default_value_t = 5, value_parser = clap::value_parser!(u32).range(1..=1000))]
    frames: u32,
    /// PDACRT's rays per pass (0: the whole batch at once, which the GPU's memory holds
    /// for every batch here; the library's default, 196,608, runs a 1M-ray batch in six
    /// passes of about 50 levels each).
    #[arg(long, default_value_t = 0)]
    chunk: usize,
    /// One JSON object per measurement instead of the tables.
    #[arg(long)]
    json: bool,
}

/// One caster's median figures for one batch or frame part (milliseconds).
#[derive(Default, Clone, Copy)]
struct Figures {
    upload_ms: f64,
    build_ms: f64,
    trace_ms: f64,
    call_ms: f64,
    tests_per_ray: f64,
    visits_per_ray: f64,
    /// PDACRT: levels, launches (kernels and CUB calls) and host read-backs of the trace.
    levels: f64,
    launches: f64,
    read_backs: f64,
}

struct Row {
    scene: String,
    batch: String,
    rays: usize,
    pdacrt: Figures,
    bvh: Figures,
}

fn pdacrt_params(a: &Args) -> warpray::pdacrt::PdacrtParams {
    warpray::pdacrt::PdacrtParams { chunk_rays: a.chunk, ..Default::default() }
}

fn load(name: &str) -> Result<warpray::scene::Scene, String> {
    let path = find_model(name)
        .ok_or_else(|| format!("model {name} not found in {}: set WARPRAY_MODELS", models_dir().display()))?;
    let mut scene = load_obj(path, &ObjOptions::default()).map_err(|e| e.to_string())?;
    if name == "conference" {
        interior_camera(&mut scene);
    }
    Ok(scene)
}

/// Keys of both casters for one batch; an error names the first ray that differs.
fn check_keys(p: &GpuPdacrt, b: &GpuBvh, rays: &[Ray], any_hit: bool, what: &str) -> Result<(), String> {
    let kp = p.trace_keys(rays, any_hit).map_err(|e| e.to_string())?;
    let kb = b.trace_keys(rays, any_hit).map_err(|e| e.to_string())?;
    let differ = kp.iter().zip(&kb).filter(|(a, b)| a != b).count();
    if let Some(i) = kp.iter().zip(&kb).position(|(a, b)| a != b) {
        return Err(format!(
            "{what}: {differ} of {} keys differ between PDACRT and the BVH; first ray {i}: {:?}, keys {:#x} vs {:#x}",
            rays.len(),
            rays[i],
            kp[i],
            kb[i]
        ));
    }
    Ok(())
}

/// Medians over rounds of per-round samples.
fn medians(samples: &[Figures]) -> Figures {
    let m = |f: fn(&Figures) -> f64| median(samples.iter().map(f).collect());
    Figures {
        upload_ms: m(|s| s.upload_ms),
        build_ms: m(|s| s.build_ms),
        trace_ms: m(|s| s.trace_ms),
        call_ms: m(|s| s.call_ms),
        tests_per_ray: m(|s| s.tests_per_ray),
        visits_per_ray: m(|s| s.visits_per_ray),
        levels: m(|s| s.levels),
        launches: m(|s| s.launches),
        read_backs: m(|s| s.read_backs),
    }
}

fn trace_pdacrt(p: &GpuPdacrt, rays: &[Ray], any_hit: bool) -> Result<Figures, String> {
    p.trace_keys(rays, any_hit).map_err(|e| e.to_string())?;
    let s = p.last_stats();
    let n = rays.len().max(1) as f64;
    Ok(Figures {
        trace_ms: s.trace_ms,
        call_ms: s.call_ms,
        tests_per_ray: s.tests as f64 / n,
        levels: s.levels as f64,
        launches: s.launches as f64,
        read_backs: s.read_backs as f64,
        ..Default::default()
    })
}

fn trace_bvh(b: &GpuBvh, rays: &[Ray], any_hit: bool) -> Result<Figures, String> {
    b.trace_keys(rays, any_hit).map_err(|e| e.to_string())?;
    let s = b.last_trace();
    let n = rays.len().max(1) as f64;
    Ok(Figures {
        trace_ms: s.trace_ms,
        call_ms: s.call_ms,
        tests_per_ray: s.tests as f64 / n,
        visits_per_ray: s.visits as f64 / n,
        ..Default::default()
    })
}

/// The models' batches: check, then rounds of (rebuild + trace the BVH, trace PDACRT).
fn model_rows(a: &Args, rows: &mut Vec<Row>) -> Result<(), String> {
    for name in &a.models {
        let scene = load(name)?;
        let tris = scene.triangle_vertices();
        let b = batches(&scene, a.size, a.size, a.ao as usize, 1);
        let mut pdacrt = GpuPdacrt::new(&tris, pdacrt_params(a)).map_err(|e| e.to_string())?;
        let mut bvh = GpuBvh::new(&tris).map_err(|e| e.to_string())?;
        for batch in &a.batches {
            let (rays, any_hit) = match batch.as_str() {
                "primary" => (&b.primary, false),
                "shadow" => (&b.shadow, true),
                "specular" => (&b.specular, false),
                "ao" => (&b.ambient, false),
                other => return Err(format!("unknown batch {other} (known: primary, shadow, specular, ao)")),
            };
            check_keys(&pdacrt, &bvh, rays, any_hit, &format!("{name} {batch}"))?;
            let (mut ps, mut bs) = (Vec::new(), Vec::new());
            for _ in 0..a.rounds {
                let upload = pdacrt.set_triangles(&tris).map_err(|e| e.to_string())?;
                ps.push(Figures { upload_ms: upload, ..trace_pdacrt(&pdacrt, rays, any_hit)? });
                let built = bvh.rebuild(&tris).map_err(|e| e.to_string())?;
                bs.push(Figures {
                    upload_ms: built.upload_ms,
                    build_ms: built.build_ms,
                    ..trace_bvh(&bvh, rays, any_hit)?
                });
            }
            rows.push(Row {
                scene: name.clone(),
                batch: batch.clone(),
                rays: rays.len(),
                pdacrt: medians(&ps),
                bvh: medians(&bs),
            });
            eprintln!("  {name} {batch}: done");
        }
    }
    Ok(())
}

/// The waving grid: per frame, new triangles, primary rays and shadow rays from their
/// hits; each caster's frame is upload (+ build) + primary + shadow.
fn grid_rows(a: &Args, rows: &mut Vec<Row>) -> Result<(), String> {
    let n = ((a.grid / 2) as f64).sqrt().round().max(1.0) as usize;
    let primary = primary_rays(&waving_grid_camera(), a.size, a.size);
    let first = waving_grid(n, -0.25);
    let mut pdacrt = GpuPdacrt::new(&first, pdacrt_params(a)).map_err(|e| e.to_string())?;
    let mut bvh = GpuBvh::new(&first).map_err(|e| e.to_string())?;
    let (mut pp, mut ps, mut bp, mut bs) = (vec![], vec![], vec![], vec![]);
    let mut shadow_rays = 0;
    for f in 0..a.frames {
        let tris = waving_grid(n, f as f32 * 0.25);
        let mut hits = vec![Hit::MISS; primary.len()];
        BvhCaster::from_triangles(tris.clone()).closest(&primary, &mut hits);
        let shadow = waving_grid_shadow_rays(&tris, &primary, &hits);
        shadow_rays = shadow.len();
        let upload = pdacrt.set_triangles(&tris).map_err(|e| e.to_string())?;
        let built = bvh.rebuild(&tris).map_err(|e| e.to_string())?;
        if f == 0 {
            check_keys(&pdacrt, &bvh, &primary, false, "grid primary")?;
            check_keys(&pdacrt, &bvh, &shadow, true, "grid shadow")?;
        }
        pp.push(Figures { upload_ms: upload, ..trace_pdacrt(&pdacrt, &primary, false)? });
        ps.push(trace_pdacrt(&pdacrt, &shadow, true)?);
        bp.push(Figures { upload_ms: built.upload_ms, build_ms: built.build_ms, ..trace_bvh(&bvh, &primary, false)? });
        bs.push(trace_bvh(&bvh, &shadow, true)?);
    }
    let scene = format!("waving grid ({} triangles)", 2 * n * n);
    rows.push(Row {
        scene: scene.clone(),
        batch: "primary".into(),
        rays: primary.len(),
        pdacrt: medians(&pp),
        bvh: medians(&bp),
    });
    rows.push(Row { scene, batch: "shadow".into(), rays: shadow_rays, pdacrt: medians(&ps), bvh: medians(&bs) });
    eprintln!("  grid: done");
    Ok(())
}

fn run(a: Args) -> Result<(), String> {
    let device = GpuBvh::new(&[]).map_err(|e| e.to_string())?.device_name().to_string();
    let machine = warpray::machine::Machine::this();
    eprintln!("GPU: {device}\nhost: {machine}");
    let mut rows = Vec::new();
    model_rows(&a, &mut rows)?;
    if a.grid > 0 {
        grid_rows(&a, &mut rows)?;
    }
    if a.json {
        println!(
            "{{\"gpu\":\"{device}\",\"machine\":{},\"rounds\":{},\"pdacrt_chunk_rays\":{}}}",
            machine.json(),
            a.rounds,
            a.chunk
        );
        for r in &rows {
            let fig = |f: &Figures| {
                format!(
                    "{{\"upload_ms\":{:.4},\"build_ms\":{:.4},\"trace_ms\":{:.4},\"call_ms\":{:.4},\"tests_per_ray\":{:.3},\"visits_per_ray\":{:.3},\"levels\":{},\"launches\":{},\"read_backs\":{}}}",
                    f.upload_ms,
                    f.build_ms,
                    f.trace_ms,
                    f.call_ms,
                    f.tests_per_ray,
                    f.visits_per_ray,
                    f.levels,
                    f.launches,
                    f.read_backs
                )
            };
            println!(
                "{{\"scene\":\"{}\",\"batch\":\"{}\",\"size\":{},\"rays\":{},\"pdacrt\":{},\"bvh\":{}}}",
                r.scene,
                r.batch,
                a.size,
                r.rays,
                fig(&r.pdacrt),
                fig(&r.bvh)
            );
        }
        return Ok(());
    }
    let chunk =
        if a.chunk == 0 { "the whole batch per pass".to_string() } else { format!("{} rays per pass", a.chunk) };
    println!(
        "# PDACRT ({chunk}) against a GPU BVH rebuilt per batch, {0}x{0}, medians of {1} rounds\n",
        a.size, a.rounds
    );
    println!("GPU: {device}. Host: {machine}.\n");
    println!(
        "| scene | batch | rays | PDACRT trace ms | BVH build ms | BVH trace ms | BVH build + trace | PDACRT ÷ BVH b+t | tests/ray PDACRT | tests/ray BVH | nodes/ray BVH | PDACRT levels / launches / read-backs | upload ms PDACRT / BVH | with transfers PDACRT / BVH |"
    );
    println!("|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|");
    for r in &rows {
        let (p, b) = (&r.pdacrt, &r.bvh);
        let bt = b.build_ms + b.trace_ms;
        println!(
            "| {} | {} | {} | {:.2} | {:.2} | {:.2} | {:.2} | {:.2}× | {:.1} | {:.1} | {:.1} | {} / {} / {} | {:.1} / {:.1} | {:.1} / {:.1} |",
            r.scene,
            r.batch,
            r.rays,
            p.trace_ms,
            b.build_ms,
            b.trace_ms,
            bt,
            p.trace_ms / bt,
            p.tests_per_ray,
            b.tests_per_ray,
            b.visits_per_ray,
            p.levels,
            p.launches,
            p.read_backs,
            p.upload_ms,
            b.upload_ms,
            p.call_ms,
            b.call_ms
        );
    }
    if a.grid > 0 {
        let g: Vec<&Row> = rows.iter().filter(|r| r.scene.starts_with("waving")).collect();
        let p = g[0].pdacrt.trace_ms + g[1].pdacrt.trace_ms;
        let b = g[0].bvh.build_ms + g[0].bvh.trace_ms + g[1].bvh.trace_ms;
        println!(
            "\nWaving-grid frame on the GPU (primary + shadow; BVH rebuilt): PDACRT {p:.2} ms, BVH {b:.2} ms ({:.2}×); with the triangles' upload: {:.2} / {:.2} ms.",
            p / b,
            p + g[0].pdacrt.upload_ms,
            b + g[0].bvh.upload_ms
        );
    }
    Ok(())
}

fn main() {
    if let Err(e) = run(Args::parse()) {
        eprintln!("error: {e}");
        std::process::exit(1);
    }
}
