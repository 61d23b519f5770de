//! Element-wise primitives: fill, sequence, gather, scatter, copy_if (stream
//! compaction) and reduce_by_key (a segmented scan on head flags).

use super::scan::{exclusive_scan, inclusive_scan};
use crate::device::Device;
use crate::memory::{DeviceBuffer, DeviceCopy, Readable};

/// Sets every element to `value`.
pub fn fill<T: DeviceCopy>(dev: &Device, buf: &mut DeviceBuffer<T>, value: T) {
    let out = buf.view_mut();
    dev.for_each("simt::fill", out.len(), |t, i| t.store(&out, i, value));
}

/// `buf[i] = start + i · step` (wrapping).
///
/// ```
/// let dev = simt::Device::default();
/// let mut b = dev.alloc::<u32>(4);
/// simt::sequence(&dev, &mut b, 10, 5);
/// assert_eq!(b.as_slice(), &[10, 15, 20, 25]);
/// ```
pub fn sequence(dev: &Device, buf: &mut DeviceBuffer<u32>, start: u32, step: u32) {
    let out = buf.view_mut();
    dev.for_each("simt::sequence", out.len(), |t, i| t.store(&out, i, start.wrapping_add(step.wrapping_mul(i as u32))));
}

/// `output[i] = input[map[i]]`.
///
/// ```
/// let dev = simt::Device::default();
/// let input = dev.alloc_from(&[10u32, 20, 30]);
/// let map = dev.alloc_from(&[2u32, 0, 0]);
/// let mut out = dev.alloc::<u32>(3);
/// simt::gather(&dev, &map, &input, &mut out);
/// assert_eq!(out.as_slice(), &[30, 10, 10]);
/// ```
pub fn gather<T: DeviceCopy>(
    dev: &Device,
    map: &DeviceBuffer<u32>,
    input: &DeviceBuffer<T>,
    output: &mut DeviceBuffer<T>,
) {
    assert_eq!(map.len(), output.len(), "gather: one map entry per output");
    let inp = input.view();
    dev.transform("simt::gather", &map.view(), output, |t, _, m| t.load(&inp, m as usize));
}

/// `output[map[i]] = input[i]` (map entries should be distinct).
///
/// ```
/// let dev = simt::Device::default();
/// let input = dev.alloc_from(&[10u32, 20, 30]);
/// let map = dev.alloc_from(&[2u32, 0, 1]);
/// let mut out = dev.alloc::<u32>(3);
/// simt::scatter(&dev, &input, &map, &mut out);
/// assert_eq!(out.as_slice(), &[20, 30, 10]);
/// ```
pub fn scatter<T: DeviceCopy>(
    dev: &Device,
    input: &DeviceBuffer<T>,
    map: &DeviceBuffer<u32>,
    output: &mut DeviceBuffer<T>,
) {
    assert_eq!(map.len(), input.len(), "scatter: one map entry per input");
    let (m, inp, out) = (map.view(), input.view(), output.view_mut());
    dev.for_each("simt::scatter", m.len(), |t, i| t.store(&out, t.load(&m, i) as usize, t.load(&inp, i)));
}

/// Copies the elements whose `stencil` entry satisfies `pred`, in order, to the front
/// of `output`; returns how many. `output` must be as long as `input`.
pub fn copy_if_stencil<T, S, P>(
    dev: &Device,
    input: &DeviceBuffer<T>,
    stencil: &DeviceBuffer<S>,
    output: &mut DeviceBuffer<T>,
    pred: P,
) -> usize
where
    T: DeviceCopy,
    S: DeviceCopy,
    P: Fn(S) -> bool + Sync,
{
    let n = input.len();
    assert_eq!(stencil.len(), n, "copy_if: one stencil entry per input");
    assert!(output.len() >= n, "copy_if: output shorter than input");
    if n == 0 {
        return 0;
    }
    if !dev.measuring() {
        return dev.host("simt::copy_if [cpu]", n, || {
            super::native::copy_if_stencil(input.as_slice(), stencil.as_slice(), output.as_mut_slice(), pred)
        });
    }
    let mut flags = dev.alloc::<u32>(n);
    {
        let (st, fl) = (stencil.view(), flags.view_mut());
        dev.for_each("simt::copy_if_flags", n, |t, i| t.store(&fl, i, pred(t.load(&st, i)) as u32));
    }
    let mut pos = dev.alloc::<u32>(n);
    exclusive_scan(dev, &flags, &mut pos, 0, 0, |a, b| a + b);
    let count = (pos.as_slice()[n - 1] + flags.as_slice()[n - 1]) as usize;
    let (inp, fl, ps, out) = (input.view(), flags.view(), pos.view(), output.view_mut());
    dev.for_each("simt::copy_if_scatter", n, |t, i| {
        if t.load(&fl, i) != 0 {
            t.store(&out, t.load(&ps, i) as usize, t.load(&inp, i));
        }
    });
    count
}

/// Copies the elements satisfying `pred`, in order, to the front of `output`;
/// returns how many (Thrust's `copy_if`, with a count for the end iterator).
///
/// ```
/// let dev = simt::Device::default();
/// let input = dev.alloc_from(&[1u32, 4, 7, 8, 3]);
/// let mut out = dev.alloc::<u32>(5);
/// let n = simt::copy_if(&dev, &input, &mut out, |x| x % 2 == 0);
/// assert_eq!(&out.as_slice()[..n], &[4, 8]);
/// ```
pub fn copy_if<T, P>(dev: &Device, input: &DeviceBuffer<T>, output: &mut DeviceBuffer<T>, pred: P) -> usize
where
    T: DeviceCopy,
    P: Fn(T) -> bool + Sync,
{
    copy_if_stencil(dev, input, input, output, pred)
}

/// A value with a segment-head flag, for segmented scans (packed to 4-byte alignment so
/// it has no padding for any `DeviceCopy` value).
#[derive(Clone, Copy, Debug, Default)]
#[repr(C, packed(4))]
pub struct Flagged<V> {
    /// Nonzero when the value is selected.
    pub flag: u32,
    /// The value.
    pub value: V,
}
unsafe impl<V: DeviceCopy> DeviceCopy for Flagged<V> {}

/// For each run of equal consecutive keys, writes the key and the reduction of its
/// values; returns the number of runs. Outputs must be as long as the inputs.
///
/// ```
/// let dev = simt::Device::default();
/// let keys = dev.alloc_from(&[1u32, 1, 3, 3, 3, 1]);
/// let vals = dev.alloc_from(&[9u32, 1, 2, 2, 2, 5]);
/// let (mut ok, mut ov) = (dev.alloc::<u32>(6), dev.alloc::<u32>(6));
/// let n = simt::reduce_by_key(&dev, &keys, &vals, &mut ok, &mut ov, 0, |a, b| a + b);
/// assert_eq!((&ok.as_slice()[..n], &ov.as_slice()[..n]), (&[1, 3, 1][..], &[10, 6, 5][..]));
/// ```
pub fn reduce_by_key<K, V, F>(
    dev: &Device,
    keys: &DeviceBuffer<K>,
    values: &DeviceBuffer<V>,
    out_keys: &mut DeviceBuffer<K>,
    out_values: &mut DeviceBuffer<V>,
    identity: V,
    op: F,
) -> usize
where
    K: DeviceCopy + PartialEq,
    V: DeviceCopy,
    F: Fn(V, V) -> V + Sync + Copy,
{
    let n = keys.len();
    assert_eq!(values.len(), n, "reduce_by_key: one value per key");
    assert!(out_keys.len() >= n && out_values.len() >= n, "reduce_by_key: outputs shorter than inputs");
    if n == 0 {
        return 0;
    }
    if !dev.measuring() {
        return dev.host("simt::reduce_by_key [cpu]", n, || {
            super::native::reduce_by_key(
                keys.as_slice(),
                values.as_slice(),
                out_keys.as_mut_slice(),
                out_values.as_mut_slice(),
                op,
            )
        });
    }
    let mut heads = dev.alloc::<u32>(n);
    let mut pairs = dev.alloc_filled(n, Flagged { flag: 0, value: identity });
    {
        let (k, v, h, p) = (keys.view(), values.view(), heads.view_mut(), pairs.view_mut());
        dev.for_each("simt::rbk_heads", n, |t, i| {
            let head = i == 0 || t.load(&k, i) != t.load(&k, i - 1);
            t.store(&h, i, head as u32);
            t.store(&p, i, Flagged { flag: head as u32, value: t.load(&v, i) });
        });
    }
    // Segmented inclusive scan: a head restarts the running value.
    let mut scanned = dev.alloc_filled(n, Flagged { flag: 0, value: identity });
    inclusive_scan(
        dev,
        &pairs,
        &mut scanned,
        Flagged { flag: 0, value: identity },
        move |a: Flagged<V>, b: Flagged<V>| {
            if b.flag != 0 { b } else { Flagged { flag: a.flag, value: op(a.value, b.value) } }
        },
    );
    drop(pairs);
    let mut seg = dev.alloc::<u32>(n);
    inclusive_scan(dev, &heads, &mut seg, 0, |a, b| a + b);
    let count = seg.as_slice()[n - 1] as usize;
    let (k, h, s, sc) = (keys.view(), heads.view(), seg.view(), scanned.view());
    let (ok, ov) = (out_keys.view_mut(), out_values.view_mut());
    dev.for_each("simt::rbk_scatter", n, |t, i| {
        let tail = i == n - 1 || t.load(&h, i + 1) != 0;
        if tail {
            let o = t.load(&s, i) as usize - 1;
            t.store(&ok, o, t.load(&k, i));
            t.store(&ov, o, t.load(&sc, i).value);
        }
    });
    count
}
