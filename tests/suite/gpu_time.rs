//! simt's GPU time model against the H200's measured kernel times (`docs/simt.md`,
//! "Predicted GPU time"), from the files one lent-machine run left in
//! `docs/measured/h200-time-model/`: the microbenchmarks' output and Nsight Compute's
//! counters of them, the emulator's launch records of PDACRT (bunny, conference, dragon
//! at 1024², primary and shadow rays) and of CIS-LBDPT's shading and compaction, and
//! ncu's counters of the same launches on the GPU. No GPU is needed: the files are the
//! measurement, the model is recomputed here.
#![cfg(feature = "cuda")]

use simt::{GpuProfile, LaunchRecord};
use warpray::gpu::calibrate::calibrate;
use warpray::gpu::ncu::parse_csv;
use warpray::gpu::time_check::{CheckedRun, check, errors, predicted_total, primitive_times};

const DIR: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/docs/measured/h200-time-model/");
const MODELS: [&str; 3] = ["bunny", "conference", "dragon"];

/// A file of `docs/measured/h200-time-model/` by name, or any file by its absolute path
/// (`.gz` unpacked).
fn text(name: &str) -> String {
    let path = if name.starts_with('/') { name.to_string() } else { format!("{DIR}{name}") };
    let bytes = std::fs::read(&path).unwrap_or_else(|e| panic!("{path}: {e}"));
    if name.ends_with(".gz") {
        let mut s = String::new();
        std::io::Read::read_to_string(&mut flate2::read::GzDecoder::new(&bytes[..]), &mut s).unwrap();
        s
    } else {
        String::from_utf8(bytes).unwrap()
    }
}

fn runs() -> Vec<CheckedRun> {
    let mut out: Vec<CheckedRun> = MODELS
        .iter()
        .map(|m| CheckedRun {
            records: simt::records_from_tsv(&text(&format!("simt-records-pdacrt-{m}-1024-primary-shadow.tsv.gz")))
                .unwrap(),
            kernels: parse_csv(&text(&format!("ncu-pdacrt-{m}-1024-primary-shadow.csv.gz"))).unwrap(),
            every: Some(
                parse_csv(&text(&format!("ncu-time-every-kernel-pdacrt-{m}-1024-primary-shadow.csv.gz")))
                    .unwrap()
                    .iter()
                    .map(|k| k.seconds)
                    .sum(),
            ),
        })
        .collect();
    out.push(CheckedRun {
        records: simt::records_from_tsv(&text("simt-records-cis-shading-compaction-3-scenes-128.tsv.gz")).unwrap(),
        kernels: parse_csv(&text("ncu-cis-shading-compaction-3-scenes-128.csv.gz")).unwrap(),
        every: Some(
            parse_csv(&text("ncu-time-every-kernel-cis-3-scenes-128.csv.gz")).unwrap().iter().map(|k| k.seconds).sum(),
        ),
    });
    out
}

/// Whether the model meets the issue's bars on these runs: a mean absolute error ≤ 20 %
/// over the kernels, no kernel past 50 %, and each whole pipeline timed (the three PDACRT
/// traces, CIS's shading and compaction: +2.6 %, +15.2 % with each copied vertex's
/// fifteen loads a round each) within 15 %.
fn meets_bars(runs: &[CheckedRun], p: &GpuProfile) -> Result<(), String> {
    let (rows, pipelines) = check(runs, p);
    if let Some(e) = pipelines.iter().find(|e| e.abs() > 0.15) {
        return Err(format!("a pipeline off by {:+.1} %", e * 100.0));
    }
    let (mape, worst) = errors(&rows);
    let worst = worst.unwrap();
    if mape > 0.20 {
        return Err(format!("mean absolute error {:.1} % over {} kernels", mape * 100.0, rows.len()));
    }
    if worst.error().abs() > 0.50 {
        return Err(format!("{} off by {:+.0} %", worst.name, worst.error() * 100.0));
    }
    Ok(())
}

/// The shipped profile's probe runs, output and ncu's CSV of each: the full run, the
/// later one of the atomic-latency and fence probes (with the fences after scattered
/// stores), and the overlap probes (on an H100; no H200 came).
fn calibration_runs() -> ([String; 4], [String; 4]) {
    (
        [
            text("microbenchmark-probes.tsv"),
            text("microbenchmark-probes-fences-scattered-stores.tsv"),
            text("microbenchmark-probes-overlap-h100.tsv"),
            text("../icache-probes-h100-straight-and-jumping-code-1-to-32-warps.tsv"),
        ],
        [
            text("ncu-microbenchmarks.csv.gz"),
            text("ncu-microbenchmarks-fences-scattered-stores.csv.gz"),
            text("ncu-microbenchmarks-overlap-h100.csv.gz"),
            text("../ncu-icache-probes-h100-1-to-32-warps.csv.gz"),
        ],
    )
}

#[test]
fn an_overlap_run_whose_loads_alone_are_other_loads_is_refused() {
    // The first overlap call's free-running loads-alone form summed two of its four
    // words, and the compiler loaded those two apart: twice the L1 sectors of the forms
    // with arithmetic. Its share would compare other loads; calibration says so.
    let (mut probes, mut csvs) = calibration_runs();
    probes[2] = text("microbenchmark-probes-overlap-h100-free-loads-of-two-words.tsv");
    csvs[2] = text("ncu-microbenchmarks-overlap-h100-free-loads-of-two-words.csv.gz");
    let Err(e) =
        calibrate(&[&probes[0], &probes[1], &probes[2], &probes[3]], &[&csvs[0], &csvs[1], &csvs[2], &csvs[3]])
    else {
        panic!("the two-word loads calibrated")
    };
    assert!(e.contains("overlap_free") && e.contains("not the same loads"), "{e}");
}

#[test]
fn the_shipped_h200_profile_is_the_microbenchmarks_calibration_and_nothing_else() {
    let (probes, csvs) = calibration_runs();
    let c = calibrate(&[&probes[0], &probes[1], &probes[2], &probes[3]], &[&csvs[0], &csvs[1], &csvs[2], &csvs[3]])
        .unwrap();
    let shipped = GpuProfile::named("h200").unwrap();
    // The shipped file holds four significant digits of each value.
    let again = GpuProfile::parse(&c.to_text("")).unwrap();
    assert_eq!(again, shipped, "simt/profiles/h200.toml is not what the stored microbenchmarks give");
}

#[test]
fn the_fetch_keys_come_from_the_icache_probes_or_calibration_says_which_run_is_missing() {
    // Without the instruction-fetch run there is no fetch-bound rate to write: the error
    // names the run. With it, the two keys are the probes' (64 KiB, the straight code's
    // knee; 0.489 warp instructions a cycle, the jumping probe's most, at 32 warps a SM:
    // 4.082e9 warp instructions over 132 SMs in 3,862.15 cycles a piece, 16,384 pieces).
    let (probes, csvs) = calibration_runs();
    let Err(e) = calibrate(&[&probes[0], &probes[1], &probes[2]], &[&csvs[0], &csvs[1], &csvs[2]]) else {
        panic!("calibrated without the icache probes")
    };
    assert!(e.contains("icache") && e.contains("MODE=icache"), "{e}");
    let c = calibrate(&[&probes[0], &probes[1], &probes[2], &probes[3]], &[&csvs[0], &csvs[1], &csvs[2], &csvs[3]])
        .unwrap();
    assert_eq!(c.profile.fetch_thrash_code_bytes, 64.0 * 1024.0);
    let rate = c.profile.fetch_issue_per_cycle_per_sm;
    assert!((rate - 4.082171196e9 / 132.0 / (3862.154 * 16384.0)).abs() < 0.0005, "{rate}");
    let source = c.sources.iter().find(|(k, _)| *k == "fetch_issue_per_cycle_per_sm").unwrap();
    assert!(source.1.contains("32 warps") && source.1.contains("H100"), "{}", source.1);
}

#[test]
fn an_h100s_fence_probes_are_refused_with_the_reason() {
    // The H100's two fence probes under load put a negative own cost on a line through
    // them (docs/simt.md, "Fences under load, probed"): calibration says so, rather
    // than writing a profile with a negative or infinite rate.
    let probes = text("../microbenchmark-probes-h100.tsv");
    let csv = text("../ncu-microbenchmarks-h100.csv.gz");
    let Err(e) = calibrate(&[&probes], &[&csv]) else { panic!("the H100's probes calibrated") };
    assert!(e.contains("own cost comes out -") && e.contains("not a line through the two probes"), "{e}");
}

/// `csv` (Nsight's CSV) with metric `metric` multiplied by `by` in the rows of the
/// kernels whose names start with `kernel`.
fn scaled(csv: &str, kernel: &str, metric: &str, by: f64) -> String {
    let (mut name, mut col) = (0, None);
    let lines = csv.lines().map(|line| {
        let mut fields: Vec<String> = line.trim_matches('"').split("\",\"").map(str::to_string).collect();
        if fields.first().map(String::as_str) == Some("ID") {
            name = fields.iter().position(|f| f == "Kernel Name").unwrap();
            col = fields.iter().position(|f| f == metric);
        } else if let Some(c) = col.filter(|_| fields.get(name).is_some_and(|k| k.starts_with(kernel))) {
            let v: f64 = fields[c].replace(',', "").parse().unwrap();
            fields[c] = format!("{:.0}", v * by);
        } else {
            return line.to_string();
        }
        format!("\"{}\"", fields.join("\",\""))
    });
    lines.collect::<Vec<_>>().join("\n")
}

#[test]
fn the_chases_misses_are_the_hbm_sectors_they_read_not_the_lines_written_back() {
    // Caches are flushed before each profiled kernel, so a chase's first pass misses,
    // and the calibration charges as many hops HBM's latency as the chase read sectors
    // from HBM. Nsight also counts, in the same launch, lines other kernels left dirty
    // being written back: counted as misses too, they took the L2 latency from 141.9 to
    // 119.7 ns and the atomic latency from 196.4 to 177.5 ns. Here the writes grow
    // twentyfold and the calibration must not move; the reads grow and it must.
    let (probes, csvs) = calibration_runs();
    let profile = |a: &str, b: &str| {
        calibrate(&[&probes[0], &probes[1], &probes[2], &probes[3]], &[a, b, &csvs[2], &csvs[3]]).unwrap().profile
    };
    let base = profile(&csvs[0], &csvs[1]);
    let [w0, w1] = [0, 1].map(|i| scaled(&csvs[i], "chase_", "dram__bytes_write.sum", 20.0));
    let written = profile(&w0, &w1);
    assert_eq!(written.l2_latency_s, base.l2_latency_s);
    assert_eq!(written.atomic_latency_s, base.atomic_latency_s);
    let [r0, r1] = [0, 1].map(|i| scaled(&csvs[i], "chase_", "dram__bytes_read.sum", 20.0));
    let read = profile(&r0, &r1);
    assert!(read.l2_latency_s < 0.9 * base.l2_latency_s, "{:e} {:e}", read.l2_latency_s, base.l2_latency_s);
    assert!(read.atomic_latency_s < 0.95 * base.atomic_latency_s);
}

#[test]
fn predicted_kernel_times_meet_the_documented_bars_on_the_h200() {
    let runs = runs();
    let p = GpuProfile::named("h200").unwrap();
    let (rows, _) = check(&runs, &p);
    // Every PDACRT kernel of the three models and CIS's shading (sorted, unsorted) and
    // compaction were matched, launch for launch.
    assert!(rows.len() >= 3 * 12 + 3, "{} rows", rows.len());
    for r in &rows {
        assert_eq!(r.launches.0, r.launches.1, "{}: launches differ", r.name);
    }
    meets_bars(&runs, &p).unwrap();
    // The decision the model is for: sorted CIS shading beats unsorted on the GPU, and
    // the predicted ratio is within 15 % of the measured one.
    let time = |name: &str| -> (f64, f64) {
        let r = rows.iter().find(|r| r.name == name).unwrap();
        (r.predicted, r.measured)
    };
    let (ps, ms) = time("cis::shade_sorted");
    let (pu, mu) = time("cis::shade_unsorted");
    assert!(ps < pu && ms < mu);
    assert!(((ps / pu) / (ms / mu) - 1.0).abs() <= 0.15);
}

/// The GPU BVH's build and trace (`cast::Lbvh` against `cuda/bvh.cu`): each model's
/// run, and PDACRT's every-kernel time measured beside it in the same call.
fn bvh_runs() -> Vec<(CheckedRun, f64)> {
    let sum = |name: &str| -> f64 { parse_csv(&text(name)).unwrap().iter().map(|k| k.seconds).sum() };
    MODELS
        .iter()
        .map(|m| {
            let run = CheckedRun {
                records: simt::records_from_tsv(&text(&format!("simt-records-bvh-{m}-1024-primary-shadow.tsv.gz")))
                    .unwrap(),
                kernels: parse_csv(&text(&format!("ncu-bvh-{m}-1024-primary-shadow.csv.gz"))).unwrap(),
                every: Some(sum(&format!("ncu-time-every-kernel-bvh-{m}-1024-primary-shadow.csv.gz"))),
            };
            (run, sum(&format!("ncu-time-every-kernel-pdacrt-{m}-1024-primary-shadow-beside-bvh.csv.gz")))
        })
        .collect()
}

#[test]
fn the_pdacrt_traces_are_predicted_within_15_percent_look_back_and_all() {
    // Whole traces, every launch (CUB's scans and selections too) against ncu's total:
    // −12.6 %, −9.9 % and −4.7 % (docs/simt.md), held to the issue's 15 %. Their
    // single-pass scans wait on the look-back's hops across the tiles; records read as
    // if their launches ran out of order (no look-back term) miss by −23 %, −17 % and
    // −18 %.
    let p = GpuProfile::named("h200").unwrap();
    let pdacrt = &runs()[..MODELS.len()];
    let (_, pipelines) = check(pdacrt, &p);
    for (m, e) in MODELS.iter().zip(&pipelines) {
        assert!(e.abs() <= 0.15, "{m}: the trace predicted {:+.2} %", e * 100.0);
    }
    let unordered: Vec<CheckedRun> = pdacrt
        .iter()
        .map(|r| CheckedRun {
            records: r.records.iter().map(|l| LaunchRecord { in_order: false, ..l.clone() }).collect(),
            kernels: r.kernels.clone(),
            every: r.every,
        })
        .collect();
    let (_, without) = check(&unordered, &p);
    assert!(without.iter().any(|e| e.abs() > 0.15), "no look-back term: {without:?}");
}

#[test]
fn the_emulated_primitives_launch_what_cub_launches_in_every_pipeline() {
    // Scans, selections, the reduction and the sort: as many launches of the emulated
    // kernels as of CUB's (the primitives' table of `gpu_check time`), in the PDACRT
    // traces, CIS's compaction and the BVH's builds. Three-launch scans, or a flags-
    // scan-scatter selection, fail this.
    let p = GpuProfile::named("h200").unwrap();
    let every = |name: &str| parse_csv(&text(name)).unwrap();
    let mut files: Vec<(String, String)> = MODELS
        .iter()
        .flat_map(|m| {
            [
                (
                    format!("simt-records-pdacrt-{m}-1024-primary-shadow.tsv.gz"),
                    format!("ncu-time-every-kernel-pdacrt-{m}-1024-primary-shadow.csv.gz"),
                ),
                (
                    format!("simt-records-bvh-{m}-1024-primary-shadow.tsv.gz"),
                    format!("ncu-time-every-kernel-bvh-{m}-1024-primary-shadow.csv.gz"),
                ),
            ]
        })
        .collect();
    files.push((
        "simt-records-cis-shading-compaction-3-scenes-128.tsv.gz".into(),
        "ncu-time-every-kernel-cis-3-scenes-128.csv.gz".into(),
    ));
    for (records, ncu) in files {
        let rows = primitive_times(&simt::records_from_tsv(&text(&records)).unwrap(), &every(&ncu), &p);
        assert!(!rows.is_empty(), "{records}: no primitives");
        for r in rows {
            assert_eq!(r.launches.0, r.launches.1, "{records}: {}", r.what);
        }
    }
}

#[test]
fn the_predicted_ratio_of_pdacrt_to_the_gpu_bvh_has_the_measured_sign_and_the_documented_error() {
    // The decision the model is for here: PDACRT's trace against a BVH rebuilt and
    // traced for each batch. Every BVH kernel is matched launch for launch; the
    // predicted ratio of the two pipelines must say which is faster, as the H200 does,
    // and by as much within 15 % (the issue's bar): −1 %, −8 % and +13 % (bunny,
    // conference room, dragon; docs/simt.md). Records without the blocks' slowest
    // warps (the mean warp's chain in each wave) give the dragon +16 %; the BVH records
    // of a meter without rounds fail (6.93 against 10.71 before the bounds' overlap).
    let p = GpuProfile::named("h200").unwrap();
    let pdacrt = runs();
    for (k, (bvh, pdacrt_measured)) in bvh_runs().into_iter().enumerate() {
        let (rows, _) = check(std::slice::from_ref(&bvh), &p);
        assert_eq!(rows.len(), 5, "{}: the five bvh:: kernels", MODELS[k]);
        for r in &rows {
            assert_eq!(r.launches.0, r.launches.1, "{}: launches differ", r.name);
        }
        let predicted = predicted_total(&pdacrt[k].records, &p) / predicted_total(&bvh.records, &p);
        let measured = pdacrt_measured / bvh.every.unwrap();
        assert!(predicted > 1.0 && measured > 1.0, "{}: {predicted:.2} against {measured:.2}", MODELS[k]);
        assert!((predicted / measured - 1.0).abs() <= 0.15, "{}: {predicted:.2} against {measured:.2}", MODELS[k]);
    }
}

#[test]
fn the_gpu_bvh_build_and_trace_are_predicted_within_15_percent_with_the_bounds_overlap() {
    // Whole pipelines, every launch (CUB's sort, reduction and scans too) against ncu's
    // total: −10.6 %, −1.0 % and −14.9 % (docs/simt.md). The dragon's sort passes run one
    // block a SM whose barriers hold its warps in one phase: with the bounds taken as
    // their largest alone (a profile whose overlap shares are 0) the dragon's pipeline
    // is −17.0 %, past the issue's 15 %.
    let p = GpuProfile::named("h200").unwrap();
    let roofline = GpuProfile { exposed_free: 0.0, exposed_one_block: 0.0, exposed_many_blocks: 0.0, ..p.clone() };
    for (k, (bvh, _)) in bvh_runs().into_iter().enumerate() {
        let error = |q: &GpuProfile| predicted_total(&bvh.records, q) / bvh.every.unwrap() - 1.0;
        assert!(error(&p).abs() <= 0.15, "{}: {:+.1} %", MODELS[k], error(&p) * 100.0);
        if MODELS[k] == "dragon" {
            assert!(error(&roofline) < -0.15, "{}: {:+.1} %", MODELS[k], error(&roofline) * 100.0);
        }
    }
}

#[test]
fn the_gpu_bvh_traversal_is_predicted_within_20_percent_with_its_loads_in_rounds() {
    // The traversal's loads are issued a node (or a leaf) at a time and waited for
    // together (docs/simt.md, "Loads issued together"); the chain counts rounds. The
    // records of a meter without rounds (commit a717941's) fail this: +109 to +183 %.
    let p = GpuProfile::named("h200").unwrap();
    for (k, (bvh, _)) in bvh_runs().into_iter().enumerate() {
        let (rows, _) = check(std::slice::from_ref(&bvh), &p);
        let trace = rows.iter().find(|r| r.name == "bvh::trace").unwrap();
        let e = trace.predicted / trace.measured - 1.0;
        assert!(e.abs() <= 0.20, "{}: bvh::trace predicted {:+.0} %", MODELS[k], e * 100.0);
    }
}

#[test]
fn planted_errors_in_the_terms_that_bind_are_caught_by_the_check() {
    let runs = runs();
    let p = GpuProfile::named("h200").unwrap();
    // Each way for the HBM latency and the launch cost: an error that lengthens the
    // kernels is caught by the kernel it moves past 50 % (filter_triangles) or by the
    // mean, one that shortens them by the mean or by a trace it moves past 15 % (the
    // HBM latency × 0.8: the bunny's trace −17.0 %).
    let planted: [(&str, GpuProfile); 5] = [
        ("HBM latency x 1.25", GpuProfile { hbm_latency_s: p.hbm_latency_s * 1.25, ..p.clone() }),
        ("HBM latency x 0.8", GpuProfile { hbm_latency_s: p.hbm_latency_s * 0.8, ..p.clone() }),
        ("arithmetic latency x 2", GpuProfile { alu_latency_cycles: p.alu_latency_cycles * 2.0, ..p.clone() }),
        ("launch cost x 2", GpuProfile { launch_s: p.launch_s * 2.0, ..p.clone() }),
        ("launch cost x 0.8", GpuProfile { launch_s: p.launch_s * 0.8, ..p.clone() }),
    ];
    for (what, bad) in planted {
        assert!(meets_bars(&runs, &bad).is_err(), "a planted error ({what}) passed the check");
    }
}

/// What the check cannot see, said as a test: at these sizes, with caches flushed
/// before each kernel, the model finds the checked kernels latency-bound, so an error
/// in a bandwidth or issue rate (the issue's example, HBM bandwidth x 2) moves the
/// kernels' mean error by under half a point and is not caught; nor is the L2 latency
/// x 1.25, as the chains' waits that set these times are mostly first touches, at HBM's.
/// If this starts failing, a kernel's bound moved and the doc's sensitivity table is
/// stale.
#[test]
fn bandwidth_errors_are_invisible_to_these_latency_bound_kernels() {
    let runs = runs();
    let p = GpuProfile::named("h200").unwrap();
    let mape = |q: &GpuProfile| errors(&check(&runs, q).0).0;
    let base = mape(&p);
    for q in [
        GpuProfile { hbm_bytes_per_s: p.hbm_bytes_per_s * 2.0, ..p.clone() },
        GpuProfile { l2_bytes_per_s: p.l2_bytes_per_s * 2.0, ..p.clone() },
        GpuProfile { issue_per_cycle_per_sm: p.issue_per_cycle_per_sm * 2.0, ..p.clone() },
        GpuProfile { l2_latency_s: p.l2_latency_s * 1.25, ..p.clone() },
    ] {
        assert!((mape(&q) - base).abs() < 0.005, "{} -> {}", base, mape(&q));
    }
}

mod heavy {
    use super::text;
    use warpray::gpu::ncu::{GpuKernel, parse_launches};

    /// Load sectors per request of a kernel's launches.
    fn per_request(requests: f64, sectors: f64) -> f64 {
        sectors / requests
    }

    /// CIS shading's load sectors per request, the emulator's against the H200's, on the
    /// launches the stored Nsight run profiled first (the Cornell box at 128², one pass,
    /// sorted then unsorted, 9 bounces each): the emulator's render is run here, so the
    /// scene reads it records (`Scene`, `Lights` and the BSDFs through `cost::read!`
    /// and `reads`) are today's. Goal (docs/gpu-check.md): within 15 %.
    #[test]
    #[ignore = "heavy tier, run by CI: cargo test --profile suite --workspace --features inspector,cuda,embree --test suite -- --ignored ::heavy::"]
    fn cis_shading_load_sectors_per_request_are_within_15_percent_of_the_h200s() {
        let launches = parse_launches(&text("ncu-cis-shading-compaction-3-scenes-128.csv.gz")).unwrap();
        let scene = warpray::scene::cornell_box();
        let caster = warpray::cast::BvhCaster::new(&scene);
        for sorted in [true, false] {
            let name = if sorted { "shade_sorted" } else { "shade_unsorted" };
            let mine = super::cis_pass_128(&scene, &caster, sorted, true, "cis::shade");
            let theirs: Vec<&GpuKernel> = launches.iter().filter(|k| k.name.ends_with(name)).take(mine.len()).collect();
            assert_eq!(mine.len(), 9, "bounces of the emulated pass");
            assert_eq!(theirs.len(), mine.len(), "{name}: launches in the stored Nsight run");
            let simt = per_request(
                mine.iter().map(|l| l.loads.requests as f64).sum(),
                mine.iter().map(|l| l.loads.sectors as f64).sum(),
            );
            let h200 = per_request(
                theirs.iter().map(|k| k.loads.requests as f64).sum(),
                theirs.iter().map(|k| k.loads.sectors as f64).sum(),
            );
            let error = simt / h200 - 1.0;
            eprintln!("{name}: {simt:.2} sectors per load request, the H200 {h200:.2} ({:+.1} %)", error * 100.0);
            assert!(error.abs() <= 0.15, "{name}: {simt:.2} against {h200:.2} sectors per request");
        }
    }

    /// The GPU BVH's emulated build and trace against the H200's counters of the same
    /// launches (bunny, 1024², primary and shadow rays, a build for each): SIMD
    /// efficiency and load sectors per request of every kernel within 5 % (the fit's
    /// climb only since it runs a level at a time, as the GPU's lanes and warps do).
    #[test]
    #[ignore = "heavy tier, run by CI: cargo test --profile suite --workspace --features inspector,cuda,embree --test suite -- --ignored ::heavy::"]
    fn the_gpu_bvh_twins_counters_are_within_5_percent_of_the_h200s() {
        use warpray::cast::RayCaster;
        let path = crate::common::require_model("bunny");
        let scene = warpray::scene::load_obj(&path, &Default::default()).unwrap();
        let b = warpray::cast::batches::batches(&scene, 1024, 1024, 8, 1);
        let dev = simt::Device::default();
        dev.set_measure(true);
        for (rays, shadow) in [(&b.primary, false), (&b.shadow, true)] {
            let bvh = warpray::cast::Lbvh::on_device(&scene.triangle_vertices(), dev.clone());
            if shadow {
                bvh.occluded(rays, &mut vec![false; rays.len()]);
            } else {
                bvh.closest(rays, &mut vec![warpray::geometry::Hit::MISS; rays.len()]);
            }
        }
        let gpu = warpray::gpu::ncu::parse_csv(&text("ncu-bvh-bunny-1024-primary-shadow.csv.gz")).unwrap();
        for k in ["morton_codes", "gather_triangles", "emit_hierarchy", "fit_boxes", "trace"] {
            let mine = dev.kernel_stats().into_iter().find(|s| s.name == format!("bvh::{k}")).unwrap();
            let theirs = gpu.iter().find(|g| g.name.ends_with(k)).unwrap();
            let simd = mine.simd_efficiency().unwrap() / theirs.simd_efficiency().unwrap() - 1.0;
            let sectors = mine.loads.sectors_per_request().unwrap() / theirs.loads.sectors_per_request().unwrap() - 1.0;
            eprintln!(
                "bvh::{k}: SIMD efficiency {:+.1} %, load sectors per request {:+.1} %",
                simd * 100.0,
                sectors * 100.0
            );
            assert!(simd.abs() <= 0.05 && sectors.abs() <= 0.05, "bvh::{k}: {simd:+.3}, {sectors:+.3}");
        }
    }
}

/// `gpu_check time --terms`: each kernel's row holds its measured time, its prediction
/// and the terms it came from, summed over its launches; the prediction less the launch
/// costs is the sum of each launch's largest bound, so it lies between the largest
/// summed bound and the sum of them all.
#[test]
fn the_terms_table_shows_what_each_prediction_is_made_of() {
    let runs = runs();
    let p = GpuProfile::named("h200").unwrap();
    let (rows, _) = check(&runs, &p);
    let table = warpray::gpu::time_check::terms_table(&rows);
    for r in &rows {
        let t = &r.terms;
        let bounds = [t.latency, t.issue, t.fetch, t.l1, t.l2, t.hbm, t.atomics, t.fences, t.barriers, t.dispatch];
        let largest = bounds.iter().cloned().fold(0.0, f64::max);
        // Each launch adds its own largest bound: the sum lies between the largest summed
        // bound and the sum of all of them.
        let over = r.predicted - t.launch;
        assert!(over >= largest * (1.0 - 1e-9) && over <= bounds.iter().sum::<f64>() * (1.0 + 1e-9), "{}", r.name);
        let row =
            format!("| {} | {:.1} | {:.1} | {:.1} |", r.name, r.measured * 1e6, r.predicted * 1e6, t.latency * 1e6);
        assert!(table.contains(&row), "{row} not in the table");
    }
}

/// `gpu_check time --launches-of`: one row per launch, in order, whose predictions sum to
/// the kernel's row; a kernel launched a different number of times in the two files has
/// no table.
#[test]
fn the_launch_table_adds_up_to_the_kernels_row() {
    let p = GpuProfile::named("h200").unwrap();
    let records = simt::records_from_tsv(&text("simt-records-pdacrt-bunny-1024-primary-shadow.tsv.gz")).unwrap();
    let csv = text("ncu-pdacrt-bunny-1024-primary-shadow.csv.gz");
    let launches = warpray::gpu::ncu::parse_launches(&csv).unwrap();
    let rows = warpray::gpu::time_check::kernel_times(&records, &parse_csv(&csv).unwrap(), &p);
    let row = rows.iter().find(|r| r.name.ends_with("filter_rays")).unwrap();
    let table = warpray::gpu::time_check::launch_table(&records, &launches, &p, "pdacrt::filter_rays").unwrap();
    let cells: Vec<Vec<&str>> =
        table.lines().skip(2).map(|l| l.split('|').map(str::trim).filter(|c| !c.is_empty()).collect()).collect();
    assert_eq!(cells.len() as u64, row.launches.1);
    let predicted: f64 = cells.iter().map(|c| c[2].parse::<f64>().unwrap()).sum();
    assert!(
        (predicted - row.predicted * 1e6).abs() <= 0.05 * cells.len() as f64,
        "{predicted} against {}",
        row.predicted * 1e6
    );
    assert!(cells.iter().enumerate().all(|(i, c)| c[0] == i.to_string()));
    let first = launches.iter().position(|l| l.name.contains("filter_rays")).unwrap();
    let fewer: Vec<_> = launches.iter().enumerate().filter(|&(i, _)| i != first).map(|(_, l)| l.clone()).collect();
    assert!(warpray::gpu::time_check::launch_table(&records, &fewer, &p, "pdacrt::filter_rays").is_none());
}

/// A library primitive's kernel launch by launch: set beside the CUB kernels the twin
/// launches in its place (the sort's passes against `DeviceRadixSortOnesweepKernel`, its
/// histogram against `DeviceRadixSortHistogramKernel` alone, not the exclusive sum's).
#[test]
fn the_launch_table_sets_a_primitives_kernel_beside_cubs() {
    let p = GpuProfile::named("h200").unwrap();
    let records = simt::records_from_tsv(&text("simt-records-bvh-bunny-1024-primary-shadow.tsv.gz")).unwrap();
    let every =
        warpray::gpu::ncu::parse_launches(&text("ncu-time-every-kernel-bvh-bunny-1024-primary-shadow.csv.gz")).unwrap();
    let rows = |kernel: &str| {
        let table = warpray::gpu::time_check::launch_table(&records, &every, &p, kernel).unwrap();
        table.lines().skip(2).map(|l| l.split('|').nth(4).unwrap().trim().parse::<f64>().unwrap()).collect::<Vec<f64>>()
    };
    let measured =
        |cub: &str| every.iter().filter(|g| g.name.ends_with(cub)).map(|g| g.seconds * 1e6).collect::<Vec<f64>>();
    for (ours, cub) in [
        ("simt::radix_onesweep", "DeviceRadixSortOnesweepKernel"),
        ("simt::radix_histogram", "DeviceRadixSortHistogramKernel"),
        ("simt::radix_exclusive_sum", "DeviceRadixSortExclusiveSumKernel"),
    ] {
        let (table, gpu) = (rows(ours), measured(cub));
        assert!(!gpu.is_empty(), "{cub}");
        assert_eq!(table.len(), gpu.len(), "{ours}");
        assert!(table.iter().zip(&gpu).all(|(t, g)| (t - g).abs() <= 0.05), "{ours}: {table:?} against {gpu:?}");
    }
}

#[test]
fn the_emulated_onesweep_pass_issues_what_cubs_issues_a_warp() {
    // CUB's onesweep kernel for 4-byte keys is unrolled, so every warp of a pass runs
    // the same instructions whatever its keys: 1,558 a warp in the bunny's first pass
    // (11 tiles of 384 threads, 132 warps, on an H100; sm_90 code, as the H200's).
    // The emulated pass counts its own operations and declares the ranking's
    // arithmetic per key; without the declaration it issues 704 a warp.
    let export = concat!(env!("CARGO_MANIFEST_DIR"), "/docs/measured/ncu-executed-sass-cub-onesweep-bunny-h100.csv.gz");
    let cub = warpray::gpu::source::executed_warp_instructions(&text(export)).unwrap() / 132.0;
    assert!((cub - 1557.6).abs() < 0.1, "{cub}");
    let dev = simt::Device::new(simt::DeviceConfig { measure: true, ..Default::default() });
    dev.set_gpu_profile(Some(GpuProfile::named("h200").unwrap()));
    let n = 11 * 6528 - 2000;
    let mut rng = crate::common::rng(11);
    let keys: Vec<u32> = (0..n).map(|_| rng.next_u64() as u32).collect();
    let (mut k, mut v) = (dev.alloc_from(&keys), dev.alloc_from(&(0..n as u32).collect::<Vec<_>>()));
    simt::sort_by_key(&dev, &mut k, &mut v);
    assert!(k.as_slice().windows(2).all(|w| w[0] <= w[1]));
    let passes: Vec<LaunchRecord> = dev.launch_log().into_iter().filter(|r| r.name == "simt::radix_onesweep").collect();
    assert_eq!(passes.len(), 4);
    for r in &passes {
        assert_eq!(r.grid, 11);
        let per_warp = r.all_regions().issued as f64 / (11.0 * 12.0);
        assert!((per_warp / cub - 1.0).abs() < 0.03, "{per_warp:.0} warp instructions a warp against CUB's {cub:.0}");
    }
}

/// CIS-LBDPT's camera pass casts the shadow rays of its active samples' waiting
/// connections, as the GPU twin does (`pending_waiting_flags` over the active list): the
/// emulated pass's `cis::scatter_blocked` threads against the twin's `pending_shadow`
/// threads in Nsight's counters of the whole renders at 128² (`cuda/render_counts.sh`,
/// an H100; a warm-up and a timed pass, halved), within what rounding each launch up to
/// whole blocks allows (256 threads a launch here, 128 there) and 1 % for the passes'
/// own draws. Read over the whole pool, as the pass first did, samples that had left the
/// list cast their last bounce's connections again every bounce: 228,352 threads in
/// the Cornell box and 278,272 in the bedroom.
#[test]
fn the_emulated_cis_pass_casts_the_shadow_rays_its_gpu_twin_casts() {
    let csv = text("../ncu-gpu-render-kernels-3-scenes-128-512-h100.csv.gz");
    let mut lines = csv.lines();
    let header = warpray::gpu::ncu::split_csv(lines.next().unwrap());
    let col = |name: &str| header.iter().position(|h| h == name).unwrap();
    let (scene_col, size_col, kernel_col, grid_col, block_col) =
        (col("scene"), col("size"), col("Kernel Name"), col("launch__grid_size"), col("launch__block_size"));
    let rows: Vec<Vec<String>> = lines.map(warpray::gpu::ncu::split_csv).collect();
    for name in ["cornell", "bedroom"] {
        let gpu: f64 = rows
            .iter()
            .filter(|r| r[scene_col] == name && r[size_col] == "128" && r[kernel_col].contains("pending_shadow"))
            .map(|r| r[grid_col].parse::<f64>().unwrap() * r[block_col].parse::<f64>().unwrap())
            .sum::<f64>()
            / 2.0;
        let scene = if name == "cornell" {
            warpray::scene::cornell_box()
        } else {
            let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("assets/scenes/bedroom.toml");
            warpray::scene::load_scene(&path).unwrap().scene
        };
        let caster = warpray::cast::BvhCaster::new(&scene);
        let log = cis_pass_128(&scene, &caster, true, false, "cis::scatter_blocked");
        let mine: f64 = log.iter().map(|l| l.threads as f64).sum();
        let allowed = 256.0 * log.len() as f64 + 0.01 * gpu;
        eprintln!("{name}: {mine} shadow-ray threads a pass, the GPU twin {gpu}");
        assert!((mine - gpu).abs() <= allowed, "{name}: {mine} against the twin's {gpu} (allowed {allowed})");
    }
}

/// The launches named `kernel` of one CIS-LBDPT pass at 128² (max depth 8, the default
/// pool, which holds every pixel), sorted by material or not, measured or not.
fn cis_pass_128(
    scene: &warpray::scene::Scene,
    caster: &warpray::cast::BvhCaster,
    sorted: bool,
    measure: bool,
    kernel: &str,
) -> Vec<LaunchRecord> {
    let mut opts = warpray::render::RenderOptions {
        width: 128,
        height: 128,
        budget: warpray::render::Budget::Samples(1),
        integrator: warpray::render::IntegratorKind::Cis,
        max_depth: 8,
        ..Default::default()
    };
    (opts.cis.sort, opts.cis.measure) = (sorted, measure);
    let mut r = warpray::render::Renderer::new(scene, caster, &opts).unwrap();
    let mut film = r.film().unwrap();
    r.passes(0, 1, &mut film);
    r.device().unwrap().launch_log().into_iter().filter(|l| l.name == kernel).collect()
}
