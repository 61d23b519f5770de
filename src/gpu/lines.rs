//! Nsight Compute's per-instruction counters summed by source line: where in a kernel
//! its instructions, and its divergence, sit (`gpu_check source --lines`).

use super::source::{Instruction, Sums, numbered, opt};
use std::collections::HashMap;
use std::fmt::Write;

/// One source line of one kernel, over the launches summed.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Line {
    /// The kernel's short name.
    pub kernel: String,
    /// Source file (no folders) and line.
    pub file: String,
    /// Its line.
    pub line: u32,
    /// That line's text.
    pub text: String,
    /// Distinct SASS instructions compiled from it (its static size).
    pub instructions: usize,
    /// Executed counts summed over its instructions and the launches.
    pub sums: Sums,
}

/// Every instruction summed per kernel and source line, over the launches `keep`
/// accepts (as for [`split`](super::source::split)); each kernel's lines by warp instructions, most first.
/// A line's share of its kernel's warp instructions and its SIMD efficiency show where
/// a kernel's divergence sits (the loop a lane leaves early, a retry loop).
pub fn lines(insts: &[Instruction], keep: impl Fn(&str, usize) -> bool) -> Vec<Line> {
    let mut by: HashMap<(String, String, u32), (Line, std::collections::HashSet<String>)> = HashMap::new();
    for (name, k, i) in numbered(insts) {
        if !keep(&name, k) {
            continue;
        }
        let (l, seen) = by.entry((name.clone(), i.file.clone(), i.line)).or_insert_with(|| {
            let l =
                Line { kernel: name, file: i.file.clone(), line: i.line, text: i.text.clone(), ..Default::default() };
            (l, Default::default())
        });
        l.sums.add(i);
        // The same instruction in another launch is not another instruction.
        if seen.insert(i.address.clone()) {
            l.instructions += 1;
        }
    }
    let mut out: Vec<Line> = by.into_values().map(|(l, _)| l).collect();
    out.sort_by(|a, b| a.kernel.cmp(&b.kernel).then(b.sums.warp.total_cmp(&a.sums.warp)).then(a.line.cmp(&b.line)));
    out
}

/// The first `top` lines of each kernel of [`lines`] as a markdown table, with each
/// line's share of its kernel's warp instructions.
pub fn lines_table(lines: &[Line], top: usize) -> String {
    let mut t = String::new();
    for chunk in lines.chunk_by(|a, b| a.kernel == b.kernel) {
        let total: f64 = chunk.iter().map(|l| l.sums.warp).sum();
        let _ = writeln!(t, "{}: {:.0} warp instructions, by source line\n", chunk[0].kernel, total);
        t.push_str("| file:line | source | SASS instructions | warp inst. | share | SIMD eff. |\n");
        t.push_str("|---|---|---:|---:|---:|---:|\n");
        for l in chunk.iter().take(top) {
            let text: String = l.text.chars().take(60).collect::<String>().replace('|', "\\|");
            let _ = writeln!(
                t,
                "| {}:{} | `{}` | {} | {:.0} | {:.4} | {} |",
                l.file,
                l.line,
                text,
                l.instructions,
                l.sums.warp,
                if total > 0.0 { l.sums.warp / total } else { 0.0 },
                opt(l.sums.simd_efficiency(), 3)
            );
        }
        t.push('\n');
    }
    t
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::gpu::source::{parse, tests::SAMPLE};

    #[test]
    fn lines_sum_their_instructions_over_launches() {
        let insts = parse(SAMPLE).unwrap();
        let l = lines(&insts, |_, _| true);
        // Line 949 of the device header: 0x20, 0x30, 0x40, 0x50 in launch 0 and 0x20 in
        // launches 1 and 2; line 309: the instruction counted once.
        assert_eq!(l.len(), 2);
        assert_eq!((l[0].line, l[0].instructions), (949, 4));
        assert_eq!(l[0].sums.warp, 4.0 + 6.0 + 1000.0 + 3.0 + 2.0 + 1.0);
        assert_eq!(l[0].sums.thread, 128.0 + 96.0 + 16000.0 + 3.0 + 64.0 + 32.0);
        assert_eq!((l[1].line, l[1].instructions, l[1].sums.warp), (309, 1, 10.0));
        let only_first = lines(&insts, |_, k| k == 0);
        assert_eq!(only_first[0].sums.warp, 4.0 + 6.0 + 1000.0 + 3.0);
        let t = lines_table(&l, 1);
        assert!(t.contains("| cis_device.cuh:949 |"), "{t}");
        assert!(!t.contains(":309 |"), "{t}");
    }
}
