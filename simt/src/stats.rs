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
    /// ([`crate::LaunchConfig::registers`]; record files older than their `registers` column
    /// read back 0).
    pub registers: u32,
    /// Bytes of the compiled code of the kernel's GPU twin, 0 when not known
    /// ([`crate::LaunchConfig::code_bytes`]).
    pub code_bytes: u32,
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
    /// Distinct sectors the launch's loads touched (estimated likewise; 0 when
    /// unmeasured): the first touches its loads wait for HBM on, where the footprint
    /// also holds what only stores and atomics touched.
    pub loaded_footprint_sectors: u64,
    /// Distinct loaded sectors per block, summed (estimated likewise): the loads that
    /// reach L2 if each block's repeated loads hit L1 (stores and atomics reach L2
    /// every time; [`LaunchRecord::stores`] and [`LaunchRecord::atomics`] count them).
    pub block_sectors: u64,
    /// The chain of the warp that issued the most instructions.
    pub longest_warp: WarpChain,
    /// Every warp's chain summed: what the warps wait for one after another (load
    /// rounds, atomics whose value they use, fences). 0 when unmeasured.
    pub waits: WarpChain,
    /// Each block's slowest warp's chain (its warps' most of every count), summed over
    /// the blocks: how long the blocks hold their SMs' slots, since a block's slot is
    /// freed only when all its warps end. 0 when unmeasured or read from a file written
    /// before it was counted.
    pub block_chains: WarpChain,
    /// Whether the blocks were started in index order, each waiting for the one before
    /// it to publish ([`crate::Device::launch_in_order`]): a single-pass kernel.
    pub in_order: bool,
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
