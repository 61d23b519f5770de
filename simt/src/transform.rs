//! Element-wise launches whose threads own their output element: Thrust's
//! `transform`, as kernels.
//!
//! In `for_each` any thread may store to any index of a read-write view, as a CUDA
//! `T*` allows, so an unmeasured store is a relaxed atomic word store behind a bounds
//! check, and LLVM cannot vectorise the lane loop. Here thread `i` reads element `i`
//! of its input and writes only element `i` of its output, which the launch hands to it:
//! unmeasured, a block of 256 threads is a plain loop over a disjoint `&mut` chunk of
//! the output with one bounds check for the launch, which compiles to what a rayon zip
//! loop compiles to. Measured, its statistics are those of the `for_each` kernel whose
//! lanes load the input (and, in place, the old output) and store the output through
//! `simt`; the launch counts those owned accesses a block at a time, since it knows
//! their addresses, and records only what `f` itself does lane by lane.

use crate::device::{Device, ELEMENT_BLOCK, LaunchConfig};
use crate::exec::{Thread, access_width};
use crate::limits::WARP_SIZE;
use crate::memory::{DeviceBuffer, DeviceCopy, Readable};
use crate::meter::{Counters, Kind, Meter};
use crate::stats::LaunchRecord;
use rayon::prelude::*;
use std::cell::RefCell;

const BLOCK: usize = ELEMENT_BLOCK as usize;
const WARP: usize = WARP_SIZE as usize;

impl Device {
    /// `output[i] = f(thread, i, input[i])` for every element of `output`
    /// (`thrust::transform` with one input): each thread owns its output element.
    /// `input` must have at least `output.len()` elements.
    ///
    /// ```
    /// let dev = simt::Device::default();
    /// let x = dev.alloc_from(&[1u32, 2, 3]);
    /// let mut y = dev.alloc::<u32>(3);
    /// dev.transform("square", &x.view(), &mut y, |_, _, x| x * x);
    /// assert_eq!(y.as_slice(), &[1, 4, 9]);
    /// ```
    pub fn transform<I, O, V, F>(
        &self,
        name: &'static str,
        input: &V,
        output: &mut DeviceBuffer<O>,
        f: F,
    ) -> LaunchRecord
    where
        I: DeviceCopy,
        O: DeviceCopy,
        V: Readable<I>,
        F: Fn(&Thread, usize, I) -> O + Sync,
    {
        self.owned(name, input, output, false, |t, i, x, o: &mut O| *o = f(t, i, x))
    }

    /// `inout[i] = f(thread, i, input[i], inout[i])` for every element of `inout`
    /// (`thrust::transform` with two inputs, the second also the result, as in Thrust's
    /// saxpy example): each thread owns its element of `inout`.
    ///
    /// ```
    /// let dev = simt::Device::default();
    /// let x = dev.alloc_from(&[1.0f32, 2.0, 3.0]);
    /// let mut y = dev.alloc_from(&[10.0f32, 20.0, 30.0]);
    /// dev.transform_in_place("saxpy", &x.view(), &mut y, |_, _, x, y| 2.0 * x + y);
    /// assert_eq!(y.as_slice(), &[12.0, 24.0, 36.0]);
    /// ```
    pub fn transform_in_place<I, O, V, F>(
        &self,
        name: &'static str,
        input: &V,
        inout: &mut DeviceBuffer<O>,
        f: F,
    ) -> LaunchRecord
    where
        I: DeviceCopy,
        O: DeviceCopy,
        V: Readable<I>,
        F: Fn(&Thread, usize, I, O) -> O + Sync,
    {
        self.owned(name, input, inout, true, |t, i, x, o: &mut O| *o = f(t, i, x, *o))
    }

    /// One thread per element of `output`, which it owns; `reads` says whether the
    /// kernel loads the old value (measured as a load).
    fn owned<I, O, V, F>(
        &self,
        name: &'static str,
        input: &V,
        output: &mut DeviceBuffer<O>,
        reads: bool,
        f: F,
    ) -> LaunchRecord
    where
        I: DeviceCopy,
        O: DeviceCopy,
        V: Readable<I>,
        F: Fn(&Thread, usize, I, &mut O) + Sync,
    {
        let n = output.len();
        assert!(input.len() >= n, "{name}: an input of {} elements for {n} outputs", input.len());
        if self.measuring() {
            let at = output.view().address(0);
            return self.owned_measured(name, input, (output.as_mut_slice(), at), reads, &f);
        }
        let grid = n.div_ceil(BLOCK) as u32;
        let run_block = |(b, chunk): (usize, &mut [O])| {
            let base = b * BLOCK;
            let thread = |k: usize| Thread::unmeasured(k as u32, b as u32, BLOCK as u32, grid);
            // SAFETY (both arms): base + chunk.len() <= n <= input.len(), checked above.
            // A zip over two slices is the loop LLVM vectorises best.
            match unsafe { input.plain_slice(base, chunk.len()) } {
                Some(xs) => {
                    for (k, (o, &x)) in chunk.iter_mut().zip(xs).enumerate() {
                        f(&thread(k), base + k, x, o);
                    }
                }
                None => {
                    for (k, o) in chunk.iter_mut().enumerate() {
                        f(&thread(k), base + k, unsafe { input.read_unchecked(base + k) }, o);
                    }
                }
            }
        };
        let threads = grid as usize * BLOCK;
        let out = output.as_mut_slice();
        self.unmeasured_launch(name, grid, BLOCK as u32, threads, || {
            self.run_blocks(name, threads as u64, |serial| {
                if serial {
                    out.chunks_mut(BLOCK).enumerate().for_each(run_block)
                } else {
                    out.par_chunks_mut(BLOCK).enumerate().for_each(run_block)
                }
            })
        })
        .1
    }

    /// The measured owned launch: the same blocks and lane order, each lane with a
    /// measuring thread, so whatever `f` loads, stores or declares through it is
    /// recorded lane by lane; the owned accesses (the input element, the old output
    /// element when `reads`, the output store) are counted a block at a time by
    /// [`Meter::owned_block`], which gives the same requests, sectors and warp chains
    /// as recording each lane's address and matching them.
    /// `out` is the output's elements, at device address `out_addr`.
    fn owned_measured<I: DeviceCopy, O: DeviceCopy>(
        &self,
        name: &'static str,
        input: &impl Readable<I>,
        (out, out_addr): (&mut [O], u64),
        reads: bool,
        f: &(impl Fn(&Thread, usize, I, &mut O) + Sync),
    ) -> LaunchRecord {
        let cfg = LaunchConfig::linear(out.len(), ELEMENT_BLOCK);
        let grid = cfg.grid;
        let predicting = self.predicting();
        let (in_size, in_width) = (std::mem::size_of::<I>() as u64, access_width::<I>());
        let (out_size, out_width) = (std::mem::size_of::<O>() as u64, access_width::<O>());
        // The meter travels from block to block boxed: moved by value, its size was
        // copied at every block (a tenth of a measured `transform`'s time).
        let run_block = |meter: Box<RefCell<Meter>>, (b, chunk): (usize, &mut [O])| {
            for (w, lanes) in chunk.chunks_mut(WARP).enumerate() {
                let first = b * BLOCK + w * WARP;
                {
                    let mut m = meter.borrow_mut();
                    m.begin_warp_call();
                    m.begin_lane_phase();
                }
                for (k, o) in lanes.iter_mut().enumerate() {
                    let thread_idx = (w * WARP + k) as u32;
                    // No lane is set here: what `f` records names its lane (the
                    // thread's index), so a loop whose `f` records nothing compiles to
                    // a plain loop.
                    let t = Thread::measured(thread_idx, b as u32, BLOCK as u32, grid, &meter);
                    // SAFETY: first + k < n <= input.len(), checked by the caller.
                    f(&t, first + k, unsafe { input.read_unchecked(first + k) }, o);
                }
                meter.borrow_mut().end_warp_phase();
            }
            let mut m = meter.borrow_mut();
            let (first, count) = (b * BLOCK, chunk.len() as u32);
            m.owned_block(Kind::Load, input.address(first), count, in_size, in_width);
            let at = out_addr + first as u64 * out_size;
            if reads {
                m.owned_block(Kind::Load, at, count, out_size, out_width);
            }
            m.owned_block(Kind::Store, at, count, out_size, out_width);
            m.totals.threads += BLOCK as u64;
            m.close_block();
            drop(m);
            meter
        };
        let threads = grid as u64 * BLOCK as u64;
        let (counters, seconds) = self.run_blocks(name, threads, |serial| {
            if serial {
                out.chunks_mut(BLOCK)
                    .enumerate()
                    .fold(Box::new(RefCell::new(Meter::new(predicting))), run_block)
                    .into_inner()
                    .totals
            } else {
                out.par_chunks_mut(BLOCK)
                    .enumerate()
                    .fold(|| Box::new(RefCell::new(Meter::new(predicting))), run_block)
                    .map(|m| m.into_inner().totals)
                    .reduce(Counters::default, Counters::merge)
            }
        });
        self.record_launch(name, &cfg, seconds, true, false, counters)
    }
}
