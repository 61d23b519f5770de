//! Speed against accuracy: render a scene with several integrators for a time budget
//! each, measure the error against a reference image at log-spaced checkpoints, and
//! write the curves as CSV and as a log-log chart (plotters).
//!
//! Errors: RMSE over all pixels and channels, and relMSE, the mean over pixels and
//! channels of `(x − r)² / (r² + 0.01)` (the 0.01 keeps dark pixels from dominating).

use crate::cast::RayCaster;
use crate::error::{Error, Result};
use crate::film::{Film, atomic_write};
use crate::render::{Budget, RenderOptions, render};
use crate::scene::Scene;
use glam::Vec3;
use std::path::Path;
use std::time::{Duration, Instant};

mod chart;
mod metrics;
#[cfg(feature = "inspector")]
pub(crate) use chart::tick;
pub use chart::write_chart;
pub use metrics::{Checkpoint, relmse, relmse_eps, rmse};

/// The integrators `converge` compares are the registry's variants.
pub use crate::render::registry::Variant;

#[derive(Clone, Debug)]
/// What a `converge` run compares and how.
pub struct ConvergeOptions {
    /// The integrators, in order.
    pub integrators: Vec<Variant>,
    /// Time budget of each integrator, seconds.
    pub seconds: f64,
    /// Number of log-spaced checkpoints from `seconds / 200` to `seconds`.
    pub checkpoints: usize,
    /// Image width.
    pub width: u32,
    /// Image height.
    pub height: u32,
    /// Largest number of bounces.
    pub max_depth: u32,
    /// Where the path tracer's Russian roulette starts ([`RenderOptions::rr_depth`]).
    pub rr_depth: u32,
    /// Seed of every integrator's render.
    pub seed: u64,
    /// Pixel reconstruction filter.
    pub filter: crate::filter::Filter,
    /// How camera samples meet the filter.
    pub filter_mode: crate::filter::FilterMode,
    /// Camera passes per light pass of the integrators with a light vertex cache (lvc,
    /// lvc-mk, cis and its ablations; [`crate::render::Iterations`]); 1 for the others.
    pub samples_per_iteration: u32,
}

/// Renders with every integrator, measuring against `reference` (pixel order, the
/// same size). `progress(integrator, checkpoint)` sees each row as it is made. When
/// `stop()` turns true (Ctrl-C) the render under way ends after its pass, that pass is
/// measured, and the rows so far are returned without the integrators still to come.
pub fn run(
    scene: &Scene,
    caster: &dyn RayCaster,
    reference: &[Vec3],
    opts: &ConvergeOptions,
    mut progress: impl FnMut(&Checkpoint),
    stop: impl Fn() -> bool,
) -> Result<Vec<Checkpoint>> {
    if reference.len() != (opts.width * opts.height) as usize {
        return Err(Error::BadSetting(format!(
            "the reference has {} pixels; the render has {}x{}",
            reference.len(),
            opts.width,
            opts.height
        )));
    }
    // Errors against a broken reference are nonsense: refuse it before rendering.
    let bad = reference.iter().filter(|p| !p.is_finite()).count();
    if bad > 0 {
        return Err(Error::BadSetting(format!(
            "the reference has {bad} NaN or infinite pixel(s) of {}: errors against it would mean nothing",
            reference.len()
        )));
    }
    if reference.iter().all(|p| *p == Vec3::ZERO) {
        return Err(Error::BadSetting(
            "the reference is black in every pixel: errors against it would mean nothing".into(),
        ));
    }
    let n = opts.checkpoints.max(2);
    let times: Vec<f64> = (0..n).map(|i| opts.seconds / 200.0 * 200f64.powf(i as f64 / (n - 1) as f64)).collect();
    let mut rows = Vec::new();
    for variant in &opts.integrators {
        let mut render_opts = variant.apply(RenderOptions {
            width: opts.width,
            height: opts.height,
            budget: Budget::Seconds(opts.seconds),
            max_depth: opts.max_depth,
            rr_depth: opts.rr_depth,
            seed: opts.seed,
            filter: opts.filter,
            filter_mode: opts.filter_mode,
            ..Default::default()
        });
        render_opts.set_samples_per_iteration(opts.samples_per_iteration);
        let label = variant.label;
        let start = Instant::now();
        let mut measuring = Duration::ZERO;
        let mut next = 0;
        let mut measure = |film: &Film, rows: &mut Vec<Checkpoint>, force: bool| {
            let elapsed = (start.elapsed() - measuring).as_secs_f64();
            if !force && (next >= times.len() || elapsed < times[next]) {
                return;
            }
            let t0 = Instant::now();
            let mean = film.mean();
            let row = Checkpoint {
                integrator: label,
                seconds: elapsed,
                spp: film.passes,
                rmse: rmse(&mean, reference),
                relmse: relmse(&mean, reference),
            };
            progress(&row);
            rows.push(row);
            while next < times.len() && times[next] <= elapsed {
                next += 1;
            }
            measuring += t0.elapsed();
        };
        let (film, _) = render(scene, caster, &render_opts, |_, film| {
            measure(film, &mut rows, false);
            !stop()
        })?;
        if rows.last().is_none_or(|r| r.spp != film.passes || r.integrator != label) {
            measure(&film, &mut rows, true);
        }
        if stop() {
            break;
        }
    }
    Ok(rows)
}

/// What determines a reference image, as a key: a 64-bit FNV-1a hash of the scene's
/// geometry, materials, emission, lights and camera and of every render option (size,
/// samples, integrator, seed, depth, filter). `converge` stores it in the reference EXR
/// it renders and reuses that file when the key matches, so a second comparison of the
/// same scene and settings skips the reference render.
pub fn reference_key(scene: &Scene, opts: &RenderOptions) -> String {
    let mut h: u64 = 0xcbf2_9ce4_8422_2325;
    let mut eat = |bytes: &[u8]| {
        for &b in bytes {
            h = (h ^ b as u64).wrapping_mul(0x100_0000_01b3);
        }
    };
    for p in &scene.positions {
        p.to_array().iter().for_each(|c| eat(&c.to_bits().to_le_bytes()));
    }
    scene.triangles.iter().flatten().chain(&scene.material_of).for_each(|i| eat(&i.to_le_bytes()));
    // Debug text of floats is exact (the shortest form that reads back the same bits).
    let rest = (&scene.materials, &scene.emission, &scene.two_sided, &scene.point_lights, &scene.camera, opts);
    eat(format!("{rest:?}").as_bytes());
    format!("{h:016x}")
}

/// Seconds each integrator first reached an RMSE of `target` (linear interpolation in
/// log-log between checkpoints), or `None` if it never did.
pub fn time_to_reach(rows: &[Checkpoint], integrator: &str, target: f64) -> Option<f64> {
    let pts: Vec<&Checkpoint> = rows.iter().filter(|r| r.integrator == integrator).collect();
    if pts.first()?.rmse <= target {
        return Some(pts[0].seconds);
    }
    pts.windows(2).find(|w| w[1].rmse <= target).map(|w| {
        let (t0, t1) = (w[0].seconds.max(1e-9).ln(), w[1].seconds.max(1e-9).ln());
        let (e0, e1) = (w[0].rmse.ln(), w[1].rmse.ln());
        let f = if e1 == e0 { 1.0 } else { (target.ln() - e0) / (e1 - e0) };
        (t0 + f * (t1 - t0)).exp()
    })
}

/// One integrator's line in the table a `converge` run ends with (the layout of the
/// CIS-LBDPT paper's runtime table: samples per pixel reached, milliseconds per sample,
/// and the speed-up over a baseline).
#[derive(Clone, Debug, PartialEq)]
pub struct Summary {
    /// The variant's label.
    pub integrator: &'static str,
    /// Samples per pixel reached in the budget (the effective spp: one camera subpath per
    /// pixel per pass, with the pass's light subpaths).
    pub spp: u32,
    /// Rendering seconds at the last checkpoint.
    pub seconds: f64,
    /// Milliseconds per sample per pixel (a pass over the whole image).
    pub ms_per_spp: f64,
    /// RMSE at the last checkpoint.
    pub rmse: f64,
    /// Seconds to first reach the common target RMSE, when reached.
    pub seconds_to_target: Option<f64>,
    /// The baseline's milliseconds per spp over this one's.
    pub speedup_per_spp: f64,
    /// The baseline's seconds to the target over this one's, when both reached it.
    pub speedup_to_target: Option<f64>,
}

/// The common target of a run: the worst final RMSE among `labels`, which every one of
/// them reaches.
pub fn common_target(rows: &[Checkpoint], labels: &[&str]) -> f64 {
    labels.iter().filter_map(|l| rows.iter().rev().find(|r| r.integrator == *l).map(|r| r.rmse)).fold(0.0, f64::max)
}

/// The integrators of a list of checkpoints, in the order they first appear (what
/// `converge --replot` charts and summarises).
pub fn labels(rows: &[Checkpoint]) -> Vec<&'static str> {
    let mut labels: Vec<&'static str> = Vec::new();
    for r in rows {
        if !labels.contains(&r.integrator) {
            labels.push(r.integrator);
        }
    }
    labels
}

/// One [`Summary`] per label that has checkpoints, against the first label as baseline.
pub fn summarize(rows: &[Checkpoint], labels: &[&str]) -> Vec<Summary> {
    let target = common_target(rows, labels);
    let mut out: Vec<Summary> = labels
        .iter()
        .filter_map(|&l| {
            let last = rows.iter().rev().find(|r| r.integrator == l)?;
            Some(Summary {
                integrator: last.integrator,
                spp: last.spp,
                seconds: last.seconds,
                ms_per_spp: 1e3 * last.seconds / last.spp.max(1) as f64,
                rmse: last.rmse,
                seconds_to_target: time_to_reach(rows, l, target),
                speedup_per_spp: 1.0,
                speedup_to_target: None,
            })
        })
        .collect();
    if let Some(base) = out.first().cloned() {
        for s in &mut out {
            s.speedup_per_spp = base.ms_per_spp / s.ms_per_spp;
            s.speedup_to_target = base.seconds_to_target.zip(s.seconds_to_target).map(|(b, t)| b / t);
        }
    }
    out
}

/// The summaries as a Markdown table.
pub fn summary_table(summaries: &[Summary]) -> String {
    let base = summaries.first().map_or("", |s| s.integrator);
    let mut t = format!(
        "| integrator | spp reached | ms per spp | final RMSE | s to common RMSE | speed-up per spp (vs {base}) | speed-up to RMSE |\n|---|---:|---:|---:|---:|---:|---:|\n"
    );
    for s in summaries {
        let reach = s.seconds_to_target.map_or("not reached".into(), |v| format!("{v:.2}"));
        let to = s.speedup_to_target.map_or("-".into(), |v| format!("{v:.2}x"));
        t.push_str(&format!(
            "| {} | {} | {:.1} | {:.5} | {reach} | {:.2}x | {to} |\n",
            s.integrator, s.spp, s.ms_per_spp, s.rmse, s.speedup_per_spp
        ));
    }
    t
}

/// Writes the checkpoints as CSV (`integrator,seconds,spp,rmse,relmse`).
pub fn write_csv(path: &Path, rows: &[Checkpoint]) -> Result<()> {
    let mut text = String::from("integrator,seconds,spp,rmse,relmse\n");
    for r in rows {
        text.push_str(&format!("{},{:.6},{},{:.8e},{:.8e}\n", r.integrator, r.seconds, r.spp, r.rmse, r.relmse));
    }
    atomic_write(path, |tmp| std::fs::write(tmp, &text).map_err(|e| e.to_string()))
}

/// Reads checkpoints back from a CSV that [`write_csv`] wrote (to redraw charts or
/// tables without rendering again). Errors name the file, line and field.
pub fn read_csv(path: &Path) -> Result<Vec<Checkpoint>> {
    let text = crate::scene::input::read_text(path, crate::scene::input::max_input_bytes())?;
    let bad = |line: usize, msg: String| Error::MalformedCsv { at: crate::error::Location::new(path, line), msg };
    let mut lines = text.lines().enumerate().map(|(i, l)| (i + 1, l));
    match lines.next() {
        Some((_, "integrator,seconds,spp,rmse,relmse")) => {}
        other => {
            return Err(bad(1, format!("expected the header 'integrator,seconds,spp,rmse,relmse', found {other:?}")));
        }
    }
    let mut rows = Vec::new();
    for (n, line) in lines.filter(|(_, l)| !l.trim().is_empty()) {
        let f: Vec<&str> = line.split(',').collect();
        if f.len() != 5 {
            return Err(bad(n, format!("expected 5 fields, found {}", f.len())));
        }
        let integrator = Variant::parse(f[0]).map_err(|e| bad(n, format!("field 'integrator': {e}")))?.label;
        let num = |i: usize, name: &str| -> Result<f64> {
            f[i].trim()
                .parse::<f64>()
                .ok()
                .filter(|v| v.is_finite() && *v >= 0.0)
                .ok_or_else(|| bad(n, format!("field '{name}': '{}' is not a finite number >= 0", f[i])))
        };
        let spp = f[2].trim().parse::<u32>().map_err(|_| bad(n, format!("field 'spp': '{}' is not a count", f[2])))?;
        rows.push(Checkpoint {
            integrator,
            seconds: num(1, "seconds")?,
            spp,
            rmse: num(3, "rmse")?,
            relmse: num(4, "relmse")?,
        });
    }
    if rows.is_empty() {
        return Err(bad(1, "no checkpoints".into()));
    }
    Ok(rows)
}

/// Reads a linear RGB EXR (e.g. a reference written by `warpray render -o ref.exr`).
pub fn read_exr(path: &Path) -> Result<(u32, u32, Vec<Vec3>)> {
    use exr::prelude::*;
    crate::scene::input::open_regular(path)?;
    let unreadable = |e: exr::error::Error| match e {
        exr::error::Error::Io(io) => crate::error::Error::io(path, io),
        other => crate::error::Error::Input { path: path.into(), msg: format!("not a readable EXR: {other}") },
    };
    // The pixel buffer is sized from the header before any pixel is read, so a tiny
    // file claiming a huge image would allocate without bound (found by fuzzing): the
    // header's sizes must pass the film's own limits first.
    let meta = exr::meta::MetaData::read_from_file(path, false).map_err(unreadable)?;
    for header in &meta.headers {
        let (w, h) = (header.layer_size.width(), header.layer_size.height());
        let side = |n: usize| u32::try_from(n).unwrap_or(u32::MAX);
        crate::film::check_size(side(w), side(h)).map_err(|e| crate::error::Error::Input {
            path: path.into(),
            msg: format!("not a readable EXR: its header claims {w}x{h} pixels ({e})"),
        })?;
    }
    // Decoded on this thread: exr's parallel decoder builds a thread pool per call,
    // whose threads outlive the call (the fuzzer saw them as leaks), and our images
    // are small enough that one thread decodes them in milliseconds.
    let image = read()
        .no_deep_data()
        .largest_resolution_level()
        .rgba_channels(
            |res, _| (res.width(), res.height(), vec![Vec3::ZERO; res.width() * res.height()]),
            |px: &mut (usize, usize, Vec<Vec3>), pos, (r, g, b, _a): (f32, f32, f32, f32)| {
                let w = px.0;
                px.2[pos.y() * w + pos.x()] = Vec3::new(r, g, b);
            },
        )
        .first_valid_layer()
        .all_attributes()
        .non_parallel()
        .from_file(path)
        .map_err(unreadable)?;
    let (w, h, px) = image.layer_data.channel_data.pixels;
    Ok((w as u32, h as u32, px))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn row(integrator: &'static str, seconds: f64, rmse: f64) -> Checkpoint {
        Checkpoint { integrator, seconds, spp: 1, rmse, relmse: rmse }
    }

    #[test]
    fn error_metrics_have_known_values() {
        let reference = [Vec3::ONE, Vec3::ZERO];
        let image = [Vec3::new(2.0, 1.0, 1.0), Vec3::ZERO];
        assert!((rmse(&image, &reference) - (1.0f64 / 6.0).sqrt()).abs() < 1e-9);
        assert!((relmse(&image, &reference) - 1.0 / 1.01 / 6.0).abs() < 1e-9);
        assert_eq!(rmse(&reference, &reference), 0.0);
    }

    #[test]
    fn time_to_reach_interpolates_in_log_log() {
        let rows = [row("a", 1.0, 0.1), row("a", 100.0, 0.001), row("b", 1.0, 0.5)];
        let t = time_to_reach(&rows, "a", 0.01).unwrap();
        assert!((t - 10.0).abs() < 1e-6, "{t}");
        assert_eq!(time_to_reach(&rows, "a", 0.2), Some(1.0));
        assert_eq!(time_to_reach(&rows, "b", 0.1), None);
    }

    #[test]
    fn the_csv_reads_back_and_bad_rows_name_their_line() {
        let dir = std::env::temp_dir().join(format!("warpray-csv-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("c.csv");
        let rows = vec![
            Checkpoint { integrator: "cis", seconds: 0.5, spp: 3, rmse: 0.25, relmse: 0.125 },
            Checkpoint { integrator: "lvc-mk", seconds: 2.0, spp: 9, rmse: 0.0625, relmse: 0.03125 },
        ];
        write_csv(&path, &rows).unwrap();
        assert_eq!(read_csv(&path).unwrap(), rows);
        for (text, want) in [
            ("integrator,seconds,spp,rmse,relmse\ncis,0.5,3,0.25\n", "c.csv:2: expected 5 fields"),
            ("integrator,seconds,spp,rmse,relmse\ncis,0.5,3,0.25,0.1\nnope,1,1,1,1\n", "c.csv:3: field 'integrator'"),
            ("integrator,seconds,spp,rmse,relmse\ncis,NaN,3,0.25,0.1\n", "c.csv:2: field 'seconds'"),
            ("integrator,seconds,spp,rmse,relmse\ncis,1,-3,0.25,0.1\n", "c.csv:2: field 'spp'"),
            ("x,y\n", "c.csv:1: expected the header"),
            ("integrator,seconds,spp,rmse,relmse\n", "c.csv:1: no checkpoints"),
        ] {
            std::fs::write(&path, text).unwrap();
            let e = read_csv(&path).unwrap_err().to_string();
            assert!(e.contains(want), "{e:?} should contain {want:?}");
        }
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn the_summary_compares_against_the_first_label() {
        let mut rows = vec![row("mk", 1.0, 0.1), row("mk", 4.0, 0.02), row("cis", 1.0, 0.05), row("cis", 4.0, 0.01)];
        rows[1].spp = 40;
        rows[3].spp = 20;
        let s = summarize(&rows, &["mk", "cis", "absent"]);
        assert_eq!(s.len(), 2);
        assert_eq!((s[0].integrator, s[0].spp, s[0].ms_per_spp), ("mk", 40, 100.0));
        assert_eq!((s[1].spp, s[1].ms_per_spp, s[1].speedup_per_spp), (20, 200.0, 0.5));
        // Common target 0.02: mk reaches it at 4 s; cis between 1 s (0.05) and 4 s (0.01),
        // log-log: t = 4^(ln(0.02/0.05) / ln(0.01/0.05)).
        let t = 4f64.powf((0.4f64).ln() / (0.2f64).ln());
        assert!((s[1].seconds_to_target.unwrap() - t).abs() < 1e-9);
        assert!((s[1].speedup_to_target.unwrap() - 4.0 / t).abs() < 1e-9);
        assert_eq!(s[0].speedup_to_target, Some(1.0));
        let table = summary_table(&s);
        assert!(table.contains("| cis | 20 | 200.0 | 0.01000 |"), "{table}");
    }
}
