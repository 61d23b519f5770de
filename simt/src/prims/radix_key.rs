//! The keys the radix sort understands, on a floor below the sort and its native
//! backend, which both read them.

use crate::memory::DeviceCopy;

/// Keys the radix sort understands: unsigned integers.
pub trait RadixKey: DeviceCopy + Ord + Default {
    /// Bits of the key that take part in the sort.
    const BITS: u32;
    /// Bits `shift..shift + width` of the key (`width` at most 16).
    fn digit(self, shift: u32, width: u32) -> u32;
    /// The key's bits, widened.
    fn bits(self) -> u64;
}

impl RadixKey for u32 {
    const BITS: u32 = 32;
    #[inline(always)]
    fn digit(self, shift: u32, width: u32) -> u32 {
        (self >> shift) & ((1u32 << width) - 1)
    }
    #[inline(always)]
    fn bits(self) -> u64 {
        self as u64
    }
}

impl RadixKey for u64 {
    const BITS: u32 = 64;
    #[inline(always)]
    fn digit(self, shift: u32, width: u32) -> u32 {
        ((self >> shift) & ((1u64 << width) - 1)) as u32
    }
    #[inline(always)]
    fn bits(self) -> u64 {
        self
    }
}
