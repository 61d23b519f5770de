//! Known-answer tests of the emulator itself: launch errors, SIMD efficiency,
//! coalescing, warp intrinsics, barriers, registers, atomics and memory accounting.
//! About 840 lines: one known answer per rule of the execution model, which reads best
//! beside the others; other launch forms are in `launch_forms.rs`.

use simt::{Device, DeviceConfig, LaunchConfig, LaunchError, Place, WorkQueue};

fn measured() -> Device {
    Device::new(DeviceConfig { measure: true, ..Default::default() })
}

#[test]
fn shared_memory_over_capacity_is_a_launch_error() {
    let dev = Device::new(DeviceConfig { shared_capacity: 1024, measure: false });
    let ran = std::sync::atomic::AtomicBool::new(false);
    let cfg = LaunchConfig::linear(64, 64).with_shared(1025);
    let err =
        dev.launch("too_much_shared", cfg, |_| ran.store(true, std::sync::atomic::Ordering::Relaxed)).unwrap_err();
    assert_eq!(err, LaunchError::SharedMemory { kernel: "too_much_shared", requested: 1025, capacity: 1024 });
    assert!(err.to_string().contains("1025") && err.to_string().contains("too_much_shared"));
    assert!(!ran.into_inner(), "a refused launch must not run");
    // Exactly the capacity is fine; the default capacity is CUDA's 48 KiB.
    dev.launch("exact", LaunchConfig::linear(64, 64).with_shared(1024), |_| {}).unwrap();
    assert_eq!(Device::default().config().shared_capacity, 48 * 1024);
    let big = LaunchConfig::linear(64, 64).with_shared(48 * 1024 + 4);
    assert!(matches!(Device::default().launch("k", big, |_| {}), Err(LaunchError::SharedMemory { .. })));
}

#[test]
fn bad_block_sizes_are_launch_errors() {
    let dev = Device::default();
    for block in [0, 1025, 4096] {
        let cfg = LaunchConfig { grid: 1, block, shared_bytes: 0, regions: &[], registers: 0, code_bytes: 0 };
        assert!(matches!(dev.launch("k", cfg, |_| {}), Err(LaunchError::BlockSize { .. })));
    }
}

#[test]
fn claiming_more_shared_than_declared_panics_clearly() {
    let dev = Device::default();
    let r = std::panic::catch_unwind(|| {
        dev.launch("greedy", LaunchConfig::linear(32, 32).with_shared(64), |blk| {
            let _ = blk.shared::<u32>(17);
        })
    });
    assert!(r.is_err());
}

#[test]
fn half_warp_branch_of_equal_length_runs_at_half_efficiency() {
    let dev = measured();
    let cfg = LaunchConfig::linear(4096, 256).with_regions(&["branch"]);
    let rec = dev
        .launch("half_branch", cfg, |blk| {
            blk.for_each_thread(|t| {
                // Even lanes take the `if`, odd lanes the `else`; both arms do 10 steps.
                let path = (t.lane_id() % 2) as usize;
                for _ in 0..10 {
                    t.work(0, path, 1);
                }
            })
        })
        .unwrap();
    assert_eq!(rec.region_efficiency("branch"), Some(0.5));
    // Everyone on the same arm: full efficiency.
    let rec = dev
        .launch("uniform", LaunchConfig::linear(4096, 256).with_regions(&["branch"]), |blk| {
            blk.for_each_thread(|t| t.work(0, 0, 10))
        })
        .unwrap();
    assert_eq!(rec.region_efficiency("branch"), Some(1.0));
    // A loop where lane i runs i+1 trips: issued 32, active 1+…+32 = 528 per warp.
    let rec = dev
        .launch("ragged_loop", LaunchConfig::linear(64, 64).with_regions(&["loop"]), |blk| {
            blk.for_each_thread(|t| t.work(0, 0, t.lane_id() + 1))
        })
        .unwrap();
    assert_eq!(rec.region_efficiency("loop"), Some(528.0 / (32.0 * 32.0)));
    // A partial warp lowers efficiency: a block of 40 threads is one full warp and one
    // of 8 lanes, each lane doing one load.
    let data = dev.alloc::<u32>(40);
    let v = data.view();
    let cfg = LaunchConfig { grid: 3, block: 40, shared_bytes: 0, regions: &[], registers: 0, code_bytes: 0 };
    let rec = dev
        .launch("partial", cfg, |blk| {
            blk.for_each_thread(|t| {
                std::hint::black_box(t.load(&v, t.thread_idx() as usize));
            })
        })
        .unwrap();
    assert_eq!(rec.simd_efficiency(), Some(40.0 / 64.0));
}

#[test]
fn an_early_break_is_measured_not_declared() {
    // Each lane scans for its target and breaks when it finds it: lane l loads l + 1
    // elements. Per warp 32 loads issue (the longest lane) and 1 + … + 32 = 528 lanes
    // execute, whatever the kernel declares.
    let dev = measured();
    let data = dev.alloc_from(&(0..64u32).collect::<Vec<_>>());
    let v = data.view();
    let rec = dev.for_each("early_break", 64, |t, i| {
        for k in 0..64 {
            if t.load(&v, k) == (i % 32) as u32 {
                break;
            }
        }
    });
    assert_eq!((rec.ops.issued, rec.ops.active), (2 * 32, 2 * 528));
    assert_eq!(rec.simd_efficiency(), Some(528.0 / 1024.0));
    // The same loop with no break runs at full efficiency: the metric can tell them apart.
    let rec = dev.for_each("no_break", 64, |t, _| {
        for k in 0..64 {
            std::hint::black_box(t.load(&v, k));
        }
    });
    assert_eq!(rec.simd_efficiency(), Some(1.0));
}

#[test]
fn an_unannotated_branch_issues_both_arms() {
    let dev = measured();
    let (a, b) = (dev.alloc::<u32>(256), dev.alloc::<u32>(256));
    let (av, bv) = (a.view(), b.view());
    // Even lanes load from `a` three times, odd lanes from `b` three times: six warp
    // instructions with 16 lanes each.
    let rec = dev.for_each("branch", 256, |t, i| {
        for _ in 0..3 {
            if i % 2 == 0 {
                std::hint::black_box(t.load(&av, i));
            } else {
                std::hint::black_box(t.load(&bv, i));
            }
        }
    });
    assert_eq!((rec.ops.issued, rec.ops.active), (8 * 6, 256 * 3));
    assert_eq!(rec.simd_efficiency(), Some(0.5));
}

#[test]
fn lanes_outside_the_launch_are_inactive() {
    let dev = measured();
    let data = dev.alloc::<u32>(40);
    let v = data.view();
    // 40 threads in one block of 256: warp 0 full, warp 1 with 8 lanes, warps 2–7 idle
    // (they issue nothing).
    let rec = dev.for_each("forty", 40, |t, i| {
        std::hint::black_box(t.load(&v, i));
    });
    assert_eq!((rec.ops.issued, rec.ops.active), (2, 40));
    assert_eq!(rec.simd_efficiency(), Some(40.0 / 64.0));
}

#[test]
fn warp_intrinsics_and_shared_accesses_are_instructions() {
    let dev = measured();
    let cfg = LaunchConfig { grid: 1, block: 64, shared_bytes: 64 * 4, regions: &[], registers: 0, code_bytes: 0 };
    let rec = dev
        .launch("intrinsic_count", cfg, |blk| {
            let s = blk.shared::<u32>(64);
            blk.for_each_warp(|w| {
                w.for_each_lane(|t| t.store_shared(s, t.thread_idx() as usize, 1));
                std::hint::black_box(w.ballot(&[true; 32]));
                std::hint::black_box(w.shfl_down(&[1u32; 32], 1));
            })
        })
        .unwrap();
    // Per warp: one shared store, one ballot, one shuffle, all 32 lanes.
    assert_eq!((rec.ops.issued, rec.ops.active), (2 * 3, 2 * 3 * 32));
}

#[test]
fn coalesced_loads_touch_4_sectors_and_strided_loads_32() {
    let dev = measured();
    let data = dev.alloc_from(&vec![1u32; 32 * 32 * 64]);
    let v = data.view();
    let rec = dev.for_each("contiguous", 1024, |t, i| {
        std::hint::black_box(t.load(&v, i));
    });
    assert_eq!(rec.loads.requests, 1024 / 32);
    assert_eq!(rec.sectors_per_request(), Some(4.0));
    let rec = dev.for_each("stride32", 1024, |t, i| {
        std::hint::black_box(t.load(&v, i * 32));
    });
    assert_eq!(rec.sectors_per_request(), Some(32.0));
    // Every lane reading the same word: one sector.
    let rec = dev.for_each("broadcast", 1024, |t, _| {
        std::hint::black_box(t.load(&v, 7));
    });
    assert_eq!(rec.sectors_per_request(), Some(1.0));
    // Two call sites are two requests per warp; a loop is one request per trip.
    let rec = dev.for_each("two_sites_and_a_loop", 64, |t, i| {
        std::hint::black_box(t.load(&v, i));
        for k in 0..3 {
            std::hint::black_box(t.load(&v, i + 64 * k));
        }
    });
    assert_eq!(rec.loads.requests, 2 * (1 + 3));
    // Random (distinct, far apart) words: 32 sectors per request.
    let rec = dev.for_each("random", 1024, |t, i| {
        std::hint::black_box(t.load(&v, (i * 7_919 * 8) % (32 * 32 * 64)));
    });
    assert_eq!(rec.sectors_per_request(), Some(32.0));
    // With measurement off nothing is counted.
    dev.set_measure(false);
    let rec = dev.for_each("unmeasured", 1024, |t, i| {
        std::hint::black_box(t.load(&v, i));
    });
    assert_eq!((rec.loads.requests, rec.loads.sectors, rec.simd_efficiency()), (0, 0, None));
}

#[test]
fn a_uniform_load_is_one_request_per_warp_on_one_element() {
    let dev = measured();
    let data = dev.alloc_from(&[5u32, 6, 7, 8, 9, 10, 11, 12]);
    let wide = dev.alloc_from(&[[1u32; 8]; 4]);
    let (v, w) = (data.view(), wide.view());
    // Three blocks of 80 threads: warps of 32, 32 and 16 lanes.
    let cfg = || LaunchConfig { grid: 3, block: 80, shared_bytes: 0, regions: &[], registers: 0, code_bytes: 0 };
    let rec = dev
        .launch("uniform", cfg(), |blk| {
            let x = blk.load_uniform(&v, blk.block_idx() as usize);
            assert_eq!(x, 5 + blk.block_idx());
            let _ = blk.load_uniform(&w, 1); // 32 bytes, 4-aligned: eight 4-byte loads
        })
        .unwrap();
    // Per warp: one request for the u32 and eight for the 32-byte element, one sector each.
    assert_eq!(rec.loads.requests, 3 * 3 * (1 + 8));
    assert_eq!(rec.loads.sectors, rec.loads.requests);
    // Every lane of a warp takes part: 16 of 32 in the partial warp.
    let expected = (2.0 * 32.0 + 16.0) / (3.0 * 32.0);
    assert!((rec.simd_efficiency().unwrap() - expected).abs() < 1e-12, "{:?}", rec.simd_efficiency());
    assert_eq!(rec.threads, 0, "a uniform load is not a phase of threads");
    // Unmeasured, the value is the same and nothing is counted.
    dev.set_measure(false);
    let rec = dev.launch("uniform_off", cfg(), |blk| assert_eq!(blk.load_uniform(&v, 2), 7)).unwrap();
    assert_eq!(rec.loads.requests, 0);
}

#[test]
fn uniform_work_counts_every_lane_of_every_warp() {
    let dev = measured();
    // Two blocks of 80 threads (warps of 32, 32 and 16 lanes); region 0 named.
    let cfg =
        || LaunchConfig { grid: 2, block: 80, shared_bytes: 0, regions: &["search"], registers: 0, code_bytes: 0 };
    let rec = dev
        .launch("uniform_work", cfg(), |blk| {
            for _ in 0..3 {
                blk.work_uniform(0, 0, 5);
            }
        })
        .unwrap();
    // Each warp issues 5 instructions three times (one call site, three occurrences),
    // with all its lanes.
    let r = &rec.regions[0];
    assert_eq!((r.name, r.issued, r.active), ("search", 2 * 3 * 3 * 5, 2 * 3 * 5 * 80));
    assert_eq!((rec.ops.issued, rec.threads), (0, 0));
    dev.set_measure(false);
    let rec = dev.launch("uniform_work_off", cfg(), |blk| blk.work_uniform(0, 0, 5)).unwrap();
    assert_eq!(rec.regions[0].issued, 0);
}

#[derive(Clone, Copy, Default)]
#[repr(C, align(16))]
struct Vec4([f32; 4]);
unsafe impl simt::DeviceCopy for Vec4 {}

#[derive(Clone, Copy, Default)]
#[repr(C, align(16))]
struct Ray48([f32; 12]);
unsafe impl simt::DeviceCopy for Ray48 {}

/// Requests and sectors per warp of a contiguous load of one `T` per lane.
fn contiguous<T: simt::DeviceCopy + Default>() -> (u64, u64) {
    let dev = measured();
    let data = dev.alloc::<T>(32);
    let v = data.view();
    let rec = dev.for_each("element", 32, |t, i| {
        std::hint::black_box(t.load(&v, i));
    });
    (rec.loads.requests, rec.loads.sectors)
}

#[test]
fn wide_elements_are_split_into_hardware_accesses() {
    // 4 bytes: one request, 128 bytes = 4 sectors.
    assert_eq!(contiguous::<u32>(), (1, 4));
    // 8 bytes, 8-aligned: one 8-byte access per lane, 256 bytes.
    assert_eq!(contiguous::<u64>(), (1, 8));
    // 12 bytes, 4-aligned: three 4-byte accesses at stride 12, each spanning 384 bytes.
    assert_eq!(contiguous::<[f32; 3]>(), (3, 3 * 12));
    // 16 bytes, 4-aligned: four 4-byte accesses at stride 16.
    assert_eq!(contiguous::<[u32; 4]>(), (4, 4 * 16));
    // 16 bytes, 16-aligned: one vector access, 512 bytes.
    assert_eq!(contiguous::<Vec4>(), (1, 16));
    // 48 bytes, 16-aligned: three 16-byte accesses at stride 48, each touching 32 sectors.
    assert_eq!(contiguous::<Ray48>(), (3, 3 * 32));
}

/// A node of 4-byte fields (36 bytes, 4-aligned), like PDACRT's.
#[derive(Clone, Copy, Default)]
#[repr(C)]
struct Node {
    bounds: [f32; 6],
    start: u32,
    count: u32,
    tries: u32,
}
unsafe impl simt::DeviceCopy for Node {}

#[test]
fn a_field_load_is_the_load_of_that_field_alone() {
    let dev = measured();
    let nodes: Vec<Node> = (0..64).map(|i| Node { count: i, ..Default::default() }).collect();
    let buf = dev.alloc_from(&nodes);
    // The same bytes as words: field `count` of node i is word 9i + 7.
    let words =
        dev.alloc_from(&nodes.iter().flat_map(|n| [0; 7].into_iter().chain([n.count, 0])).collect::<Vec<u32>>());
    let (v, w) = (buf.view(), words.view());
    let field = dev.for_each("field", 64, |t, i| assert_eq!(t.load_field(&v, i, |n: &Node| &n.count), i as u32));
    let word = dev.for_each("word", 64, |t, i| assert_eq!(t.load(&w, 9 * i + 7), i as u32));
    assert_eq!(field.loads.requests, 2);
    assert_eq!((field.loads.requests, field.loads.sectors), (word.loads.requests, word.loads.sectors));
    // The whole node is nine 4-byte loads; its six-float box field six.
    let whole = dev.for_each("whole", 64, |t, i| {
        std::hint::black_box(t.load(&v, i));
    });
    assert_eq!(whole.loads.requests, 2 * 9);
    let bounds = dev.for_each("bounds", 64, |t, i| {
        std::hint::black_box(t.load_field(&v, i, |n: &Node| &n.bounds));
    });
    assert_eq!(bounds.loads.requests, 2 * 6);
    // Lane i reads word i % 16 of one 64-byte element: one request over its two sectors.
    #[derive(Clone, Copy)]
    #[repr(C)]
    struct Wide([u32; 16]);
    unsafe impl simt::DeviceCopy for Wide {}
    let wide = dev.alloc_from(&[Wide(std::array::from_fn(|k| k as u32))]);
    let wv = wide.view();
    let rec = dev.for_each("words_of_one_element", 32, |t, i| {
        assert_eq!(t.load_field(&wv, 0, |x: &Wide| &x.0[i % 16]), (i % 16) as u32);
    });
    assert_eq!((rec.loads.requests, rec.loads.sectors), (1, 2));
    // A uniform field load: one request and one sector per warp.
    let cfg = LaunchConfig { grid: 2, block: 64, shared_bytes: 0, regions: &[], registers: 0, code_bytes: 0 };
    let rec = dev
        .launch("uniform_field", cfg, |blk| assert_eq!(blk.load_uniform_field(&v, 5, |n: &Node| &n.count), 5))
        .unwrap();
    assert_eq!((rec.loads.requests, rec.loads.sectors), (2 * 2, 2 * 2));
}

#[test]
fn a_field_store_writes_that_field_alone() {
    // 64 threads each store one of nine fields of one of eight nodes, at once: every
    // node ends with all its fields, none clobbered by a whole-element write, and each
    // warp's stores are one request per call site.
    let dev = measured();
    let mut buf = dev.alloc_filled(8, Node::default());
    let v = buf.view_mut();
    let rec = dev.for_each("fields", 72, |t, i| {
        let (node, field) = (i / 9, i % 9);
        if field < 6 {
            t.store_field(&v, node, |n: &Node| &n.bounds[field], (i + 1) as f32);
        } else {
            t.store_field(&v, node, |n: &Node| [&n.start, &n.count, &n.tries][field - 6], (i + 1) as u32);
        }
    });
    for (k, n) in buf.as_slice().iter().enumerate() {
        let first = 9 * k as u32 + 1;
        assert_eq!(n.bounds, std::array::from_fn(|f| (first + f as u32) as f32), "node {k}");
        assert_eq!((n.start, n.count, n.tries), (first + 6, first + 7, first + 8), "node {k}");
    }
    // Warps 0-2 (threads 0-71) each reach both call sites.
    assert_eq!((rec.stores.requests, rec.stores.lanes), (3 * 2, 72));
}

#[test]
#[should_panic(expected = "load_field")]
fn a_projection_outside_the_element_panics() {
    static OTHER: u32 = 3;
    let dev = measured();
    let buf = dev.alloc_from(&[Node::default()]);
    let v = buf.view();
    dev.for_each("outside", 1, |t, i| {
        t.load_field(&v, i, |_: &Node| &OTHER);
    });
}

#[test]
fn loads_stores_and_atomics_are_counted_apart() {
    let dev = measured();
    let x = dev.alloc::<u32>(64);
    let mut y = dev.alloc::<u32>(128);
    let mut c = dev.alloc::<u32>(1);
    let (xv, yv, cv) = (x.view(), y.view_mut(), c.view_mut());
    let rec = dev.for_each("mixed", 64, |t, i| {
        let a = t.load(&xv, i);
        t.store(&yv, 2 * i, a);
        t.atomic_add(&cv, 0, 1);
    });
    assert_eq!((rec.loads.requests, rec.loads.sectors), (2, 2 * 4));
    // Stride-2 stores: 256 bytes per warp.
    assert_eq!((rec.stores.requests, rec.stores.sectors), (2, 2 * 8));
    // Every lane on one word: one request, one sector per warp.
    assert_eq!((rec.atomics.requests, rec.atomics.sectors), (2, 2));
}

#[test]
fn an_unrolled_loop_issues_each_trip_apart() {
    let dev = measured();
    let mut y = dev.alloc::<u32>(64);
    let yv = y.view_mut();
    // Even lanes store on trip 0 only, odd lanes on trip 1 only.
    // 0: rolled; 1: each trip a closure run as its copy; 2: each trip's scope a copy.
    let kernel = |form: u32| {
        dev.for_each("two_trips", 32, |t, i| {
            for side in 0..2 {
                let body = || {
                    if i % 2 == side {
                        t.store(&yv, 2 * i + side, 1);
                    }
                };
                match form {
                    0 => body(),
                    1 => t.unrolled(side, body),
                    _ => {
                        let _trip = t.unroll(side);
                        body()
                    }
                }
            }
            // After the loop, every lane at one instruction again (the guards dropped).
            t.store(&yv, i, 3);
        })
    };
    // Matched by occurrence: every lane's first store is one instruction of 32 lanes.
    let rolled = kernel(0);
    assert_eq!((rolled.stores.requests, rolled.stores.lanes), (2, 64));
    // Unrolled, either form: the trips are two instructions of 16 lanes each, then the
    // store after the loop one of 32.
    for form in [1, 2] {
        let unrolled = kernel(form);
        assert_eq!((unrolled.stores.requests, unrolled.stores.lanes), (3, 64), "form {form}");
        assert_eq!(unrolled.stores.simd_efficiency(), Some(64.0 / 96.0));
    }
    // Nothing else changes: a copy ends with its closure.
    let after = dev.for_each("after", 32, |t, i| t.unrolled(0, || t.store(&yv, i, 2)));
    assert_eq!((after.stores.requests, after.stores.lanes), (1, 32));
}

#[test]
fn a_load_from_a_chosen_place_is_one_instruction_of_every_lane() {
    let dev = measured();
    let a = dev.alloc_from(&(0..64u32).map(|k| [k, k + 100]).collect::<Vec<_>>());
    let b = dev.alloc_from(&(0..64u32).map(|k| 1000 + k).collect::<Vec<_>>());
    let (av, bv) = (a.view(), b.view());
    let mut out = dev.alloc::<u32>(32);
    let ov = out.view_mut();
    // One warp: even lanes take field 1 of a[i], odd lanes b[i]; one load after the
    // branch (if-converted), against the same choice loaded in each arm.
    let selected = dev.for_each("selected", 32, |t, i| {
        let place = if i % 2 == 0 { Place::field(&av, i, |x: &[u32; 2]| &x[1]) } else { Place::of(&bv, i) };
        t.store(&ov, i, t.load_place(place));
    });
    assert_eq!((out.as_slice()[4], out.as_slice()[5]), (104, 1005));
    // One load of 32 lanes: 16 words 8 bytes apart in a (bytes 4..252: 8 sectors) and 16
    // words 4 bytes apart in b (bytes 4..128: 4 sectors).
    assert_eq!((selected.loads.requests, selected.loads.lanes, selected.loads.sectors), (1, 32, 12));
    let ov = out.view_mut();
    let in_arms = dev.for_each("in_arms", 32, |t, i| {
        let x = if i % 2 == 0 { t.load_field(&av, i, |x: &[u32; 2]| &x[1]) } else { t.load(&bv, i) };
        t.store(&ov, i, x);
    });
    assert_eq!((in_arms.loads.requests, in_arms.loads.lanes, in_arms.loads.sectors), (2, 32, 12));
}

#[test]
fn a_predicated_store_is_issued_for_every_lane_and_stores_for_those_on() {
    let dev = measured();
    let mut y = dev.alloc::<[u32; 3]>(32);
    let yv = y.view_mut();
    // One warp: `y[i] = i < 8 ? (1, i, i) : (0, 0, 0)` as two predicated stores of three
    // words each (nvcc's `@P0 STG` / `@!P0 STG`).
    let rec = dev.for_each("select", 32, |t, i| {
        let on = i < 8;
        t.store_if(on, &yv, i, [1, i as u32, i as u32]);
        t.store_if(!on, &yv, i, [0; 3]);
    });
    // Six store instructions, all 32 lanes active in each (SIMD 1.0).
    assert_eq!((rec.ops.issued, rec.ops.active), (6, 6 * 32));
    // Memory: three requests of 8 lanes over bytes 0..96 (3 sectors each, the 12-byte
    // stride spans them) and three of 24 lanes over bytes 96..384 (9 sectors each).
    assert_eq!((rec.stores.requests, rec.stores.lanes), (6, 3 * 8 + 3 * 24));
    assert_eq!(rec.stores.sectors, 3 * 3 + 3 * 9);
    // A predicate that no lane holds issues the instruction and makes no request.
    let none = dev.for_each("none", 32, |t, i| t.store_if(false, &yv, i, [7; 3]));
    assert_eq!((none.ops.issued, none.stores.requests, none.stores.lanes), (3, 0, 0));
    // Only the lanes on wrote.
    assert_eq!((y.as_slice()[0], y.as_slice()[3], y.as_slice()[20]), ([1, 0, 0], [1, 3, 3], [0; 3]));
}

#[test]
fn memory_instructions_count_the_lanes_that_execute_them() {
    let dev = measured();
    let x = dev.alloc::<u32>(64);
    let mut y = dev.alloc::<[u32; 4]>(64);
    let mut c = dev.alloc::<u32>(1);
    let (xv, yv, cv) = (x.view(), y.view_mut(), c.view_mut());
    // 40 threads: a full warp and 8 lanes of a second. Even threads load; every thread
    // stores a 16-byte element; threads below 5 of each warp add atomically.
    let rec = dev.for_each("lanes", 40, |t, i| {
        if i % 2 == 0 {
            std::hint::black_box(t.load(&xv, i));
        }
        t.store(&yv, i, [1; 4]);
        if t.lane_id() < 5 {
            t.atomic_add(&cv, 0, 1);
        }
    });
    assert_eq!((rec.loads.requests, rec.loads.lanes), (2, 16 + 4));
    assert_eq!(rec.loads.simd_efficiency(), Some(20.0 / 64.0));
    // A 4-aligned 16-byte element is four 4-byte stores, each by all 40 threads.
    assert_eq!((rec.stores.requests, rec.stores.lanes), (2 * 4, 40 * 4));
    assert_eq!(rec.stores.simd_efficiency(), Some(40.0 / 64.0));
    assert_eq!((rec.atomics.requests, rec.atomics.lanes), (2, 10));
    // An owned-element launch counts the same lanes: 40 elements of 4 bytes, each
    // thread loading its input and its old value and storing the new one.
    let mut z = dev.alloc::<u32>(40);
    let rec = dev.transform_in_place("owned", &x.view(), &mut z, |_, _, a, b| a + b);
    assert_eq!((rec.loads.requests, rec.loads.lanes, rec.stores.lanes), (4, 80, 40));
}

#[test]
fn warp_intrinsics_have_cuda_meaning() {
    let dev = Device::default();
    let mut out = dev.alloc::<u32>(8);
    let o = out.view_mut();
    dev.launch(
        "intrinsics",
        LaunchConfig { grid: 1, block: 40, shared_bytes: 0, regions: &[], registers: 0, code_bytes: 0 },
        |blk| {
            blk.for_each_warp(|w| {
                let lanes: [u32; 32] = w.lanes(|l| l);
                let even: [bool; 32] = std::array::from_fn(|l| l % 2 == 0);
                if w.warp_idx() == 0 {
                    w.for_each_lane(|t| {
                        if t.lane_id() == 0 {
                            t.store(&o, 0, w_ballot(&even));
                        }
                    });
                    o.write(1, w.shfl_down(&lanes, 4)[3]); // lane 3 reads lane 7
                    o.write(2, w.shfl_down(&lanes, 4)[30]); // beyond the warp: keeps its own
                    o.write(3, w.shfl_xor(&lanes, 1)[6]); // butterfly partner of 6 is 7
                    o.write(4, w.shfl_up(&lanes, 2)[1]); // below lane 0: keeps its own
                    o.write(5, w.all(&[true; 32]) as u32);
                } else {
                    // The second warp has 8 active lanes.
                    o.write(6, w.ballot(&[true; 32]));
                    o.write(7, w.all(&std::array::from_fn(|l| l < 8)) as u32);
                }
                fn w_ballot(p: &[bool; 32]) -> u32 {
                    p.iter().enumerate().fold(0, |m, (i, &b)| m | (b as u32) << i)
                }
            });
        },
    )
    .unwrap();
    assert_eq!(out.as_slice(), &[0x5555_5555, 7, 30, 7, 1, 1, 0xff, 1]);
}

#[test]
fn barriers_separate_phases_and_registers_survive_them() {
    let dev = measured();
    let n = 1000;
    let mut out = dev.alloc::<u32>(n);
    let o = out.view_mut();
    let cfg = LaunchConfig::linear(n, 128).with_shared(128 * 4);
    let rec = dev
        .launch("reverse_in_block", cfg, |blk| {
            let s = blk.shared::<u32>(128);
            let mine = blk.local::<u32>(0);
            blk.for_each_thread(|t| {
                t.set(mine, t.global_idx() as u32);
                t.store_shared(s, t.thread_idx() as usize, t.global_idx() as u32);
            });
            blk.sync_threads();
            // Every thread reads what the mirrored thread wrote in the previous phase.
            blk.for_each_thread(|t| {
                let i = t.global_idx();
                let mirrored = t.load_shared(s, 127 - t.thread_idx() as usize);
                if i < n {
                    t.store(&o, i, t.get(mine));
                    assert_eq!(mirrored as usize, t.block_idx() as usize * 128 + 127 - t.thread_idx() as usize);
                }
            });
        })
        .unwrap();
    assert_eq!(rec.barriers, rec.grid as u64);
    assert!(out.as_slice().iter().enumerate().all(|(i, &v)| v as usize == i));
}

/// A block that mirrors values through shared memory, with or without the barrier.
fn mirror(dev: &Device, barrier: bool) -> Result<simt::LaunchRecord, LaunchError> {
    dev.launch("mirror", LaunchConfig::linear(256, 128).with_shared(128 * 4), |blk| {
        let s = blk.shared::<u32>(128);
        blk.for_each_thread(|t| t.store_shared(s, t.thread_idx() as usize, t.thread_idx()));
        if barrier {
            blk.sync_threads();
        }
        blk.for_each_thread(|t| {
            std::hint::black_box(t.load_shared(s, 127 - t.thread_idx() as usize));
        });
    })
}

#[test]
fn a_missing_barrier_is_an_error_naming_the_kernel() {
    let dev = measured();
    assert!(mirror(&dev, true).is_ok());
    let err = mirror(&dev, false).unwrap_err();
    let LaunchError::SharedRace { kernel, race } = &err else { panic!("not a race: {err}") };
    assert_eq!(*kernel, "mirror");
    // Thread 0 reads word 127 first; thread 127 wrote it; block 0 is reported.
    assert_eq!((race.block, race.byte, race.first, race.second, race.hazard), (0, 127 * 4, 127, 0, "read after write"));
    assert!(err.to_string().contains("mirror") && err.to_string().contains("sync_threads"));
    // Unmeasured launches do not check (and cost nothing for it).
    assert!(mirror(&Device::default(), false).is_ok());
}

#[test]
fn races_within_a_phase_and_warp_synchronous_exchanges() {
    let dev = measured();
    let cfg = || LaunchConfig { grid: 1, block: 64, shared_bytes: 64 * 4, regions: &[], registers: 0, code_bytes: 0 };
    // Lane 1 reads what lane 0 wrote in the same phase: a race.
    let r = dev.launch("same_phase", cfg(), |blk| {
        let s = blk.shared::<u32>(64);
        blk.for_each_thread(|t| {
            if t.thread_idx() == 0 {
                t.store_shared(s, 0, 5);
            } else if t.thread_idx() == 1 {
                std::hint::black_box(t.load_shared(s, 0));
            }
        });
    });
    assert!(matches!(r, Err(LaunchError::SharedRace { kernel: "same_phase", .. })));
    // Write then read by another lane after it: write after read is a race too.
    let r = dev.launch("war", cfg(), |blk| {
        let s = blk.shared::<u32>(64);
        blk.for_each_thread(|t| {
            if t.thread_idx() == 0 {
                std::hint::black_box(t.load_shared(s, 3));
            } else if t.thread_idx() == 40 {
                t.store_shared(s, 3, 1);
            }
        });
    });
    assert!(matches!(r, Err(LaunchError::SharedRace { race: simt::Race { hazard: "write after read", .. }, .. })));
    // Within one warp, two lane phases separated by a warp-level step exchange safely.
    let r = dev.launch("warp_exchange", cfg(), |blk| {
        let s = blk.shared::<u32>(64);
        blk.for_each_warp(|w| {
            w.for_each_lane(|t| t.store_shared(s, t.thread_idx() as usize, t.lane_id()));
            w.for_each_lane(|t| {
                std::hint::black_box(t.load_shared(s, (t.thread_idx() ^ 1) as usize));
            });
        });
    });
    assert!(r.is_ok());
    // Across warps the same exchange needs a barrier.
    let r = dev.launch("cross_warp", cfg(), |blk| {
        let s = blk.shared::<u32>(64);
        blk.for_each_warp(|w| {
            w.for_each_lane(|t| t.store_shared(s, t.thread_idx() as usize, t.lane_id()));
            w.for_each_lane(|t| {
                std::hint::black_box(t.load_shared(s, (t.thread_idx() ^ 32) as usize));
            });
        });
    });
    assert!(matches!(r, Err(LaunchError::SharedRace { .. })));
}

#[test]
fn shared_memory_starts_zeroed_in_every_block() {
    let dev = Device::default();
    let mut out = dev.alloc::<u32>(64);
    let o = out.view_mut();
    dev.launch(
        "dirty",
        LaunchConfig { grid: 64, block: 32, shared_bytes: 4, regions: &[], registers: 0, code_bytes: 0 },
        |blk| {
            let s = blk.shared::<u32>(1);
            blk.for_each_thread(|t| {
                if t.thread_idx() == 0 {
                    t.store(&o, t.block_idx() as usize, t.load_shared(s, 0));
                    t.store_shared(s, 0, 99);
                }
            });
        },
    )
    .unwrap();
    assert!(out.as_slice().iter().all(|&v| v == 0));
}

#[test]
fn atomic_min_u64_keeps_the_closest_packed_hit() {
    let dev = Device::default();
    let mut best = dev.alloc_filled(4, u64::MAX);
    let b = best.view_mut();
    // 10 000 candidate hits per ray: key = distance bits << 32 | triangle id.
    dev.for_each("closest", 40_000, |t, i| {
        let ray = i % 4;
        let dist = 1.0 + ((i * 7919) % 10_000) as f32;
        t.atomic_min_u64(&b, ray, (dist.to_bits() as u64) << 32 | i as u64);
    });
    for (ray, &key) in best.as_slice().iter().enumerate() {
        let want = (0..40_000usize)
            .filter(|i| i % 4 == ray)
            .map(|i| ((1.0 + ((i * 7919) % 10_000) as f32).to_bits() as u64) << 32 | i as u64)
            .min()
            .unwrap();
        assert_eq!(key, want, "ray {ray}");
    }
    let mut c = dev.alloc::<u32>(1);
    let cv = c.view_mut();
    dev.for_each("count", 12_345, |t, _| {
        t.atomic_add(&cv, 0, 1);
    });
    assert_eq!(c.as_slice()[0], 12_345);
}

#[test]
fn memory_accounting_tracks_current_and_peak() {
    let dev = Device::default();
    assert_eq!(dev.memory().current, 0);
    let a = dev.alloc::<u32>(1000);
    let b = dev.alloc::<u64>(500);
    assert_eq!(dev.memory().current, 8000);
    drop(a);
    assert_eq!(dev.memory(), simt::MemoryStats { current: 4000, peak: 8000 });
    dev.reset_peak_memory();
    assert_eq!(dev.memory().peak, 4000);
    drop(b);
    assert_eq!(dev.memory().current, 0);
}

#[test]
fn pooled_buffers_reuse_their_allocation_without_zero_filling() {
    let dev = Device::default();
    let mut a = dev.alloc_pooled::<u32>(1000);
    a.as_mut_slice().fill(7);
    assert_eq!(dev.memory().current, 4000);
    drop(a);
    assert_eq!(dev.memory().current, 0, "idle pooled allocations are not device memory");
    // Same type, no larger: the same storage, stale contents (not zeroed).
    let b = dev.alloc_pooled::<u32>(600);
    assert_eq!(b.len(), 600);
    assert!(b.as_slice().iter().all(|&x| x == 7), "reused without zero-filling");
    // Another type never sees it; growth past the high-water mark is filled.
    let c = dev.alloc_pooled::<u64>(10);
    assert!(c.as_slice().iter().all(|&x| x == 0));
    drop(b);
    let d = dev.alloc_pooled::<u32>(1500);
    assert!(d.as_slice()[..1000].iter().all(|&x| x == 7) && d.as_slice()[1000..].iter().all(|&x| x == 0));
    assert_eq!(dev.memory().current, 1500 * 4 + 80);
}

#[test]
fn work_queue_pushes_every_item_once_and_reports_overflow() {
    let dev = Device::default();
    let mut q = WorkQueue::<u32>::new(&dev, 1000);
    let p = q.pusher();
    dev.for_each("push_odd", 1500, |t, i| {
        if i % 2 == 1 {
            p.push(t, i as u32);
        }
    });
    let mut items = q.items().to_vec();
    items.sort();
    assert_eq!(items, (0..1500).filter(|i| i % 2 == 1).collect::<Vec<u32>>());
    assert_eq!(q.dropped(), 0);
    let p = q.pusher();
    dev.for_each("push_all", 1500, |t, i| {
        p.push(t, i as u32);
    });
    assert_eq!((q.len(), q.dropped()), (1000, 750 + 1500 - 1000));
    q.clear();
    assert!(q.is_empty());
}

#[test]
fn statistics_aggregate_per_kernel_name() {
    let dev = measured();
    for _ in 0..3 {
        dev.for_each("a", 100, |_, _| {});
    }
    dev.for_each("b", 10, |_, _| {});
    let s = dev.kernel_stats();
    assert_eq!(s.iter().map(|k| (k.name, k.launches)).collect::<Vec<_>>(), vec![("a", 3), ("b", 1)]);
    assert_eq!(s[0].threads, 3 * 256);
    assert_eq!(dev.launch_log().len(), 4);
    assert!(simt::stats::format_table(&s).contains("SIMD eff"));
    dev.reset_stats();
    assert!(dev.kernel_stats().is_empty());
}

/// Every warp intrinsic in a partial last warp: 40 threads are one full warp and one of
/// 8 lanes, so each intrinsic issues twice for 40 active lanes (SIMD efficiency 0.625,
/// not 1.0), and what it returns ignores the 24 lanes that do not exist.
#[test]
fn every_warp_intrinsic_counts_and_answers_for_a_partial_warp() {
    type Probe = fn(&simt::Warp) -> u32;
    let probes: [(&str, Probe); 7] = [
        ("ballot", |w| w.ballot(&[true; 32])),
        ("any", |w| w.any(&std::array::from_fn(|l| l >= 8)) as u32),
        ("all", |w| w.all(&std::array::from_fn(|l| l < 8)) as u32),
        ("shfl_down", |w| w.shfl_down(&w.lanes(|l| l + 100), 4)[6]),
        ("shfl_up", |w| w.shfl_up(&w.lanes(|l| l + 100), 2)[7]),
        ("shfl_xor", |w| w.shfl_xor(&w.lanes(|l| l + 100), 8)[7]),
        ("shfl", |w| w.shfl(&w.lanes(|l| l + 100), 5)[0]),
    ];
    // Answers in the 8-lane warp: only its 8 lanes vote; lane 6's partner 10 and lane
    // 7's partner 15 do not exist, so those lanes keep their own values.
    let partial = [0xff, 0, 1, 106, 105, 107, 105];
    // In the full warp the same calls see all 32 lanes.
    let full = [u32::MAX, 1, 0, 110, 105, 115, 105];
    for (k, (name, probe)) in probes.into_iter().enumerate() {
        let dev = measured();
        let mut out = dev.alloc::<u32>(2);
        let o = out.view_mut();
        let rec = dev
            .launch(
                name,
                LaunchConfig { grid: 1, block: 40, shared_bytes: 0, regions: &[], registers: 0, code_bytes: 0 },
                |blk| {
                    blk.for_each_warp(|w| o.write(w.warp_idx() as usize, probe(w)));
                },
            )
            .unwrap();
        assert_eq!(out.as_slice(), &[full[k], partial[k]], "{name}: values (full warp, partial warp)");
        assert_eq!((rec.ops.issued, rec.ops.active), (2, 40), "{name}: issued and active lanes");
        assert_eq!(rec.simd_efficiency(), Some(40.0 / 64.0), "{name}");
    }
}

/// One-dimensional launches of `n` threads with `n` not a multiple of 32: ⌈n/32⌉ warps
/// issue each instruction, and only `n` lanes are active.
#[test]
fn simd_efficiency_of_launches_whose_size_is_not_a_multiple_of_32() {
    for n in [1usize, 31, 33, 40, 257, 1000] {
        let dev = measured();
        let data = dev.alloc::<u32>(n);
        let v = data.view();
        let rec = dev.for_each("odd", n, |t, i| {
            std::hint::black_box(t.load(&v, i));
        });
        let warps = n.div_ceil(32) as u64;
        assert_eq!((rec.ops.issued, rec.ops.active), (warps, n as u64), "n = {n}");
        assert_eq!(rec.simd_efficiency(), Some(n as f64 / (32 * warps) as f64), "n = {n}");
    }
}

/// The primitives built from warp intrinsics give the host's answers when the last
/// warp of the last tile is partial.
#[test]
fn primitives_are_exact_on_partial_warps() {
    let dev = measured();
    for n in [1usize, 7, 33, 1000, 4133] {
        let host: Vec<u32> = (0..n as u32).map(|i| i.wrapping_mul(2_654_435_761) >> 20).collect();
        let input = dev.alloc_from(&host);
        assert_eq!(simt::reduce(&dev, &input, 0, 0, |a, b| a + b), host.iter().sum::<u32>(), "reduce, n = {n}");
        let mut scanned = dev.alloc::<u32>(n);
        simt::inclusive_scan(&dev, &input, &mut scanned, 0, |a, b| a + b);
        let want: Vec<u32> = host
            .iter()
            .scan(0, |s, &x| {
                *s += x;
                Some(*s)
            })
            .collect();
        assert_eq!(scanned.as_slice(), &want[..], "inclusive_scan, n = {n}");
        let mut kept = dev.alloc::<u32>(n);
        let count = simt::copy_if(&dev, &input, &mut kept, |x| x % 3 == 0);
        let want: Vec<u32> = host.iter().copied().filter(|x| x % 3 == 0).collect();
        assert_eq!(&kept.as_slice()[..count], &want[..], "copy_if, n = {n}");
    }
}
