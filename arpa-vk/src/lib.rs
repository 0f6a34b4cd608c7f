//! ARPA's Vulkan backend on ray-tracing pipelines: [`VkTracer`] implements
//! `arpa_core::render::tracer::Tracer` (the facade's `--backend vk`). Every trace is a ray-tracing
//! pipeline (raygen, closest-hit and miss over the triangle structures; for the gather one
//! short ray per query point through an AABB hit group whose intersection shader does the
//! exact filter-space test), the store and sort are compute; ray queries are not used.
//!
//! The crate opens the Vulkan loader at run time (`ash` with `loaded`), so it builds everywhere
//! without a Vulkan SDK; where there is no Vulkan, [`VkContext::new`] returns an error.
//!
//! The iteration, module by module (each stage submits without waiting; the accumulate's
//! wait is the iteration's one, see [`VkTracer`]):
//! - [`scene`]: the scene's triangle structures (Morton-ordered bottom levels per mesh,
//!   [`SceneAccel`]) and the core's scene tables, descriptor set 0 of the traces;
//! - [`camera`]: the camera pass, ray generation over the core's `camera_pass.wgsl`;
//! - [`photons`]: emission and propagation, ray generation over the core's `photon_pass.wgsl`,
//!   keyed records appended to [`photons::PhotonOutputs`];
//! - [`maps`]: storing footprints — the core's keyed store (heuristics, progressive fallbacks),
//!   radix sort over the capacities and compaction into sorted records and boxes
//!   ([`MapStore`]);
//! - [`map_accel`]: building the structure over the sorted boxes ([`MapAccel`]: AABB bottom
//!   levels per record kind over the store's capacities, not opaque, no duplicate any-hit;
//!   one top level);
//! - [`gather`]: ray generation over the core's `gather.wgsl`, the GLSL hit group
//!   ([`shaders::GATHER_INTERSECTION`], [`shaders::GATHER_ANY_HIT`]);
//! - [`accumulate`]: the running mean ([`DeviceAccumulator`]).
//!
//! Underneath: [`device`] ([`VkContext`]: instance, optional validation layer with a messenger
//! that records every error and warning, adapter choice by type or name, the ray-tracing
//! extensions and features, one compute queue, a gpu-allocator allocator, a pipeline cache;
//! [`DeviceInfo`], [`RayTracingProperties`] and [`MemoryLimits`] queried, never assumed),
//! [`buffer`], [`accel`], [`pipeline`] (ray-tracing pipelines with a shader binding table laid
//! out from the queried handle size and alignments), [`compute`], [`kernel`] (the facade's
//! WGSL kernel contract, for the twin cases) and [`shaders`] (WGSL stages through naga 30;
//! what naga cannot express — the gather's intersection and ignoring any-hit — in GLSL,
//! compiled by `scripts/build-vk-shaders.sh` into checked-in SPIR-V that CI recompiles and
//! compares). Every failure is a [`VkError`] or [`VkTracerError`], naming the adapter, the call
//! or the resource.
//!
//! On lavapipe a pipeline is compiled at its first trace or dispatch (seconds for the camera
//! and photon passes), so the passes' pipelines are made once per context and shared
//! ([`VkTracer::new`]). naga's polyfill of WGSL's workgroup-memory zero initialisation made the
//! sort's shared-memory kernels take minutes to compile there, so the sort is compiled without
//! it ([`shaders::compile_wgsl_with`]; the kernels write every shared element before reading).
//! Box bottom levels are built over the store's whole capacity, the slots past the records
//! holding degenerate boxes outside the scene, not NaN boxes: on lavapipe NaN boxes lose
//! real boxes in traversal (see [`VkContext::build_aabb_blas`]).

#![warn(missing_docs)]

pub mod accel;
pub mod adapter;
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
pub mod submission;
pub mod timing;
pub mod tracer;

pub use accel::{AabbRange, AccelerationStructure, SceneAccel, TlasInstance};
pub use accumulate::DeviceAccumulator;
pub use ash;
pub use ash::vk;
pub use buffer::Buffer;
pub use compute::{ComputePipeline, ComputePipelineDesc, record_compute_barrier};
pub use device::{
    AdapterChoice, ApiVersion, ContextOptions, DeviceInfo, MemoryHeap, MemoryLimits, RayTracingProperties, Severity,
    ValidationLog, ValidationMessage, VkContext,
};
pub use adapter::{AdapterSummary, DeviceType};
pub use error::VkError;
pub use gpu_allocator::MemoryLocation;
pub use kernel::run_kernel;
pub use map_accel::{MapAccel, MapInstance};
pub use maps::{MapStore, RadixScratch, StorePipelines};
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
