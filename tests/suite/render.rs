//! End-to-end rendering: determinism across thread counts, an analytic direct-lighting
//! case, and the example scene files.

use crate::common::*;
use warpray::cast::{BruteForce, BvhCaster, RayCaster};
use warpray::film::Film;
use warpray::glam::Vec3;
use warpray::render::{Budget, RenderOptions, render};
use warpray::scene::{Camera, Material, PointLight, cornell_box, load_scene};

fn small(spp: u32) -> RenderOptions {
    RenderOptions { width: 48, height: 48, budget: Budget::Samples(spp), ..Default::default() }
}

fn render_with_threads(threads: usize, opts: &RenderOptions) -> Film {
    let scene = cornell_box();
    let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
    pool.install(|| {
        let caster = BvhCaster::new(&scene);
        render(&scene, &caster, opts, |_, _| true).unwrap().0
    })
}

#[test]
fn same_seed_gives_the_same_image_at_any_thread_count() {
    let opts = RenderOptions { seed: 42, ..small(3) };
    let one = render_with_threads(1, &opts);
    let two = render_with_threads(2, &opts);
    let three = render_with_threads(3, &opts);
    assert!(
        one.sum.iter().zip(&two.sum).all(|(a, b)| a.to_array().map(f32::to_bits) == b.to_array().map(f32::to_bits))
    );
    assert!(one.sum.iter().zip(&three.sum).all(|(a, b)| a == b));
    // And a different seed gives a different image (the test can fail).
    let other = render_with_threads(2, &RenderOptions { seed: 43, ..small(3) });
    assert!(one.sum.iter().zip(&other.sum).any(|(a, b)| a != b));
}

#[test]
fn cornell_box_renders_lit_and_finite_with_every_caster() {
    let scene = cornell_box();
    let casters: [Box<dyn RayCaster>; 2] = [Box::new(BvhCaster::new(&scene)), Box::new(BruteForce::new(&scene))];
    let mut means = Vec::new();
    for c in &casters {
        let (film, stats) = render(&scene, c.as_ref(), &small(4), |_, _| true).unwrap();
        assert_eq!(film.passes, 4);
        assert_eq!(film.rejected, 0);
        assert!(film.sum.iter().all(|v| v.is_finite() && v.min_element() >= 0.0));
        assert!(stats.rays > 48 * 48 * 4);
        means.push(film.image_mean());
    }
    // Same seed, same hits: the casters give the same image.
    assert!((means[0] - means[1]).abs().max_element() < 1e-6, "{means:?}");
    assert!(means[0].min_element() > 0.02, "{:?}", means[0]);
}

/// A diffuse plane lit by a point light straight above it, seen through a very
/// narrow camera: radiance is albedo/π · I/d² (direct lighting only).
#[test]
fn point_light_on_a_diffuse_plane_matches_the_analytic_radiance() {
    let big = 100.0;
    let mut scene = scene_from_triangles(&[
        [Vec3::new(-big, -big, 0.0), Vec3::new(big, -big, 0.0), Vec3::new(big, big, 0.0)],
        [Vec3::new(-big, -big, 0.0), Vec3::new(big, big, 0.0), Vec3::new(-big, big, 0.0)],
    ]);
    let albedo = 0.5;
    scene.materials[0] = Material::Diffuse { albedo: Vec3::splat(albedo) };
    let (intensity, height) = (3.0, 1.5);
    scene.point_lights.push(PointLight { position: Vec3::new(0.0, 0.0, height), intensity: Vec3::splat(intensity) });
    scene.camera = Camera::look_at(Vec3::new(0.0, 0.0, 4.0), Vec3::ZERO, Vec3::Y, 0.5);
    let caster = BvhCaster::new(&scene);
    let opts = RenderOptions { max_depth: 1, ..small(2) };
    let (film, _) = render(&scene, &caster, &opts, |_, _| true).unwrap();
    let want = albedo / std::f32::consts::PI * intensity / (height * height);
    let got = film.image_mean();
    // The view spans ±0.017 units: cos³ falloff there is below 1e-3.
    assert!(((got.x - want) / want).abs() < 2e-3, "got {got}, want {want}");
    // With max_depth 0 nothing but directly seen emitters remains: black.
    let (film, _) = render(&scene, &caster, &RenderOptions { max_depth: 0, ..small(1) }, |_, _| true).unwrap();
    assert_eq!(film.image_mean(), Vec3::ZERO);
}

#[test]
fn progressive_rendering_can_stop_early_and_by_time() {
    let scene = cornell_box();
    let caster = BvhCaster::new(&scene);
    let (film, _) = render(&scene, &caster, &small(100), |pass, _| pass < 3).unwrap();
    assert_eq!(film.passes, 3);
    let opts = RenderOptions { budget: Budget::Seconds(0.05), ..small(1) };
    let (film, stats) = render(&scene, &caster, &opts, |_, _| true).unwrap();
    assert!(film.passes >= 1 && stats.seconds >= 0.05);
}

#[test]
fn example_scene_files_load_and_render() {
    require_model("cornell-box");
    require_model("bunny");
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("assets/scenes");
    let desc = load_scene(root.join("cornell-obj.toml")).unwrap();
    assert_eq!(desc.scene.triangle_count(), 36);
    assert_eq!(desc.settings.spp, Some(64));
    let short = desc.scene.material_names.iter().position(|n| n == "shortBox").unwrap();
    assert!(matches!(desc.scene.materials[short], Material::Glossy { .. }));
    let light = desc.scene.material_names.iter().position(|n| n == "light").unwrap();
    assert_eq!(desc.scene.emission[light], Vec3::new(17.0, 12.0, 4.0));

    let bunny = load_scene(root.join("bunny.toml")).unwrap();
    assert_eq!(bunny.scene.triangle_count(), 32 + 69_451);
    assert_eq!(bunny.scene.point_lights.len(), 1);
    for d in [desc, bunny] {
        let caster = BvhCaster::new(&d.scene);
        let (film, _) = render(&d.scene, &caster, &small(2), |_, _| true).unwrap();
        assert_eq!(film.rejected, 0);
        assert!(film.image_mean().min_element() > 0.0);
    }
}

#[test]
fn built_in_scenes_load_by_name_and_render() {
    for (name, text) in warpray::scene::NAMED_SCENES {
        // Each names its model; a missing one fails loudly here.
        let model = text.lines().find_map(|l| l.strip_prefix("file = \"")).unwrap().split('"').next().unwrap();
        require_model(model.trim_end_matches(".obj.gz"));
        let desc = load_scene(name).unwrap_or_else(|e| panic!("{name}: {e}"));
        desc.scene.check_renderable().unwrap_or_else(|e| panic!("{name}: {e}"));
        assert!(desc.settings.spp.is_some(), "{name}: a [render] block");
        let caster = BvhCaster::new(&desc.scene);
        let opts = RenderOptions { width: 16, height: 12, budget: Budget::Samples(1), ..Default::default() };
        let (film, _) = render(&desc.scene, &caster, &opts, |_, _| true).unwrap();
        assert_eq!(film.rejected, 0, "{name}");
        assert!(film.image_mean().max_element() > 0.0, "{name}: a black image");
    }
    // A name that is neither a file, a built-in scene nor a model says what it tried.
    let e = load_scene("no-such-scene").unwrap_err().to_string();
    assert!(e.contains("built-in scene") && e.contains("dragon") && e.contains("WARPRAY_MODELS"), "{e}");
}

#[test]
fn a_scenes_unit_normals_follow_the_winding_and_are_zero_for_degenerate_triangles() {
    // The normals a render reads at its hits (`Scene::unit_normals`), against the cross
    // product worked out in f64.
    let v = Vec3::new;
    let tris = [
        [v(0.0, 0.0, 0.0), v(1.0, 0.0, 0.0), v(0.0, 1.0, 0.0)],
        [v(0.0, 0.0, 0.0), v(0.0, 1.0, 0.0), v(1.0, 0.0, 0.0)],
        [v(3.0, -2.0, 7.5), v(-1.25, 4.0, 0.5), v(2.0, 2.0, -6.0)],
        [v(1e4, 1e4, 1e4), v(1e4 + 0.01, 1e4, 1e4), v(1e4, 1e4 + 0.02, 1e4 + 0.03)],
        [v(1.0, 1.0, 1.0), v(2.0, 2.0, 2.0), v(3.0, 3.0, 3.0)],
        [v(5.0, 5.0, 5.0), v(5.0, 5.0, 5.0), v(5.0, 5.0, 5.0)],
    ];
    let scene = scene_from_triangles(&tris);
    let normals = scene.unit_normals();
    assert_eq!(normals.len(), tris.len());
    for (i, (t, n)) in tris.iter().zip(&normals).enumerate() {
        assert_eq!(*n, scene.unit_normal(i as u32), "triangle {i}");
        let d = |p: Vec3, q: Vec3| [(q.x - p.x) as f64, (q.y - p.y) as f64, (q.z - p.z) as f64];
        let (e1, e2) = (d(t[0], t[1]), d(t[0], t[2]));
        let c = [e1[1] * e2[2] - e1[2] * e2[1], e1[2] * e2[0] - e1[0] * e2[2], e1[0] * e2[1] - e1[1] * e2[0]];
        let len = (c[0] * c[0] + c[1] * c[1] + c[2] * c[2]).sqrt();
        if len == 0.0 {
            assert_eq!(*n, Vec3::ZERO, "degenerate triangle {i}");
        } else {
            for k in 0..3 {
                assert!((n[k] as f64 - c[k] / len).abs() < 1e-4, "triangle {i}: {n} against {c:?} / {len}");
            }
        }
    }
    assert_eq!(normals[0], Vec3::Z);
    assert_eq!(normals[1], -Vec3::Z);
}
