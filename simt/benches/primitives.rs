//! Primitive throughput against plain CPU code, and the cost of the emulator itself.
//!
//! * `sort/*`: simt's radix `sort_by_key` (u32 keys, u32 values) against rayon's
//!   `par_sort_unstable_by_key` on (key, value) pairs, at 1M and 16M elements.
//! * `scan/*`: simt's `inclusive_scan` against a sequential loop.
//!
//! With measurement off (as here) the primitives run their CPU backend. The emulator's
//! cost per kernel, and every primitive against the best CPU reference, measured and
//! unmeasured, is the `overhead` example (`cargo run --release -p simt --example
//! overhead -- --json`).
//!
//! `cargo bench -p simt --bench primitives` (add `-- sort` for one group).

use criterion::{BenchmarkId, Criterion, Throughput, criterion_group, criterion_main};
use rayon::prelude::*;
use simt::Device;
use std::hint::black_box;

fn keys(n: usize) -> Vec<u32> {
    let mut s = 0x1234_5678_u32;
    (0..n)
        .map(|_| {
            s ^= s << 13;
            s ^= s >> 17;
            s ^= s << 5;
            s
        })
        .collect()
}

fn sort(c: &mut Criterion) {
    let mut g = c.benchmark_group("sort");
    g.sample_size(10);
    let dev = Device::default();
    for n in [1 << 20, 1 << 24] {
        let k = keys(n);
        let v: Vec<u32> = (0..n as u32).collect();
        g.throughput(Throughput::Elements(n as u64));
        g.bench_with_input(BenchmarkId::new("simt_radix_sort_by_key", n), &n, |b, _| {
            b.iter_batched(
                || (dev.alloc_from(&k), dev.alloc_from(&v)),
                |(mut kb, mut vb)| simt::sort_by_key(&dev, &mut kb, &mut vb),
                criterion::BatchSize::LargeInput,
            )
        });
        let pairs: Vec<(u32, u32)> = k.iter().copied().zip(v.iter().copied()).collect();
        g.bench_with_input(BenchmarkId::new("rayon_par_sort_unstable", n), &n, |b, _| {
            b.iter_batched(
                || pairs.clone(),
                |mut p| p.par_sort_unstable_by_key(|x| x.0),
                criterion::BatchSize::LargeInput,
            )
        });
    }
    g.finish();
}

fn scan(c: &mut Criterion) {
    let mut g = c.benchmark_group("scan");
    g.sample_size(10);
    let dev = Device::default();
    for n in [1 << 20, 1 << 24] {
        let data = keys(n);
        let input = dev.alloc_from(&data);
        let mut out = dev.alloc::<u32>(n);
        g.throughput(Throughput::Elements(n as u64));
        g.bench_with_input(BenchmarkId::new("simt_inclusive_scan", n), &n, |b, _| {
            b.iter(|| simt::inclusive_scan(&dev, &input, &mut out, 0, |a, b| a.wrapping_add(b)))
        });
        let mut host_out = vec![0u32; n];
        g.bench_with_input(BenchmarkId::new("sequential_loop", n), &n, |b, _| {
            b.iter(|| {
                let mut acc = 0u32;
                for (o, &x) in host_out.iter_mut().zip(black_box(&data)) {
                    acc = acc.wrapping_add(x);
                    *o = acc;
                }
            })
        });
    }
    g.finish();
}

criterion_group!(benches, scan, sort);
criterion_main!(benches);
