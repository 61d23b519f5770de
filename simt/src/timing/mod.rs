//! GPU time predicted from a measured launch's counters, on a described GPU.
//!
//! A [`GpuProfile`] holds what the model needs to know of one GPU: its size (SMs, warps
//! and blocks per SM, shared memory, L2), rates (instruction issue, L1 sectors, L2 and
//! HBM bandwidth, atomics, barriers, block dispatch) and latencies (arithmetic, L2, HBM,
//! an empty launch). Profiles are text files in `simt/profiles/`, written by
//! `gpu_check calibrate` from microbenchmarks (`cuda/microbench.cu`) that are unlike the
//! kernels the model is checked on.
//!
//! [`predict`] turns one [`LaunchRecord`] into seconds: a fixed launch cost plus the
//! largest of the throughput bounds and a latency bound (a roofline with a latency
//! floor), or the larger of the memory and execution bounds plus the share of the
//! smaller that the overlap probes find not hidden, if that is more. `docs/simt.md`
//! ("Predicted GPU time") states each term and what it leaves out.

use crate::limits::{SECTOR_BYTES, WARP_SIZE};
use crate::stats::{LaunchRecord, WarpChain};

mod profile;
pub use profile::{GpuProfile, PROFILES};

/// One launch's predicted time and the terms it came from, seconds.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Prediction {
    /// The predicted duration: `launch` plus the largest bound, or the larger of memory
    /// and execution plus `exposed` if that is more.
    pub seconds: f64,
    /// The fixed cost of a launch.
    pub launch: f64,
    /// Warp instructions over the SMs' issue rate.
    pub issue: f64,
    /// Warp instructions over the SMs' rate of issue from code their instruction caches
    /// do not hold (a launch whose twin's code is at least the profile's
    /// `fetch_thrash_code_bytes`; else 0).
    pub fetch: f64,
    /// Sectors over the L1s' rate.
    pub l1: f64,
    /// Bytes of each block's distinct loaded sectors and of every written sector over
    /// L2 bandwidth.
    pub l2: f64,
    /// Footprint bytes over HBM bandwidth.
    pub hbm: f64,
    /// Atomic lanes over the atomic units' rates.
    pub atomics: f64,
    /// Warp fences over the GPU's fence rate, and the sectors they waited for over
    /// its rate of those.
    pub fences: f64,
    /// Barriers over the SMs' barrier rate.
    pub barriers: f64,
    /// Blocks over the dispatch rate.
    pub dispatch: f64,
    /// Waves of resident blocks times the mean block's slowest warp's dependent chain
    /// (the mean warp's where the records lack the blocks'), or the longest warp's
    /// chain if that is longer; for a single-pass kernel, plus its look-back's
    /// hops across the tiles.
    pub latency: f64,
    /// What the warps fail to hide of the smaller of the memory bounds' largest (L1,
    /// L2, HBM, atomics, fences) and the issue bound, or where blocks synchronise the
    /// execution bounds' largest (issue, latency, barriers, dispatch), under the larger
    /// (the profile's exposed shares).
    pub exposed: f64,
}

impl Prediction {
    /// Adds another launch's terms to these (a kernel's launches summed term by term).
    pub fn add(&mut self, o: &Prediction) {
        self.seconds += o.seconds;
        self.launch += o.launch;
        self.issue += o.issue;
        self.fetch += o.fetch;
        self.l1 += o.l1;
        self.l2 += o.l2;
        self.hbm += o.hbm;
        self.atomics += o.atomics;
        self.fences += o.fences;
        self.barriers += o.barriers;
        self.dispatch += o.dispatch;
        self.latency += o.latency;
        self.exposed += o.exposed;
    }

    /// The name of the largest bound (what limits the launch).
    pub fn bound(&self) -> &'static str {
        let terms = [
            ("issue", self.issue),
            ("fetch", self.fetch),
            ("l1", self.l1),
            ("l2", self.l2),
            ("hbm", self.hbm),
            ("atomics", self.atomics),
            ("fences", self.fences),
            ("barriers", self.barriers),
            ("dispatch", self.dispatch),
            ("latency", self.latency),
        ];
        terms.iter().fold(("launch", 0.0), |a, &t| if t.1 > a.1 { t } else { a }).0
    }
}

/// Resident blocks per SM for a launch: the least of the profile's block and warp
/// limits, what its shared memory allows, and what its registers per thread allow when
/// known (0: not known; a warp's registers are allocated 8 per thread at a time).
pub fn blocks_per_sm(p: &GpuProfile, block: u32, shared_bytes: usize, registers: u32) -> f64 {
    let warps = (block as f64 / WARP_SIZE as f64).ceil().max(1.0);
    let mut n = p.max_blocks_per_sm.min((p.max_warps_per_sm / warps).floor());
    if shared_bytes > 0 {
        n = n.min((p.shared_per_sm_bytes / shared_bytes as f64).floor());
    }
    if registers > 0 {
        let per_warp = (registers.div_ceil(8) * 8) as f64 * WARP_SIZE as f64;
        n = n.min(((p.registers_per_sm / per_warp).floor() / warps).floor());
    }
    n.max(1.0)
}

/// The L2 bandwidth a launch's sectors see: `l2_read`'s for sectors its requests fill
/// (eight 4-byte lanes a sector), `l2_scatter`'s for sectors a request touches one word
/// of, and in between by the share of the sectors' words the requests fill, from the
/// launch's lanes per sector (each lane counted as one 4-byte word, as most are).
fn l2_rate(r: &LaunchRecord, sectors: f64, p: &GpuProfile) -> f64 {
    let lanes = (r.loads.lanes + r.stores.lanes + r.atomics.lanes) as f64;
    let filled = if sectors > 0.0 { (lanes / sectors / 8.0).min(1.0) } else { 1.0 };
    let scattered = ((1.0 - filled) / (1.0 - 1.0 / 8.0)).clamp(0.0, 1.0);
    1.0 / ((1.0 - scattered) / p.l2_bytes_per_s + scattered / p.l2_scattered_bytes_per_s)
}

/// The predicted GPU time of a measured launch on `p` (an unmeasured record has no
/// counters: `None`).
pub fn predict(r: &LaunchRecord, p: &GpuProfile) -> Option<Prediction> {
    if !r.measured {
        return None;
    }
    let grid = r.grid.max(1) as f64;
    let warps_per_block = (r.block as f64 / WARP_SIZE as f64).ceil().max(1.0);
    let per_sm = blocks_per_sm(p, r.block, r.shared_bytes, r.registers);
    let sms = p.sms.min(grid);
    let waves = (grid / (p.sms * per_sm)).ceil();
    let warps = grid * warps_per_block;
    let issued = r.all_regions().issued as f64;
    let sectors = (r.loads.sectors + r.stores.sectors + r.atomics.sectors) as f64;
    let footprint = r.footprint_sectors as f64;
    let cycle = 1.0 / p.clock_hz;
    // Atomics: lanes beyond 8 per sector (the words of distinct 4-byte lanes in the
    // sectors touched) queue on one word.
    let same = (r.atomics.lanes as f64 - 8.0 * r.atomics.sectors as f64).max(0.0);
    let distinct = r.atomics.lanes as f64 - same;
    // One warp's dependent chain: each instruction waits on the one before, each round
    // of loads waits for its data (from HBM for first touches, else L2; a round is one
    // load request, or loads the kernel issues together), each atomic whose value it
    // uses for L2's answer (and HBM's for first touches), each fence for its own and
    // for the sectors beyond one that the warp wrote before it.
    // The share of waits that go to HBM: the loads' first touches over the loaded
    // sectors waited for (a sector that several loads of one round request is waited
    // for once). What only stores touched is never waited for and misses no load.
    let waited = r.loads.sectors.saturating_sub(r.waits.round_repeats) as f64;
    let miss = if waited > 0.0 { (r.loaded_footprint_sectors as f64 / waited).min(1.0) } else { 0.0 };
    let mem_latency = miss * p.hbm_latency_s + (1.0 - miss) * p.l2_latency_s;
    let atomic_latency = p.atomic_latency_s + miss * (p.hbm_latency_s - p.l2_latency_s).max(0.0);
    // What the GPU's fence throughput makes of a chain: with the launch's resident
    // warps all running such chains, each takes at least as long as their fences take
    // the GPU together, its own fences times the warps in flight. (A closed queue's
    // cycle is at least the longer of its lone cycle and the population times its
    // demand at a saturated server; a fence blocks its warp until its stores are seen.)
    // The GPU's time for a chain's fences, every SM fencing (the fences term's rates).
    let fence_time =
        |c: &WarpChain| c.fences as f64 / p.fences_per_s + c.fenced_sectors as f64 / p.fenced_sectors_per_s;
    let resident = warps.min(p.sms * per_sm * warps_per_block);
    let loaded_fences = |c: &WarpChain| resident * fence_time(c);
    let chain = |c: &WarpChain, over: f64| {
        let alone = c.instructions as f64 * p.alu_latency_cycles * cycle
            + c.load_rounds as f64 * mem_latency
            + c.atomic_rounds as f64 * atomic_latency
            + c.fences as f64 * p.fence_latency_s
            + (c.fenced_sectors as f64 - c.fences as f64).max(0.0) * p.fenced_sector_latency_s;
        alone.max(loaded_fences(c)) / over
    };
    let average = chain(&WarpChain { instructions: r.all_regions().issued, ..r.waits }, warps);
    // A block holds its slot on an SM until its slowest warp ends (resources are freed a
    // block at a time), so a wave lasts as long as its blocks' slowest warps: the mean
    // block's, where the records have them (older files: the mean warp's).
    let per_block = if r.block_chains == WarpChain::default() { 0.0 } else { chain(&r.block_chains, grid) };
    let longest = chain(&r.longest_warp, 1.0);
    // A single-pass kernel's look-back (an in-order launch): the tiles' prefixes move
    // back to front 32 tiles a hop (a warp reads 32 statuses at once), each hop one L2
    // round trip for the statuses and, where the look-back fences (a value wider than
    // its status word), the fence its publisher makes between value and status. The
    // emulated tiles run in order, so their own chains hold one hop each.
    let look_back = if r.in_order {
        let fence = if r.waits.fences > 0 { p.fence_latency_s } else { 0.0 };
        ((grid - 1.0) / WARP_SIZE as f64).ceil() * (2.0 * p.l2_latency_s + fence)
    } else {
        0.0
    };
    // Sectors that reach L2: each block's distinct loaded ones (its repeated loads hit
    // L1) and every stored or atomic one (L1 writes through).
    let written = (r.stores.sectors + r.atomics.sectors) as f64;
    let l2_sectors = if r.block_sectors > 0 { r.block_sectors as f64 + written } else { sectors };
    let mut t = Prediction {
        launch: p.launch_s,
        issue: issued / (p.issue_per_cycle_per_sm * sms) * cycle,
        fetch: if r.code_bytes > 0 && r.code_bytes as f64 >= p.fetch_thrash_code_bytes {
            issued / (p.fetch_issue_per_cycle_per_sm * sms) * cycle
        } else {
            0.0
        },
        l1: sectors / (p.l1_sectors_per_cycle_per_sm * sms) * cycle,
        l2: l2_sectors * SECTOR_BYTES as f64 / l2_rate(r, sectors, p),
        hbm: footprint * SECTOR_BYTES as f64 / p.hbm_bytes_per_s,
        atomics: distinct / p.atomics_per_s + same / p.same_address_atomics_per_s,
        fences: fence_time(&r.waits),
        barriers: r.barriers as f64 / (p.barriers_per_s_per_sm * sms),
        dispatch: grid / sms * p.block_dispatch_s,
        latency: (waves * average.max(per_block)).max(longest) + look_back,
        exposed: 0.0,
        seconds: 0.0,
    };
    // How the bounds combine (the overlap probes): a warp waiting on memory leaves the
    // SM to other warps' work only as far as they are elsewhere in the kernel. Warps
    // that run free hide most of the smaller of the memory and issue bounds under the
    // larger (the probes measured these two; a chain-bound launch keeps the larger of
    // its chain and memory). A block whose barriers hold its warps in one phase hides
    // little of the smaller of memory and execution by itself; the more blocks an SM
    // holds at once (up to its limit, as many as the grid gives it), the more.
    let largest = |b: &[f64]| b.iter().cloned().fold(0.0, f64::max);
    let memory = largest(&[t.l1, t.l2, t.hbm, t.atomics, t.fences]);
    let (execution, exposed) = if r.barriers > 0 {
        let held = (grid / p.sms).ceil().clamp(1.0, per_sm);
        let e = p.exposed_many_blocks + (p.exposed_one_block - p.exposed_many_blocks) / held;
        (largest(&[t.issue, t.fetch, t.latency, t.barriers, t.dispatch]), e)
    } else {
        (t.issue.max(t.fetch), p.exposed_free)
    };
    t.exposed = exposed * memory.min(execution);
    let bounds = [t.issue, t.fetch, t.l1, t.l2, t.hbm, t.atomics, t.fences, t.barriers, t.dispatch, t.latency];
    t.seconds = t.launch + largest(&bounds).max(memory.max(execution) + t.exposed);
    Some(t)
}

#[cfg(test)]
mod tests;
