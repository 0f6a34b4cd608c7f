//! [`WgpuTracer`]: the wgpu backend of [`arpa_core::tracer::Tracer`] on ray queries.

use crate::device::DeviceError;

/// Errors of the wgpu backend.
#[derive(Debug, thiserror::Error)]
pub enum WgpuError {
    /// No usable adapter or device (the message names the adapter).
    #[error(transparent)]
    Adapter(#[from] DeviceError),
    /// The scene failed validation.
    #[error("invalid scene: {0}")]
    Scene(#[from] arpa_core::scene::SceneError),
    /// A render setting is out of range.
    #[error("invalid render settings: {0}")]
    Settings(String),
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
    /// A stage was called before the stage it depends on (in this iteration).
    #[error("{stage} called before {needs}")]
    StageOrder {
        /// The stage called.
        stage: &'static str,
        /// What has to run first.
        needs: &'static str,
    },
    /// A stage of this backend is not wired yet (no fake result is produced).
    #[error("the wgpu backend cannot run {0} yet: not wired")]
    Unsupported(&'static str),
    /// `u32::MAX − 1` iterations have been accumulated.
    #[error("iteration limit reached ({0} iterations)")]
    IterationLimit(u32),
}
