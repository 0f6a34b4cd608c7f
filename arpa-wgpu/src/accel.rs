//! The photon maps' acceleration structure: one AABB bottom-level structure per record
//! kind over a batch's whole sorted box buffer ([`crate::store::MapStore`],
//! [`crate::maps::BatchMaps`]; no copy), both maps in it, under one top-level structure.
//!
//! The structures are built over the store's capacity, not its counts, so that the build
//! waits for nothing on the host (wgpu has no indirect build): the slots past the records
//! hold inactive boxes, degenerate and outside the scene
//! ([`arpa_core::base::aabb::inactive_point`]), which no point query meets. Instances:
//! footprints and progressive photons, mask `0b11` (both maps), custom index
//! [`INSTANCE_PHOTON_BIT`] for photons `|` first record index 0, so the gather
//! (`gather.wgsl`) finds record `(custom & INSTANCE_INDEX_MASK) + primitive_index` of the
//! kind's buffer and the map in the record.

use arpa_core::gpu::codes::{INSTANCE_PHOTON_BIT, MAX_RECORDS_PER_KIND};

/// Why the structure cannot be built.
#[derive(Debug, thiserror::Error)]
#[error("{records} {kind} exceed the {MAX_RECORDS_PER_KIND} one acceleration structure indexes")]
pub struct AccelSizeError {
    /// Record count.
    pub records: u32,
    /// `"footprints"` or `"photons"`.
    pub kind: &'static str,
}

/// One batch's acceleration structure (keeps its bottom levels alive).
pub struct MapAccel {
    /// The top-level structure the gather binds.
    pub tlas: wgpu::Tlas,
    _blases: Vec<wgpu::Blas>,
}

/// Records the build of the structure over the first `footprints` boxes of
/// `footprint_boxes` and the first `photons` of `photon_boxes` (`BLAS_INPUT` buffers of
/// 24-byte boxes: the store's capacities).
pub fn build(
    device: &wgpu::Device,
    encoder: &mut wgpu::CommandEncoder,
    footprint_boxes: &wgpu::Buffer,
    footprints: u32,
    photon_boxes: &wgpu::Buffer,
    photons: u32,
) -> Result<MapAccel, AccelSizeError> {
    for (records, kind) in [(footprints, "footprints"), (photons, "photons")] {
        if records >= MAX_RECORDS_PER_KIND {
            return Err(AccelSizeError { records, kind });
        }
    }
    let label = Some("arpa photon maps");
    // (buffer, count, custom data)
    let ranges: Vec<(&wgpu::Buffer, u32, u32)> =
        [(footprint_boxes, footprints, 0u32), (photon_boxes, photons, INSTANCE_PHOTON_BIT)].into_iter().filter(|r| r.1 > 0).collect();
    let sizes: Vec<wgpu::BlasAABBGeometrySizeDescriptor> = ranges
        .iter()
        .map(|r| wgpu::BlasAABBGeometrySizeDescriptor { primitive_count: r.1, flags: wgpu::AccelerationStructureGeometryFlags::NO_DUPLICATE_ANY_HIT_INVOCATION })
        .collect();
    let blases: Vec<wgpu::Blas> = sizes
        .iter()
        .map(|size| {
            device.create_blas(
                &wgpu::CreateBlasDescriptor {
                    label,
                    flags: wgpu::AccelerationStructureFlags::PREFER_FAST_TRACE,
                    update_mode: wgpu::AccelerationStructureUpdateMode::Build,
                },
                wgpu::BlasGeometrySizeDescriptors::AABBs { descriptors: vec![size.clone()] },
            )
        })
        .collect();
    let mut tlas = device.create_tlas(&wgpu::CreateTlasDescriptor {
        label,
        max_instances: 2,
        flags: wgpu::AccelerationStructureFlags::PREFER_FAST_TRACE,
        update_mode: wgpu::AccelerationStructureUpdateMode::Build,
    });
    let identity = [1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0];
    for (slot, (blas, r)) in blases.iter().zip(&ranges).enumerate() {
        tlas[slot] = Some(wgpu::TlasInstance::new(blas, identity, r.2, 0b11));
    }
    let entries: Vec<wgpu::BlasBuildEntry> = blases
        .iter()
        .zip(&ranges)
        .zip(&sizes)
        .map(|((blas, r), size)| wgpu::BlasBuildEntry {
            blas,
            geometry: wgpu::BlasGeometries::AabbGeometries(vec![wgpu::BlasAabbGeometry { size, stride: wgpu::AABB_GEOMETRY_MIN_STRIDE, aabb_buffer: r.0, primitive_offset: 0 }]),
        })
        .collect();
    encoder.build_acceleration_structures(entries.iter(), [&tlas]);
    Ok(MapAccel { tlas, _blases: blases })
}
