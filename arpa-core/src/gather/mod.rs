//! Gather (`no_std`): the irradiance at a query point from the footprints and photons
//! that contain it. Kernels, the estimate and its brute-force reference, and the scale
//! ladder of the per-pixel bandwidth.

pub mod estimate;
pub mod kernel;
pub mod scales;
