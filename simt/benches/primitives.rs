//! Primitive throughput against plain CPU code, and the cost of the emulator itself.
//!
//! * `sort/*`: simt's radix `sort_by_key` (u32 keys, u32 values) against rayon's
//!   `par_sort_unstable_by_key` on (key, value) pairs, at 1M and 16M elements.
//! * `scan/*`: simt's `inclusive_scan` against a sequential loop.
//! * `overhead/*`: the same element-wise kernel as a `simt` launch (measurement off and
//!   on) and as a direct rayon loop. `leaf` is a brute-force leaf as DACRT runs it (each
//!   thread tests one ray against 64 triangles, Möller–Trumbore); `hash` does ~40 integer
//!   operations per element and `saxpy` is memory-bound: rayon's versions of those two
//!   are auto-vectorised, which simt's per-lane loads (relaxed atomics) never are.
//!
//! `cargo bench -p simt --bench primitives` (add `-- overhead` for one group).

use criterion::{BenchmarkId, Criterion, Throughput, criterion_group, criterion_main};
use rayon::prelude::*;
use simt::{Device, DeviceConfig};
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

#[inline(always)]
fn hash(mut x: u32) -> u32 {
    for _ in 0..8 {
        x ^= x >> 16;
        x = x.wrapping_mul(0x7feb_352d);
        x ^= x >> 15;
        x = x.wrapping_mul(0x846c_a68b);
    }
    x
}

/// Closest hit of one ray (origin, direction, t_max, pad) against triangles stored as
/// (v0, edge1, edge2, pad), Möller–Trumbore.
#[inline(always)]
fn leaf(ray: [f32; 8], tri: impl Fn(usize) -> [f32; 12], count: usize) -> f32 {
    let (o, d) = ([ray[0], ray[1], ray[2]], [ray[3], ray[4], ray[5]]);
    let sub = |a: [f32; 3], b: [f32; 3]| [a[0] - b[0], a[1] - b[1], a[2] - b[2]];
    let cross =
        |a: [f32; 3], b: [f32; 3]| [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]];
    let dot = |a: [f32; 3], b: [f32; 3]| a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
    let mut best = ray[6];
    for k in 0..count {
        let t = tri(k);
        let (v0, e1, e2) = ([t[0], t[1], t[2]], [t[3], t[4], t[5]], [t[6], t[7], t[8]]);
        let p = cross(d, e2);
        let det = dot(e1, p);
        if det.abs() < 1e-12 {
            continue;
        }
        let inv = 1.0 / det;
        let s = sub(o, v0);
        let u = dot(s, p) * inv;
        let q = cross(s, e1);
        let v = dot(d, q) * inv;
        let tt = dot(e2, q) * inv;
        if u >= 0.0 && v >= 0.0 && u + v <= 1.0 && tt > 0.0 && tt < best {
            best = tt;
        }
    }
    best
}

fn leaf_data(rays: usize, tris: usize) -> (Vec<[f32; 8]>, Vec<[f32; 12]>) {
    let r = keys(rays * 6 + tris * 9);
    let f = |i: usize| (r[i] % 2000) as f32 / 1000.0 - 1.0;
    let ray_data = (0..rays)
        .map(|i| [f(6 * i), f(6 * i + 1), 3.0, f(6 * i + 3) * 0.1, f(6 * i + 4) * 0.1, -1.0, 1e30, 0.0])
        .collect();
    let base = rays * 6;
    let tri_data = (0..tris)
        .map(|i| {
            let g = |k: usize| f(base + 9 * i + k);
            [g(0), g(1), g(2), g(3) * 0.3, g(4) * 0.3, g(5) * 0.3, g(6) * 0.3, g(7) * 0.3, g(8) * 0.3, 0.0, 0.0, 0.0]
        })
        .collect();
    (ray_data, tri_data)
}

fn overhead(c: &mut Criterion) {
    let mut g = c.benchmark_group("overhead");
    g.sample_size(20);

    let rays = 1 << 18;
    let (ray_data, tri_data) = leaf_data(rays, 64);
    g.throughput(Throughput::Elements(rays as u64));
    for measure in [false, true] {
        let dev = Device::new(DeviceConfig { measure, ..Default::default() });
        let (rb, tb) = (dev.alloc_from(&ray_data), dev.alloc_from(&tri_data));
        let mut out = dev.alloc::<f32>(rays);
        let (rv, tv, ov) = (rb.view(), tb.view(), out.view_mut());
        let label = if measure { "simt_measured" } else { "simt" };
        g.bench_function(format!("leaf/{label}"), |b| {
            b.iter(|| dev.for_each("leaf", rays, |t, i| t.store(&ov, i, leaf(t.load(&rv, i), |k| t.load(&tv, k), 64))))
        });
    }
    let mut out = vec![0f32; rays];
    g.bench_function("leaf/rayon", |b| {
        b.iter(|| out.par_iter_mut().zip(black_box(&ray_data)).for_each(|(o, &r)| *o = leaf(r, |k| tri_data[k], 64)))
    });

    let n = 1 << 22;
    g.throughput(Throughput::Elements(n as u64));
    let data = keys(n);
    for measure in [false, true] {
        let dev = Device::new(DeviceConfig { measure, ..Default::default() });
        let input = dev.alloc_from(&data);
        let mut out = dev.alloc::<u32>(n);
        let (i, o) = (input.view(), out.view_mut());
        let label = if measure { "simt_measured" } else { "simt" };
        g.bench_function(format!("hash/{label}"), |b| {
            b.iter(|| dev.for_each("hash", n, |t, k| t.store(&o, k, hash(t.load(&i, k)))))
        });
        let x = dev.alloc_from(&vec![1.5f32; n]);
        let mut y = dev.alloc_from(&vec![2.5f32; n]);
        let (xv, yv) = (x.view(), y.view_mut());
        g.bench_function(format!("saxpy/{label}"), |b| {
            b.iter(|| dev.for_each("saxpy", n, |t, k| t.store(&yv, k, 2.0 * t.load(&xv, k) + t.load(&yv, k))))
        });
    }
    let mut out = vec![0u32; n];
    g.bench_function("hash/rayon", |b| {
        b.iter(|| out.par_iter_mut().zip(black_box(&data)).for_each(|(o, &x)| *o = hash(x)))
    });
    let x = vec![1.5f32; n];
    let mut y = vec![2.5f32; n];
    g.bench_function("saxpy/rayon", |b| {
        b.iter(|| y.par_iter_mut().zip(black_box(&x)).for_each(|(y, &x)| *y += 2.0 * x))
    });
    g.finish();
}

criterion_group!(benches, overhead, scan, sort);
criterion_main!(benches);
