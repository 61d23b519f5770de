//! Every integrator with every caster: the render counts the rays it cast, whichever
//! caster answers them, and since every caster returns the same hits (distance,
//! triangle, barycentrics), the images and ray counts are identical.

use crate::common::small_render;
use warpray::prelude::*;
use warpray::render::Renderer;

#[test]
fn every_integrator_counts_the_same_rays_and_makes_the_same_image_with_every_caster() {
    let scene = cornell_box();
    for integrator in
        [IntegratorKind::Path, IntegratorKind::Light, IntegratorKind::Bdpt, IntegratorKind::Lvc, IntegratorKind::Cis]
    {
        let opts = small_render(integrator);
        let mut first: Option<(Vec<Vec3>, RenderStats)> = None;
        for kind in [CasterKind::Bvh, CasterKind::Dacrt, CasterKind::Pdacrt, CasterKind::Brute] {
            let caster = kind.build(&scene).unwrap();
            let (film, stats) = render(&scene, caster.as_ref(), &opts, |_, _| true).unwrap();
            assert!(stats.rays > 0 && stats.tests > 0, "{} with {kind:?}: nothing counted", integrator.name());
            let img = film.mean();
            match &first {
                None => first = Some((img, stats)),
                Some((img0, st0)) => {
                    assert_eq!(stats.rays, st0.rays, "{} with {kind:?}: ray count", integrator.name());
                    assert!(img == *img0, "{} with {kind:?}: image differs from the BVH's", integrator.name());
                }
            }
        }
    }
}

#[test]
fn one_device_holds_a_whole_render_of_pdacrt_and_cis() {
    let scene = cornell_box();
    let opts = RenderOptions {
        width: 16,
        height: 16,
        budget: Budget::Samples(1),
        integrator: IntegratorKind::Cis,
        seed: 5,
        ..Default::default()
    };
    let caster = CasterKind::Pdacrt.build(&scene).unwrap();
    let dev = caster.device().expect("PDACRT runs on a device").clone();
    let mut renderer = Renderer::new(&scene, caster.as_ref(), &opts).unwrap();
    let mut film = renderer.film().unwrap();
    renderer.pass(0, &mut film);
    let shared = renderer.device().expect("the render has a device");
    let names: Vec<&str> = shared.kernel_stats().iter().map(|k| k.name).collect();
    // The caster's kernels and the integrator's, in one table, on the caster's device.
    assert!(names.iter().any(|n| n.starts_with("pdacrt::")), "{names:?}");
    assert!(names.iter().any(|n| n.starts_with("cis::")), "{names:?}");
    assert_eq!(dev.kernel_stats().len(), names.len());
    // Its peak covers the scene's triangles and the integrator's pool together.
    assert!(dev.memory().peak > dev.memory().current);
    // Other casters have no device; the cis integrator then brings its own.
    let bvh = CasterKind::Bvh.build(&scene).unwrap();
    assert!(bvh.device().is_none());
    let r = Renderer::new(&scene, bvh.as_ref(), &opts).unwrap();
    assert!(r.device().is_some());
}

/// `render` groups the passes of a small image into shared waves
/// (`Renderer::pass_group`): the film is bit for bit the one of passes rendered one
/// at a time, with the same rays, in fewer and larger caster calls.
#[test]
fn grouped_passes_make_the_same_film_in_fewer_caster_calls() {
    let scene = cornell_box();
    let caster = BvhCaster::new(&scene);
    for integrator in [IntegratorKind::Light, IntegratorKind::Bdpt, IntegratorKind::Lvc] {
        let opts = RenderOptions {
            width: 16,
            height: 12,
            budget: Budget::Samples(5),
            integrator,
            seed: 9,
            max_depth: 6,
            ..Default::default()
        };
        let (grouped, stats) = render(&scene, &caster, &opts, |_, _| true).unwrap();
        let mut one = Renderer::new(&scene, &caster, &opts).unwrap();
        assert!(one.pass_group() >= 5, "{}: a 16x12 image should group its passes", integrator.name());
        let mut film = one.film().unwrap();
        let rays: usize = (0..5).map(|p| one.pass(p, &mut film).rays).sum();
        let (_, calls, _) = one.ray_counts();
        let name = integrator.name();
        assert_eq!((grouped.passes, stats.rays), (film.passes, rays as u64), "{name}: passes and rays");
        assert!(
            grouped.sum == film.sum && grouped.splat == film.splat && grouped.sum_sq == film.sum_sq,
            "{name}: film"
        );
        assert!(
            stats.cast_calls * 3 <= calls,
            "{name}: {} grouped calls against {calls} one pass at a time",
            stats.cast_calls
        );
    }
}
