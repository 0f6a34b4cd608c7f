//! The photon maps of one iteration on the device, photon batch by photon batch
//! ([`arpa_core::gpu::batch`]): the keyed store, sort and compaction of each batch
//! ([`crate::store::MapStore`]) on the photon pass's buffers, every batch's sorted records
//! kept ([`BatchMaps`]), their acceleration structures ([`crate::accel`]) and the image
//! gather over them in batch order ([`crate::gather::ImageGather`]). Everything stays on
//! the device and nothing is sized by a count: the store, the sort and the build run over
//! the buffers' capacities. Each batch's photon-pass and store counters are copied into
//! one buffer of the iteration ([`PhotonMaps::batch_counts`]), which the tracer reads with
//! the accumulate's wait (the overflow check, the stats) or when the caller asks for the
//! records.

use crate::accel::MapAccel;
use crate::device::GpuContext;
use crate::gather::ImageGather;
use crate::store::{BATCH_COUNTS_BYTES, FOOTPRINT_BYTES, MapStore, PHOTON_BYTES, StorePipelines};
use crate::error::WgpuError;
use arpa_core::gpu::batch::Capacities;
use arpa_core::gather::scales::Bandwidth;
use arpa_core::store::footprint::PackedFootprint;
use arpa_core::gpu::layout::{BatchCounts, GatherBatch, PhotonCounters, StoreCounts, StoreSettings};
use arpa_core::gather::kernel::Kernel;
use arpa_core::store::progressive_photon::PackedPhoton;
use arpa_core::render::tracer::{Call, Stage, StageError};

/// Runs `record` (which creates and encodes device work) inside a validation and an
/// out-of-memory error scope; an error becomes [`WgpuError::Device`] naming `stage`.
pub(crate) fn scoped<T>(ctx: &GpuContext, stage: &'static str, record: impl FnOnce() -> Result<T, WgpuError>) -> Result<T, WgpuError> {
    let oom = ctx.device.push_error_scope(wgpu::ErrorFilter::OutOfMemory);
    let validation = ctx.device.push_error_scope(wgpu::ErrorFilter::Validation);
    let out = record();
    let v = pollster::block_on(validation.pop());
    let o = pollster::block_on(oom.pop());
    if let Some(e) = v.or(o) {
        return Err(WgpuError::Device { stage, message: e.to_string() });
    }
    out
}

/// Copies the first `bytes` of `buffer` (`COPY_SRC`) to the host (waits for the device).
pub(crate) fn read_buffer(ctx: &GpuContext, stage: &'static str, buffer: &wgpu::Buffer, bytes: u64) -> Result<Vec<u8>, WgpuError> {
    if bytes == 0 {
        return Ok(Vec::new());
    }
    let staging = scoped(ctx, stage, || {
        let staging = ctx.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("arpa read-back"),
            size: bytes,
            usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let mut encoder = ctx.device.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some("arpa read-back") });
        encoder.copy_buffer_to_buffer(buffer, 0, &staging, 0, bytes);
        ctx.submit(encoder);
        Ok(staging)
    })?;
    let readback = |e: String| WgpuError::Readback { stage, message: e };
    let (tx, rx) = std::sync::mpsc::channel();
    staging.map_async(wgpu::MapMode::Read, .., move |r| {
        let _ = tx.send(r);
    });
    ctx.device.poll(wgpu::PollType::wait_indefinitely()).map_err(|e| readback(e.to_string()))?;
    rx.recv().map_err(|e| readback(e.to_string()))?.map_err(|e| readback(e.to_string()))?;
    let out = staging.get_mapped_range(..).map_err(|e| readback(e.to_string()))?.to_vec();
    staging.unmap();
    Ok(out)
}

/// Copies of device buffers into one mappable buffer, recorded into the encoder of a
/// submission that runs anyway, so that reading them costs no submission and no wait of its
/// own: [`Readback::new`] allocates it, [`Readback::copy`] records each copy, then after the
/// encoder is submitted [`Readback::map`] requests the mapping and, after the caller's next
/// wait (`wgpu::Device::poll`), [`Readback::bytes`] returns the bytes.
pub struct Readback {
    stage: &'static str,
    staging: wgpu::Buffer,
    used: u64,
    mapped: Option<std::sync::mpsc::Receiver<Result<(), wgpu::BufferAsyncError>>>,
}

impl Readback {
    /// A read-back of up to `bytes` bytes (a multiple of 4) for `stage` (named in errors).
    pub fn new(ctx: &GpuContext, stage: &'static str, bytes: u64) -> Self {
        let staging = ctx.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("arpa read-back"),
            size: bytes.max(16),
            usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        Self { stage, staging, used: 0, mapped: None }
    }

    /// Records the copy of the first `bytes` (a multiple of 4) of `source` (`COPY_SRC`) after
    /// the bytes copied so far; returns their offset in [`Readback::bytes`].
    pub fn copy(&mut self, encoder: &mut wgpu::CommandEncoder, source: &wgpu::Buffer, bytes: u64) -> usize {
        let at = self.used;
        encoder.copy_buffer_to_buffer(source, 0, &self.staging, at, bytes);
        self.used += bytes;
        at as usize
    }

    /// Requests the mapping; call after submitting the encoder that holds the copies.
    pub fn map(&mut self) {
        let (tx, rx) = std::sync::mpsc::channel();
        self.staging.map_async(wgpu::MapMode::Read, .., move |r| {
            let _ = tx.send(r);
        });
        self.mapped = Some(rx);
    }

    /// The bytes copied, once a wait after [`Readback::map`] has completed the mapping.
    pub fn bytes(self) -> Result<Vec<u8>, WgpuError> {
        let readback = |e: String| WgpuError::Readback { stage: self.stage, message: e };
        let rx = self.mapped.as_ref().ok_or_else(|| readback("read back before it was mapped".into()))?;
        rx.recv().map_err(|e| readback(e.to_string()))?.map_err(|e| readback(e.to_string()))?;
        let out = self.staging.get_mapped_range(..).map_err(|e| readback(e.to_string()))?[..self.used as usize].to_vec();
        self.staging.unmap();
        Ok(out)
    }
}

/// One photon batch's maps: its sorted records and their boxes (caustic first; inactive
/// boxes past the records up to the capacities), the progressive radii they were stored
/// with, and, once built, their acceleration structure.
pub struct BatchMaps {
    /// Sorted footprint records ([`PackedFootprint`]); the first
    /// [`StoreCounts::total_footprints`] are valid.
    pub footprints: wgpu::Buffer,
    /// Their boxes (`BLAS_INPUT`), [`BatchMaps::capacities`]`.0` of them.
    pub footprint_boxes: wgpu::Buffer,
    /// Sorted progressive photons ([`PackedPhoton`]); the first
    /// [`StoreCounts::total_photons`] are valid.
    pub photons: wgpu::Buffer,
    /// Their boxes (`BLAS_INPUT`), [`BatchMaps::capacities`]`.1` of them.
    pub photon_boxes: wgpu::Buffer,
    /// Sorted footprints and photons the buffers hold (the store's capacities).
    pub capacities: (u32, u32),
    radii: [f32; 2],
    accel: Option<MapAccel>,
}

/// The iteration's photon maps on the device: the store's pipelines and buffers for the
/// current photon-pass buffers, and the batches stored so far.
pub struct PhotonMaps {
    pipelines: StorePipelines,
    gather: ImageGather,
    store: Option<MapStore>,
    batches: Vec<BatchMaps>,
    /// The iteration's status word ([`crate::accumulate::STATUS_BYTES`]): set on the device
    /// when a photon pass dropped appends.
    status: wgpu::Buffer,
    /// Per batch of the iteration, its [`PhotonCounters`] then its [`StoreCounts`]
    /// ([`BATCH_COUNTS_BYTES`] each).
    batch_counts: wgpu::Buffer,
}

impl PhotonMaps {
    /// Compiles the pipelines.
    pub fn new(ctx: &GpuContext) -> Result<Self, WgpuError> {
        scoped(ctx, "compiling the store and gather pipelines", || {
            let status = ctx.device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("arpa iteration status"),
                size: crate::accumulate::STATUS_BYTES,
                usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST | wgpu::BufferUsages::COPY_SRC,
                mapped_at_creation: false,
            });
            Ok(Self { pipelines: StorePipelines::new(&ctx.device), gather: ImageGather::new(&ctx.device), store: None, batches: Vec::new(), status, batch_counts: batch_counts_buffer(ctx, 1) })
        })
    }

    /// Binds the photon pass's output buffers (`raw`: keyed footprints, `photons`: keyed
    /// photons, `counters`: its [`arpa_core::gpu::layout::PhotonCounters`]) with their
    /// capacities; call again whenever they are reallocated. The batches kept so far stay.
    pub fn bind_inputs(&mut self, ctx: &GpuContext, raw: &wgpu::Buffer, photons: &wgpu::Buffer, counters: &wgpu::Buffer, capacities: Capacities) -> Result<(), WgpuError> {
        self.store = None;
        let store = scoped(ctx, "allocating the store buffers", || {
            MapStore::new(&ctx.device, &self.pipelines, raw, photons, counters, &self.status, capacities).map_err(|e| WgpuError::Size(e.to_string()))
        })?;
        self.store = Some(store);
        Ok(())
    }

    fn store_for(&self, call: impl Into<Call>) -> Result<&MapStore, StageError> {
        self.store.as_ref().ok_or_else(|| StageError::order(call, Stage::UploadScene))
    }

    /// Drops every batch and makes room for the counters of `batches` batches (the start
    /// of an iteration's photon pass).
    pub fn begin_iteration(&mut self, ctx: &GpuContext, batches: u32) {
        self.batches.clear();
        if self.batch_counts.size() < u64::from(batches) * BATCH_COUNTS_BYTES {
            self.batch_counts = batch_counts_buffer(ctx, batches);
        }
    }

    /// The iteration's status word ([`crate::accumulate::STATUS_BYTES`] bytes): non-zero
    /// once a photon pass since it was cleared dropped appends.
    pub fn status(&self) -> &wgpu::Buffer {
        &self.status
    }

    /// The buffer of the batches' counters: batch `k`'s [`PhotonCounters`] and
    /// [`StoreCounts`] at `k ·` [`BATCH_COUNTS_BYTES`] (`COPY_SRC`), [`BatchCounts`].
    pub fn batch_counts(&self) -> &wgpu::Buffer {
        &self.batch_counts
    }

    /// Records batch `k`'s store, sort and compaction into the photon pass's `encoder`
    /// after the pass ([`MapStore::encode`]), with the copy of the pass's `counters` and the
    /// store's counts into [`PhotonMaps::batch_counts`], and keeps its maps as batch `k`.
    /// `last`: the iteration's last batch, which keeps the store's output buffers
    /// themselves; an earlier batch's records are copied out (the whole capacity: nothing
    /// waits for their count), since the next batch's store reuses those buffers.
    pub fn encode_batch(&mut self, ctx: &GpuContext, encoder: &mut wgpu::CommandEncoder, settings: &StoreSettings, counters: &wgpu::Buffer, k: u32, last: bool) -> Result<(), WgpuError> {
        let store = self.store_for(Stage::PhotonPass)?;
        let device = &ctx.device;
        store.encode(device, &ctx.queue, &self.pipelines, encoder, settings);
        let at = u64::from(k) * BATCH_COUNTS_BYTES;
        let photon_bytes = size_of::<PhotonCounters>() as u64;
        encoder.copy_buffer_to_buffer(counters, 0, &self.batch_counts, at, photon_bytes);
        encoder.copy_buffer_to_buffer(store.counts_buffer(), 0, &self.batch_counts, at + photon_bytes, size_of::<StoreCounts>() as u64);
        let capacities = (store.capacities().raw_footprints, store.photons_out_capacity());
        let batch = if last {
            BatchMaps {
                footprints: store.footprints.clone(),
                footprint_boxes: store.footprint_boxes.clone(),
                photons: store.photons.clone(),
                photon_boxes: store.photon_boxes.clone(),
                capacities,
                radii: settings.radii,
                accel: None,
            }
        } else {
            use wgpu::BufferUsages as U;
            let copy = |encoder: &mut wgpu::CommandEncoder, source: &wgpu::Buffer, usage: U| {
                let b = device.create_buffer(&wgpu::BufferDescriptor { label: Some("arpa photon batch"), size: source.size(), usage: U::STORAGE | U::COPY_SRC | U::COPY_DST | usage, mapped_at_creation: false });
                encoder.copy_buffer_to_buffer(source, 0, &b, 0, source.size());
                b
            };
            BatchMaps {
                footprints: copy(encoder, &store.footprints, U::empty()),
                footprint_boxes: copy(encoder, &store.footprint_boxes, U::BLAS_INPUT),
                photons: copy(encoder, &store.photons, U::empty()),
                photon_boxes: copy(encoder, &store.photon_boxes, U::BLAS_INPUT),
                capacities,
                radii: settings.radii,
                accel: None,
            }
        };
        self.batches.truncate(k as usize);
        self.batches.push(batch);
        Ok(())
    }

    /// Photon batches kept (the iteration's, after its photon pass).
    pub fn batch_count(&self) -> u32 {
        self.batches.len() as u32
    }

    /// The batches kept, in batch order.
    pub fn batches(&self) -> &[BatchMaps] {
        &self.batches
    }

    /// Builds every batch's acceleration structure over its sorted boxes, the whole
    /// capacity (one submission).
    pub fn build(&mut self, ctx: &GpuContext) -> Result<(), WgpuError> {
        let device = &ctx.device;
        let batches = &mut self.batches;
        for b in batches.iter_mut() {
            b.accel = None;
        }
        scoped(ctx, "acceleration-structure build", || {
            let mut encoder = device.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some("arpa build") });
            for b in batches.iter_mut() {
                let accel = crate::accel::build(device, &mut encoder, &b.footprint_boxes, b.capacities.0, &b.photon_boxes, b.capacities.1).map_err(|e| WgpuError::Size(e.to_string()))?;
                b.accel = Some(accel);
            }
            ctx.submit(encoder);
            Ok(())
        })
    }

    /// Records the gather of batch `k` of the [`PhotonMaps::batch_count`] batches for
    /// `pixels` query records into `image` (every plane of `bandwidth`), with the per-pixel
    /// batch sums in `irradiance` ([`crate::gather::ImageGather::encode`]). Each batch's
    /// gather needs a submission of its own (its parameters are written through the queue).
    #[allow(clippy::too_many_arguments)]
    pub fn encode_gather(
        &self,
        ctx: &GpuContext,
        encoder: &mut wgpu::CommandEncoder,
        k: u32,
        records: &wgpu::Buffer,
        image: &wgpu::Buffer,
        irradiance: &wgpu::Buffer,
        kernel: Kernel,
        bandwidth: Bandwidth,
        pixels: u32,
    ) -> Result<(), WgpuError> {
        let b = self.batches.get(k as usize).ok_or_else(|| StageError::order(Stage::Gather, Stage::PhotonPass))?;
        let accel = b.accel.as_ref().ok_or_else(|| StageError::order(Stage::Gather, Stage::BuildAccelerationStructure))?;
        let batch = GatherBatch::of(k, self.batch_count());
        self.gather.encode(&ctx.device, &ctx.queue, encoder, &b.footprints, &b.photons, &accel.tlas, records, image, irradiance, b.radii, kernel, bandwidth, pixels, batch);
        Ok(())
    }

    /// The gather's counter buffer ([`arpa_core::gpu::layout::GatherCounts`]).
    pub fn gathered_buffer(&self) -> &wgpu::Buffer {
        self.gather.total_buffer()
    }

    /// The sorted footprints of every batch, batch after batch (each caustic first), with
    /// the batches' `counts`.
    pub fn read_footprints(&self, ctx: &GpuContext, counts: &[BatchCounts]) -> Result<Vec<PackedFootprint>, WgpuError> {
        let mut out = Vec::new();
        for (b, c) in self.batches.iter().zip(counts) {
            let n = c.store.total_footprints() as u64;
            out.extend(bytemuck::pod_collect_to_vec::<u8, PackedFootprint>(&read_buffer(ctx, "read_footprints", &b.footprints, n * FOOTPRINT_BYTES)?));
        }
        Ok(out)
    }

    /// The sorted progressive photons of every batch, batch after batch (each caustic
    /// first, padding zero).
    pub fn read_photons(&self, ctx: &GpuContext, counts: &[BatchCounts]) -> Result<Vec<PackedPhoton>, WgpuError> {
        let mut out = Vec::new();
        for (b, c) in self.batches.iter().zip(counts) {
            let n = (c.store.total_photons().min(b.capacities.1)) as u64;
            out.extend(bytemuck::pod_collect_to_vec::<u8, PackedPhoton>(&read_buffer(ctx, "read_photons", &b.photons, n * PHOTON_BYTES)?));
        }
        Ok(out)
    }
}

/// A buffer for the counters of `batches` batches.
fn batch_counts_buffer(ctx: &GpuContext, batches: u32) -> wgpu::Buffer {
    ctx.device.create_buffer(&wgpu::BufferDescriptor {
        label: Some("arpa batch counters"),
        size: u64::from(batches.max(1)) * BATCH_COUNTS_BYTES,
        usage: wgpu::BufferUsages::COPY_SRC | wgpu::BufferUsages::COPY_DST,
        mapped_at_creation: false,
    })
}
