//! Every primitive against its sequential twin in `simt::seq`, at the sizes where tiled
//! and warp-level code breaks (0, 1, 31, 32, 33, 1023, 1024, 1025, 2^17 + 3 and the tile
//! edges: 2,048 for the tiled kernels, 3,072 for a scan of 4-byte values, 5,760 for a
//! selection of them, 6,528 for a sort pass), on random inputs; plus property tests on arbitrary inputs.

use proptest::prelude::*;
use simt::{Device, DeviceConfig, seq};

/// Both backends: unmeasured (the CPU backend) and measured (the GPU kernels).
fn devices() -> [Device; 2] {
    [false, true].map(|measure| Device::new(DeviceConfig { measure, ..Default::default() }))
}

const SIZES: [usize; 17] =
    [0, 1, 31, 32, 33, 1023, 1024, 1025, 2048, 2049, 3072, 3073, 5760, 5761, 6528, 6529, (1 << 17) + 3];

/// Deterministic pseudo-random words (splitmix64).
fn random(n: usize, seed: u64, modulus: u64) -> Vec<u32> {
    let mut s = seed.wrapping_mul(0x9e37_79b9_7f4a_7c15) | 1;
    (0..n)
        .map(|_| {
            s = s.wrapping_add(0x9e37_79b9_7f4a_7c15);
            let mut z = s;
            z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
            z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
            ((z ^ (z >> 31)) % modulus) as u32
        })
        .collect()
}

fn check_scans(dev: &Device, data: &[u32]) {
    let n = data.len();
    let input = dev.alloc_from(data);
    let mut out = dev.alloc::<u32>(n);
    let add = |a: u32, b: u32| a.wrapping_add(b);
    simt::inclusive_scan(dev, &input, &mut out, 0, add);
    assert_eq!(out.as_slice(), seq::inclusive_scan(data, add).as_slice(), "inclusive +, n={n}");
    simt::exclusive_scan(dev, &input, &mut out, 17, 0, add);
    assert_eq!(out.as_slice(), seq::exclusive_scan(data, 17, add).as_slice(), "exclusive +, n={n}");
    simt::inclusive_scan(dev, &input, &mut out, 0, u32::max);
    assert_eq!(out.as_slice(), seq::inclusive_scan(data, u32::max).as_slice(), "inclusive max, n={n}");
    // A non-commutative operator (2x2 matrix product mod 2^32 packed in [u32; 4]) catches
    // any reordering of operands.
    let mats: Vec<[u32; 4]> = data.iter().map(|&x| [x | 1, x >> 3, x >> 7, 1]).collect();
    let mul = |a: [u32; 4], b: [u32; 4]| {
        [
            a[0].wrapping_mul(b[0]).wrapping_add(a[1].wrapping_mul(b[2])),
            a[0].wrapping_mul(b[1]).wrapping_add(a[1].wrapping_mul(b[3])),
            a[2].wrapping_mul(b[0]).wrapping_add(a[3].wrapping_mul(b[2])),
            a[2].wrapping_mul(b[1]).wrapping_add(a[3].wrapping_mul(b[3])),
        ]
    };
    let identity = [1, 0, 0, 1];
    let min = dev.alloc_from(&mats);
    let mut mout = dev.alloc_filled(n, identity);
    simt::inclusive_scan(dev, &min, &mut mout, identity, mul);
    assert_eq!(mout.as_slice(), seq::inclusive_scan(&mats, mul).as_slice(), "matrix scan, n={n}");
    assert_eq!(
        simt::reduce(dev, &min, identity, identity, mul),
        seq::reduce(&mats, identity, mul),
        "matrix reduce n={n}"
    );
    assert_eq!(simt::reduce(dev, &input, 5, 0, add), seq::reduce(data, 5, add), "reduce n={n}");
}

fn check_sort(dev: &Device, keys32: &[u32], begin_bit: u32, end_bit: u32) {
    let n = keys32.len();
    let vals: Vec<u32> = (0..n as u32).collect();
    let mut k = dev.alloc_from(keys32);
    let mut v = dev.alloc_from(&vals);
    simt::sort_by_key_bits(dev, &mut k, &mut v, begin_bit, end_bit);
    let wide: Vec<u64> = keys32.iter().map(|&x| x as u64).collect();
    let (wk, wv) = seq::sort_by_key_bits(&wide, &vals, begin_bit, end_bit);
    assert_eq!(v.as_slice(), wv.as_slice(), "values (stability) n={n} bits {begin_bit}..{end_bit}");
    assert!(k.as_slice().iter().zip(&wk).all(|(&a, &b)| a as u64 == b), "keys n={n}");
}

fn check_select(dev: &Device, data: &[u32]) {
    let n = data.len();
    let input = dev.alloc_from(data);
    let mut out = dev.alloc::<u32>(n);
    let count = simt::copy_if(dev, &input, &mut out, |x| x % 3 == 0);
    assert_eq!(&out.as_slice()[..count], seq::copy_if(data, |x| x % 3 == 0).as_slice(), "copy_if n={n}");
    // Sparse (each tile writes its kept elements directly) and with wider elements and
    // a stencil of another type (other tile shapes).
    let count = simt::copy_if(dev, &input, &mut out, |x| x % 50 == 0);
    assert_eq!(&out.as_slice()[..count], seq::copy_if(data, |x| x % 50 == 0).as_slice(), "sparse copy_if n={n}");
    let wide: Vec<[u32; 3]> = data.iter().map(|&x| [x, !x, x / 2]).collect();
    let stencil: Vec<u64> = data.iter().map(|&x| x as u64 * 7).collect();
    let (w, st) = (dev.alloc_from(&wide), dev.alloc_from(&stencil));
    let mut w_out = dev.alloc::<[u32; 3]>(n);
    let count = simt::copy_if_stencil(dev, &w, &st, &mut w_out, |s| s % 3 == 1);
    let want: Vec<[u32; 3]> = wide.iter().zip(&stencil).filter(|&(_, s)| s % 3 == 1).map(|(w, _)| *w).collect();
    assert_eq!(&w_out.as_slice()[..count], want.as_slice(), "copy_if_stencil of 12-byte elements n={n}");

    let map: Vec<u32> = data.iter().map(|&x| x % n.max(1) as u32).collect();
    let m = dev.alloc_from(&map);
    simt::gather(dev, &m, &input, &mut out);
    assert_eq!(out.as_slice(), seq::gather(&map, data).as_slice(), "gather n={n}");

    // A permutation for scatter: reverse order.
    let perm: Vec<u32> = (0..n as u32).rev().collect();
    let p = dev.alloc_from(&perm);
    simt::scatter(dev, &input, &p, &mut out);
    let mut want = vec![0; n];
    seq::scatter(data, &perm, &mut want);
    assert_eq!(out.as_slice(), want.as_slice(), "scatter n={n}");

    simt::sequence(dev, &mut out, 3, 2);
    assert_eq!(out.as_slice(), seq::sequence(n, 3, 2).as_slice());
    simt::fill(dev, &mut out, 9);
    assert!(out.as_slice().iter().all(|&x| x == 9));

    // reduce_by_key over runs (keys with many repeats).
    let keys: Vec<u32> = data.iter().map(|&x| x % 4).collect();
    let (k, v) = (dev.alloc_from(&keys), dev.alloc_from(data));
    let (mut ok, mut ov) = (dev.alloc::<u32>(n), dev.alloc::<u32>(n));
    let add = |a: u32, b: u32| a.wrapping_add(b);
    let runs = simt::reduce_by_key(dev, &k, &v, &mut ok, &mut ov, 0, add);
    let (wk, wv) = seq::reduce_by_key(&keys, data, add);
    assert_eq!((&ok.as_slice()[..runs], &ov.as_slice()[..runs]), (wk.as_slice(), wv.as_slice()), "reduce_by_key n={n}");
}

#[test]
fn scans_and_reductions_match_the_sequential_oracle() {
    for dev in devices() {
        for (s, &n) in SIZES.iter().enumerate() {
            check_scans(&dev, &random(n, s as u64, 1 << 32));
        }
    }
}

#[test]
fn radix_sort_matches_a_stable_sequential_sort() {
    for dev in devices() {
        for (s, &n) in SIZES.iter().enumerate() {
            // Few distinct keys make stability visible; full-width keys test every pass.
            check_sort(&dev, &random(n, 100 + s as u64, 16), 0, 32);
            check_sort(&dev, &random(n, 200 + s as u64, 1 << 32), 0, 32);
            check_sort(&dev, &random(n, 300 + s as u64, 1 << 32), 4, 13);
        }
    }
}

#[test]
fn sort_by_64_bit_keys_and_segments_stay_segments() {
    for dev in devices() {
        sort_64(&dev);
    }
}

fn sort_64(dev: &Device) {
    let n = 100_000;
    // PDACRT's use: the segment (node) id in the high bits, a code in the low bits.
    let seg = random(n, 7, 50);
    let code = random(n, 8, 4);
    let keys: Vec<u64> = seg.iter().zip(&code).map(|(&s, &c)| (s as u64) << 32 | c as u64).collect();
    let vals: Vec<u32> = (0..n as u32).collect();
    let (mut k, mut v) = (dev.alloc_from(&keys), dev.alloc_from(&vals));
    simt::sort_by_key(dev, &mut k, &mut v);
    let (wk, wv) = seq::sort_by_key_bits(&keys, &vals, 0, 64);
    assert_eq!(k.as_slice(), wk.as_slice());
    assert_eq!(v.as_slice(), wv.as_slice());
    // Each segment is contiguous, and within it the elements are in code order, ties in
    // input order.
    let out = k.as_slice();
    let mut seen = std::collections::HashSet::new();
    for w in out.windows(2) {
        if w[0] >> 32 != w[1] >> 32 {
            assert!(seen.insert(w[0] >> 32), "segment {} appears twice", w[0] >> 32);
        }
    }
}

#[test]
fn selection_and_reduce_by_key_match_the_sequential_oracle() {
    for dev in devices() {
        for (s, &n) in SIZES.iter().enumerate() {
            check_select(&dev, &random(n, 400 + s as u64, 1000));
        }
    }
    // Long runs that cross the CPU backend's chunks, and one run of everything.
    let dev = Device::default();
    for modulus in [1, 3] {
        let n = 300_000;
        let keys: Vec<u32> = (0..n as u32).map(|i| (i / 100_003) % modulus).collect();
        let vals = random(n, 9, 1000);
        let (k, v) = (dev.alloc_from(&keys), dev.alloc_from(&vals));
        let (mut ok, mut ov) = (dev.alloc::<u32>(n), dev.alloc::<u32>(n));
        let runs = simt::reduce_by_key(&dev, &k, &v, &mut ok, &mut ov, 0, u32::wrapping_add);
        let (wk, wv) = seq::reduce_by_key(&keys, &vals, u32::wrapping_add);
        assert_eq!((&ok.as_slice()[..runs], &ov.as_slice()[..runs]), (wk.as_slice(), wv.as_slice()));
    }
}

#[test]
fn primitives_free_their_temporaries() {
    for dev in devices() {
        free_temporaries(&dev);
    }
}

fn free_temporaries(dev: &Device) {
    let data = random(50_000, 1, 1 << 32);
    let (mut k, mut v) = (dev.alloc_from(&data), dev.alloc_from(&data));
    let before = dev.memory().current;
    simt::sort_by_key(dev, &mut k, &mut v);
    let mut out = dev.alloc::<u32>(data.len());
    simt::inclusive_scan(dev, &k, &mut out, 0, |a, b| a ^ b);
    drop(out);
    assert_eq!(dev.memory().current, before);
    assert!(dev.memory().peak > before, "temporaries are counted while they live");
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 48, failure_persistence: None, ..ProptestConfig::default() })]

    #[test]
    fn prop_scan_sort_select(data in proptest::collection::vec(any::<u32>(), 0..5000), bits in 1u32..32) {
        for dev in devices() {
            check_scans(&dev, &data);
            check_sort(&dev, &data, 0, bits);
            check_select(&dev, &data);
        }
    }
}

/// The single-pass primitives' tiles wait for the tiles before them, on whichever worker
/// runs those; results and counters must not depend on how many workers there are.
#[test]
fn single_pass_primitives_give_the_same_results_and_counters_at_any_thread_count() {
    let data = random(300_003, 7, 1 << 32);
    let run = |threads: usize| {
        let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
        pool.install(|| {
            let dev = Device::new(DeviceConfig { measure: true, ..Default::default() });
            let input = dev.alloc_from(&data);
            let mut scanned = dev.alloc::<u32>(data.len());
            simt::exclusive_scan(&dev, &input, &mut scanned, 3, 0, |a, b| a.wrapping_add(b));
            let (mut k, mut v) = (dev.alloc_from(&data), dev.alloc_from(&data));
            simt::sort_by_key(&dev, &mut k, &mut v);
            let mut kept = dev.alloc::<u32>(data.len());
            let m = simt::copy_if(&dev, &input, &mut kept, |x| x % 3 == 0);
            // Every column but the seconds (the fifth).
            let records: Vec<String> = simt::records_to_tsv(&dev.launch_log())
                .lines()
                .map(|l| {
                    l.split('\t').enumerate().filter(|&(i, _)| i != 4).map(|(_, c)| c).collect::<Vec<_>>().join("\t")
                })
                .collect();
            (scanned.to_vec(), k.to_vec(), v.to_vec(), kept.as_slice()[..m].to_vec(), records)
        })
    };
    let one = run(1);
    assert!(one.4.iter().any(|l| l.starts_with("simt::scan_tiles\t")), "the scan ran as the tiled kernel");
    for threads in [2, 5] {
        assert_eq!(run(threads), one, "{threads} threads against one");
    }
}

/// Single-pass launches made from inside rayon work (several devices scanning and
/// sorting at once on a small pool) finish, with the results a lone call gives.
#[test]
fn single_pass_primitives_nested_in_rayon_work_finish() {
    use rayon::prelude::*;
    let data = random(100_003, 11, 1 << 32);
    let alone = {
        let dev = Device::new(DeviceConfig { measure: true, ..Default::default() });
        let (mut k, mut v) = (dev.alloc_from(&data), dev.alloc_from(&data));
        simt::sort_by_key(&dev, &mut k, &mut v);
        k.to_vec()
    };
    for threads in [2, 3] {
        let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
        let all: Vec<Vec<u32>> = pool.install(|| {
            (0..6)
                .into_par_iter()
                .map(|_| {
                    let dev = Device::new(DeviceConfig { measure: true, ..Default::default() });
                    let (mut k, mut v) = (dev.alloc_from(&data), dev.alloc_from(&data));
                    simt::sort_by_key(&dev, &mut k, &mut v);
                    k.to_vec()
                })
                .collect()
        });
        assert!(all.iter().all(|k| *k == alone), "{threads} threads");
    }
}
