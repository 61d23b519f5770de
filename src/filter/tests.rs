//! The filters' tests: integrals, sampling, Mitsuba's table values, splats.

use super::*;

#[test]
fn gaussian_integrates_to_one_and_sampling_is_unbiased() {
    // Mitsuba's default, pbrt's, and the ends of the accepted range: the narrowest
    // σ, a σ wide against its radius (10 on 2 left 28 % of pixels black when
    // samples came from the unrestricted Gaussian), the widest σ, the widest radius.
    for (stddev, radius) in [(0.5, 2.0), (0.5, 1.5), (0.01, 0.5), (10.0, 2.0), (32.0, 2.0), (2.0, 16.0)] {
        check_gaussian(Filter::gaussian(stddev, radius).unwrap(), radius);
    }
    // Mitsuba's stepped table, at its default σ and a wider one.
    check_gaussian(Filter::mitsuba_gaussian(), 2.0);
    check_gaussian(Filter::mitsuba(1.5).unwrap(), 6.0);
}

/// A splat gives every pixel whose centre lies within the radius the product of the
/// 1-D weights at its offsets, and no other pixel: against every pixel of the image
/// evaluated directly, for the narrowest, the default and the widest radius (33
/// columns), the stepped table, and positions near and past the image's edges.
#[test]
fn a_splat_weighs_every_pixel_the_filter_reaches() {
    let filters = [
        Filter::gaussian(0.2, 0.5).unwrap(),
        Filter::gaussian(0.5, 2.0).unwrap(),
        Filter::gaussian(6.0, MAX_RADIUS).unwrap(),
        Filter::mitsuba_gaussian(),
    ];
    let (w, h) = (48u32, 40u32);
    let mut r = crate::sampling::Rng::for_sample(31, 0, 0);
    for f in filters {
        for _ in 0..200 {
            let p = Vec2::new(r.uniform() * 60.0 - 6.0, r.uniform() * 52.0 - 6.0);
            let mut got = vec![0.0f32; (w * h) as usize];
            f.splat(p, w, h, |i, wt| got[i as usize] += wt);
            for y in 0..h {
                for x in 0..w {
                    let c = Vec2::new(x as f32 + 0.5, y as f32 + 0.5);
                    let want = f.eval_1d(p.y - c.y) * f.eval_1d(p.x - c.x);
                    let i = (y * w + x) as usize;
                    assert_eq!(got[i].to_bits(), want.max(0.0).to_bits(), "{f:?} at {p}, pixel ({x}, {y})");
                }
            }
        }
    }
}

/// Mitsuba 3.9.1's own values of its default Gaussian as its film evaluates it
/// (`mi.load_dict({'type': 'gaussian'}).eval_discretized(x)`, `scalar_rgb`), against
/// the stepped filter before its normalisation; and the exact Gaussian's values
/// (`eval(x)`) against the filter without steps. Mitsuba's `exp` is an approximation
/// (its `eval(0)` is 0.99925, where 1 − exp(−8) is 0.99966), so values agree to
/// 1e-3; the steps move values by up to 0.05 (0.927 against 0.882 at x = 0.25).
#[test]
fn the_stepped_gaussian_gives_mitsubas_table_values() {
    let stepped = Filter::mitsuba_gaussian();
    let exact = Filter::gaussian(0.5, 2.0).unwrap();
    let raw = |f: &Filter, x: f32| match *f {
        Filter::Gaussian { integral, .. } => f.eval_1d(x) * integral,
        Filter::Box => unreachable!(),
    };
    let mitsuba_table =
        [(0.25, 0.927_349_87), (0.5, 0.664_956_6), (1.0, 0.153_261_32), (1.9, 0.000_574_584_6), (2.0, 0.0)];
    for (x, want) in mitsuba_table {
        assert!((raw(&stepped, x) - want).abs() < 1e-3, "x = {x}: {} against {want}", raw(&stepped, x));
        assert!((raw(&stepped, -x) - want).abs() < 1e-3, "x = -{x}");
    }
    let mitsuba_exact = [(0.25, 0.882_166_74), (0.5, 0.606_423), (1.0, 0.134_960_49), (1.5, 0.010_758_21)];
    for (x, want) in mitsuba_exact {
        assert!((raw(&exact, x) - want).abs() < 1e-3, "x = {x}: {} against {want}", raw(&exact, x));
    }
}

fn check_gaussian(f: Filter, r: f32) {
    // The normalised 2-D filter integrates to 1 (midpoint rule).
    let n = 400;
    let h = 2.0 * r / n as f32;
    let mut total = 0.0f64;
    for i in 0..n {
        for j in 0..n {
            let d = Vec2::new(-r + (i as f32 + 0.5) * h, -r + (j as f32 + 0.5) * h);
            total += (f.eval(d) * h * h) as f64;
        }
    }
    // (The midpoint rule on a filter narrower than its cells is coarse: σ = 0.01
    // on cells of 0.0025.)
    assert!((total - 1.0).abs() < 2e-3, "{f:?}: integral {total}");
    // E[w] = ∫h = 1 and E[w · g(x)] = ∫h g for a test function g (here x², whose
    // filtered value is the filter's variance, computed by quadrature).
    let mut var = 0.0f64;
    for i in 0..n {
        let x = -r + (i as f32 + 0.5) * h;
        var += (f.eval_1d(x) * x * x * h) as f64;
    }
    let m = 1 << 18;
    let (mut sw, mut sg) = (0.0f64, 0.0f64);
    for k in 0..m {
        // A low-discrepancy pair (golden-ratio lattice), deterministic.
        let u = Vec2::new((k as f32 + 0.5) / m as f32, ((k as f64 * 0.618_033_988_75).fract()) as f32);
        let (p, w) = f.sample(0, 0, u);
        let d = p - Vec2::splat(0.5);
        sw += w as f64;
        sg += (w * d.x * d.x) as f64;
    }
    assert!((sw / m as f64 - 1.0).abs() < 2e-3, "{f:?}: mean weight {}", sw / m as f64);
    assert!((sg / m as f64 - var).abs() < 2e-3 * var.max(0.01), "{f:?}: {} vs {var}", sg / m as f64);
    // Every pixel gets most of its samples: at most 1 − 2/π (36 %) have weight 0.
    let zero = (0..4096).filter(|&k| f.sample(0, 0, Vec2::new((k as f32 + 0.5) / 4096.0, 0.37)).1 == 0.0).count();
    assert!(zero < 4096 * 37 / 100, "{f:?}: {zero} of 4096 samples weigh nothing");
}

#[test]
fn splat_weights_sum_to_one_inside_the_image() {
    // The sum over pixel centres of a unit-integral filter: close to 1, not equal
    // (σ = 0.5 is narrow for a unit grid: the sum moves by about ±3 % with the
    // sub-pixel position, ±6 % in Mitsuba's steps; the continuous integral, which
    // the estimators use, is 1).
    for (f, within) in [(Filter::gaussian(0.5, 2.0).unwrap(), 0.04), (Filter::mitsuba_gaussian(), 0.06)] {
        for p in [Vec2::new(5.3, 7.9), Vec2::new(10.0, 10.0), Vec2::new(6.51, 3.49)] {
            let mut sum = 0.0;
            f.splat(p, 20, 20, |_, w| sum += w);
            assert!((sum - 1.0).abs() < within, "{f:?} at {p}: {sum}");
        }
    }
    let mut hits = Vec::new();
    Filter::Box.splat(Vec2::new(3.5, 1.2), 4, 2, |i, w| hits.push((i, w)));
    assert_eq!(hits, vec![(7, 1.0)]);
    // Outside the image (beyond the margin) nothing is touched.
    let mut none = true;
    Filter::mitsuba_gaussian().splat(Vec2::new(-3.0, 5.0), 20, 20, |_, _| none = false);
    assert!(none);
}

#[test]
fn parses_and_refuses() {
    assert_eq!("box".parse::<Filter>(), Ok(Filter::Box));
    assert!(matches!("gaussian:0.5:1.5".parse::<Filter>(), Ok(Filter::Gaussian { radius, .. }) if radius == 1.5));
    assert!("gaussian:0:2".parse::<Filter>().is_err());
    assert!("gaussian:0.5:1e9".parse::<Filter>().is_err());
    // σ the sampler cannot weigh in f32 (1e8 and 1e-8 gave all-black images).
    for bad in ["gaussian:1e8:2", "gaussian:1e-8:2", "gaussian:33:2", "gaussian:0.009:1"] {
        let e = bad.parse::<Filter>().unwrap_err();
        assert!(e.contains("stddev") && e.contains("must lie in"), "{bad}: {e}");
    }
    assert!("tent".parse::<Filter>().is_err());
}

/// A camera sample's rows of weights (the exact Gaussian's by its recurrence, where it
/// is used) against the filter evaluated at each pixel centre: within 1e-6 of the
/// filter's peak, at sub-pixel positions over the whole pixel, for Mitsuba's σ and
/// radius, the ends of the accepted range and the stepped filters. Planted: the step's
/// factor × 1.001 gives errors of 6e-4 of the peak (Mitsuba's σ).
#[test]
fn a_camera_samples_weights_are_the_filters_values() {
    let filters = [(0.5, 2.0), (0.5, 1.5), (0.01, 0.5), (10.0, 2.0), (32.0, 2.0), (2.0, 16.0), (0.1, 2.0)]
        .map(|(s, r)| Filter::gaussian(s, r).unwrap());
    let mut recurrences = 0;
    for f in filters.into_iter().chain([Filter::mitsuba_gaussian(), Filter::Box]) {
        let prepared = f.prepared();
        recurrences += prepared.gaussian_rows.is_some() as u32;
        let k = f.splat_reach() as usize;
        let n = 2 * k + 1;
        let (mut wx, mut wy) = (vec![0.0; n], vec![0.0; n]);
        let peak = f.eval_1d(0.0);
        for i in 0..97 {
            let p = Vec2::new(40.0 + i as f32 / 97.0, 17.0 + ((i * 31) % 97) as f32 / 97.0);
            prepared.splat_weights(p, &mut wx, &mut wy);
            for (j, (&x, &y)) in wx.iter().zip(&wy).enumerate() {
                let centre = |c: f32| c.floor() + (j as f32 - k as f32) + 0.5;
                let (ex, ey) = (f.eval_1d(p.x - centre(p.x)), f.eval_1d(p.y - centre(p.y)));
                let close = (x - ex).abs() <= 1e-6 * peak && (y - ey).abs() <= 1e-6 * peak;
                assert!(close, "{f:?} at {p}, {j}: ({x}, {y}) against ({ex}, {ey})");
            }
        }
    }
    // Not the narrowest (σ = 0.01 and 0.1: factors past a float's range), the widest
    // against their radius (σ = 10 and 32 on 2, where the value at the radius is 98 %
    // of the peak) nor the widest radius (16: rows of 33 values).
    assert_eq!(recurrences, 2, "the recurrence serves the other exact Gaussians");
}
