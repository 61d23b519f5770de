//! Changing geometry, where structure-free ray casting should win: a procedurally
//! waving grid (not a Stanford model: their terms forbid animation) whose vertices
//! move every frame. Per frame and caster: set-up (the obvhs BVH build; DACRT's
//! triangle boxes; PDACRT's upload), primary rays, and shadow rays to a point light
//! from the primary hits, on each thread count.
//!
//! ```text
//! cargo run --release --example animated -- [--triangles 1000000] [--size 1024]
//!     [--frames 3] [--threads 1,2,4,8,16] [--casters bvh,dacrt,pdacrt] [--json]
//! ```

use clap::Parser;
use std::time::Instant;
use warpray::cast::batches::primary_rays;
use warpray::cast::{BvhCaster, Dacrt, RayCaster, Traversal};
use warpray::geometry::{Hit, Ray, offset_ray_origin};
use warpray::glam::Vec3;
use warpray::pdacrt::Pdacrt;
use warpray::scene::Camera;

#[derive(Parser)]
struct Args {
    /// Triangles in the grid (rounded to a square grid of quads).
    #[arg(long, default_value_t = 1_000_000, value_parser = clap::value_parser!(u64).range(2..=20_000_000))]
    triangles: u64,
    /// Image side in pixels.
    #[arg(long, default_value_t = 1024, value_parser = clap::value_parser!(u32).range(1..=8192))]
    size: u32,
    /// Frames per configuration (the geometry moves between frames).
    #[arg(long, default_value_t = 3, value_parser = clap::value_parser!(u32).range(1..=1000))]
    frames: u32,
    #[arg(long, value_delimiter = ',', default_values_t = [1usize, 2, 4, 8, 16])]
    threads: Vec<usize>,
    #[arg(long, value_delimiter = ',', default_values_t = ["bvh".to_string(), "dacrt".into(), "pdacrt".into()])]
    casters: Vec<String>,
    /// One JSON object per (caster, threads, frame) instead of the table.
    #[arg(long)]
    json: bool,
}

/// The grid at time `time`: `n × n` quads over [-1, 1]², heights from two travelling
/// waves.
fn grid(n: usize, time: f32) -> Vec<[Vec3; 3]> {
    let p = |i: usize, j: usize| {
        let (x, y) = (i as f32 / n as f32 * 2.0 - 1.0, j as f32 / n as f32 * 2.0 - 1.0);
        let h = 0.08 * (7.0 * x + 2.0 * time).sin() * (5.0 * y - 1.3 * time).cos()
            + 0.03 * (23.0 * (x + y) + 5.0 * time).sin();
        Vec3::new(x, h, y)
    };
    let mut tris = Vec::with_capacity(2 * n * n);
    for j in 0..n {
        for i in 0..n {
            let (a, b, c, d) = (p(i, j), p(i + 1, j), p(i + 1, j + 1), p(i, j + 1));
            tris.push([a, b, c]);
            tris.push([a, c, d]);
        }
    }
    tris
}

/// Shadow rays to a light above the grid from every primary hit.
fn shadow_rays(tris: &[[Vec3; 3]], primary: &[Ray], hits: &[Hit]) -> Vec<Ray> {
    let light = Vec3::new(0.3, 2.0, -0.4);
    primary
        .iter()
        .zip(hits)
        .filter(|(_, h)| h.is_hit())
        .map(|(r, h)| {
            let [a, b, c] = tris[h.prim as usize];
            let n = (b - a).cross(c - a).normalize_or_zero();
            let n = if n.dot(r.dir) > 0.0 { -n } else { n };
            let p = offset_ray_origin(r.at(h.t), n);
            Ray::segment(p, light - p, 1.0)
        })
        .collect()
}

struct Frame {
    caster: String,
    threads: usize,
    frame: u32,
    setup_ms: f64,
    primary_ms: f64,
    shadow_ms: f64,
    rays: usize,
    tests: u64,
}

fn build(name: &str, tris: Vec<[Vec3; 3]>) -> Result<Box<dyn RayCaster>, String> {
    Ok(match name {
        "bvh" => Box::new(BvhCaster::from_triangles(tris).with_traversal(Traversal::Fast)),
        "dacrt" => Box::new(Dacrt::from_triangles(tris, Default::default())),
        "pdacrt" => Box::new(Pdacrt::from_triangles(&tris, Default::default())),
        other => return Err(format!("unknown caster {other} (known: bvh, dacrt, pdacrt)")),
    })
}

fn run(a: Args) -> Result<(), String> {
    if let Some(c) = a.casters.iter().find(|c| !["bvh", "dacrt", "pdacrt"].contains(&c.as_str())) {
        return Err(format!("unknown caster {c} (known: bvh, dacrt, pdacrt)"));
    }
    let n = ((a.triangles / 2) as f64).sqrt().round().max(1.0) as usize;
    let camera = Camera::look_at(Vec3::new(0.0, 1.3, -2.2), Vec3::new(0.0, -0.1, 0.0), Vec3::Y, 45.0);
    let primary = primary_rays(&camera, a.size, a.size);
    // The frames' geometry and shadow rays (found with the BVH, outside the timings).
    let frames: Vec<(Vec<[Vec3; 3]>, Vec<Ray>)> = (0..a.frames)
        .map(|f| {
            let tris = grid(n, f as f32 * 0.25);
            let mut hits = vec![Hit::MISS; primary.len()];
            BvhCaster::from_triangles(tris.clone()).closest(&primary, &mut hits);
            let shadow = shadow_rays(&tris, &primary, &hits);
            (tris, shadow)
        })
        .collect();
    eprintln!(
        "grid {n}x{n}: {} triangles, {} primary rays, {} shadow rays",
        2 * n * n,
        primary.len(),
        frames[0].1.len()
    );
    let mut rows = Vec::new();
    for &t in &a.threads {
        let pool = rayon::ThreadPoolBuilder::new().num_threads(t).build().map_err(|e| e.to_string())?;
        for c in &a.casters {
            for (f, (tris, shadow)) in frames.iter().enumerate() {
                let row = pool.install(|| -> Result<Frame, String> {
                    let start = Instant::now();
                    let caster = build(c, tris.clone())?;
                    let setup_ms = start.elapsed().as_secs_f64() * 1e3;
                    let p = caster.closest(&primary, &mut vec![Hit::MISS; primary.len()]);
                    let s = caster.occluded(shadow, &mut vec![false; shadow.len()]);
                    Ok(Frame {
                        caster: c.clone(),
                        threads: t,
                        frame: f as u32,
                        setup_ms,
                        primary_ms: p.seconds * 1e3,
                        shadow_ms: s.seconds * 1e3,
                        rays: p.rays + s.rays,
                        tests: p.tests + s.tests,
                    })
                })?;
                rows.push(row);
            }
            eprintln!("  {c}, {t} threads done");
        }
    }
    if a.json {
        for r in &rows {
            println!(
                "{{\"scene\":\"waving-grid\",\"triangles\":{},\"caster\":\"{}\",\"threads\":{},\"frame\":{},\"setup_ms\":{:.3},\"primary_ms\":{:.3},\"shadow_ms\":{:.3},\"total_ms\":{:.3},\"rays\":{},\"tests\":{}}}",
                2 * n * n,
                r.caster,
                r.threads,
                r.frame,
                r.setup_ms,
                r.primary_ms,
                r.shadow_ms,
                r.setup_ms + r.primary_ms + r.shadow_ms,
                r.rays,
                r.tests
            );
        }
        return Ok(());
    }
    println!(
        "# Waving grid: {} triangles, {}x{} primary + shadow rays, mean over {} frames\n",
        2 * n * n,
        a.size,
        a.size,
        a.frames
    );
    println!("| threads | caster | set-up ms | primary ms | shadow ms | frame ms | tests/ray |");
    println!("|---:|---|---:|---:|---:|---:|---:|");
    for &t in &a.threads {
        for c in &a.casters {
            let mine: Vec<&Frame> = rows.iter().filter(|r| r.threads == t && &r.caster == c).collect();
            let mean = |f: fn(&Frame) -> f64| mine.iter().map(|r| f(r)).sum::<f64>() / mine.len() as f64;
            let tests: u64 = mine.iter().map(|r| r.tests).sum();
            let rays: usize = mine.iter().map(|r| r.rays).sum();
            println!(
                "| {t} | {c} | {:.1} | {:.1} | {:.1} | {:.1} | {:.1} |",
                mean(|r| r.setup_ms),
                mean(|r| r.primary_ms),
                mean(|r| r.shadow_ms),
                mean(|r| r.setup_ms + r.primary_ms + r.shadow_ms),
                tests as f64 / rays.max(1) as f64
            );
        }
    }
    Ok(())
}

fn main() {
    if let Err(e) = run(Args::parse()) {
        eprintln!("error: {e}");
        std::process::exit(1);
    }
}
