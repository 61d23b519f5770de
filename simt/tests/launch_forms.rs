//! Known answers for the launches that are not plain kernels: owned-element launches
//! (`Device::transform`, `transform_in_place`) and the 64-bit shared atomic. (Split from
//! `known_answers.rs`, which keeps the emulator's core rules.)

use simt::{Device, DeviceConfig, DeviceCopy, LaunchConfig, RETRY_TRIP_INSTRUCTIONS, Readable};

fn measured() -> Device {
    Device::new(DeviceConfig { measure: true, ..Default::default() })
}

/// `transform` and `transform_in_place` compute what the `for_each` kernel with the same
/// accesses computes, and a measured one records that kernel's statistics: one load of
/// the input (and, in place, of the old value) and one store per thread, coalesced.
#[test]
fn owned_element_launches_measure_as_the_same_kernel() {
    let n = 1000; // 31.25 warps: the last warp is partial.
    let x: Vec<f32> = (0..n).map(|i| i as f32 * 0.5).collect();
    let y: Vec<f32> = (0..n).map(|i| 1.0 - i as f32).collect();
    let want: Vec<f32> = x.iter().zip(&y).map(|(x, y)| 2.0 * x + y).collect();
    for dev in [Device::default(), measured()] {
        let xb = dev.alloc_from(&x);
        let mut yb = dev.alloc_from(&y);
        let rec = dev.transform_in_place("saxpy", &xb.view(), &mut yb, |_, _, x, y| 2.0 * x + y);
        assert_eq!(yb.as_slice(), &want[..]);
        assert_eq!((rec.grid, rec.block, rec.threads), (4, 256, 1024));
        let mut zb = dev.alloc_from(&y);
        let hand = {
            let (xv, zv) = (xb.view(), zb.view_mut());
            dev.for_each("saxpy_by_hand", n, |t, i| t.store(&zv, i, 2.0 * t.load(&xv, i) + t.load(&zv, i)))
        };
        assert_eq!(zb.as_slice(), yb.as_slice());
        assert_eq!(
            (rec.loads, rec.stores, rec.ops),
            (hand.loads, hand.stores, simt::RegionStats { name: "ops", ..hand.ops })
        );
        let mut ib = dev.alloc::<u32>(n);
        let rec = dev.transform("index", &xb.view(), &mut ib, |t, i, x| (t.global_idx() == i) as u32 + x as u32);
        assert!(ib.as_slice().iter().enumerate().all(|(i, &v)| v == 1 + (i as u32) / 2));
        if dev.measuring() {
            assert!(rec.measured);
            // 32 warps: one load and one store request each, 4 sectors (128 bytes) when full.
            assert_eq!((rec.loads.requests, rec.stores.requests), (32, 32));
            assert_eq!((rec.loads.sectors, rec.stores.sectors), (31 * 4 + 1, 31 * 4 + 1));
            assert!((rec.ops.active as f64 / (rec.ops.issued as f64 * 32.0) - 1000.0 / 1024.0).abs() < 1e-9);
        } else {
            assert_eq!((rec.loads.requests, rec.stores.requests), (0, 0));
        }
    }
}

/// A 16-byte element with 16-byte alignment: one 16-byte access per lane.
#[repr(C, align(16))]
#[derive(Clone, Copy, Debug, Default, PartialEq)]
struct Quad([f32; 4]);
unsafe impl DeviceCopy for Quad {}

/// A 48-byte record with 16-byte alignment (a ray): three 16-byte accesses per lane.
#[repr(C, align(16))]
#[derive(Clone, Copy, Debug, Default, PartialEq)]
struct Record([f32; 12]);
unsafe impl DeviceCopy for Record {}

/// A measured owned launch counts its owned accesses a block at a time. Its statistics
/// equal those of the `for_each` kernel that loads and stores the same elements itself
/// (recorded lane by lane), for elements of 4, 8, 12, 16 and 48 bytes, inputs that
/// start inside a sector, partial warps, and a closure that makes accesses of its own
/// (a scattered load on every third thread, of the input's buffer, inside and outside
/// the input); with a GPU profile, so do the footprints and the warps' chains that the
/// time model reads, which the owned launch keeps as runs of sectors.
#[test]
fn owned_launches_count_what_the_lane_by_lane_kernel_counts() {
    fn check<T: DeviceCopy + PartialEq + std::fmt::Debug>(make: fn(usize) -> T) {
        let dev = measured();
        dev.set_gpu_profile(Some(simt::GpuProfile::named("h200").unwrap()));
        for (n, offset) in [(1000, 0), (77, 3), (4096, 1), (5, 2), (20_000, 5)] {
            let data: Vec<T> = (0..n + offset + 40).map(make).collect();
            let xb = dev.alloc_from(&data);
            let xv = xb.slice(offset, n);
            let ov = xb.view();
            let gather = |i: usize| (i * 7919) % data.len();
            for in_place in [false, true] {
                let start: Vec<T> = (0..n).map(|i| make(i + 5)).collect();
                let mut yb = dev.alloc_from(&start);
                let rec = if in_place {
                    dev.transform_in_place("owned", &xv, &mut yb, |t, i, x, old| match i % 3 {
                        0 => t.load(&ov, gather(i)),
                        1 => old,
                        _ => x,
                    })
                } else {
                    dev.transform("owned", &xv, &mut yb, |t, i, x| if i % 3 == 0 { t.load(&ov, gather(i)) } else { x })
                };
                // The kernel by hand stores to the same buffer, from the same start, so
                // that the footprints' samples are of the same addresses.
                let owned = yb.as_slice().to_vec();
                yb.as_mut_slice().copy_from_slice(&start);
                let hand = {
                    let zv = yb.view_mut();
                    dev.for_each("by_hand", n, |t, i| {
                        let x = t.load(&xv, i);
                        let old = if in_place { t.load(&zv, i) } else { zv.read(i) };
                        let y = match i % 3 {
                            0 => t.load(&ov, gather(i)),
                            1 if in_place => old,
                            _ => x,
                        };
                        t.store(&zv, i, y)
                    })
                };
                let what = format!("{} bytes, n {n}, offset {offset}, in place {in_place}", size_of::<T>());
                assert_eq!(owned, yb.as_slice(), "{what}");
                assert_eq!((rec.loads, rec.stores, rec.atomics), (hand.loads, hand.stores, hand.atomics), "{what}");
                assert_eq!(
                    (rec.ops.issued, rec.ops.active, rec.threads),
                    (hand.ops.issued, hand.ops.active, hand.threads),
                    "{what}"
                );
                assert_eq!(
                    (rec.footprint_sectors, rec.block_sectors, rec.longest_warp, rec.waits),
                    (hand.footprint_sectors, hand.block_sectors, hand.longest_warp, hand.waits),
                    "{what}"
                );
                assert!(rec.measured && rec.loads.requests > 0 && (n < 100 || rec.footprint_sectors > 0), "{what}");
            }
        }
    }
    check(|i| i as u32 * 3);
    check(|i| i as u64 * 0x1_0000_0001);
    check(|i| [i as u32, 2 * i as u32, 3 * i as u32]);
    check(|i| Quad([i as f32, 1.0, 2.0, 3.0]));
    check(|i| Record(std::array::from_fn(|k| (i * 12 + k) as f32)));
}

#[test]
fn an_owned_launch_with_a_short_input_panics_clearly() {
    let dev = Device::default();
    let (x, mut y) = (dev.alloc::<u32>(10), dev.alloc::<u32>(11));
    let r = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
        dev.transform("short", &x.view(), &mut y, |_, _, x| x)
    }));
    let msg = *r.unwrap_err().downcast::<String>().unwrap();
    assert!(msg.contains("short") && msg.contains("10") && msg.contains("11"), "{msg}");
}

/// A 64-bit shared `atomicAdd` carries into its high word, is measured as the GPU's
/// compare-and-swap retry loop, and reads back through `load_shared::<u64>`.
#[test]
fn shared_u64_atomics_carry_and_count_once_per_warp() {
    for dev in [Device::default(), measured()] {
        let mut out = dev.alloc::<u64>(1);
        let ov = out.view_mut();
        let cfg = LaunchConfig { grid: 1, block: 64, shared_bytes: 8, regions: &[], registers: 0, code_bytes: 0 };
        let rec = dev
            .launch("sum_u64", cfg, |blk| {
                let sum = blk.shared::<u64>(1);
                blk.for_each_thread(|t| {
                    t.atomic_add_shared_u64(sum, 0, (1 << 31) + t.thread_idx() as u64);
                });
                blk.sync_threads();
                blk.for_each_thread(|t| {
                    if t.thread_idx() == 0 {
                        t.store(&ov, 0, t.load_shared(sum, 0));
                    }
                });
            })
            .unwrap();
        assert_eq!(out.as_slice()[0], 64 * (1 << 31) + (0..64).sum::<u64>());
        if dev.measuring() {
            // Two warps of 32 lanes on one word take turns, one success per round:
            // lane k of warp p is done after 2k + p + 1 trips of the loop (7 instructions
            // on sm_90), so warp 0 runs 63 trips and warp 1 64, and the lanes 32·31 + 32
            // and 32·31 + 64 lane-trips. Then only warp 0 issues the shared load and the
            // store (one lane each).
            assert_eq!(RETRY_TRIP_INSTRUCTIONS, 7);
            assert_eq!((rec.ops.issued, rec.ops.active), (7 * (63 + 64) + 1 + 1, 7 * (1024 + 1056) + 1 + 1));
        }
    }
}

/// Lanes on different shared words retry side by side: two words of 16 lanes each take
/// 16 trips, and a second call site is a loop of its own.
#[test]
fn shared_u64_atomics_retry_per_word_and_per_call_site() {
    let dev = measured();
    let cfg = || LaunchConfig { grid: 1, block: 32, shared_bytes: 16, regions: &[], registers: 0, code_bytes: 0 };
    let rec = dev
        .launch("two_words", cfg(), |blk| {
            let sum = blk.shared::<u64>(2);
            blk.for_each_thread(|t| {
                t.atomic_add_shared_u64(sum, t.thread_idx() as usize % 2, 1);
            });
        })
        .unwrap();
    // One warp: the 16 lanes of each word succeed one per trip, both words at once:
    // 16 trips, trip j run by 2 · (16 − j) lanes, seven instructions each.
    assert_eq!((rec.ops.issued, rec.ops.active), (7 * 16, 7 * 2 * 136));
    let rec = dev
        .launch("two_sites", cfg(), |blk| {
            let sum = blk.shared::<u64>(2);
            blk.for_each_thread(|t| {
                if t.thread_idx() < 4 {
                    t.atomic_add_shared_u64(sum, 0, 1);
                } else {
                    t.atomic_add_shared_u64(sum, 0, 2);
                }
            });
        })
        .unwrap();
    // Four lanes (4 trips: 4 + 3 + 2 + 1) and 28 lanes (28 trips: 406 lane-trips).
    assert_eq!((rec.ops.issued, rec.ops.active), (7 * (4 + 28), 7 * (10 + 406)));
}

/// `into_vec` hands the contents over and the bytes leave the device's accounting.
#[test]
fn into_vec_moves_the_contents_out_of_the_accounting() {
    let dev = Device::default();
    let before = dev.memory().current;
    let mut b = dev.alloc_from(&[1u32, 2, 3, 4]);
    b.resize(2);
    assert_eq!(dev.memory().current, before + 16);
    assert_eq!(b.into_vec(), vec![1, 2]);
    assert_eq!(dev.memory().current, before);
}

/// Work declared in a region the launch names is in its statistics; work in a region it
/// does not name is a loud error of the measured launch (it used to vanish from the
/// record), whether the launch is a plain kernel or an element-wise `for_each`.
#[test]
fn work_in_an_unnamed_region_is_an_error_not_a_loss() {
    let dev = measured();
    // Named: lanes 0..16 take arm 0 (3 units), lanes 16..32 arm 1 (1 unit).
    let rec = dev.for_each_in("named", &["arms"], 32, |t, i| t.work(0, i / 16, if i < 16 { 3 } else { 1 }));
    let arms = &rec.regions[0];
    assert_eq!((arms.name, arms.issued, arms.active), ("arms", 4, 3 * 16 + 16));
    // Region 1 has no name: an error naming the kernel and the region.
    let cfg = LaunchConfig::linear(64, 32).with_regions(&["only"]);
    let err = dev.launch("one_name", cfg, |blk| blk.for_each_thread(|t| t.work(1, 0, 2))).unwrap_err();
    assert_eq!(err, simt::LaunchError::UnnamedWork { kernel: "one_name", region: 1, named: 1 });
    assert!(err.to_string().contains("one_name") && err.to_string().contains("region 1"));
    let caught = std::panic::catch_unwind(|| dev.for_each("no_names", 8, |t, _| t.work(0, 0, 1)));
    let message = caught.unwrap_err();
    let message = message.downcast_ref::<String>().expect("a formatted panic message");
    assert!(message.contains("no_names") && message.contains("region 0"), "{message}");
    // Unmeasured launches record no work, so there is nothing to lose.
    Device::default().for_each("no_names", 8, |t, _| t.work(0, 0, 1));
}
