//! A filter prepared for the film's many evaluations: a stepped filter's values in a
//! table, as Mitsuba's film keeps them, so that splatting costs no `exp` per weight;
//! the exact Gaussian's weights of one camera sample, a row of them per axis, from two
//! `exp` per row.

use super::{Filter, MITSUBA_FILTER_STEPS, centres_each, splat_with, step_of, step_value};
use glam::Vec2;

/// A filter with its stepped values tabulated ([`Filter::prepared`]): the same values
/// as [`Filter`]'s own evaluation, bit for bit, except the exact Gaussian's rows of
/// camera-sample weights ([`GaussianRows`]), within 1e-6 of them.
#[derive(Clone, Copy, Debug)]
pub(crate) struct PreparedFilter {
    filter: Filter,
    table: [f32; MITSUBA_FILTER_STEPS as usize + 1],
    pub(super) gaussian_rows: Option<GaussianRows>,
}

/// The exact Gaussian's values at pixel centres one apart, `x0, x0 − 1, x0 − 2, …`, by
/// a recurrence: with `a = 1 / 2σ²`, `g(x − 1) = g(x) · exp(a (2x − 1))`, and that
/// factor itself changes by `exp(−2a)` per step, so a row costs two `exp` instead of
/// one per value. Used where every factor and value of a row stays a normal float
/// (`a (r + 2)² ≤ 80`; Mitsuba's σ = 0.5, r = 2 gives 32) and the value at the radius,
/// which is subtracted, is at most a tenth of the peak (so that the subtraction does not
/// magnify the recurrence's rounding), for rows of at most 7 values (radius under 3.5:
/// the rounding grows with the steps taken); elsewhere each value is evaluated.
#[derive(Clone, Copy, Debug)]
pub(super) struct GaussianRows {
    a: f32,
    /// `exp(−2a)`.
    step: f32,
    radius: f32,
    bias: f32,
    integral: f32,
}

impl GaussianRows {
    fn new(filter: Filter) -> Option<GaussianRows> {
        let Filter::Gaussian { stddev, radius, integral, bias, steps: 0 } = filter else { return None };
        let a = 1.0 / (2.0 * stddev * stddev);
        let short = filter.splat_reach() <= 3;
        (short && a * (radius + 2.0) * (radius + 2.0) <= 80.0 && bias <= 0.1).then(|| GaussianRows {
            a,
            step: (-2.0 * a).exp(),
            radius,
            bias,
            integral,
        })
    }

    /// The normalised values at offsets `p − (first + j + 0.5)` into `out[j]` (0 at and
    /// past the radius, as each offset, worked out exactly, says).
    #[inline]
    fn weights(&self, p: f32, first: i64, out: &mut [f32]) {
        let offset = |j: usize| p - ((first + j as i64) as f32 + 0.5);
        let x0 = offset(0);
        let (mut g, mut factor) = ((-(x0 * x0) * self.a).exp(), ((2.0 * x0 - 1.0) * self.a).exp());
        for (j, o) in out.iter_mut().enumerate() {
            *o = if offset(j).abs() >= self.radius { 0.0 } else { (g - self.bias).max(0.0) / self.integral };
            g *= factor;
            factor *= self.step;
        }
    }
}

impl PreparedFilter {
    /// The normalised 1-D filter at offset `x`.
    #[inline]
    fn eval_1d(&self, x: f32) -> f32 {
        match self.filter {
            Filter::Gaussian { radius, steps, .. } if steps > 0 => {
                if x.abs() >= radius {
                    return 0.0;
                }
                self.table[(step_of(x, radius, steps) as usize).min(steps as usize)]
            }
            f => f.eval_1d(x),
        }
    }

    /// The 1-D filter's values at pixel centres `first + j + 0.5`, offsets from `p`,
    /// into `out[j]`: the exact Gaussian's by its recurrence where it serves, the
    /// others value by value.
    #[inline]
    fn centres(&self, p: f32, first: i64, out: &mut [f32]) {
        match self.gaussian_rows {
            Some(rows) => rows.weights(p, first, out),
            None => centres_each(|x| self.eval_1d(x), p, first, out),
        }
    }

    /// The filter it tabulates.
    pub(crate) fn filter(&self) -> Filter {
        self.filter
    }

    /// [`Filter::splat`], from the table, onto the film's rows `rows` alone (the
    /// weights of the others are not evaluated).
    #[inline]
    pub(crate) fn splat_rows(&self, p: Vec2, size: (u32, u32), rows: std::ops::Range<u32>, add: impl FnMut(u32, f32)) {
        splat_with(self.filter, |p, first, out: &mut [f32]| self.centres(p, first, out), p, size, rows, add)
    }

    /// The weights one camera sample at film position `p` gives the pixels around it,
    /// per axis: `wx[i]` for pixel column `floor(p.x) − k + i` (and `wy` for rows), where
    /// `k` is [`Filter::splat_reach`]. Unnormalised by the image edge.
    #[inline]
    pub(crate) fn splat_weights(&self, p: Vec2, wx: &mut [f32], wy: &mut [f32]) {
        let k = self.filter.splat_reach() as i64;
        self.centres(p.x, p.x.floor() as i64 - k, wx);
        self.centres(p.y, p.y.floor() as i64 - k, wy);
    }
}

impl Filter {
    /// The filter ready for many evaluations: a stepped filter's values in a table,
    /// as Mitsuba's film keeps them, so that splatting a pass's camera samples costs
    /// no `exp` per weight.
    pub(crate) fn prepared(&self) -> PreparedFilter {
        let mut table = [0.0; MITSUBA_FILTER_STEPS as usize + 1];
        if let Filter::Gaussian { stddev, radius, integral, bias, steps } = *self
            && steps > 0
        {
            // One entry per step, and the value at the radius, which a position just
            // under it can round to.
            for (i, v) in table.iter_mut().enumerate().take(steps as usize + 1) {
                *v = step_value(stddev, radius, integral, bias, steps, i as u32);
            }
        }
        PreparedFilter { filter: *self, table, gaussian_rows: GaussianRows::new(*self) }
    }
}

#[cfg(test)]
mod tests {
    use super::super::step_start;
    use super::*;

    /// The film's tabulated filter gives the filter's own values, bit for bit, at every
    /// offset: on a fine grid, at each step's start and just below the radius.
    #[test]
    fn the_prepared_filter_answers_as_the_filter() {
        let filters = [
            Filter::Box,
            Filter::gaussian(0.5, 2.0).unwrap(),
            Filter::mitsuba_gaussian(),
            Filter::mitsuba(0.3).unwrap(),
        ];
        for f in filters {
            let p = f.prepared();
            let r = f.radius();
            let mut xs: Vec<f32> = (0..=8000).map(|i| (i as f32 / 4000.0 - 1.0) * (r + 0.25)).collect();
            xs.extend((0..=MITSUBA_FILTER_STEPS).map(|i| step_start(r, MITSUBA_FILTER_STEPS, i)));
            xs.extend([r.next_down(), -r.next_down(), r, (r * 0.5).next_up()]);
            for x in xs {
                assert_eq!(p.eval_1d(x).to_bits(), f.eval_1d(x).to_bits(), "{f:?} at {x}");
            }
        }
    }
}
