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
//! Measurement (when on) is described in [`crate::meter`]: every operation a lane
//! performs is matched with the same operation of the other lanes into warp
//! instructions (SIMD efficiency, memory requests and sectors), and shared-memory
//! accesses are checked for races between barriers. With measurement off a lane phase
//! runs a plain loop whose `Thread`s carry no meter, so after inlining the kernel's
//! accesses are ordinary loads and stores.
//!
//! About 1,020 lines on purpose: `Block`, `Warp` and `Thread` are one execution model,
//! and the meter that all three feed (sites, lanes, regions) must follow the same
//! lockstep rules; keeping them together keeps those rules in one place.

use crate::memory::{DeviceCopy, GlobalMut, Readable, words};
use crate::meter::{Kind, Meter};
use std::cell::{Cell, RefCell};
use std::marker::PhantomData;
use std::panic::Location;
use std::sync::atomic::Ordering::Relaxed;
use std::sync::atomic::{AtomicU32, AtomicU64};

use crate::limits::{REGISTER_WORDS_PER_THREAD, WARP_SIZE};

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
    /// Elements.
    pub fn len(&self) -> usize {
        self.len as usize
    }
    /// Whether it has no elements.
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

/// Scratch one rayon worker reuses for the blocks it runs.
pub(crate) struct Worker {
    pub shared: Vec<Cell<u32>>,
    pub regs: Vec<Cell<u32>>,
    pub meter: RefCell<Meter>,
}

impl Worker {
    /// A worker; `predicting`: its meter also gathers what the GPU time model needs.
    pub fn new(shared_words: usize, predicting: bool) -> Worker {
        Worker {
            shared: vec![Cell::new(0); shared_words],
            regs: Vec::new(),
            meter: RefCell::new(Meter::new(predicting)),
        }
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
        if measure {
            worker.meter.get_mut().begin_block(block_idx, shared_words);
        }
        Block { block_idx, block_dim, grid_dim, measure, worker, shared_words, shared_used: 0, regs_used: 0 }
    }

    /// `blockIdx.x`: this block's index in the grid.
    pub fn block_idx(&self) -> u32 {
        self.block_idx
    }
    /// `blockDim.x`: threads per block.
    pub fn block_dim(&self) -> u32 {
        self.block_dim
    }
    /// `gridDim.x`: blocks in the grid.
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
        self.worker.meter.get_mut().barrier();
    }

    /// Runs `f` for every thread of the block, warp by warp.
    pub fn for_each_thread(&mut self, mut f: impl FnMut(&Thread)) {
        if self.measure {
            return self.for_each_warp(|w| w.for_each_lane(&mut f));
        }
        // Unmeasured: one plain loop over the block's threads (the order is the same,
        // warp by warp and lane by lane).
        for thread_idx in 0..self.block_dim {
            f(&self.thread(thread_idx, None));
        }
        self.worker.meter.get_mut().totals.threads += self.block_dim as u64;
    }

    /// Element `i` of a global buffer, loaded by every thread of the block from the same
    /// address (a block's work item, a binary search over offsets): the value the block's
    /// control flow needs, measured as on a GPU, one load per warp with all its lanes
    /// active and the sectors of one element.
    #[track_caller]
    pub fn load_uniform<T: DeviceCopy, V: Readable<T>>(&mut self, v: &V, i: usize) -> T {
        self.note_uniform::<T>(v.address(i));
        v.read(i)
    }

    /// One field of element `i`, loaded by every thread of the block from the same
    /// address: [`Block::load_uniform`] for a kernel that reads only part of an element
    /// (see [`Thread::load_field`]).
    #[track_caller]
    pub fn load_uniform_field<T: DeviceCopy, U: DeviceCopy, V: Readable<T>>(
        &mut self,
        v: &V,
        i: usize,
        field: impl FnOnce(&T) -> &U,
    ) -> U {
        let (value, addr) = read_field(v, i, field);
        self.note_uniform::<U>(addr);
        value
    }

    /// Declares `units` instructions of arithmetic that every thread of the block runs
    /// together, in the block's own flow between thread phases (the index arithmetic
    /// around [`Block::load_uniform`], say): [`Thread::work`] with every lane active.
    #[track_caller]
    pub fn work_uniform(&mut self, region: usize, path: usize, units: u32) {
        if self.measure {
            let at = site();
            self.for_each_warp(|w| {
                w.run_lanes(false, &mut |t: &Thread| {
                    if let Some(m) = t.meter {
                        note_work(m, t.thread_idx, at, region, path, units);
                    }
                })
            });
        }
    }

    /// Measures a uniform load of a `T` at `addr` (nothing when unmeasured).
    #[track_caller]
    fn note_uniform<T>(&mut self, addr: u64) {
        if self.measure {
            let at = site();
            let (size, width) = (std::mem::size_of::<T>() as u64, access_width::<T>());
            // A load inside the block's flow, not a phase of threads: lanes are measured
            // but not counted as threads again.
            self.for_each_warp(|w| {
                w.run_lanes(false, &mut |t: &Thread| {
                    if let Some(m) = t.meter {
                        note_global(m, t.thread_idx, at, Kind::Load, addr, (size, width), true);
                    }
                })
            });
        }
    }

    /// Thread `thread_idx` of this block as a kernel phase sees it (`meter` is `None`
    /// when the launch is not measured).
    #[inline(always)]
    fn thread<'s>(&'s self, thread_idx: u32, meter: Option<&'s RefCell<Meter>>) -> Thread<'s> {
        Thread {
            thread_idx,
            block_idx: self.block_idx,
            block_dim: self.block_dim,
            grid_dim: self.grid_dim,
            shared: &self.worker.shared[..self.shared_words],
            regs: &self.worker.regs,
            meter,
        }
    }

    /// Runs `f` for every warp of the block, in order.
    pub fn for_each_warp(&mut self, mut f: impl FnMut(&mut Warp)) {
        for warp_idx in 0..self.warp_count() {
            let lanes = (self.block_dim - warp_idx * WARP_SIZE).min(WARP_SIZE);
            if self.measure {
                self.worker.meter.get_mut().begin_warp_call();
            }
            let mut w = Warp { warp_idx, lanes, block: self };
            f(&mut w);
        }
        if self.measure {
            // The warps ran one after another here and together on a GPU: loops in
            // which they contend are counted now that all have run.
            self.worker.meter.get_mut().end_spins();
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
    /// This warp's index within its block.
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
        self.run_lanes(true, &mut f)
    }

    /// The lane loop; `count_threads` adds the lanes to the launch's thread count.
    fn run_lanes(&mut self, count_threads: bool, mut f: impl FnMut(&Thread)) {
        let b = self.block;
        let meter = &b.worker.meter;
        let thread = |lane: u32, meter| b.thread(self.warp_idx * WARP_SIZE + lane, meter);
        if b.measure {
            meter.borrow_mut().begin_lane_phase();
            for lane in 0..self.lanes {
                let t = thread(lane, Some(meter));
                meter.borrow_mut().begin_lane(t.thread_idx);
                f(&t);
            }
            meter.borrow_mut().end_warp_phase();
        } else {
            // The unmeasured loop: `meter` is a constant `None` here, so once `f` is
            // inlined every measurement branch in it folds away.
            for lane in 0..self.lanes {
                f(&thread(lane, None));
            }
        }
        if count_threads {
            meter.borrow_mut().totals.threads += self.lanes as u64;
        }
    }

    fn count_warp_op(&self) {
        if self.block.measure {
            self.block.worker.meter.borrow_mut().warp_op(self.lanes);
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
        self.count_warp_op();
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
        self.count_warp_op();
        std::array::from_fn(|i| {
            let src = i as u32 + delta;
            if src < self.lanes { v[src as usize] } else { v[i] }
        })
    }

    /// `__shfl_up_sync`: lane `i` gets lane `i - delta`'s value, or keeps its own.
    pub fn shfl_up<T: Copy>(&self, v: &[T; 32], delta: u32) -> [T; 32] {
        self.count_warp_op();
        std::array::from_fn(|i| if i as u32 >= delta { v[i - delta as usize] } else { v[i] })
    }

    /// `__shfl_xor_sync`: lane `i` gets lane `i ^ mask`'s value (its own if inactive).
    pub fn shfl_xor<T: Copy>(&self, v: &[T; 32], mask: u32) -> [T; 32] {
        self.count_warp_op();
        std::array::from_fn(|i| {
            let src = (i as u32 ^ mask) & 31;
            if src < self.lanes { v[src as usize] } else { v[i] }
        })
    }

    /// `__shfl_sync`: every lane gets lane `src`'s value.
    pub fn shfl<T: Copy>(&self, v: &[T; 32], src: u32) -> [T; 32] {
        self.count_warp_op();
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
    shared: &'a [Cell<u32>],
    regs: &'a [Cell<u32>],
    /// `None` when the launch is not measured.
    meter: Option<&'a RefCell<Meter>>,
}

/// Bytes per hardware access for an element type: the widest vector (4, 8 or 16 bytes)
/// that divides both its size and its alignment, as a compiler would emit.
pub(crate) const fn access_width<T>() -> u64 {
    let (size, align) = (std::mem::size_of::<T>(), std::mem::align_of::<T>());
    let mut w = 16;
    while w > 4 && (size % w != 0 || align % w != 0) {
        w /= 2;
    }
    w as u64
}

/// An element, or a field of one, that a lane will load with [`Thread::load_place`]:
/// chosen first (from one view or another, in the arms of a branch), loaded after.
#[derive(Clone, Copy, Debug)]
pub struct Place<U> {
    value: U,
    addr: u64,
}

impl<U: DeviceCopy> Place<U> {
    /// Element `i` of `v`.
    pub fn of<V: Readable<U>>(v: &V, i: usize) -> Place<U> {
        Place { value: v.read(i), addr: v.address(i) }
    }

    /// One field of element `i` of `v` (as [`Thread::load_field`]).
    pub fn field<T: DeviceCopy, V: Readable<T>>(v: &V, i: usize, field: impl FnOnce(&T) -> &U) -> Place<U> {
        let (value, addr) = read_field(v, i, field);
        Place { value, addr }
    }
}

/// The field of element `i` that `field` picks, and its address; panics unless the
/// projection returns a part of the element itself.
#[inline(always)]
fn read_field<T: DeviceCopy, U: DeviceCopy, V: Readable<T>>(v: &V, i: usize, field: impl FnOnce(&T) -> &U) -> (U, u64) {
    let x = v.read(i);
    let f = field(&x);
    let at = (f as *const U as usize).wrapping_sub(&x as *const T as usize);
    assert!(
        at.checked_add(std::mem::size_of::<U>()).is_some_and(|end| end <= std::mem::size_of::<T>()),
        "load_field: the projection must return a field of the element"
    );
    (*f, v.address(i) + at as u64)
}

// Measurement calls are kept out of line (and cold), so that the unmeasured kernel
// code they sit in stays small enough to inline. Each names the lane that records
// (`Meter::set_lane`): a launch need not set it lane by lane, so that a loop of lanes
// that record nothing of their own stays a plain loop (`Device::transform`).

/// The meter, borrowed for `lane`'s record.
#[inline(always)]
pub(crate) fn meter_of(m: &RefCell<Meter>, lane: u32) -> std::cell::RefMut<'_, Meter> {
    let mut m = m.borrow_mut();
    m.set_lane(lane);
    m
}

#[cold]
#[inline(never)]
pub(crate) fn note_global(
    m: &RefCell<Meter>,
    lane: u32,
    site: usize,
    kind: Kind,
    addr: u64,
    (size, width): (u64, u64),
    on: bool,
) {
    meter_of(m, lane).global(site, kind, addr, size, width, on);
}

#[cold]
#[inline(never)]
fn note_shared(m: &RefCell<Meter>, lane: u32, site: usize, word: usize, words: usize, write: bool) {
    let mut m = meter_of(m, lane);
    m.op(site, Kind::Other, 1, 1);
    m.shared(word, words, write);
}

#[cold]
#[inline(never)]
fn note_fence(m: &RefCell<Meter>, lane: u32, site: usize) {
    meter_of(m, lane).op(site, Kind::Fence, 1, 0);
}

#[cold]
#[inline(never)]
fn note_op(m: &RefCell<Meter>, lane: u32, site: usize) {
    meter_of(m, lane).op(site, Kind::Other, 1, 1);
}

#[cold]
#[inline(never)]
fn note_spin(m: &RefCell<Meter>, lane: u32, site: usize, word: usize) {
    meter_of(m, lane).spin(site, word);
}

#[cold]
#[inline(never)]
pub(crate) fn note_work(m: &RefCell<Meter>, lane: u32, site: usize, region: usize, path: usize, units: u32) {
    meter_of(m, lane).work(site, region, path, units);
}

#[cold]
#[inline(never)]
fn begin_together(m: &RefCell<Meter>, lane: u32, site: usize) -> u32 {
    meter_of(m, lane).begin_together(site)
}

/// Enters the copy of code that call site `site` inlines, for `lane`'s next entry
/// there ([`Thread::inlined`], [`crate::scope`]); returns the copy it was in.
#[cold]
#[inline(never)]
pub(crate) fn enter_scope(m: &RefCell<Meter>, lane: u32, site: usize) -> usize {
    meter_of(m, lane).enter_scope(site)
}

/// Enters copy `copy` of unrolled code; returns the copy it was in.
#[cold]
#[inline(never)]
fn enter_copy(m: &RefCell<Meter>, copy: usize) -> usize {
    m.borrow_mut().enter_copy(copy)
}

#[cold]
#[inline(never)]
pub(crate) fn leave_copy(m: &RefCell<Meter>, outer: usize) {
    // `try_`: a guard dropped while a panic unwinds out of the meter itself must not
    // panic again (the launch reports the first panic).
    if let Ok(mut m) = m.try_borrow_mut() {
        m.copy = outer;
    }
}

/// The call site of the `#[track_caller]` function that calls this.
#[inline(always)]
#[track_caller]
pub(crate) fn site() -> usize {
    Location::caller() as *const Location as usize
}

impl<'a> Thread<'a> {
    /// A thread of a measured launch that uses no shared memory or registers.
    #[inline(always)]
    pub(crate) fn measured(
        thread_idx: u32,
        block_idx: u32,
        block_dim: u32,
        grid_dim: u32,
        meter: &'a RefCell<Meter>,
    ) -> Self {
        Thread { thread_idx, block_idx, block_dim, grid_dim, shared: &[], regs: &[], meter: Some(meter) }
    }
}

impl Thread<'static> {
    /// A thread of an unmeasured launch that uses no shared memory or registers.
    #[inline(always)]
    pub(crate) fn unmeasured(thread_idx: u32, block_idx: u32, block_dim: u32, grid_dim: u32) -> Self {
        Thread { thread_idx, block_idx, block_dim, grid_dim, shared: &[], regs: &[], meter: None }
    }
}

impl Thread<'_> {
    /// The launch's meter (`None` when it is not measured).
    #[inline(always)]
    pub(crate) fn meter(&self) -> Option<&RefCell<Meter>> {
        self.meter
    }

    /// Whether the launch is measured: code that does host-only work for the emulator's
    /// speed (drawing ahead to prefetch, say) skips it then, so that what it runs is
    /// never counted.
    #[inline(always)]
    pub fn is_measured(&self) -> bool {
        self.meter.is_some()
    }

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
    /// The index of this thread's warp within its block.
    pub fn warp_id(&self) -> u32 {
        self.thread_idx / WARP_SIZE
    }

    #[inline(always)]
    #[track_caller]
    fn note<T>(&self, kind: Kind, addr: u64) {
        self.note_if::<T>(kind, addr, true)
    }

    /// [`Thread::note`] of a predicated access, which touches memory only when `on`.
    #[inline(always)]
    #[track_caller]
    fn note_if<T>(&self, kind: Kind, addr: u64, on: bool) {
        if let Some(m) = self.meter {
            let size = std::mem::size_of::<T>() as u64;
            let width = if kind.is_atomic() { size } else { access_width::<T>() };
            note_global(m, self.thread_idx, site(), kind, addr, (size, width), on);
        }
    }

    /// Loads element `i` of a global buffer.
    #[inline(always)]
    #[track_caller]
    pub fn load<T: DeviceCopy, V: Readable<T>>(&self, v: &V, i: usize) -> T {
        self.note::<T>(Kind::Load, v.address(i));
        v.read(i)
    }

    /// One field of element `i` of a global buffer, `field` picking it (`|n: &Node|
    /// &n.count`). [`Thread::load`] measures the whole element; compiled GPU code loads
    /// only the fields a kernel reads, each as its own load at its own address (a
    /// structure of 4-byte fields is loaded 4 bytes at a time), and this measures that.
    /// The value is the same as `load(v, i)`'s field.
    #[inline(always)]
    #[track_caller]
    pub fn load_field<T: DeviceCopy, U: DeviceCopy, V: Readable<T>>(
        &self,
        v: &V,
        i: usize,
        field: impl FnOnce(&T) -> &U,
    ) -> U {
        let (value, addr) = read_field(v, i, field);
        self.note::<U>(Kind::Load, addr);
        value
    }

    /// Loads what `place` points at, as one load instruction at this call site whichever
    /// view each lane's place is in: compiled code's if-converted branch, which selects
    /// an address in each arm and loads once after them, with every lane.
    #[inline(always)]
    #[track_caller]
    pub fn load_place<U: DeviceCopy>(&self, place: Place<U>) -> U {
        self.note::<U>(Kind::Load, place.addr);
        place.value
    }

    /// Stores element `i` of a global buffer.
    #[inline(always)]
    #[track_caller]
    pub fn store<T: DeviceCopy>(&self, v: &GlobalMut<T>, i: usize, value: T) {
        self.note::<T>(Kind::Store, v.address(i));
        v.write(i, value)
    }

    /// Stores one field of element `i`, `field` picking it (`|n: &Node| &n.count`), and
    /// nothing else of the element: other threads may store its other fields at the
    /// same time, as compiled code's store of `p[i].count` leaves them alone.
    #[inline(always)]
    #[track_caller]
    pub fn store_field<T: DeviceCopy + Default, U: DeviceCopy>(
        &self,
        v: &GlobalMut<T>,
        i: usize,
        field: impl FnOnce(&T) -> &U,
        value: U,
    ) {
        self.store_field_if(true, v, i, field, value)
    }

    /// A predicated [`Thread::store_field`], as [`Thread::store_if`] is of
    /// [`Thread::store`]: one instruction of every lane that reaches it, written (and
    /// making traffic) only where `on`. Element `i` need not exist where `on` is false.
    #[inline(always)]
    #[track_caller]
    pub fn store_field_if<T: DeviceCopy + Default, U: DeviceCopy>(
        &self,
        on: bool,
        v: &GlobalMut<T>,
        i: usize,
        field: impl FnOnce(&T) -> &U,
        value: U,
    ) {
        let x = T::default();
        let at = (field(&x) as *const U as usize).wrapping_sub(&x as *const T as usize);
        assert!(at < std::mem::size_of::<T>(), "store_field: the projection must return a field of the element");
        self.note_if::<U>(Kind::Store, v.address(i) + at as u64, on);
        if on {
            v.write_at(i, at, value)
        }
    }

    /// A predicated store: element `i` is written only when `on`, but the store is one
    /// instruction of every lane that reaches it, as compiled code makes of
    /// `x[i] = c ? a : b` with two predicated stores (`@P0 STG`, `@!P0 STG`): the lane is
    /// active in both, and only the lanes whose predicate holds make memory traffic.
    #[inline(always)]
    #[track_caller]
    pub fn store_if<T: DeviceCopy>(&self, on: bool, v: &GlobalMut<T>, i: usize, value: T) {
        self.note_if::<T>(Kind::Store, v.address(i), on);
        if on {
            v.write(i, value)
        }
    }

    /// One atomic read-modify-write of a 4-byte element, counted as `kind`.
    #[inline(always)]
    #[track_caller]
    fn rmw_u32<T: DeviceCopy>(
        &self,
        kind: Kind,
        v: &GlobalMut<T>,
        i: usize,
        op: impl FnOnce(&AtomicU32) -> u32,
    ) -> u32 {
        self.note::<T>(kind, v.address(i));
        op(v.atomic_u32(i))
    }

    /// One atomic read-modify-write of an 8-byte element, counted as `kind`.
    #[inline(always)]
    #[track_caller]
    fn rmw_u64(&self, kind: Kind, v: &GlobalMut<u64>, i: usize, op: impl FnOnce(&AtomicU64) -> u64) -> u64 {
        self.note::<u64>(kind, v.address(i));
        op(v.atomic_u64(i))
    }

    // Atomics return the old value, and the GPU time model takes the warp to wait for it
    // (`ATOMG` in SASS). Where a kernel ignores the value, nvcc emits a reduction
    // (`RED`), which the warp does not wait for: use the `red_*` forms there.

    /// `atomicAdd` on a `u32`; returns the old value.
    #[track_caller]
    pub fn atomic_add(&self, v: &GlobalMut<u32>, i: usize, value: u32) -> u32 {
        self.rmw_u32(Kind::Atomic, v, i, |a| a.fetch_add(value, Relaxed))
    }

    /// `atomicAdd` on an `f32` (a compare-and-swap loop, as on older GPUs).
    #[track_caller]
    pub fn atomic_add_f32(&self, v: &GlobalMut<f32>, i: usize, value: f32) -> f32 {
        let add = |bits: u32| Some((f32::from_bits(bits) + value).to_bits());
        f32::from_bits(
            self.rmw_u32(Kind::Atomic, v, i, |a| a.fetch_update(Relaxed, Relaxed, add).unwrap_or_else(|b| b)),
        )
    }

    /// `atomicMin` on a `u32`.
    #[track_caller]
    pub fn atomic_min(&self, v: &GlobalMut<u32>, i: usize, value: u32) -> u32 {
        self.rmw_u32(Kind::Atomic, v, i, |a| a.fetch_min(value, Relaxed))
    }

    /// `atomicMax` on a `u32`.
    #[track_caller]
    pub fn atomic_max(&self, v: &GlobalMut<u32>, i: usize, value: u32) -> u32 {
        self.rmw_u32(Kind::Atomic, v, i, |a| a.fetch_max(value, Relaxed))
    }

    /// `atomicCAS` on a `u32`: stores `new` if the element equals `expected`; returns the old value.
    #[track_caller]
    pub fn atomic_cas(&self, v: &GlobalMut<u32>, i: usize, expected: u32, new: u32) -> u32 {
        self.rmw_u32(Kind::Atomic, v, i, |a| a.compare_exchange(expected, new, Relaxed, Relaxed).unwrap_or_else(|x| x))
    }

    /// `atomicMin` on a `u64`: the closest-hit update for keys packing
    /// (distance bits << 32 | primitive id).
    #[track_caller]
    pub fn atomic_min_u64(&self, v: &GlobalMut<u64>, i: usize, value: u64) -> u64 {
        self.rmw_u64(Kind::Atomic, v, i, |a| a.fetch_min(value, Relaxed))
    }

    /// `atomicMax` on a `u64`.
    #[track_caller]
    pub fn atomic_max_u64(&self, v: &GlobalMut<u64>, i: usize, value: u64) -> u64 {
        self.rmw_u64(Kind::Atomic, v, i, |a| a.fetch_max(value, Relaxed))
    }

    /// `atomicAdd` on a `u64`.
    #[track_caller]
    pub fn atomic_add_u64(&self, v: &GlobalMut<u64>, i: usize, value: u64) -> u64 {
        self.rmw_u64(Kind::Atomic, v, i, |a| a.fetch_add(value, Relaxed))
    }

    /// `atomicCAS` on a `u64`.
    #[track_caller]
    pub fn atomic_cas_u64(&self, v: &GlobalMut<u64>, i: usize, expected: u64, new: u64) -> u64 {
        self.rmw_u64(Kind::Atomic, v, i, |a| a.compare_exchange(expected, new, Relaxed, Relaxed).unwrap_or_else(|x| x))
    }

    /// `atomicAdd` on a `u32` whose old value is not used (`RED.ADD`).
    #[track_caller]
    pub fn red_add(&self, v: &GlobalMut<u32>, i: usize, value: u32) {
        self.rmw_u32(Kind::Reduce, v, i, |a| a.fetch_add(value, Relaxed));
    }

    /// `atomicMin` on a `u32` whose old value is not used (`RED.MIN`).
    #[track_caller]
    pub fn red_min(&self, v: &GlobalMut<u32>, i: usize, value: u32) {
        self.rmw_u32(Kind::Reduce, v, i, |a| a.fetch_min(value, Relaxed));
    }

    /// `atomicMax` on a `u32` whose old value is not used (`RED.MAX`).
    #[track_caller]
    pub fn red_max(&self, v: &GlobalMut<u32>, i: usize, value: u32) {
        self.rmw_u32(Kind::Reduce, v, i, |a| a.fetch_max(value, Relaxed));
    }

    /// `atomicMin` on a `u64` whose old value is not used (`RED.MIN.64`).
    #[track_caller]
    pub fn red_min_u64(&self, v: &GlobalMut<u64>, i: usize, value: u64) {
        self.rmw_u64(Kind::Reduce, v, i, |a| a.fetch_min(value, Relaxed));
    }

    /// `atomicAdd` on a `u64` whose old value is not used (`RED.ADD.64`).
    #[track_caller]
    pub fn red_add_u64(&self, v: &GlobalMut<u64>, i: usize, value: u64) {
        self.rmw_u64(Kind::Reduce, v, i, |a| a.fetch_add(value, Relaxed));
    }

    /// Words of element `i` of a shared array, checked against its length.
    #[inline(always)]
    #[track_caller]
    fn shared_words<T: DeviceCopy>(&self, s: Shared<T>, i: usize, write: bool) -> *mut T {
        assert!(i < s.len as usize, "shared {} {i} of {}", if write { "store" } else { "load" }, s.len);
        let w = words::<T>();
        let base = s.offset as usize + i * w;
        if let Some(m) = self.meter {
            note_shared(m, self.thread_idx, site(), base, w, write);
        }
        self.shared[base..base + w].as_ptr() as *mut T
    }

    /// Loads element `i` of a shared-memory array.
    #[inline(always)]
    #[track_caller]
    pub fn load_shared<T: DeviceCopy>(&self, s: Shared<T>, i: usize) -> T {
        // SAFETY: in bounds; the block's threads run on one OS thread; Cell<u32> has
        // u32's layout; T is whole words (unaligned: shared arrays are word-aligned).
        unsafe { self.shared_words(s, i, false).read_unaligned() }
    }

    /// Stores element `i` of a shared-memory array.
    #[inline(always)]
    #[track_caller]
    pub fn store_shared<T: DeviceCopy>(&self, s: Shared<T>, i: usize, value: T) {
        // SAFETY: as for `load_shared`.
        unsafe { self.shared_words(s, i, true).write_unaligned(value) }
    }

    /// The bounds check and the measurement of a shared atomic on element `i` of `len`
    /// (one instruction at the kernel's call site).
    #[inline(always)]
    #[track_caller]
    fn shared_atomic(&self, len: u32, i: usize) {
        assert!(i < len as usize, "shared atomic {i} of {len}");
        if let Some(m) = self.meter {
            note_op(m, self.thread_idx, site());
        }
    }

    /// `atomicAdd` on shared memory; returns the old value. (A block's threads run on
    /// one OS thread, so a load and a store are already atomic here; the race check
    /// does not look at atomics.)
    #[inline(always)]
    #[track_caller]
    pub fn atomic_add_shared(&self, s: Shared<u32>, i: usize, value: u32) -> u32 {
        self.shared_atomic(s.len, i);
        let cell = &self.shared[s.offset as usize + i];
        let old = cell.get();
        cell.set(old.wrapping_add(value));
        old
    }

    /// `atomicAdd` on a 64-bit shared word (`unsigned long long`); returns the old value.
    /// Measured as the GPU runs it: sm_90 has no 64-bit shared add, and nvcc makes a
    /// load and compare-and-swap retry loop, in which the block's lanes that hit one
    /// word succeed one per round (`ATOMS.CAST.SPIN.64`; see `Meter::end_spins`).
    #[inline(always)]
    #[track_caller]
    pub fn atomic_add_shared_u64(&self, s: Shared<u64>, i: usize, value: u64) -> u64 {
        assert!(i < s.len as usize, "shared atomic {i} of {}", s.len);
        // Two words, low first, as `load_shared::<u64>` reads them.
        let at = s.offset as usize + 2 * i;
        if let Some(m) = self.meter {
            note_spin(m, self.thread_idx, site(), at);
        }
        let (lo, hi) = (&self.shared[at], &self.shared[at + 1]);
        let old = lo.get() as u64 | (hi.get() as u64) << 32;
        let new = old.wrapping_add(value);
        lo.set(new as u32);
        hi.set((new >> 32) as u32);
        old
    }

    #[inline(always)]
    fn register<T: DeviceCopy>(&self, l: Local<T>) -> *mut T {
        let base = self.thread_idx as usize * REGISTER_WORDS_PER_THREAD + l.offset as usize;
        self.regs[base..base + words::<T>()].as_ptr() as *mut T
    }

    /// This thread's value of a register.
    #[inline(always)]
    pub fn get<T: DeviceCopy>(&self, l: Local<T>) -> T {
        // SAFETY: the register's words, written as a T by `set` or `Block::local`.
        unsafe { self.register(l).read_unaligned() }
    }

    /// Sets this thread's value of a register.
    #[inline(always)]
    pub fn set<T: DeviceCopy>(&self, l: Local<T>, value: T) {
        // SAFETY: as for `get`; the block's threads run on one OS thread.
        unsafe { self.register(l).write_unaligned(value) }
    }

    /// Marks the rest of the enclosing scope as copy `copy` of an unrolled loop body,
    /// until the returned guard drops: the instructions executed meanwhile are other
    /// instructions than those of the other copies, as when a compiler unrolls a short
    /// loop (nvcc does `for (side = 0; side < 2; side++)`) and issues each trip's
    /// accesses apart, each with only the lanes that take that trip's branch. Without
    /// it, a lane's first execution of a call site is matched with the other lanes'
    /// first, whichever trip each is in. Copies nest.
    ///
    /// Bind the guard to a name (`let _trip = t.unroll(j);`; `let _ = ..` drops it at
    /// once). A guard rather than a closure so that a hot loop's body stays inline:
    /// unmeasured launches pay a test of a register where the copy starts and one where
    /// it ends, and no call.
    #[inline(always)]
    #[must_use = "the copy ends when the guard drops: bind it with `let _copy = ..`"]
    pub fn unroll(&self, copy: usize) -> Unrolled<'_> {
        match self.meter {
            Some(m) => Unrolled { meter: Some(m), outer: enter_copy(m, copy) },
            None => Unrolled { meter: None, outer: 0 },
        }
    }

    /// Marks the rest of the enclosing scope as the caller's inlined copy of a device
    /// function, until the guard drops: [`crate::scope`] for a `#[track_caller]` helper
    /// that holds the thread. nvcc compiles each call site to code of its own, and the
    /// lanes' k-th calls from one site are matched with each other, their trips from
    /// the first.
    #[inline(always)]
    #[track_caller]
    #[must_use = "the copy ends when the guard drops: bind it with `let _call = ..`"]
    pub fn inlined(&self) -> Unrolled<'_> {
        match self.meter {
            Some(m) => Unrolled { meter: Some(m), outer: enter_scope(m, self.thread_idx, site()) },
            None => Unrolled { meter: None, outer: 0 },
        }
    }

    /// Runs `f` as copy `copy` of an unrolled loop body ([`Thread::unroll`] for a
    /// scope).
    #[inline(always)]
    pub fn unrolled<R>(&self, copy: usize, f: impl FnOnce() -> R) -> R {
        let _copy = self.unroll(copy);
        f()
    }

    /// Loads issued together, until the guard drops: the compiled kernel issues them
    /// back to back and waits once for all of them (a traversal step's node boxes and
    /// ray fields, none of which depends on another). They are counted as every load is
    /// (requests, sectors), but the warp's chain of the GPU time model waits for them
    /// as one round instead of one after another ([`crate::WarpChain::load_rounds`]).
    /// Say so only where the twin's SASS shows it: loads between which a value is used
    /// stay apart. Nothing when the launch is not measured.
    #[inline(always)]
    #[track_caller]
    #[must_use = "the loads are together until the guard drops: bind it with `let _together = ..`"]
    pub fn loads_together(&self) -> Together<'_> {
        match self.meter {
            Some(m) => Together { meter: Some(m), outer: begin_together(m, self.thread_idx, site()) },
            None => Together { meter: None, outer: 0 },
        }
    }

    /// `__threadfence()`: this thread's global writes before it are seen by any thread
    /// that sees its writes (or atomics) after it. Views store with relaxed atomics, so
    /// without a fence a thread that learns of another's work through an atomic
    /// counter may read that work's stores stale. No instruction of its own (a kernel's
    /// declared work holds its `MEMBAR`, as the SASS has it on the path); the warp's
    /// chain waits for it ([`crate::WarpChain::fences`]).
    #[inline(always)]
    #[track_caller]
    pub fn thread_fence(&self) {
        if let Some(m) = self.meter {
            note_fence(m, self.thread_idx, site());
        }
        std::sync::atomic::fence(std::sync::atomic::Ordering::SeqCst);
    }

    /// Declares `units` instructions of arithmetic on branch arm `path` of region
    /// `region` (indices below [`MAX_REGIONS`](crate::MAX_REGIONS) and [`MAX_PATHS`](crate::MAX_PATHS); names come from the
    /// launch). Counted like any other instruction: lanes at the same call site, path
    /// and occurrence share a warp instruction issued `max(units)` times.
    #[inline(always)]
    #[track_caller]
    pub fn work(&self, region: usize, path: usize, units: u32) {
        if let Some(m) = self.meter {
            note_work(m, self.thread_idx, site(), region, path, units);
        }
    }
}

/// Loads issued together, from [`Thread::loads_together`] until it drops.
pub struct Together<'a> {
    meter: Option<&'a RefCell<Meter>>,
    outer: u32,
}

impl Drop for Together<'_> {
    #[inline(always)]
    fn drop(&mut self) {
        if let Some(m) = self.meter
            && let Ok(mut m) = m.try_borrow_mut()
        {
            m.end_together(self.outer);
        }
    }
}

/// The copy of unrolled code a lane is in, from [`Thread::unroll`] until it drops.
pub struct Unrolled<'a> {
    meter: Option<&'a RefCell<Meter>>,
    outer: usize,
}

impl Drop for Unrolled<'_> {
    #[inline(always)]
    fn drop(&mut self) {
        if let Some(m) = self.meter {
            leave_copy(m, self.outer);
        }
    }
}
