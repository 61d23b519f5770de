//! The error-against-time chart: RMSE and relMSE panels, log-log, one line per
//! integrator, as SVG or PNG.

use super::metrics::Checkpoint;
use crate::error::Result;
use crate::film::atomic_write;
use std::path::Path;

static FONT: &[u8] = include_bytes!("../../assets/fonts/DejaVuSans.ttf");

/// A log-log chart of RMSE and relMSE against seconds, one line per integrator; SVG or
/// PNG by the extension of `path`.
pub fn write_chart(path: &Path, rows: &[Checkpoint], title: &str) -> Result<()> {
    use plotters::prelude::*;
    let _ = plotters::style::register_font("sans-serif", FontStyle::Normal, FONT);
    let svg = path.extension().is_some_and(|e| e.eq_ignore_ascii_case("svg"));
    let draw = |tmp: &Path| -> std::result::Result<(), String> {
        let size = (1200, 520);
        if svg {
            chart(SVGBackend::new(tmp, size).into_drawing_area(), rows, title)
        } else {
            // Draw into memory and encode with the `image` crate (plotters' own encoder
            // would pull in a second version of it).
            let mut buf = vec![0u8; (size.0 * size.1 * 3) as usize];
            chart(BitMapBackend::with_buffer(&mut buf, size).into_drawing_area(), rows, title)?;
            image::save_buffer_with_format(tmp, &buf, size.0, size.1, image::ColorType::Rgb8, image::ImageFormat::Png)
                .map_err(|e| e.to_string())
        }
    };
    atomic_write(path, draw)
}

fn chart<DB: plotters::prelude::DrawingBackend>(
    root: plotters::prelude::DrawingArea<DB, plotters::coord::Shift>,
    rows: &[Checkpoint],
    title: &str,
) -> std::result::Result<(), String> {
    use plotters::prelude::*;
    let err = |e: &dyn std::fmt::Display| e.to_string();
    root.fill(&WHITE).map_err(|e| err(&e))?;
    let root = root.titled(title, ("sans-serif", 22)).map_err(|e| err(&e))?;
    let panels = root.split_evenly((1, 2));
    let names: Vec<&str> = {
        let mut v: Vec<&str> = rows.iter().map(|r| r.integrator).collect();
        v.dedup();
        v
    };
    let colours = [
        RGBColor(31, 119, 180),
        RGBColor(214, 39, 40),
        RGBColor(44, 160, 44),
        RGBColor(148, 103, 189),
        RGBColor(255, 127, 14),
        RGBColor(23, 190, 207),
        RGBColor(140, 86, 75),
    ];
    for (panel, (label, metric)) in panels.iter().zip([("RMSE", 0), ("relMSE", 1)]) {
        let value = |r: &Checkpoint| if metric == 0 { r.rmse } else { r.relmse };
        // Only points a log axis can place: positive and finite (an infinite error
        // made the axis, and the chart, never finish).
        let placeable = |x: f64| x > 0.0 && x.is_finite();
        let pos: Vec<&Checkpoint> = rows.iter().filter(|r| placeable(value(r)) && placeable(r.seconds)).collect();
        if pos.is_empty() {
            continue;
        }
        let (t0, t1) = pos.iter().fold((f64::MAX, 0f64), |(a, b), r| (a.min(r.seconds), b.max(r.seconds)));
        let (e0, e1) = pos.iter().fold((f64::MAX, 0f64), |(a, b), r| (a.min(value(r)), b.max(value(r))));
        let mut c = ChartBuilder::on(panel)
            .margin(12)
            .x_label_area_size(40)
            .y_label_area_size(70)
            .build_cartesian_2d(log_range(t0, t1).log_scale(), log_range(e0, e1).log_scale())
            .map_err(|e| err(&e))?;
        c.configure_mesh()
            .x_desc("seconds")
            .y_desc(label)
            .x_label_formatter(&|v| tick(*v))
            .y_label_formatter(&|v| tick(*v))
            .draw()
            .map_err(|e| err(&e))?;
        for (i, name) in names.iter().enumerate() {
            let colour = colours[i % colours.len()];
            let series: Vec<(f64, f64)> =
                pos.iter().filter(|r| r.integrator == *name).map(|r| (r.seconds, value(r))).collect();
            c.draw_series(LineSeries::new(series, colour.stroke_width(2)))
                .map_err(|e| err(&e))?
                .label(*name)
                .legend(move |(x, y)| PathElement::new([(x, y), (x + 18, y)], colour.stroke_width(2)));
        }
        c.configure_series_labels().background_style(WHITE.mix(0.8)).border_style(BLACK).draw().map_err(|e| err(&e))?;
    }
    root.present().map_err(|e| err(&e))
}

/// A log axis over `lo..=hi` (positive, finite), padded a little, with its ends kept
/// finite and at most 200 decades apart (the top 200 decades when the values span
/// more): plotters' log axis never finished on a range of more than about 1e308.
fn log_range(lo: f64, hi: f64) -> std::ops::Range<f64> {
    let top = (hi * 1.25).min(f64::MAX);
    let bottom = (lo * 0.8).max(top / 1e200).max(f64::MIN_POSITIVE);
    let bottom = if bottom < top { bottom } else { top / 10.0 };
    bottom..top
}

/// An axis label with three significant digits and no trailing zeros (log axes put
/// ticks at values like 0.30000000000000004).
pub(crate) fn tick(v: f64) -> String {
    if v == 0.0 || !v.is_finite() {
        return format!("{v}");
    }
    let decimals = (2 - v.abs().log10().floor() as i32).max(0) as usize;
    let s = format!("{v:.decimals$}");
    if s.contains('.') { s.trim_end_matches('0').trim_end_matches('.').to_string() } else { s }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn axis_labels_keep_three_significant_digits() {
        let got: Vec<String> = [0.30000000000000004, 0.004, 8.0, 1234.0, 0.0125].into_iter().map(tick).collect();
        assert_eq!(got, ["0.3", "0.004", "8", "1234", "0.0125"]);
    }
}
