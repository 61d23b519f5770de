//! `gpu_check gpu --gpu bvh`: the GPU BVH baseline (`warpray::gpu::GpuBvh`) built and
//! traced on the GPU for each (model, batch), its keys checked bit for bit against its
//! emulated twin (`warpray::cast::Lbvh`, the kernels `gpu_check simt --caster lbvh`
//! measures) and on a sample against brute force. Under ncu each batch is one build and
//! `--repeat` traces, as the emulated run is one build and one trace.

use crate::{Input, brute_check, inputs, median};
use std::io::Write as _;
use warpray::cast::{BruteForce, Lbvh};
use warpray::gpu::GpuBvh;

pub(crate) fn run(input: &Input, repeat: u32, brute_every: usize) -> Result<(), String> {
    let mut failed = 0usize;
    println!(
        "| model | batch | rays | GPU build ms | GPU trace ms | tests/ray | nodes/ray | keys = simt twin | brute-force sample |"
    );
    println!("|---|---|---:|---:|---:|---:|---:|---|---|");
    for (model, scene, name, rays, shadow) in inputs(input)? {
        let tris = scene.triangle_vertices();
        let gpu = GpuBvh::new(&tris).map_err(|e| e.to_string())?;
        let build_ms = gpu.last_build().build_ms;
        let mut trace = Vec::new();
        let mut keys = Vec::new();
        for _ in 0..repeat {
            keys = gpu.trace_keys(&rays, shadow).map_err(|e| e.to_string())?;
            trace.push(gpu.last_trace().trace_ms);
        }
        let s = gpu.last_trace();
        let twin = Lbvh::on_device(&tris, simt::Device::default());
        let (want, tests, visits) = twin.trace_keys(&rays, shadow);
        let differ = keys.iter().zip(&want).filter(|(a, b)| a != b).count();
        let counters = if (tests, visits) == (s.tests, s.visits) { "" } else { " (counters differ)" };
        let brute = if brute_every > 0 {
            brute_check(&gpu, &BruteForce::new(&scene), &rays, shadow, brute_every)
        } else {
            (0, 0)
        };
        failed += differ + brute.1 + usize::from(!counters.is_empty());
        let n = rays.len().max(1) as f64;
        println!(
            "| {model} | {name} | {} | {build_ms:.3} | {:.3} | {:.2} | {:.1} | {differ} of {} differ{counters} | {} of {} differ |",
            rays.len(),
            median(trace),
            s.tests as f64 / n,
            s.visits as f64 / n,
            rays.len(),
            brute.1,
            brute.0
        );
        std::io::stdout().flush().ok();
    }
    if failed > 0 {
        return Err(format!("{failed} rays (or counters) differ between the GPU BVH and its references"));
    }
    Ok(())
}
