//! Work declared by code that does not hold the [`Thread`]: functions a kernel shares
//! with host code (a renderer's BSDFs, its MIS weights) declare their arithmetic with
//! [`declare!`](crate::declare!), their reads of memory the kernel sees as global (a
//! scene's tables, read through plain references) with [`read!`](crate::read!), and mark
//! the calls and loops whose copies a GPU compiler keeps apart with [`scope`]. Inside [`Thread::ambient`] these record into that lane's measurement as
//! [`Thread::work`] would; anywhere else (host code, an unmeasured launch) they cost a
//! thread-local read and do nothing.
//!
//! Why scopes: nvcc inlines a device function at each call site, and lanes reconverge
//! after a loop. Without scopes the meter matches a lane's n-th execution of a site
//! with the other lanes' n-th, so after one lane made three trips of a loop and another
//! five, their next calls would be matched three against five. A scope entered at a call
//! site or loop is a copy of the code inside, told apart by the site and by how many
//! times the lane entered it: the lanes' k-th entries are one copy, in which trips are
//! matched again from the first.

use crate::exec::{Thread, access_width, enter_scope, leave_copy, note_global, note_work, site};
use crate::meter::Kind;
use crate::meter::Meter;
use std::cell::{Cell, RefCell};

/// The lane whose work `declare` records, and the region it goes to.
#[derive(Clone, Copy)]
struct Ambient {
    meter: *const RefCell<Meter>,
    lane: u32,
    region: usize,
}

thread_local! {
    static AMBIENT: Cell<Option<Ambient>> = const { Cell::new(None) };
}

/// Puts the previous ambient lane back, and the lane's copy as it was when the ambient
/// call began (so a scope guard kept past the call cannot leave later code in its
/// copy), also when the call unwinds.
struct Restore<'a> {
    previous: Option<Ambient>,
    meter: &'a RefCell<Meter>,
    copy: usize,
}

impl Drop for Restore<'_> {
    fn drop(&mut self) {
        AMBIENT.set(self.previous);
        leave_copy(self.meter, self.copy);
    }
}

impl Thread<'_> {
    /// Runs `f` with this thread as the *ambient* lane: [`declare!`](crate::declare!) and [`scope`] called
    /// anywhere inside `f` (in code that does not hold the thread) record into it, the
    /// declared work in region `region` (named by the launch like any region). In an
    /// unmeasured launch `f` runs with no ambient lane.
    pub fn ambient<R>(&self, region: usize, f: impl FnOnce() -> R) -> R {
        let Some(meter) = self.meter() else { return f() };
        let copy = meter.borrow().copy;
        let previous = AMBIENT.replace(Some(Ambient { meter, lane: self.thread_idx(), region }));
        let _restore = Restore { previous, meter, copy };
        f()
    }
}

#[inline(always)]
fn ambient() -> Option<Ambient> {
    AMBIENT.get()
}

/// Declares `units` instructions of arithmetic at a site of its own (the macro's place in
/// the source) for the ambient lane ([`Thread::ambient`]); outside one, nothing. Lanes
/// at the same site, copy and occurrence share a warp instruction issued `max(units)`
/// times, as with [`Thread::work`]. The work goes to the region the ambient call named,
/// or with `declare!(units, part k)` to the k-th region after it (so shared code can
/// split its work by part of the code, each part a region the launch names). A macro
/// rather than a `#[track_caller]` function: inside a `#[track_caller]` function (one
/// that opens a [`scope`] per call site) the caller's location would pass through to
/// every declaration in its body.
#[macro_export]
macro_rules! declare {
    ($units:expr) => {
        $crate::declare!($units, part 0)
    };
    ($units:expr, part $part:expr) => {
        $crate::ambient::declare_at(
            {
                const SITE: usize = $crate::ambient::site_of(::core::file!(), ::core::line!(), ::core::column!());
                SITE
            },
            $part,
            $units,
        )
    };
}

/// Reads `$slice[$i]` and, for the ambient lane ([`Thread::ambient`]), records it as a
/// global load of the element (the slice placed on a 256-byte boundary), at a site of its own (the macro's place,
/// in the lane's current copy, as [`declare!`]): what [`Thread::load`] records for a
/// view. Outside an ambient lane it is the plain read.
#[macro_export]
macro_rules! read {
    ($slice:expr, $i:expr) => {{
        let (slice, i) = (&$slice, $i);
        $crate::ambient::read_at(
            {
                const SITE: usize = $crate::ambient::site_of(::core::file!(), ::core::line!(), ::core::column!());
                SITE
            },
            &slice[..],
            i,
        );
        slice[i]
    }};
}

/// Records, for the ambient lane, `$words` 4-byte loads from the start of the record
/// `$place` points at (a `&T` into memory the kernel sees as global), at a site of its
/// own: compiled code that reads a record through a reference loads the fields it uses,
/// one instruction each, where it uses them. Like an instruction, a site loads the same
/// number of words every time. Outside an ambient lane, nothing.
#[macro_export]
macro_rules! read_words {
    ($place:expr, $words:expr) => {
        $crate::ambient::read_words_at(
            {
                const SITE: usize = $crate::ambient::site_of(::core::file!(), ::core::line!(), ::core::column!());
                SITE
            },
            $place,
            $words,
        )
    };
}

/// Where the model places host memory that shared code reads: at 256 times its host
/// address, so that each slice (or record) begins on a 256-byte boundary, as a
/// `cudaMalloc` allocation does, whatever alignment the host allocator gave it, and
/// sector counts do not change from run to run; distinct host objects stay apart. The
/// top bit marks the address as host memory (`limits::HOST_ADDRESS_BIT`), whose
/// sectors the footprint counts one by one: a hash sample of them would change with
/// the host addresses.
#[inline(always)]
fn model_address(host: *const u8) -> u64 {
    (host as u64).wrapping_shl(8) | crate::limits::HOST_ADDRESS_BIT
}

/// The function behind [`read!`]: records a load of `slice[i]` for the ambient lane;
/// outside one, nothing.
#[doc(hidden)]
#[inline(always)]
pub fn read_at<T>(site: usize, slice: &[T], i: usize) {
    note_read(site, std::mem::size_of::<T>() as u64, access_width::<T>(), || {
        model_address(slice.as_ptr().cast()) + (i * std::mem::size_of::<T>()) as u64
    });
}

/// The function behind [`read_words!`]: records `words` 4-byte loads from the start of
/// `record` for the ambient lane; outside one, nothing.
#[doc(hidden)]
#[inline(always)]
pub fn read_words_at<T: ?Sized>(site: usize, record: &T, words: u32) {
    if words > 0 {
        note_read(site, 4 * words as u64, 4, || model_address((record as *const T).cast()));
    }
}

#[inline(always)]
fn note_read(site: usize, size: u64, width: u64, addr: impl FnOnce() -> u64) {
    if let Some(a) = ambient() {
        let addr = addr();
        // Salted: a macro that declares work and records a read expands both at one
        // place in the source, and they are two instructions.
        let site = site ^ 0x2545_f491_4f6c_dd1d_u64 as usize;
        // SAFETY: as in `declare_at`.
        note_global(unsafe { &*a.meter }, a.lane, site, Kind::Load, addr, (size, width), true);
    }
}

/// A site key for a place in the source, computed when the crate compiles (what
/// [`declare!`] passes): a hash of the file's name, line and column, the same in every
/// build and wherever the code is inlined.
#[doc(hidden)]
pub const fn site_of(file: &str, line: u32, column: u32) -> usize {
    let bytes = file.as_bytes();
    let mut h: u64 = 0xcbf2_9ce4_8422_2325;
    let mut i = 0;
    while i < bytes.len() {
        h = (h ^ bytes[i] as u64).wrapping_mul(0x100_0000_01b3);
        i += 1;
    }
    h = (h ^ line as u64).wrapping_mul(0x100_0000_01b3);
    h = (h ^ column as u64).wrapping_mul(0x100_0000_01b3);
    h as usize
}

/// True while an ambient lane records on this thread ([`Thread::ambient`] in a
/// measured launch): code shared with the host may then have to run the way the
/// kernel's CUDA twin runs, so that the work it declares is the twin's.
#[inline(always)]
pub fn counting() -> bool {
    ambient().is_some()
}

/// The function behind [`declare!`].
#[doc(hidden)]
#[inline(always)]
pub fn declare_at(site: usize, part: usize, units: u32) {
    if let Some(a) = ambient() {
        // SAFETY: `Thread::ambient` sets the pointer from a borrow that outlives the
        // closure it runs, and puts the previous value back before returning or
        // unwinding; nothing else writes `AMBIENT`.
        note_work(unsafe { &*a.meter }, a.lane, site, a.region + part, 0, units);
    }
}

/// Enters a scope at the caller's site for the ambient lane, until the guard drops (see
/// the module's text). Outside an ambient lane the guard does nothing. In a
/// `#[track_caller]` function the site is that function's caller: one copy per call
/// site, as nvcc inlines.
#[inline(always)]
#[track_caller]
#[must_use = "the scope ends when the guard drops: bind it with `let _scope = ..`"]
pub fn scope() -> Scope {
    match ambient() {
        Some(a) => {
            // SAFETY: as in `declare`.
            let m = unsafe { &*a.meter };
            Scope { meter: a.meter, outer: enter_scope(m, a.lane, site()) }
        }
        None => Scope { meter: std::ptr::null(), outer: 0 },
    }
}

/// A scope of the ambient lane, from [`scope`] until it drops.
pub struct Scope {
    meter: *const RefCell<Meter>,
    outer: usize,
}

impl Drop for Scope {
    #[inline(always)]
    fn drop(&mut self) {
        // Only while the ambient lane that made the guard is still this thread's: a
        // guard kept past its `Thread::ambient` call (or sent out of it) does nothing.
        if !self.meter.is_null() && ambient().is_some_and(|a| a.meter == self.meter) {
            // SAFETY: the pointer is the current ambient lane's, valid as in `declare`.
            leave_copy(unsafe { &*self.meter }, self.outer);
        }
    }
}
