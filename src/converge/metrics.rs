//! What `converge` measures: the error metrics against a reference image, and one
//! checkpoint of an integrator's progress.

use glam::Vec3;

/// Root-mean-square error over all pixels and channels.
pub fn rmse(image: &[Vec3], reference: &[Vec3]) -> f64 {
    // In f64: the difference of two large f32 values (3e38) overflows f32 when squared.
    let sum: f64 = image.iter().zip(reference).map(|(a, b)| (a.as_dvec3() - b.as_dvec3()).length_squared()).sum();
    (sum / (3 * image.len().max(1)) as f64).sqrt()
}

/// Relative MSE: mean of `(x − r)² / (r² + 0.01)` over pixels and channels.
pub fn relmse(image: &[Vec3], reference: &[Vec3]) -> f64 {
    relmse_eps(image, reference, 0.01)
}

/// Relative MSE with offset `eps`: mean of `(x − r)² / (r² + eps)`.
pub fn relmse_eps(image: &[Vec3], reference: &[Vec3], eps: f64) -> f64 {
    let sum: f64 = image
        .iter()
        .zip(reference)
        .map(|(a, b)| {
            let (d, r) = ((*a - *b).as_dvec3(), b.as_dvec3());
            (d * d / (r * r + eps)).element_sum()
        })
        .sum();
    sum / (3 * image.len().max(1)) as f64
}

/// One measurement of one integrator's progress.
#[derive(Clone, Debug, PartialEq)]
pub struct Checkpoint {
    /// The variant's label.
    pub integrator: &'static str,
    /// Rendering time so far (error evaluation excluded).
    pub seconds: f64,
    /// Passes done.
    pub spp: u32,
    /// Root-mean-square error against the reference.
    pub rmse: f64,
    /// Relative MSE against the reference (offset as in [`relmse_eps`]).
    pub relmse: f64,
}
