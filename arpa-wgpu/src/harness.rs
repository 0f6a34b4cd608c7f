//! A compute harness: runs a WGSL entry point over a `u32` input buffer and reads a `u32`
//! output buffer back. Floats travel as their bit patterns (`f32::to_bits`), so nothing is
//! rounded on the way in or out.
//!
//! The shader must declare
//! ```wgsl
//! @group(0) @binding(0) var<storage, read> input: array<u32>;
//! @group(0) @binding(1) var<storage, read_write> output: array<u32>;
//! ```
//! and an entry point with `@workgroup_size(WORKGROUP_SIZE)` (see [`WORKGROUP_SIZE`]) that
//! handles invocation `global_invocation_id.x` and returns for ids `>= items`.

use crate::device::GpuContext;

/// Workgroup size (x) the harness dispatches for.
pub const WORKGROUP_SIZE: u32 = 64;

/// Why a kernel could not be run.
#[derive(Debug, thiserror::Error)]
pub enum HarnessError {
    /// The WGSL did not compile or the pipeline was invalid; wgpu's message names the
    /// line and the problem.
    #[error("WGSL kernel {label:?} rejected by wgpu: {message}")]
    Shader {
        /// Label of the kernel.
        label: String,
        /// wgpu's validation message.
        message: String,
    },
    /// Too many items for one dispatch, or an empty output.
    #[error("kernel {label:?}: {message}")]
    Size {
        /// Label of the kernel.
        label: String,
        /// What is wrong.
        message: String,
    },
    /// Reading the result back failed.
    #[error("kernel {label:?}: reading the output back failed: {message}")]
    Readback {
        /// Label of the kernel.
        label: String,
        /// What failed.
        message: String,
    },
}

/// Runs entry point `entry` of the WGSL module `source` for `items` invocations over
/// `input` and returns the `output_words` words of the output buffer (zero-initialised).
pub fn run_kernel(
    ctx: &GpuContext,
    label: &str,
    source: &str,
    entry: &str,
    input: &[u32],
    items: u32,
    output_words: usize,
) -> Result<Vec<u32>, HarnessError> {
    use wgpu::util::DeviceExt;
    let device = &ctx.device;
    let size_err = |message: String| HarnessError::Size { label: label.into(), message };
    if output_words == 0 {
        return Err(size_err("empty output".into()));
    }
    let groups = items.div_ceil(WORKGROUP_SIZE);
    if groups > device.limits().max_compute_workgroups_per_dimension {
        return Err(size_err(format!("{items} items need {groups} workgroups, more than one dispatch allows")));
    }
    let scope = device.push_error_scope(wgpu::ErrorFilter::Validation);
    let module = device.create_shader_module(wgpu::ShaderModuleDescriptor { label: Some(label), source: wgpu::ShaderSource::Wgsl(source.into()) });
    let io_layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
        label: Some(label),
        entries: &[storage_entry(0, true), storage_entry(1, false)],
    });
    let pipeline = pipeline(device, label, &module, &[Some(&io_layout)], entry);
    // Storage bindings must not be empty: pad the input with one word.
    let pad = [0u32];
    let input_words: &[u32] = if input.is_empty() { &pad } else { input };
    let input_buf = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
        label: Some(label),
        contents: bytemuck::cast_slice(input_words),
        usage: wgpu::BufferUsages::STORAGE,
    });
    let out_bytes = (output_words * 4) as u64;
    let (output_buf, staging) = output_and_staging(device, label, out_bytes);
    let io = device.create_bind_group(&wgpu::BindGroupDescriptor {
        label: Some(label),
        layout: &io_layout,
        entries: &[
            wgpu::BindGroupEntry { binding: 0, resource: input_buf.as_entire_binding() },
            wgpu::BindGroupEntry { binding: 1, resource: output_buf.as_entire_binding() },
        ],
    });
    let mut encoder = device.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some(label) });
    {
        let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor { label: Some(label), timestamp_writes: None });
        pass.set_pipeline(&pipeline);
        pass.set_bind_group(0, &io, &[]);
        pass.dispatch_workgroups(groups.max(1), 1, 1);
    }
    encoder.copy_buffer_to_buffer(&output_buf, 0, &staging, 0, out_bytes);
    let [out] = submit_and_read(ctx, scope, encoder, label, [&staging])?;
    Ok(bytemuck::pod_collect_to_vec(&out))
}

/// A compute-stage storage-buffer entry of a bind-group layout.
pub(crate) fn storage_entry(binding: u32, read_only: bool) -> wgpu::BindGroupLayoutEntry {
    wgpu::BindGroupLayoutEntry {
        binding,
        visibility: wgpu::ShaderStages::COMPUTE,
        ty: wgpu::BindingType::Buffer { ty: wgpu::BufferBindingType::Storage { read_only }, has_dynamic_offset: false, min_binding_size: None },
        count: None,
    }
}

/// A compute-stage uniform-buffer entry of a bind-group layout.
pub(crate) fn uniform_entry(binding: u32) -> wgpu::BindGroupLayoutEntry {
    wgpu::BindGroupLayoutEntry {
        binding,
        visibility: wgpu::ShaderStages::COMPUTE,
        ty: wgpu::BindingType::Buffer { ty: wgpu::BufferBindingType::Uniform, has_dynamic_offset: false, min_binding_size: None },
        count: None,
    }
}

/// The compute pipeline of `entry` in `module` over the bind-group layouts `groups`
/// (group 0 first).
pub(crate) fn pipeline(
    device: &wgpu::Device,
    label: &str,
    module: &wgpu::ShaderModule,
    groups: &[Option<&wgpu::BindGroupLayout>],
    entry: &str,
) -> wgpu::ComputePipeline {
    let layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor { label: Some(label), bind_group_layouts: groups, immediate_size: 0 });
    device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
        label: Some(label),
        layout: Some(&layout),
        module,
        entry_point: Some(entry),
        compilation_options: Default::default(),
        cache: None,
    })
}


/// A kernel's output buffer of `bytes` (`STORAGE | COPY_SRC`) and the `MAP_READ` staging
/// buffer of the same size it is copied into for [`submit_and_read`].
pub(crate) fn output_and_staging(device: &wgpu::Device, label: &str, bytes: u64) -> (wgpu::Buffer, wgpu::Buffer) {
    let buffer = |usage| device.create_buffer(&wgpu::BufferDescriptor { label: Some(label), size: bytes, usage, mapped_at_creation: false });
    (
        buffer(wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC),
        buffer(wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST),
    )
}

/// Closes the validation `scope` opened before the work in `encoder` was recorded (a
/// validation error becomes [`HarnessError::Shader`]), submits `encoder`, waits for the
/// device and returns the bytes of each staging buffer (`MAP_READ`, filled by copies
/// recorded in `encoder`), in order.
pub(crate) fn submit_and_read<const N: usize>(
    ctx: &GpuContext,
    scope: wgpu::ErrorScopeGuard,
    encoder: wgpu::CommandEncoder,
    label: &str,
    staging: [&wgpu::Buffer; N],
) -> Result<[Vec<u8>; N], HarnessError> {
    if let Some(err) = pollster::block_on(scope.pop()) {
        return Err(HarnessError::Shader { label: label.into(), message: err.to_string() });
    }
    ctx.queue.submit([encoder.finish()]);
    let readback = |message: String| HarnessError::Readback { label: label.into(), message };
    let mut out: [Vec<u8>; N] = core::array::from_fn(|_| Vec::new());
    for (buffer, bytes) in staging.into_iter().zip(&mut out) {
        let (tx, rx) = std::sync::mpsc::channel();
        buffer.map_async(wgpu::MapMode::Read, .., move |r| {
            let _ = tx.send(r);
        });
        ctx.device.poll(wgpu::PollType::wait_indefinitely()).map_err(|e| readback(e.to_string()))?;
        rx.recv().map_err(|e| readback(e.to_string()))?.map_err(|e| readback(e.to_string()))?;
        *bytes = buffer.get_mapped_range(..).map_err(|e| readback(e.to_string()))?.to_vec();
        buffer.unmap();
    }
    Ok(out)
}
