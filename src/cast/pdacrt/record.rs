//! What PDACRT records per breadth-first level (the tables and the inspector read it).

use crate::geometry::Aabb;
use simt::{LaunchRecord, RegionStats};

/// Time and SIMD efficiency of one kernel within one level.
#[derive(Clone, Debug, PartialEq)]
pub struct KernelTime {
    /// The launch name (`"pdacrt::filter_rays"`, …).
    pub name: &'static str,
    /// Launches of it in the level (several when the batch was traced in chunks).
    pub launches: u32,
    /// Seconds summed over those launches.
    pub seconds: f64,
    /// Active lanes per issued warp step, when measured.
    pub simd_efficiency: Option<f64>,
}

/// What one breadth-first level did (added up over the chunks of a call).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct LevelRecord {
    /// Depth of the level (0: the root).
    pub level: u32,
    /// Nodes of the level.
    pub nodes: usize,
    /// Ray references alive at this level.
    pub rays: usize,
    /// Triangle references alive at this level.
    pub triangle_refs: usize,
    /// Children of this level's nodes that went to the brute-force stage.
    pub terminal_nodes: usize,
    /// Ray references in those terminal nodes.
    pub terminal_rays: usize,
    /// Triangle references in those terminal nodes.
    pub terminal_triangles: usize,
    /// Bytes of the level's id arrays (ray and triangle ids with their node ids).
    pub id_bytes: usize,
    /// Wall time of the level.
    pub seconds: f64,
    /// Per-kernel totals, in order of first launch.
    pub kernels: Vec<KernelTime>,
    /// The level's node boxes, tightened to their triangles (kept only with
    /// `PdacrtParams::inspect`: the inspector draws them over the image).
    pub boxes: Vec<Aabb>,
}

/// Adds a later chunk's level (with its launches) to the same level of earlier chunks.
pub(super) fn merge(acc: &mut (LevelRecord, Vec<LaunchRecord>), (r, launches): (LevelRecord, Vec<LaunchRecord>)) {
    let a = &mut acc.0;
    a.nodes += r.nodes;
    a.rays += r.rays;
    a.triangle_refs += r.triangle_refs;
    a.terminal_nodes += r.terminal_nodes;
    a.terminal_rays += r.terminal_rays;
    a.terminal_triangles += r.terminal_triangles;
    a.id_bytes = a.id_bytes.max(r.id_bytes);
    a.seconds += r.seconds;
    a.boxes.extend(r.boxes);
    acc.1.extend(launches);
}

/// The record with its per-kernel totals filled in from its launches.
pub(super) fn finish(mut r: LevelRecord, launches: &[LaunchRecord]) -> LevelRecord {
    let mut out: Vec<(KernelTime, RegionStats)> = Vec::new();
    for l in launches {
        let all = l.all_regions();
        match out.iter_mut().find(|(k, _)| k.name == l.name) {
            Some((k, acc)) => {
                k.launches += 1;
                k.seconds += l.seconds;
                acc.add(&all);
            }
            None => {
                out.push((KernelTime { name: l.name, launches: 1, seconds: l.seconds, simd_efficiency: None }, all))
            }
        }
    }
    r.kernels = out.into_iter().map(|(k, acc)| KernelTime { simd_efficiency: acc.simd_efficiency(), ..k }).collect();
    r
}
