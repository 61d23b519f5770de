//! Known answers for what the GPU time model reads from a measured launch
//! (`simt::timing`): the launch's distinct sectors (its footprint), each block's
//! distinct sectors (what reaches L2 when a block's repeats hit L1), and the longest
//! warp's instructions and loads. The sector counts are estimated from 1 address in 16,
//! so they are checked on arrays large enough for the estimate to be within 1 %.

use simt::{Device, DeviceConfig, LaunchConfig};

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
    // Blocks touch disjoint sectors, so per block is the launch's footprint again.
    assert!(near(rec.block_sectors, sectors), "{} vs {sectors}", rec.block_sectors);
    // The owned-element form records the same.
    let own = dev.transform("stream_owned", &x.view(), &mut y, |_, _, v| v);
    assert!(near(own.footprint_sectors, sectors) && near(own.block_sectors, sectors), "{own:?}");
    assert_eq!(own.longest_warp, (2, 1));
    assert_eq!(rec.longest_warp, (2, 1));
}

#[test]
fn a_table_every_block_reads_is_one_footprint_and_one_l2_read_per_block() {
    let dev = measured();
    let n = 1 << 18; // 1 MiB: 32,768 sectors.
    let table = dev.alloc_from(&vec![2u32; n]);
    let mut sum = dev.alloc::<u32>(64 * 256);
    let (tv, sv) = (table.view(), sum.view_mut());
    let cfg = LaunchConfig { grid: 64, block: 256, shared_bytes: 0, regions: &[], registers: 0 };
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
    let per_block = 64 * table_sectors + out_sectors;
    assert!(near(rec.block_sectors, per_block), "{} vs {per_block}", rec.block_sectors);
    // Every warp: 1,024 loads and a store, each with its issue slot.
    assert_eq!(rec.longest_warp, (1025, 1024));
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
    assert_eq!(rec.longest_warp, (101, 100));
    // Unmeasured launches, and measured ones without a profile, record none of it.
    for plain in [Device::default(), Device::new(DeviceConfig { measure: true, ..Default::default() })] {
        let y = plain.alloc_from(&vec![1u32; 64]);
        let yv = y.view();
        let r = plain.for_each("plain", 64, |t, i| {
            t.load(&yv, i);
        });
        assert_eq!((r.footprint_sectors, r.block_sectors, r.longest_warp), (0, 0, (0, 0)));
        assert_eq!(plain.kernel_stats()[0].gpu_seconds, 0.0);
    }
    assert!(dev.kernel_stats().iter().all(|k| k.gpu_seconds > 0.0));
}
