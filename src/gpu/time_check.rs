//! `simt`'s predicted GPU time set beside Nsight Compute's, kernel by kernel and for
//! whole pipelines (`docs/simt.md`, "Predicted GPU time"; `gpu_check time`).

use super::ncu::{GpuKernel, base_name};
use simt::timing::{Prediction, predict};
use simt::{GpuProfile, LaunchRecord};
use std::fmt::Write;

/// One kernel: its launches predicted on a profile and measured on the GPU.
#[derive(Clone, Debug)]
pub struct KernelTime {
    /// The kernel's name.
    pub name: String,
    /// Launches the emulator recorded / the GPU profiled.
    pub launches: (u64, u64),
    /// Predicted seconds, summed over launches.
    pub predicted: f64,
    /// Measured seconds (`gpu__time_duration.sum`), summed.
    pub measured: f64,
    /// The predicted terms summed over launches (each launch's bounds, not only the
    /// largest), to say what the model thinks limits the kernel.
    pub terms: Prediction,
    /// Predicted HBM bytes (footprint) and measured `dram__bytes_read + write`.
    pub hbm_bytes: (f64, f64),
}

impl KernelTime {
    /// (predicted − measured) / measured.
    pub fn error(&self) -> f64 {
        (self.predicted - self.measured) / self.measured
    }
}

/// The predicted time of every launch in `records`, summed (unmeasured launches
/// count nothing).
pub fn predicted_total(records: &[LaunchRecord], p: &GpuProfile) -> f64 {
    records.iter().filter_map(|r| predict(r, p)).map(|t| t.seconds).sum()
}

/// A record with the registers per thread the GPU's run of its kernel used, where the
/// emulated launch did not declare them (the emulator cannot know them).
fn with_registers(r: &LaunchRecord, registers: u64) -> LaunchRecord {
    let mut r = r.clone();
    if r.registers == 0 {
        r.registers = registers.min(u32::MAX as u64) as u32;
    }
    r
}

/// Every kernel in `gpu` that the records also have (matched by the name without its
/// namespace), in the GPU's order, each predicted with the registers the GPU's run of
/// it used (`launch__registers_per_thread`).
pub fn kernel_times(records: &[LaunchRecord], gpu: &[GpuKernel], p: &GpuProfile) -> Vec<KernelTime> {
    gpu.iter()
        .filter_map(|g| {
            let mine: Vec<LaunchRecord> = records
                .iter()
                .filter(|r| base_name(r.name) == base_name(&g.name))
                .map(|r| with_registers(r, g.registers))
                .collect();
            if mine.is_empty() || g.seconds <= 0.0 {
                return None;
            }
            let mut terms = Prediction::default();
            let mut footprint = 0.0;
            for r in &mine {
                if let Some(t) = predict(r, p) {
                    terms.add(&t);
                }
                footprint += r.footprint_sectors as f64 * simt::SECTOR_BYTES as f64;
            }
            Some(KernelTime {
                name: mine[0].name.to_string(),
                launches: (mine.len() as u64, g.launches),
                predicted: terms.seconds,
                measured: g.seconds,
                terms,
                hbm_bytes: (footprint, g.dram_bytes()),
            })
        })
        .collect()
}

/// Mean absolute relative error over kernels, and the worst kernel.
pub fn errors(rows: &[KernelTime]) -> (f64, Option<&KernelTime>) {
    let mape = rows.iter().map(|r| r.error().abs()).sum::<f64>() / rows.len().max(1) as f64;
    let worst = rows.iter().max_by(|a, b| a.error().abs().total_cmp(&b.error().abs()));
    (mape, worst)
}

/// The comparison as a markdown table, with the mean and worst errors under it.
pub fn table(rows: &[KernelTime]) -> String {
    let mut s = String::from(
        "| kernel | launches (simt / GPU) | predicted ms | measured ms | Δ | bound | HBM MB predicted | measured |\n|---|---:|---:|---:|---:|---|---:|---:|\n",
    );
    for r in rows {
        let _ = writeln!(
            s,
            "| {} | {} / {} | {:.3} | {:.3} | {:+.0} % | {} | {:.1} | {:.1} |",
            r.name,
            r.launches.0,
            r.launches.1,
            r.predicted * 1e3,
            r.measured * 1e3,
            r.error() * 100.0,
            r.terms.bound(),
            r.hbm_bytes.0 / 1e6,
            r.hbm_bytes.1 / 1e6
        );
    }
    let (mape, worst) = errors(rows);
    if let Some(w) = worst {
        let _ = writeln!(
            s,
            "\nMean absolute error {:.1} % over {} kernels; worst {} ({:+.0} %).",
            mape * 100.0,
            rows.len(),
            w.name,
            w.error() * 100.0
        );
    }
    s
}

/// The library primitives: `simt`'s kernels of each against the CUB kernels the twins
/// launch for it (matched by the name without its namespace).
const PRIMITIVES: [(&str, &[&str], &[&str]); 6] = [
    ("scan status init", &["scan_init"], &["DeviceScanInitKernel"]),
    ("scan tiles", &["scan_tiles"], &["DeviceScanKernel"]),
    ("selection", &["select_init", "select_sweep"], &["DeviceCompactInitKernel", "DeviceSelectSweepKernel"]),
    ("reduction", &["reduce_tiles"], &["DeviceReduceKernel", "DeviceReduceSingleTileKernel"]),
    (
        "sort histogram and exclusive sum",
        &["radix_histogram", "radix_exclusive_sum"],
        &["DeviceRadixSortHistogramKernel", "DeviceRadixSortExclusiveSumKernel"],
    ),
    ("sort passes", &["radix_onesweep"], &["DeviceRadixSortOnesweepKernel"]),
];

/// One library primitive of a pipeline: its emulated kernels predicted, CUB's measured.
#[derive(Clone, Debug)]
pub struct PrimitiveTime {
    /// What it is (`scan tiles`, `selection`, …).
    pub what: &'static str,
    /// Launches of the emulated kernels / of CUB's.
    pub launches: (u64, u64),
    /// Predicted seconds, summed over the emulated launches.
    pub predicted: f64,
    /// Measured seconds (`gpu__time_duration.sum`) of CUB's, summed.
    pub measured: f64,
}

/// The library primitives of a pipeline, predicted from `records` against ncu's times
/// of every kernel (`every`, CUB's too); those neither side launched are left out.
pub fn primitive_times(records: &[LaunchRecord], every: &[GpuKernel], p: &GpuProfile) -> Vec<PrimitiveTime> {
    PRIMITIVES
        .iter()
        .filter_map(|&(what, ours, cubs)| {
            let mine: Vec<&LaunchRecord> = records.iter().filter(|r| ours.contains(&base_name(r.name))).collect();
            let gpu: Vec<&GpuKernel> = every.iter().filter(|g| cubs.contains(&base_name(&g.name))).collect();
            (!mine.is_empty() || !gpu.is_empty()).then(|| PrimitiveTime {
                what,
                launches: (mine.len() as u64, gpu.iter().map(|g| g.launches).sum()),
                predicted: mine.iter().filter_map(|r| predict(r, p)).map(|t| t.seconds).sum(),
                measured: gpu.iter().map(|g| g.seconds).sum(),
            })
        })
        .collect()
}

/// [`primitive_times`] as a markdown table (empty for no rows).
pub fn primitives_table(rows: &[PrimitiveTime]) -> String {
    if rows.is_empty() {
        return String::new();
    }
    let mut s = String::from(
        "| primitive | launches (simt / GPU) | predicted ms | measured ms | Δ |\n|---|---:|---:|---:|---:|\n",
    );
    for r in rows {
        let error = if r.measured > 0.0 {
            format!("{:+.0} %", (r.predicted - r.measured) / r.measured * 100.0)
        } else {
            "-".into()
        };
        let _ = writeln!(
            s,
            "| {} | {} / {} | {:.3} | {:.3} | {error} |",
            r.what,
            r.launches.0,
            r.launches.1,
            r.predicted * 1e3,
            r.measured * 1e3
        );
    }
    s
}

/// Each kernel's model terms (summed over its launches, µs) beside its measured time:
/// which bound sets the prediction, how far the others are below it, and what the
/// bounds' overlap added (`exposed`).
pub fn terms_table(rows: &[KernelTime]) -> String {
    let mut s = String::from(
        "| kernel | measured µs | predicted | latency | issue | fetch | L1 | L2 | HBM | atomics | fences | barriers | dispatch | exposed | launch |\n|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|\n",
    );
    for r in rows {
        let t = &r.terms;
        let _ = write!(s, "| {} | {:.1} | {:.1} |", r.name, r.measured * 1e6, r.predicted * 1e6);
        for v in [
            t.latency, t.issue, t.fetch, t.l1, t.l2, t.hbm, t.atomics, t.fences, t.barriers, t.dispatch, t.exposed,
            t.launch,
        ] {
            let _ = write!(s, " {:.1} |", v * 1e6);
        }
        s.push('\n');
    }
    s
}

/// The GPU kernels an emulated kernel stands for: itself, or for one of a library
/// primitive's kernels the CUB kernels the twins launch in its place (paired in order
/// where the primitive has as many of each, else all of CUB's).
fn gpu_names_of(kernel: &str) -> Vec<&str> {
    let kernel = base_name(kernel);
    for (_, ours, cubs) in PRIMITIVES {
        if let Some(i) = ours.iter().position(|&o| o == kernel) {
            return if ours.len() == cubs.len() { vec![cubs[i]] } else { cubs.to_vec() };
        }
    }
    vec![kernel]
}

/// One kernel launch by launch: the records of `kernel` (matched by the name without
/// its namespace) beside the GPU's launches of it (or, for a library primitive's
/// kernel, of CUB's in its place), in launch order, each predicted with the GPU
/// launch's registers; `None` when the counts differ.
pub fn launch_table(records: &[LaunchRecord], gpu: &[GpuKernel], p: &GpuProfile, kernel: &str) -> Option<String> {
    let mine: Vec<&LaunchRecord> = records.iter().filter(|r| base_name(r.name) == base_name(kernel)).collect();
    let names = gpu_names_of(kernel);
    let theirs: Vec<&GpuKernel> = gpu.iter().filter(|g| names.contains(&base_name(&g.name))).collect();
    if mine.is_empty() || mine.len() != theirs.len() {
        return None;
    }
    let mut s = String::from(
        "| launch | grid | predicted µs | measured µs | Δ | bound | latency | L1 | L2 | HBM |\n|---:|---:|---:|---:|---:|---|---:|---:|---:|---:|\n",
    );
    for (i, (r, g)) in mine.iter().zip(&theirs).enumerate() {
        let t = predict(&with_registers(r, g.registers), p)?;
        let _ = writeln!(
            s,
            "| {i} | {} | {:.1} | {:.1} | {:+.0} % | {} | {:.1} | {:.1} | {:.1} | {:.1} |",
            r.grid,
            t.seconds * 1e6,
            g.seconds * 1e6,
            (t.seconds - g.seconds) / g.seconds * 100.0,
            t.bound(),
            t.latency * 1e6,
            t.l1 * 1e6,
            t.l2 * 1e6,
            t.hbm * 1e6
        );
    }
    Some(s)
}

/// One checked run: the emulator's launch records, ncu's per-kernel counters of the same
/// launches, and (for a pipeline) ncu's total over every kernel it launched.
pub struct CheckedRun {
    /// The emulator's launch records.
    pub records: Vec<LaunchRecord>,
    /// ncu's counters of the same launches, per kernel.
    pub kernels: Vec<GpuKernel>,
    /// Measured seconds of every kernel of the pipeline (CUB's too), if profiled.
    pub every: Option<f64>,
}

/// Every kernel row of every run, and each pipeline's relative error.
pub fn check(runs: &[CheckedRun], p: &GpuProfile) -> (Vec<KernelTime>, Vec<f64>) {
    let mut rows = Vec::new();
    let mut pipelines = Vec::new();
    for r in runs {
        rows.extend(kernel_times(&r.records, &r.kernels, p));
        if let Some(measured) = r.every {
            pipelines.push((predicted_total(&r.records, p) - measured) / measured);
        }
    }
    (rows, pipelines)
}

/// How the check moves when one profile value alone is wrong: for each value scaled by
/// 0.5, 0.95, 1.05 and 2, the kernels' mean absolute error and the pipelines' errors,
/// as a markdown table (`docs/simt.md`, "What the check can see").
pub fn sensitivity(runs: &[CheckedRun], p: &GpuProfile) -> String {
    type Scale = fn(&mut GpuProfile, f64);
    // The overlap shares are capped at 1 (none of the smaller bound hidden).
    let values: [(&str, Scale); 10] = [
        ("HBM latency", |q, k| q.hbm_latency_s *= k),
        ("L2 latency", |q, k| q.l2_latency_s *= k),
        ("arithmetic latency", |q, k| q.alu_latency_cycles *= k),
        ("launch cost", |q, k| q.launch_s *= k),
        ("HBM bandwidth", |q, k| q.hbm_bytes_per_s *= k),
        ("L2 bandwidth", |q, k| q.l2_bytes_per_s *= k),
        ("scattered L2 bandwidth", |q, k| q.l2_scattered_bytes_per_s *= k),
        ("issue rate", |q, k| q.issue_per_cycle_per_sm *= k),
        ("overlap share, free-running", |q, k| q.exposed_free = (q.exposed_free * k).min(1.0)),
        ("overlap shares, phased", |q, k| {
            q.exposed_one_block = (q.exposed_one_block * k).min(1.0);
            q.exposed_many_blocks = (q.exposed_many_blocks * k).min(1.0);
        }),
    ];
    let scales = [0.5, 0.95, 1.05, 2.0];
    let mut s = String::from("| planted | × 0.5 | × 0.95 | × 1.05 | × 2 |\n|---|---|---|---|---|\n");
    for (name, scale) in values {
        let _ = write!(s, "| {name} |");
        for k in scales {
            let mut q = p.clone();
            scale(&mut q, k);
            let (rows, pipes) = check(runs, &q);
            let pipes: Vec<String> = pipes.iter().map(|e| format!("{:+.0}", e * 100.0)).collect();
            let _ = write!(s, " {:.1} %; {} % |", errors(&rows).0 * 100.0, pipes.join("/"));
        }
        s.push('\n');
    }
    s
}
