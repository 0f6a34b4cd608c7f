//! Scene upload: the triangles of every mesh into a bottom-level acceleration structure of
//! their own (positions `f32`, world space, metres; triangles in the Morton order of their
//! centroids, [`arpa_core::gpu::scene::morton_triangle_order`]), one instance per mesh
//! (custom index = mesh index) in a top-level structure ([`GpuGeometry`]); and the whole
//! prepared scene ([`GpuScene`]: that structure plus the core's
//! [`SceneTables`]) as bind group 0 of the camera and photon passes, read by the core's
//! `scene.wgsl` with this backend's ray casting ([`crate::shaders::SCENE_RAY_QUERY`]).

use crate::device::GpuContext;
use crate::harness::HarnessError;
use arpa_core::gpu::scene::{SceneTables, morton_triangle_order};
use arpa_core::render::prepared_scene::PreparedScene;
use arpa_core::render::scene::{Instancing, TriangleMesh};
use wgpu::util::DeviceExt;

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
    /// The scene's tables cannot be indexed (triangles or texture words beyond `u32`).
    #[error(transparent)]
    Tables(#[from] arpa_core::gpu::scene::SceneTablesError),
    /// The textures and texture coordinates outgrow one storage binding of this device.
    #[error("the scene's textures take {bytes} bytes; this device binds at most {max} bytes of storage at once")]
    TexturesTooLarge {
        /// Bytes of the texture words.
        bytes: u64,
        /// The device's `max_storage_buffer_binding_size`.
        max: u64,
    },
    /// The scene's instancing does not describe its meshes.
    #[error(transparent)]
    Instancing(#[from] arpa_core::render::scene::SceneError),
    /// The device rejected a build.
    #[error(transparent)]
    Device(#[from] HarnessError),
}

/// The identity 3×4 row-major transform of an instance.
const IDENTITY: [f32; 12] = [1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0];

/// An affine map as the rows of its 3×4 matrix in `f32` (a TLAS instance's transform).
fn rows(m: &arpa_core::glam::DAffine3) -> [f32; 12] {
    let (a, t) = (m.matrix3, m.translation);
    let r = |i: usize| [a.x_axis[i] as f32, a.y_axis[i] as f32, a.z_axis[i] as f32, t[i] as f32];
    let [r0, r1, r2] = [r(0), r(1), r(2)];
    [r0[0], r0[1], r0[2], r0[3], r1[0], r1[1], r1[2], r1[3], r2[0], r2[1], r2[2], r2[3]]
}

/// The scene's triangles on the device: one BLAS per non-empty mesh (one per prototype mesh
/// for instanced copies) and a TLAS with one instance per non-empty mesh.
pub struct GpuGeometry {
    blases: Vec<wgpu::Blas>,
    tlas: wgpu::Tlas,
    /// Triangles per mesh (empty meshes get no instance).
    pub triangle_counts: Vec<u32>,
    /// Per mesh: the mesh's triangle index of each BLAS primitive (primitive index ->
    /// triangle index, [`morton_triangle_order`]).
    orders: Vec<Vec<u32>>,
    /// Instances in the top-level structure.
    instances: usize,
}

impl GpuGeometry {
    /// Builds the acceleration structures of `meshes` (validated here: indices in range,
    /// finite vertices) and waits for the build. The copies that `instancing` lists
    /// ([`Instancing::copies`]: prototypes placed at least twice) share one BLAS per
    /// prototype mesh (object space), placed by their instance's transform; every other
    /// mesh has its own.
    pub fn upload(ctx: &GpuContext, meshes: &[TriangleMesh], instancing: Option<&Instancing>) -> Result<Self, SceneUploadError> {
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
        if let Some(i) = instancing {
            i.validate(meshes)?;
        }
        let label = "scene upload";
        let scope = device.push_error_scope(wgpu::ErrorFilter::Validation);
        let blas_desc = wgpu::CreateBlasDescriptor {
            label: Some(label),
            flags: wgpu::AccelerationStructureFlags::PREFER_FAST_TRACE,
            update_mode: wgpu::AccelerationStructureUpdateMode::Build,
        };
        // Per mesh: the mesh its BLAS is built from (itself, or its prototype mesh in object
        // space, shared by every copy) and its transform.
        let copies = instancing.map(|i| i.copies(meshes.len())).unwrap_or_default();
        let mut prototype_meshes: Vec<TriangleMesh> = Vec::new();
        let mut prototype_of: std::collections::HashMap<(u32, u32), usize> = std::collections::HashMap::new();
        let mut placement: Vec<(Option<usize>, [f32; 12])> = Vec::with_capacity(meshes.len());
        for (mi, m) in meshes.iter().enumerate() {
            match (copies.get(mi).copied().flatten(), instancing) {
                (Some((i, k)), Some(inst)) => {
                    let instance = &inst.instances[i as usize];
                    let p = *prototype_of.entry((instance.prototype, k)).or_insert_with(|| {
                        let pm = &inst.prototypes[instance.prototype as usize].meshes[k as usize];
                        prototype_meshes.push(TriangleMesh { name: m.name.clone(), positions: pm.positions.clone(), normals: None, uvs: None, indices: pm.indices.clone(), material: m.material, emission: None });
                        prototype_meshes.len() - 1
                    });
                    placement.push((Some(p), rows(&instance.to_world)));
                }
                _ => placement.push((None, IDENTITY)),
            }
        }
        let source = |mi: usize| placement[mi].0.map_or(&meshes[mi], |p| &prototype_meshes[p]);
        let prototype_orders: Vec<Vec<u32>> = prototype_meshes.iter().map(morton_triangle_order).collect();
        let orders: Vec<Vec<u32>> = (0..meshes.len()).map(|mi| placement[mi].0.map_or_else(|| morton_triangle_order(&meshes[mi]), |p| prototype_orders[p].clone())).collect();
        let mut parts = Vec::new();
        // BLASes: one per stand-alone mesh, one per prototype mesh (at its first copy).
        let mut blas_of_prototype: Vec<Option<usize>> = vec![None; prototype_meshes.len()];
        let mut blas_of = vec![usize::MAX; meshes.len()];
        for mi in 0..meshes.len() {
            let m = source(mi);
            if m.indices.is_empty() {
                continue;
            }
            if let Some(p) = placement[mi].0 {
                if let Some(b) = blas_of_prototype[p] {
                    blas_of[mi] = b;
                    continue;
                }
                blas_of_prototype[p] = Some(parts.len());
            }
            blas_of[mi] = parts.len();
            let order = &orders[mi];
            let sorted: Vec<[u32; 3]> = order.iter().map(|&t| m.indices[t as usize]).collect();
            let vertices: Vec<[f32; 3]> = m.positions.iter().map(|p| p.to_array()).collect();
            let vb = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some(label),
                contents: bytemuck::cast_slice(&vertices),
                usage: wgpu::BufferUsages::BLAS_INPUT,
            });
            let ib = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some(label),
                contents: bytemuck::cast_slice(&sorted),
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
        let placed: Vec<usize> = (0..meshes.len()).filter(|&mi| blas_of[mi] != usize::MAX).collect();
        let mut tlas = device.create_tlas(&wgpu::CreateTlasDescriptor {
            label: Some(label),
            max_instances: placed.len().max(1) as u32,
            flags: wgpu::AccelerationStructureFlags::PREFER_FAST_TRACE,
            update_mode: wgpu::AccelerationStructureUpdateMode::Build,
        });
        for (slot, &mi) in placed.iter().enumerate() {
            tlas[slot] = Some(wgpu::TlasInstance::new(&parts[blas_of[mi]].1, placement[mi].1, mi as u32, 0xff));
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
        Ok(Self { blases: parts.into_iter().map(|(_, blas, ..)| blas).collect(), tlas, triangle_counts, orders, instances: placed.len() })
    }

    /// Number of meshes with triangles (instances in the top-level structure).
    pub fn instance_count(&self) -> usize {
        self.instances
    }

    /// Number of BLASes (fewer than [`GpuGeometry::instance_count`] where copies share
    /// their prototype's).
    pub fn blas_count(&self) -> usize {
        self.blases.len()
    }

    /// The top-level structure (one instance per mesh with triangles, custom index = mesh
    /// index).
    pub fn tlas(&self) -> &wgpu::Tlas {
        &self.tlas
    }

    /// Per mesh, the mesh's triangle at each primitive of its BLAS
    /// ([`morton_triangle_order`]).
    pub fn triangle_orders(&self) -> &[Vec<u32>] {
        &self.orders
    }
}

/// The prepared scene on the device: the [`GpuGeometry`] plus the core's [`SceneTables`]
/// (materials with the roughness cut-off resolved, vertex positions and normals, geometric
/// normals, emission, the emitters for next-event estimation, textures and texture
/// coordinates), all in bind group 0
/// ([`GpuScene::bind_group_layout`], declared by [`crate::shaders::scene`]).
pub struct GpuScene {
    geometry: GpuGeometry,
    layout: wgpu::BindGroupLayout,
    bind_group: wgpu::BindGroup,
    /// Emitters in the device's order: delta lights, then area emitters (indices into
    /// [`arpa_core::render::prepared_scene::PreparedScene::emitters`]).
    pub emitter_order: Vec<usize>,
}

impl GpuScene {
    /// Uploads `scene` (already validated by [`PreparedScene::new`]) and waits for the
    /// acceleration-structure build.
    pub fn upload(ctx: &GpuContext, scene: &PreparedScene) -> Result<Self, SceneUploadError> {
        let geometry = GpuGeometry::upload(ctx, &scene.scene().meshes, scene.scene().instancing.as_ref())?;
        let tables = SceneTables::new(scene, &geometry.orders)?;
        let device = &ctx.device;
        let texture_bytes = 4 * tables.texture_words.len() as u64;
        let max = device.limits().max_storage_buffer_binding_size;
        if texture_bytes > max {
            return Err(SceneUploadError::TexturesTooLarge { bytes: texture_bytes, max });
        }
        let label = "scene tables";
        // Storage bindings must not be empty: one zeroed element where a table is.
        fn non_empty<T: Default + Clone>(mut v: Vec<T>) -> Vec<T> {
            if v.is_empty() {
                v.push(T::default());
            }
            v
        }
        let init = |contents: &[u8], usage| device.create_buffer_init(&wgpu::util::BufferInitDescriptor { label: Some(label), contents, usage });
        let info_buf = init(bytemuck::bytes_of(&tables.info), wgpu::BufferUsages::UNIFORM);
        let mesh_buf = init(bytemuck::cast_slice(&non_empty(tables.meshes)), wgpu::BufferUsages::STORAGE);
        let tri_buf = init(bytemuck::cast_slice(&non_empty(tables.triangles)), wgpu::BufferUsages::STORAGE);
        let emitter_buf = init(bytemuck::cast_slice(&non_empty(tables.emitters)), wgpu::BufferUsages::STORAGE);
        let texture_buf = init(bytemuck::cast_slice(&tables.texture_words), wgpu::BufferUsages::STORAGE);
        let storage = |binding| crate::harness::storage_entry(binding, true);
        let layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("scene (group 0)"),
            entries: &[
                wgpu::BindGroupLayoutEntry {
                    binding: 0,
                    visibility: wgpu::ShaderStages::COMPUTE,
                    ty: wgpu::BindingType::AccelerationStructure { vertex_return: false },
                    count: None,
                },
                crate::harness::uniform_entry(1),
                storage(2),
                storage(3),
                storage(4),
                storage(5),
            ],
        });
        let bind_group = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("scene (group 0)"),
            layout: &layout,
            entries: &[
                wgpu::BindGroupEntry { binding: 0, resource: geometry.tlas.as_binding() },
                wgpu::BindGroupEntry { binding: 1, resource: info_buf.as_entire_binding() },
                wgpu::BindGroupEntry { binding: 2, resource: mesh_buf.as_entire_binding() },
                wgpu::BindGroupEntry { binding: 3, resource: tri_buf.as_entire_binding() },
                wgpu::BindGroupEntry { binding: 4, resource: emitter_buf.as_entire_binding() },
                wgpu::BindGroupEntry { binding: 5, resource: texture_buf.as_entire_binding() },
            ],
        });
        Ok(Self { geometry, layout, bind_group, emitter_order: tables.emitter_order })
    }

    /// Layout of bind group 0 (what [`crate::shaders::scene`] declares): TLAS, scene info
    /// (uniform), meshes, triangles, emitters, texture words (read-only storage); compute
    /// stage.
    pub fn bind_group_layout(&self) -> &wgpu::BindGroupLayout {
        &self.layout
    }

    /// Bind group 0 of every pass pipeline.
    pub fn bind_group(&self) -> &wgpu::BindGroup {
        &self.bind_group
    }

    /// The acceleration structures.
    pub fn geometry(&self) -> &GpuGeometry {
        &self.geometry
    }
}

/// The compute pipeline of a pass that reads the scene: the scene's bind group 0
/// ([`GpuScene::bind_group_layout`]) and the pass's own `group1`.
pub(crate) fn scene_pipeline(
    device: &wgpu::Device,
    label: &str,
    module: &wgpu::ShaderModule,
    scene: &GpuScene,
    group1: &wgpu::BindGroupLayout,
    entry: &str,
) -> wgpu::ComputePipeline {
    crate::harness::pipeline(device, label, module, &[Some(scene.bind_group_layout()), Some(group1)], entry)
}
