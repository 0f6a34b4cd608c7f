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
//! The whole store runs in the photon pass's submission and nothing of it waits for a count
//! on the host ([`MapStore::encode`]): the schedule kernel (the core's `schedule.wgsl`)
//! writes the store's record counts and indirect dispatch sizes from the photon pass's
//! counters on the device, and the sort and the compaction run over the buffers' capacity
//! ([`StoreParams::new`]): the items past the appended ones are padding that sorts last,
//! and their slots get inactive boxes, so that the acceleration structures are built over
//! the capacity too ([`crate::accel`]).

use arpa_core::store::footprint::PackedFootprint;
use arpa_core::{gpu::layout::{KeyedPhoton, StoreCounts, StoreParams, StoreSettings}, gpu::sort::SortItem};
use arpa_core::gpu::sort::{MAX_SORT_ITEMS, sorted_len};
use arpa_core::gpu::batch::Capacities;
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
    store_check: wgpu::ComputePipeline,
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
        let entries = [crate::harness::storage_entry(0, true), crate::harness::storage_entry(1, false), crate::harness::storage_entry(2, false), crate::harness::storage_entry(3, false), crate::harness::storage_entry(4, true)];
        let schedule_layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor { label: schedule_label, entries: &entries });
        let schedule_module =
            device.create_shader_module(wgpu::ShaderModuleDescriptor { label: schedule_label, source: wgpu::ShaderSource::Wgsl(crate::shaders::schedule().into()) });
        let schedule = crate::harness::pipeline(device, "arpa store schedule", &schedule_module, &[Some(&schedule_layout)], "store_schedule");
        let store_check = crate::harness::pipeline(device, "arpa store check", &schedule_module, &[Some(&schedule_layout)], "store_check");
        Self {
            schedule_layout,
            schedule,
            store_check,
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
    capacities: Capacities,
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
    /// Buffers for `capacities`: raw footprints in `raw` ([`arpa_core::gpu::layout::KeyedFootprint`]) and
    /// progressive photons in `photons` ([`KeyedPhoton`]), appended by the photon pass
    /// whose counters ([`arpa_core::gpu::layout::PhotonCounters`]) are `counters`, and the
    /// photon sort items and sorted photons; the schedule kernel sets the iteration's
    /// `status` word when the pass dropped appends, the store check when the store dropped
    /// photon items.
    #[allow(clippy::too_many_arguments)]
    pub fn new(
        device: &wgpu::Device,
        pipelines: &StorePipelines,
        raw: &wgpu::Buffer,
        photons: &wgpu::Buffer,
        counters: &wgpu::Buffer,
        status: &wgpu::Buffer,
        capacities: Capacities,
    ) -> Result<Self, StoreSizeError> {
        let Capacities { raw_footprints: raw_capacity, sorted_photons, .. } = capacities;
        let sorted_items = raw_capacity.max(sorted_photons);
        if sorted_len(sorted_items) > MAX_SORT_ITEMS {
            return Err(StoreSizeError(format!("{raw_capacity} raw footprints or {sorted_photons} sorted photons exceed the sort's {MAX_SORT_ITEMS} items")));
        }
        let limits = device.limits();
        let max_bytes = limits.max_storage_buffer_binding_size.min(limits.max_buffer_size);
        if raw_capacity as u64 * FOOTPRINT_BYTES > max_bytes {
            return Err(StoreSizeError(format!("{raw_capacity} footprint slots of {FOOTPRINT_BYTES} bytes exceed the device's {max_bytes}-byte storage binding")));
        }
        // The sorted photons: as many as one binding holds (the store and the compaction
        // count any beyond in `StoreCounts::overflowed`).
        let photons_out_capacity = sorted_photons.min(u32::try_from(max_bytes / PHOTON_BYTES).unwrap_or(u32::MAX));
        let label = Some("arpa keyed store");
        use wgpu::BufferUsages as U;
        let buffer = |items: u32, size: u64, usage| {
            device.create_buffer(&wgpu::BufferDescriptor { label, size: (items.max(1) as u64) * size, usage: U::STORAGE | usage, mapped_at_creation: false })
        };
        let fp_slots = buffer(raw_capacity, FOOTPRINT_BYTES, U::empty());
        let fp_box_slots = buffer(raw_capacity, BOX_BYTES, U::empty());
        let ph_extra = buffer(raw_capacity, size_of::<KeyedPhoton>() as u64, U::empty());
        let fp_items = buffer(raw_capacity, ITEM_BYTES, U::COPY_DST);
        let ph_items = buffer(sorted_photons, ITEM_BYTES, U::COPY_DST);
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
        let entries: Vec<_> = [counters, &params, &args, status, &counts].iter().enumerate().map(|(i, b)| wgpu::BindGroupEntry { binding: i as u32, resource: b.as_entire_binding() }).collect();
        let schedule_group = device.create_bind_group(&wgpu::BindGroupDescriptor { label: Some("arpa store schedule"), layout: &pipelines.schedule_layout, entries: &entries });
        Ok(Self {
            args,
            schedule_group,
            capacities,
            params,
            counts,
            fp_items,
            ph_items,
            radix: RadixScratch::new(device, sorted_items),
            photons_out_capacity,
            footprints,
            footprint_boxes,
            photons: photons_out,
            photon_boxes,
            bind_group,
        })
    }

    /// The capacities this store was made for.
    pub fn capacities(&self) -> Capacities {
        self.capacities
    }

    /// Sorted progressive photons one batch can hold (the sorted-photon capacity, capped at
    /// one storage binding; more are counted in [`StoreCounts::overflowed`]).
    pub fn photons_out_capacity(&self) -> u32 {
        self.photons_out_capacity
    }

    /// The counters buffer ([`StoreCounts`], 48 bytes; `COPY_SRC`), valid after the
    /// commands of [`MapStore::encode`] ran.
    pub fn counts_buffer(&self) -> &wgpu::Buffer {
        &self.counts
    }

    /// Records one batch's whole store into the photon pass's `encoder`, after the pass:
    /// writes the parameters (through `queue`, before the next submission; `settings`'
    /// record counts are not used), then the schedule kernel (record counts and dispatch
    /// sizes from the photon pass's counters, the iteration's status), the store and the
    /// sort items (indirect dispatches), the padding of the items up to the capacities, the
    /// radix sort of both item buffers over their capacities, the compaction into the
    /// sorted records and boxes (inactive boxes past the records) and the store check
    /// (the status word, when photon items were dropped). Nothing is read back.
    pub fn encode(&self, device: &wgpu::Device, queue: &wgpu::Queue, pipelines: &StorePipelines, encoder: &mut wgpu::CommandEncoder, settings: &StoreSettings) {
        let c = self.capacities;
        let params = StoreParams::new(settings, c.raw_footprints, c.sorted_photons);
        queue.write_buffer(&self.params, 0, bytemuck::bytes_of(&params));
        encoder.clear_buffer(&self.counts, 0, None);
        {
            let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor { label: Some("arpa keyed store"), timestamp_writes: None });
            pass.set_bind_group(0, &self.schedule_group, &[]);
            pass.set_pipeline(&pipelines.schedule);
            pass.dispatch_workgroups(1, 1, 1);
            pass.set_bind_group(0, &self.bind_group, &[]);
            pass.set_pipeline(&pipelines.keyed);
            pass.dispatch_workgroups_indirect(&self.args, 0);
            pass.set_pipeline(&pipelines.photon_keys);
            pass.dispatch_workgroups_indirect(&self.args, 12);
            pass.set_pipeline(&pipelines.pad_items);
            dispatch_linear(&mut pass, params.fp_sorted.max(params.ph_sorted));
        }
        // Slots: footprints below raw_count, photons below photon_count + raw_count, both
        // within the capacities; the padding's value sorts last with its keys anyway.
        let value_bound = c.raw_footprints.saturating_add(c.photons);
        pipelines.sorter.encode_radix(device, encoder, &self.fp_items, &self.radix, params.fp_sorted, value_bound);
        pipelines.sorter.encode_radix(device, encoder, &self.ph_items, &self.radix, params.ph_sorted, value_bound);
        let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor { label: Some("arpa compaction"), timestamp_writes: None });
        pass.set_bind_group(0, &self.bind_group, &[]);
        pass.set_pipeline(&pipelines.compact_footprints);
        dispatch_linear(&mut pass, params.fp_sorted);
        pass.set_pipeline(&pipelines.compact_photons);
        dispatch_linear(&mut pass, params.ph_sorted);
        pass.set_bind_group(0, &self.schedule_group, &[]);
        pass.set_pipeline(&pipelines.store_check);
        pass.dispatch_workgroups(1, 1, 1);
    }
}

/// Bytes of one batch's counters as the tracer keeps them
/// ([`arpa_core::gpu::layout::BatchCounts`]).
pub const BATCH_COUNTS_BYTES: u64 = size_of::<arpa_core::gpu::layout::BatchCounts>() as u64;
