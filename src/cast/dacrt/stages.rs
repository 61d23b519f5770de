//! Seconds by stage of one DACRT call ([`crate::cast::RayCaster::phase_seconds`]).

use std::time::Instant;

/// `f`'s result and its seconds.
pub(super) fn timed<R>(f: impl FnOnce() -> R) -> (R, f64) {
    let start = Instant::now();
    let r = f();
    (r, start.elapsed().as_secs_f64())
}

/// Seconds by stage of one call: `lap` closes the stage since the last lap.
pub(super) struct Stages {
    last: Instant,
    pub(super) seconds: Vec<(&'static str, f64)>,
}

impl Default for Stages {
    fn default() -> Self {
        Stages { last: Instant::now(), seconds: Vec::new() }
    }
}

impl Stages {
    pub(super) fn lap(&mut self, name: &'static str) {
        let now = Instant::now();
        self.seconds.push((name, (now - self.last).as_secs_f64()));
        self.last = now;
    }

    pub(super) fn note(&mut self, name: &'static str, seconds: f64) {
        self.seconds.push((name, seconds));
    }
}
