//! Cases the lanes' tests share (`partition.rs`, `planes.rs`, `leaf.rs`): traces of
//! rays and triangles on grids that make ties, and the widths this CPU runs.

use super::state::Trace;
use crate::geometry::Ray;
use crate::geometry::hit_key::{BLOCKED, NONE, pack};
use crate::geometry::lanes::RaySlab;
use crate::geometry::packet_lanes::Width;
use crate::sampling::Rng;
use glam::Vec3;
use std::sync::atomic::Ordering::Relaxed;

/// Every wide width this CPU has; says loudly when it has none (the lanes are then
/// not checked here, and no caster runs them).
pub(super) fn widths() -> Vec<Width> {
    let w: Vec<Width> = Width::ALL.into_iter().filter(|w| w.supported()).collect();
    if w.is_empty() {
        eprintln!("WARNING: this CPU has neither AVX2 nor AVX-512: DACRT's wide lanes are not checked");
    }
    if !Width::Avx512.supported() {
        eprintln!("WARNING: this CPU has no AVX-512: DACRT's 16-lane loops are not checked here");
    }
    w
}

/// Rays and triangles on a coarse grid (origins on faces, rays along faces, zero
/// direction components, shared edges, ties) mixed with random ones; keys set to
/// hits at random distances, left at `NONE`, or (any-hit) `BLOCKED`.
pub(super) fn case(rng: &mut Rng, any_hit: bool, lanes: bool) -> (Vec<[Vec3; 3]>, Trace) {
    let point = |r: &mut Rng, coarse: bool| {
        let v = Vec3::new(r.uniform(), r.uniform(), r.uniform()) * 4.0 - 2.0;
        if coarse { (v * 2.0).round() * 0.5 } else { v }
    };
    let coarse = rng.uniform() < 0.5;
    let tris: Vec<[Vec3; 3]> = (0..40).map(|_| [point(rng, coarse), point(rng, coarse), point(rng, coarse)]).collect();
    let rays: Vec<Ray> = (0..200)
        .map(|_| {
            let origin = point(rng, coarse) + Vec3::Z * 3.0;
            let mut dir = point(rng, coarse) - origin;
            if rng.uniform() < 0.1 {
                dir.x = 0.0;
            }
            let t_max = if rng.uniform() < 0.3 { 2.0 + rng.uniform() * 3.0 } else { f32::INFINITY };
            Ray { origin, dir: if dir == Vec3::ZERO { Vec3::Z } else { dir }, t_min: 0.0, t_max }
        })
        .collect();
    let slabs = rays.iter().map(RaySlab::new).collect();
    let tr = Trace::new(rays, slabs, any_hit, 0, 0, 4.0, lanes);
    for k in &tr.keys {
        let u = rng.uniform();
        k.store(
            if u < 0.4 {
                NONE
            } else if any_hit {
                BLOCKED
            } else {
                pack(u * 6.0, (u * 1e4) as u32)
            },
            Relaxed,
        );
    }
    (tris, tr)
}
