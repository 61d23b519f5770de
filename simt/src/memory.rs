//! Device memory: typed buffers with allocation accounting, and the views kernels
//! read and write through.
//!
//! A read-only view ([`Global`]) borrows its buffer immutably, so nothing can write it
//! while a kernel reads: its loads are plain whole-element loads, which the compiler
//! may vectorise and merge. A read-write view ([`GlobalMut`]) may be stored to by any
//! thread at any index, as a CUDA `T*` may, so its accesses are relaxed atomic word
//! operations: a relaxed word load or store is an ordinary `mov` on x86 and ARM, and
//! it makes racing stores defined behaviour in Rust (torn, as on a GPU, never
//! undefined). Element types implement [`DeviceCopy`]: plain data whose size and
//! alignment are multiples of 4 bytes.

use std::any::{Any, TypeId};
use std::collections::HashMap;
use std::marker::PhantomData;
use std::sync::atomic::{AtomicU32, AtomicU64, AtomicUsize, Ordering::Relaxed};
use std::sync::{Arc, Mutex};

/// Plain data that can live in device memory.
///
/// # Safety
/// The type must be `Copy`, contain no pointers or references that kernels could use
/// to reach host memory, be valid for any bit pattern written by another instance of
/// the type, have a size and alignment that are multiples of 4 bytes, and contain no
/// padding (use `#[repr(C)]` with 4-byte fields).
pub unsafe trait DeviceCopy: Copy + Send + Sync + 'static {}

unsafe impl DeviceCopy for u32 {}
unsafe impl DeviceCopy for i32 {}
unsafe impl DeviceCopy for f32 {}
unsafe impl DeviceCopy for u64 {}
unsafe impl DeviceCopy for i64 {}
unsafe impl DeviceCopy for f64 {}
unsafe impl<T: DeviceCopy, const N: usize> DeviceCopy for [T; N] {}

/// Words in one `T` (checked at compile time to be a whole number).
pub(crate) const fn words<T: DeviceCopy>() -> usize {
    assert!(
        std::mem::size_of::<T>().is_multiple_of(4) && std::mem::align_of::<T>().is_multiple_of(4),
        "DeviceCopy needs 4-byte units"
    );
    std::mem::size_of::<T>() / 4
}

/// Reads one element word by word with relaxed atomic loads.
///
/// # Safety
/// `p` must point to a live, aligned `T`.
#[inline(always)]
pub(crate) unsafe fn read_words<T: DeviceCopy>(p: *const T) -> T {
    let n = const { words::<T>() };
    let mut out = std::mem::MaybeUninit::<T>::uninit();
    let src = p as *const AtomicU32;
    let dst = out.as_mut_ptr() as *mut u32;
    for w in 0..n {
        unsafe { dst.add(w).write((*src.add(w)).load(Relaxed)) };
    }
    unsafe { out.assume_init() }
}

/// Writes one element word by word with relaxed atomic stores.
///
/// # Safety
/// `p` must point to a live, aligned `T`.
#[inline(always)]
pub(crate) unsafe fn write_words<T: DeviceCopy>(p: *mut T, v: T) {
    let n = const { words::<T>() };
    let src = &v as *const T as *const u32;
    let dst = p as *const AtomicU32;
    for w in 0..n {
        unsafe { (*dst.add(w)).store(src.add(w).read(), Relaxed) };
    }
}

/// Current and peak bytes allocated on a device.
#[derive(Debug, Default)]
pub(crate) struct MemCounter {
    current: AtomicUsize,
    peak: AtomicUsize,
    next_base: AtomicU64,
}

impl MemCounter {
    fn alloc(&self, bytes: usize) -> u64 {
        let now = self.current.fetch_add(bytes, Relaxed) + bytes;
        self.peak.fetch_max(now, Relaxed);
        // A virtual address for sector accounting: each buffer starts 256-byte aligned,
        // as cudaMalloc guarantees, and buffers never share a sector.
        let span = (bytes as u64).div_ceil(256).max(1) * 256;
        self.next_base.fetch_add(span, Relaxed) + 256
    }
    fn free(&self, bytes: usize) {
        self.current.fetch_sub(bytes, Relaxed);
    }
    pub(crate) fn current(&self) -> usize {
        self.current.load(Relaxed)
    }
    pub(crate) fn peak(&self) -> usize {
        self.peak.load(Relaxed)
    }
    pub(crate) fn reset_peak(&self) {
        self.peak.store(self.current(), Relaxed);
    }
}

/// Allocations returned by dropped pooled buffers, by element type, for
/// [`crate::Device::alloc_pooled`] to hand out again without zero-filling.
#[derive(Default)]
pub(crate) struct BufferPool {
    free: Mutex<HashMap<TypeId, Vec<Box<dyn Any + Send>>>>,
}

/// Allocations the pool keeps per element type (the largest ones).
const POOLED_PER_TYPE: usize = 8;

impl BufferPool {
    /// A pooled vector of `T` whose high-water length is at least `n` (elements beyond
    /// the previous high-water mark are filled with defaults; the rest are stale).
    pub(crate) fn take<T: DeviceCopy + Default>(&self, n: usize) -> Vec<T> {
        let mut free = self.free.lock().unwrap_or_else(|e| e.into_inner());
        let list = free.entry(TypeId::of::<T>()).or_default();
        // The smallest that fits, else the largest (grown).
        let len = |b: &Box<dyn Any + Send>| b.downcast_ref::<Vec<T>>().map_or(0, Vec::len);
        let pick = (0..list.len())
            .filter(|&i| len(&list[i]) >= n)
            .min_by_key(|&i| len(&list[i]))
            .or_else(|| (0..list.len()).max_by_key(|&i| len(&list[i])));
        let mut v = match pick {
            Some(i) => *list.swap_remove(i).downcast::<Vec<T>>().expect("pooled by type"),
            None => Vec::new(),
        };
        drop(free);
        if v.len() < n {
            v.resize(n, T::default());
        }
        v
    }

    fn give<T: DeviceCopy>(&self, v: Vec<T>) {
        let mut free = self.free.lock().unwrap_or_else(|e| e.into_inner());
        let list = free.entry(TypeId::of::<T>()).or_default();
        list.push(Box::new(v));
        if list.len() > POOLED_PER_TYPE {
            let len = |b: &Box<dyn Any + Send>| b.downcast_ref::<Vec<T>>().map_or(0, Vec::len);
            let smallest = (0..list.len()).min_by_key(|&i| len(&list[i])).expect("non-empty");
            list.swap_remove(smallest);
        }
    }
}

/// Bytes a primitive's CPU backend holds as scratch, counted as device memory while
/// the guard lives (the kernels would hold them on the device).
pub(crate) struct Scratch {
    bytes: usize,
    mem: Arc<MemCounter>,
}

impl Scratch {
    pub(crate) fn new(mem: Arc<MemCounter>, bytes: usize) -> Scratch {
        mem.alloc(bytes);
        Scratch { bytes, mem }
    }
}

impl Drop for Scratch {
    fn drop(&mut self) {
        self.mem.free(self.bytes);
    }
}

/// A typed allocation in device memory. Dropping it frees its bytes in the device's
/// accounting. The host reads and writes it between launches; kernels reach it through
/// [`Global`] and [`GlobalMut`] views.
pub struct DeviceBuffer<T: DeviceCopy> {
    /// The allocation; its length is the buffer's high-water mark.
    data: Vec<T>,
    /// Elements in use (`<= data.len()`).
    len: usize,
    vbase: u64,
    mem: Arc<MemCounter>,
    /// Where the allocation goes when the buffer drops (pooled buffers only).
    pool: Option<Arc<BufferPool>>,
}

impl<T: DeviceCopy> DeviceBuffer<T> {
    pub(crate) fn from_vec(mem: Arc<MemCounter>, data: Vec<T>) -> Self {
        let _ = const { words::<T>() };
        let vbase = mem.alloc(data.len() * std::mem::size_of::<T>());
        DeviceBuffer { len: data.len(), data, vbase, mem, pool: None }
    }

    /// A buffer of `n` elements on a pooled allocation (contents unspecified).
    pub(crate) fn pooled(mem: Arc<MemCounter>, pool: Arc<BufferPool>, n: usize) -> Self
    where
        T: Default,
    {
        let data = pool.take::<T>(n);
        let mut b = Self::from_vec(mem, data);
        b.len = n;
        b.pool = Some(pool);
        b
    }

    /// Elements.
    pub fn len(&self) -> usize {
        self.len
    }

    /// Whether it has no elements.
    pub fn is_empty(&self) -> bool {
        self.len == 0
    }

    /// Bytes of the elements in use.
    pub fn bytes(&self) -> usize {
        self.len * std::mem::size_of::<T>()
    }

    /// Bytes the allocation holds (what the device's accounting counts).
    pub fn held_bytes(&self) -> usize {
        self.data.len() * std::mem::size_of::<T>()
    }

    /// Sets the length to `n`, reusing the allocation when it is large enough, as a
    /// pooled device allocator would: nothing is zero-filled, and elements that were
    /// there keep their (stale) contents. Only growth past the high-water mark
    /// allocates (and fills the new part with defaults); the accounting follows the
    /// bytes held, which never shrink until the buffer is dropped.
    pub fn resize(&mut self, n: usize)
    where
        T: Default,
    {
        if n > self.data.len() {
            self.mem.free(self.held_bytes());
            self.data.resize(n, T::default());
            self.vbase = self.mem.alloc(self.held_bytes());
        }
        self.len = n;
    }

    /// The contents, for the host.
    pub fn as_slice(&self) -> &[T] {
        &self.data[..self.len]
    }

    /// The contents, for the host to change between launches.
    pub fn as_mut_slice(&mut self) -> &mut [T] {
        &mut self.data[..self.len]
    }

    /// The contents as a host vector, without a copy; the buffer's bytes leave the
    /// device's accounting (and a pooled allocation does not go back to the pool).
    pub fn into_vec(mut self) -> Vec<T> {
        self.mem.free(self.held_bytes());
        self.pool = None;
        let mut v = std::mem::take(&mut self.data);
        v.truncate(self.len);
        v
    }

    /// A host copy of the contents (a device-to-host transfer).
    pub fn to_vec(&self) -> Vec<T> {
        self.as_slice().to_vec()
    }

    /// A read-only view for kernels.
    pub fn view(&self) -> Global<'_, T> {
        Global { ptr: self.data.as_ptr(), len: self.len, vbase: self.vbase, _life: PhantomData }
    }

    /// A read-write view for kernels. While it lives the host cannot touch the buffer.
    pub fn view_mut(&mut self) -> GlobalMut<'_, T> {
        GlobalMut { ptr: self.data.as_mut_ptr(), len: self.len, vbase: self.vbase, _life: PhantomData }
    }

    /// A view of elements `start..start + len`.
    pub fn slice(&self, start: usize, len: usize) -> Global<'_, T> {
        assert!(start + len <= self.len, "slice {start}..{} of a buffer of {}", start + len, self.len);
        let size = std::mem::size_of::<T>() as u64;
        Global { ptr: self.data[start..].as_ptr(), len, vbase: self.vbase + start as u64 * size, _life: PhantomData }
    }
}

impl<T: DeviceCopy> Drop for DeviceBuffer<T> {
    fn drop(&mut self) {
        self.mem.free(self.held_bytes());
        if let Some(pool) = self.pool.take() {
            pool.give(std::mem::take(&mut self.data));
        }
    }
}

impl<T: DeviceCopy + std::fmt::Debug> std::fmt::Debug for DeviceBuffer<T> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("DeviceBuffer").field("len", &self.len()).field("bytes", &self.bytes()).finish()
    }
}

/// Asks the host CPU to start loading the `n` elements from `p` into its caches: a
/// hint for the emulator's own speed where a lane's next loads are known before it
/// needs them (a GPU overlaps a warp's independent loads by itself). It reads nothing,
/// so `p` need not be valid, and no launch measures it. Does nothing off x86-64.
#[inline(always)]
pub fn prefetch_host<T>(p: *const T, n: usize) {
    #[cfg(target_arch = "x86_64")]
    {
        use std::arch::x86_64::{_MM_HINT_T0, _mm_prefetch};
        let first = p as *const i8;
        for offset in (0..n * std::mem::size_of::<T>()).step_by(64) {
            // SAFETY: SSE is part of x86-64's baseline, and a prefetch reads nothing (the
            // address need not be valid).
            unsafe { _mm_prefetch::<_MM_HINT_T0>(first.wrapping_add(offset)) };
        }
    }
    #[cfg(not(target_arch = "x86_64"))]
    let _ = (p, n);
}

/// A read-only kernel view of a buffer (like a `const T*` kernel argument).
#[derive(Clone, Copy)]
pub struct Global<'a, T: DeviceCopy> {
    ptr: *const T,
    len: usize,
    vbase: u64,
    _life: PhantomData<&'a [T]>,
}

/// A read-write kernel view of a buffer (like a `T*` kernel argument).
#[derive(Clone, Copy)]
pub struct GlobalMut<'a, T: DeviceCopy> {
    ptr: *mut T,
    len: usize,
    vbase: u64,
    _life: PhantomData<&'a [T]>,
}

// SAFETY: a `Global` only reads memory that nothing writes while it lives (it borrows
// the buffer immutably); a `GlobalMut` accesses through relaxed atomic word operations.
unsafe impl<T: DeviceCopy> Send for Global<'_, T> {}
unsafe impl<T: DeviceCopy> Sync for Global<'_, T> {}
unsafe impl<T: DeviceCopy> Send for GlobalMut<'_, T> {}
unsafe impl<T: DeviceCopy> Sync for GlobalMut<'_, T> {}

/// What kernels can load from: both view kinds.
pub trait Readable<T: DeviceCopy>: Copy + Send + Sync {
    /// Elements.
    fn len(&self) -> usize;
    /// Whether it has no elements.
    fn is_empty(&self) -> bool {
        self.len() == 0
    }
    /// Byte address of element `i` in the device's virtual address space.
    fn address(&self, i: usize) -> u64;
    /// Loads element `i` without measurement (bounds-checked).
    fn read(&self, i: usize) -> T;
    /// Loads element `i` without measurement or a bounds check.
    ///
    /// # Safety
    /// `i < self.len()`.
    #[inline(always)]
    unsafe fn read_unchecked(&self, i: usize) -> T {
        self.read(i)
    }
    /// Elements `start..start + len` as a plain slice, where nothing can store to them
    /// while the view lives (a read-only view); `None` for a read-write view.
    ///
    /// # Safety
    /// `start + len <= self.len()`.
    unsafe fn plain_slice(&self, start: usize, len: usize) -> Option<&[T]> {
        let _ = (start, len);
        None
    }
}

impl<T: DeviceCopy> Global<'_, T> {
    /// [`prefetch_host`] for elements `start..start + n` (clipped to the view): counts
    /// no load, in a measured launch or not.
    #[inline(always)]
    pub fn prefetch(&self, start: usize, n: usize) {
        prefetch_host(self.ptr.wrapping_add(start), n.min(self.len.saturating_sub(start)));
    }
}

impl<T: DeviceCopy> GlobalMut<'_, T> {
    /// [`Global::prefetch`] on a read-write view.
    #[inline(always)]
    pub fn prefetch(&self, start: usize, n: usize) {
        prefetch_host(self.ptr.wrapping_add(start), n.min(self.len.saturating_sub(start)));
    }
}

impl<T: DeviceCopy> Readable<T> for Global<'_, T> {
    fn len(&self) -> usize {
        self.len
    }
    #[inline(always)]
    fn address(&self, i: usize) -> u64 {
        self.vbase + (i * std::mem::size_of::<T>()) as u64
    }
    #[inline(always)]
    fn read(&self, i: usize) -> T {
        assert!(i < self.len, "load of element {i} from a buffer of {}", self.len);
        // SAFETY: in bounds; the buffer is borrowed immutably for 'a, so no store races.
        unsafe { self.ptr.add(i).read() }
    }
    #[inline(always)]
    unsafe fn read_unchecked(&self, i: usize) -> T {
        // SAFETY: the caller keeps `i` in bounds; nothing stores while 'a lives.
        unsafe { self.ptr.add(i).read() }
    }
    #[inline(always)]
    unsafe fn plain_slice(&self, start: usize, len: usize) -> Option<&[T]> {
        // SAFETY: the caller keeps the range in bounds; nothing stores while 'a lives.
        Some(unsafe { std::slice::from_raw_parts(self.ptr.add(start), len) })
    }
}

/// A read-write view reads word by word with relaxed atomic loads (another thread
/// may be storing to the same element).
impl<T: DeviceCopy> Readable<T> for GlobalMut<'_, T> {
    fn len(&self) -> usize {
        self.len
    }
    #[inline(always)]
    fn address(&self, i: usize) -> u64 {
        self.vbase + (i * std::mem::size_of::<T>()) as u64
    }
    #[inline(always)]
    fn read(&self, i: usize) -> T {
        assert!(i < self.len, "load of element {i} from a buffer of {}", self.len);
        unsafe { read_words(self.ptr.add(i)) }
    }
}

impl<'a, T: DeviceCopy> GlobalMut<'a, T> {
    /// Stores element `i` without measurement (bounds-checked).
    #[inline(always)]
    pub fn write(&self, i: usize, v: T) {
        assert!(i < self.len, "store to element {i} of a buffer of {}", self.len);
        unsafe { write_words(self.ptr.add(i), v) }
    }

    /// Stores `v` at byte `at` of element `i` (a field of it, as `Thread::store_field`
    /// found it: inside the element and aligned for `U`).
    #[inline(always)]
    pub(crate) fn write_at<U: DeviceCopy>(&self, i: usize, at: usize, v: U) {
        assert!(i < self.len, "store to element {i} of a buffer of {}", self.len);
        assert!(
            at + std::mem::size_of::<U>() <= std::mem::size_of::<T>() && at.is_multiple_of(std::mem::align_of::<U>())
        );
        unsafe { write_words((self.ptr.add(i) as *mut u8).add(at) as *mut U, v) }
    }

    pub(crate) fn atomic_u32(&self, i: usize) -> &AtomicU32 {
        assert!(i < self.len, "atomic on element {i} of a buffer of {}", self.len);
        const { assert!(std::mem::size_of::<T>() == 4) };
        unsafe { &*(self.ptr.add(i) as *const AtomicU32) }
    }

    pub(crate) fn atomic_u64(&self, i: usize) -> &AtomicU64 {
        assert!(i < self.len, "atomic on element {i} of a buffer of {}", self.len);
        const { assert!(std::mem::size_of::<T>() == 8 && std::mem::align_of::<T>() == 8) };
        unsafe { &*(self.ptr.add(i) as *const AtomicU64) }
    }
}
