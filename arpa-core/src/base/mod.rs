//! The base every stage stands on (`no_std`): counter-based random numbers, the sampling
//! of directions, discs and cells, orthonormal frames, axis-aligned boxes, Morton codes
//! and a cache prefetch hint. Imports nothing else of the crate.

pub mod aabb;
pub mod frame;
pub mod morton;
pub mod prefetch;
pub mod rng;
pub mod sampling;
