//! The running mean of the iteration images on the device (the core's `accumulate.wgsl`):
//! per plane and pixel a compensated `f32` sum and a count of rejected non-finite samples
//! ([`AccumPixel`]); the read-back sums form an [`arpa_core::accumulate::image::Accumulation`],
//! whose [`mean`](arpa_core::accumulate::image::Accumulation::mean) is the image.

pub use arpa_core::gpu::layout::AccumPixel;

/// The accumulation buffer and pipeline of one image size: one sum per entry of the
/// iteration image (planes × pixels, plane-major, [`arpa_core::gather::scales::Bandwidth::planes`]).
pub struct DeviceAccumulator {
    pipeline: wgpu::ComputePipeline,
    /// `entries` × [`AccumPixel`] (`COPY_SRC` for read-back).
    pub pixels: wgpu::Buffer,
    count: u32,
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
        Self { pipeline, pixels: pixels_buf, count: pixels }
    }

    /// Replaces the sums with `pixels` (one per entry; a checkpoint resumed), through the
    /// queue; `None` for a wrong count.
    pub fn write_pixels(&self, queue: &wgpu::Queue, pixels: &[AccumPixel]) -> Option<()> {
        (pixels.len() == self.count as usize).then(|| queue.write_buffer(&self.pixels, 0, bytemuck::cast_slice(pixels)))
    }

    /// Records the addition of `image` (`vec4<f32>` per entry, RGB used) to the sums.
    pub fn encode(&self, device: &wgpu::Device, encoder: &mut wgpu::CommandEncoder, image: &wgpu::Buffer) {
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
            ],
        });
        let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor { label: Some("arpa accumulate"), timestamp_writes: None });
        pass.set_pipeline(&self.pipeline);
        pass.set_bind_group(0, &bind_group, &[]);
        crate::store::dispatch_linear(&mut pass, self.count);
    }
}
