//! How a block runs: warp by warp, lane by lane, in phases separated by barriers.
//!
//! A kernel is a function of a [`Block`]. It claims shared memory and per-thread
//! registers, then runs *phases*: [`Block::for_each_thread`] (or [`Block::for_each_warp`])
//! runs one piece of code for every thread of the block, warp by warp, before the next
//! phase starts — so consecutive phases are separated by a barrier, which is what
//! `__syncthreads()` guarantees on a GPU. [`Block::sync_threads`] marks the barrier
//! (and counts it). Warp intrinsics (`ballot`, `shfl_down`, …) are warp-level
//! operations on per-lane values between lane phases, see [`Warp`].
//!
//! Measurement (when on) follows what a lockstep warp would issue:
//! * SIMD efficiency: kernels report work with [`Thread::work`]`(region, path, units)`.
//!   For each warp, each (region, path) issues as many steps as its busiest lane
//!   needs; active lane-steps are the sum over lanes. Two paths of a branch are issued
//!   one after the other, so a warp split evenly between two equal paths runs at 0.5.
//!   Every lane phase also counts one step in the implicit `body` region (partial warps
//!   lower it).
//! * Memory: each load, store or atomic through a [`Thread`] is matched with the same
//!   call site's same occurrence in the other lanes of the warp (one warp-wide request);
//!   the distinct 32-byte sectors they touch are counted (coalescing).

use crate::memory::{DeviceCopy, GlobalMut, Readable, read_words, words, write_words};
use std::cell::{Cell, RefCell};
use std::marker::PhantomData;
use std::panic::Location;
use std::sync::atomic::Ordering::Relaxed;

/// Threads in a warp.
pub const WARP_SIZE: u32 = 32;
/// Regions a kernel may name for SIMD accounting.
pub const MAX_REGIONS: usize = 8;
/// Paths (branch arms) per region.
pub const MAX_PATHS: usize = 8;
/// Per-thread register file, in 32-bit words (CUDA allows 255 registers; 64 words
/// keep the emulator's per-block scratch small).
pub const REGISTER_WORDS_PER_THREAD: usize = 64;
/// Bytes in one memory sector.
pub const SECTOR_BYTES: u64 = 32;

/// A typed array in a block's shared memory (from [`Block::shared`]).
#[derive(Debug)]
pub struct Shared<T> {
    offset: u32,
    len: u32,
    _t: PhantomData<fn() -> T>,
}
impl<T> Clone for Shared<T> {
    fn clone(&self) -> Self {
        *self
    }
}
impl<T> Copy for Shared<T> {}
impl<T> Shared<T> {
    pub fn len(&self) -> usize {
        self.len as usize
    }
    pub fn is_empty(&self) -> bool {
        self.len == 0
    }
}

/// One value per thread kept across phases, like a register (from [`Block::local`]).
#[derive(Debug)]
pub struct Local<T> {
    offset: u32,
    _t: PhantomData<fn() -> T>,
}
impl<T> Clone for Local<T> {
    fn clone(&self) -> Self {
        *self
    }
}
impl<T> Copy for Local<T> {}

/// Counters of one launch (or of one worker's share of it).
#[derive(Clone, Debug, Default)]
pub(crate) struct Counters {
    pub issued: [u64; MAX_REGIONS],
    pub active: [u64; MAX_REGIONS],
    pub body_issued: u64,
    pub body_active: u64,
    pub requests: u64,
    pub sectors: u64,
    pub barriers: u64,
    pub threads: u64,
}

impl Counters {
    pub fn merge(mut self, o: Counters) -> Counters {
        for r in 0..MAX_REGIONS {
            self.issued[r] += o.issued[r];
            self.active[r] += o.active[r];
        }
        self.body_issued += o.body_issued;
        self.body_active += o.body_active;
        self.requests += o.requests;
        self.sectors += o.sectors;
        self.barriers += o.barriers;
        self.threads += o.threads;
        self
    }
}

/// Per-worker measurement state.
#[derive(Default)]
pub(crate) struct Meter {
    pub totals: Counters,
    lane_units: [[u32; MAX_PATHS]; MAX_REGIONS],
    lane_used: bool,
    warp_max: [[u32; MAX_PATHS]; MAX_REGIONS],
    warp_sum: [[u64; MAX_PATHS]; MAX_REGIONS],
    /// (site, occurrence, sector) of every access in the current warp phase.
    accesses: Vec<(usize, u32, u64)>,
    /// Per-site occurrence counters of the current lane.
    lane_sites: Vec<(usize, u32)>,
}

impl Meter {
    fn begin_lane(&mut self) {
        self.lane_sites.clear();
    }

    fn end_lane(&mut self) {
        if !self.lane_used {
            return;
        }
        for r in 0..MAX_REGIONS {
            for p in 0..MAX_PATHS {
                let u = self.lane_units[r][p];
                if u > 0 {
                    self.warp_max[r][p] = self.warp_max[r][p].max(u);
                    self.warp_sum[r][p] += u as u64;
                }
            }
        }
        self.lane_units = Default::default();
        self.lane_used = false;
    }

    fn end_warp(&mut self, lanes: u32) {
        self.totals.body_issued += 1;
        self.totals.body_active += lanes as u64;
        for r in 0..MAX_REGIONS {
            for p in 0..MAX_PATHS {
                self.totals.issued[r] += self.warp_max[r][p] as u64;
                self.totals.active[r] += self.warp_sum[r][p];
            }
        }
        self.warp_max = Default::default();
        self.warp_sum = Default::default();
        if !self.accesses.is_empty() {
            self.accesses.sort_unstable();
            let mut last_req = None;
            let mut last_sec = None;
            for &(site, occ, sector) in &self.accesses {
                if last_req != Some((site, occ)) {
                    self.totals.requests += 1;
                    last_req = Some((site, occ));
                }
                if last_sec != Some((site, occ, sector)) {
                    self.totals.sectors += 1;
                    last_sec = Some((site, occ, sector));
                }
            }
            self.accesses.clear();
        }
    }

    fn record(&mut self, site: usize, addr: u64, bytes: u64) {
        let occ = match self.lane_sites.iter_mut().find(|(s, _)| *s == site) {
            Some((_, n)) => {
                *n += 1;
                *n
            }
            None => {
                self.lane_sites.push((site, 0));
                0
            }
        };
        for sector in addr / SECTOR_BYTES..=(addr + bytes.max(1) - 1) / SECTOR_BYTES {
            self.accesses.push((site, occ, sector));
        }
    }
}

/// Scratch one rayon worker reuses for the blocks it runs.
pub(crate) struct Worker {
    pub shared: Vec<Cell<u32>>,
    pub regs: Vec<Cell<u32>>,
    pub meter: RefCell<Meter>,
}

impl Worker {
    pub fn new(shared_words: usize) -> Worker {
        Worker { shared: vec![Cell::new(0); shared_words], regs: Vec::new(), meter: RefCell::new(Meter::default()) }
    }
}

/// One block of a launch, as the kernel sees it.
pub struct Block<'w> {
    block_idx: u32,
    block_dim: u32,
    grid_dim: u32,
    measure: bool,
    worker: &'w mut Worker,
    shared_words: usize,
    shared_used: usize,
    regs_used: usize,
}

impl<'w> Block<'w> {
    pub(crate) fn new(
        worker: &'w mut Worker,
        block_idx: u32,
        block_dim: u32,
        grid_dim: u32,
        shared_words: usize,
        measure: bool,
    ) -> Self {
        // Shared memory starts zeroed in every block, so results never depend on which
        // block ran before on this worker.
        worker.shared[..shared_words].iter().for_each(|c| c.set(0));
        Block { block_idx, block_dim, grid_dim, measure, worker, shared_words, shared_used: 0, regs_used: 0 }
    }

    pub fn block_idx(&self) -> u32 {
        self.block_idx
    }
    pub fn block_dim(&self) -> u32 {
        self.block_dim
    }
    pub fn grid_dim(&self) -> u32 {
        self.grid_dim
    }
    /// Warps in this block (the last may be partial).
    pub fn warp_count(&self) -> u32 {
        self.block_dim.div_ceil(WARP_SIZE)
    }

    /// Claims `n` elements of shared memory (zeroed). Panics if the launch declared less
    /// shared memory than the kernel claims: declare it in [`crate::LaunchConfig`].
    pub fn shared<T: DeviceCopy>(&mut self, n: usize) -> Shared<T> {
        let need = n * words::<T>();
        assert!(
            self.shared_used + need <= self.shared_words,
            "kernel claims {} bytes of shared memory but its launch declared {}",
            (self.shared_used + need) * 4,
            self.shared_words * 4
        );
        let s = Shared { offset: self.shared_used as u32, len: n as u32, _t: PhantomData };
        self.shared_used += need;
        s
    }

    /// One register of type `T` per thread, set to `init`.
    pub fn local<T: DeviceCopy>(&mut self, init: T) -> Local<T> {
        let w = words::<T>();
        assert!(
            self.regs_used + w <= REGISTER_WORDS_PER_THREAD,
            "kernel needs more than {REGISTER_WORDS_PER_THREAD} register words per thread"
        );
        let offset = self.regs_used;
        self.regs_used += w;
        let needed = REGISTER_WORDS_PER_THREAD * self.block_dim as usize;
        if self.worker.regs.len() < needed {
            self.worker.regs.resize(needed, Cell::new(0));
        }
        let l = Local { offset: offset as u32, _t: PhantomData };
        let src = &init as *const T as *const u32;
        for t in 0..self.block_dim as usize {
            for k in 0..w {
                // SAFETY: T is DeviceCopy: whole words, no padding.
                self.worker.regs[t * REGISTER_WORDS_PER_THREAD + offset + k].set(unsafe { src.add(k).read() });
            }
        }
        l
    }

    /// A barrier between phases (`__syncthreads()`). Phases already run one after the
    /// other; this marks the point and counts it.
    pub fn sync_threads(&mut self) {
        self.worker.meter.get_mut().totals.barriers += 1;
    }

    /// Runs `f` for every thread of the block, warp by warp.
    pub fn for_each_thread(&mut self, mut f: impl FnMut(&Thread)) {
        self.for_each_warp(|w| w.for_each_lane(&mut f));
    }

    /// Runs `f` for every warp of the block, in order.
    pub fn for_each_warp(&mut self, mut f: impl FnMut(&mut Warp)) {
        for warp_idx in 0..self.warp_count() {
            let lanes = (self.block_dim - warp_idx * WARP_SIZE).min(WARP_SIZE);
            let mut w = Warp { warp_idx, lanes, block: self };
            f(&mut w);
        }
    }
}

/// One warp of a block: runs lane phases and the warp intrinsics between them.
/// Per-lane values are `[T; 32]` arrays indexed by lane; lanes past [`Warp::lane_count`]
/// (in a partial last warp) are inactive.
pub struct Warp<'b, 'w> {
    warp_idx: u32,
    lanes: u32,
    block: &'b Block<'w>,
}

impl Warp<'_, '_> {
    pub fn warp_idx(&self) -> u32 {
        self.warp_idx
    }
    /// Active lanes (32 except in a partial last warp).
    pub fn lane_count(&self) -> u32 {
        self.lanes
    }
    fn active_mask(&self) -> u32 {
        if self.lanes == 32 { u32::MAX } else { (1u32 << self.lanes) - 1 }
    }

    /// Runs `f` for each active lane, in lane order: one lockstep step sequence.
    pub fn for_each_lane(&mut self, mut f: impl FnMut(&Thread)) {
        let b = self.block;
        let meter = &b.worker.meter;
        for lane in 0..self.lanes {
            if b.measure {
                meter.borrow_mut().begin_lane();
            }
            let t = Thread {
                thread_idx: self.warp_idx * WARP_SIZE + lane,
                block_idx: b.block_idx,
                block_dim: b.block_dim,
                grid_dim: b.grid_dim,
                measure: b.measure,
                shared: &b.worker.shared[..b.shared_words],
                regs: &b.worker.regs,
                meter,
            };
            f(&t);
            if b.measure {
                meter.borrow_mut().end_lane();
            }
        }
        let mut m = meter.borrow_mut();
        m.totals.threads += self.lanes as u64;
        if b.measure {
            m.end_warp(self.lanes);
        }
    }

    /// Per-lane values computed by `f(lane)` for the active lanes (`T::default()` elsewhere).
    pub fn lanes<T: Copy + Default>(&self, mut f: impl FnMut(u32) -> T) -> [T; 32] {
        let mut out = [T::default(); 32];
        for lane in 0..self.lanes {
            out[lane as usize] = f(lane);
        }
        out
    }

    /// `__ballot_sync`: bit `i` set when lane `i` is active and its predicate holds.
    pub fn ballot(&self, pred: &[bool; 32]) -> u32 {
        let mut m = 0u32;
        for (i, &p) in pred.iter().enumerate() {
            m |= (p as u32) << i;
        }
        m & self.active_mask()
    }

    /// `__any_sync`.
    pub fn any(&self, pred: &[bool; 32]) -> bool {
        self.ballot(pred) != 0
    }

    /// `__all_sync` over the active lanes.
    pub fn all(&self, pred: &[bool; 32]) -> bool {
        self.ballot(pred) == self.active_mask()
    }

    /// `__shfl_down_sync`: lane `i` gets lane `i + delta`'s value, or keeps its own
    /// when that lane is outside the warp or inactive.
    pub fn shfl_down<T: Copy>(&self, v: &[T; 32], delta: u32) -> [T; 32] {
        std::array::from_fn(|i| {
            let src = i as u32 + delta;
            if src < self.lanes { v[src as usize] } else { v[i] }
        })
    }

    /// `__shfl_up_sync`: lane `i` gets lane `i - delta`'s value, or keeps its own.
    pub fn shfl_up<T: Copy>(&self, v: &[T; 32], delta: u32) -> [T; 32] {
        std::array::from_fn(|i| if i as u32 >= delta { v[i - delta as usize] } else { v[i] })
    }

    /// `__shfl_xor_sync`: lane `i` gets lane `i ^ mask`'s value (its own if inactive).
    pub fn shfl_xor<T: Copy>(&self, v: &[T; 32], mask: u32) -> [T; 32] {
        std::array::from_fn(|i| {
            let src = (i as u32 ^ mask) & 31;
            if src < self.lanes { v[src as usize] } else { v[i] }
        })
    }

    /// `__shfl_sync`: every lane gets lane `src`'s value.
    pub fn shfl<T: Copy>(&self, v: &[T; 32], src: u32) -> [T; 32] {
        [v[(src & 31) as usize]; 32]
    }
}

/// One thread, as a kernel phase sees it. All memory access goes through it so that
/// it can be measured.
pub struct Thread<'a> {
    thread_idx: u32,
    block_idx: u32,
    block_dim: u32,
    grid_dim: u32,
    measure: bool,
    shared: &'a [Cell<u32>],
    regs: &'a [Cell<u32>],
    meter: &'a RefCell<Meter>,
}

impl Thread<'_> {
    /// `threadIdx.x`.
    #[inline(always)]
    pub fn thread_idx(&self) -> u32 {
        self.thread_idx
    }
    /// `blockIdx.x`.
    #[inline(always)]
    pub fn block_idx(&self) -> u32 {
        self.block_idx
    }
    /// `blockDim.x`.
    #[inline(always)]
    pub fn block_dim(&self) -> u32 {
        self.block_dim
    }
    /// `gridDim.x`.
    #[inline(always)]
    pub fn grid_dim(&self) -> u32 {
        self.grid_dim
    }
    /// `blockIdx.x * blockDim.x + threadIdx.x`.
    #[inline(always)]
    pub fn global_idx(&self) -> usize {
        self.block_idx as usize * self.block_dim as usize + self.thread_idx as usize
    }
    /// Lane within the warp (`threadIdx.x % 32`).
    #[inline(always)]
    pub fn lane_id(&self) -> u32 {
        self.thread_idx % WARP_SIZE
    }
    #[inline(always)]
    pub fn warp_id(&self) -> u32 {
        self.thread_idx / WARP_SIZE
    }

    #[inline(always)]
    #[track_caller]
    fn note(&self, addr: u64, bytes: usize) {
        if self.measure {
            let site = Location::caller() as *const Location as usize;
            self.meter.borrow_mut().record(site, addr, bytes as u64);
        }
    }

    /// Loads element `i` of a global buffer.
    #[inline(always)]
    #[track_caller]
    pub fn load<T: DeviceCopy, V: Readable<T>>(&self, v: &V, i: usize) -> T {
        self.note(v.address(i), std::mem::size_of::<T>());
        v.read(i)
    }

    /// Stores element `i` of a global buffer.
    #[inline(always)]
    #[track_caller]
    pub fn store<T: DeviceCopy>(&self, v: &GlobalMut<T>, i: usize, value: T) {
        self.note(v.address(i), std::mem::size_of::<T>());
        v.write(i, value)
    }

    /// `atomicAdd` on a `u32`; returns the old value.
    #[track_caller]
    pub fn atomic_add(&self, v: &GlobalMut<u32>, i: usize, value: u32) -> u32 {
        self.note(v.address(i), 4);
        v.atomic_u32(i).fetch_add(value, Relaxed)
    }

    /// `atomicAdd` on an `f32` (a compare-and-swap loop, as on older GPUs).
    #[track_caller]
    pub fn atomic_add_f32(&self, v: &GlobalMut<f32>, i: usize, value: f32) -> f32 {
        self.note(v.address(i), 4);
        let a = v.atomic_u32(i);
        let old = a
            .fetch_update(Relaxed, Relaxed, |bits| Some((f32::from_bits(bits) + value).to_bits()))
            .unwrap_or_else(|b| b);
        f32::from_bits(old)
    }

    /// `atomicMin` on a `u32`.
    #[track_caller]
    pub fn atomic_min(&self, v: &GlobalMut<u32>, i: usize, value: u32) -> u32 {
        self.note(v.address(i), 4);
        v.atomic_u32(i).fetch_min(value, Relaxed)
    }

    /// `atomicMax` on a `u32`.
    #[track_caller]
    pub fn atomic_max(&self, v: &GlobalMut<u32>, i: usize, value: u32) -> u32 {
        self.note(v.address(i), 4);
        v.atomic_u32(i).fetch_max(value, Relaxed)
    }

    /// `atomicCAS` on a `u32`: stores `new` if the element equals `expected`; returns the old value.
    #[track_caller]
    pub fn atomic_cas(&self, v: &GlobalMut<u32>, i: usize, expected: u32, new: u32) -> u32 {
        self.note(v.address(i), 4);
        v.atomic_u32(i).compare_exchange(expected, new, Relaxed, Relaxed).unwrap_or_else(|x| x)
    }

    /// `atomicMin` on a `u64`: the closest-hit update for keys packing
    /// (distance bits << 32 | primitive id).
    #[track_caller]
    pub fn atomic_min_u64(&self, v: &GlobalMut<u64>, i: usize, value: u64) -> u64 {
        self.note(v.address(i), 8);
        v.atomic_u64(i).fetch_min(value, Relaxed)
    }

    /// `atomicMax` on a `u64`.
    #[track_caller]
    pub fn atomic_max_u64(&self, v: &GlobalMut<u64>, i: usize, value: u64) -> u64 {
        self.note(v.address(i), 8);
        v.atomic_u64(i).fetch_max(value, Relaxed)
    }

    /// `atomicAdd` on a `u64`.
    #[track_caller]
    pub fn atomic_add_u64(&self, v: &GlobalMut<u64>, i: usize, value: u64) -> u64 {
        self.note(v.address(i), 8);
        v.atomic_u64(i).fetch_add(value, Relaxed)
    }

    /// `atomicCAS` on a `u64`.
    #[track_caller]
    pub fn atomic_cas_u64(&self, v: &GlobalMut<u64>, i: usize, expected: u64, new: u64) -> u64 {
        self.note(v.address(i), 8);
        v.atomic_u64(i).compare_exchange(expected, new, Relaxed, Relaxed).unwrap_or_else(|x| x)
    }

    /// Loads element `i` of a shared-memory array.
    #[inline(always)]
    pub fn load_shared<T: DeviceCopy>(&self, s: Shared<T>, i: usize) -> T {
        assert!(i < s.len as usize, "shared load {i} of {}", s.len);
        let w = words::<T>();
        let base = s.offset as usize + i * w;
        let cells = &self.shared[base..base + w];
        // SAFETY: reads `w` whole words into a T made of whole words.
        unsafe { read_words(cells.as_ptr() as *const T) }
    }

    /// Stores element `i` of a shared-memory array.
    #[inline(always)]
    pub fn store_shared<T: DeviceCopy>(&self, s: Shared<T>, i: usize, value: T) {
        assert!(i < s.len as usize, "shared store {i} of {}", s.len);
        let w = words::<T>();
        let base = s.offset as usize + i * w;
        let cells = &self.shared[base..base + w];
        // SAFETY: Cell<u32> has u32's layout; the block's threads run on one OS thread.
        unsafe { write_words(cells.as_ptr() as *mut T, value) }
    }

    /// `atomicAdd` on shared memory; returns the old value. (A block's threads run on
    /// one OS thread, so a load and a store are already atomic here.)
    #[inline(always)]
    pub fn atomic_add_shared(&self, s: Shared<u32>, i: usize, value: u32) -> u32 {
        let old = self.load_shared(s, i);
        self.store_shared(s, i, old.wrapping_add(value));
        old
    }

    /// This thread's value of a register.
    #[inline(always)]
    pub fn get<T: DeviceCopy>(&self, l: Local<T>) -> T {
        let base = self.thread_idx as usize * REGISTER_WORDS_PER_THREAD + l.offset as usize;
        let cells = &self.regs[base..base + words::<T>()];
        unsafe { read_words(cells.as_ptr() as *const T) }
    }

    /// Sets this thread's value of a register.
    #[inline(always)]
    pub fn set<T: DeviceCopy>(&self, l: Local<T>, value: T) {
        let base = self.thread_idx as usize * REGISTER_WORDS_PER_THREAD + l.offset as usize;
        let cells = &self.regs[base..base + words::<T>()];
        unsafe { write_words(cells.as_ptr() as *mut T, value) }
    }

    /// Reports `units` steps of work on branch arm `path` of divergence point `region`
    /// (indices below [`MAX_REGIONS`] and [`MAX_PATHS`]; names come from the launch).
    #[inline(always)]
    pub fn work(&self, region: usize, path: usize, units: u32) {
        if self.measure {
            let mut m = self.meter.borrow_mut();
            m.lane_units[region][path] += units;
            m.lane_used = true;
        }
    }
}
