//! Known answers for what the GPU time model reads from a measured launch
//! (`simt::timing`): the launch's distinct sectors (its footprint) and those its loads
//! touched (the first touches a load waits for HBM on), each block's
//! distinct loaded sectors (what its loads bring from L2 when its repeated loads hit
//! L1; stores reach L2 every time and are counted as stores), and the longest warp's
//! instructions and load rounds. The sector counts are estimated from 1 address in 16,
//! so they are checked on arrays large enough for the estimate to be within 1 %.

use simt::{Device, DeviceConfig, LaunchConfig, WarpChain};

/// A chain of `instructions` and `load_rounds`, nothing else waited for.
fn chain(instructions: u64, load_rounds: u64) -> WarpChain {
    WarpChain { instructions, load_rounds, ..WarpChain::default() }
}

/// A measured device predicting on the shipped H200 profile (the footprints and warp
/// chains are gathered only then).
fn measured() -> Device {
    let dev = Device::new(DeviceConfig { measure: true, ..Default::default() });
    dev.set_gpu_profile(Some(simt::GpuProfile::named("h200").unwrap()));
    dev
}

fn near(estimate: u64, exact: u64) -> bool {
    (estimate as f64 - exact as f64).abs() <= 0.01 * exact as f64
}

#[test]
fn a_stream_touches_each_sector_once_per_launch_and_per_block() {
    let dev = measured();
    let n = 1 << 20; // 4 MiB of f32: 131,072 sectors.
    let x = dev.alloc_from(&vec![1.0f32; n]);
    let mut y = dev.alloc::<f32>(n);
    let (xv, yv) = (x.view(), y.view_mut());
    let rec = dev.for_each("stream", n, |t, i| t.store(&yv, i, t.load(&xv, i)));
    let sectors = 2 * (n as u64 * 4 / 32);
    assert!(near(rec.footprint_sectors, sectors), "{} vs {sectors}", rec.footprint_sectors);
    // Blocks load disjoint sectors, so per block is the loaded half of the footprint.
    let loaded = sectors / 2;
    assert!(near(rec.block_sectors, loaded), "{} vs {loaded}", rec.block_sectors);
    assert_eq!(rec.stores.sectors, loaded);
    // The owned-element form records the same.
    let own = dev.transform("stream_owned", &x.view(), &mut y, |_, _, v| v);
    assert!(near(own.footprint_sectors, sectors) && near(own.block_sectors, loaded), "{own:?}");
    // The loads touched the input only: the output's first touches are stores.
    for r in [&rec, &own] {
        assert!(near(r.loaded_footprint_sectors, loaded), "{} vs {loaded}", r.loaded_footprint_sectors);
    }
    assert_eq!(own.longest_warp, chain(2, 1));
    assert_eq!(rec.longest_warp, chain(2, 1));
}

#[test]
fn a_sector_loaded_and_stored_counts_once_in_the_footprint_and_as_loaded() {
    let dev = measured();
    let n = 1 << 20; // 131,072 sectors each.
    let x = dev.alloc_from(&vec![1.0f32; n]);
    let mut y = dev.alloc_from(&vec![2.0f32; n]);
    let sectors = 2 * (n as u64 * 4 / 32);
    {
        let (xv, yv) = (x.view(), y.view_mut());
        let rec = dev.for_each("axpy", n, |t, i| t.store(&yv, i, t.load(&xv, i) + t.load(&yv, i)));
        assert!(near(rec.footprint_sectors, sectors), "{} vs {sectors}", rec.footprint_sectors);
        assert!(near(rec.loaded_footprint_sectors, sectors), "{} vs {sectors}", rec.loaded_footprint_sectors);
    }
    let own = dev.transform_in_place("axpy_owned", &x.view(), &mut y, |_, _, a, b| a + b);
    assert!(near(own.footprint_sectors, sectors), "{} vs {sectors}", own.footprint_sectors);
    assert!(near(own.loaded_footprint_sectors, sectors), "{} vs {sectors}", own.loaded_footprint_sectors);
    assert!(y.as_slice().iter().all(|&v| v == 4.0));
}

#[test]
fn a_table_every_block_reads_is_one_footprint_and_one_l2_read_per_block() {
    let dev = measured();
    let n = 1 << 18; // 1 MiB: 32,768 sectors.
    let table = dev.alloc_from(&vec![2u32; n]);
    let mut sum = dev.alloc::<u32>(64 * 256);
    let (tv, sv) = (table.view(), sum.view_mut());
    let cfg = LaunchConfig { grid: 64, block: 256, shared_bytes: 0, regions: &[], registers: 0, code_bytes: 0 };
    let rec = dev
        .launch("table", cfg, |blk| {
            blk.for_each_thread(|t| {
                let mut s = 0;
                for k in (t.thread_idx() as usize..n).step_by(256) {
                    s += t.load(&tv, k);
                }
                t.store(&sv, t.global_idx(), s);
            })
        })
        .unwrap();
    assert!(sum.as_slice().iter().all(|&s| s == 2 * (n as u32 / 256)));
    let (table_sectors, out_sectors) = (n as u64 * 4 / 32, 64 * 256 * 4 / 32);
    let footprint = table_sectors + out_sectors;
    assert!(near(rec.footprint_sectors, footprint), "{} vs {footprint}", rec.footprint_sectors);
    assert!(near(rec.loaded_footprint_sectors, table_sectors), "{}", rec.loaded_footprint_sectors);
    let per_block = 64 * table_sectors;
    assert!(near(rec.block_sectors, per_block), "{} vs {per_block}", rec.block_sectors);
    // Every warp: 1,024 loads and a store, each with its issue slot.
    assert_eq!(rec.longest_warp, chain(1025, 1024));
    assert_eq!(rec.waits, chain(64 * 8 * 1025, 64 * 8 * 1024));
}

#[test]
fn loads_issued_together_are_one_round_of_the_chain_and_the_same_traffic() {
    let dev = measured();
    let n = 1 << 14;
    let x = dev.alloc_from(&vec![1u32; 4 * n]);
    let mut out = dev.alloc::<u32>(n);
    let (xv, ov) = (x.view(), out.view_mut());
    let run = |together: bool| {
        dev.for_each(if together { "together" } else { "apart" }, n, |t, i| {
            // Four independent loads, then one that depends on their sum.
            let group = together.then(|| t.loads_together());
            let s: u32 = (0..4).map(|k| t.load(&xv, 4 * i + k)).sum();
            drop(group);
            t.store(&ov, i, t.load(&xv, (s as usize * i) % (4 * n)));
        })
    };
    let (apart, together) = (run(false), run(true));
    // Counted alike: requests, sectors, instructions (the group issues none).
    assert_eq!((apart.loads, apart.ops.issued), (together.loads, together.ops.issued));
    let warps = n as u64 / 32;
    assert_eq!(apart.longest_warp, chain(6, 5));
    assert_eq!(apart.waits.load_rounds, 5 * warps);
    // Together: the four are one round, the dependent load another; the four requests
    // of a warp's round touch the same 16 sectors (128 words), so 48 of their 64 sector
    // requests repeat the round's and are waited for once.
    assert_eq!(together.longest_warp, simt::WarpChain { round_repeats: 48, ..chain(6, 2) });
    assert_eq!(together.waits.load_rounds, 2 * warps);
    assert_eq!((apart.waits.round_repeats, together.waits.round_repeats), (0, 48 * warps));
    // A warp whose lanes take the group on a branch only some of them reach counts
    // it once; a lane outside any group counts its own.
    let rec = dev.for_each("branch", n, |t, i| {
        if i % 2 == 0 {
            let _g = t.loads_together();
            t.load(&xv, 4 * i);
            t.load(&xv, 4 * i + 1);
        } else {
            t.load(&xv, 4 * i + 2);
        }
    });
    assert_eq!(rec.longest_warp.load_rounds, 2);
    let p = simt::GpuProfile::named("h200").unwrap();
    let (a, b) = (simt::timing::predict(&apart, &p).unwrap(), simt::timing::predict(&together, &p).unwrap());
    assert!(b.latency < a.latency && b.l2 == a.l2, "{a:?} {b:?}");
}

#[test]
fn a_flagged_selection_loads_its_flags_with_its_elements() {
    // One tile of CUB's shape for 4-byte elements (384 threads x 15): a flag array is
    // loaded as the elements are, all of a thread's at once (one round), where a
    // predicate over stencil records loads and tests them one by one (15 rounds).
    let dev = measured();
    let n = 384 * 15;
    let input = dev.alloc_from(&(0..n as u32).collect::<Vec<_>>());
    let flags = dev.alloc_from(&(0..n as u32).map(|i| (i % 3 == 0) as u32).collect::<Vec<_>>());
    let sweep = |f: &dyn Fn(&mut simt::DeviceBuffer<u32>) -> usize| {
        let mut out = dev.alloc::<u32>(n);
        let mark = dev.launch_mark();
        let kept = f(&mut out);
        let rec = dev.launches_since(mark).into_iter().find(|r| r.name == "simt::select_sweep").unwrap();
        (out.as_slice()[..kept].to_vec(), rec)
    };
    let (flagged, a) = sweep(&|out| simt::copy_flagged(&dev, &input, &flags, out));
    let (stencil, b) = sweep(&|out| simt::copy_if_stencil(&dev, &input, &flags, out, |f| f != 0));
    assert_eq!(flagged, (0..n as u32).step_by(3).collect::<Vec<_>>());
    assert_eq!(flagged, stencil);
    // The same requests, sectors and instructions; 14 rounds a warp fewer.
    assert_eq!((a.loads, a.ops.issued), (b.loads, b.ops.issued));
    assert_eq!(b.waits.load_rounds - a.waits.load_rounds, 14 * 12);
    assert_eq!(b.longest_warp.load_rounds - a.longest_warp.load_rounds, 14);
}

#[test]
fn a_warp_waits_for_atomics_whose_value_it_uses_and_for_fences_not_for_reductions() {
    let dev = measured();
    let n = 1 << 12;
    let mut counts = dev.alloc::<u32>(64);
    let cv = counts.view_mut();
    // Each lane adds to a counter and branches on the old value (an `ATOMG` the warp
    // waits for), after a fence; or adds without looking (a `RED`).
    let used = dev.for_each("used", n, |t, i| {
        t.thread_fence();
        if t.atomic_add(&cv, i % 64, 1) == u32::MAX {
            t.thread_fence();
        }
    });
    let ignored = dev.for_each("ignored", n, |t, i| t.red_add(&cv, i % 64, 1));
    assert!(counts.as_slice().iter().all(|&c| c == 2 * n as u32 / 64));
    // The same traffic and instructions (a fence issues none of its own)...
    assert_eq!((used.atomics, used.ops.issued), (ignored.atomics, ignored.ops.issued));
    // ...but one atomic and one fence waited for per warp in the first (the second
    // fence is never reached), none in the second.
    let warps = n as u64 / 32;
    let waited = WarpChain { instructions: 1, atomic_rounds: 1, fences: 1, ..WarpChain::default() };
    assert_eq!(used.longest_warp, waited);
    assert_eq!((used.waits.atomic_rounds, used.waits.fences), (warps, warps));
    assert_eq!(ignored.longest_warp, chain(1, 0));
    assert_eq!((ignored.waits.atomic_rounds, ignored.waits.fences), (0, 0));
    let p = simt::GpuProfile::named("h200").unwrap();
    let (a, b) = (simt::timing::predict(&used, &p).unwrap(), simt::timing::predict(&ignored, &p).unwrap());
    assert!(a.latency > b.latency + p.atomic_latency_s + p.fence_latency_s - 1e-12, "{a:?} {b:?}");
    assert_eq!(a.atomics, b.atomics);
    // A fence waits for the sectors its warp wrote since its last fence: a warp's 32
    // consecutive words are 4 sectors, waited for by the first fence, not the second.
    let mut out = dev.alloc::<u32>(n);
    let ov = out.view_mut();
    let fenced = dev.for_each("fenced", n, |t, i| {
        t.store(&ov, i, 1);
        t.thread_fence();
        t.thread_fence();
    });
    assert_eq!((fenced.longest_warp.fences, fenced.longest_warp.fenced_sectors), (2, 4));
    assert_eq!(fenced.waits.fenced_sectors, 4 * warps);
    // The same in 128-byte lines: a warp's 32 consecutive words are one line; words a
    // sector apart, 8 lines of 32 sectors; 8-byte values a line apart, three stores of
    // them before the fence, 96 of each (as `microbench fencemix` forms them).
    assert_eq!((fenced.longest_warp.fenced_lines, fenced.waits.fenced_lines), (1, warps));
    let mut wide = dev.alloc::<u32>(n * 32);
    let wv = wide.view_mut();
    let spread = dev.for_each("spread", n, |t, i| {
        t.store(&wv, i * 8, 1);
        t.thread_fence();
    });
    assert_eq!((spread.longest_warp.fenced_sectors, spread.longest_warp.fenced_lines), (32, 8));
    let mut pairs = dev.alloc::<u64>(n * 48);
    let pv = pairs.view_mut();
    let lines = dev.for_each("lines", n, |t, i| {
        for j in 0..3 {
            t.store(&pv, (j * n + i) * 16, 1);
        }
        t.thread_fence();
    });
    assert_eq!((lines.longest_warp.fenced_sectors, lines.longest_warp.fenced_lines), (96, 96));
    assert_eq!(lines.waits.fenced_lines, 96 * warps);
}

#[test]
fn each_block_counts_the_most_of_each_wait_any_of_its_warps_has() {
    let dev = measured();
    let n = 4096;
    let x = dev.alloc_from(&vec![1u32; n]);
    let mut out = dev.alloc::<u32>(n);
    let (xv, ov) = (x.view(), out.view_mut());
    // In block b (256 threads, 8 warps) warp 1 loads 10 + b times and warp 2 fences
    // three times; every other warp loads once. A block's slot is held for the most of
    // each: 11 + b instructions, 10 + b load rounds, 3 fences.
    let rec = dev.for_each("slowest", n, |t, i| {
        let (b, warp) = (i / 256, i % 256 / 32);
        let trips = if warp == 1 { 10 + b } else { 1 };
        let s: u32 = (0..trips).map(|k| t.load(&xv, (i + k) % n)).sum();
        if warp == 2 {
            (0..3).for_each(|_| t.thread_fence());
        }
        t.store(&ov, i, s);
    });
    assert_eq!(rec.block, 256);
    let blocks = (n / 256) as u64;
    let rounds: u64 = (0..blocks).map(|b| 10 + b).sum();
    let expected =
        WarpChain { instructions: rounds + blocks, load_rounds: rounds, fences: 3 * blocks, ..WarpChain::default() };
    assert_eq!(rec.block_chains, expected);
    // The longest warp is one warp: the last block's looping one.
    assert_eq!(rec.longest_warp, chain(11 + blocks - 1, 10 + blocks - 1));
}

#[test]
fn the_longest_warp_is_the_one_that_loops_longest() {
    let dev = measured();
    let x = dev.alloc_from(&vec![1u32; 4096]);
    let mut out = dev.alloc::<u32>(4096);
    let (xv, ov) = (x.view(), out.view_mut());
    let rec = dev.for_each("skewed", 4096, |t, i| {
        // Lane 0 of the warp starting at thread 1,024 loads 100 times; the rest once.
        let trips = if i == 1024 { 100 } else { 1 };
        let s: u32 = (0..trips).map(|k| t.load(&xv, (i + k) % 4096)).sum();
        t.store(&ov, i, s);
    });
    assert_eq!(rec.longest_warp, chain(101, 100));
    // Unmeasured launches, and measured ones without a profile, record none of it.
    for plain in [Device::default(), Device::new(DeviceConfig { measure: true, ..Default::default() })] {
        let y = plain.alloc_from(&vec![1u32; 64]);
        let yv = y.view();
        let r = plain.for_each("plain", 64, |t, i| {
            t.load(&yv, i);
        });
        assert_eq!((r.footprint_sectors, r.block_sectors, r.longest_warp), (0, 0, WarpChain::default()));
        assert_eq!(plain.kernel_stats()[0].gpu_seconds, 0.0);
    }
    assert!(dev.kernel_stats().iter().all(|k| k.gpu_seconds > 0.0));
}
