//! The running mean of the iteration images on the device (`shaders/accumulate.wgsl`):
//! per pixel a compensated `f32` sum (Neumaier, as [`arpa_core::accumulate::RunningMean`]
//! in `f64`) and a count of rejected non-finite samples. [`DeviceAccumulator::mean`] turns
//! a read-back into the image: `(sum + compensation) / iterations` in `f64`, non-finite
//! results to 0, so no NaN or Inf reaches a pixel.

use arpa_core::glam::Vec3;

/// WGSL of the accumulation kernel (entry point `accumulate`); self-contained.
pub const ACCUMULATE_WGSL: &str = include_str!("shaders/accumulate.wgsl");

/// One pixel's accumulator (32 bytes, `AccumPixel` in the shader).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
pub struct AccumPixel {
    /// Sum of the finite samples (W/(m²·sr), RGB).
    pub sum: [f32; 3],
    /// Non-finite samples rejected.
    pub rejected: u32,
    /// Neumaier compensation of `sum`.
    pub compensation: [f32; 3],
    /// Padding.
    pub pad: u32,
}

/// The accumulation buffer and pipeline of one image size.
pub struct DeviceAccumulator {
    pipeline: wgpu::ComputePipeline,
    /// `pixels` × [`AccumPixel`] (`COPY_SRC` for read-back).
    pub pixels: wgpu::Buffer,
    count: u32,
}

impl DeviceAccumulator {
    /// A zeroed accumulator of `pixels` pixels.
    pub fn new(device: &wgpu::Device, pixels: u32) -> Self {
        let label = Some("arpa accumulate");
        let module = device.create_shader_module(wgpu::ShaderModuleDescriptor { label, source: wgpu::ShaderSource::Wgsl(ACCUMULATE_WGSL.into()) });
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
            size: pixels.max(1) as u64 * 32,
            usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: true,
        });
        // Created mapped: zero-initialised by wgpu.
        pixels_buf.unmap();
        Self { pipeline, pixels: pixels_buf, count: pixels }
    }

    /// Records the addition of `image` (`vec4<f32>` per pixel, RGB used) to the sums.
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
                        size: wgpu::BufferSize::new(self.count.max(1) as u64 * 32),
                    }),
                },
            ],
        });
        let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor { label: Some("arpa accumulate"), timestamp_writes: None });
        pass.set_pipeline(&self.pipeline);
        pass.set_bind_group(0, &bind_group, &[]);
        crate::store::dispatch_linear(&mut pass, self.count);
    }

    /// The mean of `iterations` iterations from read-back accumulators: `(sum +
    /// compensation) / iterations` in `f64`, 0 before any iteration and where not finite.
    pub fn mean(pixels: &[AccumPixel], iterations: u32) -> Vec<Vec3> {
        pixels
            .iter()
            .map(|p| {
                if iterations == 0 {
                    return Vec3::ZERO;
                }
                let s = Vec3::from_array(p.sum).as_dvec3() + Vec3::from_array(p.compensation).as_dvec3();
                let m = (s / iterations as f64).as_vec3();
                Vec3::select(m.is_finite_mask(), m, Vec3::ZERO)
            })
            .collect()
    }
}
