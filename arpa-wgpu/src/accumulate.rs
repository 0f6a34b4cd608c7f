//! The running mean of the iteration images on the device (the core's `accumulate.wgsl`):
//! per plane and pixel a compensated `f32` sum and a count of rejected non-finite samples
//! ([`AccumPixel`]); the read-back sums form an [`arpa_core::accumulate::image::Accumulation`],
//! whose [`mean`](arpa_core::accumulate::image::Accumulation::mean) is the image.

pub use arpa_core::gpu::layout::AccumPixel;

/// Bytes of an iteration's status word buffer (`schedule.wgsl`, `accumulate.wgsl`: four
/// `u32`, the first used).
pub const STATUS_BYTES: u64 = 16;

/// The accumulation buffer and pipeline of one image size: one sum per entry of the
/// iteration image (planes × pixels, plane-major, [`arpa_core::gather::scales::Bandwidth::planes`]).
pub struct DeviceAccumulator {
    pipeline: wgpu::ComputePipeline,
    /// `entries` × [`AccumPixel`] (`COPY_SRC` for read-back).
    pub pixels: wgpu::Buffer,
    count: u32,
    /// A status word that is always zero, for accumulations no iteration status guards.
    clear: wgpu::Buffer,
}

impl DeviceAccumulator {
    /// A zeroed accumulator of `pixels` entries (an image's planes × pixels).
    pub fn new(device: &wgpu::Device, pixels: u32) -> Self {
        let label = Some("arpa accumulate");
        let module = device.create_shader_module(wgpu::ShaderModuleDescriptor { label, source: wgpu::ShaderSource::Wgsl(crate::shaders::accumulate().into()) });
        let pipeline = device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
            label,
            layout: None,
            module: &module,
            entry_point: Some("accumulate"),
            compilation_options: Default::default(),
            cache: None,
        });
        let pixels_buf = device.create_buffer(&wgpu::BufferDescriptor {
            label,
            size: pixels.max(1) as u64 * size_of::<AccumPixel>() as u64,
            usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: true,
        });
        // Created mapped: zero-initialised by wgpu.
        pixels_buf.unmap();
        let clear = device.create_buffer(&wgpu::BufferDescriptor { label: Some("arpa clear status"), size: STATUS_BYTES, usage: wgpu::BufferUsages::STORAGE, mapped_at_creation: false });
        Self { pipeline, pixels: pixels_buf, count: pixels, clear }
    }

    /// Replaces the sums with `pixels` (one per entry; a checkpoint resumed), through the
    /// queue; `None` for a wrong count.
    pub fn write_pixels(&self, queue: &wgpu::Queue, pixels: &[AccumPixel]) -> Option<()> {
        (pixels.len() == self.count as usize).then(|| queue.write_buffer(&self.pixels, 0, bytemuck::cast_slice(pixels)))
    }

    /// Records the addition of `image` (`vec4<f32>` per entry, RGB used) to the sums, unless
    /// the first word of `status` (the iteration's status, [`STATUS_BYTES`] bytes, written by
    /// the store's schedule kernel: its photon pass dropped records) is non-zero when it
    /// runs; `None`: always.
    pub fn encode(&self, device: &wgpu::Device, encoder: &mut wgpu::CommandEncoder, image: &wgpu::Buffer, status: Option<&wgpu::Buffer>) {
        let bind_group = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("arpa accumulate"),
            layout: &self.pipeline.get_bind_group_layout(0),
            entries: &[
                wgpu::BindGroupEntry { binding: 0, resource: image.as_entire_binding() },
                wgpu::BindGroupEntry {
                    binding: 1,
                    resource: wgpu::BindingResource::Buffer(wgpu::BufferBinding {
                        buffer: &self.pixels,
                        offset: 0,
                        size: wgpu::BufferSize::new(self.count.max(1) as u64 * size_of::<AccumPixel>() as u64),
                    }),
                },
                wgpu::BindGroupEntry { binding: 2, resource: status.unwrap_or(&self.clear).as_entire_binding() },
            ],
        });
        let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor { label: Some("arpa accumulate"), timestamp_writes: None });
        pass.set_pipeline(&self.pipeline);
        pass.set_bind_group(0, &bind_group, &[]);
        crate::store::dispatch_linear(&mut pass, self.count);
    }
}
