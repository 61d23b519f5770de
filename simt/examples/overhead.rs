//! What the emulator costs: each kernel and primitive of `simt` against the best plain
//! CPU code for the same job, with measurement off (and, for reference, on).
//!
//! `cargo run --release -p simt --example overhead -- [--json] [--n 16777216] [--repeat 5] [--rounds 1]
//! [--only ROW] [--gpu-profile h200]`
//!
//! Rows: `saxpy` (16M f32, memory-bound, `Device::transform_in_place`: each thread owns
//! its element), `saxpy_any_store` (the same through `for_each` and a read-write view,
//! where any thread may store anywhere), `hash` (~32 integer operations per element,
//! compute-bound, `Device::transform`), `leaf` (the PDACRT terminal kernel: a block stages 64 triangles in
//! shared memory, each thread tests its ray against them), `inclusive_scan`,
//! `sort_by_key` (u32/u32), `reduce_by_key` and `copy_if`. The reference is a rayon loop
//! (or, where faster, a sequential loop; for the sort, the `rdst` parallel radix sort).
//! Each time is the median of `--repeat` runs after one warm-up (a measured kernel
//! row's, of three or `--repeat` if fewer). With `--rounds R` the
//! whole table is measured R times in turn, and each row reports the median of its R
//! ratios (each round's simt time over the same round's reference) and their range:
//! on a shared machine a slow spell then moves both sides of a ratio, or one round.
//! With `--gpu-profile NAME` the measured device also predicts GPU time on that profile
//! (`Device::set_gpu_profile`), so its launches gather the footprints and warp chains
//! the time model reads: the cost of measuring with a prediction.

use rayon::prelude::*;
use simt::timing::GpuProfile;
use simt::{Device, DeviceConfig, LaunchConfig};
use std::time::Instant;

struct Row {
    name: &'static str,
    simt_ms: f64,
    measured_ms: f64,
    reference_ms: f64,
    reference: &'static str,
}

fn median_ms(repeat: usize, mut f: impl FnMut()) -> f64 {
    f();
    let mut t: Vec<f64> = (0..repeat)
        .map(|_| {
            let s = Instant::now();
            f();
            s.elapsed().as_secs_f64() * 1e3
        })
        .collect();
    t.sort_by(f64::total_cmp);
    t[t.len() / 2]
}

/// Like [`median_ms`], with `setup` run untimed before each timed `run`.
fn median_ms_setup<S>(repeat: usize, mut setup: impl FnMut() -> S, mut run: impl FnMut(S)) -> f64 {
    let mut t = Vec::new();
    for _ in 0..=repeat {
        let s = setup();
        let start = Instant::now();
        run(s);
        t.push(start.elapsed().as_secs_f64() * 1e3);
    }
    t.remove(0);
    t.sort_by(f64::total_cmp);
    t[t.len() / 2]
}

fn random(n: usize, seed: u32) -> Vec<u32> {
    let mut s = seed | 1;
    (0..n)
        .map(|_| {
            s ^= s << 13;
            s ^= s >> 17;
            s ^= s << 5;
            s
        })
        .collect()
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

/// Closest hit of a ray (origin, direction, t_max, pad) against one triangle stored as
/// (v0, edge1, edge2), Möller–Trumbore; returns the new closest distance.
#[inline(always)]
fn test(ray: &[f32; 8], t: &[f32; 9], best: f32) -> f32 {
    let (o, d) = ([ray[0], ray[1], ray[2]], [ray[3], ray[4], ray[5]]);
    let cross =
        |a: [f32; 3], b: [f32; 3]| [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]];
    let dot = |a: [f32; 3], b: [f32; 3]| a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
    let (e1, e2) = ([t[3], t[4], t[5]], [t[6], t[7], t[8]]);
    let p = cross(d, e2);
    let det = dot(e1, p);
    if det.abs() < 1e-12 {
        return best;
    }
    let inv = 1.0 / det;
    let s = [o[0] - t[0], o[1] - t[1], o[2] - t[2]];
    let u = dot(s, p) * inv;
    let q = cross(s, e1);
    let v = dot(d, q) * inv;
    let tt = dot(e2, q) * inv;
    if u >= 0.0 && v >= 0.0 && u + v <= 1.0 && tt > 0.0 && tt < best { tt } else { best }
}

fn leaf_data(rays: usize, tris: usize) -> (Vec<[f32; 8]>, Vec<[f32; 9]>) {
    let r = random(rays * 6 + tris * 9, 7);
    let f = |i: usize| (r[i] % 2000) as f32 / 1000.0 - 1.0;
    let ray_data = (0..rays)
        .map(|i| [f(6 * i), f(6 * i + 1), 3.0, f(6 * i + 3) * 0.1, f(6 * i + 4) * 0.1, -1.0, 1e30, 0.0])
        .collect();
    let base = rays * 6;
    let tri_data = (0..tris)
        .map(|i| {
            let g = |k: usize| f(base + 9 * i + k);
            [g(0), g(1), g(2), g(3) * 0.3, g(4) * 0.3, g(5) * 0.3, g(6) * 0.3, g(7) * 0.3, g(8) * 0.3]
        })
        .collect();
    (ray_data, tri_data)
}

/// An unmeasured and a measured device; the measured one predicts on `profile` if any.
fn devices(profile: Option<&GpuProfile>) -> [Device; 2] {
    let devs = [false, true].map(|measure| Device::new(DeviceConfig { measure, ..Default::default() }));
    devs[1].set_gpu_profile(profile.cloned());
    devs
}

fn kernels(n: usize, repeat: usize, profile: Option<&GpuProfile>, only: Option<&str>, rows: &mut Vec<Row>) {
    let devs = devices(profile);
    let want = |row: &str| only.is_none_or(|o| o == row);
    // Times `launch` on the unmeasured and the measured device; buffers are made once
    // per device by `setup`, outside the timing.
    fn time<B>(
        devs: &[Device; 2],
        repeat: usize,
        setup: impl Fn(&Device) -> B,
        launch: impl Fn(&Device, &mut B),
    ) -> [f64; 2] {
        let mut out = [0.0; 2];
        for (k, dev) in devs.iter().enumerate() {
            let mut b = setup(dev);
            out[k] = median_ms(if k == 0 { repeat } else { repeat.min(3) }, || launch(dev, &mut b));
        }
        out
    }

    if want("saxpy") || want("saxpy_any_store") {
        let (x, y0) = (vec![1.5f32; n], vec![2.5f32; n]);
        let mut ys = y0.clone();
        let reference_ms = median_ms(repeat, || ys.par_iter_mut().zip(&x).for_each(|(y, &x)| *y += 2.0 * x));
        let buffers = |dev: &Device| (dev.alloc_from(&x), dev.alloc_from(&y0));
        if want("saxpy") {
            let [simt_ms, measured_ms] = time(&devs, repeat, buffers, |dev, (xb, yb)| {
                dev.transform_in_place("overhead::saxpy", &xb.view(), yb, |_, _, x, y| 2.0 * x + y);
            });
            rows.push(Row { name: "saxpy", simt_ms, measured_ms, reference_ms, reference: "rayon zip loop" });
        }
        if want("saxpy_any_store") {
            let [simt_ms, measured_ms] = time(&devs, repeat, buffers, |dev, (xb, yb)| {
                let (xv, yv) = (xb.view(), yb.view_mut());
                dev.for_each("overhead::saxpy_any_store", n, |t, i| {
                    t.store(&yv, i, 2.0 * t.load(&xv, i) + t.load(&yv, i))
                });
            });
            rows.push(Row { name: "saxpy_any_store", simt_ms, measured_ms, reference_ms, reference: "rayon zip loop" });
        }
    }

    if want("hash") {
        let data = random(n, 11);
        let [simt_ms, measured_ms] = time(
            &devs,
            repeat,
            |dev| (dev.alloc_from(&data), dev.alloc::<u32>(n)),
            |dev, (ib, ob)| {
                dev.transform("overhead::hash", &ib.view(), ob, |_, _, x| hash(x));
            },
        );
        let mut out = vec![0u32; n];
        let reference_ms = median_ms(repeat, || out.par_iter_mut().zip(&data).for_each(|(o, &x)| *o = hash(x)));
        rows.push(Row { name: "hash", simt_ms, measured_ms, reference_ms, reference: "rayon zip loop" });
    }

    if want("leaf") {
        let rays = n / 64;
        let (ray_data, tri_data) = leaf_data(rays, 64);
        let [simt_ms, measured_ms] = time(
            &devs,
            repeat,
            |dev| (dev.alloc_from(&ray_data), dev.alloc_from(&tri_data), dev.alloc::<f32>(rays)),
            |dev, (rb, tb, ob)| {
                let (rv, tv, ov) = (rb.view(), tb.view(), ob.view_mut());
                let cfg = LaunchConfig::linear(rays, 128).with_shared(64 * 36);
                dev.launch("overhead::leaf", cfg, |blk| {
                    let tris = blk.shared::<[f32; 9]>(64);
                    blk.for_each_thread(|t| {
                        for k in (t.thread_idx() as usize..64).step_by(t.block_dim() as usize) {
                            t.store_shared(tris, k, t.load(&tv, k));
                        }
                    });
                    blk.sync_threads();
                    blk.for_each_thread(|t| {
                        let i = t.global_idx();
                        if i < rays {
                            let ray = t.load(&rv, i);
                            let mut best = ray[6];
                            for k in 0..64 {
                                best = test(&ray, &t.load_shared(tris, k), best);
                            }
                            t.store(&ov, i, best);
                        }
                    });
                })
                .expect("valid launch");
            },
        );
        let mut out = vec![0f32; rays];
        let reference_ms = median_ms(repeat, || {
            out.par_iter_mut()
                .zip(&ray_data)
                .for_each(|(o, r)| *o = tri_data.iter().fold(r[6], |best, tri| test(r, tri, best)))
        });
        rows.push(Row {
            name: "leaf",
            simt_ms,
            measured_ms,
            reference_ms,
            reference: "rayon loop, rays x 64 triangles",
        });
    }
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let value = |flag: &str, default: usize| {
        args.iter().position(|a| a == flag).and_then(|i| args.get(i + 1)).map_or(default, |v| {
            v.parse().unwrap_or_else(|_| {
                eprintln!("overhead: {flag} wants a whole number, got '{v}'");
                std::process::exit(2)
            })
        })
    };
    let json = args.iter().any(|a| a == "--json");
    let n = value("--n", 1 << 24);
    let repeat = value("--repeat", 5).max(1);
    let rounds = value("--rounds", 1).max(1);
    let profile = args.iter().position(|a| a == "--gpu-profile").map(|i| {
        let name = args.get(i + 1).map_or("", String::as_str);
        GpuProfile::load(name).unwrap_or_else(|e| {
            eprintln!("overhead: --gpu-profile: {e}");
            std::process::exit(2)
        })
    });
    let mut table: Vec<Vec<Row>> = Vec::new();
    for _ in 0..rounds {
        let mut rows = Vec::new();
        let only = args.iter().position(|a| a == "--only").and_then(|i| args.get(i + 1));
        kernels(n, repeat, profile.as_ref(), only.map(String::as_str), &mut rows);
        // The primitives take minutes measured: skipped when only a kernel row is asked for.
        if only.is_none_or(|o| !rows.iter().any(|r| r.name == *o)) {
            primitives::all(n, repeat, profile.as_ref(), &mut rows);
        }
        if let Some(only) = only {
            rows.retain(|r| r.name == *only);
        }
        table.push(rows);
    }
    let threads = rayon::current_num_threads();
    if !json {
        println!("n = {n}, {threads} threads, median of {repeat} per call, {rounds} round(s): median ratio [range]");
        println!(
            "{:<16} {:>10} {:>12} {:>7} {:>15} {:>12} {:>9}  reference",
            "name", "simt ms", "reference ms", "ratio", "ratio range", "measured ms", "meas/off"
        );
    }
    for (k, r) in table[0].iter().enumerate() {
        let all: Vec<&Row> = table.iter().map(|rows| &rows[k]).collect();
        let med = |f: &dyn Fn(&Row) -> f64| {
            let mut v: Vec<f64> = all.iter().map(|r| f(r)).collect();
            v.sort_by(f64::total_cmp);
            (v[v.len() / 2], v[0], v[v.len() - 1])
        };
        let (simt_ms, reference_ms, measured_ms) =
            (med(&|r| r.simt_ms).0, med(&|r| r.reference_ms).0, med(&|r| r.measured_ms).0);
        let (ratio, lo, hi) = med(&|r| r.simt_ms / r.reference_ms);
        let (measured_ratio, mlo, mhi) = med(&|r| r.measured_ms / r.simt_ms);
        if json {
            println!(
                "{{\"name\":\"{}\",\"n\":{n},\"threads\":{threads},\"rounds\":{rounds},\"simt_ms\":{simt_ms:.3},\"measured_ms\":{measured_ms:.3},\"reference_ms\":{reference_ms:.3},\"ratio\":{ratio:.3},\"ratio_range\":[{lo:.3},{hi:.3}],\"measured_ratio\":{measured_ratio:.3},\"measured_ratio_range\":[{mlo:.3},{mhi:.3}],\"reference\":\"{}\"}}",
                r.name, r.reference
            );
        } else {
            println!(
                "{:<16} {:>10.2} {:>12.2} {:>7.2} {:>15} {:>12.1} {:>9.1}  {}",
                r.name,
                simt_ms,
                reference_ms,
                ratio,
                format!("[{lo:.2}, {hi:.2}]"),
                measured_ms,
                measured_ratio,
                r.reference
            );
        }
    }
}

mod primitives {
    use super::{GpuProfile, Row, median_ms, median_ms_setup, random};
    use rayon::prelude::*;
    use std::time::Instant;

    /// The faster of two references.
    fn best(a: (f64, &'static str), b: (f64, &'static str)) -> (f64, &'static str) {
        if a.0 <= b.0 { a } else { b }
    }

    pub fn all(n: usize, repeat: usize, profile: Option<&GpuProfile>, rows: &mut Vec<Row>) {
        let devs = super::devices(profile);
        let reps = |k: usize| if k == 0 { repeat } else { 1 };
        let data = random(n, 3);

        // inclusive_scan
        let mut t = [0.0; 2];
        for (k, dev) in devs.iter().enumerate() {
            let input = dev.alloc_from(&data);
            let mut out = dev.alloc::<u32>(n);
            t[k] = median_ms(reps(k), || simt::inclusive_scan(dev, &input, &mut out, 0, u32::wrapping_add));
        }
        let mut out = vec![0u32; n];
        let seq = median_ms(repeat, || {
            let mut acc = 0u32;
            for (o, &x) in out.iter_mut().zip(&data) {
                acc = acc.wrapping_add(x);
                *o = acc;
            }
        });
        let par = median_ms(repeat, || {
            const C: usize = 1 << 16;
            let sums: Vec<u32> = data.par_chunks(C).map(|c| c.iter().fold(0u32, |a, &x| a.wrapping_add(x))).collect();
            let offs: Vec<u32> =
                sums.iter().scan(0u32, |a, &s| Some(std::mem::replace(a, a.wrapping_add(s)))).collect();
            out.par_chunks_mut(C).zip(data.par_chunks(C)).zip(offs).for_each(|((o, i), mut acc)| {
                for (o, &x) in o.iter_mut().zip(i) {
                    acc = acc.wrapping_add(x);
                    *o = acc;
                }
            });
        });
        let (reference_ms, reference) = best((seq, "sequential loop"), (par, "rayon reduce-then-scan"));
        rows.push(Row { name: "inclusive_scan", simt_ms: t[0], measured_ms: t[1], reference_ms, reference });

        // sort_by_key u32/u32 (inputs restored before each run, untimed, for all).
        let vals: Vec<u32> = (0..n as u32).collect();
        for (k, dev) in devs.iter().enumerate() {
            let (mut kb, mut vb) = (dev.alloc_from(&data), dev.alloc_from(&vals));
            let mut times = Vec::new();
            for _ in 0..=reps(k) {
                kb.as_mut_slice().copy_from_slice(&data);
                vb.as_mut_slice().copy_from_slice(&vals);
                let start = Instant::now();
                simt::sort_by_key(dev, &mut kb, &mut vb);
                times.push(start.elapsed().as_secs_f64() * 1e3);
            }
            times.remove(0);
            times.sort_by(f64::total_cmp);
            t[k] = times[times.len() / 2];
        }
        #[derive(Clone, Copy)]
        struct Pair(u32, u32);
        impl rdst::RadixKey for Pair {
            const LEVELS: usize = 4;
            #[inline]
            fn get_level(&self, level: usize) -> u8 {
                (self.0 >> (level * 8)) as u8
            }
        }
        let pairs: Vec<Pair> = data.iter().zip(&vals).map(|(&k, &v)| Pair(k, v)).collect();
        let radix = median_ms_setup(
            repeat,
            || pairs.clone(),
            |mut p| {
                use rdst::RadixSort;
                p.radix_sort_unstable();
                std::hint::black_box(p[0].1);
            },
        );
        let tuples: Vec<(u32, u32)> = data.iter().copied().zip(vals.iter().copied()).collect();
        let rayon_sort = median_ms_setup(repeat, || tuples.clone(), |mut p| p.par_sort_by_key(|x| x.0));
        let (reference_ms, reference) =
            best((radix, "rdst radix_sort_unstable (pairs)"), (rayon_sort, "rayon par_sort_by_key (pairs)"));
        rows.push(Row { name: "sort_by_key", simt_ms: t[0], measured_ms: t[1], reference_ms, reference });

        // reduce_by_key: runs of 1–15 equal keys.
        let mut keys = Vec::with_capacity(n);
        let (mut key, mut left) = (0u32, 0u32);
        for &r in &data {
            if left == 0 {
                key += 1;
                left = 1 + r % 15;
            }
            keys.push(key);
            left -= 1;
        }
        for (k, dev) in devs.iter().enumerate() {
            let (kb, vb) = (dev.alloc_from(&keys), dev.alloc_from(&data));
            let (mut ok, mut ov) = (dev.alloc::<u32>(n), dev.alloc::<u32>(n));
            t[k] = median_ms(reps(k), || {
                simt::reduce_by_key(dev, &kb, &vb, &mut ok, &mut ov, 0, u32::wrapping_add);
            });
        }
        let (mut ok, mut ov) = (vec![0u32; n], vec![0u32; n]);
        let seq = median_ms(repeat, || {
            let mut m = 0;
            let mut i = 0;
            while i < n {
                let (k, mut acc) = (keys[i], data[i]);
                i += 1;
                while i < n && keys[i] == k {
                    acc = acc.wrapping_add(data[i]);
                    i += 1;
                }
                ok[m] = k;
                ov[m] = acc;
                m += 1;
            }
            std::hint::black_box(m);
        });
        let par = median_ms(repeat, || {
            // Chunks reduce their own runs into vectors, joined in order, the run split
            // at each chunk border merged.
            let parts: Vec<Vec<(u32, u32)>> = keys
                .par_chunks(1 << 16)
                .zip(data.par_chunks(1 << 16))
                .map(|(kc, vc)| {
                    let mut out: Vec<(u32, u32)> = Vec::with_capacity(kc.len() / 4);
                    for (&k, &v) in kc.iter().zip(vc) {
                        match out.last_mut() {
                            Some(l) if l.0 == k => l.1 = l.1.wrapping_add(v),
                            _ => out.push((k, v)),
                        }
                    }
                    out
                })
                .collect();
            let mut m = 0;
            for p in parts {
                for (k, v) in p {
                    if m > 0 && ok[m - 1] == k {
                        ov[m - 1] = ov[m - 1].wrapping_add(v);
                    } else {
                        ok[m] = k;
                        ov[m] = v;
                        m += 1;
                    }
                }
            }
            std::hint::black_box(m);
        });
        let (reference_ms, reference) = best((seq, "sequential loop"), (par, "rayon chunks + ordered join"));
        rows.push(Row { name: "reduce_by_key", simt_ms: t[0], measured_ms: t[1], reference_ms, reference });

        // copy_if: keep even values (half).
        for (k, dev) in devs.iter().enumerate() {
            let input = dev.alloc_from(&data);
            let mut out = dev.alloc::<u32>(n);
            t[k] = median_ms(reps(k), || {
                simt::copy_if(dev, &input, &mut out, |x| x % 2 == 0);
            });
        }
        let mut out = vec![0u32; n];
        let seq = median_ms(repeat, || {
            let mut m = 0;
            for &x in &data {
                out[m] = x;
                m += (x % 2 == 0) as usize;
            }
            std::hint::black_box(m);
        });
        let par = median_ms(repeat, || {
            let v: Vec<u32> = data.par_iter().copied().filter(|x| x % 2 == 0).collect();
            std::hint::black_box(v);
        });
        let (reference_ms, reference) = best((seq, "sequential loop"), (par, "rayon filter collect_into_vec"));
        rows.push(Row { name: "copy_if", simt_ms: t[0], measured_ms: t[1], reference_ms, reference });
    }
}
