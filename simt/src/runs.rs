//! Runs of sectors touched whole, for the footprints of the time model, on a floor
//! below the meter.
//!
//! A footprint is estimated from one sector in 16, chosen by a hash of its number
//! (`limits::footprint_sampled`). Where a launch knows that its lanes touch a whole
//! range of sectors (the owned elements of `Device::transform`, counted a warp at a
//! time), keeping each sampled sector of the range, sorting and deduplicating them
//! costs a thin kernel more than the kernel itself. A [`Runs`] keeps such ranges
//! instead, joined as they come, each with the count its sampled sectors would give,
//! so the estimate is the same as sampling them one by one.

use crate::limits::{FOOTPRINT_HASH, FOOTPRINT_SAMPLE_BITS};

/// The estimated sectors of `lo..=hi`: its sampled sectors, each standing for
/// `2^FOOTPRINT_SAMPLE_BITS`. The hash of consecutive sectors steps by the multiplier,
/// so each test is an add and a compare.
pub(crate) fn estimate(lo: u64, hi: u64) -> u64 {
    let (k, top) = (FOOTPRINT_HASH, u64::MAX >> FOOTPRINT_SAMPLE_BITS);
    let (mut h, mut kept) = (lo.wrapping_mul(k), 0);
    for _ in lo..hi + 1 {
        kept += (h <= top) as u64;
        h = h.wrapping_add(k);
    }
    kept << FOOTPRINT_SAMPLE_BITS
}

/// Sectors `lo..=hi`, every one touched, and their estimate.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct Run {
    pub lo: u64,
    pub hi: u64,
    pub estimate: u64,
}

/// How many of the latest runs a new range may join: a warp's owned accesses touch
/// one range per array, so a few arrays' streams interleave.
const RECENT: usize = 4;

/// Ranges of sectors, joined where one continues a recent one.
#[derive(Clone, Debug, Default)]
pub(crate) struct Runs {
    runs: Vec<Run>,
    /// Whether `runs` is sorted, disjoint and not adjacent ([`Runs::union`]).
    merged: bool,
    /// Whether the runs' estimates are left to count ([`Runs::join`]).
    uncounted: bool,
}

impl Runs {
    pub fn is_empty(&self) -> bool {
        self.runs.is_empty()
    }

    pub fn clear(&mut self) {
        self.runs.clear();
        self.merged = false;
        self.uncounted = false;
    }

    /// The latest run that `lo..` starts inside of, or right after.
    #[inline]
    fn recent(&mut self, lo: u64) -> Option<&mut Run> {
        let from = self.runs.len().saturating_sub(RECENT);
        self.runs[from..].iter_mut().rev().find(|r| r.lo <= lo && lo <= r.hi + 1)
    }

    /// Adds sectors `lo..=hi`, leaving their estimate to count when the runs are
    /// merged ([`Runs::union`]): a range that starts inside one of the latest runs, or
    /// right after it, extends that run.
    #[inline]
    pub fn join(&mut self, lo: u64, hi: u64) {
        self.merged = false;
        self.uncounted = true;
        match self.recent(lo) {
            Some(run) => run.hi = run.hi.max(hi),
            None => self.runs.push(Run { lo, hi, estimate: 0 }),
        }
    }

    /// Adds `run`, whose estimate is known (a run of another, merged `Runs`): joined to
    /// a recent run as [`Runs::join`] does, adding the estimate of its sectors past the
    /// end of that run.
    pub fn add(&mut self, run: Run) {
        debug_assert!(!self.uncounted);
        self.merged = false;
        match self.recent(run.lo) {
            Some(last) if run.hi > last.hi => {
                last.estimate += if run.lo == last.hi + 1 { run.estimate } else { estimate(last.hi + 1, run.hi) };
                last.hi = run.hi;
            }
            Some(_) => {}
            None => self.runs.push(run),
        }
    }

    /// Moves every run of `o` into these (the runs of another worker's blocks).
    pub fn append(&mut self, o: &mut Runs) {
        self.merged = false;
        self.runs.append(&mut o.runs);
    }

    /// Sorts the runs and joins those that overlap or touch; returns the estimate of
    /// their union (an overlap is counted once).
    pub fn union(&mut self) -> u64 {
        if !self.merged {
            self.runs.sort_unstable_by_key(|r| r.lo);
            // Merged in place: `runs[..kept]` are the joined runs so far.
            let mut kept: usize = 0;
            for i in 0..self.runs.len() {
                let r = self.runs[i];
                match kept.checked_sub(1).map(|k| &mut self.runs[k]) {
                    Some(last) if r.lo <= last.hi + 1 => {
                        if r.hi > last.hi && self.uncounted {
                            last.hi = r.hi;
                        } else if r.hi > last.hi {
                            last.estimate +=
                                if r.lo > last.hi { r.estimate } else { r.estimate - estimate(r.lo, last.hi) };
                            last.hi = r.hi;
                        }
                    }
                    _ => {
                        self.runs[kept] = r;
                        kept += 1;
                    }
                }
            }
            self.runs.truncate(kept);
            if self.uncounted {
                for r in &mut self.runs {
                    r.estimate = estimate(r.lo, r.hi);
                }
                self.uncounted = false;
            }
            self.merged = true;
        }
        self.runs.iter().map(|r| r.estimate).sum()
    }

    /// Whether `sector` lies in a run; the runs must be merged ([`Runs::union`]).
    pub fn contains(&self, sector: u64) -> bool {
        debug_assert!(self.merged || self.runs.len() <= 1);
        let i = self.runs.partition_point(|r| r.hi < sector);
        self.runs.get(i).is_some_and(|r| r.lo <= sector)
    }

    pub fn iter(&self) -> impl Iterator<Item = &Run> {
        self.runs.iter()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::limits::footprint_sampled;

    /// Runs give what sampling every sector of their union gives, whatever the order
    /// and overlaps of the ranges added.
    #[test]
    fn a_union_of_runs_estimates_what_sampling_each_sector_does() {
        assert_eq!(estimate(1000, 5000), (1000..=5000).filter(|&s| footprint_sampled(s)).count() as u64 * 16);
        let ranges = [(100, 131), (132, 163), (4000, 4031), (150, 200), (164, 170), (90, 99), (4010, 4100), (7, 7)];
        let (mut joined, mut every) = (Runs::default(), std::collections::BTreeSet::new());
        for &(lo, hi) in &ranges {
            joined.join(lo, hi);
            every.extend(lo..=hi);
        }
        let count =
            |set: &std::collections::BTreeSet<u64>| set.iter().filter(|&&s| footprint_sampled(s)).count() as u64 * 16;
        assert_eq!(joined.union(), count(&every));
        // Counted runs added one by one, with overlaps, and another worker's runs.
        let mut added = Runs::default();
        for &(lo, hi) in &ranges {
            added.add(Run { lo, hi, estimate: estimate(lo, hi) });
        }
        let mut other = Runs::default();
        other.add(Run { lo: 180, hi: 260, estimate: estimate(180, 260) });
        added.append(&mut other);
        every.extend(180..=260);
        assert_eq!(added.union(), count(&every));
        for s in 0..5000 {
            assert_eq!(added.contains(s), every.contains(&s), "sector {s}");
        }
    }
}
