//! The photon maps of one iteration on the device: keyed store, sort and compaction
//! ([`crate::store::MapStore`]), the AABB acceleration structure ([`crate::accel`]) and
//! the image gather ([`crate::gather::ImageGather`]), on buffers that stay on the device.
//! The host reads back only the store's 32-byte counters (they size the acceleration
//! structure build: wgpu has no indirect build) and what the caller asks for.
//!
//! [`run_from_host`] runs the chain on host data (raw footprints, photons, query records),
//! for the tests against the core and the benchmark.

use crate::accel::MapAccel;
use crate::accumulate::{AccumPixel, DeviceAccumulator};
use crate::device::GpuContext;
use crate::gather::{GatherBatch, ImageGather};
use crate::store::{KeyedFootprint, KeyedPhoton, MapStore, StoreCounts, StorePipelines, StoreSettings};
use crate::tracer::WgpuError;
use arpa_core::footprint::PackedFootprint;
use arpa_core::kernel::Kernel;
use arpa_core::progressive_photon::PackedPhoton;
use arpa_core::tracer::QueryRecord;
use wgpu::util::DeviceExt;

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
        ctx.queue.submit([encoder.finish()]);
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

/// The store → sort → build → gather chain's device state (pipelines, store buffers for
/// the current input buffers, the last structure and counts).
pub struct PhotonMaps {
    pipelines: StorePipelines,
    gather: ImageGather,
    store: Option<MapStore>,
    accel: Option<MapAccel>,
    counts: StoreCounts,
    radii: [f32; 2],
}

impl PhotonMaps {
    /// Compiles the chain's pipelines.
    pub fn new(ctx: &GpuContext) -> Result<Self, WgpuError> {
        scoped(ctx, "compiling the store and gather pipelines", || {
            Ok(Self {
                pipelines: StorePipelines::new(&ctx.device),
                gather: ImageGather::new(&ctx.device),
                store: None,
                accel: None,
                counts: StoreCounts::default(),
                radii: [0.0; 2],
            })
        })
    }

    /// Binds the photon pass's output buffers (`raw`: [`KeyedFootprint`]s, `photons`:
    /// [`KeyedPhoton`]s) with their capacities; call again whenever they are reallocated.
    pub fn bind_inputs(&mut self, ctx: &GpuContext, raw: &wgpu::Buffer, photons: &wgpu::Buffer, raw_capacity: u32, photon_capacity: u32) -> Result<(), WgpuError> {
        self.store = None;
        self.accel = None;
        let store = scoped(ctx, "allocating the store buffers", || {
            MapStore::new(&ctx.device, &self.pipelines, raw, photons, raw_capacity, photon_capacity).map_err(|e| WgpuError::Size(e.to_string()))
        })?;
        self.store = Some(store);
        Ok(())
    }

    fn store(&self, stage: &'static str) -> Result<&MapStore, WgpuError> {
        self.store.as_ref().ok_or(WgpuError::StageOrder { stage, needs: "photon_pass" })
    }

    /// Stores, sorts and compacts the photon pass's output, reads the counts back and
    /// builds the acceleration structure over the sorted boxes. Returns the counts.
    pub fn store_and_build(&mut self, ctx: &GpuContext, settings: &StoreSettings) -> Result<StoreCounts, WgpuError> {
        let counts = self.store_sorted(ctx, settings)?;
        self.build(ctx)?;
        Ok(counts)
    }

    /// Stores, sorts and compacts the photon pass's output and reads the counts back
    /// (drops the previous acceleration structure).
    pub fn store_sorted(&mut self, ctx: &GpuContext, settings: &StoreSettings) -> Result<StoreCounts, WgpuError> {
        self.accel = None;
        let store = self.store("photon_pass")?;
        scoped(ctx, "store", || {
            let mut encoder = ctx.device.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some("arpa store") });
            store.encode_store(&ctx.queue, &self.pipelines, &mut encoder, settings).map_err(|e| WgpuError::Size(e.to_string()))?;
            ctx.queue.submit([encoder.finish()]);
            Ok(())
        })?;
        let bytes = read_buffer(ctx, "store counts", store.counts_buffer(), std::mem::size_of::<StoreCounts>() as u64)?;
        let counts: StoreCounts = bytemuck::pod_read_unaligned(&bytes);
        scoped(ctx, "sort", || {
            let mut encoder = ctx.device.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some("arpa sort") });
            store.encode_sort(&ctx.device, &ctx.queue, &self.pipelines, &mut encoder, settings, &counts).map_err(|e| WgpuError::Size(e.to_string()))?;
            ctx.queue.submit([encoder.finish()]);
            Ok(())
        })?;
        self.counts = counts;
        self.radii = settings.radii;
        Ok(counts)
    }

    /// Builds the acceleration structure over the boxes of the last
    /// [`PhotonMaps::store_sorted`].
    pub fn build(&mut self, ctx: &GpuContext) -> Result<(), WgpuError> {
        self.accel = None;
        let store = self.store("build_acceleration_structure")?;
        let counts = self.counts;
        let accel = scoped(ctx, "acceleration-structure build", || {
            let mut encoder = ctx.device.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some("arpa build") });
            let accel = crate::accel::build(&ctx.device, &mut encoder, &store.footprint_boxes, &store.photon_boxes, &counts).map_err(|e| WgpuError::Size(e.to_string()))?;
            ctx.queue.submit([encoder.finish()]);
            Ok(accel)
        })?;
        self.accel = Some(accel);
        Ok(())
    }

    /// Counts of the last [`PhotonMaps::store_and_build`].
    pub fn counts(&self) -> StoreCounts {
        self.counts
    }

    /// Records the gather of `pixels` query records into `image`, as photon batch `batch`
    /// of the iteration with the per-pixel batch sum in `irradiance` (see
    /// [`ImageGather::encode`]; [`GatherBatch::WHOLE`] for an iteration in one batch).
    #[allow(clippy::too_many_arguments)]
    pub fn encode_gather(
        &self,
        ctx: &GpuContext,
        encoder: &mut wgpu::CommandEncoder,
        records: &wgpu::Buffer,
        image: &wgpu::Buffer,
        irradiance: &wgpu::Buffer,
        kernel: Kernel,
        pixels: u32,
        batch: GatherBatch,
    ) -> Result<(), WgpuError> {
        let store = self.store("gather")?;
        let accel = self.accel.as_ref().ok_or(WgpuError::StageOrder { stage: "gather", needs: "build_acceleration_structure" })?;
        self.gather.encode(&ctx.device, &ctx.queue, encoder, &store.footprints, &store.photons, &accel.tlas, records, image, irradiance, self.radii, kernel, pixels, batch);
        Ok(())
    }

    /// The gather's counter buffer (four `u32`: contributions low, high word, valid query
    /// records, zero).
    pub fn gathered_buffer(&self) -> &wgpu::Buffer {
        self.gather.total_buffer()
    }

    /// The sorted footprints of the last store (caustic first): with photon batches, the
    /// last batch's.
    pub fn read_footprints(&self, ctx: &GpuContext) -> Result<Vec<PackedFootprint>, WgpuError> {
        let store = self.store("read_footprints")?;
        let n = self.counts.total_footprints() as u64;
        Ok(bytemuck::pod_collect_to_vec(&read_buffer(ctx, "read_footprints", &store.footprints, n * 64)?))
    }

    /// The sorted progressive photons of the last store (caustic first, padding zero): with
    /// photon batches, the last batch's.
    pub fn read_photons(&self, ctx: &GpuContext) -> Result<Vec<PackedPhoton>, WgpuError> {
        let store = self.store("read_photons")?;
        let n = self.counts.total_photons() as u64;
        Ok(bytemuck::pod_collect_to_vec(&read_buffer(ctx, "read_photons", &store.photons, n * 48)?))
    }
}

/// What [`run_from_host`] read back.
#[derive(Clone, Debug, Default)]
pub struct HostRun {
    /// Store counts.
    pub counts: StoreCounts,
    /// Sorted footprints.
    pub footprints: Vec<PackedFootprint>,
    /// Sorted progressive photons.
    pub photons: Vec<PackedPhoton>,
    /// The iteration image (radiance per pixel, RGB).
    pub image: Vec<[f32; 3]>,
    /// Contributions the gather found.
    pub gathered: u64,
    /// The running mean after accumulating `image` `iterations` times.
    pub mean: Vec<arpa_core::glam::Vec3>,
}

/// Uploads `raw` and `photons` as a photon pass would leave them, runs store, sort,
/// build and gather for `records`, and accumulates the iteration image `iterations` times
/// (to exercise the running mean). For tests and benchmarks.
pub fn run_from_host(
    ctx: &GpuContext,
    raw: &[KeyedFootprint],
    photons: &[KeyedPhoton],
    settings: &StoreSettings,
    records: &[QueryRecord],
    kernel: Kernel,
    iterations: u32,
) -> Result<HostRun, WgpuError> {
    let device = &ctx.device;
    let pixels = u32::try_from(records.len()).map_err(|_| WgpuError::Size(format!("{} query records", records.len())))?;
    let upload = |bytes: &[u8], usage| {
        let pad = [0u8; 96];
        let contents = if bytes.is_empty() { &pad[..] } else { bytes };
        device.create_buffer_init(&wgpu::util::BufferInitDescriptor { label: Some("arpa host upload"), contents, usage: wgpu::BufferUsages::STORAGE | usage })
    };
    let (raw_buf, ph_buf, rec_buf) = scoped(ctx, "upload", || {
        Ok((
            upload(bytemuck::cast_slice(raw), wgpu::BufferUsages::empty()),
            upload(bytemuck::cast_slice(photons), wgpu::BufferUsages::empty()),
            upload(bytemuck::cast_slice(records), wgpu::BufferUsages::empty()),
        ))
    })?;
    let mut maps = PhotonMaps::new(ctx)?;
    maps.bind_inputs(ctx, &raw_buf, &ph_buf, raw.len() as u32, photons.len() as u32)?;
    let counts = maps.store_and_build(ctx, settings)?;
    let (image_buf, acc) = scoped(ctx, "gather", || {
        let pixel_buffer = || {
            device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("arpa image"),
                size: pixels.max(1) as u64 * 16,
                usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
                mapped_at_creation: false,
            })
        };
        let (image_buf, irradiance) = (pixel_buffer(), pixel_buffer());
        let acc = DeviceAccumulator::new(device, pixels);
        let mut encoder = device.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some("arpa gather") });
        maps.encode_gather(ctx, &mut encoder, &rec_buf, &image_buf, &irradiance, kernel, pixels, GatherBatch::WHOLE)?;
        for _ in 0..iterations {
            acc.encode(device, &mut encoder, &image_buf);
        }
        ctx.queue.submit([encoder.finish()]);
        Ok((image_buf, acc))
    })?;
    let image: Vec<[f32; 4]> = bytemuck::pod_collect_to_vec(&read_buffer(ctx, "image", &image_buf, pixels as u64 * 16)?);
    let total: [u32; 4] = bytemuck::pod_read_unaligned(&read_buffer(ctx, "gathered", maps.gathered_buffer(), 16)?);
    let acc_pixels: Vec<AccumPixel> = bytemuck::pod_collect_to_vec(&read_buffer(ctx, "accumulator", &acc.pixels, pixels as u64 * 32)?);
    Ok(HostRun {
        counts,
        footprints: maps.read_footprints(ctx)?,
        photons: maps.read_photons(ctx)?,
        image: image.iter().map(|p| [p[0], p[1], p[2]]).collect(),
        gathered: total[0] as u64 | (total[1] as u64) << 32,
        mean: DeviceAccumulator::mean(&acc_pixels, iterations),
    })
}
