//! Every integrator with every caster: the render counts the rays it cast, whichever
//! caster answers them, and since every caster returns the same hits (distance,
//! triangle, barycentrics), the images and ray counts are identical.

use warpray::prelude::*;

#[test]
fn every_integrator_counts_the_same_rays_and_makes_the_same_image_with_every_caster() {
    let scene = cornell_box();
    for integrator in
        [IntegratorKind::Path, IntegratorKind::Light, IntegratorKind::Bdpt, IntegratorKind::Lvc, IntegratorKind::Cis]
    {
        let opts = RenderOptions {
            width: 12,
            height: 12,
            budget: Budget::Samples(2),
            integrator,
            seed: 3,
            ..Default::default()
        };
        let mut first: Option<(Vec<Vec3>, RenderStats)> = None;
        for kind in [CasterKind::Bvh, CasterKind::Dacrt, CasterKind::Pdacrt, CasterKind::Brute] {
            let caster = kind.build(&scene);
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
