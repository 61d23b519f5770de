//! Measurement: what the lanes of a warp actually executed, matched into warp
//! instructions, and the shared-memory race check that finds missing barriers.
//!
//! Every operation a lane performs through `simt` (global load, store, atomic, shared
//! load/store, warp intrinsic, declared work) is one *thread instruction*. Within one
//! lane phase of a warp, the n-th execution of an operation at a call site by one lane
//! is matched with the n-th execution of the same site by the other lanes: that set is
//! one *warp instruction* (issued once, executed by the lanes that reached it). This is
//! what a lockstep warp does: a lane that leaves a loop early, or takes the other arm of
//! a branch, is idle while the instruction issues for the others. SIMD efficiency is
//! thread instructions / (32 × warp instructions), Nsight Compute's
//! `smsp__thread_inst_executed_per_inst_executed` over 32.
//!
//! Global accesses are split into the accesses the hardware issues: an element of `s`
//! bytes whose alignment allows vectors of `w` bytes (the largest power of two ≤ 16
//! dividing both the size and the alignment) is `s / w` instructions of `w` bytes.
//! Each warp-level memory instruction is one *request*; the distinct 32-byte sectors its
//! lanes touch are its *sectors*. Loads, stores and atomics are kept apart.
//!
//! With a GPU profile set, it also gathers what the time model reads: a sample of the
//! sectors touched (the launch's and each block's distinct ones) and each warp's chain
//! of instructions and loads.
//!
//! About 1,000 lines on purpose: the matching of lanes into warp instructions, the
//! memory traffic, the footprints and the race check share the per-lane and per-warp
//! state kept private here.

use crate::limits::{
    MAX_PATHS, MAX_REGIONS, RETRY_TRIP_INSTRUCTIONS, SECTOR_BYTES, SECTORS_PER_LINE, WARP_SIZE, footprint_sampled,
    footprint_weight, host_sector,
};
use crate::runs::Runs;
use std::collections::HashMap;
use std::hash::{BuildHasherDefault, Hasher};

/// Requests and sectors of one kind of memory instruction.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Traffic {
    /// Warp-level memory instructions.
    pub requests: u64,
    /// Distinct 32-byte sectors per request, summed.
    pub sectors: u64,
    /// Thread-level memory instructions: the lanes that executed each request, summed
    /// (Nsight's `smsp__sass_thread_inst_executed_op_global_{ld,st}`); of a predicated
    /// store, the lanes whose predicate held. A predicated instruction with no lane on
    /// makes no request.
    pub lanes: u64,
}

impl Traffic {
    /// Sectors per request: 4 for 32 coalesced 4-byte loads, 32 when fully scattered.
    pub fn sectors_per_request(&self) -> Option<f64> {
        (self.requests > 0).then(|| self.sectors as f64 / self.requests as f64)
    }

    /// SIMD efficiency of these instructions alone: lanes over 32 × requests.
    pub fn simd_efficiency(&self) -> Option<f64> {
        (self.requests > 0).then(|| self.lanes as f64 / (32.0 * self.requests as f64))
    }

    /// Adds another record's requests, sectors and lanes to this one.
    pub fn add(&mut self, o: &Traffic) {
        self.requests += o.requests;
        self.sectors += o.sectors;
        self.lanes += o.lanes;
    }
}

/// One warp's dependent chain: what it waits for one after another (the GPU time
/// model's latency term). Ordered by instructions first, as the longest warp is chosen.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, PartialOrd, Ord)]
pub struct WarpChain {
    /// Warp instructions.
    pub instructions: u64,
    /// Load rounds: a load request is a round of its own, loads issued together
    /// ([`crate::Thread::loads_together`]) one round.
    pub load_rounds: u64,
    /// Atomics whose old value the warp waits for (`ATOMG`; reductions, `RED`, not).
    pub atomic_rounds: u64,
    /// Memory fences (`__threadfence`), each waited for.
    pub fences: u64,
    /// The sectors the warp had stored or updated atomically, not yet fenced, at each of
    /// its fences, summed: what its fences waited to see written.
    pub fenced_sectors: u64,
    /// The same as 128-byte lines: for each store or atomic instruction, the distinct
    /// lines its lanes wrote, summed over the instructions before each fence (a fence
    /// under load costs by the lines it waits for more than by their sectors:
    /// `docs/simt.md`, "Fences under load").
    pub fenced_lines: u64,
    /// Sectors a load requested that an earlier load of its round (loads issued
    /// together) had requested: a round waits once for a sector, so the share of its
    /// waits that go to HBM is taken over the sectors less these.
    pub round_repeats: u64,
}

impl WarpChain {
    /// Adds another chain's waits to this one.
    pub fn add(&mut self, o: &WarpChain) {
        self.instructions += o.instructions;
        self.load_rounds += o.load_rounds;
        self.atomic_rounds += o.atomic_rounds;
        self.fences += o.fences;
        self.fenced_sectors += o.fenced_sectors;
        self.fenced_lines += o.fenced_lines;
        self.round_repeats += o.round_repeats;
    }

    /// Raises each count to another chain's where that is larger: over a block's warps,
    /// a chain at least as long as its slowest warp's, whatever the latencies.
    pub fn most(&mut self, o: &WarpChain) {
        self.instructions = self.instructions.max(o.instructions);
        self.load_rounds = self.load_rounds.max(o.load_rounds);
        self.atomic_rounds = self.atomic_rounds.max(o.atomic_rounds);
        self.fences = self.fences.max(o.fences);
        self.fenced_sectors = self.fenced_sectors.max(o.fenced_sectors);
        self.fenced_lines = self.fenced_lines.max(o.fenced_lines);
        self.round_repeats = self.round_repeats.max(o.round_repeats);
    }
}

/// What kind of instruction an operation is.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Kind {
    Load,
    Store,
    /// An atomic whose old value the lane uses (`ATOMG`): the warp waits for it.
    Atomic,
    /// An atomic whose value is unused (`RED`): traffic like an atomic, not waited for.
    Reduce,
    /// `__threadfence`: no instruction of its own (the kernel's declared work holds its
    /// `MEMBAR`), a wait in the warp's chain.
    Fence,
    /// Shared-memory access, warp intrinsic: counted, no global traffic.
    Other,
    /// Declared work in a named region.
    Work(u8),
    /// The start of loads issued together ([`Meter::begin_together`]): no instruction,
    /// a slot that names the group.
    Together,
}

impl Kind {
    /// Atomics, waited for or not.
    pub fn is_atomic(self) -> bool {
        matches!(self, Kind::Atomic | Kind::Reduce)
    }
}

/// No group of loads issued together.
const NO_GROUP: u32 = u32::MAX;

/// Marks a kept sector as written (by a store or an atomic) in a block's sample:
/// above every sector number (addresses, host ones included, are below 2^64, so
/// sectors below 2^59).
const WRITTEN: u64 = 1 << 63;

/// Counters of one launch (or of one worker's share of it).
#[derive(Clone, Debug, Default)]
pub(crate) struct Counters {
    /// Warp instructions / thread instructions of operations (not declared work).
    pub ops_issued: u64,
    pub ops_active: u64,
    pub issued: [u64; MAX_REGIONS],
    pub active: [u64; MAX_REGIONS],
    pub loads: Traffic,
    pub stores: Traffic,
    pub atomics: Traffic,
    pub barriers: u64,
    pub threads: u64,
    /// The sampled sectors (`limits::footprint_sampled`) of global accesses, and every
    /// sector of host memory read by shared code (`limits::host_sector`), with repeats,
    /// those a store or an atomic touched marked `WRITTEN`: sorted and deduplicated
    /// when the launch is recorded.
    pub footprint: Vec<u64>,
    /// Ranges of sectors touched whole (`Meter::owned_block`), kept as runs rather
    /// than as their sampled sectors.
    pub runs: Runs,
    /// The runs of [`Counters::runs`] that were loaded.
    pub loaded_runs: Runs,
    /// Distinct loaded sectors per block, summed (estimated from the sampled ones): the
    /// loads that reach L2 when a block's repeated loads hit its SM's L1.
    pub block_sectors: u64,
    /// The warp with the most warp instructions.
    pub longest_warp: WarpChain,
    /// Every warp's chain summed.
    pub waits: WarpChain,
    /// Each block's warps' most of every count ([`WarpChain::most`]), summed over the
    /// blocks: a block holds its SM's slot until its slowest warp ends.
    pub block_chains: WarpChain,
}

impl Counters {
    pub fn merge(mut self, mut o: Counters) -> Counters {
        for r in 0..MAX_REGIONS {
            self.issued[r] += o.issued[r];
            self.active[r] += o.active[r];
        }
        self.ops_issued += o.ops_issued;
        self.ops_active += o.ops_active;
        self.loads.add(&o.loads);
        self.stores.add(&o.stores);
        self.atomics.add(&o.atomics);
        self.barriers += o.barriers;
        self.threads += o.threads;
        if self.footprint.len() < o.footprint.len() {
            std::mem::swap(&mut self.footprint, &mut o.footprint);
        }
        self.footprint.extend_from_slice(&o.footprint);
        self.runs.append(&mut o.runs);
        self.loaded_runs.append(&mut o.loaded_runs);
        self.block_sectors += o.block_sectors;
        self.longest_warp = self.longest_warp.max(o.longest_warp);
        self.waits.add(&o.waits);
        self.block_chains.add(&o.block_chains);
        self
    }

    /// Distinct sectors the launch touched, and those of them it loaded, estimated from
    /// the sampled ones and the runs (sorts the sample in place).
    pub fn footprints(&mut self) -> (u64, u64) {
        use rayon::slice::ParallelSliceMut;
        self.footprint.par_sort_unstable();
        self.footprint.dedup();
        // Loaded sectors sort before written ones (the mark is the top bit), each part
        // in order of its sectors.
        let split = self.footprint.partition_point(|&s| s & WRITTEN == 0);
        let (loaded, written) = self.footprint.split_at(split);
        let loaded_runs = self.loaded_runs.union();
        let runs = self.runs.union();
        let weigh = |set: &Runs, s: u64| if set.contains(s) { 0 } else { footprint_weight(s) };
        let loaded_sectors = loaded_runs + loaded.iter().map(|&s| weigh(&self.loaded_runs, s)).sum::<u64>();
        // Every distinct sector of both parts: a written one counts unless also loaded.
        let mut all = runs + loaded.iter().map(|&s| weigh(&self.runs, s)).sum::<u64>();
        let mut l = 0;
        for &w in written {
            let s = w & !WRITTEN;
            l += loaded[l..].partition_point(|&x| x < s);
            if loaded.get(l) != Some(&s) {
                all += weigh(&self.runs, s);
            }
        }
        (all, loaded_sectors)
    }
}

/// A warp instruction being assembled from its lanes.
struct Slot {
    kind: Kind,
    max_units: u32,
    sum_units: u64,
    /// Lanes whose predicate let them access memory (all of them unless predicated).
    on: u64,
    /// The sector this instruction recorded last: consecutive lanes of a coalesced
    /// access touch the same sector, which is then recorded once.
    last_sector: u64,
    /// For a load: the slot of the group of loads issued together it belongs to
    /// (`NO_GROUP`: none, it waits alone).
    group: u32,
}

/// Where a lane phase stands, for the race check. Sixteen bytes, so that a block's
/// shadow of its shared words stays in the CPU's cache: the counters are one meter's
/// (one worker's launch). The barrier interval never wraps (the shadow is cleared
/// first, [`Meter::next_epoch`]); the warp and lane calls would have to wrap within one
/// interval of one block, 2^32 of them between two barriers, to match a stale stamp.
#[derive(Clone, Copy, Default)]
struct Stamp {
    /// Barrier interval (a new one per block and per `sync_threads`).
    epoch: u32,
    /// One warp's run of a `for_each_warp` body.
    warp_call: u32,
    /// One `for_each_lane` within it.
    lane_call: u32,
    thread: u32,
}

impl Stamp {
    /// Whether an access stamped `self` and one stamped `o` may race: same barrier
    /// interval, different threads, and not two lane phases of one warp body (those are
    /// separated by the warp-synchronous step between them).
    fn races(&self, o: &Stamp) -> bool {
        self.epoch == o.epoch
            && self.thread != o.thread
            && !(self.warp_call == o.warp_call && self.lane_call != o.lane_call)
    }
}

#[derive(Clone, Copy, Default)]
struct Shadow {
    write: Stamp,
    read: Stamp,
}

/// A shared-memory race: the first one found in a launch.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Race {
    /// The block in which the race happened.
    pub block: u32,
    /// Byte offset in the block's shared memory.
    pub byte: usize,
    /// Thread that accessed the word first, and the one that raced with it.
    pub first: u32,
    /// The thread that raced with `first`.
    pub second: u32,
    /// "read after write", "write after read" or "write after write".
    pub hazard: &'static str,
}

/// Per-worker measurement state.
#[derive(Default)]
pub(crate) struct Meter {
    pub totals: Counters,
    /// Interned keys (call site and path) of the operations seen by this worker, and
    /// their ids.
    index: HashMap<usize, u32, BuildHasherDefault<KeyHasher>>,
    last_key: (usize, u32),
    /// Per key: executions by the current lane.
    lane_occ: Vec<u32>,
    lane_touched: Vec<u32>,
    /// Per key: first slot of each occurrence in the current warp phase.
    slot_of: Vec<Vec<u32>>,
    warp_touched: Vec<u32>,
    slots: Vec<Slot>,
    /// (slot, sector) of every global access in the current warp phase.
    sectors: Vec<(u32, u64)>,
    // Race check.
    shadow: Vec<Shadow>,
    now: Stamp,
    block: u32,
    pub race: Option<Race>,
    /// Which copy of unrolled code the current lane is in (0: none), mixed into every
    /// call site so that copies are different instructions.
    pub copy: usize,
    /// Lanes of the current block phase at each (call site, shared word, warp) retry
    /// loop.
    spins: Vec<((usize, usize, u32), u32)>,
    /// The current block's sampled sectors, with repeats.
    block_sampled: Vec<u64>,
    /// The current block's ranges of sectors loaded, and stored, whole
    /// ([`Meter::owned_block`]).
    block_loaded: Runs,
    block_written: Runs,
    /// Per warp of the current block: its chain.
    warp_chain: Vec<WarpChain>,
    /// Per warp of the current block: sectors it wrote since its last fence.
    unfenced: Vec<u64>,
    /// Per warp of the current block: lines it wrote since its last fence.
    unfenced_lines: Vec<u64>,
    /// Sectors written per slot of the closing warp phase (scratch).
    written: Vec<u64>,
    /// The same slots' distinct 128-byte lines written (scratch).
    written_lines: Vec<u64>,
    /// The group of loads issued together that the current lane is in (`NO_GROUP`).
    group: u32,
    /// The groups of a closing warp phase's loads (scratch).
    groups: Vec<u32>,
    /// The (group, sector) pairs of a closing warp phase's grouped loads (scratch).
    round_pairs: Vec<(u32, u64)>,
    /// Whether to gather footprints and warp chains (for the GPU time model).
    predicting: bool,
    /// The lane that recorded last ([`Meter::set_lane`]): the meter starts it when it
    /// differs from the lane started before.
    lane: u32,
}

impl Meter {
    /// A meter; `predicting`: it also gathers footprints and warp chains.
    pub fn new(predicting: bool) -> Meter {
        Meter { predicting, group: NO_GROUP, ..Meter::default() }
    }

    /// The current lane starts loads issued together at `site` (`Thread::loads_together`):
    /// the loads until [`Meter::end_together`] count as one round of the warp's chain.
    /// Returns the group it was in before (groups do not nest: an inner one joins the
    /// outer).
    pub fn begin_together(&mut self, site: usize) -> u32 {
        let outer = self.group;
        if outer == NO_GROUP {
            self.group = self.op(site, Kind::Together, 1, 0);
        }
        outer
    }

    /// Ends the group [`Meter::begin_together`] started; `outer` is what it returned.
    pub fn end_together(&mut self, outer: u32) {
        self.group = outer;
    }

    /// The interned id of `key`; a key repeated (a loop's one operation) skips the map.
    #[inline(always)]
    fn intern(&mut self, key: usize) -> u32 {
        if self.last_key.0 == key && !self.index.is_empty() {
            return self.last_key.1;
        }
        self.intern_new(key)
    }

    #[inline(never)]
    fn intern_new(&mut self, key: usize) -> u32 {
        let next = self.index.len() as u32;
        let id = *self.index.entry(key).or_insert(next);
        if id == next {
            self.lane_occ.push(0);
            self.slot_of.push(Vec::new());
        }
        self.last_key = (key, id);
        id
    }

    /// Records one operation of `parts` instructions by the current lane; returns the
    /// first of its slots.
    pub fn op(&mut self, site: usize, kind: Kind, parts: u32, units: u32) -> u32 {
        let site = self.salted(site);
        self.op_keyed(site.wrapping_mul(16), kind, parts, units)
    }

    /// Counts one more execution of interned key `id` by the current lane; returns how
    /// many came before it.
    fn next_occurrence(&mut self, id: usize) -> usize {
        let occ = self.lane_occ[id] as usize;
        if occ == 0 {
            self.lane_touched.push(id as u32);
        }
        self.lane_occ[id] += 1;
        occ
    }

    fn op_keyed(&mut self, key: usize, kind: Kind, parts: u32, units: u32) -> u32 {
        self.sync_lane();
        let id = self.intern(key) as usize;
        let occ = self.next_occurrence(id);
        let per_site = &mut self.slot_of[id];
        if per_site.is_empty() {
            self.warp_touched.push(id as u32);
        }
        let first = match per_site.get(occ) {
            Some(&s) => s,
            None => {
                let s = self.slots.len() as u32;
                per_site.push(s);
                for _ in 0..parts {
                    self.slots.push(Slot {
                        kind,
                        max_units: 0,
                        sum_units: 0,
                        on: 0,
                        last_sector: u64::MAX,
                        group: NO_GROUP,
                    });
                }
                s
            }
        };
        for p in 0..parts {
            let slot = &mut self.slots[(first + p) as usize];
            slot.max_units = slot.max_units.max(units);
            slot.sum_units += units as u64;
        }
        first
    }

    /// A global access of a `size`-byte element at `addr`, issued as `size / width`
    /// instructions of `width` bytes. A predicated one (`on` false for this lane) is
    /// issued with the lane active but touches no memory; a request is counted only
    /// when some lane is on.
    pub fn global(&mut self, site: usize, kind: Kind, addr: u64, size: u64, width: u64, on: bool) {
        let parts = (size / width).max(1) as u32;
        let first = self.op(site, kind, parts, 1);
        if kind == Kind::Load && self.group != NO_GROUP {
            for p in 0..parts {
                self.slots[(first + p) as usize].group = self.group;
            }
        }
        if !on {
            return;
        }
        for p in 0..parts as u64 {
            let a = addr + p * width;
            let slot = first + p as u32;
            self.slots[slot as usize].on += 1;
            for sector in a / SECTOR_BYTES..=(a + width - 1) / SECTOR_BYTES {
                // Repeats of the slot's last sector are left out here; the rest are
                // deduplicated when the phase closes.
                let last = &mut self.slots[slot as usize].last_sector;
                if *last != sector {
                    *last = sector;
                    self.sectors.push((slot, sector));
                }
            }
        }
    }

    /// What [`Meter::global`] records for the `lanes` threads of a block that each
    /// access their own element of one array, thread `k` element `k` at
    /// `addr + k · size`, each warp in one lane phase, counted for the whole block at
    /// once: per warp, `size / width` instructions, each one request of every lane of
    /// the warp, and the distinct sectors its lanes touch (ascending with the lane, so
    /// a sector is new exactly when it lies past the last one counted).
    pub fn owned_block(&mut self, kind: Kind, addr: u64, lanes: u32, size: u64, width: u64) {
        if lanes == 0 {
            return;
        }
        let parts = (size / width).max(1);
        let warps = lanes.div_ceil(WARP_SIZE) as usize;
        let warp_lanes = |w: usize| (lanes - w as u32 * WARP_SIZE).min(WARP_SIZE) as u64;
        let sectors: u64 = (0..warps)
            .map(|w| {
                let (first, count) = (addr + (w as u64 * WARP_SIZE as u64) * size, warp_lanes(w));
                if parts == 1 && width == size {
                    // Whole elements side by side: one contiguous byte range.
                    (first + count * size - 1) / SECTOR_BYTES - first / SECTOR_BYTES + 1
                } else {
                    // Part `p` of every lane's element: `width` bytes every `size` bytes.
                    (0..parts)
                        .map(|p| {
                            let (mut sectors, mut last) = (0, None);
                            for lane in 0..count {
                                let a = first + lane * size + p * width;
                                let (lo, hi) = (a / SECTOR_BYTES, (a + width - 1) / SECTOR_BYTES);
                                let from = last.map_or(lo, |l: u64| lo.max(l + 1));
                                if hi >= from {
                                    sectors += hi - from + 1;
                                    last = Some(hi);
                                }
                            }
                            sectors
                        })
                        .sum::<u64>()
                }
            })
            .sum();
        if self.predicting {
            // Every sector of the lanes' elements is touched (by some part).
            let (lo, hi) = (addr / SECTOR_BYTES, (addr + lanes as u64 * size - 1) / SECTOR_BYTES);
            let runs = if kind == Kind::Load { &mut self.block_loaded } else { &mut self.block_written };
            runs.join(lo, hi);
            // Each warp's chain gains the instructions and, for loads, as many rounds.
            let rounds = if kind == Kind::Load { parts } else { 0 };
            if self.warp_chain.len() < warps {
                self.warp_chain.resize(warps, WarpChain::default());
            }
            for c in &mut self.warp_chain[..warps] {
                c.instructions += parts;
                c.load_rounds += rounds;
            }
            self.totals.waits.instructions += parts * warps as u64;
            self.totals.waits.load_rounds += rounds * warps as u64;
        }
        self.totals.ops_issued += parts * warps as u64;
        self.totals.ops_active += parts * lanes as u64;
        let traffic = match kind {
            Kind::Load => &mut self.totals.loads,
            Kind::Store => &mut self.totals.stores,
            _ => &mut self.totals.atomics,
        };
        traffic.requests += parts * warps as u64;
        traffic.sectors += sectors;
        traffic.lanes += parts * lanes as u64;
    }

    /// Keeps a sector for the block's (and so the launch's) footprint if it is sampled;
    /// `written`: by a store or an atomic (marked, so that the block's distinct sectors
    /// count its loads only).
    #[inline]
    fn sample(&mut self, sector: u64, written: bool) {
        if self.predicting && (host_sector(sector) || footprint_sampled(sector)) {
            self.block_sampled.push(sector | if written { WRITTEN } else { 0 });
        }
    }

    /// Adds one warp phase's chain to its warp's in this block, and its waits to the
    /// launch's.
    fn chain(&mut self, phase: WarpChain) {
        if !self.predicting || phase == WarpChain::default() {
            return;
        }
        self.totals.waits.add(&phase);
        let warp = (self.now.thread / WARP_SIZE) as usize;
        if self.warp_chain.len() <= warp {
            self.warp_chain.resize(warp + 1, WarpChain::default());
        }
        self.warp_chain[warp].add(&phase);
    }

    /// Closes the current block: its distinct sectors and its longest warp go into the
    /// totals. Called when the next block begins and by [`Meter::finish`].
    pub fn close_block(&mut self) {
        if !self.block_loaded.is_empty() {
            self.totals.block_sectors += self.block_loaded.union();
        }
        if !self.block_sampled.is_empty() {
            self.block_sampled.sort_unstable();
            self.block_sampled.dedup();
            // Loaded sectors sort before written ones (the mark is the top bit).
            let loaded = self.block_sampled.partition_point(|&s| s & WRITTEN == 0);
            let runs = &self.block_loaded;
            self.totals.block_sectors += self.block_sampled[..loaded]
                .iter()
                .filter(|&&s| !runs.contains(s))
                .map(|&s| footprint_weight(s))
                .sum::<u64>();
            // The launch's footprint gathers each block's distinct samples, loaded or
            // written (marked).
            self.totals.footprint.extend_from_slice(&self.block_sampled);
            self.block_sampled.clear();
        }
        if !self.block_written.is_empty() {
            self.block_written.union();
        }
        for run in self.block_loaded.iter() {
            self.totals.runs.add(*run);
            self.totals.loaded_runs.add(*run);
        }
        for run in self.block_written.iter() {
            self.totals.runs.add(*run);
        }
        self.block_loaded.clear();
        self.block_written.clear();
        let mut block = WarpChain::default();
        for c in self.warp_chain.drain(..) {
            self.totals.longest_warp = self.totals.longest_warp.max(c);
            block.most(&c);
        }
        self.totals.block_chains.add(&block);
        self.unfenced.clear();
        self.unfenced_lines.clear();
    }

    /// The launch's counters from this worker, its last block closed.
    pub fn finish(mut self) -> (Counters, Option<Race>) {
        self.close_block();
        (self.totals, self.race)
    }

    /// A call site inside copy `self.copy` of unrolled code.
    fn salted(&self, site: usize) -> usize {
        site ^ self.copy.wrapping_mul(0x9e37_79b9_7f4a_7c15u64 as usize)
    }

    /// A lane enters a compare-and-swap retry loop on shared word `word`, as nvcc
    /// compiles a 64-bit shared `atomicAdd` for sm_90: each trip loads the word and
    /// tries to swap in the sum (two shared-memory instructions). Counted when the
    /// block's warps have all run ([`Meter::end_spins`]).
    pub fn spin(&mut self, site: usize, word: usize) {
        self.sync_lane();
        let key = (self.salted(site), word, self.now.thread / WARP_SIZE);
        match self.spins.iter_mut().find(|(k, _)| *k == key) {
            Some((_, n)) => *n += 1,
            None => self.spins.push((key, 1)),
        }
    }

    /// Counts the retry loops of [`Meter::spin`] once every warp of the block has run
    /// them. One lane of the whole block succeeds per round on a word, and the warps
    /// take turns (the order the H100 showed: 124.8 trips per warp for 128-thread blocks
    /// of 32 lanes on one word, `docs/gpu-check.md`): with `w` warps at one (call site,
    /// word), the `k`-th of a warp's lanes there succeeds after `k·w + p + 1` trips, `p`
    /// being the warp's position among the `w`. A warp issues each trip once for all its
    /// lanes still trying, whatever their words: as many trips as its slowest lane, each
    /// [`RETRY_TRIP_INSTRUCTIONS`] instructions.
    pub fn end_spins(&mut self) {
        if self.spins.is_empty() {
            return;
        }
        self.spins.sort_unstable();
        // (site, warp) → (trips of its slowest lane, trips of all its lanes).
        let mut per_warp: Vec<((usize, u32), u64, u64)> = Vec::new();
        let mut i = 0;
        while i < self.spins.len() {
            let (site, word, _) = self.spins[i].0;
            let j = i + self.spins[i..].iter().take_while(|((s, w, _), _)| (*s, *w) == (site, word)).count();
            let w = (j - i) as u64;
            for (p, &((_, _, warp), n)) in self.spins[i..j].iter().enumerate() {
                let (n, p) = (n as u64, p as u64);
                per_warp.push(((site, warp), (n - 1) * w + p + 1, w * n * (n - 1) / 2 + n * (p + 1)));
            }
            i = j;
        }
        per_warp.sort_unstable();
        for chunk in per_warp.chunk_by(|a, b| a.0 == b.0) {
            let trips = chunk.iter().map(|c| c.1).max().unwrap_or(0);
            let lanes: u64 = chunk.iter().map(|c| c.2).sum();
            // The loop's instructions, each trip.
            self.totals.ops_issued += RETRY_TRIP_INSTRUCTIONS * trips;
            self.totals.ops_active += RETRY_TRIP_INSTRUCTIONS * lanes;
        }
        self.spins.clear();
    }

    /// The current lane enters scope `site` (a call or loop of code that runs a varying
    /// number of times): the copy it runs in from now on is told by the site and by how
    /// many times this lane entered it before, so the lanes' n-th entries are matched
    /// with each other, whatever each did in its earlier ones. Returns the copy it was in.
    pub fn enter_scope(&mut self, site: usize) -> usize {
        self.sync_lane();
        let key = self.salted(site).wrapping_mul(16) + 1;
        let id = self.intern(key) as usize;
        let occ = self.next_occurrence(id);
        self.enter_copy(key ^ (occ + 1).wrapping_mul(0x2545_f491))
    }

    /// Enters copy `copy` of code, nested in the current one; returns the copy it was in.
    pub fn enter_copy(&mut self, copy: usize) -> usize {
        let outer = self.copy;
        self.copy = outer.wrapping_mul(31).wrapping_add(copy + 1);
        outer
    }

    pub fn work(&mut self, site: usize, region: usize, path: usize, units: u32) {
        let site = self.salted(site);
        if units > 0 {
            // Paths of one site are distinct instructions (arms of a branch).
            self.op_keyed(site.wrapping_mul(16) + 8 + path % MAX_PATHS, Kind::Work(region as u8), 1, units);
        }
    }

    pub fn begin_block(&mut self, block: u32, shared_words: usize) {
        self.close_block();
        self.block = block;
        if self.shadow.len() < shared_words {
            self.shadow.resize(shared_words, Shadow::default());
        }
        self.next_epoch();
    }

    /// A new barrier interval. Before its counter would wrap, every stamp is cleared
    /// and counting starts again: a stamp of an older interval races with nothing
    /// after it, and neither does a cleared one (interval 0, never current).
    fn next_epoch(&mut self) {
        if self.now.epoch == u32::MAX {
            self.shadow.fill(Shadow::default());
            self.now.epoch = 0;
        }
        self.now.epoch += 1;
    }

    /// A warp-wide operation (ballot, shuffle) executed by `lanes` lanes.
    pub fn warp_op(&mut self, lanes: u32) {
        self.totals.ops_issued += 1;
        self.totals.ops_active += lanes as u64;
    }

    pub fn barrier(&mut self) {
        self.totals.barriers += 1;
        self.next_epoch();
    }

    pub fn begin_warp_call(&mut self) {
        self.now.warp_call = self.now.warp_call.wrapping_add(1);
    }

    pub fn begin_lane_phase(&mut self) {
        self.now.lane_call = self.now.lane_call.wrapping_add(1);
    }

    pub fn begin_lane(&mut self, thread: u32) {
        self.now.thread = thread;
        self.lane = thread;
        for &id in &self.lane_touched {
            self.lane_occ[id as usize] = 0;
        }
        self.lane_touched.clear();
    }

    /// Sets the lane running now without starting it: every record names its lane
    /// (the thread's own index, `exec::meter_of`), so a launch whose lanes mostly
    /// record nothing of their own (`Device::transform`) sets none, and a lane is
    /// started ([`Meter::begin_lane`]) only if it records. A lane left
    /// set as current from an earlier warp phase or block starts with stale occurrence
    /// counts only if it is the first to record in its phase, where the phase's slots
    /// are still empty and are taken in order whatever the counts.
    #[inline(always)]
    pub fn set_lane(&mut self, thread: u32) {
        self.lane = thread;
    }

    /// Starts the lane [`Meter::set_lane`] set, if it is not the current one.
    #[inline(always)]
    fn sync_lane(&mut self) {
        if self.lane != self.now.thread {
            self.begin_lane(self.lane);
        }
    }

    /// A shared-memory access of words `first..first + n` by the current lane.
    pub fn shared(&mut self, first: usize, n: usize, write: bool) {
        self.sync_lane();
        let now = self.now;
        let words = &mut self.shadow[first..first + n];
        // The words' own checks first, the report (rare) after.
        let found = if write {
            let mut found = None;
            for (k, s) in words.iter_mut().enumerate() {
                if found.is_none() {
                    if s.read.races(&now) {
                        found = Some((k, "write after read", s.read.thread));
                    } else if s.write.races(&now) {
                        found = Some((k, "write after write", s.write.thread));
                    }
                }
                s.write = now;
            }
            found
        } else {
            let mut found = None;
            for (k, s) in words.iter_mut().enumerate() {
                if found.is_none() && s.write.races(&now) {
                    found = Some((k, "read after write", s.write.thread));
                }
                s.read = now;
            }
            found
        };
        if let Some((k, hazard, first_thread)) = found
            && self.race.is_none()
        {
            let byte = (first + k) * 4;
            self.race = Some(Race { block: self.block, byte, first: first_thread, second: now.thread, hazard });
        }
    }

    /// Closes a lane phase of a warp: its warp instructions go into the totals.
    pub fn end_warp_phase(&mut self) {
        if self.slots.is_empty() {
            // Nothing recorded: no instruction, access or wait to add.
            debug_assert!(self.sectors.is_empty() && self.warp_touched.is_empty());
            return;
        }
        let mut phase = WarpChain::default();
        for s in &self.slots {
            phase.instructions += s.max_units as u64;
            match s.kind {
                Kind::Load if s.on > 0 => {
                    if s.group == NO_GROUP {
                        phase.load_rounds += 1;
                    } else if self.predicting {
                        self.groups.push(s.group);
                    }
                }
                Kind::Atomic if s.on > 0 => phase.atomic_rounds += 1,
                Kind::Fence => phase.fences += 1,
                _ => {}
            }
            match s.kind {
                Kind::Work(r) => {
                    self.totals.issued[r as usize] += s.max_units as u64;
                    self.totals.active[r as usize] += s.sum_units;
                }
                k => {
                    self.totals.ops_issued += s.max_units as u64;
                    self.totals.ops_active += s.sum_units;
                    let traffic = match k {
                        Kind::Load => &mut self.totals.loads,
                        Kind::Store => &mut self.totals.stores,
                        Kind::Atomic | Kind::Reduce => &mut self.totals.atomics,
                        _ => continue,
                    };
                    if s.on > 0 {
                        traffic.requests += 1;
                        traffic.lanes += s.on;
                    }
                }
            }
        }
        if self.predicting {
            self.written.clear();
            self.written.resize(self.slots.len(), 0);
            self.written_lines.clear();
            self.written_lines.resize(self.slots.len(), 0);
        }
        if !self.sectors.is_empty() {
            if !self.sectors.is_sorted() {
                self.sectors.sort_unstable();
            }
            self.sectors.dedup();
            if self.predicting {
                // A sector requested by several loads of one round is waited for once.
                for &(slot, sector) in &self.sectors {
                    let s = &self.slots[slot as usize];
                    if s.kind == Kind::Load && s.group != NO_GROUP {
                        self.round_pairs.push((s.group, sector));
                    }
                }
                if !self.round_pairs.is_empty() {
                    let all = self.round_pairs.len();
                    self.round_pairs.sort_unstable();
                    self.round_pairs.dedup();
                    phase.round_repeats += (all - self.round_pairs.len()) as u64;
                    self.round_pairs.clear();
                }
            }
            for i in 0..self.sectors.len() {
                let (slot, sector) = self.sectors[i];
                self.sample(sector, self.slots[slot as usize].kind != Kind::Load);
            }
            // Sorted by slot, then sector: a slot's sectors of one line are neighbours.
            let mut last_line = (u32::MAX, u64::MAX);
            for &(slot, sector) in &self.sectors {
                match self.slots[slot as usize].kind {
                    Kind::Load => self.totals.loads.sectors += 1,
                    Kind::Store => self.totals.stores.sectors += 1,
                    _ => self.totals.atomics.sectors += 1,
                }
                if self.predicting && self.slots[slot as usize].kind != Kind::Load {
                    self.written[slot as usize] += 1;
                    let line = (slot, sector / SECTORS_PER_LINE);
                    if line != last_line {
                        self.written_lines[slot as usize] += 1;
                        last_line = line;
                    }
                }
            }
            self.sectors.clear();
        }
        if self.predicting {
            // Each fence waits for the sectors the warp wrote before it (slots are in the
            // order the warp's first lanes reached them), since its previous fence.
            let warp = (self.now.thread / WARP_SIZE) as usize;
            if self.unfenced.len() <= warp {
                self.unfenced.resize(warp + 1, 0);
                self.unfenced_lines.resize(warp + 1, 0);
            }
            let (mut pending, mut pending_lines) = (self.unfenced[warp], self.unfenced_lines[warp]);
            for ((s, &w), &l) in self.slots.iter().zip(&self.written).zip(&self.written_lines) {
                if s.kind == Kind::Fence {
                    phase.fenced_sectors += pending;
                    phase.fenced_lines += pending_lines;
                    (pending, pending_lines) = (0, 0);
                } else {
                    pending += w;
                    pending_lines += l;
                }
            }
            self.unfenced[warp] = pending;
            self.unfenced_lines[warp] = pending_lines;
        }
        for &id in &self.warp_touched {
            self.slot_of[id as usize].clear();
        }
        self.warp_touched.clear();
        self.slots.clear();
        if !self.groups.is_empty() {
            self.groups.sort_unstable();
            self.groups.dedup();
            phase.load_rounds += self.groups.len() as u64;
            self.groups.clear();
        }
        self.chain(phase);
    }
}

/// Hasher of interned keys: they are code addresses mixed with copies, so one
/// multiply spreads them well enough (and much faster than SipHash).
#[derive(Default)]
pub(crate) struct KeyHasher(u64);

impl Hasher for KeyHasher {
    fn finish(&self) -> u64 {
        self.0
    }
    fn write(&mut self, bytes: &[u8]) {
        for &b in bytes {
            self.0 = (self.0 ^ b as u64).wrapping_mul(0x100_0000_01b3);
        }
    }
    fn write_usize(&mut self, n: usize) {
        let h = (n as u64).wrapping_mul(0x9e37_79b9_7f4a_7c15);
        self.0 = h ^ (h >> 32);
    }
}

#[cfg(test)]
mod tests {
    use super::Meter;

    /// The barrier interval's counter wraps to where it started: the stamps of before
    /// must not race with the accesses after (the shadow is cleared), and a race after
    /// the wrap is still found.
    #[test]
    fn the_race_check_survives_its_interval_counter_wrapping() {
        let mut m = Meter::new(false);
        m.begin_block(0, 4);
        m.begin_lane(1);
        m.shared(0, 1, true);
        m.now.epoch = u32::MAX;
        m.barrier();
        m.begin_lane(2);
        m.shared(0, 1, false);
        assert!(m.race.is_none(), "a write of an interval before the wrap read as racing: {:?}", m.race);
        m.begin_lane(3);
        m.shared(1, 1, true);
        m.begin_lane(4);
        m.shared(1, 1, false);
        let race = m.race.expect("a read after another lane's write in one interval");
        assert_eq!((race.byte, race.first, race.second, race.hazard), (4, 3, 4, "read after write"));
    }
}
