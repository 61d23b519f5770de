//! Every integrator with every caster on one scene: render time, rays cast, seconds
//! inside the caster and ray–triangle tests, and each time over the BVH's for the same
//! integrator. Every integrator casts wavefronts (one batch per bounce, one per
//! connection stage); this shows what the structure-free casters cost there.
//!
//! ```text
//! cargo run --release --example integrator_casters -- [--scene cornell|FILE.toml] [--size 64] [--spp 4]
//!     [--integrators path,light,bdpt,lvc,cis] [--casters bvh,dacrt,pdacrt] [--repeat 3] [--json]
//! ```

use clap::Parser;
use warpray::prelude::*;

#[derive(Parser)]
struct Args {
    /// `cornell` (built in) or a scene file (e.g. assets/scenes/bunny.toml; its models
    /// come from $WARPRAY_MODELS).
    #[arg(long, default_value = "cornell")]
    scene: String,
    #[arg(long, default_value_t = 64, value_parser = clap::value_parser!(u32).range(1..=4096))]
    size: u32,
    #[arg(long, default_value_t = 4, value_parser = clap::value_parser!(u32).range(1..=65536))]
    spp: u32,
    #[arg(long, value_delimiter = ',', default_values_t = ["path".to_string(), "light".into(), "bdpt".into(), "lvc".into(), "cis".into()])]
    integrators: Vec<String>,
    #[arg(long, value_delimiter = ',', default_values_t = CasterKind::all().iter().filter(|&&c| c != CasterKind::Brute).map(|c| format!("{c:?}").to_lowercase()))]
    casters: Vec<String>,
    /// Renders per cell; the fastest counts.
    #[arg(long, default_value_t = 3, value_parser = clap::value_parser!(u32).range(1..=100))]
    repeat: u32,
    #[arg(long)]
    json: bool,
}

fn run(a: Args) -> Result<()> {
    let scene = if a.scene == "cornell" { cornell_box() } else { warpray::scene::load_scene(&a.scene)?.scene };
    let title = if a.scene == "cornell" { "Cornell box".to_string() } else { a.scene.clone() };
    let kinds: Vec<CasterKind> = a
        .casters
        .iter()
        .map(|c| {
            <CasterKind as clap::ValueEnum>::from_str(c, true)
                .map_err(|_| Error::BadSetting(format!("unknown caster {c}")))
        })
        .collect::<Result<_>>()?;
    let integrators: Vec<IntegratorKind> = a.integrators.iter().map(|s| s.parse()).collect::<Result<_>>()?;
    if !a.json {
        println!("# {title}, {0}x{0}, {1} spp, {2} threads\n", a.size, a.spp, rayon::current_num_threads());
        println!("| integrator | caster | render ms | × bvh | rays | cast s (summed) | tests/ray |");
        println!("|---|---|---:|---:|---:|---:|---:|");
    }
    for integ in integrators {
        let mut bvh_ms = None;
        for &k in &kinds {
            let caster = k.build(&scene)?;
            let opts = RenderOptions {
                width: a.size,
                height: a.size,
                budget: Budget::Samples(a.spp),
                integrator: integ,
                ..Default::default()
            };
            let mut best: Option<RenderStats> = None;
            for _ in 0..a.repeat {
                let (_, st) = render(&scene, caster.as_ref(), &opts, |_, _| true)?;
                if best.as_ref().is_none_or(|b| st.seconds < b.seconds) {
                    best = Some(st);
                }
            }
            let st = best.expect("repeat >= 1");
            let ms = st.seconds * 1e3;
            let ratio = ms / *bvh_ms.get_or_insert(ms);
            let (name, cname) = (integ.name(), caster.name());
            if a.json {
                println!(
                    "{{\"integrator\":\"{name}\",\"caster\":\"{cname}\",\"size\":{},\"spp\":{},\"threads\":{},\"render_ms\":{ms:.3},\"ratio_to_bvh\":{ratio:.3},\"rays\":{},\"cast_seconds\":{:.4},\"untimed_rays\":{},\"tests\":{}}}",
                    a.size,
                    a.spp,
                    rayon::current_num_threads(),
                    st.rays,
                    st.cast_seconds,
                    st.single_rays,
                    st.tests
                );
            } else {
                // Rays cast one at a time from kernel threads (the megakernel's) are
                // not timed: their seconds are in the render's, not the caster's.
                let untimed =
                    if st.single_rays > 0 { format!(" ({} rays untimed)", st.single_rays) } else { String::new() };
                println!(
                    "| {name} | {cname} | {ms:.1} | {ratio:.2} | {} | {:.3}{untimed} | {:.1} |",
                    st.rays,
                    st.cast_seconds,
                    st.tests as f64 / st.rays.max(1) as f64
                );
            }
        }
    }
    Ok(())
}

fn main() {
    if let Err(e) = run(Args::parse()) {
        eprintln!("error: {e}");
        std::process::exit(1);
    }
}
