//! The photon maps' acceleration structure, built on the device from the sorted box buffers
//! of [`crate::maps::MapStore`] (no host copy of the boxes): one AABB bottom level per
//! non-empty (record kind, map), each over its range of the kind's sorted box buffer (the
//! store sorts caustic records before global ones), and a top level with one instance each.
//!
//! Instances follow the core's convention (`gather.wgsl`, the GLSL hit group): mask
//! `1 << map` (caustic 1, global 2), custom index = kind bit
//! ([`INSTANCE_PHOTON_BIT`] for progressive photons, 0 for footprints) `|` the range's first
//! record, SBT record offset 0, identity transform; so the gather finds record
//! `(custom & INSTANCE_INDEX_MASK) + primitive index` of the kind's record buffer.
//!
//! Bottom levels are built over the valid records only: lavapipe loses real boxes when a
//! geometry also holds inactive (NaN) ones (see [`VkContext::build_aabb_blas`]). An iteration
//! without records gets a top level without instances, which a trace can bind (every ray
//! misses).

use crate::accel::{AabbRange, AccelerationStructure, IDENTITY_TRANSFORM, TlasInstance};
use crate::buffer::Buffer;
use crate::device::VkContext;
use crate::error::VkError;
use arpa_core::gpu::codes::{INSTANCE_PHOTON_BIT, MAX_RECORDS_PER_KIND};
use arpa_core::gpu::layout::StoreCounts;
use ash::vk;

/// One instance of the maps' top level: which records its bottom level holds.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct MapInstance {
    /// `true` for progressive photons, `false` for footprints.
    pub photons: bool,
    /// The photon map (0 caustic, 1 global).
    pub map: u32,
    /// Index of the first record (and box) in the kind's sorted buffer.
    pub first: u32,
    /// Records (boxes) in the bottom level.
    pub count: u32,
}

impl MapInstance {
    /// The instance custom index: kind bit `|` first record.
    pub fn custom_index(&self) -> u32 {
        if self.photons { INSTANCE_PHOTON_BIT | self.first } else { self.first }
    }

    /// The instance mask `1 << map`.
    pub fn mask(&self) -> u8 {
        1 << self.map
    }
}

/// The instances of the maps of `counts` in top-level order: footprints caustic, global, then
/// photons caustic, global, each only when it has records.
pub fn map_instances(counts: &StoreCounts) -> Vec<MapInstance> {
    let mut out = Vec::new();
    for (photons, per_map) in [(false, counts.footprints), (true, counts.photons)] {
        let mut first = 0u32;
        for (map, &count) in per_map.iter().enumerate() {
            if count > 0 {
                out.push(MapInstance { photons, map: map as u32, first, count });
            }
            first += count;
        }
    }
    out
}

/// One iteration's map structure: the top level and the bottom levels it refers to.
pub struct MapAccel {
    /// Dropped first: it refers to the bottom levels.
    tlas: AccelerationStructure,
    blases: Vec<AccelerationStructure>,
    instances: Vec<MapInstance>,
}

impl MapAccel {
    /// Builds the structure over the first records of `footprint_boxes` and `photon_boxes`
    /// (24-byte boxes, metres; usage `ACCELERATION_STRUCTURE_BUILD_INPUT_READ_ONLY_KHR |
    /// SHADER_DEVICE_ADDRESS`, written by an earlier submission that ended with a barrier to
    /// the build stage, as [`crate::maps::MapStore::sort`] does) as `counts` (the store's)
    /// sizes them: the bottom levels in one submission, the top level in another, neither
    /// waited for (queue order runs them before later traces; dropping the structure waits
    /// for them first).
    ///
    /// Errors: [`VkError::InvalidInput`] for a kind with [`MAX_RECORDS_PER_KIND`] records or
    /// more (the custom index holds 23 bits of record index), or counts past a buffer's end;
    /// device errors as [`VkContext::build_aabb_blases`].
    pub fn build(ctx: &VkContext, footprint_boxes: &Buffer, photon_boxes: &Buffer, counts: &StoreCounts) -> Result<Self, VkError> {
        for (records, kind) in [(counts.total_footprints(), "footprints"), (counts.total_photons(), "photons")] {
            if records >= MAX_RECORDS_PER_KIND {
                return Err(VkError::InvalidInput {
                    what: "photon-map acceleration structure".into(),
                    reason: format!("{records} {kind} exceed the {MAX_RECORDS_PER_KIND} one structure indexes"),
                });
            }
        }
        let instances = map_instances(counts);
        let labels: Vec<String> = instances
            .iter()
            .map(|i| format!("{} map {} BLAS", if i.photons { "photon" } else { "footprint" }, i.map))
            .collect();
        let ranges: Vec<AabbRange<'_>> = instances
            .iter()
            .zip(&labels)
            .map(|(i, label)| AabbRange { label, boxes: if i.photons { photon_boxes } else { footprint_boxes }, first: i.first, count: i.count })
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
    fn instances_skip_empty_maps_and_start_each_kind_at_zero() {
        let counts = StoreCounts { footprints: [0, 5], photons: [3, 4], ..Default::default() };
        let i = map_instances(&counts);
        assert_eq!(
            i,
            [
                MapInstance { photons: false, map: 1, first: 0, count: 5 },
                MapInstance { photons: true, map: 0, first: 0, count: 3 },
                MapInstance { photons: true, map: 1, first: 3, count: 4 },
            ]
        );
        assert_eq!((i[0].custom_index(), i[0].mask()), (0, 2));
        assert_eq!((i[2].custom_index(), i[2].mask()), (INSTANCE_PHOTON_BIT | 3, 2));
        assert!(map_instances(&StoreCounts::default()).is_empty());
    }
}
