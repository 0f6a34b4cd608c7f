//! The wgpu backend's error type, below the passes and maps that return it.

use crate::device::DeviceError;
use arpa_core::render::tracer::StageError;

/// Errors of the wgpu backend.
#[derive(Debug, thiserror::Error)]
pub enum WgpuError {
    /// A call out of order, the iteration limit, or a scene or settings no render can use
    /// (the errors every backend shares; this backend adds one setting check: the `u32`
    /// record keys bound `photons_per_iteration · max_depth`).
    #[error(transparent)]
    Stage(#[from] StageError),
    /// No usable adapter or device (the message names the adapter).
    #[error(transparent)]
    Adapter(#[from] DeviceError),
    /// The scene could not be uploaded to the device.
    #[error("scene upload: {0}")]
    SceneUpload(String),
    /// wgpu reported a validation or out-of-memory error while recording `stage`.
    #[error("wgpu error in {stage}: {message}")]
    Device {
        /// The stage.
        stage: &'static str,
        /// wgpu's message.
        message: String,
    },
    /// Reading a buffer back failed.
    #[error("reading back {stage} failed: {message}")]
    Readback {
        /// What was read.
        stage: &'static str,
        /// What failed.
        message: String,
    },
    /// A size beyond what a buffer, dispatch or acceleration structure takes.
    #[error("size limit: {0}")]
    Size(String),
    /// The camera pass could not be built.
    #[error(transparent)]
    CameraPass(#[from] crate::camera::CameraPassError),
    /// The photon pass could not be built or run.
    #[error(transparent)]
    PhotonPass(#[from] crate::photon::PhotonPassError),
}
