//! Scene upload: the triangles of every mesh into a bottom-level acceleration structure of
//! their own (positions `f32`, world space, metres; triangles in the Morton order of their
//! centroids, see [`morton_triangle_order`]), one instance per mesh (custom data = mesh
//! index) in a top-level structure ([`GpuGeometry`]); closest-hit ray casting against
//! it on ray queries, the device side of [`arpa_core::ray_cast::RayCaster`], checked
//! against [`arpa_core::ray_cast::BruteForceCaster`]; and the whole prepared scene
//! ([`GpuScene`]: geometry, materials, vertex normals, emitters) as bind group 0 of every
//! pass, read by the WGSL of [`SCENE_WGSL`].

use crate::device::GpuContext;
use crate::harness::{HarnessError, output_and_staging, submit_and_read};
use crate::sort::morton_code;
use arpa_core::emission::Light;
use arpa_core::glam::{DVec3, Vec3};
use arpa_core::prepared_scene::PreparedScene;
use arpa_core::ray_cast::RayHit;
use arpa_core::scene::{Scattering, TriangleMesh};
use arpa_core::shading_normal::ShadedTriangle;
use wgpu::util::DeviceExt;

/// WGSL of the scene on the device (`shaders/scene.wgsl`): the group-0 bindings of
/// [`GpuScene::bind_group_layout`] and `arpa_scene_intersect`, `arpa_scene_occluded`,
/// `arpa_scene_surface` (`ArpaSurface`), `arpa_scene_triangle_vertices`,
/// `arpa_scene_triangle_normals`, `arpa_offset_origin`, the emitters
/// (`arpa_scene_emitters`, `ArpaSceneEmitter`), `arpa_scene_info` and `ARPA_SCENE_T_MAX`
/// (the extent of an unbounded ray). Needs `enable wgpu_ray_query;` at the top of the
/// module and the core twin's [`arpa_core::shaders::MATH`] before it.
pub const SCENE_WGSL: &str = include_str!("shaders/scene.wgsl");

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
    /// More triangles in all than a `u32` counts.
    #[error("the scene has more than 2^32 - 1 triangles")]
    TooManyTriangles,
    /// The device rejected a build.
    #[error(transparent)]
    Device(#[from] HarnessError),
}

/// The scene's triangles on the device: one BLAS per non-empty mesh and a TLAS.
pub struct GpuGeometry {
    blases: Vec<wgpu::Blas>,
    tlas: wgpu::Tlas,
    /// Triangles per mesh (empty meshes get no instance).
    pub triangle_counts: Vec<u32>,
    /// Per mesh: the mesh's triangle index of each BLAS primitive (primitive index ->
    /// triangle index, [`morton_triangle_order`]).
    orders: Vec<Vec<u32>>,
}

/// The order in which a mesh's triangles go into its BLAS: triangle indices sorted by the
/// 30-bit Morton code ([`morton_code`]) of their `f32` centroids in the box of all the
/// mesh's centroids (world space, metres), ties by index. A spatially coherent primitive
/// order keeps the BVH of a builder that does not sort the primitives itself (lavapipe's)
/// fast to traverse; a driver that does sort builds the same BVH either way. Centroids with
/// a non-finite coordinate land in cell 0 of that axis (meshes are validated before upload).
pub fn morton_triangle_order(mesh: &TriangleMesh) -> Vec<u32> {
    let centroid = |t: &[u32; 3]| {
        let [a, b, c] = t.map(|i| mesh.positions.get(i as usize).copied().unwrap_or(Vec3::ZERO));
        (a + b + c) / 3.0
    };
    let centroids: Vec<Vec3> = mesh.indices.iter().map(centroid).collect();
    let lo = centroids.iter().copied().fold(Vec3::INFINITY, Vec3::min);
    let hi = centroids.iter().copied().fold(Vec3::NEG_INFINITY, Vec3::max);
    let extent = hi - lo;
    // A flat (or empty) axis maps every centroid to cell 0.
    let inv = |e: f32| if e > 0.0 && e.is_finite() { 1.0 / e } else { 0.0 };
    let inv_extent = [inv(extent.x), inv(extent.y), inv(extent.z)];
    let lo = if lo.is_finite() { lo } else { Vec3::ZERO };
    let mut keyed: Vec<(u32, u32)> = centroids.iter().zip(0u32..).map(|(c, i)| (morton_code(c.to_array(), lo.to_array(), inv_extent), i)).collect();
    keyed.sort_unstable();
    keyed.into_iter().map(|(_, i)| i).collect()
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

impl GpuGeometry {
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
        let orders: Vec<Vec<u32>> = meshes.iter().map(morton_triangle_order).collect();
        let mut parts = Vec::new();
        for (mi, m) in meshes.iter().enumerate() {
            if m.indices.is_empty() {
                continue;
            }
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
        Ok(Self { blases: parts.into_iter().map(|(_, blas, ..)| blas).collect(), tlas, triangle_counts, orders })
    }

    /// The triangle of mesh `mesh` (index into the mesh's `indices`) that its BLAS holds as
    /// primitive `primitive`; `None` if either is out of range.
    pub fn blas_triangle(&self, mesh: u32, primitive: u32) -> Option<u32> {
        self.orders.get(mesh as usize)?.get(primitive as usize).copied()
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
            .map(|h| {
                // A miss has mesh u32::MAX. The kernel reports the BLAS primitive: map it
                // back to the mesh's triangle.
                let triangle = self.blas_triangle(h.mesh, h.triangle)?;
                Some(RayHit { t: h.t, mesh: h.mesh, triangle, b1: h.b1, b2: h.b2 })
            })
            .collect())
    }
}

/// `ArpaSceneInfo` of `scene.wgsl` (uniform, 32 bytes).
#[repr(C)]
#[derive(Clone, Copy, Debug, bytemuck::Pod, bytemuck::Zeroable)]
struct SceneInfo {
    mesh_count: u32,
    delta_count: u32,
    area_count: u32,
    pad0: u32,
    sphere_centre: [f32; 3],
    sphere_radius: f32,
}

/// `ArpaSceneMesh` of `scene.wgsl` (48 bytes).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, bytemuck::Pod, bytemuck::Zeroable)]
struct SceneMesh {
    first_triangle: u32,
    triangle_count: u32,
    kind: u32,
    emissive: u32,
    color: [f32; 3],
    ior: f32,
    emission: [f32; 3],
    has_normals: u32,
}

/// `ArpaSceneTriangle` of `scene.wgsl` (112 bytes). The table is in the meshes' triangle
/// order; `blas_triangle` of the record at `first_triangle + i` is the triangle of the
/// mesh's BLAS primitive `i` ([`GpuGeometry::blas_triangle`]), read by
/// `arpa_scene_intersect` (it rides in the record's padding so that group 0 keeps three
/// storage buffers: the photon pass binds eight in all, WebGPU's default limit).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, bytemuck::Pod, bytemuck::Zeroable)]
struct SceneTriangle {
    p0: [f32; 3],
    flags: u32,
    p1: [f32; 3],
    blas_triangle: u32,
    p2: [f32; 3],
    pad2: u32,
    normal: [f32; 3],
    pad3: u32,
    n0: [f32; 3],
    pad4: u32,
    n1: [f32; 3],
    pad5: u32,
    n2: [f32; 3],
    pad6: u32,
}

/// `ArpaSceneEmitter` of `scene.wgsl` (80 bytes).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, bytemuck::Pod, bytemuck::Zeroable)]
struct SceneEmitter {
    kind: u32,
    falloff: u32,
    cutoff: f32,
    beam_width: f32,
    p0: [f32; 3],
    cdf: f32,
    p1: [f32; 3],
    probability: f32,
    p2: [f32; 3],
    pad0: f32,
    color: [f32; 3],
    pad1: f32,
}

const TRIANGLE_SHADED: u32 = 1;
const TRIANGLE_NORMALS: u32 = 2;

/// The prepared scene on the device: the [`GpuGeometry`] plus what the passes read at a
/// hit (materials with the roughness cut-off resolved, vertex positions and normals,
/// geometric normals, emission) and the emitters for next-event estimation, all in bind
/// group 0 ([`GpuScene::bind_group_layout`], declared by [`SCENE_WGSL`]). Every value is
/// the core's rounded once to `f32`.
pub struct GpuScene {
    geometry: GpuGeometry,
    layout: wgpu::BindGroupLayout,
    bind_group: wgpu::BindGroup,
    /// Emitters in the device's order: delta lights, then area emitters (indices into
    /// [`arpa_core::prepared_scene::PreparedScene::emitters`]).
    pub emitter_order: Vec<usize>,
}

impl GpuScene {
    /// Uploads `scene` (already validated by [`PreparedScene::new`]) and waits for the
    /// acceleration-structure build.
    pub fn upload(ctx: &GpuContext, scene: &PreparedScene) -> Result<Self, SceneUploadError> {
        let geometry = GpuGeometry::upload(ctx, &scene.scene().meshes)?;
        let device = &ctx.device;
        let label = "scene tables";
        let s = scene.scene();
        let f3 = |v: DVec3| v.as_vec3().to_array();
        let mut meshes = Vec::with_capacity(s.meshes.len());
        let mut triangles = Vec::new();
        for (mi, m) in s.meshes.iter().enumerate() {
            let (kind, color, ior) = match s.materials[m.material as usize].scattering(s.roughness_cutoff) {
                Scattering::Diffuse(c) => (0, c, 1.0),
                Scattering::Mirror(c) => (1, c, 1.0),
                Scattering::Refractive(ior, c) => (2, c, ior),
            };
            let first_triangle = u32::try_from(triangles.len()).map_err(|_| SceneUploadError::TooManyTriangles)?;
            meshes.push(SceneMesh {
                first_triangle,
                triangle_count: m.indices.len() as u32,
                kind,
                emissive: m.emission.is_some() as u32,
                color: color.to_array(),
                ior,
                emission: m.emission.unwrap_or(Vec3::ZERO).to_array(),
                has_normals: m.normals.is_some() as u32,
            });
            for (ti, idx) in m.indices.iter().enumerate() {
                let p = scene.triangle(mi as u32, ti as u32);
                let probe = scene.surface(&RayHit { t: 1.0, mesh: mi as u32, triangle: ti as u32, b1: 0.0, b2: 0.0 });
                let normal = probe.geometric_normal;
                let (n, normals_usable) = match &m.normals {
                    Some(ns) => {
                        let n = idx.map(|i| ns[i as usize]);
                        let usable = ShadedTriangle { p, n: n.map(|v| v.as_dvec3()) }.barycentric_gradients().is_ok();
                        (n.map(|v| v.to_array()), usable)
                    }
                    None => ([f3(normal); 3], false),
                };
                let flags = if scene.has_shading_normals(&probe) { TRIANGLE_SHADED } else { 0 } | if normals_usable { TRIANGLE_NORMALS } else { 0 };
                triangles.push(SceneTriangle {
                    p0: f3(p[0]),
                    p1: f3(p[1]),
                    p2: f3(p[2]),
                    flags,
                    normal: f3(normal),
                    blas_triangle: geometry.orders[mi][ti],
                    n0: n[0],
                    n1: n[1],
                    n2: n[2],
                    ..SceneTriangle::default()
                });
            }
        }
        let emitters = scene.emitters();
        let powers = scene.emitter_powers();
        let (area, cdf) = scene.area_emitter_cdf();
        let total = cdf.last().copied().unwrap_or(0.0);
        let mut order: Vec<usize> = (0..emitters.len()).filter(|&i| !matches!(emitters[i], Light::Triangle(_) | Light::Quad(_))).collect();
        let delta_count = order.len();
        // Without positive total power the core picks no area emitter: upload none.
        let area_count = if total > 0.0 { area.len() } else { 0 };
        order.extend(&area[..area_count]);
        let packed: Vec<SceneEmitter> = order
            .iter()
            .enumerate()
            .map(|(slot, &i)| {
                let (cdf, probability) = if slot >= delta_count { ((cdf[slot - delta_count] / total) as f32, (powers[i] / total) as f32) } else { (0.0, 0.0) };
                let e = SceneEmitter { kind: emitters[i].kind_code(), cdf, probability, ..SceneEmitter::default() };
                match emitters[i] {
                    Light::Point(l) => SceneEmitter { p0: f3(l.position), color: f3(l.intensity), ..e },
                    Light::Spot(l) => SceneEmitter {
                        falloff: l.falloff.code(),
                        cutoff: l.cutoff as f32,
                        beam_width: l.beam_width as f32,
                        p0: f3(l.position),
                        p1: f3(l.direction.normalize_or(DVec3::Z)),
                        color: f3(l.intensity),
                        ..e
                    },
                    Light::Directional(l) => SceneEmitter { p0: f3(l.direction.normalize_or(DVec3::Z)), color: f3(l.irradiance), ..e },
                    Light::Triangle(l) => SceneEmitter { p0: f3(l.p[0]), p1: f3(l.p[1]), p2: f3(l.p[2]), color: f3(l.radiance), ..e },
                    Light::Quad(l) => SceneEmitter { p0: f3(l.origin), p1: f3(l.edge_u), p2: f3(l.edge_v), color: f3(l.radiance), ..e },
                }
            })
            .collect();
        let (centre, radius) = scene.bounding_sphere();
        let info = SceneInfo {
            mesh_count: s.meshes.len() as u32,
            delta_count: delta_count as u32,
            area_count: area_count as u32,
            pad0: 0,
            sphere_centre: f3(centre),
            sphere_radius: radius as f32,
        };
        // Storage bindings must not be empty: one zeroed element where a table is.
        fn non_empty<T: Default + Clone>(mut v: Vec<T>) -> Vec<T> {
            if v.is_empty() {
                v.push(T::default());
            }
            v
        }
        let init = |contents: &[u8], usage| device.create_buffer_init(&wgpu::util::BufferInitDescriptor { label: Some(label), contents, usage });
        let info_buf = init(bytemuck::bytes_of(&info), wgpu::BufferUsages::UNIFORM);
        let mesh_buf = init(bytemuck::cast_slice(&non_empty(meshes)), wgpu::BufferUsages::STORAGE);
        let tri_buf = init(bytemuck::cast_slice(&non_empty(triangles)), wgpu::BufferUsages::STORAGE);
        let emitter_buf = init(bytemuck::cast_slice(&non_empty(packed)), wgpu::BufferUsages::STORAGE);
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
            ],
        });
        Ok(Self { geometry, layout, bind_group, emitter_order: order })
    }

    /// Layout of bind group 0 (what [`SCENE_WGSL`] declares): TLAS, scene info (uniform),
    /// meshes, triangles, emitters (read-only storage); compute stage.
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
