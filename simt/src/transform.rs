//! Element-wise launches whose threads own their output element: Thrust's
//! `transform`, as kernels.
//!
//! In `for_each` any thread may store to any index of a read-write view, as a CUDA
//! `T*` allows, so an unmeasured store is a relaxed atomic word store behind a bounds
//! check, and LLVM cannot vectorise the lane loop. Here thread `i` reads element `i`
//! of its input and writes only element `i` of its output, which the launch hands to it:
//! unmeasured, a block of 256 threads is a plain loop over a disjoint `&mut` chunk of
//! the output with one bounds check for the launch, which compiles to what a rayon zip
//! loop compiles to. Measured, it is an ordinary `for_each` launch whose lanes load
//! the input (and, in place, the old output) and store the output through `simt`, so
//! its statistics are those of the same CUDA kernel.

use crate::device::{Device, ELEMENT_BLOCK};
use crate::exec::Thread;
use crate::memory::{DeviceBuffer, DeviceCopy, Readable};
use crate::stats::LaunchRecord;
use rayon::prelude::*;

const BLOCK: usize = ELEMENT_BLOCK as usize;

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
            let out = output.view_mut();
            return self.for_each(name, n, |t, i| {
                let x = t.load(input, i);
                // Without `reads` the old value is only a placeholder that `f` overwrites.
                let mut o = if reads { t.load(&out, i) } else { out.read(i) };
                f(t, i, x, &mut o);
                t.store(&out, i, o);
            });
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
        let serial = self.runs_serially(name, threads as u64);
        let out = output.as_mut_slice();
        let record = self
            .unmeasured_launch(name, grid, BLOCK as u32, threads, || {
                if serial {
                    out.chunks_mut(BLOCK).enumerate().for_each(run_block)
                } else {
                    out.par_chunks_mut(BLOCK).enumerate().for_each(run_block)
                }
            })
            .1;
        if serial {
            self.note_serial(name, threads as u64, record.seconds);
        }
        record
    }
}
