//! The CPU backend's error type, below every stage that can fail.

use arpa_core::render::tracer::StageError;

use crate::embree::EmbreeError;

/// Errors of the CPU backend.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum CpuError {
    /// A call out of order, the iteration limit, or a scene or settings no render can use
    /// (the errors every backend shares).
    #[error(transparent)]
    Stage(#[from] StageError),
    /// The image has more pixels than the `u32` pixel index can address.
    #[error("image of {width}×{height} pixels is too large (at most 2^32 − 1 pixels)")]
    ImageTooLarge {
        /// Width in pixels.
        width: u32,
        /// Height in pixels.
        height: u32,
    },
    /// Embree failed (device creation, BVH build).
    #[error(transparent)]
    Embree(#[from] EmbreeError),
    /// A buffer could not be allocated.
    #[error("out of memory allocating {0}")]
    OutOfMemory(&'static str),
}
