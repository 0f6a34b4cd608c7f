//! The photon maps' acceleration structure: AABB bottom-level structures over a batch's
//! sorted boxes ([`crate::store::MapStore`], [`crate::maps::BatchMaps`]; one per record kind
//! and map, each a range of the sorted box buffer, no copy) under one top-level structure.
//!
//! Instances: footprints caustic/global, progressive photons caustic/global; the mask is
//! `1 << map` (caustic 1, global 2), the custom index
//! [`INSTANCE_PHOTON_BIT`] (photons) `|` first record index, so the gather (`gather.wgsl`)
//! finds record `(custom & INSTANCE_INDEX_MASK) + primitive_index` of the kind's buffer.
//! Built per iteration from the counts the store read back (wgpu has no indirect build).

use arpa_core::gpu::codes::{INSTANCE_PHOTON_BIT, MAX_RECORDS_PER_KIND};
use arpa_core::gpu::layout::StoreCounts;

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

/// Records the build of the structure over the sorted boxes (`footprint_boxes`,
/// `photon_boxes`: `BLAS_INPUT` buffers of 24-byte boxes) with `counts`.
pub fn build(
    device: &wgpu::Device,
    encoder: &mut wgpu::CommandEncoder,
    footprint_boxes: &wgpu::Buffer,
    photon_boxes: &wgpu::Buffer,
    counts: &StoreCounts,
) -> Result<MapAccel, AccelSizeError> {
    for (records, kind) in [(counts.total_footprints(), "footprints"), (counts.total_photons(), "photons")] {
        if records >= MAX_RECORDS_PER_KIND {
            return Err(AccelSizeError { records, kind });
        }
    }
    let label = Some("arpa photon maps");
    // (buffer, first record, count, custom data, mask)
    let mut ranges = Vec::new();
    for (kind, buffer, per_map) in [(0u32, footprint_boxes, counts.footprints), (INSTANCE_PHOTON_BIT, photon_boxes, counts.photons)] {
        let mut start = 0u32;
        for (map, &n) in per_map.iter().enumerate() {
            if n > 0 {
                ranges.push((buffer, start, n, kind | start, 1u8 << map));
            }
            start += n;
        }
    }
    let sizes: Vec<wgpu::BlasAABBGeometrySizeDescriptor> = ranges
        .iter()
        .map(|r| wgpu::BlasAABBGeometrySizeDescriptor { primitive_count: r.2, flags: wgpu::AccelerationStructureGeometryFlags::NO_DUPLICATE_ANY_HIT_INVOCATION })
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
        max_instances: 4,
        flags: wgpu::AccelerationStructureFlags::PREFER_FAST_TRACE,
        update_mode: wgpu::AccelerationStructureUpdateMode::Build,
    });
    let identity = [1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0];
    for (slot, (blas, r)) in blases.iter().zip(&ranges).enumerate() {
        tlas[slot] = Some(wgpu::TlasInstance::new(blas, identity, r.3, r.4));
    }
    let entries: Vec<wgpu::BlasBuildEntry> = blases
        .iter()
        .zip(&ranges)
        .zip(&sizes)
        .map(|((blas, r), size)| wgpu::BlasBuildEntry {
            blas,
            geometry: wgpu::BlasGeometries::AabbGeometries(vec![wgpu::BlasAabbGeometry {
                size,
                stride: wgpu::AABB_GEOMETRY_MIN_STRIDE,
                aabb_buffer: r.0,
                primitive_offset: r.1 * crate::store::BOX_BYTES as u32,
            }]),
        })
        .collect();
    encoder.build_acceleration_structures(entries.iter(), [&tlas]);
    Ok(MapAccel { tlas, _blases: blases })
}
