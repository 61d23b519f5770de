//! `converge --replot`: the input is a CSV as `converge` writes it. What `--replot`
//! does with one it accepts — the chart as SVG and PNG, the time each integrator needs
//! to reach the common error, the summary table — must finish (libFuzzer's timeout
//! catches a hang) and must not panic, whatever the numbers.
#![no_main]

mod common;

use libfuzzer_sys::fuzz_target;
use warpray::converge::{common_target, labels, read_csv, summarize, summary_table, write_chart};

fuzz_target!(|data: &[u8]| {
    let dir = common::scratch();
    let csv = dir.join("c.csv");
    std::fs::write(&csv, data).unwrap();
    let Ok(rows) = read_csv(&csv) else { return };
    let labels = labels(&rows);
    let _ = write_chart(&dir.join("c.svg"), &rows, "fuzz");
    let _ = write_chart(&dir.join("c.png"), &rows, "fuzz");
    let _ = common_target(&rows, &labels);
    let _ = summary_table(&summarize(&rows, &labels));
});
