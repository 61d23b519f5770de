//! Nsight Compute's per-kernel counters, read from its CSV, and set beside what `simt`
//! predicts for the kernel of the same name.
//!
//! Collect with (the program traces the same rays as the `simt` run):
//!
//! ```text
//! ncu --csv --page raw --print-units base --metrics <METRICS> --log-file ncu.csv PROGRAM ...
//! ```
//!
//! The counters are sums, so launches of one kernel add up exactly as `simt`'s
//! [`KernelSummary`] does: SIMD efficiency is `smsp__thread_inst_executed.sum /
//! (32 · smsp__inst_executed.sum)`, which is `smsp__thread_inst_executed_per_inst_executed.ratio
//! / 32` over all of them; sectors per request are `l1tex__t_sectors… / l1tex__t_requests…`.

use simt::{KernelSummary, Traffic};
use std::fmt::Write;

/// The metrics [`parse_csv`] reads, comma-separated for `ncu --metrics`.
pub const METRICS: &str = "smsp__inst_executed.sum,smsp__thread_inst_executed.sum,\
l1tex__t_requests_pipe_lsu_mem_global_op_ld.sum,l1tex__t_sectors_pipe_lsu_mem_global_op_ld.sum,\
l1tex__t_requests_pipe_lsu_mem_global_op_st.sum,l1tex__t_sectors_pipe_lsu_mem_global_op_st.sum,\
l1tex__t_requests_pipe_lsu_mem_global_op_atom.sum,l1tex__t_sectors_pipe_lsu_mem_global_op_atom.sum,\
l1tex__t_requests_pipe_lsu_mem_global_op_red.sum,l1tex__t_sectors_pipe_lsu_mem_global_op_red.sum,\
launch__shared_mem_per_block_static,launch__shared_mem_per_block_dynamic,gpu__time_duration.sum,\
dram__bytes_read.sum,dram__bytes_write.sum,lts__t_sectors.sum,launch__registers_per_thread,\
sm__cycles_elapsed.avg.per_second,launch__grid_size,launch__block_size";

/// One kernel's counters, summed over its launches.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct GpuKernel {
    /// `pdacrt::filter_rays` for ours; CUB's kernels keep their own names (`cub::DeviceScanKernel`).
    pub name: String,
    /// Launches profiled.
    pub launches: u64,
    /// Warp instructions issued.
    pub inst: f64,
    /// Thread instructions executed.
    pub thread_inst: f64,
    /// Global loads.
    pub loads: Traffic,
    /// Global stores.
    pub stores: Traffic,
    /// Atomics, with and without a returned value (`atom` and `red`).
    pub atomics: Traffic,
    /// Largest shared memory per block of any launch (static + dynamic), bytes.
    pub shared_bytes: u64,
    /// GPU time, seconds.
    pub seconds: f64,
    /// Bytes read from device memory (HBM): a load's miss reads.
    pub dram_read_bytes: f64,
    /// Bytes written to device memory: write-backs of evicted dirty lines.
    pub dram_write_bytes: f64,
    /// Sectors the L2 cache served (every source), summed.
    pub l2_sectors: f64,
    /// Registers per thread (the largest of any launch).
    pub registers: u64,
    /// SM clock (cycles per second), summed over launches: [`GpuKernel::clock_hz`] is
    /// the mean.
    pub clock_hz_sum: f64,
    /// Cycles a warp took per instruction it issued
    /// (`smsp__average_warp_latency_per_inst_issued.ratio`, where the CSV has it; 0
    /// where not), summed over launches (a launch's own where `launches` is 1).
    pub warp_cycles_per_issue_sum: f64,
}

impl GpuKernel {
    /// Bytes read from and written to device memory (HBM).
    pub fn dram_bytes(&self) -> f64 {
        self.dram_read_bytes + self.dram_write_bytes
    }

    /// Thread instructions over 32 × warp instructions.
    pub fn simd_efficiency(&self) -> Option<f64> {
        (self.inst > 0.0).then(|| self.thread_inst / (32.0 * self.inst))
    }

    /// Adds another profile of the same kernel (launches, counters and time summed; the
    /// largest shared memory and register count kept).
    pub fn add(&mut self, o: &GpuKernel) {
        self.launches += o.launches;
        self.inst += o.inst;
        self.thread_inst += o.thread_inst;
        self.loads.add(&o.loads);
        self.stores.add(&o.stores);
        self.atomics.add(&o.atomics);
        self.shared_bytes = self.shared_bytes.max(o.shared_bytes);
        self.seconds += o.seconds;
        self.dram_read_bytes += o.dram_read_bytes;
        self.dram_write_bytes += o.dram_write_bytes;
        self.l2_sectors += o.l2_sectors;
        self.registers = self.registers.max(o.registers);
        self.clock_hz_sum += o.clock_hz_sum;
        self.warp_cycles_per_issue_sum += o.warp_cycles_per_issue_sum;
    }

    /// The SM clock, cycles per second, over this kernel's launches (`None` if not
    /// collected).
    pub fn clock_hz(&self) -> Option<f64> {
        (self.clock_hz_sum > 0.0 && self.launches > 0).then(|| self.clock_hz_sum / self.launches as f64)
    }
}

/// The name after the last `::`: ncu reports a kernel with or without its namespace,
/// depending on how it was asked to name kernels, so kernels are matched by this.
pub fn base_name(name: &str) -> &str {
    name.rsplit("::").next().unwrap_or(name)
}

/// The kernel's name without parameters, template arguments or return type, under the
/// namespace `pdacrt::` when it is one of ours (`void pdacrt::filter_rays(...)`,
/// `filter_rays`), `cis::` for CIS-LBDPT's (`cis::shade_sorted(cis::ShadeArgs)`) and
/// `cub::` for CUB's; any other namespace is kept (`micro::hbm_read`, `bvh::trace`).
pub fn short_name(full: &str) -> String {
    // Drop the parameter list and template arguments (outermost first).
    let mut depth = 0i32;
    let mut out = String::new();
    for c in full.chars() {
        match c {
            '(' | '<' => depth += 1,
            ')' | '>' => depth -= 1,
            _ if depth == 0 => out.push(c),
            _ => {}
        }
    }
    let base = out.trim().rsplit([' ', ':']).next().unwrap_or("").to_string();
    let qualified = out.trim().rsplit(' ').next().unwrap_or("");
    let namespace = if full.contains("cub::") || base.starts_with("Device") {
        "cub"
    } else if let Some((ns, _)) = qualified.split_once("::") {
        ns
    } else {
        "pdacrt"
    };
    format!("{namespace}::{base}")
}

fn field(s: &str) -> String {
    s.trim().trim_matches('"').to_string()
}

/// Splits one CSV line (quoted fields, commas inside quotes kept).
pub fn split_csv(line: &str) -> Vec<String> {
    let mut out = Vec::new();
    let (mut cur, mut quoted) = (String::new(), false);
    for c in line.chars() {
        match c {
            '"' => quoted = !quoted,
            ',' if !quoted => out.push(field(&std::mem::take(&mut cur))),
            _ => cur.push(c),
        }
    }
    out.push(field(&cur));
    out
}

/// A counter in base units (numbers may carry thousands separators; times scale to
/// seconds, sizes to bytes).
fn value(text: &str, unit: &str, line: usize, column: &str) -> Result<f64, String> {
    let plain: String = text.chars().filter(|&c| c != ',').collect();
    if plain.is_empty() || plain == "n/a" {
        return Ok(0.0);
    }
    let v: f64 = plain.parse().map_err(|_| format!("line {line}: column {column}: '{text}' is not a number"))?;
    let scale = match unit {
        "nsecond" | "ns" => 1e-9,
        "usecond" | "us" => 1e-6,
        "msecond" | "ms" => 1e-3,
        "second" | "s" => 1.0,
        "cycle/second" | "cycle/s" => 1.0,
        "cycle/nsecond" | "cycle/ns" => 1e9,
        "cycle/usecond" | "cycle/us" => 1e6,
        "Kbyte" | "KB" => 1e3,
        "Mbyte" | "MB" => 1e6,
        "Kibyte" | "KiB" => 1024.0,
        "Gbyte" | "GB" => 1e9,
        "Mibyte" | "MiB" => 1024.0 * 1024.0,
        _ => 1.0,
    };
    Ok(v * scale)
}

/// Per-kernel sums from `ncu --csv --page raw` output (other lines, such as the
/// profiler's `==PROF==` notes, are skipped). Errors name the line and column.
pub fn parse_csv(text: &str) -> Result<Vec<GpuKernel>, String> {
    Ok(by_kernel(&parse_launches(text)?))
}

/// Launches summed per kernel, in the order of each kernel's first launch.
pub fn by_kernel(launches: &[GpuKernel]) -> Vec<GpuKernel> {
    let mut kernels: Vec<GpuKernel> = Vec::new();
    for launch in launches {
        match kernels.iter_mut().find(|k| k.name == launch.name) {
            Some(k) => k.add(launch),
            None => kernels.push(launch.clone()),
        }
    }
    kernels
}

/// Every launch of an ncu CSV export, in the export's order (one [`GpuKernel`] with
/// `launches` 1 each); [`parse_csv`] sums them per kernel.
pub fn parse_launches(text: &str) -> Result<Vec<GpuKernel>, String> {
    let mut lines = text.lines().enumerate().skip_while(|(_, l)| !l.trim_start().starts_with("\"ID\""));
    let (_, header) = lines.next().ok_or("no ncu CSV header (a line starting with \"ID\") found")?;
    let header = split_csv(header);
    let col = |name: &str| header.iter().position(|h| h == name);
    let name_col = col("Kernel Name").ok_or("the CSV has no 'Kernel Name' column")?;
    let mut units: Option<Vec<String>> = None;
    let mut launches = Vec::new();
    for (i, line) in lines {
        let row = split_csv(line);
        if row.len() < header.len() {
            continue;
        }
        if units.is_none() && row[0].is_empty() {
            units = Some(row);
            continue;
        }
        let units = units.get_or_insert_with(|| vec![String::new(); header.len()]);
        let get = |metric: &str| -> Result<f64, String> {
            match col(metric) {
                Some(c) => value(&row[c], &units[c], i + 1, metric),
                None => Ok(0.0),
            }
        };
        let traffic = |op: &str| -> Result<Traffic, String> {
            Ok(Traffic {
                requests: get(&format!("l1tex__t_requests_pipe_lsu_mem_global_op_{op}.sum"))? as u64,
                sectors: get(&format!("l1tex__t_sectors_pipe_lsu_mem_global_op_{op}.sum"))? as u64,
                // Nsight Compute has no per-kernel counter of the lanes executing global
                // accesses; its source view has them per instruction (`super::source`).
                lanes: 0,
            })
        };
        let name = short_name(&row[name_col]);
        let (atom, red) = (traffic("atom")?, traffic("red")?);
        let launch = GpuKernel {
            name,
            launches: 1,
            inst: get("smsp__inst_executed.sum")?,
            thread_inst: get("smsp__thread_inst_executed.sum")?,
            loads: traffic("ld")?,
            stores: traffic("st")?,
            atomics: Traffic { requests: atom.requests + red.requests, sectors: atom.sectors + red.sectors, lanes: 0 },
            shared_bytes: (get("launch__shared_mem_per_block_static")? + get("launch__shared_mem_per_block_dynamic")?)
                as u64,
            seconds: get("gpu__time_duration.sum")?,
            dram_read_bytes: get("dram__bytes_read.sum")?,
            dram_write_bytes: get("dram__bytes_write.sum")?,
            l2_sectors: get("lts__t_sectors.sum")?,
            registers: get("launch__registers_per_thread")? as u64,
            clock_hz_sum: get("sm__cycles_elapsed.avg.per_second")?,
            warp_cycles_per_issue_sum: get("smsp__average_warp_latency_per_inst_issued.ratio")?,
        };
        launches.push(launch);
    }
    Ok(launches)
}

/// One kernel, predicted and measured.
#[derive(Clone, Debug)]
pub struct Comparison {
    /// The kernel's name.
    pub name: String,
    /// What `simt` measured.
    pub simt: KernelSummary,
    /// What Nsight Compute measured.
    pub gpu: GpuKernel,
}

/// Relative difference of a prediction from a measurement (`None` if either is absent).
pub fn relative(predicted: Option<f64>, measured: Option<f64>) -> Option<f64> {
    match (predicted, measured) {
        (Some(p), Some(m)) if m != 0.0 => Some((p - m) / m),
        _ => None,
    }
}

/// The kernels both sides ran, in the GPU's order.
pub fn compare(simt: &[KernelSummary], gpu: &[GpuKernel]) -> Vec<Comparison> {
    gpu.iter()
        .filter_map(|g| {
            simt.iter().find(|s| base_name(s.name) == base_name(&g.name)).map(|s| Comparison {
                name: s.name.to_string(),
                simt: s.clone(),
                gpu: g.clone(),
            })
        })
        .collect()
}

fn opt(v: Option<f64>, digits: usize) -> String {
    v.map_or("–".into(), |x| format!("{x:.digits$}"))
}

fn pct(v: Option<f64>) -> String {
    v.map_or("–".into(), |x| format!("{:+.0} %", x * 100.0))
}

/// The comparison as a markdown table: SIMD efficiency, load/store sectors per
/// request, shared bytes per block, and time (GPU and the emulator).
pub fn table(rows: &[Comparison]) -> String {
    let mut s = String::new();
    s.push_str("| kernel | launches (simt / GPU) | SIMD eff. simt | GPU | Δ | ld sect/req simt | GPU | Δ | st sect/req simt | GPU | Δ | atomic req simt / GPU | shared B simt / GPU | GPU ms |\n");
    s.push_str("|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|\n");
    for r in rows {
        let (se, ge) = (r.simt.simd_efficiency(), r.gpu.simd_efficiency());
        let (sl, gl) = (r.simt.loads.sectors_per_request(), r.gpu.loads.sectors_per_request());
        let (ss, gs) = (r.simt.stores.sectors_per_request(), r.gpu.stores.sectors_per_request());
        let _ = writeln!(
            s,
            "| {} | {} / {} | {} | {} | {} | {} | {} | {} | {} | {} | {} | {} / {} | {} / {} | {:.3} |",
            r.name,
            r.simt.launches,
            r.gpu.launches,
            opt(se, 3),
            opt(ge, 3),
            pct(relative(se, ge)),
            opt(sl, 2),
            opt(gl, 2),
            pct(relative(sl, gl)),
            opt(ss, 2),
            opt(gs, 2),
            pct(relative(ss, gs)),
            r.simt.atomics.requests,
            r.gpu.atomics.requests,
            r.simt.shared_bytes,
            r.gpu.shared_bytes,
            r.gpu.seconds * 1e3
        );
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    const SAMPLE: &str = concat!(
        "==PROF== Connected to process 1\n",
        "\"ID\",\"Process ID\",\"Kernel Name\",\"gpu__time_duration.sum\",\"l1tex__t_requests_pipe_lsu_mem_global_op_ld.sum\",\"l1tex__t_sectors_pipe_lsu_mem_global_op_ld.sum\",\"smsp__inst_executed.sum\",\"smsp__thread_inst_executed.sum\",\"launch__shared_mem_per_block_static\"\n",
        "\"\",\"\",\"\",\"usecond\",\"\",\"sector\",\"inst\",\"inst\",\"Kbyte\"\n",
        "\"0\",\"7\",\"pdacrt::filter_rays(const unsigned int *, float)\",\"2.5\",\"100\",\"400\",\"1,000\",\"16,000\",\"0\"\n",
        "\"1\",\"7\",\"void cub::detail::scan::DeviceScanKernel<Policy, int>(int)\",\"1\",\"0\",\"0\",\"10\",\"320\",\"0\"\n",
        "\"2\",\"7\",\"pdacrt::filter_rays(const unsigned int *, float)\",\"1.5\",\"100\",\"800\",\"1,000\",\"32,000\",\"5.12\"\n",
    );

    #[test]
    fn launches_of_one_kernel_add_up() {
        let k = parse_csv(SAMPLE).unwrap();
        assert_eq!(k.len(), 2);
        let f = &k[0];
        assert_eq!(f.name, "pdacrt::filter_rays");
        assert_eq!(f.launches, 2);
        // (16k + 32k) / (32 · 2k) = 0.75: the sums, not the mean of the two ratios.
        assert!((f.simd_efficiency().unwrap() - 0.75).abs() < 1e-12);
        assert_eq!(f.loads.sectors_per_request(), Some(6.0));
        assert!((f.seconds - 4e-6).abs() < 1e-15);
        assert_eq!(f.shared_bytes, 5120);
        assert_eq!(k[1].name, "cub::DeviceScanKernel");
    }

    #[test]
    fn names_lose_parameters_and_templates() {
        assert_eq!(short_name("brute_force"), "pdacrt::brute_force");
        assert_eq!(short_name("void pdacrt::brute_force(pdacrt::BruteForceArgs)"), "pdacrt::brute_force");
        assert_eq!(short_name("DeviceSelectSweepKernel"), "cub::DeviceSelectSweepKernel");
        assert_eq!(short_name("cis::shade_sorted(cis::ShadeArgs)"), "cis::shade_sorted");
        assert_eq!(short_name("void cis::alive_flags(const unsigned int *, const cis::Slot *)"), "cis::alive_flags");
        assert_eq!(short_name("void micro::hbm_read(const float4 *, unsigned long)"), "micro::hbm_read");
    }

    #[test]
    fn bad_numbers_name_line_and_column() {
        let bad = SAMPLE.replace("\"2.5\"", "\"fast\"");
        let e = parse_csv(&bad).unwrap_err();
        assert!(e.contains("line 4") && e.contains("gpu__time_duration.sum"), "{e}");
        assert!(parse_csv("no csv here").is_err());
    }

    #[test]
    fn the_comparison_is_relative_to_the_measurement() {
        assert_eq!(relative(Some(1.1), Some(1.0)).map(|x| (x * 1e6).round()), Some(100_000.0));
        assert_eq!(relative(None, Some(1.0)), None);
        let simt = KernelSummary { name: "pdacrt::filter_rays", launches: 2, ..Default::default() };
        let rows = compare(&[simt], &parse_csv(SAMPLE).unwrap());
        assert_eq!(rows.len(), 1);
        assert!(table(&rows).contains("| pdacrt::filter_rays | 2 / 2 |"));
    }

    #[test]
    fn atomic_requests_are_atom_and_red_summed_beside_the_emulators() {
        let csv = concat!(
            "\"ID\",\"Kernel Name\",\"l1tex__t_requests_pipe_lsu_mem_global_op_atom.sum\",\"l1tex__t_requests_pipe_lsu_mem_global_op_red.sum\"\n",
            "\"\",\"\",\"\",\"\"\n",
            "\"0\",\"pdacrt::node_bounds(const unsigned int *)\",\"3\",\"40\"\n",
            "\"1\",\"pdacrt::node_bounds(const unsigned int *)\",\"0\",\"7\"\n",
        );
        let gpu = parse_csv(csv).unwrap();
        assert_eq!(gpu[0].atomics.requests, 50);
        let simt = KernelSummary {
            name: "pdacrt::node_bounds",
            launches: 2,
            atomics: Traffic { requests: 21, sectors: 30, lanes: 90 },
            ..Default::default()
        };
        let t = table(&compare(&[simt], &gpu));
        assert!(t.contains("| 21 / 50 | 0 / 0 |"), "{t}");
    }
}
