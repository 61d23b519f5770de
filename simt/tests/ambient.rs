//! Work declared by shared code through the ambient lane (`simt::declare`, `simt::scope`):
//! known counts for one warp, and nothing recorded outside an ambient lane.

use simt::{Device, DeviceConfig};

fn measured() -> Device {
    Device::new(DeviceConfig { measure: true, ..Default::default() })
}

/// Code that does not hold the thread: a loop of `trips` trips, `per_trip` units each,
/// then 10 units after it, as a helper a kernel shares with the host would declare them.
/// With `scoped`, the loop is a scope (its k-th run by each lane is one copy).
fn shared_helper(trips: usize, per_trip: u32, scoped: bool) {
    let _loop = scoped.then(simt::scope);
    for _ in 0..trips {
        simt::declare!(per_trip);
    }
    drop(_loop);
    simt::declare!(10);
}

#[test]
fn declared_work_counts_where_the_lanes_execute_it() {
    let dev = measured();
    // One warp. Each lane calls the helper twice: even lanes with 1 then 3 trips, odd
    // lanes with 3 then 1. Per trip 2 units.
    let run = |scoped: bool| {
        dev.for_each_in("ambient", &["shared"], 32, |t, i| {
            t.ambient(0, || {
                let (a, b) = if i % 2 == 0 { (1, 3) } else { (3, 1) };
                shared_helper(a, 2, scoped);
                shared_helper(b, 2, scoped);
            })
        })
    };
    // Active lane-units, the same either way: every lane makes 4 trips and 2 exits,
    // 32 × (4 × 2 + 2 × 10) = 896.
    //
    // Without scopes the loop's site is matched by occurrence over both calls: every
    // lane makes 4 trips, so 4 warp instructions of 2 units (8 issued); the exit's two
    // occurrences are 2 of 10 (20 issued): 28.
    let plain = run(false);
    let r = &plain.regions[0];
    assert_eq!((r.issued, r.active), (28, 896));
    // With scopes each call's loop starts from its first trip: call 1 has trips 1..3
    // (3 instructions, 6 issued), call 2 the same, the exits 20: 32 issued, SIMD
    // efficiency 896 / (32 × 32) = 0.875.
    let scoped = run(true);
    let r = &scoped.regions[0];
    assert_eq!((r.issued, r.active), (32, 896));
    assert_eq!(r.simd_efficiency(), Some(896.0 / (32.0 * 32.0)));
}

#[test]
fn a_scope_is_copied_per_call_site_and_entry() {
    let dev = measured();
    // Half the lanes reach the helper from one call site, half from the other: two
    // inlined copies, so two instructions of 16 lanes for each of its sites.
    // (`declare!` keeps its own site inside a `#[track_caller]` function.)
    #[track_caller]
    fn helper() {
        let _inlined = simt::scope();
        simt::declare!(5);
    }
    #[allow(clippy::if_same_then_else)] // two call sites are the point
    let rec =
        dev.for_each_in("sites", &["shared"], 32, |t, i| t.ambient(0, || if i < 16 { helper() } else { helper() }));
    let r = &rec.regions[0];
    assert_eq!((r.issued, r.active), (10, 32 * 5));
}

#[test]
fn outside_an_ambient_lane_nothing_is_recorded() {
    let dev = measured();
    // Host code, and a measured kernel's code outside `ambient`: no work, no error.
    shared_helper(3, 2, true);
    let rec = dev.for_each_in("outside", &["shared"], 32, |_t, _i| shared_helper(2, 1, true));
    assert_eq!((rec.regions[0].issued, rec.regions[0].active), (0, 0));
    // An unmeasured launch runs the code with no lane to record into.
    let plain = Device::new(DeviceConfig::default());
    let rec = plain.for_each_in("unmeasured", &["shared"], 32, |t, _i| t.ambient(0, || shared_helper(2, 1, true)));
    assert!(rec.regions.iter().all(|r| r.issued == 0));
    // A guard kept past its ambient call does nothing when it drops.
    let rec = dev.for_each_in("kept", &["shared"], 32, |t, _i| {
        let kept = t.ambient(0, simt::scope);
        t.ambient(0, || simt::declare!(1));
        drop(kept);
    });
    assert_eq!((rec.regions[0].issued, rec.regions[0].active), (1, 32));
}

#[test]
fn work_in_a_region_the_launch_does_not_name_is_refused() {
    let dev = measured();
    let cfg = simt::LaunchConfig::linear(32, 32).with_regions(&["one"]);
    let res = dev.launch("unnamed", cfg, |blk| blk.for_each_thread(|t| t.ambient(3, || simt::declare!(1))));
    assert!(res.is_err(), "region 3 is not named by the launch");
}

#[test]
fn reads_through_plain_references_count_as_the_lanes_global_loads() {
    let dev = measured();
    // A table of 256 16-byte elements of 4-byte alignment (so 4 load instructions per
    // element, as for a view) and a record of 12 words, read by shared code that holds
    // no view.
    let table: Vec<[f32; 4]> = (0..256).map(|i| [i as f32; 4]).collect();
    let record = [0u32; 12];
    let rec = dev.for_each_in("ambient", &["shared"], 32, |t, i| {
        t.ambient(0, || {
            // Lane k reads element 2k: each of the 4 loads touches 32 sectors.
            let v = simt::read!(table, 2 * i);
            assert_eq!(v[0], (2 * i) as f32);
            // Every lane reads the record's first 5 words: 5 loads of one sector.
            simt::read_words!(&record, 5);
        })
    });
    assert_eq!((rec.loads.requests, rec.loads.sectors, rec.loads.lanes), (4 + 5, 4 * 32 + 5, 9 * 32));
    // Outside an ambient lane the same reads record nothing.
    let rec = dev.for_each_in("plain", &["shared"], 32, |_t, i| {
        std::hint::black_box(simt::read!(table, i));
        simt::read_words!(&record, 5);
    });
    assert_eq!(rec.loads.requests, 0);
}

/// The footprint (distinct sectors, for the GPU time model) of host memory read by
/// shared code is counted sector by sector, not sampled by a hash of the address: the
/// host address moves from run to run, and a sample of it would move the count.
/// Copies of one table at different host addresses give the same, exact footprint.
#[test]
fn reads_through_plain_references_have_an_exact_footprint_wherever_the_table_lives() {
    let dev = measured();
    dev.set_gpu_profile(Some(simt::GpuProfile::named("h200").unwrap()));
    let footprint = |table: &[[f32; 4]]| {
        let rec = dev.for_each_in("ambient", &["shared"], 64, |t, i| {
            t.ambient(0, || {
                // Lane k reads element 3k: 64 elements of 16 bytes, 48 bytes apart
                // from a 256-byte boundary, each in a sector of its own.
                std::hint::black_box(simt::read!(table, 3 * i));
            })
        });
        rec.footprint_sectors
    };
    // The sectors of elements 3k (bytes 48k .. 48k + 16 of a 256-byte aligned start).
    let want =
        (0..64u64).flat_map(|k| [48 * k / 32, (48 * k + 15) / 32]).collect::<std::collections::BTreeSet<_>>().len()
            as u64;
    let tables: Vec<Vec<[f32; 4]>> = (0..8).map(|j| vec![[j as f32; 4]; 200 + j]).collect();
    for t in &tables {
        assert_eq!(footprint(t), want, "table at {:p}", t.as_ptr());
    }
}
