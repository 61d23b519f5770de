//! The path tracer's hits on Lambertian surfaces, shaded [`WIDTH`] at a time on the
//! CPU's SIMD lanes: structure of arrays in, one loop, structure of arrays out.
//!
//! A group's hits are gathered one by one ([`Group::push`]: the scene's reads, the
//! light's choice, the path's random numbers), then one loop runs the scalar shading's
//! own steps (`shade.rs`: emission, next-event estimation, the BSDF sample and Russian
//! roulette) for every lane, with nothing that leaves the loop early, so that the
//! compiler turns the loop into vector instructions; the results go back to the paths
//! one by one. The loop is compiled three times, for AVX-512 (16 lanes a register),
//! AVX2 (8) and x86-64's baseline SSE2 (4), and the CPU's widest is chosen at run time.
//! Each lane performs the scalar code's operations in its order, and Rust never fuses
//! a multiply and an add, so every lane's answer is the scalar one bit for bit
//! (`tests::lanes_shade_as_one_path_at_a_time_does`): the image does not depend on
//! which hits went through the lanes, nor on the CPU.

use super::shade::{brings, continue_path, emitter_density, next_event, with_emission};
use super::state::{Bounce, PathState, Shadow};
use crate::bsdf::TransportMode;
use crate::geometry::packet_lanes::Width;
use crate::geometry::{Hit, Ray, barycentric_point};
use crate::lights::{Light, LightSample, area_point};
use crate::render::context::Context;
use crate::sampling::Frame;
use crate::scene::Material;
use glam::{Vec2, Vec3};

/// Hits a group holds: one AVX-512 register of `f32` per quantity.
pub(super) const WIDTH: usize = 16;

type Lane = [f32; WIDTH];
type Flags = [bool; WIDTH];

/// A vector quantity of every lane, by coordinate.
#[derive(Clone, Copy, Default)]
struct Vec3s {
    x: Lane,
    y: Lane,
    z: Lane,
}

impl Vec3s {
    #[inline(always)]
    fn get(&self, k: usize) -> Vec3 {
        Vec3::new(self.x[k], self.y[k], self.z[k])
    }
    #[inline(always)]
    fn set(&mut self, k: usize, v: Vec3) {
        (self.x[k], self.y[k], self.z[k]) = (v.x, v.y, v.z);
    }
}

/// What the lanes read: per lane one path's state, its hit and its light sample's
/// ingredients.
#[derive(Default)]
pub(super) struct Inputs {
    corners: [Vec3s; 3],
    /// The hit's barycentric weights of corners 1 and 2, and its distance.
    u: Lane,
    v: Lane,
    t: Lane,
    ng: Vec3s,
    albedo: Vec3s,
    /// The material is black seen from behind ([`crate::scene::Scene::bsdf_facing`]).
    one_sided: Flags,
    emitted: Vec3s,
    /// Light sampling's area density at the hit (zero where the triangle emits nothing).
    pdf_area: Lane,
    // The path.
    dir: Vec3s,
    throughput: Vec3s,
    radiance: Vec3s,
    prev_pdf: Lane,
    prev_delta: Flags,
    eta2: Lane,
    // The random numbers of the light's point, the BSDF's direction and the roulette.
    u_light: [Lane; 2],
    u_dir: [Lane; 2],
    u_rr: Lane,
    // The light chosen: its triangle's corners (a point light's position thrice), and
    // its sample without the point.
    light: Flags,
    light_corners: [Vec3s; 3],
    light_normal: Vec3s,
    light_emitted: Vec3s,
    light_pdf: Lane,
    light_delta: Flags,
}

/// What the lanes write: the path's new state and its shadow ray.
#[derive(Default)]
pub(super) struct Outputs {
    radiance: Vec3s,
    throughput: Vec3s,
    prev_pdf: Lane,
    prev_delta: Flags,
    eta2: Lane,
    alive: Flags,
    origin: Vec3s,
    dir: Vec3s,
    shadow: Flags,
    shadow_origin: Vec3s,
    shadow_dir: Vec3s,
    shadow_t_max: Lane,
    shadow_l: Vec3s,
}

/// The albedo of this path's hit when the lanes take its bounce: a hit on a
/// non-degenerate triangle whose material is Lambertian, on a bounce that goes on past
/// its emission; `None` for a bounce shaded one path at a time.
#[inline]
pub(super) fn diffuse_albedo(ctx: &Context, bounce: Bounce, hit: &Hit) -> Option<Vec3> {
    if bounce.last || !hit.is_hit() || ctx.normal(hit.prim) == Vec3::ZERO {
        return None;
    }
    match *ctx.scene.material(hit.prim) {
        Material::Diffuse { albedo } => Some(albedo),
        _ => None,
    }
}

/// Up to [`WIDTH`] diffuse hits gathered for the lanes, by their paths' indices.
pub(super) struct Group {
    inputs: Box<Inputs>,
    outputs: Box<Outputs>,
    paths: [u32; WIDTH],
    len: usize,
    kernel: Kernel,
}

/// The lanes' loop compiled for one extension: unsafe to call where the CPU lacks it.
pub(super) type Kernel = unsafe fn(&Inputs, Bounce, &mut Outputs);

/// The lanes' loop for every vector extension this CPU has, widest first, by name.
pub(super) fn kernels() -> impl Iterator<Item = (&'static str, Kernel)> {
    let all: [(&str, Option<Width>, Kernel); 3] = [
        ("AVX-512", Some(Width::Avx512), shade_avx512),
        ("AVX2", Some(Width::Avx2), shade_avx2),
        ("SSE2", None, shade_baseline),
    ];
    all.into_iter().filter(|k| k.1.is_none_or(Width::supported)).map(|(name, _, kernel)| (name, kernel))
}

impl Group {
    /// An empty group, with the loop for this CPU's widest vector extension.
    pub(super) fn new() -> Group {
        Group::with_kernel(kernels().next().expect("SSE2 is x86-64's baseline").1)
    }

    /// An empty group whose lanes run `kernel`, one of [`kernels`].
    pub(super) fn with_kernel(kernel: Kernel) -> Group {
        Group { inputs: Box::default(), outputs: Box::default(), paths: [0; WIDTH], len: 0, kernel }
    }

    /// Whether the group has a hit in every lane.
    pub(super) fn is_full(&self) -> bool {
        self.len == WIDTH
    }

    /// Gathers path `index`'s bounce into the next lane (its hit's `albedo`, from
    /// [`diffuse_albedo`]): reads the scene, draws the path's random numbers (as
    /// [`super::shade::shade`] draws them) and picks its light.
    pub(super) fn push(
        &mut self,
        ctx: &Context,
        bounce: Bounce,
        index: usize,
        p: &mut PathState,
        hit: &Hit,
        albedo: Vec3,
    ) {
        let (scene, i, k) = (ctx.scene, &mut *self.inputs, self.len);
        let prim = hit.prim;
        for (c, v) in i.corners.iter_mut().zip(scene.vertices(prim)) {
            c.set(k, v);
        }
        (i.u[k], i.v[k], i.t[k]) = (hit.u, hit.v, hit.t);
        i.ng.set(k, ctx.normal(prim));
        i.albedo.set(k, albedo);
        i.one_sided[k] = !scene.two_sided[scene.material_of[prim as usize] as usize];
        let le = scene.emission_of(prim);
        i.emitted.set(k, le);
        i.pdf_area[k] = emitter_density(ctx, prim, le);
        i.dir.set(k, p.ray.dir);
        i.throughput.set(k, p.throughput);
        i.radiance.set(k, p.radiance);
        (i.prev_pdf[k], i.prev_delta[k], i.eta2[k]) = (p.prev_pdf, p.prev_delta, p.eta2);

        // The light sample's numbers, then the BSDF's (its lobe number, which a
        // Lambertian lobe does not read, and its direction), then the roulette's.
        let u_select = p.rng.uniform();
        let u_light = p.rng.uniform2();
        let _u_lobe = p.rng.uniform();
        let u_dir = p.rng.uniform2();
        i.u_rr[k] = if bounce.roulette { p.rng.uniform() } else { 0.0 };
        [i.u_light[0][k], i.u_light[1][k]] = u_light.to_array();
        [i.u_dir[0][k], i.u_dir[1][k]] = u_dir.to_array();

        i.light[k] = false;
        if let Some((light, p_sel)) = ctx.lights.pick(u_select) {
            let (corners, position) = match *light {
                Light::Area { tri, .. } => (scene.vertices(tri), Vec3::ZERO),
                Light::Point { position, .. } => ([position; 3], position),
            };
            let ls = light.sample_at(position, p_sel);
            for (c, v) in i.light_corners.iter_mut().zip(corners) {
                c.set(k, v);
            }
            i.light_normal.set(k, ls.normal);
            i.light_emitted.set(k, ls.emitted);
            (i.light[k], i.light_pdf[k], i.light_delta[k]) = (true, ls.pdf, ls.is_delta);
        }
        self.paths[k] = index as u32;
        self.len += 1;
    }

    /// Shades the group's hits on the lanes and gives each path its new state and
    /// shadow; the group is then empty.
    pub(super) fn shade(&mut self, bounce: Bounce, paths: &mut [PathState], shadows: &mut [Shadow]) {
        if self.len == 0 {
            return;
        }
        // SAFETY: the kernel is one of `kernels()`, those for extensions this CPU has.
        unsafe { (self.kernel)(&self.inputs, bounce, &mut self.outputs) };
        let o = &*self.outputs;
        for (k, &index) in self.paths[..self.len].iter().enumerate() {
            let p = &mut paths[index as usize];
            p.radiance = o.radiance.get(k);
            p.throughput = o.throughput.get(k);
            (p.prev_pdf, p.prev_delta, p.eta2, p.alive) = (o.prev_pdf[k], o.prev_delta[k], o.eta2[k], o.alive[k]);
            if p.alive {
                p.ray = Ray::new(o.origin.get(k), o.dir.get(k));
            }
            shadows[index as usize] = o.shadow[k].then(|| {
                (Ray::segment(o.shadow_origin.get(k), o.shadow_dir.get(k), o.shadow_t_max[k]), o.shadow_l.get(k))
            });
        }
        self.len = 0;
    }
}

/// [`shade_lanes`] compiled for AVX-512. Call only on a CPU with AVX-512F.
#[target_feature(enable = "avx512f")]
fn shade_avx512(i: &Inputs, bounce: Bounce, o: &mut Outputs) {
    shade_lanes(i, bounce, o)
}

/// [`shade_lanes`] compiled for AVX2. Call only on a CPU with AVX2.
#[target_feature(enable = "avx2")]
fn shade_avx2(i: &Inputs, bounce: Bounce, o: &mut Outputs) {
    shade_lanes(i, bounce, o)
}

/// [`shade_lanes`] for x86-64's baseline (SSE2). Safe everywhere; unsafe only to share
/// the [`Kernel`] type.
unsafe fn shade_baseline(i: &Inputs, bounce: Bounce, o: &mut Outputs) {
    shade_lanes(i, bounce, o)
}

/// Every lane's bounce: [`super::shade::shade`]'s steps after its reads, for a
/// Lambertian material. (Lanes past the group's end shade zeros; nothing reads them.)
#[inline(always)]
fn shade_lanes(i: &Inputs, bounce: Bounce, o: &mut Outputs) {
    for k in 0..WIDTH {
        let mut p = PathState {
            pixel: 0,
            rng: Default::default(),
            ray: Ray::new(Vec3::ZERO, i.dir.get(k)),
            throughput: i.throughput.get(k),
            radiance: i.radiance.get(k),
            prev_pdf: i.prev_pdf[k],
            eta2: i.eta2[k],
            prev_delta: i.prev_delta[k],
            alive: true,
        };
        let ng = i.ng.get(k);
        let pos = barycentric_point([i.corners[0].get(k), i.corners[1].get(k), i.corners[2].get(k)], i.u[k], i.v[k]);
        let wo = -p.ray.dir.normalize();
        p.radiance = with_emission(&p, bounce, i.emitted.get(k), ng, wo, i.t[k], i.pdf_area[k]);

        let frame = Frame::from_normal(ng);
        let wo_local = frame.to_local(wo);
        // `Scene::bsdf_facing` for a Lambertian material (never a dielectric).
        let albedo = if wo_local.z < 0.0 && i.one_sided[k] { Vec3::ZERO } else { i.albedo.get(k) };
        let material = Material::Diffuse { albedo };
        let corners = [i.light_corners[0].get(k), i.light_corners[1].get(k), i.light_corners[2].get(k)];
        let ls = LightSample {
            position: if i.light_delta[k] {
                corners[0]
            } else {
                area_point(corners, Vec2::new(i.u_light[0][k], i.u_light[1][k]))
            },
            normal: i.light_normal.get(k),
            emitted: i.light_emitted.get(k),
            pdf: i.light_pdf[k],
            is_delta: i.light_delta[k],
            tri: 0,
        };
        let shadow = next_event(&material, &frame, wo_local, pos, ng, p.throughput, &ls);
        let u_dir = Vec2::new(i.u_dir[0][k], i.u_dir[1][k]);
        let sample = material.sample_f_inlined(wo_local, 0.0, u_dir, TransportMode::Radiance);
        continue_path(&mut p, sample.map(|s| (s, material.eta(wo_local, s.wi))), &frame, pos, ng, bounce, i.u_rr[k]);

        o.radiance.set(k, p.radiance);
        o.throughput.set(k, p.throughput);
        (o.prev_pdf[k], o.prev_delta[k], o.eta2[k], o.alive[k]) = (p.prev_pdf, p.prev_delta, p.eta2, p.alive);
        o.origin.set(k, p.ray.origin);
        o.dir.set(k, p.ray.dir);
        o.shadow[k] = i.light[k] && brings(&shadow);
        let (ray, l) = shadow;
        o.shadow_origin.set(k, ray.origin);
        o.shadow_dir.set(k, ray.dir);
        o.shadow_t_max[k] = ray.t_max;
        o.shadow_l.set(k, l);
    }
}
