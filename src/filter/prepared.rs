//! A filter prepared for the film's many evaluations: a stepped filter's values in a
//! table, as Mitsuba's film keeps them, so that splatting costs no `exp` per weight.

use super::{Filter, MITSUBA_FILTER_STEPS, splat_with, step_of, step_value};
use glam::Vec2;

/// A filter with its stepped values tabulated ([`Filter::prepared`]): the same values
/// as [`Filter`]'s own evaluation, bit for bit.
#[derive(Clone, Copy, Debug)]
pub(crate) struct PreparedFilter {
    filter: Filter,
    table: [f32; MITSUBA_FILTER_STEPS as usize + 1],
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

    /// The filter it tabulates.
    pub(crate) fn filter(&self) -> Filter {
        self.filter
    }

    /// [`Filter::splat`], from the table, onto the film's rows `rows` alone (the
    /// weights of the others are not evaluated).
    #[inline]
    pub(crate) fn splat_rows(&self, p: Vec2, size: (u32, u32), rows: std::ops::Range<u32>, add: impl FnMut(u32, f32)) {
        splat_with(self.filter, |x| self.eval_1d(x), p, size, rows, add)
    }

    /// The weights one camera sample at film position `p` gives the pixels around it,
    /// per axis: `wx[i]` for pixel column `floor(p.x) − k + i` (and `wy` for rows), where
    /// `k` is [`Filter::splat_reach`]. Unnormalised by the image edge.
    #[inline]
    pub(crate) fn splat_weights(&self, p: Vec2, wx: &mut [f32], wy: &mut [f32]) {
        let k = self.filter.splat_reach() as i32;
        let (cx, cy) = (p.x.floor(), p.y.floor());
        let offset = |i: usize| (i as i32 - k) as f32 + 0.5;
        for i in 0..wx.len() {
            wx[i] = self.eval_1d(p.x - (cx + offset(i)));
            wy[i] = self.eval_1d(p.y - (cy + offset(i)));
        }
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
        PreparedFilter { filter: *self, table }
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
