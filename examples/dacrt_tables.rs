//! The paper's tables for this machine: ray casting without a stored structure (DACRT,
//! PDACRT) against the obvhs BVH and Embree (build and trace separately, and summed),
//! on primary, shadow (one point light), specular (mirror) and ambient-occlusion
//! batches (8 rays per primary hit), with peak memory and ray–triangle tests; and
//! thread scaling.
//!
//! ```text
//! WARPRAY_MODELS=../shared/models cargo run --release --features embree --example dacrt_tables -- \
//!     [--size 1024] [--scenes bunny,conference,dragon] \
//!     [--casters bvh,bvh4,dacrt,pdacrt,embree,embree-fast] [--rounds 5] \
//!     [--threads N] [--scaling 1,2,4,8,16] [--ao 8] [--repeat 1] [--sweep] [--json] \
//!     [--pdacrt-chunk RAYS] [--dacrt-top-cell TRIANGLES] [--dacrt-groups-per-thread N]
//!     [--dacrt-packet RAYS]
//! ```
//!
//! `bvh4` traces in packets of 16 rays where the CPU has AVX-512 (8 with AVX2),
//! `bvh4-8` in packets of 8 rays, `bvh4-single` the same tree one ray at a time.
//! `dacrt` partitions and solves leaves on the widest SIMD lanes the CPU has (16 on
//! AVX-512, 8 on AVX2), `dacrt-sse` on SSE alone (`DacrtParams::lanes` off): the same
//! hits and tests, so the two columns show what the lanes are worth on this machine.
//! `embree` is Embree's default build (medium quality) traced one ray at a time;
//! `embree-fast` its fastest rebuild (low quality, dynamic scene) traced in 16-ray
//! packets; both need the cargo feature `embree`. With `--rounds R` every caster is
//! measured once per round, the casters interleaved within each round, and each cell
//! is the median over the rounds (build, trace and their sum, each its own median).
//!
//! `--json` prints the machine (`{"machine":{...}}`), then one object per measured row
//! (keys `scene, batch, caster, threads, rays, rounds, build_ms, trace_ms, total_ms,
//! peak_bytes, tests`, plus `structure_bytes`, and for DACRT `phases`: the median
//! call's ms by stage, `RayCaster::phase_seconds`) instead of the tables.

use clap::Parser;
use warpray::cast::batches::interior_camera;
use warpray::cast::{Bvh4, BvhBuild, BvhCaster, CastStats, Dacrt, DacrtParams, RayCaster, Traversal, phases_json};
use warpray::geometry::{Hit, Ray};
use warpray::machine::median;
use warpray::pdacrt::{Pdacrt, PdacrtParams};
use warpray::scene::{ObjOptions, Scene, find_model, load_obj, models_dir};

#[derive(Parser)]
struct Args {
    /// Image side in pixels (primary rays: size²).
    #[arg(long, default_value_t = 1024, value_parser = clap::value_parser!(u32).range(1..=8192))]
    size: u32,
    /// Models from WARPRAY_MODELS.
    #[arg(long, value_delimiter = ',', default_values_t = ["bunny".to_string(), "conference".into(), "dragon".into()])]
    scenes: Vec<String>,
    #[arg(long, value_delimiter = ',', default_values_t = ["bvh".to_string(), "dacrt".into(), "pdacrt".into()])]
    casters: Vec<String>,
    /// Worker threads (default: all cores).
    #[arg(long, value_parser = clap::value_parser!(u32).range(1..=1024))]
    threads: Option<u32>,
    /// Thread counts for the scaling table (primary + shadow rays).
    #[arg(long, value_delimiter = ',')]
    scaling: Vec<usize>,
    /// AO rays per primary hit.
    #[arg(long, default_value_t = 8, value_parser = clap::value_parser!(u32).range(0..=64))]
    ao: u32,
    /// Runs per measurement; the fastest is kept.
    #[arg(long, default_value_t = 1, value_parser = clap::value_parser!(u32).range(1..=100))]
    repeat: u32,
    /// Interleaved rounds; each cell is the median over them.
    #[arg(long, default_value_t = 1, value_parser = clap::value_parser!(u32).range(1..=1000))]
    rounds: u32,
    /// Leaf-size sweep on primary rays.
    #[arg(long)]
    sweep: bool,
    /// One JSON object per row instead of tables.
    #[arg(long)]
    json: bool,
    /// PDACRT rays per chunk (default: PDACRT's own).
    #[arg(long)]
    pdacrt_chunk: Option<usize>,
    /// DACRT's `top_cell_triangles` (default: DACRT's own).
    #[arg(long)]
    dacrt_top_cell: Option<usize>,
    /// DACRT's `groups_per_thread` (default: DACRT's own).
    #[arg(long)]
    dacrt_groups_per_thread: Option<usize>,
    /// DACRT's `packet_rays` (0: no packet filtering; default: DACRT's own).
    #[arg(long)]
    dacrt_packet: Option<usize>,
    /// DACRT's `fork_min_rays` (0: no forks; default: DACRT's own).
    #[arg(long)]
    dacrt_fork: Option<usize>,
    /// DACRT's `sampled_min_pairs` (0: no ray-sampled planes; default: DACRT's own).
    #[arg(long)]
    dacrt_sampled: Option<u64>,
}

/// Tunables given on the command line, over the casters' defaults.
#[derive(Clone, Copy, Default)]
struct Tunables {
    pdacrt_chunk: Option<usize>,
    dacrt_top_cell: Option<usize>,
    dacrt_groups_per_thread: Option<usize>,
    dacrt_packet: Option<usize>,
    dacrt_fork: Option<usize>,
    dacrt_sampled: Option<u64>,
}

/// One measured (scene, batch, caster, threads) cell.
struct Row {
    scene: String,
    batch: &'static str,
    caster: &'static str,
    threads: usize,
    rays: usize,
    build_ms: f64,
    trace_ms: f64,
    /// Build + trace (with rounds: the median of the rounds' sums).
    total_ms: f64,
    rounds: u32,
    peak_bytes: usize,
    structure_bytes: usize,
    tests: u64,
    /// The caster's stages of the fastest call, seconds (DACRT only).
    phases: Vec<(&'static str, f64)>,
}

impl Row {
    fn json(&self) -> String {
        format!(
            "{{\"scene\":\"{}\",\"batch\":\"{}\",\"caster\":\"{}\",\"threads\":{},\"rays\":{},\"rounds\":{},\"build_ms\":{:.3},\"trace_ms\":{:.3},\"total_ms\":{:.3},\"peak_bytes\":{},\"structure_bytes\":{},\"tests\":{}{}}}",
            self.scene,
            self.batch,
            self.caster,
            self.threads,
            self.rays,
            self.rounds,
            self.build_ms,
            self.trace_ms,
            self.total_ms,
            self.peak_bytes,
            self.structure_bytes,
            self.tests,
            phases_field(&self.phases)
        )
    }
}

/// `,"phases":{...}` in ms, or nothing.
fn phases_field(phases: &[(&str, f64)]) -> String {
    if phases.is_empty() { String::new() } else { format!(",\"phases\":{}", phases_json(phases)) }
}

fn scene(name: &str) -> Result<Scene, String> {
    let path = find_model(name)
        .ok_or_else(|| format!("model {name} not found in {}: set WARPRAY_MODELS", models_dir().display()))?;
    let mut s = load_obj(path, &ObjOptions::default()).map_err(|e| e.to_string())?;
    if name == "conference" {
        interior_camera(&mut s);
    }
    Ok(s)
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

/// The caster (only the BVH builds a structure; the others copy the triangles).
fn build(name: &str, s: &Scene) -> Result<Box<dyn RayCaster>, String> {
    Ok(match name {
        "bvh" => Box::new(BvhCaster::new(s).with_traversal(Traversal::Fast)),
        "bvh-fast" | "bvh-very-fast" | "bvh-fastest" => {
            let b = match name {
                "bvh-fast" => BvhBuild::Fast,
                "bvh-very-fast" => BvhBuild::VeryFast,
                _ => BvhBuild::Fastest,
            };
            Box::new(BvhCaster::with_build(s.triangle_vertices(), b).with_traversal(Traversal::Fast))
        }
        "bvh4" => Box::new(Bvh4::new(s)),
        "bvh4-8" => Box::new(Bvh4::new(s).max_packet(8)),
        "bvh4-single" => Box::new(Bvh4::new(s).single_rays()),
        "dacrt" | "dacrt-sse" | "dacrt-by-id" | "dacrt-median" => {
            let mut d = Dacrt::new(s);
            d.params.lanes = name != "dacrt-sse";
            d.params.cell_layout = name != "dacrt-by-id";
            let t = TUNABLES.get().copied().unwrap_or_default();
            d.params.top_cell_triangles = t.dacrt_top_cell.unwrap_or(d.params.top_cell_triangles);
            d.params.groups_per_thread = t.dacrt_groups_per_thread.unwrap_or(d.params.groups_per_thread);
            d.params.packet_rays = t.dacrt_packet.unwrap_or(d.params.packet_rays);
            d.params.fork_min_rays = t.dacrt_fork.unwrap_or(d.params.fork_min_rays);
            d.params.sampled_min_pairs = t.dacrt_sampled.unwrap_or(d.params.sampled_min_pairs);
            if name == "dacrt-median" {
                d.params.sampled_min_pairs = 0;
            }
            Box::new(d)
        }
        "pdacrt" => {
            let mut p = Pdacrt::new(s);
            if let Some(c) = TUNABLES.get().and_then(|t| t.pdacrt_chunk) {
                p.params.chunk_rays = c;
            }
            Box::new(p)
        }
        #[cfg(feature = "embree")]
        "embree" | "embree-fast" => {
            use warpray::cast::embree::{EmbreeCaster, EmbreeParams};
            let p = EmbreeParams::by_label(name).expect("a label of EmbreeParams");
            Box::new(EmbreeCaster::from_triangles(s.triangle_vertices(), p).map_err(|e| e.to_string())?)
        }
        other => return Err(format!("unknown caster {other} (known: {})", known().collect::<Vec<_>>().join(", "))),
    })
}

/// The casters this build can measure: warpray's own, then Embree's where it is built in.
const OWN: &[&str] = &[
    "bvh",
    "bvh-fast",
    "bvh-very-fast",
    "bvh-fastest",
    "bvh4",
    "bvh4-8",
    "bvh4-single",
    "dacrt",
    "dacrt-sse",
    "dacrt-by-id",
    "dacrt-median",
    "pdacrt",
];
#[cfg(feature = "embree")]
const EMBREE: &[&str] = &["embree", "embree-fast"];
#[cfg(not(feature = "embree"))]
const EMBREE: &[&str] = &[];

fn known() -> impl Iterator<Item = &'static str> {
    OWN.iter().chain(EMBREE).copied()
}

/// One row per cell from the rounds' rows: build, trace and total each the median of
/// its own values; the stages of the round whose trace was nearest the median.
fn medians(rounds: Vec<Vec<Row>>) -> Vec<Row> {
    let mut cells: Vec<Vec<Row>> = Vec::new();
    for row in rounds.into_iter().flatten() {
        let same = |r: &Row| {
            r.scene == row.scene && r.batch == row.batch && r.caster == row.caster && r.threads == row.threads
        };
        match cells.iter_mut().find(|c| same(&c[0])) {
            Some(c) => c.push(row),
            None => cells.push(vec![row]),
        }
    }
    cells
        .into_iter()
        .map(|mut c| {
            let n = c.len() as u32;
            let build = median(c.iter().map(|r| r.build_ms).collect());
            let trace = median(c.iter().map(|r| r.trace_ms).collect());
            let total = median(c.iter().map(|r| r.build_ms + r.trace_ms).collect());
            let peak = c.iter().map(|r| r.peak_bytes).max().unwrap_or(0);
            c.sort_by(|a, b| (a.trace_ms - trace).abs().total_cmp(&(b.trace_ms - trace).abs()));
            let mut r = c.swap_remove(0);
            (r.build_ms, r.trace_ms, r.total_ms, r.rounds, r.peak_bytes) = (build, trace, total, n, peak);
            r
        })
        .collect()
}

/// The command line's tunables, set once before anything is measured.
static TUNABLES: std::sync::OnceLock<Tunables> = std::sync::OnceLock::new();

fn cast(c: &dyn RayCaster, rays: &[Ray], shadow: bool) -> CastStats {
    if shadow {
        c.occluded(rays, &mut vec![false; rays.len()])
    } else {
        c.closest(rays, &mut vec![Hit::MISS; rays.len()])
    }
}

/// Rows for one caster on the given batches; the BVH is rebuilt for each run, so its
/// build time is measured as often as the traces.
fn measure(
    caster: &str,
    s: &Scene,
    scene_name: &str,
    batches: &[(&'static str, Vec<Ray>, bool)],
    repeat: u32,
) -> Result<Vec<Row>, String> {
    let threads = rayon::current_num_threads();
    let mut rows: Vec<Row> = Vec::new();
    for _ in 0..repeat {
        let c = build(caster, s)?;
        for (k, (name, rays, shadow)) in batches.iter().enumerate() {
            let st = cast(c.as_ref(), rays, *shadow);
            let row = Row {
                scene: scene_name.into(),
                batch: name,
                // The command line's label (two labels may build one caster type).
                caster: known().find(|&k| k == caster).unwrap_or(c.name()),
                threads,
                rays: rays.len(),
                build_ms: c.build_seconds() * 1e3,
                trace_ms: st.seconds * 1e3,
                total_ms: (c.build_seconds() + st.seconds) * 1e3,
                rounds: 1,
                peak_bytes: st.peak_working_bytes + c.memory_bytes(),
                structure_bytes: c.memory_bytes(),
                tests: st.tests,
                phases: c.phase_seconds(),
            };
            match rows.get_mut(k) {
                Some(r) => {
                    r.build_ms = r.build_ms.min(row.build_ms);
                    r.total_ms = r.build_ms + r.trace_ms.min(row.trace_ms);
                    if row.trace_ms < r.trace_ms {
                        r.trace_ms = row.trace_ms;
                        r.phases = row.phases;
                    }
                }
                None => rows.push(row),
            }
        }
    }
    Ok(rows)
}

/// Primary-ray time over a grid of leaf sizes, for choosing the defaults.
fn sweep(s: &Scene, primary: &[Ray]) {
    println!("\n## Leaf-size sweep: primary rays, trace ms (tests per ray)\n");
    println!("| leaf rays | leaf triangles | dacrt ms | pdacrt ms |");
    println!("|---:|---:|---:|---:|");
    let tris = s.triangle_vertices();
    for (lr, lt) in [(4, 4), (8, 8), (12, 12), (16, 16), (32, 8), (32, 16), (64, 16), (64, 32), (128, 32)] {
        let d = Dacrt::from_triangles(
            tris.clone(),
            DacrtParams { leaf_rays: lr, leaf_triangles: lt, ..Default::default() },
        );
        let p = Pdacrt::from_triangles(
            &tris,
            PdacrtParams { leaf_rays: lr as u32, leaf_triangles: lt as u32, ..Default::default() },
        );
        let best = |c: &dyn RayCaster| {
            let runs: Vec<CastStats> = (0..3).map(|_| cast(c, primary, false)).collect();
            let ms = runs.iter().map(|r| r.seconds).fold(f64::MAX, f64::min) * 1e3;
            format!("{ms:.1} ({:.0})", runs[0].tests_per_ray())
        };
        println!("| {lr} | {lt} | {} | {} |", best(&d), best(&p));
    }
}

fn print_tables(rows: &[Row]) {
    let threads = rows.first().map_or(0, |r| r.threads);
    let find = |scene: &str, caster: &str, batch: &str| {
        rows.iter().find(|r| r.scene == scene && r.caster == caster && r.batch == batch && r.threads == threads)
    };
    let mut keys: Vec<(String, &'static str)> = Vec::new();
    for r in rows.iter().filter(|r| r.threads == threads) {
        if !keys.iter().any(|k| k.0 == r.scene && k.1 == r.caster) {
            keys.push((r.scene.clone(), r.caster));
        }
    }
    println!("\n## Table 1: primary rays ({threads} threads)\n");
    println!("| scene | caster | build ms | trace ms | total ms | Mrays/s (trace) | tests/ray |");
    println!("|---|---|---:|---:|---:|---:|---:|");
    for (s, c) in &keys {
        if let Some(r) = find(s, c, "primary") {
            println!(
                "| {s} | {c} | {:.1} | {:.1} | {:.1} | {:.2} | {:.1} |",
                r.build_ms,
                r.trace_ms,
                r.total_ms,
                r.rays as f64 / r.trace_ms / 1e3,
                r.tests as f64 / r.rays as f64
            );
        }
    }
    println!("\n## Table 2: secondary rays, trace ms (Mrays/s; tests/ray) ({threads} threads)\n");
    println!("| scene | caster | shadow | specular | ambient occlusion |");
    println!("|---|---|---:|---:|---:|");
    for (s, c) in &keys {
        let cell = |b: &str| {
            find(s, c, b).map_or("-".into(), |r| {
                format!(
                    "{:.1} ({:.2}; {:.1})",
                    r.trace_ms,
                    r.rays as f64 / r.trace_ms / 1e3,
                    r.tests as f64 / r.rays.max(1) as f64
                )
            })
        };
        println!("| {s} | {c} | {} | {} | {} |", cell("shadow"), cell("specular"), cell("ao"));
    }
    println!("\n## Table 3: peak memory, MB (structure or working set, plus triangles), and bytes per ray\n");
    println!("| scene | caster | batch | rays | peak MB | working bytes/ray |");
    println!("|---|---|---|---:|---:|---:|");
    for r in rows.iter().filter(|r| r.threads == threads) {
        println!(
            "| {} | {} | {} | {} | {:.1} | {:.1} |",
            r.scene,
            r.caster,
            r.batch,
            r.rays,
            r.peak_bytes as f64 / 1e6,
            (r.peak_bytes - r.structure_bytes) as f64 / r.rays.max(1) as f64
        );
    }
}

fn run(a: Args) -> Result<(), String> {
    let tunables = Tunables {
        pdacrt_chunk: a.pdacrt_chunk,
        dacrt_top_cell: a.dacrt_top_cell,
        dacrt_groups_per_thread: a.dacrt_groups_per_thread,
        dacrt_packet: a.dacrt_packet,
        dacrt_fork: a.dacrt_fork,
        dacrt_sampled: a.dacrt_sampled,
    };
    TUNABLES.set(tunables).map_err(|_| "tunables set twice".to_string())?;
    let mut pool = rayon::ThreadPoolBuilder::new();
    if let Some(t) = a.threads {
        pool = pool.num_threads(t as usize);
    }
    let pool = pool.build().map_err(|e| e.to_string())?;
    // Check every name before any work starts.
    if let Some(c) = a.casters.iter().find(|c| !known().any(|k| k == c.as_str())) {
        return Err(format!("unknown caster {c} (known: {})", known().collect::<Vec<_>>().join(", ")));
    }
    let machine = warpray::machine::Machine::this();
    if a.json {
        println!("{{\"machine\":{}}}", machine.json());
    } else {
        println!(
            "# DACRT tables: {}x{} primary rays, {} AO rays per hit, {} threads, {} interleaved round(s)\n\nMachine: {machine}",
            a.size,
            a.size,
            a.ao,
            pool.current_num_threads(),
            a.rounds
        );
    }
    let mut rows = Vec::new();
    for name in &a.scenes {
        let s = scene(name)?;
        let b = batches(&s, a.size, a.ao as usize);
        if a.sweep {
            pool.install(|| sweep(&s, &b[0].1));
        }
        eprintln!(
            "{name}: {} triangles; rays: {}",
            s.triangle_count(),
            b.iter().map(|x| format!("{} {}", x.0, x.1.len())).collect::<Vec<_>>().join(", ")
        );
        let mut rounds = Vec::new();
        for round in 0..a.rounds {
            for c in &a.casters {
                rounds.push(pool.install(|| measure(c, &s, name, &b, a.repeat))?);
            }
            eprintln!("  round {} of {} done", round + 1, a.rounds);
        }
        rows.extend(medians(rounds));
        for &t in &a.scaling {
            let pool = rayon::ThreadPoolBuilder::new().num_threads(t).build().map_err(|e| e.to_string())?;
            let mut rounds = Vec::new();
            for _ in 0..a.rounds {
                for c in &a.casters {
                    rounds.push(pool.install(|| measure(c, &s, name, &b[..2], a.repeat))?);
                }
            }
            rows.extend(medians(rounds));
            eprintln!("  {t} threads done");
        }
        if !a.json && !a.scaling.is_empty() {
            println!("\n## Thread scaling on {name}: primary + shadow rays, Mrays/s (BVH includes its build)\n");
            println!("| threads | {} |", a.casters.join(" | "));
            println!("|---:|{}|", a.casters.iter().map(|_| "---:").collect::<Vec<_>>().join("|"));
            for &t in &a.scaling {
                let cells: Vec<String> = a
                    .casters
                    .iter()
                    .map(|c| {
                        let mine: Vec<&Row> = rows
                            .iter()
                            .filter(|r| r.scene == *name && r.caster == c && r.threads == t)
                            .take(2)
                            .collect();
                        let rays: usize = mine.iter().map(|r| r.rays).sum();
                        let ms: f64 =
                            mine.iter().map(|r| r.trace_ms).sum::<f64>() + mine.first().map_or(0.0, |r| r.build_ms);
                        format!("{:.2}", rays as f64 / ms / 1e3)
                    })
                    .collect();
                println!("| {t} | {} |", cells.join(" | "));
            }
        }
    }
    if a.json {
        for r in &rows {
            println!("{}", r.json());
        }
    } else {
        print_tables(&rows);
    }
    Ok(())
}

fn main() {
    if let Err(e) = run(Args::parse()) {
        eprintln!("error: {e}");
        std::process::exit(1);
    }
}
