//! The image gather on ray queries (the core's `gather.wgsl` with this backend's box
//! traversal, [`crate::shaders::gather`]): per query record of the camera pass, every
//! footprint and progressive photon of a batch's maps whose box contains the query point
//! ([`crate::accel`]), tested exactly and summed per map at every scale of the bandwidth
//! ([`arpa_core::gather::scales`]); the iteration's image planes per pixel out.

use arpa_core::gather::scales::Bandwidth;
use arpa_core::gpu::layout::{GatherBatch, GatherCounts, GatherImageParams};
use arpa_core::gather::kernel::Kernel;

/// The tracer's gather: per query record (one per pixel, [`arpa_core::render::tracer::QueryRecord`])
/// and scale `k` of the bandwidth, `radiance + weight · E_k` with non-finite components set
/// to 0 (as arpa-cpu's gather; `E_0 = E_caustic + E_global`, the stored scale), written as
/// `vec4<f32>` (RGB, 0) per plane and pixel, plane-major, then (per-pixel bandwidth) the
/// moment planes ([`arpa_core::gather::scales::moments`]); the contributions and candidates per
/// map at the stored scale summed into 64-bit counters and the valid records counted
/// ([`ImageGather::total_buffer`]).
pub struct ImageGather {
    pipeline: wgpu::ComputePipeline,
    params: wgpu::Buffer,
    total: wgpu::Buffer,
}

impl ImageGather {
    /// Compiles the pipeline.
    pub fn new(device: &wgpu::Device) -> Self {
        let label = Some("arpa image gather");
        let module = device.create_shader_module(wgpu::ShaderModuleDescriptor { label, source: wgpu::ShaderSource::Wgsl(crate::shaders::gather().into()) });
        let pipeline = device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
            label,
            layout: None,
            module: &module,
            entry_point: Some("gather_image"),
            compilation_options: Default::default(),
            cache: None,
        });
        let buffer = |size, usage| device.create_buffer(&wgpu::BufferDescriptor { label, size, usage, mapped_at_creation: false });
        use wgpu::BufferUsages as U;
        Self { pipeline, params: buffer(size_of::<GatherImageParams>() as u64, U::STORAGE | U::COPY_DST), total: buffer(size_of::<GatherCounts>() as u64, U::STORAGE | U::COPY_DST | U::COPY_SRC) }
    }

    /// The counters ([`GatherCounts`]), valid after the commands of
    /// [`ImageGather::encode`] ran.
    pub fn total_buffer(&self) -> &wgpu::Buffer {
        &self.total
    }

    /// Records the gather of `pixels` query records `records` against one batch's sorted
    /// `footprints` and `photons` ([`crate::maps::BatchMaps`]) in `tlas` ([`crate::accel`])
    /// with progressive `radii` (metres) and footprint `kernel`, into `image`
    /// ([`Bandwidth::planes`] × `pixels` × 16 bytes, plane-major: plane `p` of pixel `i` at
    /// `p · pixels + i`; [`arpa_core::gpu::layout::ImageBufferSizes::image`]).
    ///
    /// Photon batches: an iteration traced in several batches gathers each batch's maps in
    /// turn, into `irradiance` ([`Bandwidth::scales`] × `pixels` × 16 bytes, scale-major:
    /// per scale and pixel the irradiance summed over the batches so far, W/m², RGB);
    /// `batch` says which: the first starts the sums (and clears the counters), the last
    /// writes `image` = `radiance + weight · (sum)` per scale (and the moments) and not
    /// `irradiance`. [`GatherBatch::WHOLE`] is the single-pass gather, bit for bit. The
    /// contribution count then sums over the batches; the valid records are counted once.
    #[allow(clippy::too_many_arguments)]
    pub fn encode(
        &self,
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        encoder: &mut wgpu::CommandEncoder,
        footprints: &wgpu::Buffer,
        photons: &wgpu::Buffer,
        tlas: &wgpu::Tlas,
        records: &wgpu::Buffer,
        image: &wgpu::Buffer,
        irradiance: &wgpu::Buffer,
        radii: [f32; 2],
        kernel: Kernel,
        bandwidth: Bandwidth,
        pixels: u32,
        batch: GatherBatch,
    ) {
        let params = GatherImageParams::new(radii, kernel, pixels, batch, bandwidth);
        queue.write_buffer(&self.params, 0, bytemuck::bytes_of(&params));
        if batch.first {
            encoder.clear_buffer(&self.total, 0, None);
        }
        let bind_group = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("arpa image gather"),
            layout: &self.pipeline.get_bind_group_layout(0),
            entries: &[
                wgpu::BindGroupEntry { binding: 0, resource: footprints.as_entire_binding() },
                wgpu::BindGroupEntry { binding: 1, resource: photons.as_entire_binding() },
                wgpu::BindGroupEntry { binding: 2, resource: records.as_entire_binding() },
                wgpu::BindGroupEntry { binding: 3, resource: image.as_entire_binding() },
                wgpu::BindGroupEntry { binding: 4, resource: self.params.as_entire_binding() },
                wgpu::BindGroupEntry { binding: 5, resource: self.total.as_entire_binding() },
                wgpu::BindGroupEntry { binding: 6, resource: irradiance.as_entire_binding() },
                wgpu::BindGroupEntry { binding: 7, resource: tlas.as_binding() },
            ],
        });
        let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor { label: Some("arpa image gather"), timestamp_writes: None });
        pass.set_pipeline(&self.pipeline);
        pass.set_bind_group(0, &bind_group, &[]);
        crate::store::dispatch_linear(&mut pass, pixels);
    }
}
