//! Changing geometry, where structure-free ray casting should win: a procedurally
//! waving grid (not a Stanford model: their terms forbid animation) whose vertices
//! move every frame. Per frame and caster: set-up (the obvhs BVH build; DACRT's
//! triangle boxes; PDACRT's upload; Embree's rebuild or refit), primary rays, and
//! secondary rays from the primary hits, on each thread count.
//!
//! ```text
//! cargo run --release --features embree --example animated -- [--triangles 1000000]
//!     [--size 1024] [--frames 5] [--threads 1,2,4,8,16] [--secondary shadow|diffuse]
//!     [--casters bvh,bvh4,dacrt,dacrt-sse,dacrt-by-id,dacrt-median,pdacrt,embree,embree-fast,embree-refit] [--json]
//!     [--dacrt-groups-per-thread N] [--dacrt-leaf N]
//! ```
//!
//! Secondary rays: `shadow` (segments to a point light above the grid: coherent, the
//! easy case) or `diffuse` (one cosine-weighted bounce per hit, closest hit: the
//! incoherent case). Casters: `embree` rebuilds every frame with Embree's defaults,
//! `embree-fast` with low quality and the dynamic flag, in 16-ray packets;
//! `embree-refit` keeps one structure and refits it to each frame's vertices (built
//! once before the timed frames). Within each frame the casters run one after another
//! (interleaved), and the table gives medians over the frames. `--json` prints one row
//! per frame and caster, with each call's ray–triangle tests and, for DACRT, its ms
//! by stage (`primary_phases`, `secondary_phases`: `RayCaster::phase_seconds`).

use clap::Parser;
use std::time::Instant;
use warpray::cast::batches::{primary_rays, waving_grid, waving_grid_camera, waving_grid_shadow_rays};
use warpray::cast::{Bvh4, BvhCaster, Dacrt, DacrtParams, RayCaster, Traversal, phases_json};
use warpray::geometry::{Hit, Ray, offset_ray_origin};
use warpray::glam::Vec3;
use warpray::machine::median;
use warpray::pdacrt::Pdacrt;

#[derive(Parser)]
struct Args {
    /// Triangles in the grid (rounded to a square grid of quads).
    #[arg(long, default_value_t = 1_000_000, value_parser = clap::value_parser!(u64).range(2..=20_000_000))]
    triangles: u64,
    /// Image side in pixels.
    #[arg(long, default_value_t = 1024, value_parser = clap::value_parser!(u32).range(1..=8192))]
    size: u32,
    /// Frames per configuration (the geometry moves between frames).
    #[arg(long, default_value_t = 5, value_parser = clap::value_parser!(u32).range(1..=1000))]
    frames: u32,
    /// Secondary rays: `shadow` or `diffuse` (one cosine-weighted bounce per hit).
    #[arg(long, default_value = "shadow", value_parser = ["shadow", "diffuse"])]
    secondary: String,
    #[arg(long, value_delimiter = ',', default_values_t = [1usize, 2, 4, 8, 16])]
    threads: Vec<usize>,
    #[arg(long, value_delimiter = ',', default_values_t = ["bvh".to_string(), "dacrt".into(), "pdacrt".into()])]
    casters: Vec<String>,
    /// One JSON object per (caster, threads, frame) instead of the table.
    #[arg(long)]
    json: bool,
    /// DACRT's ray groups per thread for one-origin batches (default: the library's).
    #[arg(long, value_parser = clap::value_parser!(u64).range(0..=1024))]
    dacrt_groups_per_thread: Option<u64>,
    /// DACRT's leaf size: `leaf_rays` and `leaf_triangles` both (default: the library's).
    #[arg(long, value_parser = clap::value_parser!(u64).range(1..=4096))]
    dacrt_leaf: Option<u64>,
}

/// One cosine-weighted diffuse bounce from every primary hit (seeded by pixel).
fn diffuse_rays(tris: &[[Vec3; 3]], primary: &[Ray], hits: &[Hit]) -> Vec<Ray> {
    use warpray::sampling::{Frame, Rng, cosine_hemisphere};
    primary
        .iter()
        .zip(hits)
        .enumerate()
        .filter(|(_, (_, h))| h.is_hit())
        .map(|(i, (r, h))| {
            let [a, b, c] = tris[h.prim as usize];
            let n = (b - a).cross(c - a).normalize_or_zero();
            let n = if n.dot(r.dir) > 0.0 { -n } else { n };
            let p = offset_ray_origin(r.at(h.t), n);
            let d = Frame::from_normal(n).to_world(cosine_hemisphere(Rng::for_sample(7, i as u64, 0).uniform2()));
            Ray::new(p, d)
        })
        .collect()
}

struct FrameRow {
    caster: String,
    threads: usize,
    frame: u32,
    setup_ms: f64,
    primary_ms: f64,
    secondary_ms: f64,
    rays: usize,
    tests: u64,
    /// The primary and the secondary call's ray–triangle tests and ms by stage
    /// (`RayCaster::phase_seconds`; DACRT's only).
    primary_tests: u64,
    primary_phases: Vec<(&'static str, f64)>,
    secondary_phases: Vec<(&'static str, f64)>,
}

/// The casters this build can measure.
#[cfg(feature = "embree")]
const KNOWN: &[&str] = &[
    "bvh",
    "bvh4",
    "dacrt",
    "dacrt-sse",
    "dacrt-by-id",
    "dacrt-median",
    "pdacrt",
    "embree",
    "embree-fast",
    "embree-refit",
];
#[cfg(not(feature = "embree"))]
const KNOWN: &[&str] = &["bvh", "bvh4", "dacrt", "dacrt-sse", "dacrt-by-id", "dacrt-median", "pdacrt"];

/// A caster kept across frames and told each frame's triangles, or rebuilt each frame.
enum Live {
    Rebuilt(String, DacrtParams),
    #[cfg(feature = "embree")]
    Refit(Option<warpray::cast::embree::EmbreeCaster>),
}

impl Live {
    fn new(name: &str, dacrt: DacrtParams) -> Live {
        match name {
            #[cfg(feature = "embree")]
            "embree-refit" => Live::Refit(None),
            other => Live::Rebuilt(other.to_string(), dacrt),
        }
    }

    /// Sets up the caster for this frame's triangles and runs `f` on it; returns the
    /// set-up's seconds and what `f` returned.
    fn frame<R>(&mut self, tris: Vec<[Vec3; 3]>, f: impl FnOnce(&dyn RayCaster) -> R) -> Result<(f64, R), String> {
        let start = Instant::now();
        match self {
            Live::Rebuilt(name, dacrt) => {
                let c = build(name, tris, *dacrt)?;
                let setup = start.elapsed().as_secs_f64();
                Ok((setup, f(c.as_ref())))
            }
            #[cfg(feature = "embree")]
            Live::Refit(slot) => {
                use warpray::cast::embree::{EmbreeCaster, EmbreeParams};
                let c = match slot {
                    Some(c) => {
                        c.update(tris).map_err(|e| e.to_string())?;
                        c
                    }
                    None => slot
                        .insert(EmbreeCaster::from_triangles(tris, EmbreeParams::refit()).map_err(|e| e.to_string())?),
                };
                let setup = start.elapsed().as_secs_f64();
                Ok((setup, f(&*c)))
            }
        }
    }
}

fn build(name: &str, tris: Vec<[Vec3; 3]>, dacrt: DacrtParams) -> Result<Box<dyn RayCaster>, String> {
    Ok(match name {
        "bvh" => Box::new(BvhCaster::from_triangles(tris).with_traversal(Traversal::Fast)),
        "bvh4" => Box::new(Bvh4::from_triangles(tris)),
        "dacrt" => Box::new(Dacrt::from_triangles(tris, dacrt)),
        // DACRT on SSE alone (no AVX2 or AVX-512 lanes): what the lanes are worth.
        "dacrt-sse" => Box::new(Dacrt::from_triangles(tris, DacrtParams { lanes: false, ..dacrt })),
        // DACRT gathering every cell's triangles from the scene by id (no per-call
        // layout): what the layout is worth.
        "dacrt-by-id" => Box::new(Dacrt::from_triangles(tris, DacrtParams { cell_layout: false, ..dacrt })),
        // DACRT splitting every node at the spatial median (no ray-sampled planes).
        "dacrt-median" => Box::new(Dacrt::from_triangles(tris, DacrtParams { sampled_min_pairs: 0, ..dacrt })),
        "pdacrt" => Box::new(Pdacrt::from_triangles(&tris, Default::default())),
        #[cfg(feature = "embree")]
        "embree" | "embree-fast" => {
            use warpray::cast::embree::{EmbreeCaster, EmbreeParams};
            let p = EmbreeParams::by_label(name).expect("a label of EmbreeParams");
            Box::new(EmbreeCaster::from_triangles(tris, p).map_err(|e| e.to_string())?)
        }
        other => return Err(format!("unknown caster {other} (known: {})", KNOWN.join(", "))),
    })
}

fn run(a: Args) -> Result<(), String> {
    if let Some(c) = a.casters.iter().find(|c| !KNOWN.contains(&c.as_str())) {
        return Err(format!("unknown caster {c} (known: {})", KNOWN.join(", ")));
    }
    let diffuse = a.secondary == "diffuse";
    let mut dacrt = DacrtParams::default();
    dacrt.groups_per_thread = a.dacrt_groups_per_thread.map_or(dacrt.groups_per_thread, |g| g as usize);
    if let Some(leaf) = a.dacrt_leaf {
        (dacrt.leaf_rays, dacrt.leaf_triangles) = (leaf as usize, leaf as usize);
    }
    let n = ((a.triangles / 2) as f64).sqrt().round().max(1.0) as usize;
    let camera = waving_grid_camera();
    let primary = primary_rays(&camera, a.size, a.size);
    // The frames' geometry and secondary rays (found with the BVH, outside the timings).
    let secondary = |tris: &[[Vec3; 3]], hits: &[Hit]| {
        if diffuse { diffuse_rays(tris, &primary, hits) } else { waving_grid_shadow_rays(tris, &primary, hits) }
    };
    let frames: Vec<(Vec<[Vec3; 3]>, Vec<Ray>)> = (0..a.frames)
        .map(|f| {
            let tris = waving_grid(n, f as f32 * 0.25);
            let mut hits = vec![Hit::MISS; primary.len()];
            BvhCaster::from_triangles(tris.clone()).closest(&primary, &mut hits);
            let rays = secondary(&tris, &hits);
            (tris, rays)
        })
        .collect();
    let machine = warpray::machine::Machine::this();
    eprintln!(
        "grid {n}x{n}: {} triangles, {} primary rays, {} {} rays\nmachine: {machine}",
        2 * n * n,
        primary.len(),
        frames[0].1.len(),
        a.secondary
    );
    let mut rows = Vec::new();
    for &t in &a.threads {
        let pool = rayon::ThreadPoolBuilder::new().num_threads(t).build().map_err(|e| e.to_string())?;
        let mut live: Vec<Live> = a.casters.iter().map(|c| Live::new(c, dacrt)).collect();
        // A refitted structure is built once, from the frame before the first.
        pool.install(|| live.iter_mut().try_for_each(|l| l.frame(waving_grid(n, -0.25), |_| ()).map(|_| ())))?;
        for (f, (tris, rays)) in frames.iter().enumerate() {
            for (c, l) in a.casters.iter().zip(&mut live) {
                let (setup, ((p, primary_phases), (s, secondary_phases))) = pool.install(|| {
                    l.frame(tris.clone(), |caster| {
                        let p = caster.closest(&primary, &mut vec![Hit::MISS; primary.len()]);
                        let p_phases = caster.phase_seconds();
                        let s = if diffuse {
                            caster.closest(rays, &mut vec![Hit::MISS; rays.len()])
                        } else {
                            caster.occluded(rays, &mut vec![false; rays.len()])
                        };
                        ((p, p_phases), (s, caster.phase_seconds()))
                    })
                })?;
                rows.push(FrameRow {
                    caster: c.clone(),
                    threads: t,
                    frame: f as u32,
                    setup_ms: setup * 1e3,
                    primary_ms: p.seconds * 1e3,
                    secondary_ms: s.seconds * 1e3,
                    rays: p.rays + s.rays,
                    tests: p.tests + s.tests,
                    primary_tests: p.tests,
                    primary_phases,
                    secondary_phases,
                });
            }
        }
        eprintln!("  {t} threads done");
    }
    let scene = if diffuse { "waving-grid-diffuse" } else { "waving-grid" };
    if a.json {
        println!("{{\"machine\":{}}}", machine.json());
        for r in &rows {
            println!(
                "{{\"scene\":\"{scene}\",\"triangles\":{},\"caster\":\"{}\",\"threads\":{},\"frame\":{},\"setup_ms\":{:.3},\"primary_ms\":{:.3},\"secondary\":\"{}\",\"secondary_ms\":{:.3},\"total_ms\":{:.3},\"rays\":{},\"tests\":{},\"primary_tests\":{},\"primary_phases\":{},\"secondary_phases\":{}}}",
                2 * n * n,
                r.caster,
                r.threads,
                r.frame,
                r.setup_ms,
                r.primary_ms,
                a.secondary,
                r.secondary_ms,
                r.setup_ms + r.primary_ms + r.secondary_ms,
                r.rays,
                r.tests,
                r.primary_tests,
                phases_json(&r.primary_phases),
                phases_json(&r.secondary_phases)
            );
        }
        return Ok(());
    }
    println!(
        "# Waving grid: {} triangles, {}x{} primary + {} rays, medians over {} frames\n\nMachine: {machine}\n",
        2 * n * n,
        a.size,
        a.size,
        a.secondary,
        a.frames
    );
    println!("| threads | caster | set-up ms | primary ms | {} ms | frame ms | tests/ray |", a.secondary);
    println!("|---:|---|---:|---:|---:|---:|---:|");
    for &t in &a.threads {
        for c in &a.casters {
            let mine: Vec<&FrameRow> = rows.iter().filter(|r| r.threads == t && &r.caster == c).collect();
            let med = |f: fn(&FrameRow) -> f64| median(mine.iter().map(|r| f(r)).collect());
            let tests: u64 = mine.iter().map(|r| r.tests).sum();
            let rays: usize = mine.iter().map(|r| r.rays).sum();
            println!(
                "| {t} | {c} | {:.1} | {:.1} | {:.1} | {:.1} | {:.1} |",
                med(|r| r.setup_ms),
                med(|r| r.primary_ms),
                med(|r| r.secondary_ms),
                med(|r| r.setup_ms + r.primary_ms + r.secondary_ms),
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
