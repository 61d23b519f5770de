//! What the whole-render GPU examples (`gpu_render`, `gpu_convergence`) share: the
//! scenes and integrators they compare, and one integrator's render options.

use warpray::render::{RenderOptions, Variant};
use warpray::scene::{Scene, load_scene};

/// The scenes, integrators and image of a comparison.
#[derive(clap::Args)]
pub struct Common {
    /// Scenes: cornell, white-room, bedroom, or scene files (comma-separated).
    #[arg(long, value_delimiter = ',', default_value = "cornell,white-room,bedroom")]
    pub scenes: Vec<String>,
    /// Integrators (labels of `warpray render --integrator`): lvc-mk and the cis variants;
    /// the first is the baseline of the speed-ups.
    #[arg(long, value_delimiter = ',', default_value = "lvc-mk,cis,cis-nosort")]
    pub integrators: Vec<String>,
    /// Image side in pixels.
    #[arg(long, default_value_t = 512, value_parser = clap::value_parser!(u32).range(8..=4096))]
    pub size: u32,
    /// Longest path, in bounces.
    #[arg(long, default_value_t = 8, value_parser = clap::value_parser!(u32).range(1..=30))]
    pub max_depth: u32,
}

/// Scene `name` (the two rooms by name, or a scene file or built-in scene).
pub fn load(name: &str) -> Result<Scene, String> {
    let path = match name {
        "white-room" | "bedroom" => format!("assets/scenes/{name}.toml"),
        other => other.to_string(),
    };
    load_scene(path).map(|d| d.scene).map_err(|e| e.to_string())
}

/// The options of integrator `label` with `seed`, CIS-LBDPT's pool of `pool` samples
/// in flight (0: one slot per pixel).
pub fn options(c: &Common, label: &str, seed: u64, pool: u32) -> Result<RenderOptions, String> {
    let mut o = Variant::parse(label).map_err(|e| e.to_string())?.apply(RenderOptions {
        width: c.size,
        height: c.size,
        max_depth: c.max_depth,
        seed,
        ..Default::default()
    });
    o.cis.pool = if pool == 0 { c.size * c.size } else { pool };
    Ok(o)
}
