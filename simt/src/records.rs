//! Launch records as tab-separated text, one launch a line: a measured run kept to be
//! predicted later (`gpu_check time`), and files written before later columns were
//! added read with those columns' defaults.

use crate::meter::{Traffic, WarpChain};
use crate::stats::{LaunchRecord, RegionStats};
use std::fmt::Write;

/// The columns of [`records_to_tsv`].
const RECORD_HEADER: &str = "name\tgrid\tblock\tshared\tseconds\tmeasured\tthreads\tops_issued\tops_active\twork_issued\twork_active\tld_req\tld_sec\tld_lanes\tst_req\tst_sec\tst_lanes\tat_req\tat_sec\tat_lanes\tbarriers\tfootprint\tblock_sectors\tlongest_issued\tlongest_loads\tload_rounds\tlongest_atomics\tlongest_fences\tatomic_rounds\tfences\tlongest_fenced_sectors\tfenced_sectors\tround_repeats\tloaded_footprint\tin_order\tlongest_fenced_lines\tfenced_lines\tblock_issued\tblock_load_rounds\tblock_atomic_rounds\tblock_fences\tblock_fenced_sectors\tblock_fenced_lines\tcode_bytes\tregisters";

/// Columns of [`RECORD_HEADER`] that files written before them lack, newest first:
/// the registers a thread the launch stated and the bytes of the twin's code (both read
/// as not known), the blocks' slowest warps' chains (read as none: the model then takes the mean
/// warp's), the lines fences waited for (read as none), whether the blocks ran in order (read as not), the loaded footprint (read as the
/// whole footprint), the sectors repeated within rounds
/// of loads, the sectors fences waited for, the atomics
/// and fences waited for (all read as none), and load rounds (read as one per load
/// request).
const LATER_COLUMNS: &[&str] = &[
    "\tregisters",
    "\tcode_bytes",
    "\tblock_issued\tblock_load_rounds\tblock_atomic_rounds\tblock_fences\tblock_fenced_sectors\tblock_fenced_lines",
    "\tlongest_fenced_lines\tfenced_lines",
    "\tin_order",
    "\tloaded_footprint",
    "\tround_repeats",
    "\tlongest_fenced_sectors\tfenced_sectors",
    "\tlongest_atomics\tlongest_fences\tatomic_rounds\tfences",
    "\tload_rounds",
];

/// Launch records as tab-separated lines, one per launch, to keep a measured run and
/// predict from it later ([`crate::timing::predict`]). Declared regions are summed into
/// one region named `work`.
pub fn records_to_tsv(records: &[LaunchRecord]) -> String {
    let mut s = format!("{RECORD_HEADER}\n");
    for r in records {
        let mut work = RegionStats::default();
        r.regions.iter().for_each(|x| work.add(x));
        let t = |x: &Traffic| format!("{}\t{}\t{}", x.requests, x.sectors, x.lanes);
        let _ = writeln!(
            s,
            "{}\t{}\t{}\t{}\t{}\t{}\t{}\t{}\t{}\t{}\t{}\t{}\t{}\t{}\t{}\t{}\t{}\t{}\t{}\t{}\t{}\t{}\t{}\t{}\t{}\t{}\t{}\t{}\t{}\t{}\t{}\t{}\t{}\t{}\t{}\t{}\t{}\t{}\t{}",
            r.name,
            r.grid,
            r.block,
            r.shared_bytes,
            r.seconds,
            r.measured as u8,
            r.threads,
            r.ops.issued,
            r.ops.active,
            work.issued,
            work.active,
            t(&r.loads),
            t(&r.stores),
            t(&r.atomics),
            r.barriers,
            r.footprint_sectors,
            r.block_sectors,
            r.longest_warp.instructions,
            r.longest_warp.load_rounds,
            r.waits.load_rounds,
            r.longest_warp.atomic_rounds,
            r.longest_warp.fences,
            r.waits.atomic_rounds,
            r.waits.fences,
            r.longest_warp.fenced_sectors,
            r.waits.fenced_sectors,
            r.waits.round_repeats,
            r.loaded_footprint_sectors,
            r.in_order as u8,
            r.longest_warp.fenced_lines,
            r.waits.fenced_lines,
            r.block_chains.instructions,
            r.block_chains.load_rounds,
            r.block_chains.atomic_rounds,
            r.block_chains.fences,
            r.block_chains.fenced_sectors,
            r.block_chains.fenced_lines,
            r.code_bytes,
            r.registers
        );
    }
    s
}

/// A kernel name read from a file, kept for the program's life (each distinct name
/// once).
fn intern(name: &str) -> &'static str {
    use std::sync::Mutex;
    static NAMES: Mutex<Vec<&'static str>> = Mutex::new(Vec::new());
    let mut names = NAMES.lock().unwrap_or_else(|e| e.into_inner());
    if let Some(n) = names.iter().find(|n| **n == name) {
        return n;
    }
    let n: &'static str = Box::leak(name.to_string().into_boxed_str());
    names.push(n);
    n
}

/// Reads what [`records_to_tsv`] wrote; errors name the line and field.
pub fn records_from_tsv(text: &str) -> Result<Vec<LaunchRecord>, String> {
    let mut lines = text.lines().enumerate();
    let header = match lines.next() {
        Some((_, h)) if is_record_header(h) => h,
        _ => return Err("not a simt launch-record file (its header differs)".into()),
    };
    let columns: Vec<&str> = header.split('\t').collect();
    let mut out = Vec::new();
    for (i, line) in lines {
        let f: Vec<&str> = line.split('\t').collect();
        if f.len() != columns.len() {
            return Err(format!("line {}: {} fields, expected {}", i + 1, f.len(), columns.len()));
        }
        let n = |k: usize| f[k].parse::<u64>().map_err(|_| format!("line {}: {}: '{}'", i + 1, columns[k], f[k]));
        let traffic = |k: usize| -> Result<Traffic, String> {
            Ok(Traffic { requests: n(k)?, sectors: n(k + 1)?, lanes: n(k + 2)? })
        };
        let seconds: f64 = f[4].parse().map_err(|_| format!("line {}: seconds: '{}'", i + 1, f[4]))?;
        out.push(LaunchRecord {
            name: intern(f[0]),
            grid: n(1)? as u32,
            block: n(2)? as u32,
            shared_bytes: n(3)? as usize,
            registers: if columns.len() > 44 {
                u32::try_from(n(44)?).map_err(|_| format!("line {}: registers: '{}' is past 4 G", i + 1, f[44]))?
            } else {
                0
            },
            seconds,
            measured: n(5)? != 0,
            threads: n(6)?,
            ops: RegionStats { name: "ops", issued: n(7)?, active: n(8)? },
            regions: vec![RegionStats { name: "work", issued: n(9)?, active: n(10)? }],
            loads: traffic(11)?,
            stores: traffic(14)?,
            atomics: traffic(17)?,
            barriers: n(20)?,
            footprint_sectors: n(21)?,
            loaded_footprint_sectors: if columns.len() > 33 { n(33)? } else { n(21)? },
            block_sectors: n(22)?,
            longest_warp: WarpChain {
                instructions: n(23)?,
                load_rounds: n(24)?,
                atomic_rounds: if columns.len() > 26 { n(26)? } else { 0 },
                fences: if columns.len() > 26 { n(27)? } else { 0 },
                fenced_sectors: if columns.len() > 30 { n(30)? } else { 0 },
                fenced_lines: if columns.len() > 35 { n(35)? } else { 0 },
                round_repeats: 0,
            },
            waits: WarpChain {
                instructions: n(7)? + n(9)?,
                load_rounds: if columns.len() > 25 { n(25)? } else { n(11)? },
                atomic_rounds: if columns.len() > 26 { n(28)? } else { 0 },
                fences: if columns.len() > 26 { n(29)? } else { 0 },
                fenced_sectors: if columns.len() > 30 { n(31)? } else { 0 },
                fenced_lines: if columns.len() > 35 { n(36)? } else { 0 },
                round_repeats: if columns.len() > 32 { n(32)? } else { 0 },
            },
            block_chains: if columns.len() > 37 {
                WarpChain {
                    instructions: n(37)?,
                    load_rounds: n(38)?,
                    atomic_rounds: n(39)?,
                    fences: n(40)?,
                    fenced_sectors: n(41)?,
                    fenced_lines: n(42)?,
                    round_repeats: 0,
                }
            } else {
                WarpChain::default()
            },
            in_order: columns.len() > 34 && n(34)? != 0,
            code_bytes: if columns.len() > 43 {
                u32::try_from(n(43)?).map_err(|_| format!("line {}: code_bytes: '{}' is past 4 GiB", i + 1, f[43]))?
            } else {
                0
            },
        });
    }
    Ok(out)
}

/// The current header, or one that lacks only the [`LATER_COLUMNS`] added after it
/// was written.
fn is_record_header(h: &str) -> bool {
    let mut current = RECORD_HEADER;
    for later in std::iter::once("").chain(LATER_COLUMNS.iter().copied()) {
        match current.strip_suffix(later) {
            Some(older) => current = older,
            None => return false,
        }
        if h == current {
            return true;
        }
    }
    false
}

#[cfg(test)]
mod tests {
    use super::*;

    fn record() -> LaunchRecord {
        let t = |k: u64| Traffic { requests: k, sectors: 2 * k, lanes: 32 * k };
        LaunchRecord {
            name: "test::kernel",
            grid: 3,
            block: 64,
            shared_bytes: 128,
            registers: 167,
            code_bytes: 685_056,
            seconds: 0.25,
            measured: true,
            threads: 192,
            ops: RegionStats { name: "ops", issued: 40, active: 1000 },
            regions: vec![RegionStats { name: "work", issued: 60, active: 1500 }],
            loads: t(5),
            stores: t(3),
            atomics: t(2),
            barriers: 4,
            footprint_sectors: 9,
            loaded_footprint_sectors: 7,
            block_sectors: 8,
            longest_warp: WarpChain {
                instructions: 20,
                load_rounds: 3,
                atomic_rounds: 2,
                fences: 1,
                fenced_sectors: 9,
                fenced_lines: 6,
                round_repeats: 0,
            },
            waits: WarpChain {
                instructions: 100,
                load_rounds: 12,
                atomic_rounds: 7,
                fences: 5,
                fenced_sectors: 40,
                fenced_lines: 25,
                round_repeats: 11,
            },
            block_chains: WarpChain {
                instructions: 50,
                load_rounds: 6,
                atomic_rounds: 4,
                fences: 3,
                fenced_sectors: 19,
                fenced_lines: 13,
                round_repeats: 0,
            },
            in_order: true,
        }
    }

    #[test]
    fn records_read_back_as_written_and_older_files_without_their_later_columns() {
        let text = records_to_tsv(&[record()]);
        let back = &records_from_tsv(&text).unwrap()[0];
        assert_eq!((back.longest_warp, back.waits), (record().longest_warp, record().waits));
        assert_eq!(back.block_chains, record().block_chains);
        assert_eq!((back.loads, back.atomics, back.block_sectors), (record().loads, record().atomics, 8));
        assert_eq!((back.footprint_sectors, back.loaded_footprint_sectors, back.in_order), (9, 7, true));
        assert_eq!((back.code_bytes, back.registers), (685_056, 167));
        // Cut the later columns off, newest first: the registers and then the code's
        // bytes are then not known,
        // the blocks' chains are then none,
        // fenced lines are then none, the launch is then not in order, the loaded
        // footprint is then the whole footprint, round repeats are none, then
        // fenced sectors, then atomics and fences, and then load rounds are one per load
        // request.
        let cut = |text: &str, columns: usize| -> String {
            text.lines().map(|l| l.split('\t').take(columns).collect::<Vec<_>>().join("\t") + "\n").collect()
        };
        let unlined = |w: WarpChain| WarpChain { fenced_lines: 0, ..w };
        let before_registers = &records_from_tsv(&cut(&text, 44)).unwrap()[0];
        assert_eq!((before_registers.registers, before_registers.code_bytes), (0, 685_056));
        let before_code = &records_from_tsv(&cut(&text, 43)).unwrap()[0];
        assert_eq!((before_code.code_bytes, before_code.block_chains), (0, record().block_chains));
        let before_blocks = &records_from_tsv(&cut(&text, 37)).unwrap()[0];
        assert_eq!((before_blocks.block_chains, before_blocks.waits), (WarpChain::default(), record().waits));
        let before_lines = &records_from_tsv(&cut(&text, 35)).unwrap()[0];
        assert_eq!((before_lines.in_order, before_lines.waits), (true, unlined(record().waits)));
        assert_eq!(before_lines.longest_warp, unlined(record().longest_warp));
        let before_order = &records_from_tsv(&cut(&text, 34)).unwrap()[0];
        assert_eq!((before_order.in_order, before_order.loaded_footprint_sectors), (false, 7));
        let before_loaded = &records_from_tsv(&cut(&text, 33)).unwrap()[0];
        assert_eq!((before_loaded.loaded_footprint_sectors, before_loaded.waits), (9, unlined(record().waits)));
        let before_repeats = &records_from_tsv(&cut(&text, 32)).unwrap()[0];
        assert_eq!(before_repeats.waits, WarpChain { round_repeats: 0, ..unlined(record().waits) });
        let before_fenced = &records_from_tsv(&cut(&text, 30)).unwrap()[0];
        assert_eq!(before_fenced.longest_warp, WarpChain { fenced_sectors: 0, ..unlined(record().longest_warp) });
        assert_eq!(before_fenced.waits, WarpChain { fenced_sectors: 0, round_repeats: 0, ..unlined(record().waits) });
        let before_atomics = &records_from_tsv(&cut(&text, 26)).unwrap()[0];
        let none = WarpChain { atomic_rounds: 0, fences: 0, fenced_sectors: 0, ..WarpChain::default() };
        assert_eq!(before_atomics.longest_warp, WarpChain { instructions: 20, load_rounds: 3, ..none });
        assert_eq!(before_atomics.waits, WarpChain { instructions: 100, load_rounds: 12, ..none });
        let before_rounds = &records_from_tsv(&cut(&text, 25)).unwrap()[0];
        assert_eq!(before_rounds.waits.load_rounds, 5);
        // Any other header is refused.
        for columns in [24, 27, 31, 36, 42] {
            assert!(records_from_tsv(&cut(&text, columns)).unwrap_err().contains("header differs"));
        }
        // A code size past what a launch states is an error naming the line and field.
        let huge = text.replace("\t685056\t167\n", "\t4294967296\t167\n");
        let e = records_from_tsv(&huge).unwrap_err();
        assert!(e.starts_with("line 2: code_bytes"), "{e}");
    }
}
