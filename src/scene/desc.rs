//! What a loaded scene file gives besides its scene: the render settings it asks for,
//! and the line a byte of its text is on (for errors). The floor under the scene-file
//! readers (`file.rs` for TOML, `mitsuba/` for XML) and the loader that picks one.

use super::data::Scene;
use serde::Deserialize;

/// Render settings a scene file may carry; command-line flags override them.
#[derive(Clone, Debug, Default, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct RenderSettings {
    /// Image width.
    pub width: Option<u32>,
    /// Image height.
    pub height: Option<u32>,
    /// Samples per pixel.
    pub spp: Option<u32>,
    /// Time budget, seconds.
    pub seconds: Option<f64>,
    /// Largest number of bounces.
    pub max_depth: Option<u32>,
    /// Bounces before the path tracer's Russian roulette starts (`rr_depth`, ≥ 1).
    pub rr_depth: Option<u32>,
    /// Integrator name.
    pub integrator: Option<String>,
    /// Random seed.
    pub seed: Option<u64>,
    /// Pixel filter: `"box"`, `"gaussian"` or `"gaussian:STDDEV:RADIUS"` (`rfilter`).
    #[serde(default, deserialize_with = "parse_text")]
    pub filter: Option<crate::filter::Filter>,
    /// How camera samples meet the filter: `"sample"` or `"splat"` (Mitsuba's).
    #[serde(default, deserialize_with = "parse_text")]
    pub filter_mode: Option<crate::filter::FilterMode>,
}

fn parse_text<'de, D: serde::Deserializer<'de>, T: std::str::FromStr<Err = String>>(
    d: D,
) -> std::result::Result<Option<T>, D::Error> {
    let text = String::deserialize(d)?;
    text.parse().map(Some).map_err(serde::de::Error::custom)
}

/// A loaded scene and the settings its file asked for.
#[derive(Clone, Debug)]
pub struct SceneDesc {
    /// The scene.
    pub scene: Scene,
    /// The `[render]` block, if any.
    pub settings: RenderSettings,
}

/// The 1-based line of byte `offset` in `text` (scene-file and XML errors).
pub(crate) fn line_of(text: &str, offset: usize) -> usize {
    text[..offset.min(text.len())].bytes().filter(|&b| b == b'\n').count() + 1
}
