//! Launch records and their aggregation per kernel name.

use crate::exec::WARP_SIZE;
use std::collections::{HashMap, VecDeque};
use std::fmt::Write;

/// Launch records kept in the device's log (older ones are dropped; the per-kernel
/// summaries keep counting).
pub const LOG_CAPACITY: usize = 4096;

/// Issued warp steps and active lane-steps of one region.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct RegionStats {
    pub name: &'static str,
    /// Warp steps issued (per warp, the busiest lane's units, summed over paths).
    pub issued: u64,
    /// Lane steps that did work.
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
    pub name: &'static str,
    pub grid: u32,
    pub block: u32,
    pub shared_bytes: usize,
    pub seconds: f64,
    /// Whether SIMD efficiency and memory traffic were measured.
    pub measured: bool,
    pub threads: u64,
    /// The implicit region: one step per lane phase.
    pub body: RegionStats,
    /// The regions the kernel named, in order.
    pub regions: Vec<RegionStats>,
    /// Warp-wide memory requests (loads, stores, atomics).
    pub requests: u64,
    /// Distinct 32-byte sectors those requests touched.
    pub sectors: u64,
    pub barriers: u64,
}

impl LaunchRecord {
    /// The body and every named region together.
    pub fn all_regions(&self) -> RegionStats {
        let mut all = self.body.clone();
        self.regions.iter().for_each(|r| all.add(r));
        all
    }

    /// SIMD efficiency over the body and every named region.
    pub fn simd_efficiency(&self) -> Option<f64> {
        self.all_regions().simd_efficiency()
    }

    /// Efficiency of the named region.
    pub fn region_efficiency(&self, name: &str) -> Option<f64> {
        self.regions.iter().find(|r| r.name == name).and_then(RegionStats::simd_efficiency)
    }

    /// Sectors per request: 4 for 32 coalesced 4-byte loads, 32 when fully scattered.
    pub fn sectors_per_request(&self) -> Option<f64> {
        (self.requests > 0).then(|| self.sectors as f64 / self.requests as f64)
    }
}

/// Totals of every launch of one kernel name.
#[derive(Clone, Debug, Default)]
pub struct KernelSummary {
    pub name: &'static str,
    pub launches: u64,
    pub seconds: f64,
    pub threads: u64,
    /// Launches that were measured (the efficiency and traffic figures cover these).
    pub measured_launches: u64,
    pub body: RegionStats,
    pub regions: Vec<RegionStats>,
    pub requests: u64,
    pub sectors: u64,
    /// Largest shared memory per block of any launch.
    pub shared_bytes: usize,
    pub barriers: u64,
}

impl KernelSummary {
    pub fn simd_efficiency(&self) -> Option<f64> {
        let mut all = self.body.clone();
        self.regions.iter().for_each(|r| all.add(r));
        all.simd_efficiency()
    }

    pub fn sectors_per_request(&self) -> Option<f64> {
        (self.requests > 0).then(|| self.sectors as f64 / self.requests as f64)
    }

    fn add(&mut self, r: &LaunchRecord) {
        self.name = r.name;
        self.launches += 1;
        self.seconds += r.seconds;
        self.threads += r.threads;
        self.measured_launches += r.measured as u64;
        self.body.name = "body";
        self.body.add(&r.body);
        for reg in &r.regions {
            match self.regions.iter_mut().find(|x| x.name == reg.name) {
                Some(x) => x.add(reg),
                None => self.regions.push(reg.clone()),
            }
        }
        self.requests += r.requests;
        self.sectors += r.sectors;
        self.shared_bytes = self.shared_bytes.max(r.shared_bytes);
        self.barriers += r.barriers;
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
    pub fn add(&mut self, r: &LaunchRecord) {
        self.total += 1;
        if !self.by_name.contains_key(r.name) {
            self.order.push(r.name);
        }
        self.by_name.entry(r.name).or_default().add(r);
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

/// A plain-text table of kernel summaries (what the benches print).
pub fn format_table(rows: &[KernelSummary]) -> String {
    let mut s = String::new();
    let _ = writeln!(
        s,
        "{:<32} {:>8} {:>10} {:>8} {:>9} {:>10}",
        "kernel", "launches", "ms", "SIMD eff", "sect/req", "shared B"
    );
    let opt = |x: Option<f64>, digits: usize| x.map_or("-".to_string(), |v| format!("{v:.digits$}"));
    for r in rows {
        let _ = writeln!(
            s,
            "{:<32} {:>8} {:>10.3} {:>8} {:>9} {:>10}",
            r.name,
            r.launches,
            r.seconds * 1e3,
            opt(r.simd_efficiency(), 3),
            opt(r.sectors_per_request(), 2),
            r.shared_bytes
        );
    }
    s
}
