//! The light vertex cache's host half, checked where nothing else would notice.
use super::host::*;
use crate::render::RenderOptions;
use crate::render::bidir::{Vertex, VertexKind, VertexList, camera_vertex};
use crate::render::context::TestSetup;
use crate::sampling::Rng;
use crate::scene::cornell_box;
use glam::Vec3;
use std::cell::RefCell;

/// The prefetch hint names the entries the connections then read, in order: over
/// camera vertices on diffuse walls (the light sample draws first) and on a mirror
/// (it draws nothing), for uniform and resampled connections. (A wrong guess would
/// cost time only, so nothing else would notice.)
#[test]
fn the_prefetched_entries_are_the_ones_the_connections_read() {
    let mut scene = cornell_box();
    let mirror = scene.add_material(
        "mirror",
        crate::scene::Material::Mirror { reflectance: glam::Vec3::splat(0.9) },
        Vec3::ZERO,
    );
    scene.material_of[2] = mirror;
    let opts = RenderOptions { width: 16, height: 16, max_depth: 6, ..Default::default() };
    let setup = TestSetup::new(&scene);
    let ctx = setup.ctx(&opts);
    let light_tri = (0..scene.triangle_count() as u32).find(|&t| scene.emission_of(t).max_element() > 0.0).unwrap();
    // A vertex at the centre of triangle `tri`, of `kind`, with the triangle's emission.
    let at_centre = |kind: VertexKind, tri: u32| {
        let [a, b, c] = scene.vertices(tri);
        let p = (a + b + c) / 3.0;
        Vertex::new(kind, p, scene.normal(tri), tri, Vec3::ONE, false, scene.emission_of(tri))
    };
    let light = at_centre(VertexKind::Light, light_tri);
    let (read, hinted) = (RefCell::new(Vec::new()), RefCell::new(Vec::new()));
    let subpath = |e: usize, list: &mut VertexList, _: bool| {
        read.borrow_mut().push(e);
        list.clear();
        list.push(light);
        1
    };
    let prefetch = |drawn: &[usize]| hinted.borrow_mut().extend_from_slice(drawn);
    let counts = StrategyCounts { splat: 1.0, connection: 1.0, splat_paths: 1.0 };
    let (mut path, mut checked) = (VertexList::default(), 0);
    for (tri, connections) in [
        (0, Connections::Uniform { n: 3 }),
        (2, Connections::Uniform { n: 2 }),
        (4, Connections::Resampled { candidates: 5, draws: 2 }),
        (2, Connections::Resampled { candidates: 4, draws: 1 }),
    ] {
        let cam = [camera_vertex(&scene.camera), at_centre(VertexKind::Surface, tri)];
        for seed in 0..20 {
            let mut rng = Rng::for_sample(seed, 3, 1);
            read.borrow_mut().clear();
            hinted.borrow_mut().clear();
            let access: CacheAccess = (&subpath, Some(&prefetch));
            vertex_strategies(
                &ctx,
                (&cam, &[]),
                2,
                1000,
                access,
                counts,
                connections,
                &mut rng,
                &mut path,
                &mut |_| {},
            );
            let (read, hinted) = (read.borrow(), hinted.borrow());
            assert!(!read.is_empty(), "{connections:?}: no connection read the cache");
            // Resampling reads each candidate's tail, then its draws again.
            let candidates = match connections {
                Connections::Uniform { n } => n as usize,
                Connections::Resampled { candidates, .. } => candidates as usize,
            };
            assert_eq!(&read[..candidates], &hinted[..], "{connections:?}, triangle {tri}, seed {seed}");
            checked += 1;
        }
    }
    assert_eq!(checked, 80);
}

/// A copied vertex is one round of a warp's dependent chain (its fifteen words loaded
/// together), its instructions as fifteen loads; each call site of the copy is an
/// instruction stream of its own, as nvcc inlines it: lanes copying two or three
/// vertices at the first site and three or two at the second issue three vertices'
/// loads at each (six rounds a warp), not five matched across the sites.
#[test]
fn a_copied_vertex_is_one_round_of_fifteen_loads() {
    use super::kernels::load_vertices;
    let dev = simt::Device::new(simt::DeviceConfig { measure: true, ..Default::default() });
    dev.set_gpu_profile(Some(simt::GpuProfile::named("h200").unwrap()));
    let v = Vertex::new(VertexKind::Surface, Vec3::ONE, Vec3::Z, 0, Vec3::ONE, false, Vec3::ZERO);
    let verts = dev.alloc_from(&vec![v; 64 * 5]);
    let view = verts.view();
    let rec = dev.for_each("copies", 64, |t, i| {
        let (mut a, mut b) = (VertexList::default(), VertexList::default());
        let first = 2 + i % 2;
        load_vertices(t, &view, 5 * i..5 * i + first, &mut a);
        load_vertices(t, &view, 5 * i + first..5 * i + 5, &mut b);
        assert_eq!(a.len() + b.len(), 5);
    });
    assert_eq!(rec.longest_warp.load_rounds, 6);
    assert_eq!(rec.waits.load_rounds, 2 * 6);
    assert_eq!(rec.loads.requests, 2 * 6 * 15);
}
