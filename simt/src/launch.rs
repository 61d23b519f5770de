//! The shape of a launch and the ways a launch can be refused or fail.

use crate::limits::MAX_REGIONS;
use crate::meter::Race;

/// Largest block, as on current NVIDIA GPUs.
pub const MAX_BLOCK_DIM: u32 = 1024;

/// The shape of a launch: `grid` blocks of `block` threads, `shared_bytes` of shared
/// memory per block, and the names of the regions the kernel reports work in.
#[derive(Clone, Debug)]
pub struct LaunchConfig {
    /// Blocks in the grid.
    pub grid: u32,
    /// Threads per block (a multiple of the warp width is best).
    pub block: u32,
    /// Dynamic shared memory per block, bytes.
    pub shared_bytes: usize,
    /// Names of the work regions the kernel declares with `Thread::work`, in order.
    pub regions: &'static [&'static str],
    /// Registers per thread of the kernel's compiled GPU twin (`ncu`'s
    /// `launch__registers_per_thread`; the emulator cannot know them), which bound how
    /// many blocks an SM holds; 0 when not known (no bound).
    pub registers: u32,
    /// Bytes of the twin's compiled code (`cuobjdump -sass`; the emulator cannot know
    /// them), which tell whether its warps fetch their instructions from beyond the SM's
    /// instruction cache; 0 when not known (taken as fitting).
    pub code_bytes: u32,
}

impl LaunchConfig {
    /// Enough blocks of `block` threads to cover `n` threads.
    pub fn linear(n: usize, block: u32) -> LaunchConfig {
        let grid = n.div_ceil(block.max(1) as usize).min(u32::MAX as usize) as u32;
        LaunchConfig { grid, block, shared_bytes: 0, regions: &[], registers: 0, code_bytes: 0 }
    }

    /// This configuration with `bytes` of shared memory per block.
    pub fn with_shared(mut self, bytes: usize) -> LaunchConfig {
        self.shared_bytes = bytes;
        self
    }

    /// This configuration with the registers per thread its GPU twin uses.
    pub fn with_registers(mut self, registers: u32) -> LaunchConfig {
        self.registers = registers;
        self
    }

    /// This configuration with the bytes of its GPU twin's compiled code.
    pub fn with_code_bytes(mut self, bytes: u32) -> LaunchConfig {
        self.code_bytes = bytes;
        self
    }

    /// This configuration with named work regions.
    pub fn with_regions(mut self, regions: &'static [&'static str]) -> LaunchConfig {
        self.regions = regions;
        self
    }
}

/// Why a launch was refused. Nothing runs when a launch fails.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum LaunchError {
    #[error("kernel '{kernel}' asks for {requested} bytes of shared memory per block; the device has {capacity}")]
    /// A launch asked for more shared memory per block than the device has.
    SharedMemory {
        /// The kernel.
        kernel: &'static str,
        /// Bytes asked for.
        requested: usize,
        /// Bytes a block may have.
        capacity: usize,
    },
    #[error("kernel '{kernel}' has a block of {block} threads; blocks hold 1 to {MAX_BLOCK_DIM}")]
    /// A launch asked for a block size of zero or above the limit.
    BlockSize {
        /// The kernel.
        kernel: &'static str,
        /// Threads per block asked for.
        block: u32,
    },
    #[error("kernel '{kernel}' names {regions} regions; at most {MAX_REGIONS}")]
    /// A launch declared more work regions than a kernel may have.
    Regions {
        /// The kernel.
        kernel: &'static str,
        /// Regions declared.
        regions: usize,
    },
    /// Found in measured launches only (the kernel ran; its results are suspect).
    #[error(
        "kernel '{kernel}': shared-memory race ({}) on byte {} in block {}: threads {} and {} touch it with no sync_threads between them",
        race.hazard, race.byte, race.block, race.first, race.second
    )]
    SharedRace {
        /// The kernel.
        kernel: &'static str,
        /// The first race found.
        race: Race,
    },
    /// Found in measured launches only (the kernel ran; its statistics would have lost
    /// the work): `Thread::work` or `Block::work_uniform` named a region the launch's
    /// configuration has no name for.
    #[error(
        "kernel '{kernel}' declared work in region {region}, but its launch names {named} region(s) (LaunchConfig::with_regions, Device::for_each_in)"
    )]
    UnnamedWork {
        /// The kernel.
        kernel: &'static str,
        /// The lowest region with work and no name.
        region: usize,
        /// Regions the launch names.
        named: usize,
    },
}
