//! One WGSL compute kernel over a buffer of 32-bit words: what the core's WGSL twin cases
//! (the conformance suite's `twin-*`) need from a backend, here on Vulkan through naga →
//! SPIR-V ([`run_kernel`]).
//!
//! The kernel contract (as the facade's `KernelRunner` documents it): the WGSL module
//! declares
//! ```wgsl
//! @group(0) @binding(0) var<storage, read> input: array<u32>;
//! @group(0) @binding(1) var<storage, read_write> output: array<u32>;
//! ```
//! and the entry point with `@workgroup_size(64)`, handling invocation
//! `global_invocation_id.x` and returning for ids `>= invocations`. The runner dispatches
//! `⌈invocations / 64⌉` workgroups along x, binds the input (a one-word buffer when empty)
//! and a zero-initialised output of `output_words` words, and returns the output. Floats
//! travel as their bit patterns (`f32::to_bits`).

use crate::compute::{ComputePipeline, LINEAR_WORKGROUP_SIZE, record_compute_barrier, record_fill};
use crate::device::VkContext;
use crate::error::VkError;
use crate::pipeline::{BindingKind, Resource};
use ash::vk;
use gpu_allocator::MemoryLocation;

/// Runs entry point `entry` of `wgsl_source` for `invocations` invocations under the kernel
/// contract (module docs) and returns the `output_words` output words. `label` names the
/// kernel in errors and debug names. One upload and one submission, waited for.
///
/// Errors: [`VkError::Shader`] when naga rejects the source; [`VkError::InvalidInput`] for
/// `output_words == 0`, an entry point the module lacks, or more than
/// `maxComputeWorkGroupCount[0]` workgroups; device errors as [`VkContext::create_buffer`]
/// and [`VkContext::submit_and_wait`].
pub fn run_kernel(
    ctx: &VkContext,
    label: &str,
    wgsl_source: &str,
    entry: &str,
    input: &[u32],
    invocations: u32,
    output_words: usize,
) -> Result<Vec<u32>, VkError> {
    if output_words == 0 {
        return Err(VkError::InvalidInput { what: format!("kernel {label:?}"), reason: "an output of 0 words".into() });
    }
    use BindingKind::StorageBuffer as Sb;
    let pipeline = ComputePipeline::from_wgsl(ctx, label, wgsl_source, entry, &[&[Sb, Sb]])?;
    let words: &[u32] = if input.is_empty() { &[0] } else { input };
    let input_buf = ctx.upload(&format!("{label} input"), bytemuck::cast_slice(words), vk::BufferUsageFlags::STORAGE_BUFFER)?;
    let bytes = (output_words as u64).checked_mul(4).ok_or_else(|| VkError::InvalidInput {
        what: format!("kernel {label:?}"),
        reason: format!("{output_words} output words"),
    })?;
    let output = ctx.create_buffer(
        &format!("{label} output"),
        bytes,
        vk::BufferUsageFlags::STORAGE_BUFFER | vk::BufferUsageFlags::TRANSFER_DST,
        MemoryLocation::GpuToCpu,
    )?;
    let bindings = pipeline.bind(&[&[Resource::StorageBuffer(&input_buf), Resource::StorageBuffer(&output)]])?;
    let groups = [invocations.div_ceil(LINEAR_WORKGROUP_SIZE), 1, 1];
    let device = ctx.device();
    ctx.submit_and_wait(|cmd| {
        record_fill(device, cmd, &output, 0);
        record_compute_barrier(device, cmd);
        pipeline.record_dispatch(cmd, &bindings, &[], groups)?;
        record_compute_barrier(device, cmd);
        Ok::<(), VkError>(())
    })??;
    let out = output.read(0, bytes)?;
    drop(bindings);
    Ok(crate::buffer::pod_vec(&out))
}
