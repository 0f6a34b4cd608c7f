//! ARPA's Vulkan backend on ray-tracing pipelines (raygen, closest-hit and miss over the
//! triangle BVH; an AABB hit group whose intersection shader does the exact filter-space test
//! of each photon footprint), built up layer by layer. Not yet a backend of the facade.
//!
//! The crate opens the Vulkan loader at run time (`ash` with `loaded`), so it builds everywhere
//! without a Vulkan SDK; where there is no Vulkan, [`VkContext::new`] returns an error.
//!
//! What works (tested on lavapipe under the Khronos validation layer):
//! - **Device layer.** [`VkContext`]: instance (Vulkan 1.3 when the loader has it, else 1.2),
//!   optionally the validation layer with a debug messenger that records every error and
//!   warning ([`VkContext::validation_messages`]); adapter choice by type or by name
//!   ([`AdapterChoice`]: a GPU that has everything, else lavapipe); a device with
//!   `VK_KHR_acceleration_structure`, `VK_KHR_ray_tracing_pipeline`,
//!   `VK_KHR_deferred_host_operations`, buffer device addresses and `geometryShader` (see
//!   [`shaders`]); one compute queue; a gpu-allocator memory allocator. [`DeviceInfo`],
//!   [`RayTracingProperties`] and [`MemoryLimits`] are queried from the adapter, never
//!   assumed. [`Buffer`]s with device addresses, host access, staged
//!   [`upload`](VkContext::upload) and [`read_back`](VkContext::read_back), one-time
//!   submissions ([`VkContext::submit_and_wait`]).
//! - **Acceleration structures** ([`accel`]): triangle bottom levels per mesh in Morton order
//!   with the map back to the mesh's triangles, AABB bottom levels (not opaque, no duplicate
//!   any-hit), top levels over instances with mask, custom index and SBT offset;
//!   [`SceneAccel`] for a whole `PreparedScene`. Sizes, scratch alignment from the device; one
//!   submission per build.
//! - **Ray-tracing pipelines** ([`pipeline`]): raygen, miss and hit groups (triangle and
//!   procedural) from SPIR-V, recursion depth 1, a shader binding table laid out from the
//!   queried handle size and alignments ([`SbtLayout`]), descriptor sets of buffers and top
//!   levels ([`RtPipeline::bind`]), push constants, traces ([`RtPipeline::record_trace`],
//!   [`RtPipeline::trace_and_wait`]).
//! - **Shaders** ([`shaders`]): WGSL ray-tracing stages compiled to SPIR-V by naga 30 at run
//!   time, composed with the core's WGSL; closest-hit ray casting ([`shaders::RAY_CAST`]) agrees
//!   with the core's `BruteForceCaster` (`tests/ray_cast.rs`).
//! - **The gather's AABB hit group** ([`shaders::GATHER_INTERSECTION`],
//!   [`shaders::GATHER_ANY_HIT`]): what naga cannot express, in GLSL (`arpa-vk/shaders/*.rint`,
//!   `*.rahit`, `gather_common.glsl`) compiled by `scripts/build-vk-shaders.sh` (Debian's
//!   `glslc`, pinned flags, `spirv-val`) into checked-in SPIR-V embedded here ([`GlslStage`]);
//!   `--check` recompiles and compares the bytes (CI). The intersection shader does the exact
//!   test (filter-space ellipse and slab for footprints, progressive-radius sphere for
//!   photons), the any-hit shader adds the irradiance and count to the payload and ignores the
//!   intersection. One short ray per query point through it agrees with
//!   `arpa_core::estimate::gather_brute_force` (counts exact, sums to f32 summation error;
//!   `tests/gather_hit_group.rs`, with a GLSL test ray generation and miss).
//! - **Compute** ([`compute`]): compute pipelines of one WGSL entry point (naga → SPIR-V),
//!   descriptor sets shared with the ray-tracing pipelines, push constants, dispatches checked
//!   against `maxComputeWorkGroupCount`, the core's linear 64-wide dispatch
//!   ([`compute::linear_groups`]) and a compute barrier ([`record_compute_barrier`]).
//!   [`run_kernel`] runs one WGSL kernel under the facade's kernel contract (the twin cases);
//!   tested on a tiny kernel and the core's rng twin (`tests/maps.rs`).
//! - **Photon maps on the device** ([`maps`], [`map_accel`]): the core's keyed store, bitonic
//!   sort and compaction ([`MapStore`]: one batch per iteration, one 48-byte counter readback
//!   between the store and the sort), then AABB bottom levels over ranges of the sorted box
//!   buffers by device address and a top level with the core's instance convention
//!   ([`MapAccel`]). Tested against a CPU reference (outcomes = the core's heuristics, photons
//!   = the host's sort bit for bit, independent of the append order) and through the GLSL
//!   gather hit group (counts = brute force).
//! - **Running mean** ([`accumulate`]): the core's `accumulate.wgsl` ([`DeviceAccumulator`]).
//! - Every failure is a [`VkError`]: no loader, no adapter, a missing extension or feature
//!   (naming the adapter and each one), out of device memory, device lost, a failing Vulkan
//!   call, a shader naga rejects, an invalid input.
//!
//! What the tracer still needs: the gather's production ray generation (query records in,
//! image out, an order-independent sum), the camera and photon passes as raygen shaders over
//! the core's path WGSL, the chain (photon pass, store, sort, build, gather, accumulate) in as
//! few submissions per iteration as the counter readback allows, and the
//! `arpa_core::tracer::Tracer` implementation with its registry entry.
//! Box BLASes cannot simply be built over the full capacity with inactive (NaN) boxes: on
//! lavapipe that loses real boxes in traversal (see [`VkContext::build_aabb_blas`]), hence the
//! readback that sizes them.
//!
//! On lavapipe the first dispatch of a pipeline compiles it (llvmpipe). naga's polyfill of
//! WGSL's workgroup-memory zero initialisation made the sort's shared-memory kernels take
//! minutes to compile there on a cold Mesa shader cache, so the sort is compiled without it
//! ([`shaders::compile_wgsl_with`]; the kernels write every shared element before reading).

#![warn(missing_docs)]

pub mod accel;
pub mod accumulate;
pub mod buffer;
pub mod camera;
pub mod compute;
pub mod device;
pub mod error;
pub mod gather;
pub mod kernel;
pub mod map_accel;
pub mod maps;
pub mod photons;
pub mod pipeline;
pub mod scene;
pub mod shaders;
pub mod tracer;

pub use accel::{AabbRange, AccelerationStructure, SceneAccel, TlasInstance};
pub use accumulate::DeviceAccumulator;
pub use ash;
pub use ash::vk;
pub use buffer::Buffer;
pub use compute::{ComputePipeline, ComputePipelineDesc, record_compute_barrier};
pub use device::{
    AdapterChoice, ApiVersion, ContextOptions, DeviceInfo, DeviceType, MemoryHeap, MemoryLimits, RayTracingProperties, Severity,
    ValidationLog, ValidationMessage, VkContext,
};
pub use error::{AdapterSummary, VkError};
pub use gpu_allocator::MemoryLocation;
pub use kernel::run_kernel;
pub use map_accel::{MapAccel, MapInstance};
pub use maps::{MapStore, StorePipelines};
pub use pipeline::{
    BindingKind, Bindings, HitGroup, Resource, RtPipeline, RtPipelineDesc, SbtLayout, SbtRegion, ShaderEntry, ShaderModule,
};
pub use shaders::{GlslStage, SpirvModule, compile_wgsl, compile_wgsl_with};
pub use tracer::{VkTracer, VkTracerError};

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
