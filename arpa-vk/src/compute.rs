//! Compute pipelines from naga-compiled WGSL (the core's path kernels: store, sort,
//! accumulate; the twin's test kernels), their descriptor sets and dispatches.
//!
//! A [`ComputePipeline`] is one compute entry point of a SPIR-V module
//! ([`crate::shaders::compile_wgsl`] translates every entry point of a WGSL source; the
//! pipeline picks one by name), with descriptor-set layouts of storage and uniform buffers
//! ([`BindingKind`]; naga maps `@group(g) @binding(b)` to set `g`, binding `b`, and the kind
//! must match the WGSL declaration: `var<storage>` is [`BindingKind::StorageBuffer`],
//! `var<uniform>` is [`BindingKind::UniformBuffer`]) and optionally a push-constant block.
//! The descriptor code is shared with the ray-tracing pipelines ([`crate::pipeline`]).
//!
//! The core's kernels are 64 wide and linearise a 2-D grid of workgroups
//! (`gid.x + gid.y · groups.x · 64`) so that more than 65 535 workgroups fit in one dispatch:
//! [`linear_groups`] and [`ComputePipeline::record_dispatch_linear`] lay such a dispatch out.
//! Dispatches are recorded into the caller's command buffer; the caller orders them with
//! [`record_compute_barrier`] (or finer barriers) and submits
//! ([`VkContext::submit_and_wait`]).

use crate::buffer::Buffer;
use crate::device::{Shared, VkContext};
use crate::error::VkError;
use crate::pipeline::{BindingKind, Bindings, Partial, Resource, allocate_bindings, create_pipeline_layout, create_set_layouts};
use crate::shaders::SpirvModule;
use ash::vk;
use std::ffi::CString;
use std::sync::Arc;

/// Workgroup width of the core's linear kernels (`@workgroup_size(64)`).
pub const LINEAR_WORKGROUP_SIZE: u32 = arpa_core::gpu::codes::WORKGROUP_SIZE;

/// Workgroups along x of a linear dispatch that needs a second dimension (`2^15`, below
/// every device's `maxComputeWorkGroupCount[0]` of at least 65 535).
pub const LINEAR_ROW_GROUPS: u32 = 32_768;

/// The workgroup grid of a linear dispatch of `invocations` invocations of a 64-wide kernel
/// (`gid.x + gid.y · groups.x · 64` covers every index below `invocations`): one row when at
/// most `max_x` workgroups (the device's `maxComputeWorkGroupCount[0]`) are needed, else rows
/// of [`LINEAR_ROW_GROUPS`]. At least one workgroup (the kernels return for indices past
/// their count).
pub fn linear_groups(invocations: u32, max_x: u32) -> [u32; 3] {
    let groups = invocations.div_ceil(LINEAR_WORKGROUP_SIZE).max(1);
    if groups <= max_x { [groups, 1, 1] } else { [LINEAR_ROW_GROUPS, groups.div_ceil(LINEAR_ROW_GROUPS), 1] }
}

/// Stages a compute barrier waits for and blocks: compute and transfer before;
/// compute, transfer, acceleration-structure builds, ray-tracing shaders and the host after.
const BARRIER_DST_STAGES: vk::PipelineStageFlags = vk::PipelineStageFlags::from_raw(
    vk::PipelineStageFlags::COMPUTE_SHADER.as_raw()
        | vk::PipelineStageFlags::TRANSFER.as_raw()
        | vk::PipelineStageFlags::ACCELERATION_STRUCTURE_BUILD_KHR.as_raw()
        | vk::PipelineStageFlags::RAY_TRACING_SHADER_KHR.as_raw()
        | vk::PipelineStageFlags::HOST.as_raw(),
);

/// Records a global memory barrier after compute (or transfer) writes: shader and transfer
/// writes before it are visible to later shader reads and writes (compute and ray-tracing
/// stages, uniforms included), transfers, acceleration-structure builds reading their inputs
/// and the host (after the submission is waited for).
pub fn record_compute_barrier(device: &ash::Device, cmd: vk::CommandBuffer) {
    let barrier = vk::MemoryBarrier::default()
        .src_access_mask(vk::AccessFlags::SHADER_WRITE | vk::AccessFlags::TRANSFER_WRITE)
        .dst_access_mask(
            vk::AccessFlags::SHADER_READ
                | vk::AccessFlags::SHADER_WRITE
                | vk::AccessFlags::UNIFORM_READ
                | vk::AccessFlags::TRANSFER_READ
                | vk::AccessFlags::TRANSFER_WRITE
                | vk::AccessFlags::HOST_READ,
        );
    // SAFETY: a plain memory barrier in a command buffer the caller is recording.
    unsafe {
        device.cmd_pipeline_barrier(
            cmd,
            vk::PipelineStageFlags::COMPUTE_SHADER | vk::PipelineStageFlags::TRANSFER,
            BARRIER_DST_STAGES,
            vk::DependencyFlags::empty(),
            &[barrier],
            &[],
            &[],
        );
    }
}

/// How to create a compute pipeline.
#[derive(Clone, Copy)]
pub struct ComputePipelineDesc<'a> {
    /// Label for errors.
    pub label: &'a str,
    /// The module (e.g. [`crate::shaders::compile_wgsl`]'s), holding the entry point.
    pub spirv: &'a SpirvModule,
    /// The compute entry point's name.
    pub entry: &'a str,
    /// Per descriptor set (WGSL `@group`), the kind of each binding (`@binding` = position).
    pub sets: &'a [&'a [BindingKind]],
    /// Bytes of the push-constant block (0: none), a multiple of 4.
    pub push_constant_size: u32,
}

/// A compute pipeline with its layout. Dropping it destroys the pipeline, its layout and
/// its set layouts (every submission using it must have been waited for).
pub struct ComputePipeline {
    pipeline: vk::Pipeline,
    layout: vk::PipelineLayout,
    set_layouts: Vec<vk::DescriptorSetLayout>,
    set_kinds: Vec<Vec<BindingKind>>,
    push_constant_size: u32,
    /// `maxComputeWorkGroupCount` of the device.
    max_groups: [u32; 3],
    label: String,
    shared: Arc<Shared>,
}

impl ComputePipeline {
    /// Creates the pipeline of `desc.entry` (a compute entry point of `desc.spirv`).
    ///
    /// Errors: [`VkError::InvalidInput`] for an entry point the module lacks or that is not a
    /// compute shader (when the module lists its entry points), a name with a NUL byte or a
    /// push-constant size that is not a multiple of 4; a failing Vulkan call.
    pub fn new(ctx: &VkContext, desc: &ComputePipelineDesc<'_>) -> Result<Self, VkError> {
        let invalid = |reason: String| VkError::InvalidInput { what: format!("compute pipeline {:?}", desc.label), reason };
        if !desc.push_constant_size.is_multiple_of(4) {
            return Err(invalid(format!("push-constant size {} is not a multiple of 4", desc.push_constant_size)));
        }
        let entries = &desc.spirv.entry_points;
        if !entries.is_empty() && !entries.iter().any(|(s, n)| *s == naga::ShaderStage::Compute && n == desc.entry) {
            return Err(invalid(format!("{:?} has no compute entry point {:?}", desc.spirv.label, desc.entry)));
        }
        let name = CString::new(desc.entry).map_err(|_| invalid(format!("entry name {:?} has a NUL byte", desc.entry)))?;
        let module = ctx.create_shader_module(desc.spirv)?;
        let device = ctx.device();
        let stages = vk::ShaderStageFlags::COMPUTE;
        let mut partial = Partial { device, set_layouts: Vec::new(), layout: vk::PipelineLayout::null(), pipeline: vk::Pipeline::null() };
        create_set_layouts(device, desc.sets, stages, &mut partial.set_layouts)?;
        partial.layout = create_pipeline_layout(device, &partial.set_layouts, stages, desc.push_constant_size)?;
        let stage = vk::PipelineShaderStageCreateInfo::default().stage(stages).module(module.raw()).name(&name);
        let info = vk::ComputePipelineCreateInfo::default().stage(stage).layout(partial.layout);
        // SAFETY: the module, name and layout live across the call.
        let created = unsafe { device.create_compute_pipelines(ctx.shared.pipeline_cache, &[info], None) };
        partial.pipeline = match created {
            Ok(p) => p[0],
            Err((p, r)) => {
                for pl in p {
                    // SAFETY: unused (null or failed) pipelines.
                    unsafe { device.destroy_pipeline(pl, None) };
                }
                return Err(VkError::from_vk("vkCreateComputePipelines", r));
            }
        };
        drop(module);
        // SAFETY: a physical device of this instance.
        let limits = unsafe { ctx.instance().get_physical_device_properties(ctx.physical_device()) }.limits;
        let (pipeline, layout, set_layouts) = partial.finish();
        Ok(Self {
            pipeline,
            layout,
            set_layouts,
            set_kinds: desc.sets.iter().map(|s| s.to_vec()).collect(),
            push_constant_size: desc.push_constant_size,
            max_groups: limits.max_compute_work_group_count,
            label: desc.label.into(),
            shared: Arc::clone(&ctx.shared),
        })
    }

    /// Compiles `source` (WGSL) with [`crate::shaders::compile_wgsl`] and creates the
    /// pipeline of its compute entry point `entry` (no push constants). For several entry
    /// points of one source, compile once and use [`ComputePipeline::new`].
    pub fn from_wgsl(ctx: &VkContext, label: &str, source: &str, entry: &str, sets: &[&[BindingKind]]) -> Result<Self, VkError> {
        let spirv = crate::shaders::compile_wgsl(label, source)?;
        Self::new(ctx, &ComputePipelineDesc { label, spirv: &spirv, entry, sets, push_constant_size: 0 })
    }

    /// The Vulkan pipeline.
    pub fn raw(&self) -> vk::Pipeline {
        self.pipeline
    }

    /// The pipeline layout.
    pub fn layout(&self) -> vk::PipelineLayout {
        self.layout
    }

    /// The label given at creation.
    pub fn label(&self) -> &str {
        &self.label
    }

    /// The device's `maxComputeWorkGroupCount` (workgroups per dimension of one dispatch).
    pub fn max_groups(&self) -> [u32; 3] {
        self.max_groups
    }

    /// Descriptor sets holding `sets[s][b]` at set `s`, binding `b` (whole buffers), matching
    /// the pipeline's [`ComputePipelineDesc::sets`]. The buffers must outlive every
    /// submission that uses the sets.
    ///
    /// Errors: [`VkError::InvalidInput`] for a count or kind that does not match.
    pub fn bind(&self, sets: &[&[Resource<'_>]]) -> Result<Bindings, VkError> {
        allocate_bindings(&self.shared, &format!("bindings of compute pipeline {:?}", self.label), &self.set_layouts, &self.set_kinds, sets)
    }

    /// Records a dispatch of `groups` workgroups (`[x, y, z]`) into `cmd`: binds the
    /// pipeline, `bindings` and `push` (exactly the pipeline's push-constant size). A group
    /// count of 0 in any dimension records nothing. Barriers are the caller's.
    ///
    /// Errors: [`VkError::InvalidInput`] for a count above `maxComputeWorkGroupCount` or push
    /// constants of the wrong size.
    pub fn record_dispatch(&self, cmd: vk::CommandBuffer, bindings: &Bindings, push: &[u8], groups: [u32; 3]) -> Result<(), VkError> {
        let invalid = |reason: String| VkError::InvalidInput { what: format!("dispatch of compute pipeline {:?}", self.label), reason };
        if groups.iter().zip(&self.max_groups).any(|(g, m)| g > m) {
            return Err(invalid(format!("{groups:?} workgroups exceed maxComputeWorkGroupCount {:?}", self.max_groups)));
        }
        if push.len() != self.push_constant_size as usize {
            return Err(invalid(format!("{} push-constant bytes, the layout has {}", push.len(), self.push_constant_size)));
        }
        if groups.contains(&0) {
            return Ok(());
        }
        self.record_bind(cmd, bindings, push);
        // SAFETY: bound above; the counts are checked against the device's limits.
        unsafe { self.shared.device.device.cmd_dispatch(cmd, groups[0], groups[1], groups[2]) };
        Ok(())
    }

    /// Binds the pipeline, `bindings` and `push` (its size checked by the caller) into `cmd`.
    fn record_bind(&self, cmd: vk::CommandBuffer, bindings: &Bindings, push: &[u8]) {
        let device = &self.shared.device.device;
        // SAFETY: the pipeline and sets are alive while the caller's submission runs (the
        // caller keeps `bindings` and its buffers until it has waited); push size checked.
        unsafe {
            device.cmd_bind_pipeline(cmd, vk::PipelineBindPoint::COMPUTE, self.pipeline);
            if !bindings.sets.is_empty() {
                device.cmd_bind_descriptor_sets(cmd, vk::PipelineBindPoint::COMPUTE, self.layout, 0, &bindings.sets, &[]);
            }
            if !push.is_empty() {
                device.cmd_push_constants(cmd, self.layout, vk::ShaderStageFlags::COMPUTE, 0, push);
            }
        }
    }

    /// Records an indirect dispatch into `cmd`: binds the pipeline, `bindings` and `push` (as
    /// [`ComputePipeline::record_dispatch`]) and dispatches the workgroups `[x, y, z]` that
    /// the device finds at `offset` of `args` (`INDIRECT_BUFFER` usage; written before with a
    /// barrier to the indirect-command stage; each count within `maxComputeWorkGroupCount`).
    ///
    /// Errors: [`VkError::InvalidInput`] for push constants of the wrong size, an `args`
    /// buffer without `INDIRECT_BUFFER` usage or 12 bytes at `offset`.
    pub fn record_dispatch_indirect(&self, cmd: vk::CommandBuffer, bindings: &Bindings, push: &[u8], args: &Buffer, offset: u64) -> Result<(), VkError> {
        let invalid = |reason: String| VkError::InvalidInput { what: format!("indirect dispatch of compute pipeline {:?}", self.label), reason };
        if push.len() != self.push_constant_size as usize {
            return Err(invalid(format!("{} push-constant bytes, the layout has {}", push.len(), self.push_constant_size)));
        }
        if !args.usage().contains(vk::BufferUsageFlags::INDIRECT_BUFFER) || !offset.is_multiple_of(4) || offset + 12 > args.size() {
            return Err(invalid(format!("arguments at {offset} of {:?} ({} bytes, {:?})", args.label(), args.size(), args.usage())));
        }
        self.record_bind(cmd, bindings, push);
        // SAFETY: bound above; the arguments are alive while the caller's submission runs,
        // their size and usage checked above.
        unsafe { self.shared.device.device.cmd_dispatch_indirect(cmd, args.raw(), offset) };
        Ok(())
    }

    /// Records the linear dispatch of `invocations` invocations of a 64-wide kernel
    /// ([`linear_groups`] with this device's `maxComputeWorkGroupCount[0]`); at least one
    /// workgroup runs.
    pub fn record_dispatch_linear(&self, cmd: vk::CommandBuffer, bindings: &Bindings, push: &[u8], invocations: u32) -> Result<(), VkError> {
        self.record_dispatch(cmd, bindings, push, linear_groups(invocations, self.max_groups[0]))
    }
}

impl Drop for ComputePipeline {
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

/// Records `vkCmdFillBuffer` of the whole `buffer` (which needs `TRANSFER_DST` usage) with
/// `word`, for zeroing counters and outputs before a dispatch (follow it with
/// [`record_compute_barrier`]).
pub fn record_fill(device: &ash::Device, cmd: vk::CommandBuffer, buffer: &Buffer, word: u32) {
    // SAFETY: a live buffer with transfer-destination usage (checked by validation); the
    // whole-size fill rounds down to a multiple of 4 bytes.
    unsafe { device.cmd_fill_buffer(cmd, buffer.raw(), 0, vk::WHOLE_SIZE, word) };
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn linear_groups_cover_every_invocation() {
        assert_eq!(linear_groups(0, 65_535), [1, 1, 1]);
        assert_eq!(linear_groups(64, 65_535), [1, 1, 1]);
        assert_eq!(linear_groups(65, 65_535), [2, 1, 1]);
        assert_eq!(linear_groups(65_535 * 64, 65_535), [65_535, 1, 1]);
        let g = linear_groups(65_536 * 64, 65_535);
        assert_eq!(g, [32_768, 2, 1]);
        for n in [65_535 * 64 + 1, 1 << 25, u32::MAX] {
            let g = linear_groups(n, 65_535);
            assert!(u64::from(g[0]) * u64::from(g[1]) * 64 >= u64::from(n) && g[0] <= 65_535, "{n}: {g:?}");
        }
    }
}
