//! The device: configuration, memory accounting, kernel launches and statistics.
//!
//! About 540 lines on purpose: the launch paths (measured, unmeasured, in order) share
//! the statistics and the serial-cost bookkeeping this file keeps private.

use crate::exec::{Block, Thread, Worker};
pub use crate::launch::{LaunchConfig, LaunchError, MAX_BLOCK_DIM};
use crate::limits::MAX_REGIONS;
use crate::memory::{BufferPool, DeviceBuffer, DeviceCopy, MemCounter, Scratch};
use crate::meter::{Counters, Race, WarpChain};
use crate::stats::{KernelSummary, LaunchRecord, RegionStats, Stats};
use crate::timing::{GpuProfile, predict};
use rayon::prelude::*;
use std::collections::HashMap;
use std::sync::atomic::{AtomicBool, AtomicU32, Ordering::Relaxed};
use std::sync::{Arc, Mutex};
use std::time::Instant;

/// What a device is like.
#[derive(Clone, Debug)]
pub struct DeviceConfig {
    /// Shared memory one block may use, in bytes (48 KiB, CUDA's default limit).
    pub shared_capacity: usize,
    /// Record SIMD efficiency, memory requests and sectors (launch counts, times and
    /// shared bytes are always recorded).
    pub measure: bool,
}

impl Default for DeviceConfig {
    fn default() -> Self {
        DeviceConfig { shared_capacity: 48 * 1024, measure: false }
    }
}

struct Inner {
    config: DeviceConfig,
    measure: AtomicBool,
    mem: Arc<MemCounter>,
    stats: Mutex<Stats>,
    /// Host scratch the primitives' CPU backend reuses between calls (never zeroed).
    pool: Mutex<Vec<u128>>,
    /// Allocations of dropped pooled buffers.
    buffers: Arc<BufferPool>,
    /// Per kernel (and measurement mode): seconds and threads of its serial launches.
    serial_cost: Mutex<HashMap<(&'static str, bool), SerialCost>>,
    /// The GPU measured launches are predicted on, if any.
    profile: Mutex<Option<GpuProfile>>,
}

/// Seconds and threads of a kernel's serial launches, summed.
type SerialCost = (f64, u64);

/// A launch whose work on one thread is expected to take less than this runs on the
/// calling thread: handing blocks to the rayon pool costs more (waking workers).
const SERIAL_SECONDS: f64 = 20e-6;
/// A kernel whose serial cost is not yet known runs serially up to this many threads,
/// which measures it.
const SERIAL_PROBE_THREADS: u64 = 1024;
/// Threads per block of the element-wise launches (`for_each`, `transform`).
pub(crate) const ELEMENT_BLOCK: u32 = 256;

/// The race in the lowest block, so that the report does not depend on scheduling.
fn first_race(a: Option<Race>, b: Option<Race>) -> Option<Race> {
    match (a, b) {
        (Some(a), Some(b)) => Some(if (b.block, b.byte) < (a.block, a.byte) { b } else { a }),
        (a, b) => a.or(b),
    }
}

/// An emulated GPU. Cheap to clone (clones share memory accounting and statistics).
/// Launches run on the current rayon thread pool.
#[derive(Clone)]
pub struct Device {
    inner: Arc<Inner>,
}

impl Default for Device {
    fn default() -> Self {
        Device::new(DeviceConfig::default())
    }
}

/// Current and peak bytes of device memory.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct MemoryStats {
    /// Bytes allocated now.
    pub current: usize,
    /// Most bytes allocated at once since the last reset.
    pub peak: usize,
}

impl Device {
    /// A device with `config`.
    pub fn new(config: DeviceConfig) -> Device {
        let measure = AtomicBool::new(config.measure);
        let (mem, stats, pool) = (Arc::default(), Mutex::new(Stats::default()), Mutex::new(Vec::new()));
        let buffers = Arc::default();
        Device {
            inner: Arc::new(Inner {
                config,
                measure,
                mem,
                stats,
                pool,
                buffers,
                serial_cost: Default::default(),
                profile: Default::default(),
            }),
        }
    }

    /// The configuration it was made with.
    pub fn config(&self) -> &DeviceConfig {
        &self.inner.config
    }

    /// Turns detailed measurement (SIMD efficiency, requests, sectors) on or off.
    pub fn set_measure(&self, on: bool) {
        self.inner.measure.store(on, Relaxed);
    }

    /// The GPU on which measured launches are predicted ([`crate::timing::predict`]):
    /// their times sum into [`KernelSummary::gpu_seconds`]. `None` stops predicting.
    /// With a profile, measured launches also record their footprints and longest warp
    /// ([`LaunchRecord::footprint_sectors`], ..), which costs them time; without, those
    /// are 0.
    pub fn set_gpu_profile(&self, profile: Option<GpuProfile>) {
        *self.inner.profile.lock().unwrap_or_else(|e| e.into_inner()) = profile;
    }

    /// Whether measured launches gather the footprints and warp chains the GPU time
    /// model needs (only with a profile set: they cost measured launches time).
    pub(crate) fn predicting(&self) -> bool {
        self.inner.profile.lock().unwrap_or_else(|e| e.into_inner()).is_some()
    }

    /// The GPU profile set with [`Device::set_gpu_profile`].
    pub fn gpu_profile(&self) -> Option<GpuProfile> {
        self.inner.profile.lock().unwrap_or_else(|e| e.into_inner()).clone()
    }

    /// Whether launches are measured (SIMD efficiency, memory traffic) now.
    pub fn measuring(&self) -> bool {
        self.inner.measure.load(Relaxed)
    }

    // ---- memory -------------------------------------------------------------------

    /// A buffer of `n` default (zero) elements.
    pub fn alloc<T: DeviceCopy + Default>(&self, n: usize) -> DeviceBuffer<T> {
        DeviceBuffer::from_vec(self.inner.mem.clone(), vec![T::default(); n])
    }

    /// A buffer of `n` elements whose contents are unspecified (stale values of earlier
    /// buffers of the same type), for kernels that overwrite what they read, like
    /// `cudaMallocAsync` from a memory pool: when the buffer drops its allocation
    /// returns to the device's pool and the next `alloc_pooled` of that type reuses
    /// it without zero-filling (only growth past its high-water mark is filled).
    /// Counted as device memory while the buffer lives; idle pooled allocations are
    /// host memory the device keeps until it is dropped.
    pub fn alloc_pooled<T: DeviceCopy + Default>(&self, n: usize) -> DeviceBuffer<T> {
        DeviceBuffer::pooled(self.inner.mem.clone(), self.inner.buffers.clone(), n)
    }

    /// A buffer of `n` copies of `value`.
    pub fn alloc_filled<T: DeviceCopy>(&self, n: usize, value: T) -> DeviceBuffer<T> {
        DeviceBuffer::from_vec(self.inner.mem.clone(), vec![value; n])
    }

    /// A buffer holding a copy of host data (`cudaMemcpy` host to device).
    pub fn alloc_from<T: DeviceCopy>(&self, data: &[T]) -> DeviceBuffer<T> {
        DeviceBuffer::from_vec(self.inner.mem.clone(), data.to_vec())
    }

    /// A buffer taking over a host vector.
    pub fn alloc_vec<T: DeviceCopy>(&self, data: Vec<T>) -> DeviceBuffer<T> {
        DeviceBuffer::from_vec(self.inner.mem.clone(), data)
    }

    /// Counts `bytes` of host scratch as device memory until the guard drops.
    pub(crate) fn scratch(&self, bytes: usize) -> Scratch {
        Scratch::new(self.inner.mem.clone(), bytes)
    }

    /// Runs `f` with an uninitialised scratch vector of at least `bytes` (16-byte
    /// aligned), taken from the device's pool and returned to it, so that large
    /// temporaries are neither zero-filled nor faulted in again on every call. The
    /// pool keeps the largest vector it has seen; its bytes count as device memory
    /// while `f` runs.
    pub(crate) fn with_pool<R>(&self, bytes: usize, f: impl FnOnce(&mut Vec<u128>) -> R) -> R {
        let _counted = self.scratch(bytes);
        let mut v = std::mem::take(&mut *self.inner.pool.lock().unwrap_or_else(|e| e.into_inner()));
        let words = bytes.div_ceil(16);
        if v.capacity() < words {
            v = Vec::with_capacity(words);
        }
        v.clear();
        let r = f(&mut v);
        let mut pool = self.inner.pool.lock().unwrap_or_else(|e| e.into_inner());
        if v.capacity() > pool.capacity() {
            *pool = v;
        }
        r
    }

    /// Device memory now and at its peak.
    pub fn memory(&self) -> MemoryStats {
        MemoryStats { current: self.inner.mem.current(), peak: self.inner.mem.peak() }
    }

    /// Starts a new peak-memory measurement from the current allocation.
    pub fn reset_peak_memory(&self) {
        self.inner.mem.reset_peak();
    }

    // ---- launches -----------------------------------------------------------------

    /// Launches `kernel` on a grid of blocks (`kernel<<<grid, block, shared>>>`). Blocks
    /// run in parallel on rayon; threads within a block run warp by warp. Returns the
    /// launch's record, which is also added to the device statistics.
    pub fn launch<K>(&self, name: &'static str, cfg: LaunchConfig, kernel: K) -> Result<LaunchRecord, LaunchError>
    where
        K: Fn(&mut Block) + Sync,
    {
        self.launch_blocks(name, cfg, false, kernel)
    }

    /// [`Device::launch`] with the blocks started in index order, for a single-pass
    /// kernel whose blocks wait for what earlier blocks publish (a decoupled look-back,
    /// as in CUB's scans and onesweep sort): a block is taken only after every block
    /// before it, so a wait always ends. Counted like any launch. A block must not wait
    /// for rayon work of its own (its worker would stop taking blocks).
    pub fn launch_in_order<K>(
        &self,
        name: &'static str,
        cfg: LaunchConfig,
        kernel: K,
    ) -> Result<LaunchRecord, LaunchError>
    where
        K: Fn(&mut Block) + Sync,
    {
        self.launch_blocks(name, cfg, true, kernel)
    }

    fn launch_blocks<K: Fn(&mut Block) + Sync>(
        &self,
        name: &'static str,
        cfg: LaunchConfig,
        in_order: bool,
        kernel: K,
    ) -> Result<LaunchRecord, LaunchError> {
        if cfg.block == 0 || cfg.block > MAX_BLOCK_DIM {
            return Err(LaunchError::BlockSize { kernel: name, block: cfg.block });
        }
        let capacity = self.inner.config.shared_capacity;
        if cfg.shared_bytes > capacity {
            return Err(LaunchError::SharedMemory { kernel: name, requested: cfg.shared_bytes, capacity });
        }
        if cfg.regions.len() > MAX_REGIONS {
            return Err(LaunchError::Regions { kernel: name, regions: cfg.regions.len() });
        }
        let measure = self.measuring();
        let predicting = measure && self.predicting();
        let shared_words = cfg.shared_bytes.div_ceil(4);
        let run_block = |mut w: Worker, b| {
            let mut block = Block::new(&mut w, b, cfg.block, cfg.grid, shared_words, measure);
            kernel(&mut block);
            w
        };
        let finish = |w: Worker| w.meter.into_inner().finish();
        let merge =
            |(a, ra): (Counters, Option<Race>), (b, rb): (Counters, Option<Race>)| (a.merge(b), first_race(ra, rb));
        let threads = cfg.grid as u64 * cfg.block as u64;
        let ((counters, race), seconds) = self.run_blocks(name, threads, |serial| {
            if serial {
                finish((0..cfg.grid).fold(Worker::new(shared_words, predicting), run_block))
            } else if in_order {
                // Workers take blocks in index order from one counter, so every block a
                // block may wait for has been taken by a running worker.
                let next = AtomicU32::new(0);
                let workers = rayon::current_num_threads().min(cfg.grid as usize);
                (0..workers)
                    .into_par_iter()
                    .map(|_| {
                        let mut w = Worker::new(shared_words, predicting);
                        loop {
                            let b = next.fetch_add(1, Relaxed);
                            if b >= cfg.grid {
                                break finish(w);
                            }
                            w = run_block(w, b);
                        }
                    })
                    .reduce(|| (Counters::default(), None), merge)
            } else {
                (0..cfg.grid)
                    .into_par_iter()
                    .fold(|| Worker::new(shared_words, predicting), run_block)
                    .map(finish)
                    .reduce(|| (Counters::default(), None), merge)
            }
        });
        if let Some(race) = race {
            return Err(LaunchError::SharedRace { kernel: name, race });
        }
        let named = cfg.regions.len();
        if let Some(region) = (named..MAX_REGIONS).find(|&r| counters.issued[r] > 0) {
            return Err(LaunchError::UnnamedWork { kernel: name, region, named });
        }
        Ok(self.record_launch(name, &cfg, seconds, measure, in_order, counters))
    }

    /// `run(serial)`, serial when [`Device::runs_serially`] says so (then learning the
    /// kernel's cost from it); returns `run`'s result and its seconds.
    pub(crate) fn run_blocks<R>(&self, name: &'static str, threads: u64, run: impl FnOnce(bool) -> R) -> (R, f64) {
        let serial = self.runs_serially(name, threads);
        let start = Instant::now();
        let r = run(serial);
        let seconds = start.elapsed().as_secs_f64();
        if serial {
            self.note_serial(name, threads, seconds);
        }
        (r, seconds)
    }

    /// The record of a launch from its counters, added to the statistics.
    pub(crate) fn record_launch(
        &self,
        name: &'static str,
        cfg: &LaunchConfig,
        seconds: f64,
        measured: bool,
        in_order: bool,
        mut counters: Counters,
    ) -> LaunchRecord {
        let (footprint, loaded_footprint) = if measured { counters.footprints() } else { (0, 0) };
        let record = LaunchRecord {
            name,
            grid: cfg.grid,
            block: cfg.block,
            shared_bytes: cfg.shared_bytes,
            registers: cfg.registers,
            code_bytes: cfg.code_bytes,
            seconds,
            measured,
            threads: counters.threads,
            ops: RegionStats { name: "ops", issued: counters.ops_issued, active: counters.ops_active },
            regions: cfg
                .regions
                .iter()
                .enumerate()
                .map(|(i, &n)| RegionStats { name: n, issued: counters.issued[i], active: counters.active[i] })
                .collect(),
            loads: counters.loads,
            stores: counters.stores,
            atomics: counters.atomics,
            barriers: counters.barriers,
            footprint_sectors: footprint,
            loaded_footprint_sectors: loaded_footprint,
            block_sectors: counters.block_sectors,
            longest_warp: counters.longest_warp,
            waits: counters.waits,
            block_chains: counters.block_chains,
            in_order,
        };
        self.add_record(&record);
        record
    }

    /// Adds a launch to the statistics, with its predicted GPU time if the device has
    /// a profile.
    fn add_record(&self, record: &LaunchRecord) {
        let gpu =
            self.inner.profile.lock().unwrap_or_else(|e| e.into_inner()).as_ref().and_then(|p| predict(record, p));
        self.inner.stats.lock().unwrap_or_else(|e| e.into_inner()).add(record, gpu.map_or(0.0, |t| t.seconds));
    }

    /// Whether a launch of `threads` threads of kernel `name` should run on the calling
    /// thread: its serial cost per thread, from its earlier serial launches, times
    /// `threads` is under [`SERIAL_SECONDS`] (unknown: `threads` is at most
    /// [`SERIAL_PROBE_THREADS`]). Blocks are independent, so the result is the same.
    pub(crate) fn runs_serially(&self, name: &'static str, threads: u64) -> bool {
        if rayon::current_num_threads() == 1 {
            return true;
        }
        let costs = self.inner.serial_cost.lock().unwrap_or_else(|e| e.into_inner());
        match costs.get(&(name, self.measuring())) {
            Some(&(seconds, n)) => seconds / n.max(1) as f64 * threads as f64 <= SERIAL_SECONDS,
            None => threads <= SERIAL_PROBE_THREADS,
        }
    }

    /// Records a serial launch's time for [`Device::runs_serially`].
    pub(crate) fn note_serial(&self, name: &'static str, threads: u64, seconds: f64) {
        let mut costs = self.inner.serial_cost.lock().unwrap_or_else(|e| e.into_inner());
        let c = costs.entry((name, self.measuring())).or_default();
        c.0 += seconds;
        c.1 += threads;
    }

    /// One thread per element: runs `f(thread, i)` for `i in 0..n` in blocks of 256
    /// threads. The simplest launch, for element-wise kernels.
    ///
    /// ```
    /// let dev = simt::Device::default();
    /// let x = dev.alloc_from(&[1.0f32, 2.0, 3.0]);
    /// let mut y = dev.alloc_from(&[10.0f32, 20.0, 30.0]);
    /// let (xv, yv) = (x.view(), y.view_mut());
    /// dev.for_each("saxpy", 3, |t, i| t.store(&yv, i, 2.0 * t.load(&xv, i) + t.load(&yv, i)));
    /// assert_eq!(y.as_slice(), &[12.0, 24.0, 36.0]);
    /// ```
    pub fn for_each<F>(&self, name: &'static str, n: usize, f: F) -> LaunchRecord
    where
        F: Fn(&Thread, usize) + Sync,
    {
        self.for_each_in(name, &[], n, f)
    }

    /// [`Device::for_each`] for a kernel that declares arithmetic with
    /// [`Thread::work`]: `regions` names its work regions, as
    /// [`LaunchConfig::with_regions`] does for [`Device::launch`].
    ///
    /// # Panics
    /// In a measured launch, when `f` declares work in a region `regions` does not name
    /// (the statistics would lose it): a fault of the kernel, not of its input.
    pub fn for_each_in<F>(&self, name: &'static str, regions: &'static [&'static str], n: usize, f: F) -> LaunchRecord
    where
        F: Fn(&Thread, usize) + Sync,
    {
        let cfg = LaunchConfig::linear(n, ELEMENT_BLOCK).with_regions(regions);
        let launched = self.launch(name, cfg, |blk| {
            blk.for_each_thread(|t| {
                let i = t.global_idx();
                if i < n {
                    f(t, i)
                }
            })
        });
        launched.unwrap_or_else(|e| panic!("{e}"))
    }

    /// Runs `f` on the host (a primitive's CPU backend) and records it like a launch:
    /// `name`, its time and the number of elements as threads; grid and block are 0.
    pub(crate) fn host<R>(&self, name: &'static str, elements: usize, f: impl FnOnce() -> R) -> R {
        self.unmeasured_launch(name, 0, 0, elements, f).0
    }

    /// Runs `f`, natively and unmeasured, and records it as launch `name` of `grid`
    /// blocks of `block` threads with `threads` threads; returns `f`'s result and the record.
    pub(crate) fn unmeasured_launch<R>(
        &self,
        name: &'static str,
        grid: u32,
        block: u32,
        threads: usize,
        f: impl FnOnce() -> R,
    ) -> (R, LaunchRecord) {
        let start = Instant::now();
        let r = f();
        let record = LaunchRecord {
            name,
            grid,
            block,
            shared_bytes: 0,
            registers: 0,
            code_bytes: 0,
            seconds: start.elapsed().as_secs_f64(),
            measured: false,
            threads: threads as u64,
            ops: RegionStats { name: "ops", issued: 0, active: 0 },
            regions: Vec::new(),
            loads: Default::default(),
            stores: Default::default(),
            atomics: Default::default(),
            barriers: 0,
            footprint_sectors: 0,
            loaded_footprint_sectors: 0,
            block_sectors: 0,
            longest_warp: WarpChain::default(),
            waits: WarpChain::default(),
            block_chains: WarpChain::default(),
            in_order: false,
        };
        self.add_record(&record);
        (r, record)
    }

    // ---- statistics ---------------------------------------------------------------

    /// Statistics per kernel name, in order of first launch.
    pub fn kernel_stats(&self) -> Vec<KernelSummary> {
        self.inner.stats.lock().unwrap_or_else(|e| e.into_inner()).summaries()
    }

    /// The most recent launches (at most [`crate::stats::LOG_CAPACITY`]), oldest first.
    pub fn launch_log(&self) -> Vec<LaunchRecord> {
        self.inner.stats.lock().unwrap_or_else(|e| e.into_inner()).log()
    }

    /// A mark for [`Device::launches_since`]: the number of launches recorded so far.
    pub fn launch_mark(&self) -> u64 {
        self.inner.stats.lock().unwrap_or_else(|e| e.into_inner()).total()
    }

    /// The launches made since `mark` (as far as the log still holds them), oldest first.
    pub fn launches_since(&self, mark: u64) -> Vec<LaunchRecord> {
        self.inner.stats.lock().unwrap_or_else(|e| e.into_inner()).since(mark)
    }

    /// Forgets all launch statistics (memory accounting and the GPU profile are kept).
    pub fn reset_stats(&self) {
        *self.inner.stats.lock().unwrap_or_else(|e| e.into_inner()) = Stats::default();
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Small launches run on the calling thread; the choice follows each kernel's serial
    /// cost per thread (costs are injected here, so the test does not depend on timing).
    #[test]
    fn tiny_launches_run_serially_and_expensive_ones_in_parallel() {
        let pool = rayon::ThreadPoolBuilder::new().num_threads(2).build().unwrap();
        pool.install(|| {
            let dev = Device::default();
            // Unknown kernels: serial up to the probe size, parallel above it.
            assert!(dev.runs_serially("tiny", SERIAL_PROBE_THREADS));
            assert!(!dev.runs_serially("tiny", SERIAL_PROBE_THREADS + 1));
            // A serial launch records its cost; a parallel one does not.
            let mut out = dev.alloc::<u32>(4096);
            let v = out.view_mut();
            dev.for_each("tiny", 256, |t, i| t.store(&v, i, i as u32));
            dev.for_each("big", 4096, |t, i| t.store(&v, i, i as u32));
            let costs = |name| dev.inner.serial_cost.lock().unwrap().get(&(name, false)).copied();
            assert_eq!(costs("tiny").map(|c| c.1), Some(256));
            assert_eq!(costs("big"), None);
            // 1 ns per thread: 4,096 threads (4 µs) stay serial, 100,000 (100 µs) do not.
            dev.note_serial("cheap", 1000, 1e-6);
            assert!(dev.runs_serially("cheap", 4096) && !dev.runs_serially("cheap", 100_000));
            // 10 µs per thread: one thread is under the bar, four are not.
            dev.note_serial("heavy", 10, 1e-4);
            assert!(dev.runs_serially("heavy", 1) && !dev.runs_serially("heavy", 4));
            // Measured and unmeasured costs are kept apart.
            dev.set_measure(true);
            assert!(!dev.runs_serially("cheap", 4096));
        });
    }
}
