//! What one bounce of the stream read and wrote in `cis::shade` and in the compaction
//! after it, handed to an observer: the GPU check (`examples/gpu_check/`) runs the same
//! inputs through the CUDA twins and compares. Copies are made only while an observer
//! is set.

use super::kernels::{PendingData, Slot};
use crate::geometry::Hit;
use crate::render::bidir::Vertex;
use crate::render::cache::host::{Connections, StrategyCounts};

/// One bounce of one pass, as `cis::shade` and the compaction saw it. The fields are
/// the stream's own records; outside the crate only their sizes and the bounce's place
/// are visible, and `warpray::gpu` (feature `cuda`) reads the rest.
#[cfg_attr(not(feature = "cuda"), allow(dead_code))]
pub struct ShadeCapture<'a> {
    /// The pass (iteration).
    pub pass: u32,
    /// The wavefront iteration within the pass.
    pub bounce: u32,
    /// Whether the samples were shaded in material order.
    pub sorted: bool,
    pub(crate) order: &'a [u32],
    pub(crate) active: &'a [u32],
    pub(crate) hits: &'a [Hit],
    pub(crate) slots_before: &'a [Slot],
    pub(crate) vertices_before: &'a [Vertex],
    pub(crate) slots: &'a [Slot],
    pub(crate) vertices: &'a [Vertex],
    pub(crate) pending: &'a [PendingData],
    /// The pool after the connect stage, as the compaction read it.
    pub(crate) slots_compacted: &'a [Slot],
    /// The active samples the compaction kept.
    pub(crate) kept: &'a [u32],
    pub(crate) cache_vertices: &'a [Vertex],
    pub(crate) cache_entries: &'a [[u32; 2]],
    pub(crate) counts: StrategyCounts,
    pub(crate) connections: Connections,
}

impl ShadeCapture<'_> {
    /// Samples shaded (threads of the launch).
    pub fn active_samples(&self) -> usize {
        self.order.len()
    }

    /// Slots in the pool.
    pub fn pool(&self) -> usize {
        self.slots.len()
    }

    /// Samples the compaction kept.
    pub fn kept(&self) -> usize {
        self.kept.len()
    }
}

/// A function that sees every bounce of a CIS-LBDPT render ([`super::CisLbdpt::observe`]).
pub type ShadeObserver = Box<dyn FnMut(&ShadeCapture) + Send>;
