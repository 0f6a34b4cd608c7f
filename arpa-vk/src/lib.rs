//! The device layer of ARPA's Vulkan backend, which will trace with ray-tracing pipelines
//! (raygen, closest-hit and miss over the triangle BVH; an AABB hit group whose intersection
//! shader does the exact filter-space test of each photon footprint).
//!
//! The crate opens the Vulkan loader at run time (`ash` with `loaded`), so it builds everywhere
//! without a Vulkan SDK; where there is no Vulkan, [`VkContext::new`] returns an error.
//!
//! What works:
//! - [`VkContext`]: instance (Vulkan 1.3 when the loader has it, else 1.2), optionally the
//!   Khronos validation layer with a debug messenger that records every error and warning
//!   ([`VkContext::validation_messages`]); adapter choice by type or by name
//!   ([`AdapterChoice`]: a GPU that has everything, else lavapipe); a device with
//!   `VK_KHR_acceleration_structure`, `VK_KHR_ray_tracing_pipeline`,
//!   `VK_KHR_deferred_host_operations` and buffer device addresses; one compute queue; a
//!   gpu-allocator memory allocator. [`DeviceInfo`], [`RayTracingProperties`] (shader-group
//!   handle size and alignments, recursion depth, scratch alignment) and [`MemoryLimits`] are
//!   queried from the adapter, never assumed.
//! - [`Buffer`]s with device addresses, host writes and reads, staged
//!   [`upload`](VkContext::upload) and [`read_back`](VkContext::read_back), and one-time
//!   submissions ([`VkContext::submit_and_wait`]).
//! - Every failure is a [`VkError`]: no loader, no adapter, a missing extension or feature (naming
//!   the adapter and each one), out of device memory, device lost, a failing Vulkan call.
//!
//! What the tracer will add: acceleration structures (triangle BLAS, footprint and photon AABB
//! BLASes, TLAS), the ray-tracing pipelines and shader binding tables, the passes of one
//! iteration in one submission, and the `arpa_core::tracer::Tracer` implementation with its
//! registry entry. Until then the crate is not a backend of the facade.

#![warn(missing_docs)]

pub mod buffer;
pub mod device;
pub mod error;

pub use ash;
pub use ash::vk;
pub use buffer::Buffer;
pub use device::{
    AdapterChoice, ApiVersion, ContextOptions, DeviceInfo, DeviceType, MemoryHeap, MemoryLimits, RayTracingProperties, Severity,
    ValidationLog, ValidationMessage, VkContext,
};
pub use error::{AdapterSummary, VkError};
pub use gpu_allocator::MemoryLocation;

#[cfg(test)]
mod tests {
    /// The context and buffers may be shared between and moved across threads.
    #[test]
    fn handles_are_send_and_sync() {
        fn check<T: Send + Sync>() {}
        check::<crate::VkContext>();
        check::<crate::Buffer>();
        check::<crate::ValidationLog>();
        check::<crate::VkError>();
    }
}
