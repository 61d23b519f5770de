//! The probe program's own report (`cuda/microbench.cu`: the device, each probe's work,
//! the instruction-fetch probes' timed rows) and what calibration reads from the
//! instruction-fetch probes with Nsight's counters of them.

use crate::gpu::ncu::GpuKernel;

/// The probe program's report: `device` lines (name, value), `probe` lines (probe,
/// quantity, amount) and the instruction-fetch probes' `timed` rows (`microbench
/// icache`). Other `timed` rows are read by no one here.
pub(super) struct Report {
    pub(super) device: Vec<(String, String)>,
    pub(super) probes: Vec<(String, f64)>,
    pub(super) straight: Vec<Straight>,
    pub(super) jumps: Vec<Jump>,
}

/// One row of the straight-line instruction-fetch probe: warps a SM running passes
/// over `code_kib` of multiply-adds, each warp at its own place.
#[derive(Clone, Copy, Debug)]
pub(super) struct Straight {
    code_kib: f64,
    warps: u32,
    cycles_per_fma: f64,
}

/// One row of the jumping instruction-fetch probe: warps a SM each running pieces of
/// code in its own order.
#[derive(Clone, Copy, Debug)]
pub(super) struct Jump {
    pieces: u32,
    warps: u32,
    cycles_per_piece: f64,
}

pub(super) fn read_report(text: &str) -> Result<Report, String> {
    let mut r = Report { device: Vec::new(), probes: Vec::new(), straight: Vec::new(), jumps: Vec::new() };
    let number = |i: usize, what: &str, v: &str| -> Result<f64, String> {
        v.parse().map_err(|_| format!("line {}: {what}: '{v}' is not a number", i + 1))
    };
    for (i, line) in text.lines().enumerate() {
        if line.trim().is_empty() {
            continue;
        }
        let f: Vec<&str> = line.split('\t').collect();
        match f.as_slice() {
            ["device", k, v] => r.device.push((k.to_string(), v.to_string())),
            ["probe", name, _, amount] => {
                let a =
                    amount.parse().map_err(|_| format!("line {}: probe {name}: '{amount}' is not a number", i + 1))?;
                r.probes.push((name.to_string(), a));
            }
            ["timed", "icache", "code_kib", k, "warps_per_sm", w, "cycles_per_fma", c] => r.straight.push(Straight {
                code_kib: number(i, "code_kib", k)?,
                warps: number(i, "warps_per_sm", w)? as u32,
                cycles_per_fma: number(i, "cycles_per_fma", c)?,
            }),
            ["timed", "icache_jump", "pieces", k, "warps_per_sm", w, "cycles_per_piece", c] => r.jumps.push(Jump {
                pieces: number(i, "pieces", k)? as u32,
                warps: number(i, "warps_per_sm", w)? as u32,
                cycles_per_piece: number(i, "cycles_per_piece", c)?,
            }),
            ["timed", ..] => {}
            _ => return Err(format!("line {}: expected 'device', 'probe' or 'timed' fields", i + 1)),
        }
    }
    Ok(r)
}

/// Pieces each warp of the jumping instruction-fetch probe runs (`icache_jump_row` in
/// `cuda/microbench.cu`).
const JUMP_PIECES_PER_WARP: f64 = 16384.0;

/// The instruction-fetch probes read: the smallest code the SM's instruction cache
/// does not hold, and the most warp instructions an SM issues from code its warps
/// jump about that it does not hold.
pub(super) struct Fetch {
    pub(super) code_kib: f64,
    pub(super) straight_warps: u32,
    pub(super) pieces: u32,
    pub(super) warps: u32,
    pub(super) issue_per_cycle_per_sm: f64,
}

impl Fetch {
    /// Code the cache does not hold: the straight-line probe's smallest code on which,
    /// with the most warps a SM it ran, a multiply-add takes over 1.5 times what it
    /// takes on its smallest code (the probe states its code's size). Fetch-bound
    /// jumping: the jumping probe's fewest pieces on which, with its most warps a SM,
    /// a piece takes over twice what it takes on its fewest. A jumping row's issue rate
    /// is Nsight's warp instructions of its timed launch (each row launches twice, a
    /// warm-up first) per SM over the probe's own cycles for its pieces, or, where the
    /// CSV has no instruction counts, its warps a SM over Nsight's cycles a warp took
    /// per instruction it issued; the rate is the most of any warps a SM.
    pub(super) fn read(report: &Report, launches: &[GpuKernel], sms: f64) -> Result<Fetch, String> {
        let again = "(run MODE=icache sh cuda/microbench.sh and give its probe and ncu files)";
        if report.straight.is_empty() || report.jumps.is_empty() {
            return Err(format!("probe output: no icache and icache_jump rows {again}"));
        }
        let most = report.straight.iter().map(|r| r.warps).max().unwrap_or(0);
        let mut rows: Vec<Straight> = report.straight.iter().copied().filter(|r| r.warps == most).collect();
        rows.sort_by(|a, b| a.code_kib.total_cmp(&b.code_kib));
        let code_kib = rows
            .iter()
            .find(|r| r.cycles_per_fma > 1.5 * rows[0].cycles_per_fma)
            .map(|r| r.code_kib)
            .ok_or("icache: no code size slowed the straight-line probe (never 1.5 times its smallest code's)")?;
        let launches: Vec<&GpuKernel> = launches.iter().filter(|k| k.name.ends_with("icache_jump")).collect();
        if launches.len() != 2 * report.jumps.len() {
            return Err(format!(
                "ncu CSV: {} launches of icache_jump for {} probe rows (two a row) {again}",
                launches.len(),
                report.jumps.len()
            ));
        }
        let jump_most = report.jumps.iter().map(|j| j.warps).max().unwrap_or(0);
        let at = |pieces: u32| report.jumps.iter().find(|j| j.pieces == pieces && j.warps == jump_most);
        let mut sizes: Vec<u32> = report.jumps.iter().map(|j| j.pieces).collect();
        sizes.sort_unstable();
        sizes.dedup();
        let base =
            at(sizes[0]).ok_or(format!("icache_jump: no row of {} pieces at {jump_most} warps a SM", sizes[0]))?;
        let pieces = sizes
            .iter()
            .copied()
            .find(|&k| at(k).is_some_and(|j| j.cycles_per_piece > 2.0 * base.cycles_per_piece))
            .ok_or("icache_jump: no code was fetch-bound (a piece never took twice as long as on the fewest pieces)")?;
        let mut best = (0, 0.0);
        for (j, l) in report.jumps.iter().zip(launches.chunks(2).map(|pair| &pair[1])) {
            if j.pieces != pieces {
                continue;
            }
            let rate = if l.inst > 0.0 {
                l.inst / sms / (j.cycles_per_piece * JUMP_PIECES_PER_WARP)
            } else if l.warp_cycles_per_issue_sum > 0.0 {
                j.warps as f64 / l.warp_cycles_per_issue_sum
            } else {
                return Err(format!(
                    "ncu CSV: icache_jump has neither smsp__inst_executed.sum nor smsp__average_warp_latency_per_inst_issued.ratio {again}"
                ));
            };
            if rate > best.1 {
                best = (j.warps, rate);
            }
        }
        Ok(Fetch { code_kib, straight_warps: most, pieces, warps: best.0, issue_per_cycle_per_sm: best.1 })
    }
}
