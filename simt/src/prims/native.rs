//! The primitives' CPU backend: what they run when the device is not measuring, as
//! Thrust's OpenMP and TBB backends run the same calls natively on a CPU. Same
//! results as the kernels (the same sequential twins in [`crate::seq`] check both);
//! no emulated GPU. Measured devices run the kernels, so their statistics stay what a
//! GPU would do.
//!
//! Work is cut into fixed chunks of [`CHUNK`] elements, never into one chunk per thread,
//! so results (for operators that are only nearly associative, such as float sums)
//! do not depend on the number of threads.

use crate::memory::DeviceCopy;
use crate::prims::radix_key::RadixKey;
use rayon::prelude::*;

/// Elements per chunk of the parallel scans, reductions and compactions: small
/// enough that a pass over a few hundred thousand elements still feeds 16 threads
/// (PDACRT's deep levels are such passes: at 16 threads its scans took 111 ms with
/// chunks of 2^16, 63 ms with 2^14 and 45 ms with 2^12; `docs/simt.md`).
pub const CHUNK: usize = 1 << 12;

/// Elements per chunk of the radix sort's histogram and scatter passes: each chunk
/// keeps a histogram of up to 4,096 buckets, so its chunks stay large.
const SORT_CHUNK: usize = 1 << 16;

/// A pointer that parallel chunks write through at disjoint positions.
#[derive(Clone, Copy)]
struct Disjoint<T>(*mut T);
// SAFETY: every user writes each position from exactly one chunk.
unsafe impl<T: Send> Send for Disjoint<T> {}
unsafe impl<T: Send> Sync for Disjoint<T> {}
impl<T> Disjoint<T> {
    /// # Safety
    /// `i` is in bounds and no other chunk writes it during the pass.
    #[inline(always)]
    unsafe fn write(self, i: usize, v: T) {
        unsafe { self.0.add(i).write(v) }
    }
}

/// Reduce-then-scan: chunk totals in parallel, a scan of the totals, then each chunk
/// scanned from its offset.
pub(crate) fn scan<I, T, M, F>(input: &[I], map: M, output: &mut [T], init: Option<T>, identity: T, op: F)
where
    I: DeviceCopy,
    T: DeviceCopy,
    M: Fn(I) -> T + Sync + Copy,
    F: Fn(T, T) -> T + Sync + Copy,
{
    let scan_chunk = |inp: &[I], out: &mut [T], mut acc: T| {
        if init.is_some() {
            for (o, &x) in out.iter_mut().zip(inp) {
                *o = acc;
                acc = op(acc, map(x));
            }
        } else {
            for (o, &x) in out.iter_mut().zip(inp) {
                acc = op(acc, map(x));
                *o = acc;
            }
        }
    };
    let start = init.unwrap_or(identity);
    if input.len() <= CHUNK {
        return scan_chunk(input, output, start);
    }
    let totals: Vec<T> = input.par_chunks(CHUNK).map(|c| c.iter().fold(identity, |a, &x| op(a, map(x)))).collect();
    let mut offsets = Vec::with_capacity(totals.len());
    let mut acc = start;
    for &t in &totals {
        offsets.push(acc);
        acc = op(acc, t);
    }
    input
        .par_chunks(CHUNK)
        .zip(output.par_chunks_mut(CHUNK))
        .zip(offsets)
        .for_each(|((i, o), offset)| scan_chunk(i, o, offset));
}

pub(crate) fn reduce<I, T, M, F>(input: &[I], map: M, init: T, identity: T, op: F) -> T
where
    I: DeviceCopy,
    T: DeviceCopy,
    M: Fn(I) -> T + Sync + Copy,
    F: Fn(T, T) -> T + Sync + Copy,
{
    let totals: Vec<T> = input.par_chunks(CHUNK).map(|c| c.iter().fold(identity, |a, &x| op(a, map(x)))).collect();
    totals.into_iter().fold(init, op)
}

/// Chunks evaluate the predicate once per element into a bitmask and count the set
/// bits; a scan of the counts places each chunk, which then copies the elements its
/// mask selects. The stencil is read and the predicate evaluated once (PDACRT's
/// predicates are ray-box tests), and neither pass branches on the data.
pub(crate) fn copy_if_stencil<T, S, P>(input: &[T], stencil: &[S], output: &mut [T], pred: P) -> usize
where
    T: DeviceCopy,
    S: DeviceCopy,
    P: Fn(S) -> bool + Sync,
{
    const WORDS: usize = CHUNK / 64;
    let masks: Vec<(usize, [u64; WORDS])> = stencil
        .par_chunks(CHUNK)
        .map(|c| {
            let mut mask = [0u64; WORDS];
            for (word, part) in mask.iter_mut().zip(c.chunks(64)) {
                for (b, &s) in part.iter().enumerate() {
                    *word |= (pred(s) as u64) << b;
                }
            }
            (mask.iter().map(|w| w.count_ones() as usize).sum(), mask)
        })
        .collect();
    let total = masks.iter().map(|m| m.0).sum();
    let mut rest = &mut output[..total];
    let mut parts = Vec::with_capacity(masks.len());
    for &(c, _) in &masks {
        let (head, tail) = rest.split_at_mut(c);
        parts.push(head);
        rest = tail;
    }
    input.par_chunks(CHUNK).zip(parts).zip(&masks).for_each(|((inp, out), (_, mask))| {
        let mut slots = out.iter_mut();
        for (w, &word) in mask.iter().enumerate() {
            let mut bits = word;
            while bits != 0 {
                let i = w * 64 + bits.trailing_zeros() as usize;
                *slots.next().expect("a slot per set bit") = inp[i];
                bits &= bits - 1;
            }
        }
    });
    total
}

/// Each chunk reduces the runs whose first key lies in it, reading past its end to
/// finish its last run; a scan of the chunks' head counts places their outputs.
pub(crate) fn reduce_by_key<K, V, F>(keys: &[K], values: &[V], out_keys: &mut [K], out_values: &mut [V], op: F) -> usize
where
    K: DeviceCopy + PartialEq,
    V: DeviceCopy,
    F: Fn(V, V) -> V + Sync + Copy,
{
    let n = keys.len();
    let is_head = |i: usize| i == 0 || keys[i] != keys[i - 1];
    let chunks = n.div_ceil(CHUNK);
    let heads: Vec<usize> = (0..chunks)
        .into_par_iter()
        .map(|c| (c * CHUNK..((c + 1) * CHUNK).min(n)).filter(|&i| is_head(i)).count())
        .collect();
    let mut starts = Vec::with_capacity(chunks);
    let mut total = 0;
    for &h in &heads {
        starts.push(total);
        total += h;
    }
    let (ok, ov) = (Disjoint(out_keys.as_mut_ptr()), Disjoint(out_values.as_mut_ptr()));
    assert!(out_keys.len() >= total && out_values.len() >= total);
    (0..chunks).into_par_iter().zip(starts).for_each(|(c, mut o)| {
        let mut i = c * CHUNK;
        let end = ((c + 1) * CHUNK).min(n);
        while i < end && !is_head(i) {
            i += 1;
        }
        while i < end {
            let key = keys[i];
            let mut acc = values[i];
            i += 1;
            while i < n && keys[i] == key {
                acc = op(acc, values[i]);
                i += 1;
            }
            // SAFETY: chunk c writes outputs starts[c]..starts[c] + heads[c] only.
            unsafe {
                ok.write(o, key);
                ov.write(o, acc);
            }
            o += 1;
        }
    });
    total
}

/// Elements per bucket the top digit aims at (a bucket and its scratch stay in L2).
const BUCKET: usize = 1 << 14;

/// Stable radix sort. One read finds the bits that vary between keys (the others
/// cannot change the order). The top varying bits (up to 12, enough for buckets of
/// about [`BUCKET`] elements) are one parallel, stable scatter into buckets; each bucket
/// is then sorted on its lower bits by a sequential LSD radix sort of 8-bit digits, in
/// cache, buckets in parallel, and written back into the caller's slices.
pub(crate) fn sort_by_key_bits<K: RadixKey, V: DeviceCopy>(
    keys: &mut [K],
    values: &mut [V],
    begin: u32,
    end: u32,
    pool: &mut Vec<u128>,
) {
    let n = keys.len();
    assert!(n < u32::MAX as usize, "sort_by_key: {n} elements is more than the CPU backend indexes");
    let range = if end - begin >= 64 { u64::MAX } else { ((1u64 << (end - begin)) - 1) << begin };
    let (or, and) = keys
        .par_chunks(SORT_CHUNK)
        .map(|c| c.iter().fold((0u64, u64::MAX), |(o, a), k| (o | k.bits(), a & k.bits())))
        .reduce(|| (0, u64::MAX), |x, y| (x.0 | y.0, x.1 & y.1));
    let varying = (or ^ and) & range;
    if varying == 0 {
        return;
    }
    let (lo, hi) = (varying.trailing_zeros(), 64 - varying.leading_zeros());
    let want = (usize::BITS - (n / BUCKET).leading_zeros()).clamp(1, 12);
    let top_width = want.min(hi - lo);
    let (shift, width) = (hi - top_width, top_width);
    let digit = move |k: K| k.digit(shift, width) as usize;
    // Lower digits of at most 11 bits, as even as possible (21 bits: 11 + 10).
    let lower: Vec<(u32, u32)> = if shift > lo {
        let passes = (shift - lo).div_ceil(11);
        let w = (shift - lo).div_ceil(passes);
        (lo..shift).step_by(w as usize).map(|s| (s, (shift - s).min(w))).collect()
    } else {
        Vec::new()
    };

    // The top digit: the chunks' histograms scanned digit-major, then a stable scatter.
    let buckets = 1usize << width;
    let chunk = SORT_CHUNK;
    let per_chunk: Vec<Vec<u32>> = keys
        .par_chunks(chunk)
        .map(|c| {
            let mut h = vec![0u32; buckets];
            c.iter().for_each(|&k| h[digit(k)] += 1);
            h
        })
        .collect();
    let mut offsets = vec![vec![0usize; buckets]; per_chunk.len()];
    let mut bucket_start = vec![0usize; buckets + 1];
    let mut base = 0;
    for d in 0..buckets {
        bucket_start[d] = base;
        for (c, h) in per_chunk.iter().enumerate() {
            offsets[c][d] = base;
            base += h[d] as usize;
        }
    }
    bucket_start[buckets] = n;
    // The pairs live in the pool's (16-byte aligned, uninitialised) storage.
    const { assert!(std::mem::align_of::<(K, V)>() <= 16) };
    assert!(pool.capacity() * 16 >= n * std::mem::size_of::<(K, V)>());
    let dst = Disjoint(pool.as_mut_ptr() as *mut (K, V));
    keys.par_chunks(chunk).zip(values.par_chunks(chunk)).zip(offsets).for_each(|((ck, cv), mut o)| {
        let o = &mut o[..];
        for (&k, &v) in ck.iter().zip(cv) {
            let d = digit(k);
            // SAFETY: positions offsets[c][d].. belong to chunk c for digit d; the vector
            // has room for n and every position is written once.
            unsafe { dst.write(o[d], (k, v)) };
            o[d] += 1;
        }
    });
    // SAFETY: the scatter wrote all n pairs into storage that holds them, aligned.
    let pairs: &mut [(K, V)] = unsafe { std::slice::from_raw_parts_mut(dst.0, n) };

    // Buckets on their lower digits, in parallel, into the caller's slices.
    let mut parts = Vec::with_capacity(buckets);
    let (mut rp, mut rk, mut rv) = (pairs, &mut *keys, &mut *values);
    for d in 0..buckets {
        let len = bucket_start[d + 1] - bucket_start[d];
        let (p, tp) = rp.split_at_mut(len);
        let (k, tk) = rk.split_at_mut(len);
        let (v, tv) = rv.split_at_mut(len);
        parts.push((p, k, v));
        (rp, rk, rv) = (tp, tk, tv);
    }
    parts.into_par_iter().for_each_init(Vec::new, |scratch, (p, k, v)| lsd_bucket(p, scratch, k, v, &lower));
}

/// A pass's source and destination.
type SrcDst<'a, K, V> = (&'a [(K, V)], &'a mut [(K, V)]);

/// Sequential stable LSD radix sort of one bucket on `digits` (low to high, each at
/// most 11 bits), ping-pong between the bucket and `scratch`; the last pass writes
/// straight into `keys` and `values`.
fn lsd_bucket<K: RadixKey, V: DeviceCopy>(
    bucket: &mut [(K, V)],
    scratch: &mut Vec<(K, V)>,
    keys: &mut [K],
    values: &mut [V],
    digits: &[(u32, u32)],
) {
    let n = bucket.len();
    // Every digit's histogram in one read; digits every key shares are dropped.
    let mut hist = vec![[0u32; 2048]; digits.len()];
    for kv in bucket.iter() {
        for (h, &(s, w)) in hist.iter_mut().zip(digits) {
            h[kv.0.digit(s, w) as usize & 2047] += 1;
        }
    }
    let passes: Vec<(usize, (u32, u32))> =
        digits.iter().enumerate().filter(|(p, _)| !hist[*p].contains(&(n as u32))).map(|(p, &d)| (p, d)).collect();
    if passes.is_empty() {
        for ((k, v), &(a, b)) in keys.iter_mut().zip(values.iter_mut()).zip(bucket.iter()) {
            *k = a;
            *v = b;
        }
        return;
    }
    if scratch.len() < n {
        scratch.resize(n, bucket[0]);
    }
    let mut src_is_bucket = true;
    let last = passes.len() - 1;
    for (i, &(p, (shift, width))) in passes.iter().enumerate() {
        let mut o = [0u32; 2048];
        let mut base = 0;
        for d in 0..1usize << width {
            o[d] = base;
            base += hist[p][d];
        }
        if i == last {
            let src: &[(K, V)] = if src_is_bucket { bucket } else { &scratch[..n] };
            for &(k, v) in src {
                let d = k.digit(shift, width) as usize & 2047;
                let at = o[d] as usize;
                keys[at] = k;
                values[at] = v;
                o[d] += 1;
            }
        } else {
            let (src, dst): SrcDst<K, V> =
                if src_is_bucket { (&*bucket, &mut scratch[..n]) } else { (&scratch[..n], &mut *bucket) };
            for &kv in src {
                let d = kv.0.digit(shift, width) as usize & 2047;
                // SAFETY: o[d] < n: digit d's slots end where digit d + 1's begin.
                unsafe { *dst.get_unchecked_mut(o[d] as usize) = kv };
                o[d] += 1;
            }
            src_is_bucket = !src_is_bucket;
        }
    }
}
