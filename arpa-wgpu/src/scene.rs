//! Scene upload: the triangles of every mesh into a bottom-level acceleration structure of
//! their own (positions `f32`, world space, metres), one instance per mesh (custom data =
//! mesh index) in a top-level structure; and closest-hit ray casting against it on ray
//! queries, the device side of [`arpa_core::ray_cast::RayCaster`], checked against
//! [`arpa_core::ray_cast::BruteForceCaster`].

use crate::device::GpuContext;
use crate::harness::{HarnessError, output_and_staging, submit_and_read};
use arpa_core::ray_cast::RayHit;
use arpa_core::scene::TriangleMesh;
use arpa_core::glam::Vec3;
use wgpu::util::DeviceExt;

/// WGSL of the ray-cast kernel (entry point `cast_rays`), after `enable wgpu_ray_query;`.
pub const RAY_CAST_WGSL: &str = include_str!("shaders/ray_cast.wgsl");

/// Why a scene could not be uploaded.
#[derive(Debug, thiserror::Error)]
pub enum SceneUploadError {
    /// A mesh names a vertex it does not have.
    #[error("mesh {mesh:?}: triangle {triangle} uses vertex {index}, but the mesh has {count} vertices")]
    IndexOutOfRange {
        /// Mesh name.
        mesh: String,
        /// Triangle index.
        triangle: usize,
        /// The offending vertex index.
        index: u32,
        /// Number of vertices.
        count: usize,
    },
    /// A vertex position is NaN or infinite.
    #[error("mesh {mesh:?}: vertex {vertex} is not finite")]
    NonFiniteVertex {
        /// Mesh name.
        mesh: String,
        /// Vertex index.
        vertex: usize,
    },
    /// More meshes than instance data can index (2²⁴) or than the device's TLAS holds.
    #[error("{meshes} meshes; this device's top-level acceleration structure holds at most {max}")]
    TooManyMeshes {
        /// Mesh count.
        meshes: usize,
        /// Limit.
        max: u32,
    },
    /// The device rejected a build.
    #[error(transparent)]
    Device(#[from] HarnessError),
}

/// The scene's geometry on the device.
pub struct GpuScene {
    blases: Vec<wgpu::Blas>,
    tlas: wgpu::Tlas,
    /// Triangles per mesh (empty meshes get no instance).
    pub triangle_counts: Vec<u32>,
}

#[repr(C)]
#[derive(Clone, Copy, Debug, bytemuck::Pod, bytemuck::Zeroable)]
struct CastRay {
    origin: [f32; 3],
    t_max: f32,
    direction: [f32; 3],
    pad: u32,
}

#[repr(C)]
#[derive(Clone, Copy, Debug, bytemuck::Pod, bytemuck::Zeroable)]
struct CastHit {
    t: f32,
    mesh: u32,
    triangle: u32,
    b1: f32,
    b2: f32,
    pad: [u32; 3],
}

impl GpuScene {
    /// Builds the acceleration structures of `meshes` (validated here: indices in range,
    /// finite vertices) and waits for the build.
    pub fn upload(ctx: &GpuContext, meshes: &[TriangleMesh]) -> Result<Self, SceneUploadError> {
        let device = &ctx.device;
        let max = device.limits().max_tlas_instance_count.min((1 << 24) - 1);
        if meshes.len() > max as usize {
            return Err(SceneUploadError::TooManyMeshes { meshes: meshes.len(), max });
        }
        for m in meshes {
            if let Some(vertex) = m.positions.iter().position(|p| !p.is_finite()) {
                return Err(SceneUploadError::NonFiniteVertex { mesh: m.name.clone(), vertex });
            }
            for (triangle, t) in m.indices.iter().enumerate() {
                if let Some(&index) = t.iter().find(|&&i| i as usize >= m.positions.len()) {
                    return Err(SceneUploadError::IndexOutOfRange { mesh: m.name.clone(), triangle, index, count: m.positions.len() });
                }
            }
        }
        let label = "scene upload";
        let scope = device.push_error_scope(wgpu::ErrorFilter::Validation);
        let blas_desc = wgpu::CreateBlasDescriptor {
            label: Some(label),
            flags: wgpu::AccelerationStructureFlags::PREFER_FAST_TRACE,
            update_mode: wgpu::AccelerationStructureUpdateMode::Build,
        };
        let mut parts = Vec::new();
        for (mi, m) in meshes.iter().enumerate() {
            if m.indices.is_empty() {
                continue;
            }
            let vertices: Vec<[f32; 3]> = m.positions.iter().map(|p| p.to_array()).collect();
            let vb = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some(label),
                contents: bytemuck::cast_slice(&vertices),
                usage: wgpu::BufferUsages::BLAS_INPUT,
            });
            let ib = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some(label),
                contents: bytemuck::cast_slice(&m.indices),
                usage: wgpu::BufferUsages::BLAS_INPUT,
            });
            let size = wgpu::BlasTriangleGeometrySizeDescriptor {
                vertex_format: wgpu::VertexFormat::Float32x3,
                vertex_count: m.positions.len() as u32,
                index_format: Some(wgpu::IndexFormat::Uint32),
                index_count: Some(3 * m.indices.len() as u32),
                flags: wgpu::AccelerationStructureGeometryFlags::OPAQUE,
            };
            let blas = device.create_blas(&blas_desc, wgpu::BlasGeometrySizeDescriptors::Triangles { descriptors: vec![size.clone()] });
            parts.push((mi, blas, vb, ib, size));
        }
        let mut tlas = device.create_tlas(&wgpu::CreateTlasDescriptor {
            label: Some(label),
            max_instances: parts.len().max(1) as u32,
            flags: wgpu::AccelerationStructureFlags::PREFER_FAST_TRACE,
            update_mode: wgpu::AccelerationStructureUpdateMode::Build,
        });
        let identity = [1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0];
        for (slot, (mi, blas, ..)) in parts.iter().enumerate() {
            tlas[slot] = Some(wgpu::TlasInstance::new(blas, identity, *mi as u32, 0xff));
        }
        let entries: Vec<wgpu::BlasBuildEntry> = parts
            .iter()
            .map(|(_, blas, vb, ib, size)| wgpu::BlasBuildEntry {
                blas,
                geometry: wgpu::BlasGeometries::TriangleGeometries(vec![wgpu::BlasTriangleGeometry {
                    size,
                    vertex_buffer: vb,
                    first_vertex: 0,
                    vertex_stride: 12,
                    index_buffer: Some(ib),
                    first_index: Some(0),
                    transform_buffer: None,
                    transform_buffer_offset: None,
                }]),
            })
            .collect();
        let mut encoder = device.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some(label) });
        encoder.build_acceleration_structures(entries.iter(), [&tlas]);
        if let Some(e) = pollster::block_on(scope.pop()) {
            return Err(HarnessError::Shader { label: label.into(), message: e.to_string() }.into());
        }
        ctx.queue.submit([encoder.finish()]);
        drop(entries);
        let triangle_counts = meshes.iter().map(|m| m.indices.len() as u32).collect();
        Ok(Self { blases: parts.into_iter().map(|(_, blas, ..)| blas).collect(), tlas, triangle_counts })
    }

    /// Number of meshes with triangles (instances in the top-level structure).
    pub fn instance_count(&self) -> usize {
        self.blases.len()
    }

    /// Closest hits of the rays `(origin, unit direction, t_max)` (metres), as
    /// [`arpa_core::ray_cast::RayCaster::intersect`] would return them.
    pub fn intersect(&self, ctx: &GpuContext, rays: &[(Vec3, Vec3, f32)]) -> Result<Vec<Option<RayHit>>, HarnessError> {
        let label = "ray cast";
        if rays.is_empty() {
            return Ok(Vec::new());
        }
        let device = &ctx.device;
        let groups = u32::try_from(rays.len()).unwrap_or(u32::MAX).div_ceil(64);
        if groups > device.limits().max_compute_workgroups_per_dimension {
            return Err(HarnessError::Size { label: label.into(), message: format!("{} rays exceed one dispatch", rays.len()) });
        }
        let input: Vec<CastRay> =
            rays.iter().map(|(o, d, t)| CastRay { origin: o.to_array(), t_max: *t, direction: d.to_array(), pad: 0 }).collect();
        let scope = device.push_error_scope(wgpu::ErrorFilter::Validation);
        let source = format!("enable wgpu_ray_query;\n{RAY_CAST_WGSL}");
        let module = device.create_shader_module(wgpu::ShaderModuleDescriptor { label: Some(label), source: wgpu::ShaderSource::Wgsl(source.into()) });
        let pipeline = device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
            label: Some(label),
            layout: None,
            module: &module,
            entry_point: Some("cast_rays"),
            compilation_options: Default::default(),
            cache: None,
        });
        let in_buf = device.create_buffer_init(&wgpu::util::BufferInitDescriptor { label: Some(label), contents: bytemuck::cast_slice(&input), usage: wgpu::BufferUsages::STORAGE });
        let out_bytes = (rays.len() * std::mem::size_of::<CastHit>()) as u64;
        let (out_buf, staging) = output_and_staging(device, label, out_bytes);
        let bind_group = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some(label),
            layout: &pipeline.get_bind_group_layout(0),
            entries: &[
                wgpu::BindGroupEntry { binding: 0, resource: in_buf.as_entire_binding() },
                wgpu::BindGroupEntry { binding: 1, resource: out_buf.as_entire_binding() },
                wgpu::BindGroupEntry { binding: 2, resource: self.tlas.as_binding() },
            ],
        });
        let mut encoder = device.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some(label) });
        {
            let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor { label: Some(label), timestamp_writes: None });
            pass.set_pipeline(&pipeline);
            pass.set_bind_group(0, &bind_group, &[]);
            pass.dispatch_workgroups(groups, 1, 1);
        }
        encoder.copy_buffer_to_buffer(&out_buf, 0, &staging, 0, out_bytes);
        let [out] = submit_and_read(ctx, scope, encoder, label, [&staging])?;
        Ok(bytemuck::pod_collect_to_vec::<u8, CastHit>(&out)
            .iter()
            .map(|h| (h.mesh != u32::MAX).then_some(RayHit { t: h.t, mesh: h.mesh, triangle: h.triangle, b1: h.b1, b2: h.b2 }))
            .collect())
    }
}
