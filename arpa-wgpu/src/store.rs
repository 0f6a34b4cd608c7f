//! The keyed store on the device, on the photon pass's buffers (the core's
//! `store.wgsl`, [`arpa_core::gpu::shaders::STORE`]): raw footprints ([`arpa_core::gpu::layout::KeyedFootprint`],
//! smoothed by the photon pass) go through the twin's heuristics, rejected ones fall back to
//! progressive photons as in [`arpa_core::store`]; they and the pass's progressive photons
//! ([`KeyedPhoton`]), each with its unique photon key, are keyed by `(map, Morton code of
//! the box centre, photon key)`, sorted on the device ([`crate::sort`]) and compacted into
//! sorted record and box buffers: caustic records first, then global ones. The result does
//! not depend on the order the photon pass appended in (bit-identical), and it is spatially
//! sorted for the acceleration-structure build ([`crate::accel`]).
//!
//! The store half runs in the photon pass's submission: the schedule kernel (the core's
//! `schedule.wgsl`) writes its record counts and indirect dispatch sizes from the photon
//! pass's counters on the device ([`MapStore::encode_store`]). The host reads back the
//! pass's and the store's counters together after it (one wait per photon batch): the
//! overflow check, the sort's passes (item counts and tiles, [`MapStore::encode_sort`]) and
//! the acceleration-structure build (wgpu has no indirect build) depend on them.

use arpa_core::store::footprint::PackedFootprint;
use arpa_core::{gpu::layout::{KeyedPhoton, StoreCounts, StoreParams, StoreSettings}, gpu::sort::SortItem};
use arpa_core::gpu::sort::{MAX_SORT_ITEMS, sorted_len};
use crate::sort::RadixScratch;
use arpa_core::store::progressive_photon::PackedPhoton;

/// Bytes of a sorted footprint record ([`PackedFootprint`]).
pub const FOOTPRINT_BYTES: u64 = size_of::<PackedFootprint>() as u64;
/// Bytes of a sorted progressive photon ([`PackedPhoton`]).
pub const PHOTON_BYTES: u64 = size_of::<PackedPhoton>() as u64;
/// Bytes of one acceleration-structure box (min xyz, max xyz, `f32`; metres).
pub const BOX_BYTES: u64 = wgpu::AABB_GEOMETRY_MIN_STRIDE;
const ITEM_BYTES: u64 = size_of::<SortItem>() as u64;

/// Compiled pipelines of the keyed store (one per device).
pub struct StorePipelines {
    layout: wgpu::BindGroupLayout,
    keyed: wgpu::ComputePipeline,
    photon_keys: wgpu::ComputePipeline,
    compact_footprints: wgpu::ComputePipeline,
    compact_photons: wgpu::ComputePipeline,
    pad_items: wgpu::ComputePipeline,
    schedule_layout: wgpu::BindGroupLayout,
    schedule: wgpu::ComputePipeline,
    sorter: crate::sort::Sorter,
}

impl StorePipelines {
    /// Compiles the keyed store's pipelines.
    pub fn new(device: &wgpu::Device) -> Self {
        let label = Some("arpa keyed store");
        let entries: Vec<_> = (0..=12).map(|b| crate::harness::storage_entry(b, b <= 2)).collect();
        let layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor { label, entries: &entries });
        let module = device.create_shader_module(wgpu::ShaderModuleDescriptor { label, source: wgpu::ShaderSource::Wgsl(crate::shaders::store().into()) });
        let pipeline = |entry: &str| crate::harness::pipeline(device, "arpa keyed store", &module, &[Some(&layout)], entry);
        let schedule_label = Some("arpa store schedule");
        let entries = [crate::harness::storage_entry(0, true), crate::harness::storage_entry(1, false), crate::harness::storage_entry(2, false)];
        let schedule_layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor { label: schedule_label, entries: &entries });
        let schedule_module =
            device.create_shader_module(wgpu::ShaderModuleDescriptor { label: schedule_label, source: wgpu::ShaderSource::Wgsl(crate::shaders::schedule().into()) });
        let schedule = crate::harness::pipeline(device, "arpa store schedule", &schedule_module, &[Some(&schedule_layout)], "store_schedule");
        Self {
            schedule_layout,
            schedule,
            keyed: pipeline("store_keyed"),
            photon_keys: pipeline("photon_keys"),
            compact_footprints: pipeline("compact_footprints"),
            compact_photons: pipeline("compact_photons"),
            pad_items: pipeline("pad_items"),
            sorter: crate::sort::Sorter::new(device),
            layout,
        }
    }
}

/// Dispatches `threads` invocations of a 64-wide kernel that linearises a 2D grid
/// (`gid.x + gid.y · groups.x · 64`), so that more than 65 535 workgroups fit.
pub(crate) fn dispatch_linear(pass: &mut wgpu::ComputePass, threads: u32) {
    let groups = threads.div_ceil(arpa_core::gpu::codes::WORKGROUP_SIZE).max(1);
    if groups <= 65_535 {
        pass.dispatch_workgroups(groups, 1, 1);
    } else {
        pass.dispatch_workgroups(32_768, groups.div_ceil(32_768), 1);
    }
}

/// Why the keyed store cannot take a size.
#[derive(Debug, thiserror::Error)]
#[error("keyed store: {0}")]
pub struct StoreSizeError(pub String);

/// The keyed store's device buffers for given input buffers and capacities: slots, sort
/// items, counters and the sorted outputs (see the module docs).
pub struct MapStore {
    raw_capacity: u32,
    photon_capacity: u32,
    params: wgpu::Buffer,
    counts: wgpu::Buffer,
    fp_items: wgpu::Buffer,
    ph_items: wgpu::Buffer,
    /// The radix sort's second item buffer and counters (for either item buffer).
    radix: RadixScratch,
    /// The store half's indirect dispatch arguments (store_keyed, photon_keys), written by
    /// the schedule kernel.
    args: wgpu::Buffer,
    schedule_group: wgpu::BindGroup,
    photons_out_capacity: u32,
    /// Sorted footprint records ([`PackedFootprint`]); the first
    /// [`StoreCounts::total_footprints`] are valid, caustic first.
    pub footprints: wgpu::Buffer,
    /// Their boxes (6 `f32` each: min xyz, max xyz; metres): the AABB build input.
    pub footprint_boxes: wgpu::Buffer,
    /// Sorted progressive photons ([`PackedPhoton`], padding zero); the first
    /// [`StoreCounts::total_photons`] are valid, caustic first.
    pub photons: wgpu::Buffer,
    /// Their boxes (the sphere of the map's progressive radius, padded as in
    /// [`arpa_core::base::aabb::Aabb::padded_f32`]).
    pub photon_boxes: wgpu::Buffer,
    bind_group: wgpu::BindGroup,
}

impl MapStore {
    /// Buffers for up to `raw_capacity` raw footprints in `raw` ([`arpa_core::gpu::layout::KeyedFootprint`]) and
    /// `photon_capacity` progressive photons in `photons` ([`KeyedPhoton`]), appended by the
    /// photon pass whose counters ([`arpa_core::gpu::layout::PhotonCounters`]) are `counters`.
    pub fn new(
        device: &wgpu::Device,
        pipelines: &StorePipelines,
        raw: &wgpu::Buffer,
        photons: &wgpu::Buffer,
        counters: &wgpu::Buffer,
        raw_capacity: u32,
        photon_capacity: u32,
    ) -> Result<Self, StoreSizeError> {
        let total_photons = raw_capacity.checked_add(photon_capacity).filter(|&t| sorted_len(t) <= MAX_SORT_ITEMS);
        let Some(total_photons) = total_photons else {
            return Err(StoreSizeError(format!(
                "{raw_capacity} raw footprints + {photon_capacity} photons exceed the sort's {} items",
                MAX_SORT_ITEMS
            )));
        };
        let limits = device.limits();
        let max_bytes = limits.max_storage_buffer_binding_size.min(limits.max_buffer_size);
        if raw_capacity as u64 * FOOTPRINT_BYTES > max_bytes {
            return Err(StoreSizeError(format!("{raw_capacity} footprint slots of {FOOTPRINT_BYTES} bytes exceed the device's {max_bytes}-byte storage binding")));
        }
        // The sorted photons: as many as one binding holds (the compaction counts any
        // beyond in `StoreCounts::overflowed`).
        let photons_out_capacity = total_photons.min(u32::try_from(max_bytes / PHOTON_BYTES).unwrap_or(u32::MAX));
        let label = Some("arpa keyed store");
        use wgpu::BufferUsages as U;
        let buffer = |items: u32, size: u64, usage| {
            device.create_buffer(&wgpu::BufferDescriptor { label, size: (items.max(1) as u64) * size, usage: U::STORAGE | usage, mapped_at_creation: false })
        };
        let fp_sorted = sorted_len(raw_capacity);
        let ph_sorted = sorted_len(total_photons);
        let fp_slots = buffer(raw_capacity, FOOTPRINT_BYTES, U::empty());
        let fp_box_slots = buffer(raw_capacity, BOX_BYTES, U::empty());
        let ph_extra = buffer(raw_capacity, size_of::<KeyedPhoton>() as u64, U::empty());
        let fp_items = buffer(fp_sorted, ITEM_BYTES, U::COPY_DST);
        let ph_items = buffer(ph_sorted, ITEM_BYTES, U::COPY_DST);
        let counts = buffer(1, size_of::<StoreCounts>() as u64, U::COPY_SRC | U::COPY_DST);
        let params = buffer(1, size_of::<StoreParams>() as u64, U::COPY_DST);
        let footprints = buffer(raw_capacity, FOOTPRINT_BYTES, U::COPY_SRC);
        let footprint_boxes = buffer(raw_capacity, BOX_BYTES, U::COPY_SRC | U::BLAS_INPUT);
        let photons_out = buffer(photons_out_capacity, PHOTON_BYTES, U::COPY_SRC);
        let photon_boxes = buffer(photons_out_capacity, BOX_BYTES, U::COPY_SRC | U::BLAS_INPUT);
        let resources = [
            raw, photons, &params, &fp_slots, &fp_box_slots, &ph_extra, &fp_items, &ph_items, &counts, &footprints, &footprint_boxes, &photons_out,
            &photon_boxes,
        ];
        let entries: Vec<_> = resources.iter().enumerate().map(|(i, b)| wgpu::BindGroupEntry { binding: i as u32, resource: b.as_entire_binding() }).collect();
        let bind_group = device.create_bind_group(&wgpu::BindGroupDescriptor { label, layout: &pipelines.layout, entries: &entries });
        let args = device.create_buffer(&wgpu::BufferDescriptor { label: Some("arpa store dispatch"), size: 24, usage: U::STORAGE | U::INDIRECT, mapped_at_creation: false });
        let entries: Vec<_> = [counters, &params, &args].iter().enumerate().map(|(i, b)| wgpu::BindGroupEntry { binding: i as u32, resource: b.as_entire_binding() }).collect();
        let schedule_group = device.create_bind_group(&wgpu::BindGroupDescriptor { label: Some("arpa store schedule"), layout: &pipelines.schedule_layout, entries: &entries });
        Ok(Self {
            args,
            schedule_group,
            raw_capacity,
            photon_capacity,
            params,
            counts,
            fp_items,
            ph_items,
            radix: RadixScratch::new(device, total_photons),
            photons_out_capacity,
            footprints,
            footprint_boxes,
            photons: photons_out,
            photon_boxes,
            bind_group,
        })
    }

    /// Raw-footprint and photon capacities this store was made for.
    pub fn capacities(&self) -> (u32, u32) {
        (self.raw_capacity, self.photon_capacity)
    }

    /// The counters buffer ([`StoreCounts`], 48 bytes; `COPY_SRC`), valid after the
    /// commands of [`MapStore::encode_store`] ran.
    pub fn counts_buffer(&self) -> &wgpu::Buffer {
        &self.counts
    }

    /// First half, after the photon pass's commands in the same submission: writes this
    /// iteration's parameters (through `queue`, before the next submission; `settings`'
    /// record counts are not used), records the schedule kernel, which sets the record
    /// counts and the dispatch sizes from the photon pass's counters on the device, and the
    /// store and the appending of the sort items (indirect dispatches). Submit it and read
    /// the counts ([`MapStore::counts_buffer`]) before [`MapStore::encode_sort`].
    pub fn encode_store(&self, queue: &wgpu::Queue, pipelines: &StorePipelines, encoder: &mut wgpu::CommandEncoder, settings: &StoreSettings) {
        queue.write_buffer(&self.params, 0, bytemuck::bytes_of(&StoreParams::new(settings, None)));
        encoder.clear_buffer(&self.counts, 0, None);
        let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor { label: Some("arpa keyed store"), timestamp_writes: None });
        pass.set_bind_group(0, &self.schedule_group, &[]);
        pass.set_pipeline(&pipelines.schedule);
        pass.dispatch_workgroups(1, 1, 1);
        pass.set_bind_group(0, &self.bind_group, &[]);
        pass.set_pipeline(&pipelines.keyed);
        pass.dispatch_workgroups_indirect(&self.args, 0);
        pass.set_pipeline(&pipelines.photon_keys);
        pass.dispatch_workgroups_indirect(&self.args, 12);
    }

    /// Second half, with the `counts` read back after [`MapStore::encode_store`]: pads the
    /// appended items to their sorted lengths, sorts the appended ones (the radix sort; the
    /// padding sorts last anyway) and compacts the records.
    pub fn encode_sort(
        &self,
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        pipelines: &StorePipelines,
        encoder: &mut wgpu::CommandEncoder,
        settings: &StoreSettings,
        counts: &StoreCounts,
    ) -> Result<(), StoreSizeError> {
        if counts.total_photons() > self.photons_out_capacity {
            return Err(StoreSizeError(format!(
                "{} progressive photons in one iteration; one storage binding of this device holds {}",
                counts.total_photons(),
                self.photons_out_capacity
            )));
        }
        let params = StoreParams::new(settings, Some(counts));
        queue.write_buffer(&self.params, 0, bytemuck::bytes_of(&params));
        {
            let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor { label: Some("arpa sort padding"), timestamp_writes: None });
            pass.set_bind_group(0, &self.bind_group, &[]);
            pass.set_pipeline(&pipelines.pad_items);
            dispatch_linear(&mut pass, params.fp_sorted.max(params.ph_sorted));
        }
        // Slots: footprints below raw_count, photons below photon_count + raw_count.
        let value_bound = settings.photon_count.saturating_add(settings.raw_count);
        pipelines.sorter.encode_radix(device, encoder, &self.fp_items, &self.radix, params.fp_count, value_bound);
        pipelines.sorter.encode_radix(device, encoder, &self.ph_items, &self.radix, params.ph_count, value_bound);
        let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor { label: Some("arpa compaction"), timestamp_writes: None });
        pass.set_bind_group(0, &self.bind_group, &[]);
        pass.set_pipeline(&pipelines.compact_footprints);
        dispatch_linear(&mut pass, params.fp_sorted);
        pass.set_pipeline(&pipelines.compact_photons);
        dispatch_linear(&mut pass, params.ph_sorted);
        Ok(())
    }
}
