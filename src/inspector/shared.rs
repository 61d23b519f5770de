//! What the render worker and the UI share: the image, the error curves, the analysis
//! records, behind one mutex.

use crate::cast::pdacrt::LevelRecord;
use crate::render::cis::QueueRecord;
use glam::Vec3;
use simt::KernelSummary;
use std::sync::Mutex;

/// One render's error curve.
#[derive(Clone, Debug, Default)]
pub struct Series {
    /// What the render was: `integrator / caster: scene, size, max depth`.
    pub label: String,
    /// (seconds, RMSE against the reference)
    pub points: Vec<(f64, f64)>,
}

/// What the worker shares with the UI.
#[derive(Default)]
pub struct Shared {
    /// The mean image so far.
    pub image: Vec<Vec3>,
    /// Image width.
    pub width: u32,
    /// Image height.
    pub height: u32,
    /// Passes done.
    pub passes: u32,
    /// Whether the worker is busy (analysing, rendering the reference, or rendering).
    pub running: bool,
    /// What the worker is doing, with its progress.
    pub status: String,
    /// While the worker prepares a render (loading, analyses, the reference): the
    /// current step's progress from 0 to 1; `None` otherwise.
    pub progress: Option<f32>,
    /// Error curves, one per render since the inspector started.
    pub series: Vec<Series>,
    /// PDACRT's levels on the primary rays.
    pub levels: Vec<LevelRecord>,
    /// Per pixel: PDACRT terminal nodes that tested its primary ray.
    pub visits: Vec<u32>,
    /// The scene's camera (to draw level boxes over the image).
    pub camera: Option<crate::scene::Camera>,
    /// CIS-LBDPT queue records of the last pass rendered.
    pub queues: Vec<QueueRecord>,
    /// Material names of the scene, by index (for the queue panel).
    pub material_names: Vec<String>,
    /// `cis::shade` SIMD efficiency of one pass, unsorted and sorted.
    pub sorting_effect: Option<(f64, f64)>,
    /// Kernels of the chosen render's own device (PDACRT casting, CIS-LBDPT); empty
    /// when the render runs nothing on one.
    pub kernels: Vec<KernelSummary>,
    /// Kernels of the analysis before the render (PDACRT on the primary rays, one CIS
    /// pass sorted), kept apart from the render's.
    pub analysis_kernels: Vec<KernelSummary>,
    pub(super) references: Vec<(String, u32, Vec<Vec3>)>,
}

pub(super) fn lock(s: &Mutex<Shared>) -> std::sync::MutexGuard<'_, Shared> {
    s.lock().unwrap_or_else(|e| e.into_inner())
}
