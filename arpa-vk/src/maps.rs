//! The keyed store, sort and compaction of one iteration's photon maps on the device: a port
//! of arpa-wgpu's `store.rs`, `sort.rs` and `maps.rs` without photon batches (one batch per
//! iteration), running the core's WGSL kernels (`path/store.wgsl`, `path/radix.wgsl`,
//! [`arpa_core::gpu::shaders::STORE`], [`arpa_core::gpu::shaders::RADIX`]) as compute
//! pipelines; the bitonic sort (`path/sort.wgsl`) stays available through
//! [`StorePipelines::sort_items`] (same order; tests and the sort benchmark).
//!
//! Raw footprints ([`KeyedFootprint`], smoothed by the photon pass) go through the twin's
//! heuristics; rejected ones fall back to progressive photons as in [`arpa_core::store`].
//! They and the pass's progressive photons ([`KeyedPhoton`]) are keyed by
//! `(map << 30 | Morton code of the box centre, unique photon key, slot)`, radix-sorted on
//! the device ([`arpa_core::gpu::sort`]) and compacted into sorted record buffers
//! ([`PackedFootprint`], [`PackedPhoton`]) and box buffers (6 `f32` per record: min xyz then
//! max xyz, metres, stride [`BOX_BYTES`]): caustic records first, then global ones. The order
//! is total, so the result does not depend on the order the photon pass appended in, and it
//! is spatial, which the acceleration-structure build needs ([`crate::map_accel`]).
//!
//! Nothing of it waits for a count on the host: the tracer records a batch's whole store
//! into the photon pass's submission ([`MapStore::prepare_batch`],
//! [`MapStore::record_batch`]): the schedule kernel (`path/schedule.wgsl`) takes the record
//! counts and dispatch sizes from the pass's counters on the device (and sets the
//! iteration's status word when the pass dropped appends), the padding reads the appended
//! counts from the store's counters, and the sort and the compaction run over the
//! capacities, writing inactive boxes past the records, so that the acceleration structures
//! are built over the capacities too ([`crate::map_accel`]). [`MapStore::store`] and
//! [`MapStore::sort`] are the two halves on counts the host gives, each in a submission of
//! its own and waited for (tests). The store's parameters ([`StoreParams`], a storage
//! buffer in `store.wgsl`) go through a small host-visible buffer per submission; the
//! sort's pass (a uniform in `radix.wgsl`, read at dynamic offsets on wgpu) is written into
//! one uniform buffer with `vkCmdUpdateBuffer` before each pass's dispatches.

use std::sync::Arc;
use crate::buffer::Buffer;
use crate::compute::{ComputePipeline, ComputePipelineDesc, record_compute_barrier, record_fill};
use crate::device::VkContext;
use crate::error::VkError;
use crate::pipeline::{BindingKind, Bindings, Resource};
use arpa_core::store::footprint::PackedFootprint;
use arpa_core::{gpu::layout::{KeyedFootprint, KeyedPhoton, StoreCounts, StoreParams, StoreSettings}, gpu::sort::SortItem};
use arpa_core::gpu::sort::{MAX_SORT_ITEMS, SORT_BLOCK, radix_count_len, radix_passes, sort_steps, sorted_len};
use arpa_core::gpu::batch::Capacities;
use arpa_core::store::progressive_photon::PackedPhoton;
use ash::vk;
use gpu_allocator::MemoryLocation;

/// Bytes of a sorted footprint record ([`PackedFootprint`]).
pub const FOOTPRINT_BYTES: u64 = size_of::<PackedFootprint>() as u64;
/// Bytes of a sorted progressive photon ([`PackedPhoton`]).
pub const PHOTON_BYTES: u64 = size_of::<PackedPhoton>() as u64;
/// Bytes of one box (min xyz, max xyz, `f32`, metres): the AABB stride.
pub const BOX_BYTES: u64 = crate::accel::AABB_STRIDE;
const ITEM_BYTES: u64 = size_of::<SortItem>() as u64;
const COUNTS_BYTES: u64 = size_of::<StoreCounts>() as u64;
/// Bytes of the sort step the kernels read (`SortStep` of `sort.wgsl`: k, j, two pads).
const STEP_BYTES: usize = 16;

/// Usage of the box buffers: acceleration-structure build input by device address, written
/// by the compaction kernels, readable back.
pub const BOX_USAGE: vk::BufferUsageFlags = vk::BufferUsageFlags::from_raw(
    vk::BufferUsageFlags::ACCELERATION_STRUCTURE_BUILD_INPUT_READ_ONLY_KHR.as_raw()
        | vk::BufferUsageFlags::SHADER_DEVICE_ADDRESS.as_raw()
        | vk::BufferUsageFlags::STORAGE_BUFFER.as_raw()
        | vk::BufferUsageFlags::TRANSFER_SRC.as_raw(),
);

/// The keyed store's and the sorts' compute pipelines (the core's `store.wgsl`, `radix.wgsl`
/// and `sort.wgsl`), independent of any capacity: made once per context and shared by every
/// [`MapStore`] (on lavapipe a pipeline is compiled at its first dispatch, which takes
/// seconds).
pub struct StorePipelines {
    schedule: ComputePipeline,
    store_check: ComputePipeline,
    keyed: ComputePipeline,
    photon_keys: ComputePipeline,
    pad_items: ComputePipeline,
    compact_footprints: ComputePipeline,
    compact_photons: ComputePipeline,
    sort_local: ComputePipeline,
    sort_merge: ComputePipeline,
    sort_global: ComputePipeline,
    radix_count: ComputePipeline,
    radix_scan: ComputePipeline,
    radix_scatter: ComputePipeline,
}

/// An item buffer with the radix scratch and the kernels' bindings to them, both directions
/// (shared with the submissions that use them).
struct RadixTarget<'a> {
    items: &'a Buffer,
    scratch: &'a RadixScratch,
    bindings: Arc<[Bindings; 2]>,
}

/// The radix sort's scratch buffers for up to `capacity` items: the second item buffer, the
/// per-tile digit counters and the pass uniform (written by `vkCmdUpdateBuffer`).
pub struct RadixScratch {
    items: Buffer,
    counts: Buffer,
    pass: Buffer,
    capacity: u32,
}

impl RadixScratch {
    /// Scratch for sorts of at most `capacity` items (`capacity` × 12 bytes plus 1 KiB per
    /// [`arpa_core::gpu::sort::RADIX_TILE`] items).
    ///
    /// Errors: device errors as [`VkContext::create_buffer`].
    pub fn new(ctx: &VkContext, capacity: u32) -> Result<Self, VkError> {
        use vk::BufferUsageFlags as U;
        let gpu = |label: &str, bytes: u64, usage: U| ctx.create_buffer(&format!("arpa radix {label}"), bytes.max(16), usage, MemoryLocation::GpuOnly);
        Ok(Self {
            items: gpu("items", u64::from(capacity) * ITEM_BYTES, U::STORAGE_BUFFER | U::TRANSFER_SRC)?,
            counts: gpu("counts", u64::from(radix_count_len(capacity)) * 4, U::STORAGE_BUFFER)?,
            pass: gpu("pass", STEP_BYTES as u64, U::UNIFORM_BUFFER | U::TRANSFER_DST)?,
            capacity,
        })
    }
}

impl StorePipelines {
    /// Compiles the store and sort kernels.
    ///
    /// Errors: [`VkError::Shader`] if naga rejects the core's WGSL; device errors.
    pub fn new(ctx: &VkContext) -> Result<Self, VkError> {
        let store_spirv = crate::shaders::compile_wgsl("arpa store", &arpa_core::gpu::shaders::compose(&[&arpa_core::gpu::shaders::STORE]))?;
        // sort.wgsl's shared-memory kernels copy all SORT_BLOCK items into workgroup memory
        // before the first barrier and read nothing else, so WGSL's zero initialisation of
        // workgroup memory is dead work; naga's polyfill of it makes lavapipe's first
        // compilation of sort_merge take minutes (see `compile_wgsl_with`).
        let sort_spirv =
            crate::shaders::compile_wgsl_with("arpa sort", &arpa_core::gpu::shaders::compose(&[&arpa_core::gpu::shaders::SORT]), false)?;
        // radix.wgsl's kernels, likewise, write every workgroup element before reading it.
        let radix_spirv =
            crate::shaders::compile_wgsl_with("arpa radix sort", &arpa_core::gpu::shaders::compose(&[&arpa_core::gpu::shaders::RADIX]), false)?;
        let store_set = [BindingKind::StorageBuffer; 13];
        let sort_set = [BindingKind::StorageBuffer, BindingKind::UniformBuffer];
        let radix_set = [BindingKind::StorageBuffer, BindingKind::StorageBuffer, BindingKind::StorageBuffer, BindingKind::UniformBuffer];
        let make = |spirv, entry, set: &[BindingKind]| {
            ComputePipeline::new(ctx, &ComputePipelineDesc { label: entry, spirv, entry, sets: &[set], push_constant_size: 0 })
        };

        let schedule_spirv = crate::shaders::compile_wgsl("arpa store schedule", &arpa_core::gpu::shaders::compose(&[&arpa_core::gpu::shaders::SCHEDULE]))?;
        Ok(Self {
            schedule: make(&schedule_spirv, "store_schedule", &[BindingKind::StorageBuffer; 5])?,
            store_check: make(&schedule_spirv, "store_check", &[BindingKind::StorageBuffer; 5])?,
            keyed: make(&store_spirv, "store_keyed", &store_set)?,
            photon_keys: make(&store_spirv, "photon_keys", &store_set)?,
            pad_items: make(&store_spirv, "pad_items", &store_set)?,
            compact_footprints: make(&store_spirv, "compact_footprints", &store_set)?,
            compact_photons: make(&store_spirv, "compact_photons", &store_set)?,
            sort_local: make(&sort_spirv, "sort_local", &sort_set)?,
            sort_merge: make(&sort_spirv, "sort_merge", &sort_set)?,
            sort_global: make(&sort_spirv, "sort_global", &sort_set)?,
            radix_count: make(&radix_spirv, "radix_count", &radix_set)?,
            radix_scan: make(&radix_spirv, "radix_scan", &radix_set)?,
            radix_scatter: make(&radix_spirv, "radix_scatter", &radix_set)?,
        })
    }

    /// Binds the radix kernels to `items` and the scratch, both directions.
    fn radix_bindings<'a>(&self, items: &'a Buffer, scratch: &'a RadixScratch) -> Result<RadixTarget<'a>, VkError> {
        let bind = |src, dst| self.radix_count.bind(&[&[Resource::StorageBuffer(src), Resource::StorageBuffer(dst), Resource::StorageBuffer(&scratch.counts), Resource::UniformBuffer(&scratch.pass)]]);
        Ok(RadixTarget { items, scratch, bindings: Arc::new([bind(items, &scratch.items)?, bind(&scratch.items, items)?]) })
    }

    /// Records the radix sort of the first `n` items (`n` ≤ the scratch's capacity) of the
    /// target's items, whose values are below `value_bound`: per pass of [`radix_passes`], the pass written into the
    /// uniform, then `radix_count`, `radix_scan`, `radix_scatter`; a copy back into `items`
    /// after an odd number of passes. Ends with a barrier.
    fn record_radix(&self, device: &ash::Device, cmd: vk::CommandBuffer, target: &RadixTarget<'_>, n: u32, value_bound: u32) -> Result<(), VkError> {
        let RadixTarget { items, scratch, bindings } = target;
        debug_assert!(n <= scratch.capacity);
        let passes = radix_passes(n, value_bound);
        for (i, p) in passes.iter().enumerate() {
            // SAFETY: the pass buffer is alive, has TRANSFER_DST usage and holds 16 bytes; the
            // barrier after the previous dispatch orders its uniform reads before this write.
            unsafe { device.cmd_update_buffer(cmd, scratch.pass.raw(), 0, &bytemuck::bytes_of(p)[..STEP_BYTES]) };
            record_compute_barrier(device, cmd);
            let b = &bindings[i % 2];
            self.radix_count.record_dispatch(cmd, b, &[], [p.tiles, 1, 1])?;
            record_compute_barrier(device, cmd);
            self.radix_scan.record_dispatch(cmd, b, &[], [1, 1, 1])?;
            record_compute_barrier(device, cmd);
            self.radix_scatter.record_dispatch(cmd, b, &[], [p.tiles, 1, 1])?;
            record_compute_barrier(device, cmd);
        }
        if !passes.len().is_multiple_of(2) {
            let region = vk::BufferCopy { src_offset: 0, dst_offset: 0, size: u64::from(n) * ITEM_BYTES };
            // SAFETY: both buffers are alive with TRANSFER_SRC / TRANSFER_DST usage and hold
            // `n` items; the barrier above orders the last scatter before the copy.
            unsafe { device.cmd_copy_buffer(cmd, scratch.items.raw(), items.raw(), &[region]) };
            record_compute_barrier(device, cmd);
        }
        Ok(())
    }

    /// Sorts the first `n` [`SortItem`]s of `items` by `(hi, lo, value)` in one submission,
    /// waited for: with `radix` (scratch for at least `n` items; values below `value_bound`)
    /// the radix sort the store runs, else the bitonic sort (`n` a power of two ≥
    /// [`SORT_BLOCK`], at most [`MAX_SORT_ITEMS`]; `value_bound` unused). For tests and the
    /// sort benchmark; `items` needs `STORAGE_BUFFER` and, for the radix sort, `TRANSFER_DST`.
    ///
    /// Errors: [`VkError::InvalidInput`] for `n` beyond these bounds or the buffer; device
    /// errors.
    pub fn sort_items(&self, ctx: &VkContext, items: &Buffer, n: u32, value_bound: u32, radix: Option<&RadixScratch>) -> Result<(), VkError> {
        if u64::from(n) * ITEM_BYTES > items.size() {
            return Err(size_error(format!("{n} items in a buffer of {} bytes", items.size())));
        }
        let device = ctx.device();
        match radix {
            Some(scratch) => {
                if n > scratch.capacity {
                    return Err(size_error(format!("{n} items for a radix scratch of {}", scratch.capacity)));
                }
                let target = self.radix_bindings(items, scratch)?;
                ctx.submit_and_wait(|cmd| self.record_radix(device, cmd, &target, n, value_bound))??;
            }
            None => {
                if !(n.is_power_of_two() && (SORT_BLOCK..=MAX_SORT_ITEMS).contains(&n)) {
                    return Err(size_error(format!("{n} items: the bitonic sort takes a power of two from {SORT_BLOCK} to {MAX_SORT_ITEMS}")));
                }
                let step = ctx.create_buffer("arpa sort step", STEP_BYTES as u64, vk::BufferUsageFlags::UNIFORM_BUFFER | vk::BufferUsageFlags::TRANSFER_DST, MemoryLocation::GpuOnly)?;
                let bindings = self.sort_local.bind(&[&[Resource::StorageBuffer(items), Resource::UniformBuffer(&step)]])?;
                ctx.submit_and_wait(|cmd| self.record_bitonic(device, cmd, &bindings, &step, n))??;
            }
        }
        Ok(())
    }

    /// Records the bitonic sort of the first `n` items (a power of two ≥ [`SORT_BLOCK`]) of
    /// the buffer `bindings` binds: per step of [`sort_steps`], the step written into the
    /// uniform `step`, then `n / SORT_BLOCK` workgroups of `sort_local`, `sort_global` or
    /// `sort_merge`.
    fn record_bitonic(&self, device: &ash::Device, cmd: vk::CommandBuffer, bindings: &Bindings, step: &Buffer, n: u32) -> Result<(), VkError> {
        debug_assert!(n.is_power_of_two() && (SORT_BLOCK..=MAX_SORT_ITEMS).contains(&n));
        for (i, s) in sort_steps(n).iter().enumerate() {
            let pipeline = match (i, s.j) {
                (0, _) => &self.sort_local,
                (_, 0) => &self.sort_merge,
                _ => &self.sort_global,
            };
            if i > 0 {
                // SAFETY: the step buffer is alive, has TRANSFER_DST usage and holds 16 bytes;
                // the previous step's barrier (compute → transfer) orders its uniform read
                // before this write.
                unsafe { device.cmd_update_buffer(cmd, step.raw(), 0, &bytemuck::bytes_of(s)[..STEP_BYTES]) };
                record_compute_barrier(device, cmd);
            }
            pipeline.record_dispatch(cmd, bindings, &[], [n / SORT_BLOCK, 1, 1])?;
            record_compute_barrier(device, cmd);
        }
        Ok(())
    }
}

/// The keyed store's device buffers for given input capacities: slots, sort items, counters
/// and the sorted outputs (see the module docs), with the shared [`StorePipelines`].
/// Dropping it frees the buffers (after waiting for the submissions in flight, as every
/// buffer's drop does).
pub struct MapStore {
    raw_capacity: u32,
    photon_capacity: u32,
    /// Photon sort items (the sorted-photon capacity).
    sorted_photons: u32,
    photons_out_capacity: u32,
    pipelines: Arc<StorePipelines>,
    /// `StoreCounts` as the kernels count them (device-local).
    counts: Buffer,
    /// Host-visible copy of `counts`, read after each submission.
    counts_host: Buffer,
    /// The store half's indirect dispatch arguments (`store_keyed`, `photon_keys`), written
    /// by the schedule kernel.
    args: Buffer,
    fp_slots: Buffer,
    fp_box_slots: Buffer,
    ph_extra: Buffer,
    fp_items: Buffer,
    ph_items: Buffer,
    /// The radix sort's scratch (both item buffers' counts).
    radix: RadixScratch,
    footprints: Buffer,
    footprint_boxes: Buffer,
    photons: Buffer,
    photon_boxes: Buffer,
}

/// What one batch's store, recorded into the photon pass's submission
/// ([`MapStore::prepare_batch`], [`MapStore::record_batch`]), uses: keep it (an `Arc`, in
/// the submission's [`crate::buffer::KeepAlive`]) until that submission is done.
pub struct BatchStore {
    bindings: Bindings,
    schedule: Bindings,
    fp_sort: Arc<[Bindings; 2]>,
    ph_sort: Arc<[Bindings; 2]>,
    /// The parameters ([`StoreParams::new`] over the capacities), bound in both sets.
    params: StoreParams,
    _params: Buffer,
}

fn size_error(reason: String) -> VkError {
    VkError::InvalidInput { what: "keyed store".into(), reason }
}

impl MapStore {
    /// Allocates buffers for `capacities`: raw footprints ([`KeyedFootprint`]) and
    /// progressive photons ([`KeyedPhoton`]) per batch, photon sort items and sorted
    /// photons.
    ///
    /// Errors: [`VkError::InvalidInput`] when the capacities exceed the sort's
    /// [`MAX_SORT_ITEMS`] or a buffer exceeds the device's `maxStorageBufferRange` (the sorted
    /// photons are capped at what one binding holds; the store and the compaction count any
    /// beyond in [`StoreCounts::overflowed`]); [`VkError::Shader`] if naga rejects the core's
    /// WGSL; device errors as [`VkContext::create_buffer`].
    pub fn new(ctx: &VkContext, pipelines: &Arc<StorePipelines>, capacities: Capacities) -> Result<Self, VkError> {
        let Capacities { raw_footprints: raw_capacity, photons: photon_capacity, sorted_photons } = capacities;
        let sorted_items = raw_capacity.max(sorted_photons);
        if sorted_len(sorted_items) > MAX_SORT_ITEMS {
            return Err(size_error(format!("{raw_capacity} raw footprints or {sorted_photons} sorted photons exceed the sort's {MAX_SORT_ITEMS} items")));
        }
        // SAFETY: a physical device of this instance.
        let limits = unsafe { ctx.instance().get_physical_device_properties(ctx.physical_device()) }.limits;
        let max_range = u64::from(limits.max_storage_buffer_range);
        for (what, bytes) in [
            ("footprint slots", u64::from(raw_capacity) * FOOTPRINT_BYTES),
            ("raw-footprint photon slots", u64::from(raw_capacity) * size_of::<KeyedPhoton>() as u64),
            ("photon sort items", u64::from(sorted_photons) * ITEM_BYTES),
        ] {
            if bytes > max_range {
                return Err(size_error(format!("{what}: {bytes} bytes exceed the device's maxStorageBufferRange {max_range}")));
            }
        }
        let photons_out_capacity = sorted_photons.min(u32::try_from(max_range / PHOTON_BYTES).unwrap_or(u32::MAX));

        use vk::BufferUsageFlags as U;
        let gpu = |label: &str, records: u32, bytes: u64, usage: U| {
            ctx.create_buffer(&format!("arpa store {label}"), u64::from(records.max(1)) * bytes, usage, MemoryLocation::GpuOnly)
        };
        let storage = U::STORAGE_BUFFER;
        Ok(Self {
            raw_capacity,
            photon_capacity,
            sorted_photons,
            photons_out_capacity,
            pipelines: Arc::clone(pipelines),
            counts: gpu("counts", 1, COUNTS_BYTES, storage | U::TRANSFER_SRC | U::TRANSFER_DST)?,
            counts_host: ctx.create_buffer("arpa store counts (host)", COUNTS_BYTES, U::TRANSFER_DST, MemoryLocation::GpuToCpu)?,
            args: gpu("dispatch arguments", 1, 24, storage | U::INDIRECT_BUFFER)?,
            fp_slots: gpu("footprint slots", raw_capacity, FOOTPRINT_BYTES, storage)?,
            fp_box_slots: gpu("footprint box slots", raw_capacity, BOX_BYTES, storage)?,
            ph_extra: gpu("fallback photons", raw_capacity, size_of::<KeyedPhoton>() as u64, storage)?,
            fp_items: gpu("footprint items", raw_capacity, ITEM_BYTES, storage | U::TRANSFER_DST)?,
            ph_items: gpu("photon items", sorted_photons, ITEM_BYTES, storage | U::TRANSFER_DST)?,
            radix: RadixScratch::new(ctx, sorted_items)?,
            footprints: gpu("sorted footprints", raw_capacity, FOOTPRINT_BYTES, storage | U::TRANSFER_SRC)?,
            footprint_boxes: gpu("sorted footprint boxes", raw_capacity, BOX_BYTES, BOX_USAGE)?,
            photons: gpu("sorted photons", photons_out_capacity, PHOTON_BYTES, storage | U::TRANSFER_SRC)?,
            photon_boxes: gpu("sorted photon boxes", photons_out_capacity, BOX_BYTES, BOX_USAGE)?,
        })
    }

    /// Raw-footprint and photon capacities this store was made for.
    pub fn capacities(&self) -> Capacities {
        Capacities { raw_footprints: self.raw_capacity, photons: self.photon_capacity, sorted_photons: self.sorted_photons }
    }

    /// Sorted progressive photons one batch can hold (the sorted-photon capacity, capped at
    /// one storage binding).
    pub fn photons_out_capacity(&self) -> u32 {
        self.photons_out_capacity
    }

    /// Sorted footprint records ([`PackedFootprint`], 64 bytes); after [`MapStore::sort`] the
    /// first [`StoreCounts::total_footprints`] are valid, caustic first.
    pub fn footprints(&self) -> &Buffer {
        &self.footprints
    }

    /// The footprints' boxes (24 bytes each, metres; [`BOX_USAGE`]): the AABB build input.
    pub fn footprint_boxes(&self) -> &Buffer {
        &self.footprint_boxes
    }

    /// Sorted progressive photons ([`PackedPhoton`], 48 bytes, padding zero); after
    /// [`MapStore::sort`] the first [`StoreCounts::total_photons`] are valid, caustic first.
    pub fn photons(&self) -> &Buffer {
        &self.photons
    }

    /// The photons' boxes: the sphere of the map's progressive radius, padded as every
    /// acceleration-structure box (`arpa_padded_box`, the twin of
    /// [`arpa_core::base::aabb::Aabb::padded_f32`]); 24 bytes each, [`BOX_USAGE`].
    pub fn photon_boxes(&self) -> &Buffer {
        &self.photon_boxes
    }

    fn check_inputs(&self, raw: &Buffer, photons: &Buffer, settings: &StoreSettings) -> Result<(), VkError> {
        if settings.raw_count > self.raw_capacity || settings.photon_count > self.photon_capacity {
            return Err(size_error(format!(
                "{} raw footprints / {} photons given for capacities {} / {}",
                settings.raw_count, settings.photon_count, self.raw_capacity, self.photon_capacity
            )));
        }
        for (b, count, bytes) in
            [(raw, settings.raw_count, size_of::<KeyedFootprint>() as u64), (photons, settings.photon_count, size_of::<KeyedPhoton>() as u64)]
        {
            if !b.usage().contains(vk::BufferUsageFlags::STORAGE_BUFFER) {
                return Err(VkError::MissingUsage { what: b.label().into(), usage: "STORAGE_BUFFER" });
            }
            if u64::from(count) * bytes > b.size() {
                return Err(size_error(format!("{count} records of {bytes} bytes in the {}-byte buffer {:?}", b.size(), b.label())));
            }
        }
        Ok(())
    }

    /// A host-visible copy of `params` for one submission.
    fn params(ctx: &VkContext, params: &StoreParams) -> Result<Buffer, VkError> {
        let mut b = ctx.create_buffer(
            "arpa store params",
            size_of::<StoreParams>() as u64,
            vk::BufferUsageFlags::STORAGE_BUFFER,
            MemoryLocation::CpuToGpu,
        )?;
        b.write(0, bytemuck::bytes_of(params))?;
        Ok(b)
    }

    fn store_bindings(&self, raw: &Buffer, photons: &Buffer, params: &Buffer) -> Result<Bindings, VkError> {
        let set = [raw, photons, params, &self.fp_slots, &self.fp_box_slots, &self.ph_extra, &self.fp_items, &self.ph_items, &self.counts]
            .into_iter()
            .chain([&self.footprints, &self.footprint_boxes, &self.photons, &self.photon_boxes])
            .map(Resource::StorageBuffer)
            .collect::<Vec<_>>();
        // One set for all five store pipelines: their set layouts are identically defined,
        // hence compatible.
        self.pipelines.keyed.bind(&[&set])
    }

    /// Records the copy of the counters to the host-visible buffer (after a barrier).
    fn record_counts_copy(&self, device: &ash::Device, cmd: vk::CommandBuffer) {
        record_compute_barrier(device, cmd);
        let region = vk::BufferCopy::default().size(COUNTS_BYTES);
        // SAFETY: both buffers are alive until the caller's wait and have the transfer usages.
        unsafe { device.cmd_copy_buffer(cmd, self.counts.raw(), self.counts_host.raw(), &[region]) };
        record_compute_barrier(device, cmd);
    }

    /// The counters copied out by the last submission of [`MapStore::record_batch`], [`MapStore::sort`] or
    /// [`MapStore::store`], once it has been waited for.
    pub fn read_counts(&self) -> Result<StoreCounts, VkError> {
        Ok(bytemuck::pod_read_unaligned(&self.counts_host.read(0, COUNTS_BYTES)?))
    }

    /// The first half, one submission waited for: stores the photon pass's output (`raw`:
    /// `settings.raw_count` [`KeyedFootprint`]s, `photons`: `settings.photon_count`
    /// [`KeyedPhoton`]s; storage buffers whose writes are visible to compute shaders, e.g.
    /// uploaded or written by an earlier submission ending in a barrier), appends the sort
    /// items and reads the counters back (the one host readback of the chain).
    ///
    /// Errors: [`VkError::InvalidInput`] for counts above the capacities or past the input
    /// buffers; [`VkError::MissingUsage`] for inputs without `STORAGE_BUFFER`; device errors.
    pub fn store(&self, ctx: &VkContext, raw: &Buffer, photons: &Buffer, settings: &StoreSettings) -> Result<StoreCounts, VkError> {
        self.check_inputs(raw, photons, settings)?;
        let params = Self::params(ctx, &StoreParams::new(settings, self.raw_capacity, self.sorted_photons))?;
        let bindings = self.store_bindings(raw, photons, &params)?;
        let device = ctx.device();
        ctx.submit_and_wait(|cmd| {
            record_fill(device, cmd, &self.counts, 0);
            record_compute_barrier(device, cmd);
            self.pipelines.keyed.record_dispatch_linear(cmd, &bindings, &[], settings.raw_count)?;
            record_compute_barrier(device, cmd);
            self.pipelines.photon_keys.record_dispatch_linear(cmd, &bindings, &[], settings.photon_count)?;
            self.record_counts_copy(device, cmd);
            Ok::<(), VkError>(())
        })??;
        drop((bindings, params));
        self.read_counts()
    }

    /// One batch's whole store for the photon pass's submission: checks the inputs (`raw`
    /// and `photons`, the pass's append buffers with these capacities; `counters`, its
    /// [`arpa_core::gpu::layout::PhotonCounters`]; `status`, the iteration's status word of
    /// [`crate::accumulate::STATUS_BYTES`]: storage buffers) and makes the parameters
    /// (`settings`' record counts unused: the schedule kernel writes them; the sort and the
    /// compaction run over the capacities) and the bindings [`MapStore::record_batch`]
    /// records with.
    ///
    /// Errors: [`VkError::MissingUsage`] for inputs without `STORAGE_BUFFER`; device errors.
    pub fn prepare_batch(&self, ctx: &VkContext, raw: &Buffer, photons: &Buffer, counters: &Buffer, status: &Buffer, settings: &StoreSettings) -> Result<Arc<BatchStore>, VkError> {
        let capacities = StoreSettings { raw_count: self.raw_capacity, photon_count: self.photon_capacity, ..*settings };
        self.check_inputs(raw, photons, &capacities)?;
        for b in [counters, status] {
            if !b.usage().contains(vk::BufferUsageFlags::STORAGE_BUFFER) {
                return Err(VkError::MissingUsage { what: b.label().into(), usage: "STORAGE_BUFFER" });
            }
        }
        let p = StoreParams::new(settings, self.raw_capacity, self.sorted_photons);
        let params = Self::params(ctx, &p)?;
        let bindings = self.store_bindings(raw, photons, &params)?;
        let schedule = self.pipelines.schedule.bind(&[&[
            Resource::StorageBuffer(counters),
            Resource::StorageBuffer(&params),
            Resource::StorageBuffer(&self.args),
            Resource::StorageBuffer(status),
            Resource::StorageBuffer(&self.counts),
        ]])?;
        let fp_sort = self.pipelines.radix_bindings(&self.fp_items, &self.radix)?.bindings;
        let ph_sort = self.pipelines.radix_bindings(&self.ph_items, &self.radix)?.bindings;
        Ok(Arc::new(BatchStore { bindings, schedule, fp_sort, ph_sort, params: p, _params: params }))
    }

    /// Records the batch's store into `cmd` after the photon pass's trace: a barrier (the
    /// pass's writes before compute reads), the schedule kernel (record counts and dispatch
    /// sizes from the pass's counters, the iteration's status), the store and the sort items
    /// as indirect dispatches, the padding of the items up to the capacities, the radix
    /// sort of both item buffers over them and the compaction into the sorted records and
    /// boxes (inactive boxes past the records), then a barrier that makes them visible to
    /// later shaders, transfers, acceleration-structure builds and the host, and the copy
    /// of the counters to the host-visible buffer ([`MapStore::read_counts`] after a wait);
    /// last the store check (the status word, when photon items were dropped). Nothing in
    /// it depends on a count the host has read.
    ///
    /// Errors: as [`ComputePipeline::record_dispatch_indirect`].
    pub fn record_batch(&self, device: &ash::Device, cmd: vk::CommandBuffer, prepared: &BatchStore) -> Result<(), VkError> {
        let after_trace = vk::MemoryBarrier::default()
            .src_access_mask(vk::AccessFlags::SHADER_WRITE | vk::AccessFlags::TRANSFER_WRITE | vk::AccessFlags::HOST_WRITE)
            .dst_access_mask(vk::AccessFlags::SHADER_READ | vk::AccessFlags::SHADER_WRITE | vk::AccessFlags::TRANSFER_WRITE);
        let to_indirect = vk::MemoryBarrier::default()
            .src_access_mask(vk::AccessFlags::SHADER_WRITE)
            .dst_access_mask(vk::AccessFlags::INDIRECT_COMMAND_READ | vk::AccessFlags::SHADER_READ | vk::AccessFlags::UNIFORM_READ);
        // SAFETY: plain barriers in a recording command buffer.
        unsafe {
            device.cmd_pipeline_barrier(
                cmd,
                vk::PipelineStageFlags::RAY_TRACING_SHADER_KHR | vk::PipelineStageFlags::COMPUTE_SHADER | vk::PipelineStageFlags::TRANSFER | vk::PipelineStageFlags::HOST,
                vk::PipelineStageFlags::COMPUTE_SHADER | vk::PipelineStageFlags::TRANSFER,
                vk::DependencyFlags::empty(),
                &[after_trace],
                &[],
                &[],
            );
        }
        record_fill(device, cmd, &self.counts, 0);
        record_compute_barrier(device, cmd);
        self.pipelines.schedule.record_dispatch(cmd, &prepared.schedule, &[], [1, 1, 1])?;
        // SAFETY: as above.
        unsafe {
            device.cmd_pipeline_barrier(
                cmd,
                vk::PipelineStageFlags::COMPUTE_SHADER,
                vk::PipelineStageFlags::DRAW_INDIRECT | vk::PipelineStageFlags::COMPUTE_SHADER,
                vk::DependencyFlags::empty(),
                &[to_indirect],
                &[],
                &[],
            );
        }
        self.pipelines.keyed.record_dispatch_indirect(cmd, &prepared.bindings, &[], &self.args, 0)?;
        record_compute_barrier(device, cmd);
        self.pipelines.photon_keys.record_dispatch_indirect(cmd, &prepared.bindings, &[], &self.args, 12)?;
        record_compute_barrier(device, cmd);
        self.record_sort(device, cmd, &prepared.bindings, &prepared.fp_sort, &prepared.ph_sort, &prepared.params)?;
        // The store check: the status word, when photon items were dropped.
        self.pipelines.store_check.record_dispatch(cmd, &prepared.schedule, &[], [1, 1, 1])?;
        record_compute_barrier(device, cmd);
        Ok(())
    }

    /// Records the padding, the radix sorts over the capacities and the compaction, then the
    /// counters' copy to the host-visible buffer.
    fn record_sort(&self, device: &ash::Device, cmd: vk::CommandBuffer, bindings: &Bindings, fp_sort: &Arc<[Bindings; 2]>, ph_sort: &Arc<[Bindings; 2]>, p: &StoreParams) -> Result<(), VkError> {
        self.pipelines.pad_items.record_dispatch_linear(cmd, bindings, &[], p.fp_sorted.max(p.ph_sorted))?;
        record_compute_barrier(device, cmd);
        // Slots: footprints below raw_count, photons below photon_count + raw_count, both
        // within the capacities; the padding's value sorts last with its keys anyway.
        let value_bound = self.raw_capacity.saturating_add(self.photon_capacity);
        let fp = RadixTarget { items: &self.fp_items, scratch: &self.radix, bindings: Arc::clone(fp_sort) };
        let ph = RadixTarget { items: &self.ph_items, scratch: &self.radix, bindings: Arc::clone(ph_sort) };
        self.pipelines.record_radix(device, cmd, &fp, p.fp_sorted, value_bound)?;
        self.pipelines.record_radix(device, cmd, &ph, p.ph_sorted, value_bound)?;
        self.pipelines.compact_footprints.record_dispatch_linear(cmd, bindings, &[], p.fp_sorted)?;
        self.pipelines.compact_photons.record_dispatch_linear(cmd, bindings, &[], p.ph_sorted)?;
        self.record_counts_copy(device, cmd);
        Ok(())
    }

    /// The second half on its own, one submission waited for, after [`MapStore::store`] on
    /// the same `raw`, `photons` and `settings` (whose record counts are the appended ones):
    /// pads the items, sorts them over the capacities and compacts the records and boxes into
    /// [`MapStore::footprints`], [`MapStore::footprint_boxes`], [`MapStore::photons`] and
    /// [`MapStore::photon_boxes`] (inactive boxes past the records); returns the counters
    /// after the compaction (with [`StoreCounts::overflowed`]).
    ///
    /// Errors: [`VkError::InvalidInput`] for counts above the capacities or past the input
    /// buffers; [`VkError::MissingUsage`] for inputs without `STORAGE_BUFFER`; device errors.
    pub fn sort(&self, ctx: &VkContext, raw: &Buffer, photons: &Buffer, settings: &StoreSettings) -> Result<StoreCounts, VkError> {
        self.check_inputs(raw, photons, settings)?;
        let p = StoreParams::new(settings, self.raw_capacity, self.sorted_photons);
        let params = Self::params(ctx, &p)?;
        let bindings = self.store_bindings(raw, photons, &params)?;
        let fp_sort = self.pipelines.radix_bindings(&self.fp_items, &self.radix)?.bindings;
        let ph_sort = self.pipelines.radix_bindings(&self.ph_items, &self.radix)?.bindings;
        let device = ctx.device();
        ctx.submit_and_wait(|cmd| self.record_sort(device, cmd, &bindings, &fp_sort, &ph_sort, &p))??;
        drop((bindings, params));
        self.read_counts()
    }

    /// The device counters ([`StoreCounts`], `TRANSFER_SRC`), valid after the store's commands.
    pub fn counts(&self) -> &Buffer {
        &self.counts
    }

    /// The sorted footprints of `counts` (caustic first), read back.
    pub fn read_footprints(&self, ctx: &VkContext, counts: &StoreCounts) -> Result<Vec<PackedFootprint>, VkError> {
        let n = u64::from(counts.total_footprints());
        Ok(crate::buffer::pod_vec(&ctx.read_back(&self.footprints, 0, n * FOOTPRINT_BYTES)?))
    }

    /// The sorted progressive photons of `counts` (caustic first, padding zero), read back.
    pub fn read_photons(&self, ctx: &VkContext, counts: &StoreCounts) -> Result<Vec<PackedPhoton>, VkError> {
        let n = u64::from(counts.total_photons().min(self.photons_out_capacity));
        Ok(crate::buffer::pod_vec(&ctx.read_back(&self.photons, 0, n * PHOTON_BYTES)?))
    }

    /// The boxes of the sorted footprints of `counts` (min xyz, max xyz; metres), read back.
    pub fn read_footprint_boxes(&self, ctx: &VkContext, counts: &StoreCounts) -> Result<Vec<[f32; 6]>, VkError> {
        let n = u64::from(counts.total_footprints());
        Ok(crate::buffer::pod_vec(&ctx.read_back(&self.footprint_boxes, 0, n * BOX_BYTES)?))
    }

    /// The boxes of the sorted photons of `counts` (min xyz, max xyz; metres), read back.
    pub fn read_photon_boxes(&self, ctx: &VkContext, counts: &StoreCounts) -> Result<Vec<[f32; 6]>, VkError> {
        let n = u64::from(counts.total_photons().min(self.photons_out_capacity));
        Ok(crate::buffer::pod_vec(&ctx.read_back(&self.photon_boxes, 0, n * BOX_BYTES)?))
    }
}
