//! Sums 100 000 numbers: each block stages its slice in shared memory, a barrier, then
//! each warp reduces with `shfl_down` and one thread per block adds the block's total
//! to the result with an atomic. Prints what the emulated GPU measured.
use simt::{Device, DeviceConfig, LaunchConfig};

fn main() {
    let dev = Device::new(DeviceConfig { measure: true, ..Default::default() });
    let n = 100_000;
    let input = dev.alloc_from(&(0..n as u32).collect::<Vec<_>>());
    let mut total = dev.alloc::<u64>(1);
    let (inp, out) = (input.view(), total.view_mut());

    let cfg = LaunchConfig::linear(n, 256).with_shared(256 * 4);
    let record = dev
        .launch("example::block_sum", cfg, |blk| {
            let stage = blk.shared::<u32>(256);
            blk.for_each_thread(|t| {
                let i = t.global_idx();
                let v = if i < n { t.load(&inp, i) } else { 0 };
                t.store_shared(stage, t.thread_idx() as usize, v);
            });
            blk.sync_threads();
            blk.for_each_warp(|w| {
                let first = w.warp_idx() as usize * 32;
                let mut v = [0u64; 32];
                w.for_each_lane(|t| {
                    v[t.lane_id() as usize] = t.load_shared(stage, first + t.lane_id() as usize) as u64
                });
                for d in [16, 8, 4, 2, 1] {
                    let down = w.shfl_down(&v, d);
                    for lane in 0..d as usize {
                        v[lane] += down[lane];
                    }
                }
                w.for_each_lane(|t| {
                    if t.lane_id() == 0 {
                        t.atomic_add_u64(&out, 0, v[0]);
                    }
                });
            });
        })
        .expect("valid launch");

    let sum = total.as_slice()[0];
    assert_eq!(sum, (n as u64 - 1) * n as u64 / 2);
    println!("sum = {sum}");
    println!(
        "{} blocks x {} threads, SIMD efficiency {:.3}, {:.2} sectors per request",
        record.grid,
        record.block,
        record.simd_efficiency().unwrap_or(0.0),
        record.sectors_per_request().unwrap_or(0.0)
    );
    print!("{}", simt::stats::format_table(&dev.kernel_stats()));
}
