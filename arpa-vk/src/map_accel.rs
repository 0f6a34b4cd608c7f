//! The photon maps' acceleration structure, built on the device from the sorted box buffers
//! of [`crate::maps::MapStore`] (no host copy of the boxes): one AABB bottom level per record
//! kind over the kind's whole box buffer, both maps in it, and a top level with one
//! instance each.
//!
//! The structures are built over the store's capacities, not its counts, so that nothing
//! waits for a count on the host: the slots past the records hold inactive boxes,
//! degenerate and outside the scene ([`arpa_core::base::aabb::inactive_point`]), which no
//! point query meets (not NaN boxes: lavapipe loses real boxes when a geometry also holds
//! NaN ones, see [`VkContext::build_aabb_blas`]). Vulkan's indirect build would take the
//! primitive counts from the device instead (`accelerationStructureIndirectBuild`,
//! [`crate::DeviceInfo::acceleration_structure_indirect_build`]; lavapipe lacks it), but
//! the structures' sizes would still be those of the capacities.
//!
//! Instances follow the core's convention (`gather.wgsl`, the GLSL hit group): mask `0b11`
//! (both maps), custom index = kind bit ([`INSTANCE_PHOTON_BIT`] for progressive photons, 0
//! for footprints) `|` first record 0, SBT record offset 0, identity transform; so the
//! gather finds record `(custom & INSTANCE_INDEX_MASK) + primitive index` of the kind's
//! record buffer, and the map in the record.

use crate::accel::{AabbRange, AccelerationStructure, IDENTITY_TRANSFORM, TlasInstance};
use crate::buffer::Buffer;
use crate::device::VkContext;
use crate::error::VkError;
use arpa_core::gpu::codes::{INSTANCE_PHOTON_BIT, MAX_RECORDS_PER_KIND};
use ash::vk;

/// One instance of the maps' top level: which records its bottom level holds.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct MapInstance {
    /// `true` for progressive photons, `false` for footprints.
    pub photons: bool,
    /// Boxes in the bottom level (the kind's capacity; records first, then inactive boxes).
    pub count: u32,
}

impl MapInstance {
    /// The instance custom index: the kind bit (the first record is 0).
    pub fn custom_index(&self) -> u32 {
        if self.photons { INSTANCE_PHOTON_BIT } else { 0 }
    }

    /// The instance mask: both maps.
    pub fn mask(&self) -> u8 {
        0b11
    }
}

/// The instances over `footprints` and `photons` boxes in top-level order (footprints, then
/// photons), each only when it has boxes.
pub fn map_instances(footprints: u32, photons: u32) -> Vec<MapInstance> {
    [MapInstance { photons: false, count: footprints }, MapInstance { photons: true, count: photons }].into_iter().filter(|i| i.count > 0).collect()
}

/// One iteration's map structure: the top level and the bottom levels it refers to.
pub struct MapAccel {
    /// Dropped first: it refers to the bottom levels.
    tlas: AccelerationStructure,
    blases: Vec<AccelerationStructure>,
    instances: Vec<MapInstance>,
}

impl MapAccel {
    /// Builds the structure over the first `footprints` boxes of `footprint_boxes` and the
    /// first `photons` of `photon_boxes` (24-byte boxes, metres; usage
    /// `ACCELERATION_STRUCTURE_BUILD_INPUT_READ_ONLY_KHR | SHADER_DEVICE_ADDRESS`, written by
    /// an earlier submission that ended with a barrier to the build stage, as
    /// [`crate::maps::MapStore::record_batch`] does; the store's capacities): the bottom
    /// levels in one submission, the top level in another, neither waited for (queue order
    /// runs them before later traces; dropping the structure waits for them first).
    ///
    /// Errors: [`VkError::InvalidInput`] for a kind with [`MAX_RECORDS_PER_KIND`] records or
    /// more (the custom index holds 23 bits of record index), or counts past a buffer's end;
    /// device errors as [`VkContext::build_aabb_blases`].
    pub fn build(ctx: &VkContext, footprint_boxes: &Buffer, footprints: u32, photon_boxes: &Buffer, photons: u32) -> Result<Self, VkError> {
        for (records, kind) in [(footprints, "footprints"), (photons, "photons")] {
            if records >= MAX_RECORDS_PER_KIND {
                return Err(VkError::InvalidInput {
                    what: "photon-map acceleration structure".into(),
                    reason: format!("{records} {kind} exceed the {MAX_RECORDS_PER_KIND} one structure indexes"),
                });
            }
        }
        let instances = map_instances(footprints, photons);
        let labels: Vec<String> = instances.iter().map(|i| format!("{} BLAS", if i.photons { "photon" } else { "footprint" })).collect();
        let ranges: Vec<AabbRange<'_>> = instances
            .iter()
            .zip(&labels)
            .map(|(i, label)| AabbRange { label, boxes: if i.photons { photon_boxes } else { footprint_boxes }, first: 0, count: i.count })
            .collect();
        let blases = ctx.build_aabb_blases(&ranges)?;
        let tlas_instances: Vec<TlasInstance<'_>> = blases
            .iter()
            .zip(&instances)
            .map(|(blas, i)| TlasInstance {
                blas,
                transform: IDENTITY_TRANSFORM,
                custom_index: i.custom_index(),
                mask: i.mask(),
                sbt_record_offset: 0,
                flags: vk::GeometryInstanceFlagsKHR::empty(),
            })
            .collect();
        let tlas = ctx.build_tlas("photon-map TLAS", &tlas_instances)?;
        Ok(Self { tlas, blases, instances })
    }

    /// The top level the gather binds.
    pub fn tlas(&self) -> &AccelerationStructure {
        &self.tlas
    }

    /// The instances, in top-level order (bottom level `i` is instance `i`'s).
    pub fn instances(&self) -> &[MapInstance] {
        &self.instances
    }

    /// The bottom levels, one per instance.
    pub fn blases(&self) -> &[AccelerationStructure] {
        &self.blases
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn instances_skip_empty_kinds() {
        let i = map_instances(0, 7);
        assert_eq!(i, [MapInstance { photons: true, count: 7 }]);
        assert_eq!((i[0].custom_index(), i[0].mask()), (INSTANCE_PHOTON_BIT, 0b11));
        assert_eq!(map_instances(5, 7)[0].custom_index(), 0);
        assert!(map_instances(0, 0).is_empty());
    }
}
