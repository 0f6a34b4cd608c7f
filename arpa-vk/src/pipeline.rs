//! Ray-tracing pipelines from SPIR-V modules, their shader binding tables and traces.
//!
//! A pipeline ([`RtPipeline`]) has one ray-generation group, any number of miss groups and
//! hit groups (triangles: closest-hit and/or any-hit; procedural: an intersection shader,
//! any-hit and closest-hit optional), a maximum recursion depth of 1, descriptor sets of
//! storage buffers, uniform buffers and top-level structures ([`BindingKind`]), and optionally
//! a push-constant block. Its shader binding table ([`SbtLayout`]) is laid out from the
//! adapter's queried `shaderGroupHandleSize`, `shaderGroupHandleAlignment` and
//! `shaderGroupBaseAlignment`, filled with `vkGetRayTracingShaderGroupHandlesKHR`.

use crate::accel::AccelerationStructure;
use crate::buffer::{Buffer, KeepAlive, Submission};
use crate::device::{RayTracingProperties, Shared, VkContext};
use crate::error::{VkError, VkResultExt};
use crate::shaders::SpirvModule;
use ash::vk;
use gpu_allocator::MemoryLocation;
use std::ffi::CString;
use std::sync::Arc;

/// Every ray-tracing stage: descriptor sets and push constants are visible to all of them.
const RT_STAGES: vk::ShaderStageFlags = vk::ShaderStageFlags::from_raw(
    vk::ShaderStageFlags::RAYGEN_KHR.as_raw()
        | vk::ShaderStageFlags::MISS_KHR.as_raw()
        | vk::ShaderStageFlags::CLOSEST_HIT_KHR.as_raw()
        | vk::ShaderStageFlags::ANY_HIT_KHR.as_raw()
        | vk::ShaderStageFlags::INTERSECTION_KHR.as_raw(),
);

/// A `VkShaderModule`; destroyed on drop (pipelines made from it stay valid).
pub struct ShaderModule {
    raw: vk::ShaderModule,
    label: String,
    shared: Arc<Shared>,
}

impl ShaderModule {
    /// The Vulkan handle.
    pub fn raw(&self) -> vk::ShaderModule {
        self.raw
    }

    /// The label of the SPIR-V it was made from.
    pub fn label(&self) -> &str {
        &self.label
    }
}

impl Drop for ShaderModule {
    fn drop(&mut self) {
        // SAFETY: a module of this device; pipelines do not need it after creation.
        unsafe { self.shared.device.device.destroy_shader_module(self.raw, None) };
    }
}

impl VkContext {
    /// Creates a shader module from SPIR-V (e.g. [`crate::shaders::compile_wgsl`]'s).
    pub fn create_shader_module(&self, spirv: &SpirvModule) -> Result<ShaderModule, VkError> {
        let info = vk::ShaderModuleCreateInfo::default().code(&spirv.words);
        // SAFETY: naga's SPIR-V for this device's features.
        let raw = unsafe { self.device().create_shader_module(&info, None) }.vk("vkCreateShaderModule")?;
        Ok(ShaderModule { raw, label: spirv.label.clone(), shared: Arc::clone(&self.shared) })
    }
}

/// One entry point of a shader module.
#[derive(Clone, Copy)]
pub struct ShaderEntry<'a> {
    /// The module.
    pub module: &'a ShaderModule,
    /// The entry point's name.
    pub entry: &'a str,
}

/// A hit group (one shader-binding-table hit record).
#[derive(Clone, Copy)]
pub enum HitGroup<'a> {
    /// Triangle geometry: closest-hit and any-hit shaders, each optional.
    Triangles {
        /// Runs once for the closest hit.
        closest_hit: Option<ShaderEntry<'a>>,
        /// Runs for every candidate hit of non-opaque geometry.
        any_hit: Option<ShaderEntry<'a>>,
    },
    /// AABB geometry: the intersection shader decides what a box holds.
    Procedural {
        /// Tests the ray against a primitive's content and reports hits.
        intersection: ShaderEntry<'a>,
        /// Runs for every reported hit (the geometry must not be opaque).
        any_hit: Option<ShaderEntry<'a>>,
        /// Runs once for the closest reported hit.
        closest_hit: Option<ShaderEntry<'a>>,
    },
}

/// What one descriptor binding holds (binding numbers are the positions in the set).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum BindingKind {
    /// `var<storage>` (read or read-write).
    StorageBuffer,
    /// `var<uniform>`.
    UniformBuffer,
    /// `acceleration_structure` (a top level).
    AccelerationStructure,
}

impl BindingKind {
    fn descriptor_type(self) -> vk::DescriptorType {
        match self {
            Self::StorageBuffer => vk::DescriptorType::STORAGE_BUFFER,
            Self::UniformBuffer => vk::DescriptorType::UNIFORM_BUFFER,
            Self::AccelerationStructure => vk::DescriptorType::ACCELERATION_STRUCTURE_KHR,
        }
    }
}

/// How to create a pipeline.
#[derive(Clone, Copy)]
pub struct RtPipelineDesc<'a> {
    /// Label for errors.
    pub label: &'a str,
    /// The ray-generation shader.
    pub raygen: ShaderEntry<'a>,
    /// Miss shaders, miss index order (naga's `traceRay` always uses index 0).
    pub miss: &'a [ShaderEntry<'a>],
    /// Hit groups, SBT hit-record order.
    pub hit_groups: &'a [HitGroup<'a>],
    /// Per descriptor set (WGSL `@group`), the kind of each binding (`@binding` = position).
    pub sets: &'a [&'a [BindingKind]],
    /// Bytes of the push-constant block (0: none), a multiple of 4.
    pub push_constant_size: u32,
}

/// One region of the shader binding table (`VkStridedDeviceAddressRegionKHR` relative to the
/// table's start).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct SbtRegion {
    /// Offset from the table's start, a multiple of `shaderGroupBaseAlignment`.
    pub offset: u64,
    /// Bytes between records, a multiple of `shaderGroupHandleAlignment`.
    pub stride: u64,
    /// Bytes of the region (records × stride; for ray generation equal to the stride).
    pub size: u64,
}

/// The shader binding table's layout: ray generation, then miss records, then hit records,
/// each region starting at a multiple of `shaderGroupBaseAlignment`, each record
/// `shaderGroupHandleSize` rounded up to `shaderGroupHandleAlignment`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct SbtLayout {
    /// `shaderGroupHandleSize` (bytes copied per record).
    pub handle_size: u64,
    /// `shaderGroupBaseAlignment` (alignment of the table's device address).
    pub base_alignment: u64,
    /// The ray-generation record.
    pub raygen: SbtRegion,
    /// The miss records.
    pub miss: SbtRegion,
    /// The hit records.
    pub hit: SbtRegion,
    /// Bytes of the whole table.
    pub size: u64,
}

fn align_up(x: u64, a: u64) -> u64 {
    x.div_ceil(a.max(1)) * a.max(1)
}

impl SbtLayout {
    /// The layout for one ray-generation record, `miss` miss and `hit` hit records.
    pub fn new(props: &RayTracingProperties, miss: u32, hit: u32) -> Self {
        let handle_size = u64::from(props.shader_group_handle_size);
        let base = u64::from(props.shader_group_base_alignment);
        let stride = align_up(handle_size, u64::from(props.shader_group_handle_alignment));
        // Vulkan: the ray-generation region's size equals its stride.
        let raygen = SbtRegion { offset: 0, stride, size: stride };
        let miss = SbtRegion { offset: align_up(raygen.size, base), stride, size: stride * u64::from(miss) };
        let hit = SbtRegion { offset: align_up(miss.offset + miss.size, base), stride, size: stride * u64::from(hit) };
        Self { handle_size, base_alignment: base, raygen, miss, hit, size: hit.offset + hit.size }
    }
}

/// A ray-tracing pipeline with its layout and shader binding table. Dropping it destroys the
/// pipeline, its layout and set layouts, then frees the table.
pub struct RtPipeline {
    pipeline: vk::Pipeline,
    layout: vk::PipelineLayout,
    set_layouts: Vec<vk::DescriptorSetLayout>,
    set_kinds: Vec<Vec<BindingKind>>,
    push_constant_size: u32,
    sbt_layout: SbtLayout,
    /// Device address of the table's first record (aligned to the base alignment).
    sbt_address: vk::DeviceAddress,
    loader: ash::khr::ray_tracing_pipeline::Device,
    label: String,
    /// Freed after the pipeline is destroyed.
    _sbt: Buffer,
    shared: Arc<Shared>,
}

/// The objects made so far while creating a pipeline, destroyed if creation fails.
pub(crate) struct Partial<'a> {
    pub(crate) device: &'a ash::Device,
    pub(crate) set_layouts: Vec<vk::DescriptorSetLayout>,
    pub(crate) layout: vk::PipelineLayout,
    pub(crate) pipeline: vk::Pipeline,
}

impl Partial<'_> {
    /// The finished objects `(pipeline, layout, set layouts)`, which the caller now owns
    /// (nothing is destroyed).
    pub(crate) fn finish(mut self) -> (vk::Pipeline, vk::PipelineLayout, Vec<vk::DescriptorSetLayout>) {
        let set_layouts = std::mem::take(&mut self.set_layouts);
        let (pipeline, layout) = (self.pipeline, self.layout);
        std::mem::forget(self);
        (pipeline, layout, set_layouts)
    }
}

impl Drop for Partial<'_> {
    fn drop(&mut self) {
        // SAFETY: none of these is in use; null handles are ignored by Vulkan.
        unsafe {
            self.device.destroy_pipeline(self.pipeline, None);
            self.device.destroy_pipeline_layout(self.layout, None);
            for &l in &self.set_layouts {
                self.device.destroy_descriptor_set_layout(l, None);
            }
        }
    }
}

impl RtPipeline {
    /// Creates the pipeline (max recursion depth 1), its layout and its shader binding table.
    ///
    /// Errors: [`VkError::InvalidInput`] for an entry name with a NUL byte or a push-constant
    /// size that is not a multiple of 4; a failing Vulkan call (e.g. an entry point the module
    /// lacks); device errors as [`VkContext::create_buffer`].
    pub fn new(ctx: &VkContext, desc: &RtPipelineDesc<'_>) -> Result<Self, VkError> {
        let invalid = |reason: String| VkError::InvalidInput { what: format!("ray-tracing pipeline {:?}", desc.label), reason };
        if !desc.push_constant_size.is_multiple_of(4) {
            return Err(invalid(format!("push-constant size {} is not a multiple of 4", desc.push_constant_size)));
        }
        let device = ctx.device();
        let loader = ash::khr::ray_tracing_pipeline::Device::new(ctx.instance(), device);
        let mut partial = Partial { device, set_layouts: Vec::new(), layout: vk::PipelineLayout::null(), pipeline: vk::Pipeline::null() };
        create_set_layouts(device, desc.sets, RT_STAGES, &mut partial.set_layouts)?;
        partial.layout = create_pipeline_layout(device, &partial.set_layouts, RT_STAGES, desc.push_constant_size)?;

        // Stages and groups.
        let mut names: Vec<CString> = Vec::new();
        let mut stage_specs: Vec<(vk::ShaderStageFlags, vk::ShaderModule)> = Vec::new();
        let mut add = |e: &ShaderEntry<'_>, stage: vk::ShaderStageFlags| -> Result<u32, VkError> {
            names.push(CString::new(e.entry).map_err(|_| invalid(format!("entry name {:?} has a NUL byte", e.entry)))?);
            stage_specs.push((stage, e.module.raw));
            Ok(stage_specs.len() as u32 - 1)
        };
        let general = |i: u32| {
            vk::RayTracingShaderGroupCreateInfoKHR::default()
                .ty(vk::RayTracingShaderGroupTypeKHR::GENERAL)
                .general_shader(i)
                .closest_hit_shader(vk::SHADER_UNUSED_KHR)
                .any_hit_shader(vk::SHADER_UNUSED_KHR)
                .intersection_shader(vk::SHADER_UNUSED_KHR)
        };
        let mut groups = vec![general(add(&desc.raygen, vk::ShaderStageFlags::RAYGEN_KHR)?)];
        for m in desc.miss {
            groups.push(general(add(m, vk::ShaderStageFlags::MISS_KHR)?));
        }
        for h in desc.hit_groups {
            let mut opt = |e: &Option<ShaderEntry<'_>>, stage| e.as_ref().map_or(Ok(vk::SHADER_UNUSED_KHR), |e| add(e, stage));
            let g = match h {
                HitGroup::Triangles { closest_hit, any_hit } => vk::RayTracingShaderGroupCreateInfoKHR::default()
                    .ty(vk::RayTracingShaderGroupTypeKHR::TRIANGLES_HIT_GROUP)
                    .general_shader(vk::SHADER_UNUSED_KHR)
                    .closest_hit_shader(opt(closest_hit, vk::ShaderStageFlags::CLOSEST_HIT_KHR)?)
                    .any_hit_shader(opt(any_hit, vk::ShaderStageFlags::ANY_HIT_KHR)?)
                    .intersection_shader(vk::SHADER_UNUSED_KHR),
                HitGroup::Procedural { intersection, any_hit, closest_hit } => vk::RayTracingShaderGroupCreateInfoKHR::default()
                    .ty(vk::RayTracingShaderGroupTypeKHR::PROCEDURAL_HIT_GROUP)
                    .general_shader(vk::SHADER_UNUSED_KHR)
                    .intersection_shader(opt(&Some(*intersection), vk::ShaderStageFlags::INTERSECTION_KHR)?)
                    .any_hit_shader(opt(any_hit, vk::ShaderStageFlags::ANY_HIT_KHR)?)
                    .closest_hit_shader(opt(closest_hit, vk::ShaderStageFlags::CLOSEST_HIT_KHR)?),
            };
            groups.push(g);
        }
        let stages: Vec<vk::PipelineShaderStageCreateInfo<'_>> = stage_specs
            .iter()
            .zip(&names)
            .map(|(&(stage, module), name)| vk::PipelineShaderStageCreateInfo::default().stage(stage).module(module).name(name))
            .collect();
        let info = vk::RayTracingPipelineCreateInfoKHR::default()
            .stages(&stages)
            .groups(&groups)
            .max_pipeline_ray_recursion_depth(1)
            .layout(partial.layout);
        // SAFETY: the stages, groups and layout live across the call.
        let created =
            unsafe { loader.create_ray_tracing_pipelines(vk::DeferredOperationKHR::null(), ctx.shared.pipeline_cache, &[info], None) };
        partial.pipeline = match created {
            Ok(p) => p[0],
            Err((p, r)) => {
                for pl in p {
                    // SAFETY: unused (null or failed) pipelines.
                    unsafe { device.destroy_pipeline(pl, None) };
                }
                return Err(VkError::from_vk("vkCreateRayTracingPipelinesKHR", r));
            }
        };

        // Shader binding table.
        let rt = ctx.ray_tracing();
        let sbt_layout = SbtLayout::new(rt, desc.miss.len() as u32, desc.hit_groups.len() as u32);
        let group_count = groups.len() as u32;
        let h = sbt_layout.handle_size as usize;
        // SAFETY: the pipeline has `group_count` groups.
        let handles = unsafe { loader.get_ray_tracing_shader_group_handles(partial.pipeline, 0, group_count, h * group_count as usize) }
            .vk("vkGetRayTracingShaderGroupHandlesKHR")?;
        let usage = vk::BufferUsageFlags::SHADER_BINDING_TABLE_KHR | vk::BufferUsageFlags::SHADER_DEVICE_ADDRESS;
        let mut sbt = ctx.create_buffer(
            &format!("{} SBT", desc.label),
            sbt_layout.size + sbt_layout.base_alignment,
            usage,
            MemoryLocation::CpuToGpu,
        )?;
        let raw_address = sbt.device_address().unwrap_or(0);
        let sbt_address = align_up(raw_address, sbt_layout.base_alignment);
        let pad = sbt_address - raw_address;
        let mut bytes = vec![0u8; sbt_layout.size as usize];
        let mut put =
            |offset: u64, group: usize| bytes[offset as usize..offset as usize + h].copy_from_slice(&handles[group * h..(group + 1) * h]);
        put(sbt_layout.raygen.offset, 0);
        for i in 0..desc.miss.len() {
            put(sbt_layout.miss.offset + i as u64 * sbt_layout.miss.stride, 1 + i);
        }
        for i in 0..desc.hit_groups.len() {
            put(sbt_layout.hit.offset + i as u64 * sbt_layout.hit.stride, 1 + desc.miss.len() + i);
        }
        sbt.write(pad, &bytes)?;

        let (pipeline, layout, set_layouts) = partial.finish();
        Ok(Self {
            pipeline,
            layout,
            set_layouts,
            set_kinds: desc.sets.iter().map(|s| s.to_vec()).collect(),
            push_constant_size: desc.push_constant_size,
            sbt_layout,
            sbt_address,
            loader,
            label: desc.label.into(),
            _sbt: sbt,
            shared: Arc::clone(&ctx.shared),
        })
    }

    /// The shader binding table's layout.
    pub fn sbt_layout(&self) -> &SbtLayout {
        &self.sbt_layout
    }

    /// The Vulkan pipeline.
    pub fn raw(&self) -> vk::Pipeline {
        self.pipeline
    }

    /// The pipeline layout.
    pub fn layout(&self) -> vk::PipelineLayout {
        self.layout
    }

    fn region(&self, r: &SbtRegion) -> vk::StridedDeviceAddressRegionKHR {
        if r.size == 0 {
            return vk::StridedDeviceAddressRegionKHR::default();
        }
        vk::StridedDeviceAddressRegionKHR::default().device_address(self.sbt_address + r.offset).stride(r.stride).size(r.size)
    }

    /// Descriptor sets holding `sets[s][b]` at set `s`, binding `b`, matching the pipeline's
    /// [`RtPipelineDesc::sets`] kinds.
    ///
    /// Errors: [`VkError::InvalidInput`] for a count or kind that does not match.
    pub fn bind(&self, sets: &[&[Resource<'_>]]) -> Result<Bindings, VkError> {
        allocate_bindings(&self.shared, &format!("bindings of ray-tracing pipeline {:?}", self.label), &self.set_layouts, &self.set_kinds, sets)
    }

    /// Checks a launch against `maxRayDispatchInvocationCount` and the push-constant size.
    fn check_trace(&self, push_constants: &[u8], extent: [u32; 3]) -> Result<(), VkError> {
        let invalid = |reason: String| VkError::InvalidInput { what: format!("trace of ray-tracing pipeline {:?}", self.label), reason };
        let rays = extent.iter().map(|&e| u64::from(e)).product::<u64>();
        let max = u64::from(self.shared.ray_tracing.max_ray_dispatch_invocation_count);
        if rays > max {
            return Err(invalid(format!("{extent:?} = {rays} rays exceed maxRayDispatchInvocationCount {max}")));
        }
        if push_constants.len() != self.push_constant_size as usize {
            return Err(invalid(format!("{} push-constant bytes, the layout has {}", push_constants.len(), self.push_constant_size)));
        }
        Ok(())
    }

    /// Records a trace of `extent` rays (`[width, height, depth]`) into `cmd`: binds the
    /// pipeline, `bindings` and `push_constants` (exactly the pipeline's push-constant size).
    /// The caller orders it against earlier writes and later reads with barriers (see
    /// [`RtPipeline::trace_and_wait`]).
    ///
    /// Errors: [`VkError::InvalidInput`] for a launch above `maxRayDispatchInvocationCount`
    /// or push constants of the wrong size.
    pub fn record_trace(
        &self,
        cmd: vk::CommandBuffer,
        bindings: &Bindings,
        push_constants: &[u8],
        extent: [u32; 3],
    ) -> Result<(), VkError> {
        self.check_trace(push_constants, extent)?;
        let device = &self.shared.device.device;
        let l = &self.sbt_layout;
        // SAFETY: the pipeline, sets and table are alive while the caller's submission runs.
        unsafe {
            device.cmd_bind_pipeline(cmd, vk::PipelineBindPoint::RAY_TRACING_KHR, self.pipeline);
            if !bindings.sets.is_empty() {
                device.cmd_bind_descriptor_sets(cmd, vk::PipelineBindPoint::RAY_TRACING_KHR, self.layout, 0, &bindings.sets, &[]);
            }
            if !push_constants.is_empty() {
                device.cmd_push_constants(cmd, self.layout, RT_STAGES, 0, push_constants);
            }
            self.loader.cmd_trace_rays(
                cmd,
                &self.region(&l.raygen),
                &self.region(&l.miss),
                &self.region(&l.hit),
                &vk::StridedDeviceAddressRegionKHR::default(),
                extent[0],
                extent[1],
                extent[2],
            );
        }
        Ok(())
    }

    /// One submission: a barrier (earlier host, transfer and build writes before the
    /// shaders read), the trace, a barrier (shader writes before host and transfer reads),
    /// then waits for it.
    pub fn trace_and_wait(&self, ctx: &VkContext, bindings: &Bindings, push_constants: &[u8], extent: [u32; 3]) -> Result<(), VkError> {
        self.check_trace(push_constants, extent)?;
        ctx.submit_and_wait(|cmd| self.record_framed_trace(ctx, cmd, bindings, push_constants, extent))?
    }

    /// As [`RtPipeline::trace_and_wait`] without the wait ([`VkContext::submit`]): `keep`
    /// (what the trace uses that the caller does not keep, e.g. `bindings` themselves, moved
    /// in after this call records them) lives until a later wait finds it done.
    pub fn trace(&self, ctx: &VkContext, bindings: &Bindings, push_constants: &[u8], extent: [u32; 3], keep: KeepAlive) -> Result<Submission, VkError> {
        self.check_trace(push_constants, extent)?;
        let (recorded, submission) = ctx.submit(keep, |cmd| self.record_framed_trace(ctx, cmd, bindings, push_constants, extent))?;
        recorded?;
        Ok(submission)
    }

    /// Records the barriers and the trace of [`RtPipeline::trace_and_wait`].
    pub(crate) fn record_framed_trace(&self, ctx: &VkContext, cmd: vk::CommandBuffer, bindings: &Bindings, push_constants: &[u8], extent: [u32; 3]) -> Result<(), VkError> {
        let device = ctx.device();
        let before = vk::MemoryBarrier::default()
            .src_access_mask(vk::AccessFlags::HOST_WRITE | vk::AccessFlags::TRANSFER_WRITE | vk::AccessFlags::ACCELERATION_STRUCTURE_WRITE_KHR)
            .dst_access_mask(vk::AccessFlags::SHADER_READ | vk::AccessFlags::SHADER_WRITE | vk::AccessFlags::ACCELERATION_STRUCTURE_READ_KHR);
        let after = vk::MemoryBarrier::default()
            .src_access_mask(vk::AccessFlags::SHADER_WRITE)
            .dst_access_mask(vk::AccessFlags::HOST_READ | vk::AccessFlags::TRANSFER_READ);
        // SAFETY: plain barriers in a recording command buffer.
        unsafe {
            device.cmd_pipeline_barrier(
                cmd,
                vk::PipelineStageFlags::HOST | vk::PipelineStageFlags::TRANSFER | vk::PipelineStageFlags::ACCELERATION_STRUCTURE_BUILD_KHR,
                vk::PipelineStageFlags::RAY_TRACING_SHADER_KHR,
                vk::DependencyFlags::empty(),
                &[before],
                &[],
                &[],
            );
        }
        self.record_trace(cmd, bindings, push_constants, extent)?;
        // SAFETY: as above.
        unsafe {
            device.cmd_pipeline_barrier(
                cmd,
                vk::PipelineStageFlags::RAY_TRACING_SHADER_KHR,
                vk::PipelineStageFlags::HOST | vk::PipelineStageFlags::TRANSFER,
                vk::DependencyFlags::empty(),
                &[after],
                &[],
                &[],
            );
        }
        Ok(())
    }
}

impl Drop for RtPipeline {
    fn drop(&mut self) {
        let device = &self.shared.device.device;
        // SAFETY: every submission using the pipeline was waited for.
        unsafe {
            device.destroy_pipeline(self.pipeline, None);
            device.destroy_pipeline_layout(self.layout, None);
            for &l in &self.set_layouts {
                device.destroy_descriptor_set_layout(l, None);
            }
        }
    }
}

/// A resource bound to a descriptor.
#[derive(Clone, Copy)]
pub enum Resource<'a> {
    /// A storage buffer (whole).
    StorageBuffer(&'a Buffer),
    /// A uniform buffer (whole).
    UniformBuffer(&'a Buffer),
    /// A top-level acceleration structure.
    AccelerationStructure(&'a AccelerationStructure),
}

impl Resource<'_> {
    fn kind(&self) -> BindingKind {
        match self {
            Self::StorageBuffer(_) => BindingKind::StorageBuffer,
            Self::UniformBuffer(_) => BindingKind::UniformBuffer,
            Self::AccelerationStructure(_) => BindingKind::AccelerationStructure,
        }
    }
}

/// Descriptor sets of one pipeline ([`RtPipeline::bind`], `ComputePipeline::bind`) and their pool, destroyed on drop.
/// The resources they name must outlive every trace that uses them.
pub struct Bindings {
    pool: vk::DescriptorPool,
    pub(crate) sets: Vec<vk::DescriptorSet>,
    shared: Arc<Shared>,
}

impl Drop for Bindings {
    fn drop(&mut self) {
        crate::buffer::settle(&self.shared);
        // SAFETY: no submission using the sets is pending (none is in flight after `settle`).
        unsafe { self.shared.device.device.destroy_descriptor_pool(self.pool, None) };
    }
}

/// Creates one descriptor-set layout per entry of `sets` (binding `b` of set `s` of kind
/// `sets[s][b]`, visible to `stages`), pushing each onto `out` as it is made (so a caller's
/// [`Partial`] destroys them if a later one fails). Shared by ray-tracing and compute
/// pipelines.
pub(crate) fn create_set_layouts(
    device: &ash::Device,
    sets: &[&[BindingKind]],
    stages: vk::ShaderStageFlags,
    out: &mut Vec<vk::DescriptorSetLayout>,
) -> Result<(), VkError> {
    for kinds in sets {
        let bindings: Vec<vk::DescriptorSetLayoutBinding<'_>> = kinds
            .iter()
            .enumerate()
            .map(|(i, k)| {
                vk::DescriptorSetLayoutBinding::default()
                    .binding(i as u32)
                    .descriptor_type(k.descriptor_type())
                    .descriptor_count(1)
                    .stage_flags(stages)
            })
            .collect();
        let info = vk::DescriptorSetLayoutCreateInfo::default().bindings(&bindings);
        // SAFETY: a valid create info.
        let l = unsafe { device.create_descriptor_set_layout(&info, None) }.vk("vkCreateDescriptorSetLayout")?;
        out.push(l);
    }
    Ok(())
}

/// Creates a pipeline layout over `set_layouts` with a push-constant block of
/// `push_constant_size` bytes (none when 0) visible to `stages`.
pub(crate) fn create_pipeline_layout(
    device: &ash::Device,
    set_layouts: &[vk::DescriptorSetLayout],
    stages: vk::ShaderStageFlags,
    push_constant_size: u32,
) -> Result<vk::PipelineLayout, VkError> {
    let push = [vk::PushConstantRange::default().stage_flags(stages).offset(0).size(push_constant_size)];
    let mut layout_info = vk::PipelineLayoutCreateInfo::default().set_layouts(set_layouts);
    if push_constant_size > 0 {
        layout_info = layout_info.push_constant_ranges(&push);
    }
    // SAFETY: valid set layouts of this device.
    unsafe { device.create_pipeline_layout(&layout_info, None) }.vk("vkCreatePipelineLayout")
}

/// Descriptor sets holding `sets[s][b]` at set `s`, binding `b`, allocated with
/// `set_layouts` (made from `set_kinds` by [`create_set_layouts`]) from a pool of their own.
/// `what` names the pipeline in errors. Shared by ray-tracing and compute pipelines.
///
/// Errors: [`VkError::InvalidInput`] for a count or kind that does not match, or a bottom
/// level given for an acceleration structure.
pub(crate) fn allocate_bindings(
    shared: &Arc<Shared>,
    what: &str,
    set_layouts: &[vk::DescriptorSetLayout],
    set_kinds: &[Vec<BindingKind>],
    sets: &[&[Resource<'_>]],
) -> Result<Bindings, VkError> {
    let invalid = |reason: String| VkError::InvalidInput { what: what.into(), reason };
    if sets.len() != set_kinds.len() {
        return Err(invalid(format!("{} sets given, the pipeline has {}", sets.len(), set_kinds.len())));
    }
    let mut counts = [0u32; 3];
    for (s, (given, kinds)) in sets.iter().zip(set_kinds).enumerate() {
        if given.len() != kinds.len() {
            return Err(invalid(format!("set {s}: {} bindings given, the layout has {}", given.len(), kinds.len())));
        }
        for (b, (r, k)) in given.iter().zip(kinds).enumerate() {
            if r.kind() != *k {
                return Err(invalid(format!("set {s} binding {b}: a {:?} given, the layout has a {k:?}", r.kind())));
            }
            if let Resource::AccelerationStructure(a) = r
                && a.level() != vk::AccelerationStructureTypeKHR::TOP_LEVEL
            {
                return Err(invalid(format!("set {s} binding {b}: {:?} is not a top-level structure", a.label())));
            }
            counts[*k as usize] += 1;
        }
    }
    let device = &shared.device.device;
    let sizes: Vec<vk::DescriptorPoolSize> = [BindingKind::StorageBuffer, BindingKind::UniformBuffer, BindingKind::AccelerationStructure]
        .iter()
        .filter(|k| counts[**k as usize] > 0)
        .map(|k| vk::DescriptorPoolSize::default().ty(k.descriptor_type()).descriptor_count(counts[*k as usize]))
        .collect();
    let pool_info = vk::DescriptorPoolCreateInfo::default().max_sets(sets.len().max(1) as u32).pool_sizes(&sizes);
    // SAFETY: a valid create info.
    let pool = unsafe { device.create_descriptor_pool(&pool_info, None) }.vk("vkCreateDescriptorPool")?;
    let mut bindings = Bindings { pool, sets: Vec::new(), shared: Arc::clone(shared) };
    if sets.is_empty() {
        return Ok(bindings);
    }
    let alloc = vk::DescriptorSetAllocateInfo::default().descriptor_pool(pool).set_layouts(set_layouts);
    // SAFETY: the pool has room for these sets.
    let allocated = unsafe { device.allocate_descriptor_sets(&alloc) }.vk("vkAllocateDescriptorSets")?;
    bindings.sets = allocated;
    for (s, given) in sets.iter().enumerate() {
        for (b, r) in given.iter().enumerate() {
            let write =
                vk::WriteDescriptorSet::default().dst_set(bindings.sets[s]).dst_binding(b as u32).descriptor_type(r.kind().descriptor_type());
            match r {
                Resource::StorageBuffer(buf) | Resource::UniformBuffer(buf) => {
                    let info = [vk::DescriptorBufferInfo::default().buffer(buf.raw()).offset(0).range(vk::WHOLE_SIZE)];
                    // SAFETY: a live buffer of the right usage (checked by validation).
                    unsafe { device.update_descriptor_sets(&[write.buffer_info(&info)], &[]) };
                }
                Resource::AccelerationStructure(a) => {
                    let handles = [a.raw()];
                    let mut as_write = vk::WriteDescriptorSetAccelerationStructureKHR::default().acceleration_structures(&handles);
                    let write = write.descriptor_count(1).push_next(&mut as_write);
                    // SAFETY: a live top-level structure.
                    unsafe { device.update_descriptor_sets(&[write], &[]) };
                }
            }
        }
    }
    Ok(bindings)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn props(handle: u32, align: u32, base: u32) -> RayTracingProperties {
        RayTracingProperties {
            shader_group_handle_size: handle,
            shader_group_handle_alignment: align,
            shader_group_base_alignment: base,
            max_ray_recursion_depth: 1,
            max_shader_group_stride: 4096,
            max_ray_dispatch_invocation_count: 1 << 30,
            max_ray_hit_attribute_size: 32,
            min_acceleration_structure_scratch_offset_alignment: 128,
            max_geometry_count: 1 << 24,
            max_instance_count: 1 << 24,
            max_primitive_count: 1 << 29,
        }
    }

    #[test]
    fn sbt_layout_follows_the_queried_sizes() {
        // lavapipe's values (handle 32, alignment 16, base 32).
        let l = SbtLayout::new(&props(32, 16, 32), 1, 2);
        assert_eq!(l.raygen, SbtRegion { offset: 0, stride: 32, size: 32 });
        assert_eq!(l.miss, SbtRegion { offset: 32, stride: 32, size: 32 });
        assert_eq!(l.hit, SbtRegion { offset: 64, stride: 32, size: 64 });
        assert_eq!(l.size, 128);
        // NVIDIA's (handle 32, alignment 32, base 64): regions start at multiples of 64.
        let l = SbtLayout::new(&props(32, 32, 64), 2, 3);
        assert_eq!(l.raygen, SbtRegion { offset: 0, stride: 32, size: 32 });
        assert_eq!(l.miss, SbtRegion { offset: 64, stride: 32, size: 64 });
        assert_eq!(l.hit, SbtRegion { offset: 128, stride: 32, size: 96 });
        // A handle smaller than its alignment: records padded to the alignment.
        let l = SbtLayout::new(&props(24, 32, 64), 1, 1);
        assert_eq!((l.raygen.stride, l.raygen.size, l.miss.offset, l.hit.offset, l.size), (32, 32, 64, 128, 160));
        for r in [l.raygen, l.miss, l.hit] {
            assert!(r.offset % 64 == 0 && r.stride % 32 == 0);
        }
    }
}
