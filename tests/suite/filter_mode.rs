//! Camera samples splatted through the filter and normalised (`FilterMode::Splat`,
//! Mitsuba 3's film) against filter importance sampling (`FilterMode::Sample`) and
//! against images known without the renderer.

use crate::common::*;
use warpray::cast::BvhCaster;
use warpray::film::Film;
use warpray::filter::{Filter, FilterMode, pixel_offset};
use warpray::glam::{Vec2, Vec3};
use warpray::render::{Budget, IntegratorKind, RenderOptions, render};
use warpray::scene::{Scene, cornell_box};

/// A film of `passes` passes whose camera samples see the radiance `l(film position)`.
fn film_of(l: impl Fn(Vec2) -> f32, filter: Filter, (w, h): (u32, u32), passes: u32, seed: u64) -> Film {
    let mut film = Film::new(w, h).unwrap().with_filter(filter, FilterMode::Splat, seed);
    for pass in 0..passes {
        let est: Vec<Vec3> = (0..w * h)
            .map(|p| {
                let pos = Vec2::new((p % w) as f32, (p / w) as f32) + pixel_offset(seed, p, pass);
                Vec3::splat(l(pos))
            })
            .collect();
        film.add_pass(pass, &est);
    }
    film
}

/// For a linear image and a symmetric filter, the filtered value of an interior pixel
/// is the image at the pixel's centre: the splatted estimator must converge there.
/// A gradient in x and y catches a sample's weight given to the wrong neighbour or
/// one offset weighted wrongly (each shifts the pixel toward one side).
#[test]
fn a_linear_image_is_reconstructed_at_pixel_centres() {
    let (w, h) = (40, 40);
    let l = |p: Vec2| 1.0 + 0.25 * p.x + 0.125 * p.y;
    let film = film_of(l, Filter::mitsuba_gaussian(), (w, h), 256, 3);
    let mean = film.mean();
    // Interior pixels (the filter's reach from every border): error against the centre.
    let errors: Vec<f64> = (2..h - 2)
        .flat_map(|y| (2..w - 2).map(move |x| (x, y)))
        .map(|(x, y)| (mean[(y * w + x) as usize].x - l(Vec2::new(x as f32 + 0.5, y as f32 + 0.5))) as f64)
        .collect();
    let (m, se) = statistics(&errors);
    // Per pixel the error is noise (each pixel's sample positions are random); over
    // 1,296 pixels its mean must vanish within a few standard errors, and the standard
    // error itself is small against the gradient (one pixel's shift would be 0.25).
    assert!(m.abs() < 4.0 * se + 1e-4, "mean error {m:.5} ± {se:.5}");
    assert!(se < 2e-3, "standard error {se}");
    // Border pixels receive samples from one side only and are normalised by what they
    // received: still finite, positive and between the image's extremes there.
    assert!(mean.iter().all(|v| v.x.is_finite() && v.x >= l(Vec2::ZERO) && v.x <= l(Vec2::new(40.0, 40.0))));
}

/// For a quadratic image, the filtered value of an interior pixel is the image at its
/// centre plus the filter's variance (per axis): this checks the filter's width, which
/// a linear image cannot see. The variance is computed here by quadrature of
/// [`Filter::eval`], not by the code under test.
#[test]
fn a_quadratic_image_is_blurred_by_the_filter_variance() {
    let f = Filter::mitsuba_gaussian();
    let n = 4000;
    let (mut m0, mut m2) = (0.0f64, 0.0f64);
    for i in 0..n {
        let x = -2.0 + 4.0 * (i as f32 + 0.5) / n as f32;
        let v = f.eval(Vec2::new(x, 0.0)) as f64;
        (m0, m2) = (m0 + v, m2 + v * (x * x) as f64);
    }
    let var = m2 / m0;
    let (w, h, c) = (12, 12, 6.0f32);
    let l = |p: Vec2| (p.x - c).powi(2) + (p.y - c).powi(2);
    let film = film_of(l, f, (w, h), 4096, 5);
    let mean = film.mean();
    let errors: Vec<f64> = (2..h - 2)
        .flat_map(|y| (2..w - 2).map(move |x| (x, y)))
        .map(|(x, y)| {
            let centre = l(Vec2::new(x as f32 + 0.5, y as f32 + 0.5)) as f64;
            mean[(y * w + x) as usize].x as f64 - (centre + 2.0 * var)
        })
        .collect();
    let (m, se) = statistics(&errors);
    eprintln!("variance {var:.5}; mean error {m:.5} ± {se:.5}");
    assert!(m.abs() < 4.0 * se, "mean error {m:.5} ± {se:.5} (filter variance {var:.4})");
    // Power: a filter 5 % too wide or narrow moves the value by about 0.1 × 2var.
    assert!(4.0 * se < 0.1 * 2.0 * var, "standard error {se} too large to see the filter's width");
}

/// With the box filter both modes are one estimator: the same samples, the same image.
#[test]
fn with_the_box_filter_splatting_equals_sampling() {
    let scene = cornell_box();
    let caster = BvhCaster::new(&scene);
    let run = |mode| {
        let opts = RenderOptions {
            width: 32,
            height: 32,
            budget: Budget::Samples(4),
            filter: Filter::Box,
            filter_mode: mode,
            ..Default::default()
        };
        render(&scene, &caster, &opts, |_, _| true).unwrap().0.mean()
    };
    let (a, b) = (run(FilterMode::Sample), run(FilterMode::Splat));
    let worst =
        a.iter().zip(&b).map(|(x, y)| (*x - *y).abs().max_element() / x.max_element().max(1e-3)).fold(0.0, f32::max);
    assert!(worst < 1e-5, "largest relative difference {worst}");
}

/// Every integrator splats the same image at one and at two threads.
#[test]
fn splatted_renders_are_deterministic_across_thread_counts() {
    let scene = glossy_glass_box();
    let caster = BvhCaster::new(&scene);
    for kind in IntegratorKind::ALL {
        let opts = RenderOptions {
            width: 20,
            height: 20,
            budget: Budget::Samples(2),
            integrator: kind,
            filter: Filter::mitsuba_gaussian(),
            filter_mode: FilterMode::Splat,
            ..Default::default()
        };
        let run = |threads| {
            let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
            pool.install(|| render(&scene, &caster, &opts, |_, _| true).unwrap().0)
        };
        let (a, b) = (run(1), run(2));
        assert!(
            a.sum == b.sum && a.weight == b.weight && a.splat == b.splat,
            "{}: 1 and 2 threads differ",
            kind.name()
        );
    }
}

fn modes_agree(filter: Filter) {
    let scene: Scene = cornell_box();
    let caster = BvhCaster::new(&scene);
    let size = 24;
    let interior = |film: &Film| {
        let m = film.mean();
        let px: Vec<f64> = (2..size - 2)
            .flat_map(|y| (2..size - 2).map(move |x| (x, y)))
            .map(|(x, y)| warpray::film::luminance(m[(y * size + x) as usize]) as f64)
            .collect();
        let black = px.iter().filter(|&&v| v == 0.0).count();
        assert_eq!(black, 0, "{filter:?}: {black} black interior pixels");
        px.iter().sum::<f64>() / px.len() as f64
    };
    let means = |mode| -> Vec<f64> {
        (0..8)
            .map(|seed| {
                let opts = RenderOptions {
                    width: size,
                    height: size,
                    budget: Budget::Samples(192),
                    max_depth: 4,
                    seed,
                    filter,
                    filter_mode: mode,
                    ..Default::default()
                };
                interior(&render(&scene, &caster, &opts, |_, _| true).unwrap().0)
            })
            .collect()
    };
    let (a, sa) = statistics(&means(FilterMode::Sample));
    let (b, sb) = statistics(&means(FilterMode::Splat));
    let z = (a - b) / (sa * sa + sb * sb).sqrt();
    eprintln!("{filter:?}: sample {a:.5} ± {sa:.5}, splat {b:.5} ± {sb:.5} (z = {z:.2})");
    assert!(z.abs() < 4.0, "{filter:?}: sample {a:.5} ± {sa:.5}, splat {b:.5} ± {sb:.5} (z = {z:.2})");
    // The comparison has power: the standard errors are under 1 % of the mean.
    assert!(sa.max(sb) < 0.01 * a, "{filter:?}: standard errors {sa}, {sb} against {a}");
}

/// The heavy tier (README, docs/testing.md): tests that need many samples for their
/// power, run by CI and before a release rather than before every commit.
mod heavy {
    use super::*;

    /// Both modes estimate the same filtered image: on the Cornell box, the interior mean
    /// over independent seeds agrees within the standard error, with Mitsuba's Gaussian
    /// and with one wide against its radius (σ = 10, r = 2, which in `sample` mode left
    /// 28 % of pixels black when offsets came from the unrestricted Gaussian).
    #[test]
    #[ignore = "heavy tier, run by CI: cargo test --profile suite --workspace --features inspector,cuda,embree --test suite -- --ignored ::heavy::"]
    fn splatting_and_sampling_converge_to_the_same_image() {
        for filter in [Filter::mitsuba_gaussian(), Filter::gaussian(10.0, 2.0).unwrap()] {
            modes_agree(filter);
        }
    }
}
