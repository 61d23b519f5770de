//! `gpu_check source`: a per-instruction export split by what each access touches, set
//! beside the emulator's statistics of the same launches (`docs/gpu-check.md`, "Which
//! instructions the model sees").

use super::{merge, read};
use warpray::gpu::ncu;

/// The source-level split of each kernel in an export, and, given the emulator's
/// statistics of the same launches, the accesses it sees set beside the GPU's.
pub fn source_run(
    csv: &std::path::Path,
    simt_launches: Option<&std::path::Path>,
    classes: &str,
    first: usize,
    lines: Option<usize>,
) -> Result<(), String> {
    use warpray::gpu::source;
    let (classes, seen): (_, &[&str]) = match classes {
        "cis" => (source::CIS_CLASSES, &["pool", "cache"]),
        "all" => (source::ALL_CLASSES, &["all"]),
        other => return Err(format!("unknown classes {other} (known: cis, all)")),
    };
    let text = read(csv)?;
    let insts = source::parse(&text).map_err(|e| format!("{}: {e}", csv.display()))?;
    let splits = source::split(&insts, classes, |_, k| k < first);
    for s in &splits {
        println!("{}", source::table(s));
    }
    if let Some(top) = lines {
        println!("{}", warpray::gpu::lines::lines_table(&warpray::gpu::lines::lines(&insts, |_, k| k < first), top));
    }
    let Some(path) = simt_launches else { return Ok(()) };
    let launches: Vec<simt::KernelSummary> = simt::records_from_tsv(&read(path)?)
        .map_err(|e| format!("{}: {e}", path.display()))?
        .iter()
        .map(simt::KernelSummary::from)
        .collect();
    println!("The accesses the emulator sees ({}), on the same launches:\n", seen.join(", "));
    println!("| kernel | launches | figure | simt | GPU | Δ |\n|---|---:|---|---:|---:|---:|");
    for s in &splits {
        // The emulator's first `s.launches` launches of this kernel are the profiled ones.
        let (mut mine, mut n) = (Vec::new(), 0);
        for k in launches.iter().filter(|k| k.name == s.kernel) {
            if n >= s.launches as u64 {
                break;
            }
            n += k.launches;
            mine.push(k.clone());
        }
        if n != s.launches as u64 {
            return Err(format!(
                "{}: {} launches of {} in the export, {n} in the first rows of {}",
                csv.display(),
                s.launches,
                s.kernel,
                path.display()
            ));
        }
        let simt = merge(mine).remove(0);
        let (ld, st, at) = (s.of("Load", seen), s.of("Store", seen), s.of("Atomic", seen));
        let rows = [
            ("SIMD efficiency, loads", simt.loads.simd_efficiency(), ld.simd_efficiency()),
            ("sectors / request, loads", simt.loads.sectors_per_request(), ld.sectors_per_request()),
            ("load requests", Some(simt.loads.requests as f64), Some(ld.warp)),
            ("SIMD efficiency, stores", simt.stores.simd_efficiency(), st.simd_efficiency()),
            ("sectors / request, stores", simt.stores.sectors_per_request(), st.sectors_per_request()),
            ("atomic requests", Some(simt.atomics.requests as f64), Some(at.warp)),
            ("SIMD efficiency, atomics", simt.atomics.simd_efficiency(), at.simd_efficiency()),
            ("SIMD efficiency, every instruction", simt.simd_efficiency(), s.all.simd_efficiency()),
        ];
        for (what, p, m) in rows {
            let f = |v: Option<f64>| {
                v.map_or("–".to_string(), |x| if x >= 100.0 { format!("{x:.0}") } else { format!("{x:.3}") })
            };
            let d = ncu::relative(p, m).map_or("–".to_string(), |x| format!("{:+.1} %", x * 100.0));
            println!("| {} | {} | {what} | {} | {} | {d} |", s.kernel, s.launches, f(p), f(m));
        }
    }
    Ok(())
}
