//! Predicted GPU time of the single-pass scan by its tiles: the sizes `cuda/microbench.cu`
//! runs with `MODE=scan` (CUB's own scan of 1,920 × G four-byte sums and of 640 × G
//! three-word sums, G = 1 … 1,024), scanned on a measuring device, each launch of the
//! tiled kernel (`simt::scan_tiles`) predicted on a profile with its terms. The probe's
//! measured times sit beside these in docs/simt.md ("The library primitives").
//!
//! `cargo run --release -p simt --example scan_tiles -- [--gpu-profile h200] [--json]`
use simt::{Device, DeviceConfig, GpuProfile};

/// The probe's tile counts, as `MODE=scan` steps them.
const G: [usize; 12] = [1, 2, 3, 4, 8, 16, 32, 64, 128, 256, 512, 1024];

fn add3(a: [u32; 3], b: [u32; 3]) -> [u32; 3] {
    [a[0] + b[0], a[1] + b[1], a[2] + b[2]]
}

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let json = args.iter().any(|a| a == "--json");
    let name = args.iter().position(|a| a == "--gpu-profile").and_then(|i| args.get(i + 1)).map_or("h200", |s| s);
    let profile = match GpuProfile::load(name) {
        Ok(p) => p,
        Err(e) => {
            eprintln!("scan_tiles: --gpu-profile {name}: {e}");
            std::process::exit(2);
        }
    };
    let dev = Device::new(DeviceConfig { measure: true, ..Default::default() });
    // With a profile the meter also gathers the warps' chains the model needs.
    dev.set_gpu_profile(Some(profile.clone()));
    let mut rows = Vec::new();
    for g in G {
        let mark = dev.launch_mark();
        let ones = dev.alloc_from(&vec![1u32; 1920 * g]);
        let mut out = dev.alloc::<u32>(ones.len());
        simt::exclusive_scan(&dev, &ones, &mut out, 0, 0, |a, b| a + b);
        let triples = dev.alloc_from(&vec![[1u32, 0, 1]; 640 * g]);
        let mut out3 = dev.alloc::<[u32; 3]>(triples.len());
        simt::exclusive_scan(&dev, &triples, &mut out3, [0; 3], [0; 3], add3);
        let tiled = dev.launches_since(mark).into_iter().filter(|r| r.name == "simt::scan_tiles");
        for (value, r) in ["u32", "u32x3"].into_iter().zip(tiled) {
            let t = simt::timing::predict(&r, &profile).expect("a measured launch");
            rows.push((value, g, r.grid, t));
        }
    }
    if json {
        for (value, g, tiles, t) in &rows {
            println!(
                "{{\"value\":\"{value}\",\"g\":{g},\"tiles\":{tiles},\"predicted_us\":{:.3},\"latency_us\":{:.3},\"bound\":\"{}\"}}",
                t.seconds * 1e6,
                t.latency * 1e6,
                t.bound()
            );
        }
        return;
    }
    println!("Predicted on {} (the launch {:.2} µs of each):", profile.name, profile.launch_s * 1e6);
    println!("{:6} {:>5} {:>6} {:>13} {:>11}  bound", "value", "G", "tiles", "predicted µs", "latency µs");
    for (value, g, tiles, t) in &rows {
        println!("{value:6} {g:>5} {tiles:>6} {:>13.2} {:>11.2}  {}", t.seconds * 1e6, t.latency * 1e6, t.bound());
    }
}
