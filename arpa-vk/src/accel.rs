//! Acceleration structures: triangle bottom levels (one per mesh, triangles in the Morton
//! order of [`morton_triangle_order`]), AABB bottom levels (from `[f32; 6]` boxes), and top
//! levels over instances with a mask, a custom index and a shader-binding-table offset each.
//!
//! Every build takes its sizes from `vkGetAccelerationStructureBuildSizesKHR`, puts each
//! structure in a buffer of its own (device address, `ACCELERATION_STRUCTURE_STORAGE_KHR`),
//! takes scratch memory aligned to the queried `minAccelerationStructureScratchOffsetAlignment`
//! and runs as one submission that the host does not wait for ([`VkContext::submit`]: the
//! scratch and the top level's instance records stay alive with the submission, and the
//! structures and their inputs must outlive it, which dropping them ensures by waiting
//! first). Builds prefer fast tracing; nothing is compacted or updated in place.
//!
//! Each submission ends with a barrier that makes the structures visible to later builds and
//! to ray-tracing shaders, so a top level built after its bottom levels, and a trace after
//! both, read finished structures.

use crate::buffer::{Buffer, KeepAlive};
use crate::device::{Shared, VkContext};
use crate::error::{VkError, VkResultExt};
use arpa_core::gpu::scene::morton_triangle_order;
use arpa_core::render::prepared_scene::PreparedScene;
use arpa_core::render::scene::TriangleMesh;
use ash::vk;
use gpu_allocator::MemoryLocation;
use std::sync::Arc;

/// The identity 3×4 row-major transform of an instance.
pub const IDENTITY_TRANSFORM: [f32; 12] = [1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0];

/// Largest instance custom index and shader-binding-table record offset (24 bits each).
pub const MAX_INSTANCE_FIELD: u32 = (1 << 24) - 1;

/// One built acceleration structure and the buffer that holds it. Dropping it destroys the
/// structure, then frees its buffer; it keeps the device alive until then.
pub struct AccelerationStructure {
    raw: vk::AccelerationStructureKHR,
    loader: ash::khr::acceleration_structure::Device,
    address: vk::DeviceAddress,
    level: vk::AccelerationStructureTypeKHR,
    primitive_count: u32,
    label: String,
    /// Freed after the structure is destroyed (`Drop` runs before the fields drop).
    buffer: Buffer,
    shared: Arc<Shared>,
}

impl std::fmt::Debug for AccelerationStructure {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("AccelerationStructure")
            .field("label", &self.label)
            .field("level", &self.level)
            .field("primitive_count", &self.primitive_count)
            .field("size", &self.buffer.size())
            .finish()
    }
}

impl AccelerationStructure {
    /// The Vulkan handle (for descriptor writes).
    pub fn raw(&self) -> vk::AccelerationStructureKHR {
        self.raw
    }

    /// Its device address (what a top-level instance refers to).
    pub fn device_address(&self) -> vk::DeviceAddress {
        self.address
    }

    /// `BOTTOM_LEVEL_KHR` or `TOP_LEVEL_KHR`.
    pub fn level(&self) -> vk::AccelerationStructureTypeKHR {
        self.level
    }

    /// Triangles, boxes or instances it was built over.
    pub fn primitive_count(&self) -> u32 {
        self.primitive_count
    }

    /// The label given at the build.
    pub fn label(&self) -> &str {
        &self.label
    }

    /// Bytes of its storage buffer (`accelerationStructureSize`).
    pub fn size(&self) -> u64 {
        self.buffer.size()
    }
}

impl Drop for AccelerationStructure {
    fn drop(&mut self) {
        crate::buffer::settle(&self.shared);
        // SAFETY: no submission that used the structure is in flight after `settle`; it is
        // destroyed before its buffer (a field, freed after this).
        unsafe { self.loader.destroy_acceleration_structure(self.raw, None) };
    }
}

/// Bytes of one box of an AABB geometry (`VkAabbPositionsKHR`: min xyz, max xyz, `f32`).
pub const AABB_STRIDE: u64 = 24;

/// A range of boxes in a device buffer, the input of one AABB bottom level
/// ([`VkContext::build_aabb_blases`]).
#[derive(Clone, Copy)]
pub struct AabbRange<'a> {
    /// Names the bottom level.
    pub label: &'a str,
    /// The boxes (`[min x, min y, min z, max x, max y, max z]`, metres, 24 bytes each), with
    /// `ACCELERATION_STRUCTURE_BUILD_INPUT_READ_ONLY_KHR | SHADER_DEVICE_ADDRESS` usage.
    pub boxes: &'a Buffer,
    /// Index of the first box of the range.
    pub first: u32,
    /// Boxes in the range (at least 1).
    pub count: u32,
}

/// One instance of a top-level structure (`VkAccelerationStructureInstanceKHR`).
#[derive(Clone, Copy, Debug)]
pub struct TlasInstance<'a> {
    /// The bottom-level structure it places.
    pub blas: &'a AccelerationStructure,
    /// Object-to-world transform, 3×4 row-major ([`IDENTITY_TRANSFORM`] for world-space
    /// geometry).
    pub transform: [f32; 12],
    /// `InstanceCustomIndexKHR` (WGSL `instance_custom_data`), at most [`MAX_INSTANCE_FIELD`].
    pub custom_index: u32,
    /// Visibility mask, ANDed with the ray's cull mask.
    pub mask: u8,
    /// `instanceShaderBindingTableRecordOffset`: the hit group of this instance's geometry, at
    /// most [`MAX_INSTANCE_FIELD`]. naga's `traceRay` always passes SBT offset 0 and stride 0,
    /// so with naga-compiled ray generation this offset alone selects the hit group.
    pub sbt_record_offset: u32,
    /// Instance flags (e.g. `FORCE_OPAQUE`); empty for none.
    pub flags: vk::GeometryInstanceFlagsKHR,
}

/// `VkAccelerationStructureInstanceKHR` as bytes (64, the bit fields packed low bits first).
#[repr(C)]
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
struct InstanceRecord {
    transform: [f32; 12],
    custom_index_and_mask: u32,
    sbt_offset_and_flags: u32,
    blas_address: u64,
}
const _: () = assert!(std::mem::size_of::<InstanceRecord>() == 64);

/// What one build needs besides its geometry descriptions.
struct BuildRequest {
    label: String,
    level: vk::AccelerationStructureTypeKHR,
    geometry: vk::AccelerationStructureGeometryKHR<'static>,
    primitive_count: u32,
}

fn align_up(x: u64, a: u64) -> u64 {
    x.div_ceil(a) * a
}

/// Bytes of `T`s as the device reads them.
fn input_buffer(ctx: &VkContext, label: &str, bytes: &[u8]) -> Result<Buffer, VkError> {
    let usage = vk::BufferUsageFlags::ACCELERATION_STRUCTURE_BUILD_INPUT_READ_ONLY_KHR | vk::BufferUsageFlags::SHADER_DEVICE_ADDRESS;
    let mut b = ctx.create_buffer(label, bytes.len() as u64, usage, MemoryLocation::CpuToGpu)?;
    b.write(0, bytes)?;
    Ok(b)
}

/// The device address of `b`, checked against the `align` Vulkan asks of build inputs.
fn input_address(b: &Buffer, align: u64) -> Result<vk::DeviceAddress, VkError> {
    let a = b.device_address().unwrap_or(0);
    if a == 0 || !a.is_multiple_of(align) {
        return Err(VkError::InvalidInput { what: b.label().into(), reason: format!("device address {a:#x} is not {align}-byte aligned") });
    }
    Ok(a)
}

impl VkContext {
    fn accel_loader(&self) -> ash::khr::acceleration_structure::Device {
        ash::khr::acceleration_structure::Device::new(self.instance(), self.device())
    }

    /// Builds every request in one submission (each with its own scratch region), not waited
    /// for; the scratch and `keep` live until a later wait finds it done.
    fn build_structures(&self, requests: &[BuildRequest], mut keep: KeepAlive) -> Result<Vec<AccelerationStructure>, VkError> {
        let loader = self.accel_loader();
        let rt = self.ray_tracing();
        let scratch_align = u64::from(rt.min_acceleration_structure_scratch_offset_alignment.max(1));
        let flags = vk::BuildAccelerationStructureFlagsKHR::PREFER_FAST_TRACE;
        let geometries: Vec<[vk::AccelerationStructureGeometryKHR<'static>; 1]> = requests.iter().map(|r| [r.geometry]).collect();
        let mut infos: Vec<vk::AccelerationStructureBuildGeometryInfoKHR<'_>> = requests
            .iter()
            .zip(&geometries)
            .map(|(r, g)| {
                vk::AccelerationStructureBuildGeometryInfoKHR::default()
                    .ty(r.level)
                    .flags(flags)
                    .mode(vk::BuildAccelerationStructureModeKHR::BUILD)
                    .geometries(g)
            })
            .collect();
        let mut built = Vec::with_capacity(requests.len());
        let mut scratch_offsets = Vec::with_capacity(requests.len());
        let mut scratch_total = 0u64;
        for (r, info) in requests.iter().zip(&infos) {
            let mut sizes = vk::AccelerationStructureBuildSizesInfoKHR::default();
            // SAFETY: a complete build description with one geometry and its count.
            unsafe {
                loader.get_acceleration_structure_build_sizes(
                    vk::AccelerationStructureBuildTypeKHR::DEVICE,
                    info,
                    &[r.primitive_count],
                    &mut sizes,
                )
            };
            let usage = vk::BufferUsageFlags::ACCELERATION_STRUCTURE_STORAGE_KHR | vk::BufferUsageFlags::SHADER_DEVICE_ADDRESS;
            let buffer = self.create_buffer(&r.label, sizes.acceleration_structure_size.max(1), usage, MemoryLocation::GpuOnly)?;
            let create = vk::AccelerationStructureCreateInfoKHR::default()
                .buffer(buffer.raw())
                .offset(0)
                .size(sizes.acceleration_structure_size)
                .ty(r.level);
            // SAFETY: the buffer has acceleration-structure storage usage and the size asked for.
            let raw = unsafe { loader.create_acceleration_structure(&create, None) }.vk("vkCreateAccelerationStructureKHR")?;
            // SAFETY: a valid structure of this device.
            let address = unsafe {
                loader.get_acceleration_structure_device_address(
                    &vk::AccelerationStructureDeviceAddressInfoKHR::default().acceleration_structure(raw),
                )
            };
            built.push(AccelerationStructure {
                raw,
                loader: loader.clone(),
                address,
                level: r.level,
                primitive_count: r.primitive_count,
                label: r.label.clone(),
                buffer,
                shared: Arc::clone(&self.shared),
            });
            scratch_offsets.push(scratch_total);
            scratch_total += align_up(sizes.build_scratch_size.max(1), scratch_align);
        }
        let scratch_usage = vk::BufferUsageFlags::STORAGE_BUFFER | vk::BufferUsageFlags::SHADER_DEVICE_ADDRESS;
        let scratch = self.create_buffer(
            "acceleration-structure build scratch",
            scratch_total + scratch_align,
            scratch_usage,
            MemoryLocation::GpuOnly,
        )?;
        let scratch_base = align_up(scratch.device_address().unwrap_or(0), scratch_align);
        for ((info, s), offset) in infos.iter_mut().zip(&built).zip(&scratch_offsets) {
            info.dst_acceleration_structure = s.raw;
            info.scratch_data = vk::DeviceOrHostAddressKHR { device_address: scratch_base + offset };
        }
        let ranges: Vec<[vk::AccelerationStructureBuildRangeInfoKHR; 1]> =
            requests.iter().map(|r| [vk::AccelerationStructureBuildRangeInfoKHR::default().primitive_count(r.primitive_count)]).collect();
        let range_refs: Vec<&[vk::AccelerationStructureBuildRangeInfoKHR]> = ranges.iter().map(|r| &r[..]).collect();
        let device = self.device();
        keep.push(Box::new(scratch));
        self.submit(keep, |cmd| {
            let before = vk::MemoryBarrier::default()
                .src_access_mask(vk::AccessFlags::ACCELERATION_STRUCTURE_WRITE_KHR)
                .dst_access_mask(vk::AccessFlags::ACCELERATION_STRUCTURE_READ_KHR);
            let after = vk::MemoryBarrier::default()
                .src_access_mask(vk::AccessFlags::ACCELERATION_STRUCTURE_WRITE_KHR)
                .dst_access_mask(vk::AccessFlags::ACCELERATION_STRUCTURE_READ_KHR | vk::AccessFlags::SHADER_READ);
            // SAFETY: every structure and input is alive until a wait finds the submission
            // done (dropping one waits first) and the scratch lives with the submission;
            // scratch regions do not overlap.
            unsafe {
                // Earlier builds (bottom levels this top level refers to) finish first.
                device.cmd_pipeline_barrier(
                    cmd,
                    vk::PipelineStageFlags::ACCELERATION_STRUCTURE_BUILD_KHR,
                    vk::PipelineStageFlags::ACCELERATION_STRUCTURE_BUILD_KHR,
                    vk::DependencyFlags::empty(),
                    &[before],
                    &[],
                    &[],
                );
                loader.cmd_build_acceleration_structures(cmd, &infos, &range_refs);
                device.cmd_pipeline_barrier(
                    cmd,
                    vk::PipelineStageFlags::ACCELERATION_STRUCTURE_BUILD_KHR,
                    vk::PipelineStageFlags::ACCELERATION_STRUCTURE_BUILD_KHR | vk::PipelineStageFlags::RAY_TRACING_SHADER_KHR,
                    vk::DependencyFlags::empty(),
                    &[after],
                    &[],
                    &[],
                );
            }
        })?;
        Ok(built)
    }

    /// Builds one triangle bottom level per mesh with triangles (`None` for empty meshes), in
    /// one submission: mesh `m`'s primitive `i` is its triangle `orders[m][i]` (positions
    /// `f32`, world space; `orders` from [`morton_triangle_order`], which lavapipe needs since
    /// it does not sort primitives itself). The geometry is `OPAQUE`, right for the scene's
    /// triangles (no any-hit shader runs on them).
    ///
    /// Errors: [`VkError::InvalidInput`] for an order that is not a permutation of the mesh's
    /// triangles, a vertex index out of range, a non-finite vertex or more triangles than
    /// `maxPrimitiveCount`; device errors as [`VkContext::create_buffer`].
    pub fn build_triangle_blases(
        &self,
        meshes: &[&TriangleMesh],
        orders: &[Vec<u32>],
    ) -> Result<Vec<Option<AccelerationStructure>>, VkError> {
        let max = self.ray_tracing().max_primitive_count;
        let mut inputs = Vec::new();
        let mut requests = Vec::new();
        let mut slots = Vec::with_capacity(meshes.len());
        for (mi, m) in meshes.iter().enumerate() {
            let what = || format!("triangle BLAS of mesh {mi} ({:?})", m.name);
            let invalid = |reason: String| VkError::InvalidInput { what: what(), reason };
            if m.indices.is_empty() {
                slots.push(None);
                continue;
            }
            let order = orders.get(mi).ok_or_else(|| invalid("no triangle order".into()))?;
            let mut seen = vec![false; m.indices.len()];
            if order.len() != m.indices.len()
                || !order.iter().all(|&t| seen.get_mut(t as usize).is_some_and(|s| !std::mem::replace(s, true)))
            {
                return Err(invalid(format!("the order is not a permutation of its {} triangles", m.indices.len())));
            }
            if m.indices.len() as u64 > max {
                return Err(invalid(format!("{} triangles exceed maxPrimitiveCount {max}", m.indices.len())));
            }
            if let Some(v) = m.positions.iter().position(|p| !p.is_finite()) {
                return Err(invalid(format!("vertex {v} is not finite")));
            }
            if let Some((t, i)) =
                m.indices.iter().enumerate().find_map(|(t, ix)| ix.iter().find(|&&i| i as usize >= m.positions.len()).map(|&i| (t, i)))
            {
                return Err(invalid(format!("triangle {t} uses vertex {i} of {}", m.positions.len())));
            }
            let sorted: Vec<[u32; 3]> = order.iter().map(|&t| m.indices[t as usize]).collect();
            let vertices: Vec<[f32; 3]> = m.positions.iter().map(|p| p.to_array()).collect();
            let vb = input_buffer(self, &format!("{} vertices", what()), bytemuck::cast_slice(&vertices))?;
            let ib = input_buffer(self, &format!("{} indices", what()), bytemuck::cast_slice(&sorted))?;
            let triangles = vk::AccelerationStructureGeometryTrianglesDataKHR::default()
                .vertex_format(vk::Format::R32G32B32_SFLOAT)
                .vertex_data(vk::DeviceOrHostAddressConstKHR { device_address: input_address(&vb, 4)? })
                .vertex_stride(12)
                .max_vertex(vertices.len() as u32 - 1)
                .index_type(vk::IndexType::UINT32)
                .index_data(vk::DeviceOrHostAddressConstKHR { device_address: input_address(&ib, 4)? });
            let geometry = vk::AccelerationStructureGeometryKHR::default()
                .geometry_type(vk::GeometryTypeKHR::TRIANGLES)
                .geometry(vk::AccelerationStructureGeometryDataKHR { triangles })
                .flags(vk::GeometryFlagsKHR::OPAQUE);
            slots.push(Some(requests.len()));
            requests.push(BuildRequest {
                label: what(),
                level: vk::AccelerationStructureTypeKHR::BOTTOM_LEVEL,
                geometry,
                primitive_count: sorted.len() as u32,
            });
            inputs.push((vb, ib));
        }
        // The inputs live with the submission.
        let keep: KeepAlive = inputs.into_iter().map(|i| Box::new(i) as Box<dyn std::any::Any + Send>).collect();
        let mut built: Vec<Option<AccelerationStructure>> =
            if requests.is_empty() { Vec::new() } else { self.build_structures(&requests, keep)?.into_iter().map(Some).collect() };
        Ok(slots.into_iter().map(|s| s.and_then(|i| built[i].take())).collect())
    }

    /// Builds a bottom level over axis-aligned boxes (`[min x, min y, min z, max x, max y,
    /// max z]`, `VkAabbPositionsKHR`), one primitive per box, in one submission.
    ///
    /// The geometry is **not** `OPAQUE` and has `NO_DUPLICATE_ANY_HIT_INVOCATION`: the gather's
    /// any-hit shader must run exactly once per box a ray reaches (an opaque geometry, or the
    /// opaque ray flag, would skip any-hit and collect nothing). Vulkan makes a box whose
    /// min x is NaN an inactive primitive, but lavapipe mishandles them: with inactive boxes
    /// after the real ones, traversal misses many real boxes. Unused slots therefore get
    /// degenerate boxes outside the scene instead ([`arpa_core::base::aabb::inactive_point`]),
    /// which lavapipe traverses without losing real boxes. (Unchecked on a GPU.)
    ///
    /// Errors: [`VkError::InvalidInput`] for no boxes or more than `maxPrimitiveCount`.
    pub fn build_aabb_blas(&self, label: &str, boxes: &[[f32; 6]]) -> Result<AccelerationStructure, VkError> {
        let max = self.ray_tracing().max_primitive_count;
        if boxes.is_empty() || boxes.len() as u64 > max {
            return Err(VkError::InvalidInput {
                what: label.into(),
                reason: format!("{} boxes (1 to maxPrimitiveCount {max} allowed)", boxes.len()),
            });
        }
        let b = input_buffer(self, &format!("{label} boxes"), bytemuck::cast_slice(boxes))?;
        let range = AabbRange { label, boxes: &b, first: 0, count: boxes.len() as u32 };
        let mut built = self.build_aabb_blases(std::slice::from_ref(&range))?;
        drop(b);
        Ok(built.remove(0))
    }

    /// Builds one AABB bottom level per range of boxes already on the device (e.g. the
    /// sorted box buffers of [`crate::maps::MapStore`]), all in one submission, without
    /// copying them: range `r`'s geometry reads `r.count` boxes of [`AABB_STRIDE`] bytes from
    /// `r.boxes`' device address + `r.first` × 24. Geometry flags as
    /// [`VkContext::build_aabb_blas`] (not opaque, no duplicate any-hit). The boxes must have
    /// been written before this call's submission with a barrier to the build stage (e.g.
    /// [`crate::compute::record_compute_barrier`]).
    ///
    /// Errors: [`VkError::InvalidInput`] for an empty range or one beyond
    /// `maxPrimitiveCount` or past the buffer's end, or a buffer without
    /// `ACCELERATION_STRUCTURE_BUILD_INPUT_READ_ONLY_KHR` and `SHADER_DEVICE_ADDRESS` usage;
    /// device errors as [`VkContext::create_buffer`].
    pub fn build_aabb_blases(&self, ranges: &[AabbRange<'_>]) -> Result<Vec<AccelerationStructure>, VkError> {
        let max = self.ray_tracing().max_primitive_count;
        let needed = vk::BufferUsageFlags::ACCELERATION_STRUCTURE_BUILD_INPUT_READ_ONLY_KHR | vk::BufferUsageFlags::SHADER_DEVICE_ADDRESS;
        let mut requests = Vec::with_capacity(ranges.len());
        for r in ranges {
            let invalid = |reason: String| VkError::InvalidInput { what: r.label.into(), reason };
            if r.count == 0 || u64::from(r.count) > max {
                return Err(invalid(format!("{} boxes (1 to maxPrimitiveCount {max} allowed)", r.count)));
            }
            if !r.boxes.usage().contains(needed) {
                return Err(invalid(format!("box buffer {:?} lacks BUILD_INPUT_READ_ONLY and SHADER_DEVICE_ADDRESS usage", r.boxes.label())));
            }
            let end = (u64::from(r.first) + u64::from(r.count)) * AABB_STRIDE;
            if end > r.boxes.size() {
                return Err(invalid(format!("boxes {}..{} past the {}-byte buffer {:?}", r.first, r.first + r.count, r.boxes.size(), r.boxes.label())));
            }
            let address = input_address(r.boxes, 8)? + u64::from(r.first) * AABB_STRIDE;
            let aabbs = vk::AccelerationStructureGeometryAabbsDataKHR::default()
                .data(vk::DeviceOrHostAddressConstKHR { device_address: address })
                .stride(AABB_STRIDE);
            let geometry = vk::AccelerationStructureGeometryKHR::default()
                .geometry_type(vk::GeometryTypeKHR::AABBS)
                .geometry(vk::AccelerationStructureGeometryDataKHR { aabbs })
                .flags(vk::GeometryFlagsKHR::NO_DUPLICATE_ANY_HIT_INVOCATION);
            requests.push(BuildRequest {
                label: r.label.into(),
                level: vk::AccelerationStructureTypeKHR::BOTTOM_LEVEL,
                geometry,
                primitive_count: r.count,
            });
        }
        if requests.is_empty() {
            return Ok(Vec::new());
        }
        self.build_structures(&requests, KeepAlive::new())
    }

    /// Builds a top level over `instances` (possibly none) in one submission, after every
    /// build submitted before.
    ///
    /// Errors: [`VkError::InvalidInput`] for a bottom level that is not one, a custom index
    /// or SBT offset above [`MAX_INSTANCE_FIELD`], or more instances than `maxInstanceCount`.
    pub fn build_tlas(&self, label: &str, instances: &[TlasInstance<'_>]) -> Result<AccelerationStructure, VkError> {
        let invalid = |reason: String| VkError::InvalidInput { what: label.into(), reason };
        if instances.len() as u64 > self.ray_tracing().max_instance_count {
            return Err(invalid(format!(
                "{} instances exceed maxInstanceCount {}",
                instances.len(),
                self.ray_tracing().max_instance_count
            )));
        }
        let mut records = Vec::with_capacity(instances.len().max(1));
        for (i, inst) in instances.iter().enumerate() {
            if inst.blas.level != vk::AccelerationStructureTypeKHR::BOTTOM_LEVEL {
                return Err(invalid(format!("instance {i} refers to a top-level structure")));
            }
            if inst.custom_index > MAX_INSTANCE_FIELD || inst.sbt_record_offset > MAX_INSTANCE_FIELD {
                return Err(invalid(format!(
                    "instance {i}: custom index {} or SBT offset {} above 2^24 - 1",
                    inst.custom_index, inst.sbt_record_offset
                )));
            }
            records.push(InstanceRecord {
                transform: inst.transform,
                custom_index_and_mask: inst.custom_index | (u32::from(inst.mask) << 24),
                sbt_offset_and_flags: inst.sbt_record_offset | ((inst.flags.as_raw() & 0xff) << 24),
                blas_address: inst.blas.address,
            });
        }
        // Buffers hold at least one byte: an empty top level reads a zeroed record it never uses.
        if records.is_empty() {
            records.push(bytemuck::Zeroable::zeroed());
        }
        let b = input_buffer(self, &format!("{label} instances"), bytemuck::cast_slice(&records))?;
        let data = vk::AccelerationStructureGeometryInstancesDataKHR::default()
            .array_of_pointers(false)
            .data(vk::DeviceOrHostAddressConstKHR { device_address: input_address(&b, 16)? });
        let geometry = vk::AccelerationStructureGeometryKHR::default()
            .geometry_type(vk::GeometryTypeKHR::INSTANCES)
            .geometry(vk::AccelerationStructureGeometryDataKHR { instances: data });
        let request = BuildRequest {
            label: label.into(),
            level: vk::AccelerationStructureTypeKHR::TOP_LEVEL,
            geometry,
            primitive_count: instances.len() as u32,
        };
        // The instance records live with the submission.
        let mut built = self.build_structures(std::slice::from_ref(&request), vec![Box::new(b)])?;
        Ok(built.remove(0))
    }
}

/// The triangles of a prepared scene on the device: one triangle bottom level per mesh with
/// triangles, except the copies of shared geometry ([`Scene::instancing`], prototypes
/// placed at least twice, [`Instancing::copies`]): one bottom level per prototype mesh (in
/// its object space), which each copy's instance places by its transform. The top level has
/// one instance per mesh with triangles (custom index = mesh index, mask `0xff`, SBT record
/// offset as given, identity transform or the copy's). The closest-hit shader recomputes
/// the barycentric weights from the mesh's world-space triangle and the world ray, so a hit
/// through an instance shades as the flattened copy's does.
///
/// [`Scene::instancing`]: arpa_core::render::scene::Scene::instancing
/// [`Instancing::copies`]: arpa_core::render::scene::Instancing::copies
pub struct SceneAccel {
    /// Dropped first: it refers to the bottom levels.
    tlas: AccelerationStructure,
    /// The bottom levels: the stand-alone meshes' and the prototype meshes'.
    blases: Vec<Option<AccelerationStructure>>,
    /// Per mesh, its bottom level in `blases`.
    blas_of: Vec<usize>,
    orders: Vec<Vec<u32>>,
}

impl SceneAccel {
    /// Builds the structures of `scene` (the bottom levels in one submission, the top level in
    /// another) and waits for them.
    pub fn build(ctx: &VkContext, scene: &PreparedScene) -> Result<Self, VkError> {
        Self::build_with_sbt_offsets(ctx, scene, |_| 0)
    }

    /// [`SceneAccel::build`] with mesh `i`'s instance taking SBT record offset
    /// `sbt_offset(i)` (which hit group its hits run).
    pub fn build_with_sbt_offsets(ctx: &VkContext, scene: &PreparedScene, sbt_offset: impl Fn(usize) -> u32) -> Result<Self, VkError> {
        let meshes = &scene.scene().meshes;
        if meshes.len() > MAX_INSTANCE_FIELD as usize {
            return Err(VkError::InvalidInput {
                what: "scene".into(),
                reason: format!("{} meshes; instance custom indices hold 2^24 - 1", meshes.len()),
            });
        }
        let instancing = scene.scene().instancing.as_ref();
        let copies = instancing.map(|i| i.copies(meshes.len())).unwrap_or_default();
        // The prototype meshes that copies place, once each, in object space.
        let mut prototype_meshes: Vec<TriangleMesh> = Vec::new();
        let mut prototype_source: std::collections::HashMap<(u32, u32), usize> = std::collections::HashMap::new();
        let mut placement = Vec::with_capacity(meshes.len());
        for (mi, m) in meshes.iter().enumerate() {
            match (copies.get(mi).copied().flatten(), instancing) {
                (Some((i, k)), Some(inst)) => {
                    let instance = &inst.instances[i as usize];
                    let p = *prototype_source.entry((instance.prototype, k)).or_insert_with(|| {
                        let pm = &inst.prototypes[instance.prototype as usize].meshes[k as usize];
                        prototype_meshes.push(TriangleMesh { name: m.name.clone(), positions: pm.positions.clone(), normals: None, uvs: None, indices: pm.indices.clone(), material: m.material, emission: None });
                        prototype_meshes.len() - 1
                    });
                    placement.push((Some(p), rows(&instance.to_world)));
                }
                _ => placement.push((None, IDENTITY_TRANSFORM)),
            }
        }
        // The bottom levels' sources: the stand-alone meshes, then the prototype meshes.
        let mut sources: Vec<&TriangleMesh> = Vec::new();
        let mut blas_of = Vec::with_capacity(meshes.len());
        for (m, (p, _)) in meshes.iter().zip(&placement) {
            if p.is_none() {
                blas_of.push(sources.len());
                sources.push(m);
            } else {
                blas_of.push(usize::MAX);
            }
        }
        let first_prototype = sources.len();
        sources.extend(prototype_meshes.iter());
        for (b, (p, _)) in blas_of.iter_mut().zip(&placement) {
            if let Some(p) = p {
                *b = first_prototype + p;
            }
        }
        let source_orders: Vec<Vec<u32>> = sources.iter().map(|m| morton_triangle_order(m)).collect();
        let blases = ctx.build_triangle_blases(&sources, &source_orders)?;
        let transforms: Vec<[f32; 12]> = placement.iter().map(|p| p.1).collect();
        let instances: Vec<TlasInstance<'_>> = (0..meshes.len())
            .filter_map(|mi| {
                blases[blas_of[mi]].as_ref().map(|blas| TlasInstance {
                    blas,
                    transform: transforms[mi],
                    custom_index: mi as u32,
                    mask: 0xff,
                    sbt_record_offset: sbt_offset(mi),
                    flags: vk::GeometryInstanceFlagsKHR::empty(),
                })
            })
            .collect();
        let tlas = ctx.build_tlas("scene TLAS", &instances)?;
        let orders = blas_of.iter().map(|&b| source_orders[b].clone()).collect();
        Ok(Self { tlas, blases, blas_of, orders })
    }

    /// The top level (custom index = mesh index).
    pub fn tlas(&self) -> &AccelerationStructure {
        &self.tlas
    }

    /// Mesh `mesh`'s bottom level (its prototype mesh's, for a copy), `None` for a mesh
    /// without triangles (or out of range).
    pub fn blas(&self, mesh: usize) -> Option<&AccelerationStructure> {
        self.blases.get(*self.blas_of.get(mesh)?).and_then(|b| b.as_ref())
    }

    /// Meshes with triangles (instances of the top level).
    pub fn instance_count(&self) -> usize {
        self.blas_of.iter().filter(|&&b| self.blases[b].is_some()).count()
    }

    /// Bottom levels built (fewer than [`SceneAccel::instance_count`] where copies share
    /// their prototype's).
    pub fn blas_count(&self) -> usize {
        self.blases.iter().filter(|b| b.is_some()).count()
    }

    /// Per mesh, the mesh's triangle at each primitive of its bottom level (what
    /// [`arpa_core::gpu::scene::SceneTables::new`] takes).
    pub fn triangle_orders(&self) -> &[Vec<u32>] {
        &self.orders
    }

    /// The mesh's triangle index of primitive `primitive` of mesh `mesh`'s bottom level.
    pub fn mesh_triangle(&self, mesh: u32, primitive: u32) -> Option<u32> {
        self.orders.get(mesh as usize)?.get(primitive as usize).copied()
    }
}

/// An affine map as the rows of its 3×4 matrix in `f32` (`VkTransformMatrixKHR`).
fn rows(m: &arpa_core::glam::DAffine3) -> [f32; 12] {
    let (a, t) = (m.matrix3, m.translation);
    let r = |i: usize| [a.x_axis[i] as f32, a.y_axis[i] as f32, a.z_axis[i] as f32, t[i] as f32];
    let [r0, r1, r2] = [r(0), r(1), r(2)];
    [r0[0], r0[1], r0[2], r0[3], r1[0], r1[1], r1[2], r1[3], r2[0], r2[1], r2[2], r2[3]]
}
