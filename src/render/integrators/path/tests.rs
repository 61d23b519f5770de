//! The lanes against the scalar shading, path by path.

use super::lanes;
use super::shade::shade;
use super::shade_all;
use super::state::{Bounce, PathState, Shadow};
use crate::geometry::{Hit, Ray};
use crate::render::RenderOptions;
use crate::render::context::TestSetup;
use crate::sampling::{Rng, uniform_sphere};
use crate::scene::{Material, PointLight, cornell_box};
use glam::Vec3;

/// Paths from random points in the Cornell box in random directions, with random
/// state, and their hits. The box has a point light besides its area light, a glossy
/// block (shaded one path at a time, between diffuse hits), and one-sided walls (black
/// seen from behind; rays from points outside the box meet them from behind).
fn paths_and_hits(setup: &TestSetup, opts: &RenderOptions, n: usize) -> (Vec<PathState>, Vec<Hit>) {
    let ctx = setup.ctx(opts);
    let mut rng = Rng::for_sample(11, 0, 0);
    let paths: Vec<PathState> = (0..n as u32)
        .map(|pixel| {
            let origin = Vec3::new(2.4 * rng.uniform() - 1.2, 2.4 * rng.uniform() - 0.2, 2.4 * rng.uniform() - 1.2);
            let dir = uniform_sphere(rng.uniform2()) * (0.5 + rng.uniform());
            PathState {
                pixel,
                rng: Rng::for_sample(3, pixel as u64, 1),
                ray: Ray::new(origin, dir),
                throughput: Vec3::new(rng.uniform(), rng.uniform(), rng.uniform()) * 2.0,
                radiance: Vec3::splat(rng.uniform()),
                prev_pdf: 4.0 * rng.uniform(),
                eta2: 0.5 + rng.uniform(),
                prev_delta: rng.uniform() < 0.2,
                alive: true,
            }
        })
        .collect();
    let rays: Vec<Ray> = paths.iter().map(|p| p.ray).collect();
    let mut hits = vec![Hit::MISS; n];
    ctx.caster.closest(&rays, &mut hits);
    (paths, hits)
}

/// Every bounce kind (first, middle, last; with and without roulette), with the lanes'
/// loop of every vector extension this CPU has: the paths after
/// [`shade_all`] (diffuse hits through the lanes, the rest one at a time) are those
/// after [`shade`] alone, bit for bit, and so are their shadow rays. Planted errors,
/// each caught (docs/mutations.md): the lanes reading the hit's second barycentric
/// weight for its first, the roulette's number drawn before the light's, the one-sided
/// rule dropped, the light's area density left out of the emission's weight.
#[test]
fn lanes_shade_as_one_path_at_a_time_does() {
    let mut scene = cornell_box();
    let glossy = Material::Glossy { diffuse: Vec3::splat(0.3), specular: Vec3::splat(0.4), roughness: 0.2 };
    let block = scene.material_names.iter().position(|n| n == "tallBlock").unwrap();
    scene.materials[block] = glossy;
    let white = scene.material_names.iter().position(|n| n == "white").unwrap();
    scene.two_sided[white] = false;
    scene.point_lights.push(PointLight { position: Vec3::new(0.3, 1.7, 0.2), intensity: Vec3::splat(0.8) });
    let setup = TestSetup::new(&scene);
    let opts = RenderOptions { width: 16, height: 16, max_depth: 5, rr_depth: 2, ..Default::default() };
    let ctx = setup.ctx(&opts);
    let n = 12_000;
    let (start, hits) = paths_and_hits(&setup, &opts, n);
    // Every loop this CPU can run; the widest is what renders use.
    let kernels: Vec<_> = lanes::kernels().collect();
    let names: Vec<&str> = kernels.iter().map(|k| k.0).collect();
    if !names.contains(&"AVX-512") {
        eprintln!(
            "lanes_shade_as_one_path_at_a_time_does: no AVX-512 on this CPU; its loop is checked only where it runs"
        );
    }
    let mut seen = [0usize; 4]; // lanes, shadows, paths alive, one-sided lanes from behind
    for (name, kernel) in kernels {
        for depth in [0, 1, 3, 5] {
            let bounce = Bounce::new(depth, opts.max_depth, opts.rr_depth);
            let (mut one, mut lanes) = (start.clone(), start.clone());
            let one_shadows: Vec<Shadow> = one.iter_mut().zip(&hits).map(|(p, h)| shade(&ctx, bounce, p, h)).collect();
            let mut lane_shadows = vec![None; n];
            // Two runs of odd lengths, so that groups end part full.
            for range in [0..4_999, 4_999..n] {
                let group = &mut lanes::Group::with_kernel(kernel);
                shade_all(
                    &ctx,
                    bounce,
                    &mut lanes[range.clone()],
                    &hits[range.clone()],
                    &mut lane_shadows[range],
                    group,
                );
            }
            for (k, ((a, b), hit)) in one.iter().zip(&lanes).zip(&hits).enumerate() {
                let took = lanes::diffuse_albedo(&ctx, bounce, hit).is_some();
                let at = format!("{name}, path {k}, bounce {depth}");
                assert_eq!(a.alive, b.alive, "{at}: alive");
                let bits = |v: Vec3| v.to_array().map(f32::to_bits);
                assert_eq!(bits(a.radiance), bits(b.radiance), "{at}");
                if a.alive {
                    assert_eq!(a, b, "{at}");
                }
                assert_eq!(one_shadows[k], lane_shadows[k], "{at}: shadow");
                if name == names[0] {
                    seen[0] += took as usize;
                    seen[1] += one_shadows[k].is_some() as usize;
                    seen[2] += a.alive as usize;
                    let m = scene.material_of[hit.prim.min(scene.triangle_count() as u32 - 1) as usize] as usize;
                    seen[3] += (took && m == white && start[k].ray.dir.dot(ctx.normal(hit.prim)) > 0.0) as usize;
                }
            }
        }
    }
    // Not vacuous: most bounces went through the lanes, in many full groups, and the
    // cases the lanes must get right all occurred.
    let [took, shadows, alive, behind] = seen;
    assert!(took > 15_000, "{took} lanes");
    assert!(
        shadows > 10_000 && alive > 10_000 && behind > 100,
        "{shadows} shadows, {alive} alive, {behind} from behind"
    );
}
