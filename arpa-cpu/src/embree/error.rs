//! Error type of the Embree layer.

/// An error reported by Embree (`RTCError` + the message passed to the device's error
/// callback), or an input that arpa-cpu rejected before it reached Embree.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum EmbreeError {
    /// `RTC_ERROR_UNKNOWN`.
    #[error("Embree: unknown error: {0}")]
    Unknown(String),
    /// `RTC_ERROR_INVALID_ARGUMENT`.
    #[error("Embree: invalid argument: {0}")]
    InvalidArgument(String),
    /// `RTC_ERROR_INVALID_OPERATION`.
    #[error("Embree: invalid operation: {0}")]
    InvalidOperation(String),
    /// `RTC_ERROR_OUT_OF_MEMORY`.
    #[error("Embree: out of memory: {0}")]
    OutOfMemory(String),
    /// `RTC_ERROR_UNSUPPORTED_CPU`: the CPU lacks the ISA the library needs (SSE2 at least).
    #[error("Embree: unsupported CPU: {0}")]
    UnsupportedCpu(String),
    /// `RTC_ERROR_CANCELLED`: a build was cancelled by a progress callback.
    #[error("Embree: operation cancelled: {0}")]
    Cancelled(String),
    /// Any other `RTCError` code (e.g. 7, `RTC_ERROR_LEVEL_ZERO_RAYTRACING_SUPPORT_MISSING`).
    #[error("Embree: error code {code}: {message}")]
    Other {
        /// Raw `RTCError` value.
        code: u32,
        /// Message from the error callback, if any.
        message: String,
    },
    /// `rtcNewDevice` returned `NULL`.
    #[error("Embree: rtcNewDevice failed: {0}")]
    DeviceCreation(Box<EmbreeError>),
    /// The linked library is not an Embree 4 whose ray/hit ABI arpa-cpu mirrors
    /// (see `ffi.rs`). `found` is `RTC_DEVICE_PROPERTY_VERSION`, e.g. 40400 for 4.4.0.
    #[error("unsupported Embree library version {found} (arpa-cpu needs Embree 4, >= 4.0)")]
    UnsupportedVersion {
        /// Version reported by the library, `major*10000 + minor*100 + patch`.
        found: i64,
    },
    /// arpa-cpu rejected an argument before calling Embree (non-finite coordinate,
    /// out-of-range index, malformed ray interval, ...): passing it on would be undefined
    /// behaviour in Embree's release build, which does not validate.
    #[error("invalid input: {0}")]
    InvalidInput(String),
}

impl EmbreeError {
    /// Maps a raw `RTCError` code plus message; `None` for `RTC_ERROR_NONE` (0).
    pub(crate) fn from_code(code: u32, message: String) -> Option<Self> {
        Some(match code {
            0 => return None,
            1 => Self::Unknown(message),
            2 => Self::InvalidArgument(message),
            3 => Self::InvalidOperation(message),
            4 => Self::OutOfMemory(message),
            5 => Self::UnsupportedCpu(message),
            6 => Self::Cancelled(message),
            code => Self::Other { code, message },
        })
    }
}

/// Result alias of this crate.
pub type Result<T, E = EmbreeError> = core::result::Result<T, E>;
