//! Two estimators compared over independent seeds, as a statistician would: each is
//! rendered with `SEEDS` seeds, and its image mean and the means of image blocks (per
//! channel) are taken with their standard errors across seeds. Two estimators agree
//! when
//!
//! - the image means differ by less than 4.5 combined standard errors, and that combined
//!   error is below a stated precision, so that the test has power and not only a
//!   tolerance. Each test's precision sits about 1.5 times above the largest combined
//!   error seen over six seed sets (`WARPRAY_TEST_SEED_OFFSET` 0 to 5000), since the
//!   estimated error is itself noisy; where it is 0.18 %, a 1 % bias is at least 5.6
//!   and typically 8 to 11 standard errors, and fails; and
//! - no block's channel mean differs by more than Welch's t-test allows at a family
//!   false-alarm rate of 1e-4 (Šidák over the blocks): the *limit* of the two
//!   estimators must agree region by region, which a check that errors shrink cannot
//!   see.
//!
//! The same numbers also give the convergence rate when a test wants it.

use statrs::distribution::{ContinuousCDF, StudentsT};
use warpray::glam::Vec3;

/// Seeds per estimator.
pub const SEEDS: u64 = 16;

/// Per-seed statistics of one estimator's images.
pub struct Runs {
    /// What was rendered, for messages.
    pub what: String,
    /// Per seed: the luminance image mean, then each block's mean per channel.
    pub per_seed: Vec<Vec<f64>>,
    /// The images' average over seeds.
    pub average: Vec<Vec3>,
    /// The first seed's image.
    pub first: Vec<Vec3>,
    /// Image width and block size, in pixels.
    width: usize,
    block: usize,
}

/// The luminance image mean, then each block's mean per channel.
fn image_stats(img: &[Vec3], width: usize, block: usize) -> Vec<f64> {
    let height = img.len() / width;
    let mut stats = vec![img.iter().map(|&c| warpray::film::luminance(c) as f64).sum::<f64>() / img.len() as f64];
    for by in 0..height / block {
        for bx in 0..width / block {
            let mut sum = [0.0f64; 3];
            for y in by * block..(by + 1) * block {
                for x in bx * block..(bx + 1) * block {
                    let c = img[y * width + x];
                    sum.iter_mut().zip(c.to_array()).for_each(|(s, v)| *s += v as f64);
                }
            }
            stats.extend(sum.iter().map(|s| s / (block * block) as f64));
        }
    }
    stats
}

/// Added to every seed: `WARPRAY_TEST_SEED_OFFSET=1000` runs every comparison of the
/// suite on other seeds, to check that none was chosen to pass.
fn seed_offset() -> u64 {
    std::env::var("WARPRAY_TEST_SEED_OFFSET").ok().and_then(|s| s.parse().ok()).unwrap_or(0)
}

/// Renders `SEEDS` images with seeds `base + i` (plus the offset above) through
/// `render` and summarises them over `block` x `block` pixel blocks of a `width`-wide
/// image.
pub fn runs(what: &str, base: u64, width: usize, block: usize, render: impl Fn(u64) -> Vec<Vec3>) -> Runs {
    let base = base + seed_offset();
    let mut per_seed = Vec::new();
    let mut average: Vec<Vec3> = Vec::new();
    let mut first = Vec::new();
    for i in 0..SEEDS {
        let img = render(base + i);
        assert!(
            img.len().is_multiple_of(width) && width.is_multiple_of(block) && (img.len() / width).is_multiple_of(block)
        );
        per_seed.push(image_stats(&img, width, block));
        if average.is_empty() {
            average = vec![Vec3::ZERO; img.len()];
            first = img.clone();
        }
        average.iter_mut().zip(&img).for_each(|(a, v)| *a += *v / SEEDS as f32);
    }
    Runs { what: what.to_string(), per_seed, average, first, width, block }
}

impl Runs {
    /// Statistics computed elsewhere (another renderer's seeds), laid out as [`runs`]
    /// lays them out.
    pub fn from_per_seed(what: &str, per_seed: Vec<Vec<f64>>, width: usize, block: usize) -> Runs {
        assert_eq!(per_seed.len() as u64, SEEDS, "{what}: {SEEDS} seeds expected");
        Runs { what: what.to_string(), per_seed, average: Vec::new(), first: Vec::new(), width, block }
    }

    /// (mean, standard error) of statistic `k` over seeds.
    pub fn stat(&self, k: usize) -> (f64, f64) {
        crate::common::statistics(&self.per_seed.iter().map(|s| s[k]).collect::<Vec<_>>())
    }

    /// The luminance image mean and its standard error.
    pub fn mean(&self) -> (f64, f64) {
        self.stat(0)
    }
}

/// Two-sided p-value of Welch's t-test for two means with their standard errors, each
/// from `SEEDS` values.
fn welch_p((ma, sa): (f64, f64), (mb, sb): (f64, f64)) -> f64 {
    let v = sa * sa + sb * sb;
    if v == 0.0 {
        return if ma == mb { 1.0 } else { 0.0 };
    }
    let t = (ma - mb).abs() / v.sqrt();
    let n1 = SEEDS as f64 - 1.0;
    let df = v * v / (sa.powi(4) / n1 + sb.powi(4) / n1);
    2.0 * (1.0 - StudentsT::new(0.0, 1.0, df.max(1.0)).unwrap().cdf(t))
}

/// Whether `a` and `b` estimate the same image (see the module's text), with the
/// combined standard error of the means at most `precision` of `b`'s mean. Returns a
/// description; panics with every failed check.
pub fn assert_agree(a: &Runs, b: &Runs, precision: f64) -> String {
    let mut failures = Vec::new();
    let ((ma, sa), (mb, sb)) = (a.mean(), b.mean());
    let se = (sa * sa + sb * sb).sqrt();
    let z = (ma - mb) / se.max(1e-300);
    let line = format!(
        "{} {ma:.5} ± {sa:.5} vs {} {mb:.5} ± {sb:.5}: {:+.3} % ± {:.3} %, z = {z:+.2}",
        a.what,
        b.what,
        100.0 * (ma - mb) / mb,
        100.0 * se / mb
    );
    if z.abs() > 4.5 {
        failures.push(format!("image means differ: {line}"));
    }
    if se > precision * mb.abs() {
        failures.push(format!("too imprecise to see a bias of {:.2} %: {line}", 100.0 * 6.0 * se / mb));
    }
    let tests = a.per_seed[0].len() - 1;
    let alpha = 1.0 - (1.0f64 - 1e-4).powf(1.0 / tests as f64);
    for k in 1..=tests {
        let (p, q) = (a.stat(k), b.stat(k));
        let pv = welch_p(p, q);
        if pv < alpha {
            let (block, channel) = ((k - 1) / 3, ["red", "green", "blue"][(k - 1) % 3]);
            failures.push(format!(
                "block {block} {channel}: {:.5} ± {:.5} vs {:.5} ± {:.5} (p = {pv:.1e} < {alpha:.1e})",
                p.0, p.1, q.0, q.1
            ));
        }
    }
    assert!(failures.is_empty(), "{} vs {}:\n{}", a.what, b.what, failures.join("\n"));
    line
}

/// Whether `a` estimates the image `want` (a closed form, per pixel): the image mean
/// within 4.5 standard errors of `want`'s, that standard error at most `precision` of
/// it, and every block's channel means within Student's t at a family false-alarm rate
/// of 1e-4.
pub fn assert_matches(a: &Runs, want: &[Vec3], precision: f64) -> String {
    let want = image_stats(want, a.width, a.block);
    let mut failures = Vec::new();
    let (m, se) = a.mean();
    let lum = want[0];
    let z = (m - lum) / se.max(1e-300);
    let line = format!(
        "{} {m:.5} ± {se:.5} vs closed form {lum:.5}: {:+.3} % ± {:.3} %, z = {z:+.2}",
        a.what,
        100.0 * (m - lum) / lum,
        100.0 * se / lum
    );
    if z.abs() > 4.5 {
        failures.push(format!("image mean differs: {line}"));
    }
    if se > precision * lum {
        failures.push(format!("too imprecise to see a bias of {:.2} %: {line}", 100.0 * 6.0 * se / lum));
    }
    let tests = want.len() - 1;
    let alpha = 1.0 - (1.0f64 - 1e-4).powf(1.0 / tests as f64);
    let t = StudentsT::new(0.0, 1.0, SEEDS as f64 - 1.0).unwrap();
    for (k, &w) in want.iter().enumerate().skip(1) {
        let (mk, sk) = a.stat(k);
        let p = 2.0 * (1.0 - t.cdf((mk - w).abs() / sk.max(1e-300)));
        if p < alpha {
            failures.push(format!(
                "block {} channel {}: {mk:.5} ± {sk:.5} vs {w:.5} (p = {p:.1e})",
                (k - 1) / 3,
                (k - 1) % 3
            ));
        }
    }
    assert!(failures.is_empty(), "{}:\n{}", a.what, failures.join("\n"));
    line
}

/// [`assert_matches`] for an image of constant radiance `want`.
pub fn assert_constant(a: &Runs, want: Vec3, precision: f64) -> String {
    assert_matches(a, &vec![want; a.first.len()], precision)
}
