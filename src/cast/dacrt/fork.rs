//! DACRT's forks: a node's far child handed to rayon as a task of its own, so that a
//! thread left without work takes it over, and otherwise run after the near child on
//! the same thread, as the serial recursion would.
//!
//! With one ray group per thread, the groups alone leave threads idle at the end of a
//! call (the longest group takes 2.5–3× the mean), while many groups cost work: each
//! one re-partitions the triangles of every shared-top cell it reaches. A fork keeps the
//! groups few and lends their far halves out only when a thread would idle.
//!
//! The far child's triangles do not depend on the rays, so they are copied out before
//! the near child starts; its rays are those entering it at that moment, a superset of
//! the ones entering it after the near child's hits (a ray's interval only shrinks).
//! When the task starts, the rays the near child has since stopped are dropped, so a
//! far child run on its own thread after the near one holds exactly the serial
//! recursion's lists, and one taken by another thread at once holds more rays, whose
//! intervals are cut again at every level below as hits arrive.

use super::planes::partition_triangles;
use super::state::{Dacrt, Soup, Trace};
use super::top::{Scratch, SharedTop, Top};
use crate::geometry::Aabb;
use std::sync::atomic::Ordering::Relaxed;
use std::time::Instant;

impl Trace {
    /// The rays of `rays` that enter `b`, in their order, as a list of their own: the
    /// ray partition (on the trace's lanes) of a copy. (A task that owns its list
    /// partitions it in place.)
    fn entering(&self, rays: &[u32], b: &Aabb, spare: &mut Vec<u32>) -> Vec<u32> {
        let mut kept = rays.to_vec();
        let n = self.partition_rays(&mut kept, b, spare);
        kept.truncate(n);
        kept
    }

    /// True when a node with `rays` rays hands its far child out as a task.
    #[inline]
    pub(super) fn forks(&self, rays: usize) -> bool {
        self.fork_min_rays > 0 && rays >= self.fork_min_rays
    }
}

impl Dacrt {
    /// A node's two children, `near` in place and `far` as a task (see the module docs).
    #[allow(clippy::too_many_arguments)]
    pub(super) fn fork(
        &self,
        tr: &Trace,
        soup: Soup,
        [near, far]: [Aabb; 2],
        rays: &mut [u32],
        tris: &mut [u32],
        spare: &mut Vec<u32>,
        depth: u32,
    ) {
        // The far child's triangles and rays, copied out (on the trace's lanes).
        let mut far_tris = tris.to_vec();
        let (nt, union) = partition_triangles(tr.lanes, soup.boxes, &mut far_tris, &far, spare);
        far_tris.truncate(nt);
        let tight = far.intersection(union);
        let far_rays = if far_tris.is_empty() { Vec::new() } else { tr.entering(rays, &tight, spare) };
        if far_rays.is_empty() {
            return self.child(tr, soup, near, rays, tris, spare, depth);
        }
        self.join(
            tr,
            far_tris.len() + far_rays.len(),
            || self.child(tr, soup, near, rays, tris, spare, depth),
            |tr| {
                let (mut far_rays, mut spare) = (far_rays, Vec::new());
                let n = tr.partition_rays(&mut far_rays, &tight, &mut spare);
                self.recurse(tr, soup, tight, &mut far_rays[..n], &mut far_tris, &mut spare, depth + 1);
            },
        );
    }

    /// A shared-top split's two children, `near` in place and `far` as a task.
    pub(super) fn fork_top(
        &self,
        tr: &Trace,
        top: &SharedTop,
        [near, far]: [&Top; 2],
        rays: &mut [u32],
        scratch: &mut Scratch,
        depth: u32,
    ) {
        let b = *far.bounds();
        let far_rays = tr.entering(rays, &b, &mut scratch.rays);
        let near_part = |rays: &mut [u32], scratch: &mut Scratch| {
            let nr = tr.partition_rays(rays, near.bounds(), &mut scratch.rays);
            self.trace_top(tr, top, near, &mut rays[..nr], scratch, depth + 1);
        };
        if far_rays.is_empty() {
            return near_part(rays, scratch);
        }
        self.join(
            tr,
            far_rays.len(),
            || near_part(rays, scratch),
            |tr| {
                let (mut far_rays, mut scratch) = (far_rays, Scratch::default());
                let n = tr.partition_rays(&mut far_rays, &b, &mut scratch.rays);
                self.trace_top(tr, top, far, &mut far_rays[..n], &mut scratch, depth + 1);
            },
        );
    }

    /// `rayon::join` of the near part and the far task, with the far task's copied
    /// lists (`words` ids) in the working set while they live, and the threads' busy
    /// time kept exact: the far task counts its own span, and the forking task drops
    /// from its span whatever the join took beyond the near part (the far task run
    /// inline, or the wait for it, during which this thread runs other tasks that
    /// count themselves).
    fn join(&self, tr: &Trace, words: usize, near: impl FnOnce() + Send, far: impl FnOnce(&Trace) + Send) {
        tr.alloc(words * 4);
        let start = Instant::now();
        let (near_s, ()) = rayon::join(
            || {
                let t = Instant::now();
                near();
                t.elapsed()
            },
            || {
                let t = Instant::now();
                far(tr);
                tr.busy_ns.fetch_add(t.elapsed().as_nanos() as u64, Relaxed);
            },
        );
        let beyond = start.elapsed().saturating_sub(near_s);
        tr.busy_ns.fetch_sub(beyond.as_nanos() as u64, Relaxed);
        tr.free(words * 4);
    }
}

#[cfg(test)]
mod tests {
    use super::super::packets::ORIGIN_BITS;
    use super::super::state::DacrtParams;
    use super::*;

    /// A camera's batch (one origin) is cut into many groups and never forks; an
    /// ambient-occlusion batch (rays from every hit point) gets one group per thread
    /// and forks. Hits of both are checked against brute force in `tests/suite/dacrt.rs`.
    #[test]
    fn batches_from_one_origin_are_grouped_and_the_others_fork() {
        let scene = crate::scene::cornell_box();
        // Forks from 64 rays, so that the AO batch of a small image is large enough.
        let d = Dacrt::new(&scene).with_params(DacrtParams { fork_min_rays: 64, ..DacrtParams::default() });
        let b = crate::cast::batches::batches(&scene, 64, 64, 2, 3);
        let pool = rayon::ThreadPoolBuilder::new().num_threads(4).build().expect("a pool of 4 threads");
        pool.install(|| {
            let (ids, _, varying) = d.valid_rays(&b.primary);
            assert_eq!(varying & ORIGIN_BITS, 0, "a pinhole camera's rays share their origin bits");
            let (groups, fork) = d.grouping(ids.len(), true);
            assert!(groups > 4 && fork == 0, "{groups} groups, forks from {fork} rays");
            let (ids, _, varying) = d.valid_rays(&b.ambient);
            assert_ne!(varying & ORIGIN_BITS, 0, "AO rays start at many points");
            assert_eq!(d.grouping(ids.len(), false), (4, 64));
            // A batch from many origins with less than 2 · 64 rays a thread is grouped.
            assert_eq!(d.grouping(511, false).1, 0);
        });
        let one = rayon::ThreadPoolBuilder::new().num_threads(1).build().expect("a pool of 1 thread");
        assert_eq!(one.install(|| d.grouping(4096, false)), (1, 0), "one thread: one group, no forks");
    }
}
