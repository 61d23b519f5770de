//! A work queue kernels push into with an atomic counter (per-material queues of a
//! wavefront renderer). The order of items depends on scheduling: never derive random
//! numbers or results from an item's position.

use crate::device::Device;
use crate::exec::Thread;
use crate::memory::{DeviceBuffer, DeviceCopy, GlobalMut, Readable};

/// A device-side queue: a buffer and an atomic length that kernels push to (`QueuePusher`).
pub struct WorkQueue<T: DeviceCopy> {
    items: DeviceBuffer<T>,
    count: DeviceBuffer<u32>,
}

impl<T: DeviceCopy + Default> WorkQueue<T> {
    /// A queue of at most `capacity` items.
    pub fn new(dev: &Device, capacity: usize) -> Self {
        WorkQueue { items: dev.alloc(capacity), count: dev.alloc(1) }
    }
}

impl<T: DeviceCopy> WorkQueue<T> {
    /// Most items it can hold.
    pub fn capacity(&self) -> usize {
        self.items.len()
    }

    /// Items held (pushes beyond the capacity are dropped and counted in [`Self::dropped`]).
    pub fn len(&self) -> usize {
        (self.count.as_slice()[0] as usize).min(self.capacity())
    }

    /// Whether nothing has been pushed since the last clear.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Pushes that found the queue full.
    pub fn dropped(&self) -> usize {
        (self.count.as_slice()[0] as usize).saturating_sub(self.capacity())
    }

    /// The items pushed so far.
    pub fn items(&self) -> &[T] {
        &self.items.as_slice()[..self.len()]
    }

    /// The whole item buffer (for launches over the queue).
    pub fn buffer(&self) -> &DeviceBuffer<T> {
        &self.items
    }

    /// Empties the queue (the storage is kept).
    pub fn clear(&mut self) {
        self.count.as_mut_slice()[0] = 0;
    }

    /// The kernel-side handle.
    pub fn pusher(&mut self) -> QueuePusher<'_, T> {
        QueuePusher { items: self.items.view_mut(), count: self.count.view_mut() }
    }
}

/// Pushes into a [`WorkQueue`] from kernels.
#[derive(Clone, Copy)]
pub struct QueuePusher<'a, T: DeviceCopy> {
    items: GlobalMut<'a, T>,
    count: GlobalMut<'a, u32>,
}

impl<T: DeviceCopy> QueuePusher<'_, T> {
    /// Appends `item`; returns its slot, or `None` when the queue is full.
    #[track_caller]
    pub fn push(&self, t: &Thread, item: T) -> Option<usize> {
        let slot = t.atomic_add(&self.count, 0, 1) as usize;
        (slot < self.items.len()).then(|| {
            t.store(&self.items, slot, item);
            slot
        })
    }
}
