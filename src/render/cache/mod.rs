//! The light vertex cache (Davidovič et al. 2014) that LVC-BDPT, its megakernel and
//! CIS-LBDPT share: its host half (the cache, MIS counts, the wavefront light pass, the
//! strategies at a camera vertex) and its device half (the cache in device memory and
//! its kernels).

pub(crate) mod device;
pub mod host;
pub(crate) mod kernels;
#[cfg(test)]
mod tests;

pub use host::{Connections, LightVertexCache, MAX_CANDIDATES, StrategyCounts};
