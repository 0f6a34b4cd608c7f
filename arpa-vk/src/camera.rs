//! The camera pass on a ray-tracing pipeline: ray generation `vk_camera_raygen`
//! ([`crate::shaders::CAMERA_RAYGEN`], the core's `camera_pass.wgsl` per pixel) launched
//! `(width, height, 1)`, its rays through `scene_trace.wgsl`'s miss and triangle
//! closest-hit shaders. Writes one [`QueryRecord`] per pixel. Descriptor set 0 is the scene
//! ([`VkScene`]); set 1 the parameters ([`CameraParams`], uniform) and the query records.

use crate::buffer::{Buffer, KeepAlive, Submission};
use crate::device::VkContext;
use crate::error::VkError;
use crate::pipeline::{BindingKind, Bindings, HitGroup, Resource, RtPipeline, RtPipelineDesc, ShaderEntry};
use crate::scene::{SCENE_SET, VkScene};
use crate::shaders::{CAMERA_RAYGEN, compile_wgsl};
use arpa_core::gpu::layout::CameraParams;
use arpa_core::render::tracer::QueryRecord;
use ash::vk;
use std::sync::Arc;
use gpu_allocator::MemoryLocation;

/// Bytes of one query record.
pub const QUERY_RECORD_BYTES: u64 = size_of::<QueryRecord>() as u64;

/// The camera pass of one render (pipeline, parameters, bindings to its query buffer).
pub struct CameraPass {
    bindings: Bindings,
    pipeline: Arc<RtPipeline>,
    params: Buffer,
    base: CameraParams,
    /// The last trace, which reads `params` (host-visible) until it is done.
    last: Option<Submission>,
}

/// A pipeline whose ray generation `raygen` of `module` traces the scene through
/// `scene_trace.wgsl`'s miss and closest-hit shaders; set 0 the scene, set 1 `pass_set`.
pub(crate) fn scene_pipeline(ctx: &VkContext, label: &str, source: &str, raygen: &str, pass_set: &[BindingKind]) -> Result<RtPipeline, VkError> {
    let spirv = compile_wgsl(label, source)?;
    let module = ctx.create_shader_module(&spirv)?;
    let entry = |entry| ShaderEntry { module: &module, entry };
    RtPipeline::new(
        ctx,
        &RtPipelineDesc {
            label,
            raygen: entry(raygen),
            miss: &[entry("vk_cast_miss")],
            hit_groups: &[HitGroup::Triangles { closest_hit: Some(entry("vk_cast_closest_hit")), any_hit: None }],
            sets: &[&SCENE_SET, pass_set],
            push_constant_size: 0,
        },
    )
}

/// The camera pass's pipeline (independent of scene and settings; shared by every
/// [`CameraPass`] of a context).
pub fn camera_pipeline(ctx: &VkContext) -> Result<RtPipeline, VkError> {
    let source = arpa_core::gpu::shaders::compose(&[&CAMERA_RAYGEN]);
    scene_pipeline(ctx, "camera pass", &source, "vk_camera_raygen", &[BindingKind::UniformBuffer, BindingKind::StorageBuffer])
}

impl CameraPass {
    /// The pass for `params` (iteration 0; [`CameraPass::run`] sets the iteration) on
    /// `pipeline` ([`camera_pipeline`]), writing `width · height` records into `queries`.
    pub fn new(ctx: &VkContext, pipeline: &Arc<RtPipeline>, scene: &VkScene, params: CameraParams, queries: &Buffer) -> Result<Self, VkError> {
        let pipeline = Arc::clone(pipeline);
        let mut uniform = ctx.create_buffer("camera pass parameters", size_of::<CameraParams>() as u64, vk::BufferUsageFlags::UNIFORM_BUFFER, MemoryLocation::CpuToGpu)?;
        uniform.write(0, bytemuck::bytes_of(&params))?;
        let bindings = pipeline.bind(&[&scene.resources(), &[Resource::UniformBuffer(&uniform), Resource::StorageBuffer(queries)]])?;
        Ok(Self { bindings, pipeline, params: uniform, base: params, last: None })
    }

    /// Submits the trace of iteration `iteration`'s query records without waiting for it
    /// (queue order runs it before later submissions; [`VkContext::finish`] waits). Waits
    /// only when the previous trace is still in flight, since it reads the parameters this
    /// one writes (a camera pass run twice in an iteration).
    pub fn run(&mut self, ctx: &VkContext, iteration: u32) -> Result<(), VkError> {
        if let Some(last) = self.last.take() {
            ctx.wait_for(last)?;
        }
        let p = CameraParams { iteration, ..self.base };
        self.params.write(0, bytemuck::bytes_of(&p))?;
        if p.pixel_count == 0 {
            return Ok(());
        }
        self.last = Some(self.pipeline.trace(ctx, &self.bindings, &[], [p.width, p.height, 1], KeepAlive::new())?);
        Ok(())
    }
}
