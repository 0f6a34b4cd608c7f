//! The crate's error type: every failure of the device layer is a [`VkError`], never a panic.

use crate::adapter::{AdapterList, AdapterSummary};
use ash::vk;


/// Why the Vulkan device layer failed.
#[derive(Debug, thiserror::Error)]
pub enum VkError {
    /// The Vulkan loader (`libvulkan.so.1`) could not be opened or lacks an entry point.
    #[error("no Vulkan loader: {0} (on Debian 12 `bash scripts/install-lavapipe.sh` installs libvulkan1 and lavapipe)")]
    NoLoader(String),

    /// The loader supports a Vulkan version older than the 1.2 the backend needs.
    #[error("the Vulkan loader supports Vulkan {found}; the backend needs 1.2 or newer")]
    LoaderTooOld {
        /// The instance version the loader reports (`major.minor.patch`).
        found: String,
    },

    /// Validation was requested but `VK_LAYER_KHRONOS_validation` (or `VK_EXT_debug_utils`) is
    /// not available.
    #[error(
        "validation requested but {what} is not available (on Debian 12 `bash scripts/install-vulkan-tools.sh` installs vulkan-validationlayers)"
    )]
    ValidationUnavailable {
        /// The missing layer or instance extension.
        what: String,
    },

    /// No adapter has everything the backend needs (or there is no adapter at all).
    #[error(
        "no Vulkan adapter with ray-tracing pipelines; adapters seen: {} (lavapipe needs Mesa >= 25: `bash scripts/install-lavapipe.sh`)",
        AdapterList(seen)
    )]
    NoAdapter {
        /// Every adapter seen, with what each lacks.
        seen: Vec<AdapterSummary>,
    },

    /// No adapter's name contains the requested text.
    #[error("no Vulkan adapter name contains {wanted:?}; adapters seen: {}", AdapterList(seen))]
    AdapterNotFound {
        /// The requested part of the name.
        wanted: String,
        /// Every adapter seen.
        seen: Vec<AdapterSummary>,
    },

    /// The chosen adapter lacks required extensions or features.
    #[error("Vulkan adapter {adapter:?} cannot run the ray-tracing-pipeline backend: missing {}", missing.join(", "))]
    MissingRequirements {
        /// The adapter's name.
        adapter: String,
        /// Each missing extension, feature, API version or queue.
        missing: Vec<String>,
    },

    /// A buffer size the device cannot hold in one buffer or one allocation.
    #[error("buffer {what:?}: {bytes} bytes exceeds the device's {limit} ({max} bytes)")]
    BufferTooLarge {
        /// The buffer's label.
        what: String,
        /// The size asked for, in bytes.
        bytes: u64,
        /// The Vulkan limit exceeded (`maxBufferSize`, `maxMemoryAllocationSize`).
        limit: &'static str,
        /// The limit's value, in bytes.
        max: u64,
    },

    /// A zero-sized buffer was asked for (Vulkan buffers hold at least one byte).
    #[error("buffer {what:?}: size 0 (Vulkan buffers hold at least one byte)")]
    EmptyBuffer {
        /// The buffer's label.
        what: String,
    },

    /// The device has no memory left for an allocation.
    #[error("out of device memory allocating {what:?} ({bytes} bytes)")]
    OutOfDeviceMemory {
        /// What was being allocated (the buffer's label).
        what: String,
        /// The size asked for, in bytes.
        bytes: u64,
    },

    /// A host access to a buffer that is not host-visible and host-coherent.
    #[error("buffer {what:?} is not host-visible and coherent memory; use a staging copy")]
    NotHostVisible {
        /// The buffer's label.
        what: String,
    },

    /// A buffer lacks a usage flag the operation needs.
    #[error("buffer {what:?} lacks the {usage} usage this operation needs")]
    MissingUsage {
        /// The buffer's label.
        what: String,
        /// The missing `VkBufferUsageFlags` bit.
        usage: &'static str,
    },

    /// A host access outside the buffer.
    #[error("buffer {what:?}: range {offset}..{end} lies outside its {size} bytes")]
    OutOfRange {
        /// The buffer's label.
        what: String,
        /// Start of the range, in bytes.
        offset: u64,
        /// End of the range (exclusive), in bytes.
        end: u64,
        /// The buffer's size, in bytes.
        size: u64,
    },

    /// The device was lost (driver reset, hang, crash); it cannot be used any more.
    #[error("Vulkan device lost during {call}")]
    DeviceLost {
        /// The call that reported it.
        call: &'static str,
    },

    /// Any other Vulkan error, with the call that returned it.
    #[error("{call} failed: {result}")]
    Vulkan {
        /// The Vulkan call.
        call: &'static str,
        /// Its result code.
        result: vk::Result,
    },

    /// A WGSL shader did not parse, validate or translate to SPIR-V (naga's message).
    #[error("shader {label:?}: {message}")]
    Shader {
        /// The shader's label.
        label: String,
        /// naga's diagnostic.
        message: String,
    },

    /// An argument the device layer cannot use: a mesh index out of range, a binding of the
    /// wrong kind, a launch larger than the device allows, and the like.
    #[error("{what}: {reason}")]
    InvalidInput {
        /// What was being built or recorded.
        what: String,
        /// What is wrong with it.
        reason: String,
    },

    /// gpu-allocator failed for a reason other than running out of memory.
    #[error("allocating {what:?}: {source}")]
    Allocator {
        /// What was being allocated or freed.
        what: String,
        /// gpu-allocator's error.
        source: gpu_allocator::AllocationError,
    },
}

impl VkError {
    /// Maps a Vulkan result from `call` to [`VkError::DeviceLost`] or [`VkError::Vulkan`].
    pub fn from_vk(call: &'static str, result: vk::Result) -> Self {
        match result {
            vk::Result::ERROR_DEVICE_LOST => Self::DeviceLost { call },
            result => Self::Vulkan { call, result },
        }
    }
}

/// `.vk("vkCall")?` turns an `ash` result into a [`VkError`] naming the call.
pub(crate) trait VkResultExt<T> {
    fn vk(self, call: &'static str) -> Result<T, VkError>;
}

impl<T> VkResultExt<T> for Result<T, vk::Result> {
    fn vk(self, call: &'static str) -> Result<T, VkError> {
        self.map_err(|r| VkError::from_vk(call, r))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::adapter::DeviceType;

    #[test]
    fn messages_name_adapters_and_what_they_lack() {
        let seen = vec![
            AdapterSummary {
                name: "llvmpipe (LLVM 15)".into(),
                device_type: DeviceType::Cpu,
                missing: vec!["VK_KHR_ray_tracing_pipeline".into()],
            },
            AdapterSummary { name: "GPU".into(), device_type: DeviceType::DiscreteGpu, missing: vec![] },
        ];
        let e = VkError::AdapterNotFound { wanted: "radeon".into(), seen: seen.clone() }.to_string();
        assert!(e.contains("\"radeon\"") && e.contains("llvmpipe (LLVM 15)") && e.contains("\"GPU\""), "{e}");
        let e = VkError::NoAdapter { seen }.to_string();
        assert!(e.contains("missing VK_KHR_ray_tracing_pipeline") && e.contains("discrete GPU"), "{e}");
        assert!(VkError::NoAdapter { seen: vec![] }.to_string().contains("adapters seen: none"));
        let e = VkError::MissingRequirements { adapter: "X".into(), missing: vec!["a".into(), "b".into()] }.to_string();
        assert!(e.contains("\"X\"") && e.contains("missing a, b"), "{e}");
        let e = VkError::OutOfDeviceMemory { what: "photons".into(), bytes: 12 }.to_string();
        assert!(e.contains("\"photons\"") && e.contains("12 bytes"), "{e}");
    }

    #[test]
    fn device_lost_is_its_own_error() {
        assert!(matches!(VkError::from_vk("vkQueueSubmit", vk::Result::ERROR_DEVICE_LOST), VkError::DeviceLost { call: "vkQueueSubmit" }));
        let e = VkError::from_vk("vkCreateBuffer", vk::Result::ERROR_INITIALIZATION_FAILED);
        assert!(e.to_string().contains("vkCreateBuffer"), "{e}");
    }
}
