//! Store footprints (`no_std`): what a photon leaves at a diffuse hit. The elliptical
//! footprint and its packed gather record, the heuristics that shape or reject it, the
//! progressive photon it falls back to, and the one decision every backend's photon pass
//! makes between them.

pub mod decision;
pub mod footprint;
pub mod heuristics;
pub mod progressive_photon;
