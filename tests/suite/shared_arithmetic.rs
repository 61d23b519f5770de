//! The arithmetic that BSDF code declares for `simt`'s model (`src/cost.rs`), counted by
//! hand from the rule and checked on one warp: a lane-uniform warp executes every
//! declared instruction with all 32 lanes, and a warp split between two materials issues
//! the shared prefix once and each material's arm for its own lanes. Without the cargo
//! feature `model-arithmetic` (which `cuda`, and so the README's test command, turns on)
//! the declarations compile to nothing, and that is what is checked instead.

#![cfg_attr(not(feature = "model-arithmetic"), allow(dead_code))]

use glam::Vec3;
use simt::{Device, DeviceConfig};
use warpray::bsdf::TransportMode;
use warpray::scene::Material;

// The rule's weights (src/cost.rs), restated: the test counts by hand from them.
const BRANCH: u64 = 2;
const DIV: u64 = 10;
const SQRT: u64 = 10;
const V3: u64 = 3;
const DOT: u64 = 5;
const NORMALIZE_OR_ZERO: u64 = DOT + SQRT + DIV + 3 + 4;

/// `Material::f` before its match: the rough-glass test, the two-sided flip and the
/// hemisphere tests, the match's branch.
const PREFIX: u64 = BRANCH + (3 * BRANCH + 2) + BRANCH;
/// The diffuse arm.
const DIFFUSE_ARM: u64 = V3;

/// GGX `lambda` for a direction off the horizon.
const LAMBDA: u64 = (1 + BRANCH) + (7 + DIV + SQRT);
/// GGX `d` for a normal above the horizon.
const D: u64 = BRANCH + 7 + DIV;
/// `reflection`: the side tests, the half vector, the value's and density's own
/// arithmetic, then D and Λ(ωo) once each, G2 (with Λ(ωi)) and the visible density
/// (with G1).
const REFLECTION: u64 = 2 * BRANCH
    + (V3 + NORMALIZE_OR_ZERO + 4)
    + (4 + DIV + DOT + 1 + DIV)
    + D
    + LAMBDA
    + (2 + DIV + LAMBDA)
    + (DOT + 3 + DIV + (1 + DIV));
/// Fresnel of a conductor: per channel 29 operations, two roots and two divisions.
const FRESNEL_CONDUCTOR: u64 = 4 + 3 * (29 + 2 * SQRT + 2 * DIV);
/// The rough conductor's arm.
const CONDUCTOR_ARM: u64 = REFLECTION + (DOT + V3) + FRESNEL_CONDUCTOR;

fn warp_of(materials: impl Fn(usize) -> Material + Sync) -> (u64, u64) {
    let dev = Device::new(DeviceConfig { measure: true, ..Default::default() });
    let (wo, wi) = (Vec3::new(0.3, 0.1, 0.9).normalize(), Vec3::new(-0.2, 0.4, 0.8).normalize());
    let rec = dev.for_each_in("bsdf::f", PARTS, 32, |t, i| {
        t.ambient(0, || {
            std::hint::black_box(materials(i).f(wo, wi, TransportMode::Radiance));
        })
    });
    // The declared arithmetic, without the loads of the material's fields (counted in
    // the next test).
    let all = rec.all_regions();
    let (issued, active) = (all.issued - rec.loads.requests, all.active - rec.loads.lanes);
    // Each declaration lands in its part's region: the BSDF's dispatch in `bsdf`, GGX
    // and Fresnel in `microfacet`, nothing elsewhere.
    let part = |name: &str| rec.regions.iter().find(|r| r.name == name).map_or(0, |r| r.issued);
    assert_eq!(part("bsdf") + part("microfacet"), issued, "{:?}", rec.regions);
    (issued, active)
}

/// The regions of the code's parts, as `cis::shade` names them after its arithmetic
/// region (`warpray::cost::Part`).
const PARTS: &[&str] = &["kernel", "microfacet", "bsdf", "bidirectional", "sampling", "lights"];

fn diffuse() -> Material {
    Material::Diffuse { albedo: Vec3::splat(0.5) }
}

fn conductor() -> Material {
    Material::Conductor { eta: Vec3::new(0.2, 0.9, 1.1), k: Vec3::new(3.9, 2.4, 2.2), roughness: 0.3 }
}

#[cfg(feature = "model-arithmetic")]
#[test]
fn a_uniform_warp_executes_every_declared_instruction_with_all_lanes() {
    assert_eq!(warp_of(|_| diffuse()), (PREFIX + DIFFUSE_ARM, 32 * (PREFIX + DIFFUSE_ARM)));
    assert_eq!(warp_of(|_| conductor()), (PREFIX + CONDUCTOR_ARM, 32 * (PREFIX + CONDUCTOR_ARM)));
}

#[cfg(feature = "model-arithmetic")]
#[test]
fn a_warp_split_between_materials_issues_each_arm_for_its_own_lanes() {
    let (issued, active) = warp_of(|i| if i < 16 { diffuse() } else { conductor() });
    assert_eq!(active, 16 * (PREFIX + DIFFUSE_ARM) + 16 * (PREFIX + CONDUCTOR_ARM));
    assert_eq!(issued, PREFIX + DIFFUSE_ARM + CONDUCTOR_ARM);
}

/// The scene reads a BSDF records (`cost::declare!(.., reads ..)`): the diffuse arm of
/// `Material::f` loads its material's kind and albedo, four 4-byte loads, each one warp
/// request; the lanes that read one material share each load's sector, so a warp split
/// between two materials touches two sectors per load.
#[cfg(feature = "model-arithmetic")]
#[test]
fn a_bsdf_loads_the_words_it_reads_of_its_material_one_sector_per_material() {
    let materials = [diffuse(), Material::Diffuse { albedo: Vec3::splat(0.25) }];
    assert!(std::mem::size_of::<Material>() >= 32, "two materials' kinds must lie in different sectors");
    let (wo, wi) = (Vec3::new(0.3, 0.1, 0.9).normalize(), Vec3::new(-0.2, 0.4, 0.8).normalize());
    let loads = |pick: &(dyn Fn(usize) -> usize + Sync)| {
        let dev = Device::new(DeviceConfig { measure: true, ..Default::default() });
        let rec = dev.for_each_in("bsdf::f", PARTS, 32, |t, i| {
            t.ambient(0, || {
                std::hint::black_box(materials[pick(i)].f(wo, wi, TransportMode::Radiance));
            })
        });
        (rec.loads.requests, rec.loads.sectors, rec.loads.lanes)
    };
    assert_eq!(loads(&|_| 0), (4, 4, 4 * 32));
    assert_eq!(loads(&|i| i / 16), (4, 8, 4 * 32));
}

#[test]
fn outside_a_kernel_the_declarations_do_nothing() {
    // Host code: the same call, no ambient lane; and a measured launch that does not
    // make its lanes ambient records no arithmetic.
    let (wo, wi) = (Vec3::Z, Vec3::new(0.0, 0.6, 0.8));
    let host = conductor().f(wo, wi, TransportMode::Radiance);
    assert!(host.max_element() > 0.0);
    let dev = Device::new(DeviceConfig { measure: true, ..Default::default() });
    let rec = dev.for_each_in("bsdf::f", PARTS, 32, |_t, _i| {
        std::hint::black_box(conductor().f(wo, wi, TransportMode::Radiance));
    });
    assert_eq!((rec.all_regions().issued, rec.all_regions().active), (0, 0));
}

/// Every CIS-LBDPT kernel that runs code it shares with the CPU integrators (a camera
/// sample, starting a light subpath, shading a light vertex, splatting light vertices,
/// shading a camera vertex) counts that code's declared arithmetic as its lanes' own, as
/// the GPU twins execute it; a launch whose lanes are not ambient would count none.
#[cfg(feature = "model-arithmetic")]
#[test]
fn every_cis_kernel_that_runs_shared_code_counts_its_arithmetic() {
    use warpray::render::{Budget, IntegratorKind, RenderOptions, Renderer};
    let scene = warpray::scene::cornell_box();
    let caster = warpray::cast::BvhCaster::new(&scene);
    let mut opts = RenderOptions {
        width: 16,
        height: 16,
        budget: Budget::Samples(1),
        integrator: IntegratorKind::Cis,
        max_depth: 4,
        ..Default::default()
    };
    opts.cis.measure = true;
    let mut r = Renderer::new(&scene, &caster, &opts).unwrap();
    let mut film = r.film().unwrap();
    r.passes(0, 1, &mut film);
    let log = r.device().unwrap().launch_log();
    for name in ["cis::generate", "cis::light_generate", "cis::light_shade", "cis::light_splat", "cis::shade"] {
        let launches = log.iter().filter(|l| l.name == name).count();
        let arithmetic: u64 = log
            .iter()
            .filter(|l| l.name == name)
            .flat_map(|l| l.regions.iter())
            .filter(|g| g.name.starts_with("arithmetic"))
            .map(|g| g.issued)
            .sum();
        assert!(launches > 0 && arithmetic > 0, "{name}: {launches} launches, {arithmetic} arithmetic instructions");
    }
}

/// Runs `f` below `depth` extra stack frames of 256 bytes: a value copied onto the stack
/// inside `f` lies at another address for each depth.
#[inline(never)]
fn at_depth(depth: usize, f: &dyn Fn()) {
    if depth == 0 {
        return f();
    }
    let pad = std::hint::black_box([0u8; 256]);
    at_depth(depth - 1, f);
    std::hint::black_box(pad);
}

/// A layered material's BSDF reads its coats and base where the scene holds them, as
/// the GPU twin reads them from global memory: 32 lanes evaluating one material at 32
/// stack depths touch the sectors 32 lanes at one depth touch. (Matched by value, the
/// material was copied onto each worker's stack and its reads counted there: the
/// footprint then grew with the stack addresses the lanes ran at, and changed from run
/// to run with the threads.)
#[cfg(feature = "model-arithmetic")]
#[test]
fn a_layered_bsdf_reads_the_scenes_material_not_a_copy() {
    let coat = warpray::scene::Coat { ior: 1.5, roughness: 0.2, absorption: Vec3::new(0.1, 0.2, 0.3) };
    let base = warpray::scene::LayerBase::Diffuse { albedo: Vec3::splat(0.6) };
    let scene_materials =
        [Material::Layered(warpray::scene::Layered { coats: [coat; 2], coat_count: 2, base }), diffuse()];
    let footprint = |spread: bool| {
        let dev = Device::new(DeviceConfig { measure: true, ..Default::default() });
        dev.set_gpu_profile(Some(simt::GpuProfile::named("h200").unwrap()));
        let (wo, wi) = (Vec3::new(0.3, 0.1, 0.9).normalize(), Vec3::new(-0.2, 0.4, 0.8).normalize());
        let m = &scene_materials[0];
        dev.for_each_in("bsdf::layered", PARTS, 32, |t, i| {
            t.ambient(0, || {
                at_depth(if spread { i } else { 0 }, &|| {
                    std::hint::black_box(m.f(wo, wi, TransportMode::Radiance));
                    std::hint::black_box(m.sample_f(wo, 0.7, glam::Vec2::new(0.3, 0.6), TransportMode::Radiance));
                })
            })
        })
        .footprint_sectors
    };
    let (one, spread) = (footprint(false), footprint(true));
    assert!(one > 0);
    assert_eq!(spread, one, "32 stack depths touch {spread} sectors, one depth {one}");
}

#[cfg(not(feature = "model-arithmetic"))]
#[test]
fn without_the_feature_nothing_is_declared() {
    eprintln!(
        "model-arithmetic is off in this build: the known counts of BSDF arithmetic are \
         checked with `--features model-arithmetic` (or `cuda`); here only their absence"
    );
    assert_eq!(warp_of(|_| conductor()), (0, 0));
}
