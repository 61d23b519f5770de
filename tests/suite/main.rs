//! The integration tests, as one test binary with a module per subject: after a
//! change the suite links once instead of once per file, and all its tests share the
//! machine's cores instead of waiting for each file's slowest test. Run one subject
//! with a filter on its module: `cargo test --profile suite --test suite dacrt::`.

mod common;

mod bad_input;
mod bsdf;
mod bsdf_energy;
mod bsdf_reference;
mod bvh_robust;
mod bvh_vs_brute;
mod cis;
mod cis_twin;
mod cli;
mod dacrt;
mod dacrt_leaf;
mod direct;
mod embree;
mod filter_mode;
mod gpu;
mod gpu_render;
mod gpu_time;
mod hygiene;
mod import_graph;
mod inspector;
mod integrators;
mod lvc;
mod mitsuba;
mod mitsuba_bsdfs;
mod mitsuba_plastic;
mod optics;
mod outputs;
mod pdacrt_weights;
mod point_light;
mod reference;
mod render;
mod render_casters;
mod rooms;
mod seeds;
mod shared_arithmetic;
mod strategies;
