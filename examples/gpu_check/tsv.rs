//! `simt::KernelSummary` to and from tab-separated lines (the measured run and the
//! report may run as separate commands).

use simt::{KernelSummary, RegionStats, Traffic};

const HEADER: &str = "name\tlaunches\tthreads\tissued\tactive\tld_req\tld_sec\tst_req\tst_sec\tat_req\tat_sec\tshared\tseconds\tld_lanes\tst_lanes\tat_lanes";

pub fn write(rows: &[KernelSummary]) -> String {
    let mut s = format!("{HEADER}\n");
    for r in rows {
        let mut all = r.ops.clone();
        r.regions.iter().for_each(|x| all.add(x));
        s += &format!(
            "{}\t{}\t{}\t{}\t{}\t{}\t{}\t{}\t{}\t{}\t{}\t{}\t{}\t{}\t{}\t{}\n",
            r.name,
            r.launches,
            r.threads,
            all.issued,
            all.active,
            r.loads.requests,
            r.loads.sectors,
            r.stores.requests,
            r.stores.sectors,
            r.atomics.requests,
            r.atomics.sectors,
            r.shared_bytes,
            r.seconds,
            r.loads.lanes,
            r.stores.lanes,
            r.atomics.lanes
        );
    }
    s
}

pub fn read(text: &str) -> Result<Vec<KernelSummary>, String> {
    let mut lines = text.lines().enumerate();
    match lines.next() {
        Some((_, h)) if h == HEADER => {}
        _ => return Err("not a gpu_check simt file (header differs)".into()),
    }
    let mut out = Vec::new();
    for (i, line) in lines {
        let f: Vec<&str> = line.split('\t').collect();
        if f.len() != 16 {
            return Err(format!("line {}: {} fields, expected 16", i + 1, f.len()));
        }
        let n = |k: usize| f[k].parse::<u64>().map_err(|_| format!("line {}: field {k}: '{}'", i + 1, f[k]));
        let name: &'static str = Box::leak(f[0].to_string().into_boxed_str());
        out.push(KernelSummary {
            name,
            launches: n(1)?,
            threads: n(2)?,
            measured_launches: n(1)?,
            ops: RegionStats { name: "all", issued: n(3)?, active: n(4)? },
            loads: Traffic { requests: n(5)?, sectors: n(6)?, lanes: n(13)? },
            stores: Traffic { requests: n(7)?, sectors: n(8)?, lanes: n(14)? },
            atomics: Traffic { requests: n(9)?, sectors: n(10)?, lanes: n(15)? },
            shared_bytes: n(11)? as usize,
            seconds: f[12].parse().map_err(|_| format!("line {}: seconds '{}'", i + 1, f[12]))?,
            ..Default::default()
        });
    }
    Ok(out)
}
