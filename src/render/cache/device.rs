//! The light vertex cache in device memory: filled by the device light passes (CIS's
//! stream, the LVC megakernel), read by their camera kernels, copied back for tests and
//! the inspector.

use super::host::{LightVertexCache, StrategyCounts};
use super::kernels::{CacheViews, SplatData, cache_counts, cache_store};
use crate::render::bidir::Vertex;
use crate::render::context::Context;
use crate::render::options::Iterations;
use glam::{Vec2, Vec3};
use simt::{Device, DeviceBuffer};

/// The light vertex cache in device memory (see [`CacheViews`] for its layout).
pub(crate) struct DeviceCache {
    pub vertices: DeviceBuffer<Vertex>,
    pub entries: DeviceBuffer<[u32; 2]>,
    /// Per subpath: (its number in the iteration, first vertex, length).
    pub paths: DeviceBuffer<[u32; 3]>,
    /// Light subpaths the iteration traced.
    pub light_paths: u32,
}

impl DeviceCache {
    pub fn new(dev: &Device, light_paths: u32) -> DeviceCache {
        DeviceCache { vertices: dev.alloc(0), entries: dev.alloc(0), paths: dev.alloc(0), light_paths }
    }

    /// MIS sample counts once the cache is complete (as [`LightVertexCache`]'s), for
    /// camera passes made as `iterations` says.
    pub fn counts(&self, ctx: &Context, n_c: u32, iterations: Iterations) -> StrategyCounts {
        StrategyCounts::new(ctx, self.light_paths, self.entries.len(), n_c, iterations)
    }

    /// A host copy, subpaths in the order of their numbers (as the host light pass
    /// builds it), for tests and the inspector.
    pub fn to_host(&self) -> LightVertexCache {
        let mut paths = self.paths.to_vec();
        paths.sort_by_key(|p| p[0]);
        let verts = self.vertices.as_slice();
        let mut cache = LightVertexCache { light_paths: self.light_paths, ..Default::default() };
        let mut entries = self.entries.to_vec();
        entries.sort_by_key(|e| e[0]);
        for [_, start, len] in paths {
            let at = cache.vertices.len() as u32;
            cache.vertices.extend_from_slice(&verts[start as usize..(start + len) as usize]);
            let first = entries.partition_point(|e| e[0] < start);
            let ours = entries[first..].iter().take_while(|e| e[0] == start);
            cache.entries.extend(ours.map(|e| (at, e[1])));
        }
        cache
    }
}

/// Appends the subpaths listed in `done` (slot, number, length; vertices staged
/// `stride` per slot) to `cache`, in list order.
pub(crate) fn append_paths(
    dev: &Device,
    ctx: &Context,
    done: &DeviceBuffer<[u32; 3]>,
    staging: &DeviceBuffer<Vertex>,
    stride: usize,
    cache: &mut DeviceCache,
) {
    let m = done.len();
    if m == 0 {
        return;
    }
    let (mut n_v, mut n_e) = (dev.alloc_pooled::<u32>(m), dev.alloc_pooled::<u32>(m));
    {
        let (dv, sv, vv, ev) = (done.view(), staging.view(), n_v.view_mut(), n_e.view_mut());
        dev.for_each("cis::cache_counts", m, |t, f| cache_counts(t, ctx, f, (&dv, &sv, stride), &vv, &ev));
    }
    let (mut off_v, mut off_e) = (dev.alloc_pooled::<u32>(m), dev.alloc_pooled::<u32>(m));
    simt::exclusive_scan(dev, &n_v, &mut off_v, 0, 0, |a, b| a + b);
    simt::exclusive_scan(dev, &n_e, &mut off_e, 0, 0, |a, b| a + b);
    let total = |off: &DeviceBuffer<u32>, n: &DeviceBuffer<u32>| (off.as_slice()[m - 1] + n.as_slice()[m - 1]) as usize;
    let bases = [cache.vertices.len() as u32, cache.entries.len() as u32, cache.paths.len() as u32];
    cache.vertices.resize(bases[0] as usize + total(&off_v, &n_v));
    cache.entries.resize(bases[1] as usize + total(&off_e, &n_e));
    cache.paths.resize(bases[2] as usize + m);
    let views = CacheViews {
        vertices: cache.vertices.view_mut(),
        entries: cache.entries.view_mut(),
        paths: cache.paths.view_mut(),
    };
    let (dv, sv, ov, oe) = (done.view(), staging.view(), off_v.view(), off_e.view());
    dev.for_each("cis::cache_store", m, |t, f| cache_store(t, ctx, f, (&dv, &sv, stride), (&ov, &oe), bases, &views));
}

/// The visible splats (`state` 2) of `splats`, in order (`copy_if`), read back.
pub(crate) fn visible_splats(dev: &Device, splats: &DeviceBuffer<SplatData>) -> Vec<(Vec2, Vec3)> {
    let mut kept = dev.alloc_pooled::<SplatData>(splats.len());
    let m = simt::copy_if(dev, splats, &mut kept, |s: SplatData| s.state == 2);
    kept.as_slice()[..m].iter().map(|s| (s.film, s.value)).collect()
}
