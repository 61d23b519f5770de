//! The film's unit tests: splats' bookkeeping, parallel splats, EXR metadata.

use super::*;

/// Many splats, added by bands of rows in parallel, give the sums one thread gives
/// splat by splat, bit for bit: splats near and beyond every edge, invalid ones, a
/// wide Gaussian and the box filter, several thread counts.
#[test]
fn splats_added_in_parallel_give_the_serial_sums() {
    let mut rng = crate::sampling::Rng::for_sample(7, 0, 0);
    let (w, h) = (67, 93);
    let mut splats: Vec<(Vec2, Vec3)> = (0..40_000)
        .map(|_| {
            let p = Vec2::new(rng.uniform() * 80.0 - 6.0, rng.uniform() * 105.0 - 6.0);
            (p, Vec3::new(rng.uniform(), rng.uniform() * 3.0, rng.uniform() * 1e-3))
        })
        .collect();
    splats[5].1 = Vec3::NAN;
    splats[17].0 = Vec2::new(f32::INFINITY, 3.0);
    splats[29].1 = Vec3::new(-1.0, 0.0, 0.0);
    let wide = Filter::gaussian(1.5, 3.5).unwrap();
    for filter in [Filter::Box, Filter::mitsuba_gaussian(), Filter::gaussian(0.5, 2.0).unwrap(), wide] {
        let serial = {
            let mut film = Film::new(w, h).unwrap().with_filter(filter, FilterMode::Sample, 0);
            splats.iter().for_each(|&s| film.add_splats([s]));
            film
        };
        for threads in [2, 3, 8] {
            let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
            let mut film = Film::new(w, h).unwrap().with_filter(filter, FilterMode::Sample, 0);
            pool.install(|| film.add_splats(splats.iter().copied()));
            assert_eq!(film.rejected, 3);
            let differ = film.pass_splat.iter().zip(&serial.pass_splat).filter(|(a, b)| a != b).count();
            assert_eq!(differ, 0, "{filter:?}, {threads} threads: {differ} pixels differ");
        }
    }
}

/// Splats of several passes reach the image whatever the mode and however a pass
/// ends: each pixel's mean is its splats' sum over the passes (a box filter puts
/// each splat on one pixel with weight 1), during a pass too, and the per-pass
/// variance sees each pass's own splats.
#[test]
fn every_passes_splats_reach_the_mean_and_the_variance() {
    for mode in [FilterMode::Sample, FilterMode::Splat] {
        for ends_with_estimates in [true, false] {
            let mut film = Film::new(2, 1).unwrap().with_filter(Filter::Box, mode, 1);
            let mut want = [0.0f32; 2];
            for pass in 0..3u32 {
                let v = (pass + 1) as f32;
                film.add_splats([(Vec2::new(0.5, 0.5), Vec3::splat(v)), (Vec2::new(1.5, 0.5), Vec3::splat(2.0))]);
                want[0] += v;
                want[1] += 2.0;
                if pass > 0 {
                    // The mean in progress: every splat so far over the finished passes.
                    assert_eq!(film.mean()[0].x, want[0] / pass as f32, "{mode:?} pass {pass}: pending splats");
                }
                if ends_with_estimates {
                    film.add_pass(pass, &[Vec3::ZERO; 2]);
                } else {
                    film.end_pass();
                }
            }
            let mean = film.mean();
            assert_eq!([mean[0].x, mean[1].x], [want[0] / 3.0, want[1] / 3.0], "{mode:?}");
            // Pixel 0's passes gave 1, 2 and 3: sample variance 1; pixel 1's none.
            let var = film.variance();
            assert!((var[0].x - 1.0).abs() < 1e-5 && var[1].x.abs() < 1e-5, "{mode:?}: {var:?}");
        }
    }
}

#[test]
fn exr_metadata_round_trips_and_non_latin1_text_is_replaced() {
    let dir = std::env::temp_dir().join(format!("warpray-film-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("m.exr");
    let mut film = Film::new(3, 2).unwrap();
    film.add_pass(0, &[Vec3::ONE; 6]);
    film.add_splats([(Vec2::new(2.5, 1.5), Vec3::ONE)]);
    film.write_with(&path, 1.0, &[("spp", "1".into()), ("scene", "Ünïcode ∞ scene".into())]).unwrap();
    let m = read_exr_metadata(&path).unwrap();
    assert_eq!(m, vec![("scene".to_string(), "Ünïcode ? scene".to_string()), ("spp".to_string(), "1".to_string())]);
    // Without metadata there is none, and a non-EXR is an error naming the file.
    film.write(&path, 1.0).unwrap();
    assert!(read_exr_metadata(&path).unwrap().is_empty());
    std::fs::write(&path, b"not an exr").unwrap();
    let e = read_exr_metadata(&path).unwrap_err().to_string();
    assert!(e.contains("m.exr"), "{e}");
    std::fs::remove_dir_all(&dir).ok();
}
