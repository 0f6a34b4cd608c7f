//! Emit (`no_std`): lights, their preparation for an iteration, and one photon with its
//! ray differential per index.

pub mod emission;
