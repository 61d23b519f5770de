//! Launch records and their aggregation per kernel name.

use crate::limits::WARP_SIZE;
pub use crate::meter::{Traffic, WarpChain};
use std::collections::{HashMap, VecDeque};
use std::fmt::Write;

/// Launch records kept in the device's log (older ones are dropped; the per-kernel
/// summaries keep counting).
pub const LOG_CAPACITY: usize = 4096;

/// Warp instructions issued and thread instructions executed, for one region.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct RegionStats {
    /// The region's name (`ops` for the operations `simt` counts itself).
    pub name: &'static str,
    /// Warp instructions issued (Nsight: `smsp__inst_executed`).
    pub issued: u64,
    /// Thread instructions executed: the lanes active in each issued instruction,
    /// summed (Nsight: `smsp__thread_inst_executed`).
    pub active: u64,
}

impl RegionStats {
    /// Active lanes per issued warp step, over the warp width: 1 is perfect lockstep.
    /// `None` when nothing was issued (or nothing measured).
    pub fn simd_efficiency(&self) -> Option<f64> {
        (self.issued > 0).then(|| self.active as f64 / (self.issued as f64 * WARP_SIZE as f64))
    }

    /// Adds another region's steps to this one.
    pub fn add(&mut self, o: &RegionStats) {
        self.issued += o.issued;
        self.active += o.active;
    }
}

/// What one launch did.
#[derive(Clone, Debug)]
pub struct LaunchRecord {
    /// The kernel's name (`feature::stage`).
    pub name: &'static str,
    /// Blocks launched.
    pub grid: u32,
    /// Threads per block.
    pub block: u32,
    /// Shared memory per block, bytes.
    pub shared_bytes: usize,
    /// Registers per thread of the kernel's GPU twin, 0 when not known
    /// ([`crate::LaunchConfig::registers`]; not kept in the record files, which read back 0).
    pub registers: u32,
    /// Wall time of the launch, seconds.
    pub seconds: f64,
    /// Whether SIMD efficiency and memory traffic were measured.
    pub measured: bool,
    /// Threads launched (grid × block, less any the kernel asked not to count).
    pub threads: u64,
    /// Instructions of the operations lanes performed through `simt` (global and
    /// shared accesses, atomics, warp intrinsics).
    pub ops: RegionStats,
    /// Work the kernel declared with `Thread::work`, per named region, in order.
    pub regions: Vec<RegionStats>,
    /// Global loads, stores and atomics: warp-level requests and the sectors they touched.
    pub loads: Traffic,
    /// Global stores.
    pub stores: Traffic,
    /// Global atomics.
    pub atomics: Traffic,
    /// Block-wide barriers (`sync_threads`) passed, per block, summed.
    pub barriers: u64,
    /// Distinct 32-byte sectors the launch's global accesses touched (estimated from a
    /// sample of 1 in 16 addresses; 0 when unmeasured).
    pub footprint_sectors: u64,
    /// Distinct loaded sectors per block, summed (estimated likewise): the loads that
    /// reach L2 if each block's repeated loads hit L1 (stores and atomics reach L2
    /// every time; [`LaunchRecord::stores`] and [`LaunchRecord::atomics`] count them).
    pub block_sectors: u64,
    /// The chain of the warp that issued the most instructions.
    pub longest_warp: WarpChain,
    /// Every warp's chain summed: what the warps wait for one after another (load
    /// rounds, atomics whose value they use, fences). 0 when unmeasured.
    pub waits: WarpChain,
}

impl LaunchRecord {
    /// Every instruction counted: operations and declared work.
    pub fn all_regions(&self) -> RegionStats {
        let mut all = self.ops.clone();
        self.regions.iter().for_each(|r| all.add(r));
        all
    }

    /// SIMD efficiency over every counted instruction.
    pub fn simd_efficiency(&self) -> Option<f64> {
        self.all_regions().simd_efficiency()
    }

    /// Efficiency of the named region.
    pub fn region_efficiency(&self, name: &str) -> Option<f64> {
        self.regions.iter().find(|r| r.name == name).and_then(RegionStats::simd_efficiency)
    }

    /// Sectors per global load request.
    pub fn sectors_per_request(&self) -> Option<f64> {
        self.loads.sectors_per_request()
    }
}

/// Totals of every launch of one kernel name.
#[derive(Clone, Debug, Default)]
pub struct KernelSummary {
    /// The kernel's name.
    pub name: &'static str,
    /// Launches summed.
    pub launches: u64,
    /// Wall time of all launches, seconds.
    pub seconds: f64,
    /// Threads of all launches.
    pub threads: u64,
    /// Launches that were measured (the efficiency and traffic figures cover these).
    pub measured_launches: u64,
    /// Operations `simt` counted itself (memory, atomics, intrinsics).
    pub ops: RegionStats,
    /// Declared work per named region.
    pub regions: Vec<RegionStats>,
    /// Global loads.
    pub loads: Traffic,
    /// Global stores.
    pub stores: Traffic,
    /// Global atomics.
    pub atomics: Traffic,
    /// Largest shared memory per block of any launch.
    pub shared_bytes: usize,
    /// Barriers passed.
    pub barriers: u64,
    /// Distinct sectors of each launch, summed.
    pub footprint_sectors: u64,
    /// Predicted GPU time of the measured launches on the device's GPU profile, seconds
    /// (0 without one; see [`crate::timing`]).
    pub gpu_seconds: f64,
}

impl KernelSummary {
    /// Active lanes per issued warp step over all regions, over the warp width.
    pub fn simd_efficiency(&self) -> Option<f64> {
        let mut all = self.ops.clone();
        self.regions.iter().for_each(|r| all.add(r));
        all.simd_efficiency()
    }

    /// Sectors per global load request.
    pub fn sectors_per_request(&self) -> Option<f64> {
        self.loads.sectors_per_request()
    }

    /// Adds another summary's launches to this one (the same kernel measured in two
    /// runs, say).
    pub fn merge(&mut self, o: &KernelSummary) {
        self.launches += o.launches;
        self.seconds += o.seconds;
        self.threads += o.threads;
        self.measured_launches += o.measured_launches;
        self.ops.add(&o.ops);
        self.add_regions(&o.regions);
        self.loads.add(&o.loads);
        self.stores.add(&o.stores);
        self.atomics.add(&o.atomics);
        self.shared_bytes = self.shared_bytes.max(o.shared_bytes);
        self.barriers += o.barriers;
        self.footprint_sectors += o.footprint_sectors;
        self.gpu_seconds += o.gpu_seconds;
    }

    fn add_regions(&mut self, regions: &[RegionStats]) {
        for reg in regions {
            match self.regions.iter_mut().find(|x| x.name == reg.name) {
                Some(x) => x.add(reg),
                None => self.regions.push(reg.clone()),
            }
        }
    }

    fn add(&mut self, r: &LaunchRecord, gpu_seconds: f64) {
        self.name = r.name;
        self.launches += 1;
        self.seconds += r.seconds;
        self.threads += r.threads;
        self.measured_launches += r.measured as u64;
        self.ops.name = "ops";
        self.ops.add(&r.ops);
        self.add_regions(&r.regions);
        self.loads.add(&r.loads);
        self.stores.add(&r.stores);
        self.atomics.add(&r.atomics);
        self.shared_bytes = self.shared_bytes.max(r.shared_bytes);
        self.barriers += r.barriers;
        self.footprint_sectors += r.footprint_sectors;
        self.gpu_seconds += gpu_seconds;
    }
}

impl From<&LaunchRecord> for KernelSummary {
    /// The summary of one launch (to compare launches one by one).
    fn from(r: &LaunchRecord) -> Self {
        let mut s = KernelSummary::default();
        s.add(r, 0.0);
        s
    }
}

#[derive(Default)]
pub(crate) struct Stats {
    /// Launches recorded since the last reset.
    total: u64,
    order: Vec<&'static str>,
    by_name: HashMap<&'static str, KernelSummary>,
    log: VecDeque<LaunchRecord>,
}

impl Stats {
    /// Adds a launch, with its predicted GPU time (0 if none).
    pub fn add(&mut self, r: &LaunchRecord, gpu_seconds: f64) {
        self.total += 1;
        if !self.by_name.contains_key(r.name) {
            self.order.push(r.name);
        }
        self.by_name.entry(r.name).or_default().add(r, gpu_seconds);
        if self.log.len() == LOG_CAPACITY {
            self.log.pop_front();
        }
        self.log.push_back(r.clone());
    }

    pub fn summaries(&self) -> Vec<KernelSummary> {
        self.order.iter().map(|n| self.by_name[n].clone()).collect()
    }

    pub fn log(&self) -> Vec<LaunchRecord> {
        self.log.iter().cloned().collect()
    }

    pub fn total(&self) -> u64 {
        self.total
    }

    /// The records of launches numbered `mark..total` that are still in the log.
    pub fn since(&self, mark: u64) -> Vec<LaunchRecord> {
        let n = (self.total.saturating_sub(mark) as usize).min(self.log.len());
        self.log.iter().skip(self.log.len() - n).cloned().collect()
    }
}

/// A plain-text table of kernel summaries (what the benches print), with a column of
/// predicted GPU time when the device had a GPU profile.
pub fn format_table(rows: &[KernelSummary]) -> String {
    let gpu = rows.iter().any(|r| r.gpu_seconds > 0.0);
    let mut s = String::new();
    let _ = write!(
        s,
        "{:<32} {:>8} {:>10} {:>8} {:>9} {:>9} {:>10}",
        "kernel", "launches", "ms", "SIMD eff", "ld s/req", "st s/req", "shared B"
    );
    let _ = writeln!(s, "{}", if gpu { format!(" {:>10}", "GPU ms") } else { String::new() });
    let opt = |x: Option<f64>, digits: usize| x.map_or("-".to_string(), |v| format!("{v:.digits$}"));
    for r in rows {
        let _ = write!(
            s,
            "{:<32} {:>8} {:>10.3} {:>8} {:>9} {:>9} {:>10}",
            r.name,
            r.launches,
            r.seconds * 1e3,
            opt(r.simd_efficiency(), 3),
            opt(r.loads.sectors_per_request(), 2),
            opt(r.stores.sectors_per_request(), 2),
            r.shared_bytes
        );
        let _ = writeln!(s, "{}", if gpu { format!(" {:>10.3}", r.gpu_seconds * 1e3) } else { String::new() });
    }
    s
}

/// The columns of [`records_to_tsv`].
const RECORD_HEADER: &str = "name\tgrid\tblock\tshared\tseconds\tmeasured\tthreads\tops_issued\tops_active\twork_issued\twork_active\tld_req\tld_sec\tld_lanes\tst_req\tst_sec\tst_lanes\tat_req\tat_sec\tat_lanes\tbarriers\tfootprint\tblock_sectors\tlongest_issued\tlongest_loads\tload_rounds\tlongest_atomics\tlongest_fences\tatomic_rounds\tfences\tlongest_fenced_sectors\tfenced_sectors\tround_repeats";

/// Columns of [`RECORD_HEADER`] that files written before them lack, newest first: the
/// sectors repeated within rounds of loads, the sectors fences waited for, the atomics
/// and fences waited for (all read as none), and load rounds (read as one per load
/// request).
const LATER_COLUMNS: &[&str] = &[
    "\tround_repeats",
    "\tlongest_fenced_sectors\tfenced_sectors",
    "\tlongest_atomics\tlongest_fences\tatomic_rounds\tfences",
    "\tload_rounds",
];

/// Launch records as tab-separated lines, one per launch, to keep a measured run and
/// predict from it later ([`crate::timing::predict`]). Declared regions are summed into
/// one region named `work`.
pub fn records_to_tsv(records: &[LaunchRecord]) -> String {
    let mut s = format!("{RECORD_HEADER}\n");
    for r in records {
        let mut work = RegionStats::default();
        r.regions.iter().for_each(|x| work.add(x));
        let t = |x: &Traffic| format!("{}\t{}\t{}", x.requests, x.sectors, x.lanes);
        let _ = writeln!(
            s,
            "{}\t{}\t{}\t{}\t{}\t{}\t{}\t{}\t{}\t{}\t{}\t{}\t{}\t{}\t{}\t{}\t{}\t{}\t{}\t{}\t{}\t{}\t{}\t{}\t{}\t{}\t{}",
            r.name,
            r.grid,
            r.block,
            r.shared_bytes,
            r.seconds,
            r.measured as u8,
            r.threads,
            r.ops.issued,
            r.ops.active,
            work.issued,
            work.active,
            t(&r.loads),
            t(&r.stores),
            t(&r.atomics),
            r.barriers,
            r.footprint_sectors,
            r.block_sectors,
            r.longest_warp.instructions,
            r.longest_warp.load_rounds,
            r.waits.load_rounds,
            r.longest_warp.atomic_rounds,
            r.longest_warp.fences,
            r.waits.atomic_rounds,
            r.waits.fences,
            r.longest_warp.fenced_sectors,
            r.waits.fenced_sectors,
            r.waits.round_repeats
        );
    }
    s
}

/// A kernel name read from a file, kept for the program's life (each distinct name
/// once).
fn intern(name: &str) -> &'static str {
    use std::sync::Mutex;
    static NAMES: Mutex<Vec<&'static str>> = Mutex::new(Vec::new());
    let mut names = NAMES.lock().unwrap_or_else(|e| e.into_inner());
    if let Some(n) = names.iter().find(|n| **n == name) {
        return n;
    }
    let n: &'static str = Box::leak(name.to_string().into_boxed_str());
    names.push(n);
    n
}

/// Reads what [`records_to_tsv`] wrote; errors name the line and field.
pub fn records_from_tsv(text: &str) -> Result<Vec<LaunchRecord>, String> {
    let mut lines = text.lines().enumerate();
    let header = match lines.next() {
        Some((_, h)) if is_record_header(h) => h,
        _ => return Err("not a simt launch-record file (its header differs)".into()),
    };
    let columns: Vec<&str> = header.split('\t').collect();
    let mut out = Vec::new();
    for (i, line) in lines {
        let f: Vec<&str> = line.split('\t').collect();
        if f.len() != columns.len() {
            return Err(format!("line {}: {} fields, expected {}", i + 1, f.len(), columns.len()));
        }
        let n = |k: usize| f[k].parse::<u64>().map_err(|_| format!("line {}: {}: '{}'", i + 1, columns[k], f[k]));
        let traffic = |k: usize| -> Result<Traffic, String> {
            Ok(Traffic { requests: n(k)?, sectors: n(k + 1)?, lanes: n(k + 2)? })
        };
        let seconds: f64 = f[4].parse().map_err(|_| format!("line {}: seconds: '{}'", i + 1, f[4]))?;
        out.push(LaunchRecord {
            name: intern(f[0]),
            grid: n(1)? as u32,
            block: n(2)? as u32,
            shared_bytes: n(3)? as usize,
            registers: 0,
            seconds,
            measured: n(5)? != 0,
            threads: n(6)?,
            ops: RegionStats { name: "ops", issued: n(7)?, active: n(8)? },
            regions: vec![RegionStats { name: "work", issued: n(9)?, active: n(10)? }],
            loads: traffic(11)?,
            stores: traffic(14)?,
            atomics: traffic(17)?,
            barriers: n(20)?,
            footprint_sectors: n(21)?,
            block_sectors: n(22)?,
            longest_warp: WarpChain {
                instructions: n(23)?,
                load_rounds: n(24)?,
                atomic_rounds: if columns.len() > 26 { n(26)? } else { 0 },
                fences: if columns.len() > 26 { n(27)? } else { 0 },
                fenced_sectors: if columns.len() > 30 { n(30)? } else { 0 },
                round_repeats: 0,
            },
            waits: WarpChain {
                instructions: n(7)? + n(9)?,
                load_rounds: if columns.len() > 25 { n(25)? } else { n(11)? },
                atomic_rounds: if columns.len() > 26 { n(28)? } else { 0 },
                fences: if columns.len() > 26 { n(29)? } else { 0 },
                fenced_sectors: if columns.len() > 30 { n(31)? } else { 0 },
                round_repeats: if columns.len() > 32 { n(32)? } else { 0 },
            },
        });
    }
    Ok(out)
}

/// The current header, or one that lacks only the [`LATER_COLUMNS`] added after it
/// was written.
fn is_record_header(h: &str) -> bool {
    let mut current = RECORD_HEADER;
    for later in std::iter::once("").chain(LATER_COLUMNS.iter().copied()) {
        match current.strip_suffix(later) {
            Some(older) => current = older,
            None => return false,
        }
        if h == current {
            return true;
        }
    }
    false
}

#[cfg(test)]
mod tests {
    use super::*;

    fn record() -> LaunchRecord {
        let t = |k: u64| Traffic { requests: k, sectors: 2 * k, lanes: 32 * k };
        LaunchRecord {
            name: "test::kernel",
            grid: 3,
            block: 64,
            shared_bytes: 128,
            registers: 0,
            seconds: 0.25,
            measured: true,
            threads: 192,
            ops: RegionStats { name: "ops", issued: 40, active: 1000 },
            regions: vec![RegionStats { name: "work", issued: 60, active: 1500 }],
            loads: t(5),
            stores: t(3),
            atomics: t(2),
            barriers: 4,
            footprint_sectors: 9,
            block_sectors: 8,
            longest_warp: WarpChain {
                instructions: 20,
                load_rounds: 3,
                atomic_rounds: 2,
                fences: 1,
                fenced_sectors: 9,
                round_repeats: 0,
            },
            waits: WarpChain {
                instructions: 100,
                load_rounds: 12,
                atomic_rounds: 7,
                fences: 5,
                fenced_sectors: 40,
                round_repeats: 11,
            },
        }
    }

    #[test]
    fn records_read_back_as_written_and_older_files_without_their_later_columns() {
        let text = records_to_tsv(&[record()]);
        let back = &records_from_tsv(&text).unwrap()[0];
        assert_eq!((back.longest_warp, back.waits), (record().longest_warp, record().waits));
        assert_eq!((back.loads, back.atomics, back.block_sectors), (record().loads, record().atomics, 8));
        // Cut the later columns off, newest first: round repeats are then none, then
        // fenced sectors, then atomics and fences, and then load rounds are one per load
        // request.
        let cut = |text: &str, columns: usize| -> String {
            text.lines().map(|l| l.split('\t').take(columns).collect::<Vec<_>>().join("\t") + "\n").collect()
        };
        let before_repeats = &records_from_tsv(&cut(&text, 32)).unwrap()[0];
        assert_eq!(before_repeats.waits, WarpChain { round_repeats: 0, ..record().waits });
        let before_fenced = &records_from_tsv(&cut(&text, 30)).unwrap()[0];
        assert_eq!(before_fenced.longest_warp, WarpChain { fenced_sectors: 0, ..record().longest_warp });
        assert_eq!(before_fenced.waits, WarpChain { fenced_sectors: 0, round_repeats: 0, ..record().waits });
        let before_atomics = &records_from_tsv(&cut(&text, 26)).unwrap()[0];
        let none = WarpChain { atomic_rounds: 0, fences: 0, fenced_sectors: 0, ..WarpChain::default() };
        assert_eq!(before_atomics.longest_warp, WarpChain { instructions: 20, load_rounds: 3, ..none });
        assert_eq!(before_atomics.waits, WarpChain { instructions: 100, load_rounds: 12, ..none });
        let before_rounds = &records_from_tsv(&cut(&text, 25)).unwrap()[0];
        assert_eq!(before_rounds.waits.load_rounds, 5);
        // Any other header is refused.
        for columns in [24, 27, 31] {
            assert!(records_from_tsv(&cut(&text, columns)).unwrap_err().contains("header differs"));
        }
    }
}
