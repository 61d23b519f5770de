//! BDPT's images of the two test boxes, rendered once per run of the suite and shared by
//! every test that compares an integrator with BDPT there (`integrators`, `lvc`, `cis`):
//! each used to render its own, at 6 to 16 samples per pixel.

use crate::common::glossy_glass_box;
use crate::seeds::{Runs, runs};
use std::collections::HashMap;
use std::sync::{Arc, Mutex, OnceLock};
use warpray::cast::BvhCaster;
use warpray::render::{Budget, IntegratorKind, RenderOptions, render};
use warpray::scene::{Scene, cornell_box};

/// The image side, samples per pixel, path depth and first seed of the reference.
pub const SIZE: u32 = 32;
pub const SPP: u32 = 16;
pub const MAX_DEPTH: u32 = 8;
const BASE_SEED: u64 = 0;

/// A box the reference is rendered for.
#[derive(Clone, Copy, PartialEq, Eq, Hash, Debug)]
pub enum TestBox {
    Cornell,
    GlossyGlass,
}

impl TestBox {
    pub fn scene(self) -> Scene {
        match self {
            TestBox::Cornell => cornell_box(),
            TestBox::GlossyGlass => glossy_glass_box(),
        }
    }
}

/// BDPT over 16 seeds (`seeds.rs`) at [`SIZE`]², [`SPP`] samples per pixel, depth
/// [`MAX_DEPTH`], 8×8 blocks. Tests that ask for the same box share one rendering; the
/// first to ask renders it while the others wait.
pub fn bdpt(which: TestBox) -> Arc<Runs> {
    type Cells = HashMap<TestBox, Arc<OnceLock<Arc<Runs>>>>;
    static CACHE: Mutex<Option<Cells>> = Mutex::new(None);
    let cell = {
        let mut cache = CACHE.lock().unwrap_or_else(|e| e.into_inner());
        cache.get_or_insert_with(HashMap::new).entry(which).or_default().clone()
    };
    cell.get_or_init(|| {
        let scene = which.scene();
        let caster = BvhCaster::new(&scene);
        Arc::new(runs("bdpt", BASE_SEED, SIZE as usize, 8, |seed| {
            let opts = RenderOptions {
                width: SIZE,
                height: SIZE,
                budget: Budget::Samples(SPP),
                max_depth: MAX_DEPTH,
                integrator: IntegratorKind::Bdpt,
                seed,
                ..Default::default()
            };
            let (film, _) = render(&scene, &caster, &opts, |_, _| true).unwrap();
            assert_eq!(film.rejected, 0, "bdpt: non-finite samples");
            film.mean()
        }))
    })
    .clone()
}
