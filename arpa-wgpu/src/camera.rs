//! The camera pass on the device: one invocation per pixel traces the camera path of
//! [`arpa_core::render::camera_path::trace_camera_path`] in `f32` (same random stream
//! `StreamDomain::Camera`, jitter, specular chains with the Fresnel choice, radiance-mode
//! `(n_i/n_t)²`, emission seen, next-event estimation with every delta light and one area
//! emitter picked by power, shading-normal Lambertian, flipped orientation) and writes one
//! [`arpa_core::render::tracer::QueryRecord`] per pixel, row-major, into a caller's buffer.
//!
//! Precision: positions, weights and radiance agree with the core to `f32` rounding where
//! the path takes the same decisions; a decision taken at a threshold (Fresnel choice,
//! area-emitter pick, a shadow ray or camera ray grazing an edge) can go the other way
//! within that rounding, and the path then differs (the tests bound the share of such
//! pixels).

use crate::device::GpuContext;
use crate::harness::{HarnessError, storage_entry, uniform_entry};
use crate::scene::scene_pipeline;
use crate::scene::GpuScene;
use arpa_core::gpu::codes::WORKGROUP_SIZE as WORKGROUP;
use arpa_core::gpu::layout::CameraParams;
use arpa_core::render::prepared_scene::PreparedScene;
use arpa_core::render::scene::SceneError;
use arpa_core::render::tracer::{QueryRecord, RenderSettings};
use wgpu::util::DeviceExt;

/// Bytes of one query record on the device (= `size_of::<QueryRecord>()`).
pub const QUERY_RECORD_BYTES: u64 = std::mem::size_of::<QueryRecord>() as u64;

/// Why the camera pass could not be built.
#[derive(Debug, thiserror::Error)]
pub enum CameraPassError {
    /// The scene's camera is degenerate.
    #[error("camera pass: {0}")]
    Camera(#[from] SceneError),
    /// The image is too large for one dispatch or a `u32` pixel index.
    #[error("camera pass: a {width} x {height} image has more pixels than one dispatch of this device allows ({max})")]
    TooManyPixels {
        /// Image width (pixels).
        width: u32,
        /// Image height (pixels).
        height: u32,
        /// Most pixels one dispatch covers.
        max: u64,
    },
    /// The device rejected the shader or pipeline.
    #[error(transparent)]
    Device(#[from] HarnessError),
}

/// The camera pass of one scene, camera and settings: a compute pipeline with the scene in
/// group 0 and its parameters and the query buffer in group 1.
pub struct CameraPass {
    device: wgpu::Device,
    pipeline: wgpu::ComputePipeline,
    layout: wgpu::BindGroupLayout,
    scene_group: wgpu::BindGroup,
    params: CameraParams,
    groups: (u32, u32),
}

impl CameraPass {
    /// Builds the pipeline for `scene` (uploaded from `prepared`), its camera and the
    /// `seed`, `max_depth` and `direct_lighting` of `settings`.
    pub fn new(ctx: &GpuContext, scene: &GpuScene, prepared: &PreparedScene, settings: &RenderSettings) -> Result<Self, CameraPassError> {
        let device = &ctx.device;
        let cam = prepared.scene().camera;
        let pixels = cam.width as u64 * cam.height as u64;
        let max_groups = device.limits().max_compute_workgroups_per_dimension as u64;
        let max = max_groups * max_groups * WORKGROUP as u64;
        if pixels > u32::MAX as u64 || pixels > max {
            return Err(CameraPassError::TooManyPixels { width: cam.width, height: cam.height, max: max.min(u32::MAX as u64) });
        }
        let groups_total = pixels.div_ceil(WORKGROUP as u64);
        let groups_x = groups_total.min(max_groups);
        let groups_y = groups_total.div_ceil(groups_x.max(1));
        let params = CameraParams::new(&cam, settings, (groups_x * WORKGROUP as u64) as u32)?;
        let label = "camera pass";
        let scope = device.push_error_scope(wgpu::ErrorFilter::Validation);
        let source = crate::shaders::camera_pass();
        let module = device.create_shader_module(wgpu::ShaderModuleDescriptor { label: Some(label), source: wgpu::ShaderSource::Wgsl(source.into()) });
        let layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some(label),
            entries: &[uniform_entry(0), storage_entry(1, false)],
        });
        let pipeline = scene_pipeline(device, label, &module, scene, &layout, "arpa_camera_main");
        if let Some(e) = pollster::block_on(scope.pop()) {
            return Err(HarnessError::Shader { label: label.into(), message: e.to_string() }.into());
        }
        Ok(Self { device: device.clone(), pipeline, layout, scene_group: scene.bind_group().clone(), params, groups: (groups_x as u32, groups_y as u32) })
    }

    /// Pixels of the image (= query records per iteration).
    pub fn pixel_count(&self) -> u32 {
        self.params.pixel_count
    }

    /// Bytes a query buffer needs (48 per pixel).
    pub fn query_buffer_bytes(&self) -> u64 {
        self.params.pixel_count as u64 * QUERY_RECORD_BYTES
    }

    /// A query buffer for [`CameraPass::encode`]: `STORAGE` plus `extra` usages (e.g.
    /// `COPY_SRC` to read it back).
    pub fn create_query_buffer(&self, extra: wgpu::BufferUsages) -> wgpu::Buffer {
        self.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("camera pass queries"),
            size: self.query_buffer_bytes().max(QUERY_RECORD_BYTES),
            usage: wgpu::BufferUsages::STORAGE | extra,
            mapped_at_creation: false,
        })
    }

    /// Records the camera pass of 0-based `iteration` into `encoder`: one
    /// [`QueryRecord`] per pixel (row-major) written to `queries` (`STORAGE`, at least
    /// [`CameraPass::query_buffer_bytes`]; a smaller buffer is a wgpu validation error of
    /// the encoder, not undefined behaviour).
    pub fn encode(&self, encoder: &mut wgpu::CommandEncoder, iteration: u32, queries: &wgpu::Buffer) {
        let params = CameraParams { iteration, ..self.params };
        let uniform = self.device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("camera pass parameters"),
            contents: bytemuck::bytes_of(&params),
            usage: wgpu::BufferUsages::UNIFORM,
        });
        let group = self.device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("camera pass"),
            layout: &self.layout,
            entries: &[
                wgpu::BindGroupEntry { binding: 0, resource: uniform.as_entire_binding() },
                wgpu::BindGroupEntry { binding: 1, resource: queries.as_entire_binding() },
            ],
        });
        let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor { label: Some("camera pass"), timestamp_writes: None });
        pass.set_pipeline(&self.pipeline);
        pass.set_bind_group(0, &self.scene_group, &[]);
        pass.set_bind_group(1, &group, &[]);
        if self.params.pixel_count > 0 {
            pass.dispatch_workgroups(self.groups.0, self.groups.1, 1);
        }
    }
}
