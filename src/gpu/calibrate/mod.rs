//! A GPU profile for `simt`'s time model from the microbenchmarks of
//! `cuda/microbench.cu`: their own report of the device and of the work each probe did,
//! and Nsight Compute's counters of each probe kernel (`cuda/microbench.sh`).
//!
//! Only the probes enter the profile; the kernels the model is checked on (PDACRT's,
//! CIS's) never do, so their errors are out-of-sample.

mod probes;

use super::ncu::{GpuKernel, base_name, by_kernel, parse_launches};
use probes::{Fetch, Report, read_report};
use simt::GpuProfile;

/// A calibrated profile and, per key, where its value came from.
pub struct Calibration {
    /// The profile.
    pub profile: GpuProfile,
    /// `(key, provenance)`: `device query`, or the probe and counters used.
    pub sources: Vec<(&'static str, String)>,
    /// Figures measured by probes the model does not use (checks), one line each.
    pub notes: Vec<String>,
}

/// Registers per SM where the probe output has no device query of them (runs before it
/// printed one): the 65,536 of every NVIDIA GPU since Kepler, the H200 included.
const REGISTERS_PER_SM: f64 = 65536.0;

/// Builds the profile from the probe program's output and ncu's CSV of it, one pair per
/// run (`probes[k]` with `ncu_csvs[k]`): a later run may add probes an earlier one
/// lacked (`microbench fences`); where two runs have a probe, the first one's counts.
pub fn calibrate(probes: &[&str], ncu_csvs: &[&str]) -> Result<Calibration, String> {
    if probes.is_empty() || probes.len() != ncu_csvs.len() {
        return Err(format!(
            "{} probe outputs for {} ncu CSVs: give one of each per run",
            probes.len(),
            ncu_csvs.len()
        ));
    }
    let report = read_report(&probes.join("\n"))?;
    // Every launch of every run, read once; summed per kernel within each run (a probe
    // two runs have is two entries, the first one's found first).
    let (mut launches, mut kernels) = (Vec::new(), Vec::new());
    for csv in ncu_csvs {
        let run = parse_launches(csv)?;
        kernels.extend(by_kernel(&run));
        launches.extend(run);
    }
    let dev = |k: &str| -> Result<f64, String> {
        let v = report.device.iter().find(|(n, _)| n == k).ok_or_else(|| format!("probe output: no device {k}"))?;
        v.1.parse().map_err(|_| format!("probe output: device {k}: '{}' is not a number", v.1))
    };
    let amount = |p: &str| -> Result<f64, String> {
        report.probes.iter().find(|(n, _)| n == p).map(|x| x.1).ok_or_else(|| format!("probe output: no probe {p}"))
    };
    // Per-launch means of one probe kernel (ncu names them `…::empty` or `empty`).
    let probe = |p: &str| -> Result<GpuKernel, String> {
        kernels
            .iter()
            .find(|k| k.name.rsplit("::").next() == Some(p))
            .cloned()
            .map(|k| {
                let n = k.launches.max(1) as f64;
                GpuKernel {
                    seconds: k.seconds / n,
                    inst: k.inst / n,
                    dram_read_bytes: k.dram_read_bytes / n,
                    dram_write_bytes: k.dram_write_bytes / n,
                    l2_sectors: k.l2_sectors / n,
                    loads: simt::Traffic {
                        requests: k.loads.requests / n as u64,
                        sectors: k.loads.sectors / n as u64,
                        lanes: 0,
                    },
                    stores: simt::Traffic {
                        requests: k.stores.requests / n as u64,
                        sectors: k.stores.sectors / n as u64,
                        lanes: 0,
                    },
                    ..k
                }
            })
            .ok_or_else(|| format!("ncu CSV: no kernel {p}"))
    };
    let sms = dev("sms")?;
    let launch = probe("empty")?.seconds;
    let busy = |k: &GpuKernel| (k.seconds - launch).max(1e-9);
    let alu = probe("alu_mix")?;
    let clock = alu.clock_hz().ok_or("ncu CSV: alu_mix has no sm__cycles_elapsed.avg.per_second")?;
    let name = report.device.iter().find(|(n, _)| n == "name").map(|x| x.1.clone()).unwrap_or_default();

    let blocks = probe("empty_blocks")?;
    let chain = probe("alu_chain")?;
    let hbm = probe("hbm_read")?;
    let hbm_write = probe("hbm_write")?;
    let l2 = probe("l2_read")?;
    let l2_scatter = probe("l2_scatter")?;
    let l1 = probe("l1_read")?;
    let chase_hbm = probe("chase_hbm")?;
    let chase_l2 = probe("chase_l2")?;
    let chase_atomic = probe("chase_atomic")?;
    let fence_store = probe("fence_store")?;
    let fence_alone = probe("fence_alone")?;
    let fence_many = probe("fence_many")?;
    let scattered_many = probe("fence_scattered_many")?;
    let scattered_warp = probe("fence_scattered_warp")?;
    let at = probe("atomic_distinct")?;
    let at_same = probe("atomic_same")?;
    let barrier = probe("barrier")?;
    let shared = probe("shared_rw")?;

    let hbm_latency = busy(&chase_hbm) / amount("chase_hbm")?;
    // The L2 chase's first pass misses (caches are flushed before each kernel): those
    // hops, at most the sectors read from HBM, are charged at the HBM latency. The
    // sectors written back meanwhile (lines other kernels left dirty) are no misses of
    // the chase.
    let l2_misses = (chase_l2.dram_read_bytes / 32.0).min(amount("chase_l2")? - 1.0);
    let l2_latency = (busy(&chase_l2) - l2_misses * hbm_latency) / (amount("chase_l2")? - l2_misses);
    // A fence's cost is a line in the sectors it waits for, `own + sectors * per_sector`,
    // through two probes' (sectors, seconds) per fence, the sectors from their store
    // counters. Every SM fencing: after one coalesced store and after three scattered
    // ones (the GPU's rates); one warp alone: one thread after one stored sector and a
    // warp after scattered stores (the latency).
    let per_fence = |p: &str, k: &GpuKernel| -> Result<(f64, f64), String> {
        let fences = amount(p)?;
        Ok((k.stores.sectors as f64 / fences, busy(k) / fences))
    };
    let (sector_time, fence_time) = fence_line(
        "every SM fencing",
        per_fence("fence_many", &fence_many)?,
        per_fence("fence_scattered_many", &scattered_many)?,
    )?;
    let (sector_latency, latency_at_0) = fence_line(
        "one warp",
        per_fence("fence_store", &fence_store)?,
        per_fence("fence_scattered_warp", &scattered_warp)?,
    )?;
    // The atomic chase runs over the L2 chase's 8 KiB, and its first pass misses alike.
    let atomic_misses = (chase_atomic.dram_read_bytes / 32.0).min(amount("chase_atomic")? - 1.0);
    let atomic_latency =
        (busy(&chase_atomic) - atomic_misses * hbm_latency) / (amount("chase_atomic")? - atomic_misses);
    // How the bounds combine: the overlap probes' shares of the smaller work that the
    // larger does not hide, free-running and phased with 1 and 4 blocks a SM (with R
    // blocks the model takes `many + (one - many) / R`, solved here through 1 and 4;
    // 2 blocks a SM is a check).
    let overlap = Overlap::read(&report, &launches)?;
    let fetch = Fetch::read(&report, &launches, sms)?;
    let free = overlap.exposed("overlap_free", &[2, 4, 8, 16])?;
    let one = overlap.exposed("overlap_phased_1", &[8, 16, 32])?;
    let four = overlap.exposed("overlap_phased_4", &[8, 16, 32])?;
    let two = overlap.exposed("overlap_phased_2", &[8, 16, 32])?;
    let profile = GpuProfile {
        name,
        sms,
        clock_hz: clock,
        max_warps_per_sm: dev("max_warps_per_sm")?,
        max_blocks_per_sm: dev("max_blocks_per_sm")?,
        shared_per_sm_bytes: dev("shared_per_sm_bytes")?,
        registers_per_sm: dev("registers_per_sm").unwrap_or(REGISTERS_PER_SM),
        l2_bytes: dev("l2_bytes")?,
        issue_per_cycle_per_sm: alu.inst / (busy(&alu) * clock * sms),
        fetch_thrash_code_bytes: fetch.code_kib * 1024.0,
        fetch_issue_per_cycle_per_sm: fetch.issue_per_cycle_per_sm,
        alu_latency_cycles: busy(&chain) * clock / amount("alu_chain")?,
        l1_sectors_per_cycle_per_sm: l1.loads.sectors as f64 / (busy(&l1) * clock * sms),
        l2_bytes_per_s: l2.loads.sectors as f64 * 32.0 / busy(&l2),
        l2_scattered_bytes_per_s: l2_scatter.loads.sectors as f64 * 32.0 / busy(&l2_scatter),
        hbm_bytes_per_s: hbm.dram_read_bytes / busy(&hbm),
        l2_latency_s: l2_latency,
        hbm_latency_s: hbm_latency,
        atomic_latency_s: atomic_latency,
        fence_latency_s: latency_at_0 + sector_latency,
        fenced_sector_latency_s: sector_latency,
        fences_per_s: 1.0 / fence_time,
        fenced_sectors_per_s: 1.0 / sector_time,
        atomics_per_s: amount("atomic_distinct")? / busy(&at),
        same_address_atomics_per_s: amount("atomic_same")? / busy(&at_same),
        barriers_per_s_per_sm: amount("barrier")? / (busy(&barrier) * sms),
        block_dispatch_s: busy(&blocks) / (amount("empty_blocks")? / sms),
        launch_s: launch,
        exposed_free: free.share.clamp(0.0, 1.0),
        exposed_one_block: one.share.clamp(0.0, 1.0),
        exposed_many_blocks: ((4.0 * four.share - one.share) / 3.0).clamp(0.0, 1.0),
    };
    let two_law = profile.exposed_many_blocks + (profile.exposed_one_block - profile.exposed_many_blocks) / 2.0;
    let probe_of = |p: &str, how: &str| format!("measured: {p} ({how})");
    // The overlap probes may come from another card of the family (their shares are
    // ratios of times); the provenance names it.
    let overlap_gpu = probes
        .iter()
        .find(|t| t.contains("\toverlap_"))
        .and_then(|t| t.lines().find_map(|l| l.strip_prefix("device\tname\t")))
        .filter(|g| *g != profile.name)
        .map_or(String::new(), |g| format!(", on an {g}"));
    let overlap_of = |p: &str, how: &str| format!("measured: {p} ({how}{overlap_gpu})");
    // Likewise the instruction-fetch probe (its rates are per SM cycle).
    let jump_gpu = probes
        .iter()
        .find(|t| t.contains("\ticache_jump\t") || t.contains("\ticache\t"))
        .and_then(|t| t.lines().find_map(|l| l.strip_prefix("device\tname\t")))
        .filter(|g| *g != profile.name)
        .map_or(String::new(), |g| format!(", on an {g}"));
    let sources = vec![
        ("sms", "device query".to_string()),
        ("clock_ghz", probe_of("alu_mix", "sm__cycles_elapsed.avg.per_second")),
        ("max_warps_per_sm", "device query".into()),
        ("max_blocks_per_sm", "device query".into()),
        ("shared_per_sm_bytes", "device query".into()),
        (
            "registers_per_sm",
            if dev("registers_per_sm").is_ok() {
                "device query".into()
            } else {
                "datasheets: 64K 32-bit registers per SM on every NVIDIA GPU since Kepler (this probe output has no query)".into()
            },
        ),
        ("l2_bytes", "device query".into()),
        ("issue_per_cycle_per_sm", probe_of("alu_mix", "warp instructions / SM cycles")),
        (
            "fetch_thrash_code_kib",
            format!(
                "measured: icache (the smallest straight-line code on which a multiply-add took over 1.5 times as long as on the smallest, {} warps a SM{jump_gpu})",
                fetch.straight_warps
            ),
        ),
        (
            "fetch_issue_per_cycle_per_sm",
            format!(
                "measured: icache_jump ({} pieces, the fewest a piece took over twice as long on; {} warps a SM, the most of any warps: warp instructions / SM cycles{jump_gpu})",
                fetch.pieces, fetch.warps
            ),
        ),
        ("alu_latency_cycles", probe_of("alu_chain", "cycles per dependent FMA, one warp")),
        ("l1_sectors_per_cycle_per_sm", probe_of("l1_read", "L1-hit load sectors / SM cycles")),
        ("l2_gb_per_s", probe_of("l2_read", "ld.global.cg sectors x 32 B / time")),
        (
            "l2_scattered_gb_per_s",
            probe_of("l2_scatter", "ld.global.cg of one 4-byte word a sector, sectors x 32 B / time"),
        ),
        ("hbm_gb_per_s", probe_of("hbm_read", "dram__bytes_read / time")),
        ("l2_latency_ns", probe_of("chase_l2", "one-thread pointer chase, first-pass misses at HBM latency")),
        ("hbm_latency_ns", probe_of("chase_hbm", "one-thread pointer chase, 8,212-byte steps")),
        (
            "atomic_latency_ns",
            probe_of(
                "chase_atomic",
                "one-thread chase of atomicAdd's returned values, first-pass misses at HBM latency",
            ),
        ),
        ("fence_latency_ns", probe_of("fence_store", "one thread: a store, then __threadfence(), repeated")),
        (
            "fenced_sector_latency_ns",
            probe_of(
                "fence_store, fence_scattered_warp",
                "one warp's fence wait per stored sector beyond the first (two-probe solve)",
            ),
        ),
        (
            "fences_per_ns",
            probe_of(
                "fence_many, fence_scattered_many",
                "warp __threadfence()s per ns every SM fencing, less the sectors they wait for",
            ),
        ),
        (
            "fenced_sectors_per_ns",
            probe_of(
                "fence_many, fence_scattered_many",
                "stored sectors fences wait for per ns, every SM fencing (two-probe solve)",
            ),
        ),
        ("atomics_per_ns", probe_of("atomic_distinct", "atomicAdd lanes to distinct words / time")),
        ("same_address_atomics_per_ns", probe_of("atomic_same", "atomicAdd lanes to one word / time")),
        ("barriers_per_us_per_sm", probe_of("barrier", "block barriers / time / SMs")),
        ("block_dispatch_ns", probe_of("empty_blocks", "(time - empty launch) / blocks per SM")),
        ("launch_us", probe_of("empty", "gpu__time_duration of one empty block")),
        (
            "overlap_exposed_free",
            overlap_of(
                &free.forms,
                "(both - larger) / smaller of the loads and the arithmetic alone, less the loop alone",
            ),
        ),
        (
            "overlap_exposed_one_block",
            overlap_of(&one.forms, "(both - larger) / smaller, each less the loop and barriers alone, 1 block a SM"),
        ),
        (
            "overlap_exposed_many_blocks",
            overlap_of(&format!("{}, {}", one.forms, four.forms), "the share with 4 blocks a SM and with 1, solved"),
        ),
    ];
    let notes = vec![
        format!(
            "hbm_write: {:.0} GB/s written (dram__bytes_write / time)",
            hbm_write.dram_write_bytes / busy(&hbm_write) / 1e9
        ),
        format!(
            "shared_rw: {:.2} warp instructions per SM cycle with shared loads and stores",
            shared.inst / (busy(&shared) * clock * sms)
        ),
        format!(
            "fence_alone: {:.1} ns per __threadfence() with no store before it",
            busy(&fence_alone) / amount("fence_alone")? * 1e9
        ),
        format!(
            "{}: {:.2} of the smaller work exposed with 2 blocks a SM (the model's {two_law:.2})",
            two.forms, two.share
        ),
    ];
    Ok(Calibration { profile, sources, notes })
}

/// The overlap probes (`microbench overlap`): each form's median launch time, by the
/// probe output's names in order (ncu names every form of one template alike).
struct Overlap {
    /// (probe, median seconds, load sectors of its median launch).
    forms: Vec<(String, f64, u64)>,
}

/// One overlap share: the form it was read from and the share of the smaller bound
/// the larger did not hide.
struct Exposed {
    forms: String,
    share: f64,
}

impl Overlap {
    fn read(report: &Report, launches: &[GpuKernel]) -> Result<Overlap, String> {
        let mut names: Vec<&str> = Vec::new();
        for (n, _) in &report.probes {
            if n.starts_with("overlap_") && names.last() != Some(&n.as_str()) {
                names.push(n);
            }
        }
        let launches: Vec<&GpuKernel> =
            launches.iter().filter(|k| base_name(&k.name).starts_with("overlap_")).collect();
        if names.is_empty() {
            return Err("probe output: no overlap probes (run MODE=overlap sh cuda/microbench.sh)".into());
        }
        if !launches.len().is_multiple_of(names.len()) {
            return Err(format!("ncu CSV: {} overlap launches for {} overlap probes", launches.len(), names.len()));
        }
        let per = launches.len() / names.len();
        let forms = names
            .iter()
            .zip(launches.chunks(per))
            .map(|(n, l)| {
                let mut t: Vec<(f64, u64)> = l.iter().map(|k| (k.seconds, k.loads.sectors)).collect();
                t.sort_by(|a, b| a.0.total_cmp(&b.0));
                (n.to_string(), t[t.len() / 2].0, t[t.len() / 2].1)
            })
            .collect();
        Ok(Overlap { forms })
    }

    fn get(&self, name: &str) -> Result<(f64, u64), String> {
        self.forms
            .iter()
            .find(|(n, _, _)| n == name)
            .map(|x| (x.1, x.2))
            .ok_or_else(|| format!("no overlap probe {name}"))
    }

    fn time(&self, name: &str) -> Result<f64, String> {
        Ok(self.get(name)?.0)
    }

    /// The share of the smaller of the loads' and the arithmetic's times that adds to
    /// the larger when both run (`{stem}_load_alu_K` against `{stem}_load` and
    /// `{stem}_alu_K`, each less `{stem}_none`), at the `K` whose two times are the
    /// closest: where the bounds are equal, how they combine shows most.
    fn exposed(&self, stem: &str, rounds: &[u32]) -> Result<Exposed, String> {
        let none = self.time(&format!("{stem}_none"))?;
        let (load, sectors) = self.get(&format!("{stem}_load"))?;
        let load = load - none;
        let mut best: Option<(f64, Exposed)> = None;
        for k in rounds {
            let alu = self.time(&format!("{stem}_alu_{k}"))? - none;
            let (both, both_sectors) = self.get(&format!("{stem}_load_alu_{k}"))?;
            let both = both - none;
            // The loads alone must be the loads of the form with arithmetic: the same
            // sectors (the compiler may load fewer words where fewer are used).
            if sectors.abs_diff(both_sectors) > sectors / 100 {
                return Err(format!(
                    "overlap probes {stem}: the loads alone read {sectors} L1 sectors, with {k} rounds \
                     {both_sectors}: not the same loads"
                ));
            }
            let (small, large) = (load.min(alu), load.max(alu));
            if small <= 0.0 {
                return Err(format!("overlap probes {stem}: the loop alone takes as long as the work ({k} rounds)"));
            }
            let balance = small / large;
            let e = Exposed { forms: format!("{stem}_load_alu_{k}"), share: (both - large) / small };
            if best.as_ref().is_none_or(|(b, _)| balance > *b) {
                best = Some((balance, e));
            }
        }
        best.map(|b| b.1).ok_or_else(|| format!("overlap probes {stem}: no rounds"))
    }
}

/// The line `own + sectors * per_sector` through two probes' (sectors, seconds) per
/// fence, as (per_sector, own); an error when the second probe does not wait for more
/// sectors for longer, or the fence's own cost is not positive.
fn fence_line(what: &str, (s1, t1): (f64, f64), (s2, t2): (f64, f64)) -> Result<(f64, f64), String> {
    if s2 <= s1 || t2 <= t1 {
        return Err(format!("fence probes, {what}: {s2:.1} sectors take {t2:e} s a fence against {s1:.1} in {t1:e} s"));
    }
    let per_sector = (t2 - t1) / (s2 - s1);
    let own = t1 - s1 * per_sector;
    if own <= 0.0 {
        return Err(format!(
            "fence probes, {what}: a fence's own cost comes out {own:e} s: on this GPU a fence's cost is not \
             a line through the two probes (an H100 gives this; docs/simt.md, \"Fences under load, probed\"), \
             and the model has no other fence law yet"
        ));
    }
    Ok((per_sector, own))
}

impl Calibration {
    /// The profile file: a header naming the GPU, the run and the command, then one
    /// line per key with its provenance.
    pub fn to_text(&self, header: &str) -> String {
        let mut h = header.to_string();
        for n in &self.notes {
            h += &format!("\nchecks (not used by the model): {n}");
        }
        self.profile.to_text(&h, |k| {
            self.sources.iter().find(|(n, _)| *n == k).map_or_else(|| "?".to_string(), |s| s.1.clone())
        })
    }
}
