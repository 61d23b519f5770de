//! Decoupled look-back (Merrill and Garland, "Single-pass Parallel Prefix Scan with
//! Decoupled Look-back", NVIDIA technical report NVR-2016-002), the step that lets a scan
//! or a radix sort pass run as one launch: each tile publishes its own total as soon as
//! it has it, walks back over the tiles before it adding their totals until it meets
//! one that has published an inclusive prefix, and then publishes its own inclusive
//! prefix. CUB's single-pass scans and its onesweep sort work this way.
//!
//! Tiles keep `slots` values each (one for a scan; one per digit for a sort pass), with
//! a status word per value. The kernels that use it run with
//! [`Device::launch_in_order`], so the walk always finds the tile just before
//! finished: one read, the GPU's shortest look-back.

use crate::device::Device;
use crate::exec::Thread;
use crate::memory::{DeviceBuffer, DeviceCopy, GlobalMut};

/// Status of a tile's value: not published yet.
const NOT_READY: u32 = 0;
/// Status of a tile's value: the tile's own total.
const AGGREGATE: u32 = 1;
/// Status of a tile's value: the total of every tile up to and including it.
const INCLUSIVE: u32 = 2;

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
    fn publish(&self, t: &Thread, tile: usize, slot: usize, flag: u32, value: T) {
        // CUB packs a 4-byte value and its status in one 8-byte word and stores it once;
        // here they are two stores (the walk below reads them as one round).
        let i = tile * self.slots + slot;
        t.store(&self.values, i, value);
        t.store(&self.flags, i, flag);
    }

    /// Thread `t`'s look-back for value `slot` of tile `tile`, whose own total is
    /// `aggregate`: publishes it, walks back, publishes the inclusive prefix, and
    /// returns the exclusive one (the total of every earlier tile; `identity` for the
    /// first). `op(earlier, later)` keeps operand order.
    pub(super) fn look_back<F>(&self, t: &Thread, tile: usize, slot: usize, aggregate: T, identity: T, op: F) -> T
    where
        F: Fn(T, T) -> T,
    {
        if tile == 0 {
            self.publish(t, tile, slot, INCLUSIVE, aggregate);
            return identity;
        }
        self.publish(t, tile, slot, AGGREGATE, aggregate);
        let mut prefix = identity;
        for p in (0..tile).rev() {
            let i = p * self.slots + slot;
            let (flag, value) = {
                let _together = t.loads_together();
                (t.load(&self.flags, i), t.load(&self.values, i))
            };
            match flag {
                INCLUSIVE => {
                    prefix = op(value, prefix);
                    break;
                }
                AGGREGATE => prefix = op(value, prefix),
                // A GPU's block would wait here for tile `p` to publish.
                _ => panic!("look-back reached tile {p}, which has not published: run the kernel with launch_in_order"),
            }
        }
        self.publish(t, tile, slot, INCLUSIVE, op(prefix, aggregate));
        prefix
    }
}
