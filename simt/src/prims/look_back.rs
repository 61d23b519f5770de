//! Decoupled look-back (Merrill and Garland, "Single-pass Parallel Prefix Scan with
//! Decoupled Look-back", NVIDIA technical report NVR-2016-002), the step that lets a scan
//! or a radix sort pass run as one launch: each tile publishes its own total as soon as
//! it has it, walks back over the tiles before it adding their totals until it meets
//! one that has published an inclusive prefix, and then publishes its own inclusive
//! prefix. CUB's single-pass scans and its onesweep sort work this way.
//!
//! Tiles keep `slots` values each (one for a scan; one per digit for a sort pass), with
//! a status word per value. The kernels that use it run with
//! [`Device::launch_in_order`], and a tile waits, unmeasured, until the tile just before
//! it has published its inclusive prefix before walking: the walk is then always one
//! read, the GPU's shortest look-back, whichever worker ran which tile (so the counts
//! never depend on timing; what a GPU's walk and wait cost is the time model's).

use crate::device::Device;
use crate::exec::Thread;
use crate::memory::{DeviceBuffer, DeviceCopy, GlobalMut, Readable};
use std::sync::atomic::Ordering::{Acquire, Release};
use std::sync::atomic::fence;
use std::time::{Duration, Instant};

/// Status of a tile's value: not published yet.
const NOT_READY: u32 = 0;
/// Status of a tile's value: the tile's own total.
const AGGREGATE: u32 = 1;
/// Status of a tile's value: the total of every tile up to and including it.
const INCLUSIVE: u32 = 2;

/// Longest a tile waits for the one before it before the launch is taken to be
/// unordered (a tile's work is microseconds to milliseconds).
const WAIT_LIMIT: Duration = Duration::from_secs(60);

/// The status words and values of `tiles × slots` tile values.
pub(super) struct TileStatus<T: DeviceCopy> {
    flags: DeviceBuffer<u32>,
    values: DeviceBuffer<T>,
    slots: usize,
}

/// What a kernel's thread needs of a [`TileStatus`] (plain views, `Copy`).
#[derive(Clone, Copy)]
pub(super) struct StatusViews<'a, T: DeviceCopy> {
    flags: GlobalMut<'a, u32>,
    values: GlobalMut<'a, T>,
    slots: usize,
}

impl<T: DeviceCopy> TileStatus<T> {
    /// Status for `tiles` tiles of `slots` values, every one not ready. With `init`
    /// named, a launch of that name clears the words (CUB's scans run such an init
    /// kernel); without, they are cleared as a memset is, with no kernel (CUB's
    /// onesweep sort clears its look-back words with `cudaMemsetAsync`).
    pub(super) fn new(dev: &Device, tiles: usize, slots: usize, identity: T, init: Option<&'static str>) -> Self {
        let mut flags = dev.alloc::<u32>(tiles * slots);
        if let Some(name) = init {
            let n = flags.len();
            let f = flags.view_mut();
            dev.for_each(name, n, |t, i| t.store(&f, i, NOT_READY));
        }
        TileStatus { flags, values: dev.alloc_filled(tiles * slots, identity), slots }
    }

    pub(super) fn views(&mut self) -> StatusViews<'_, T> {
        StatusViews { flags: self.flags.view_mut(), values: self.values.view_mut(), slots: self.slots }
    }
}

impl<T: DeviceCopy> StatusViews<'_, T> {
    /// Whether a value and its status share one word, as CUB keeps a primitive value of
    /// up to 8 bytes (its scans' and selections' counts, the sort's digit counts): one
    /// store publishes both, one load reads both, and no fence orders them. A larger
    /// value (PDACRT's three counts) is stored, then fenced, then its status stored; a
    /// reader loads the status, fences, then loads the value (CUB's `MEMBAR.GPU`s).
    fn packed() -> bool {
        std::mem::size_of::<T>() <= 8
    }

    fn publish(&self, t: &Thread, tile: usize, slot: usize, flag: u32, value: T) {
        // Packed, CUB stores the word once; here value and status are two stores.
        let i = tile * self.slots + slot;
        t.store(&self.values, i, value);
        if Self::packed() {
            // Unmeasured: the value is visible to a waiter that sees the flag (see
            // `wait_inclusive`).
            fence(Release);
        } else {
            t.thread_fence();
        }
        t.store(&self.flags, i, flag);
    }

    /// The status and value of value `i`, loaded as CUB loads them.
    fn read(&self, t: &Thread, i: usize) -> (u32, T) {
        if Self::packed() {
            let _together = t.loads_together();
            (t.load(&self.flags, i), t.load(&self.values, i))
        } else {
            let flag = t.load(&self.flags, i);
            t.thread_fence();
            // The value's words, loaded together.
            let _together = t.loads_together();
            (flag, t.load(&self.values, i))
        }
    }

    /// Waits, unmeasured, until value `i` is published inclusive: its tile ran, or is
    /// running on another worker, since tiles are taken in order.
    fn wait_inclusive(&self, i: usize) {
        let flag = self.flags.atomic_u32(i);
        let start = Instant::now();
        let mut spins = 0u32;
        while flag.load(Acquire) != INCLUSIVE {
            spins += 1;
            if spins < 64 {
                std::hint::spin_loop();
            } else {
                std::thread::yield_now();
                if spins.is_multiple_of(1024) && start.elapsed() > WAIT_LIMIT {
                    panic!("look-back waited {WAIT_LIMIT:?} for value {i}: run the kernel with launch_in_order");
                }
            }
        }
    }

    /// Thread `t`'s look-back for value `slot` of tile `tile`, whose own total is
    /// `aggregate`: publishes it, reads the inclusive prefix of the tile before (once it
    /// is published), publishes its own inclusive prefix, and returns the exclusive one
    /// (the total of every earlier tile; `identity` for the first). `op(earlier, later)`
    /// keeps operand order. A GPU's walk over tiles that have published only their own
    /// totals is the time model's look-back term, not counted here.
    pub(super) fn look_back<F>(&self, t: &Thread, tile: usize, slot: usize, aggregate: T, identity: T, op: F) -> T
    where
        F: Fn(T, T) -> T,
    {
        if tile == 0 {
            // CUB's first tile publishes only when another tile follows.
            if self.flags.len() > self.slots {
                self.publish(t, tile, slot, INCLUSIVE, aggregate);
            }
            return identity;
        }
        self.publish(t, tile, slot, AGGREGATE, aggregate);
        let before = (tile - 1) * self.slots + slot;
        self.wait_inclusive(before);
        let (flag, prefix) = self.read(t, before);
        assert_eq!(flag, INCLUSIVE, "tile {} was waited for", tile - 1);
        self.publish(t, tile, slot, INCLUSIVE, op(prefix, aggregate));
        prefix
    }
}
