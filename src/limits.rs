//! Limits shared by the scene loaders and the renderer, kept below both so that
//! neither has to import the other for them.

/// Longest time budget a render accepts, seconds (about 116 days; a `Duration` of
/// 1e30 s does not exist).
pub const MAX_SECONDS: f64 = 1.0e7;

/// Longest full path (light and camera vertices together) the bidirectional
/// integrators handle: `max_depth + 2` vertices, so the deepest `max_depth` every
/// integrator supports is `MAX_PATH_VERTICES - 2`.
pub const MAX_PATH_VERTICES: usize = 64;
