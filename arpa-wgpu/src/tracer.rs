//! [`WgpuTracer`]: the wgpu backend of [`arpa_core::tracer::Tracer`] on ray queries.

use crate::device::DeviceError;

/// Errors of the wgpu backend.
#[derive(Debug, thiserror::Error)]
pub enum WgpuError {
    /// No usable adapter or device (the message names the adapter).
    #[error(transparent)]
    Adapter(#[from] DeviceError),
    /// The scene failed validation.
    #[error("invalid scene: {0}")]
    Scene(#[from] arpa_core::scene::SceneError),
    /// The scene could not be uploaded to the device.
    #[error("scene upload: {0}")]
    SceneUpload(String),
    /// A render setting is out of range.
    #[error("invalid render settings: {0}")]
    Settings(String),
    /// wgpu reported a validation or out-of-memory error while recording `stage`.
    #[error("wgpu error in {stage}: {message}")]
    Device {
        /// The stage.
        stage: &'static str,
        /// wgpu's message.
        message: String,
    },
    /// Reading a buffer back failed.
    #[error("reading back {stage} failed: {message}")]
    Readback {
        /// What was read.
        stage: &'static str,
        /// What failed.
        message: String,
    },
    /// A size beyond what a buffer, dispatch or acceleration structure takes.
    #[error("size limit: {0}")]
    Size(String),
    /// A stage was called before the stage it depends on (in this iteration).
    #[error("{stage} called before {needs}")]
    StageOrder {
        /// The stage called.
        stage: &'static str,
        /// What has to run first.
        needs: &'static str,
    },
    /// The camera pass could not be built.
    #[error(transparent)]
    CameraPass(#[from] crate::camera::CameraPassError),
    /// The photon pass could not be built or run.
    #[error(transparent)]
    PhotonPass(#[from] crate::photon::PhotonPassError),
    /// `u32::MAX − 1` iterations have been accumulated.
    #[error("iteration limit reached ({0} iterations)")]
    IterationLimit(u32),
}

use crate::accumulate::{AccumPixel, DeviceAccumulator};
use crate::device::{AdapterChoice, GpuContext};
use crate::gather::GatherBatch;
use crate::maps::{PhotonMaps, read_buffer, scoped};
use crate::camera::CameraPass;
use crate::photon::{PhotonCounters, PhotonOutputs, PhotonPass};
use crate::scene::GpuScene;
use crate::store::StoreSettings;
use arpa_core::footprint::PackedFootprint;
use arpa_core::photon_path::PhotonPassSetup;
use arpa_core::prepared_scene::PreparedScene;
use arpa_core::progressive_photon::PackedPhoton;
use arpa_core::scene::Scene;
use arpa_core::tracer::{Capabilities, Image, IterationStats, Method, QueryRecord, RenderSettings, Tracer};
use std::time::Instant;

/// Stored records per photon of a batch the photon buffers start with (each buffer; they
/// grow when a batch overflows them).
pub const INITIAL_RECORDS_PER_PHOTON: u32 = 2;

/// Bytes of one query record ([`QueryRecord`]).
const QUERY_BYTES: u64 = std::mem::size_of::<QueryRecord>() as u64;

/// The photon-mapping pipeline on wgpu ray queries (a GPU, or lavapipe).
///
/// Every buffer lives on the device: scene ([`GpuScene`]), query records, the photon
/// pass's append buffers, the sorted maps and their acceleration structure
/// ([`PhotonMaps`]), the iteration image and the running mean ([`DeviceAccumulator`]).
///
/// | stage | on the device | read back |
/// |---|---|---|
/// | [`upload_scene`](Tracer::upload_scene) | validates scene and settings ([`PreparedScene`]), uploads the scene, zeroes the accumulation | — |
/// | [`camera_pass`](Tracer::camera_pass) | one query record per pixel ([`CameraPass`]) | — |
/// | [`photon_pass`](Tracer::photon_pass) | photons (of batch 0) traced into append buffers ([`PhotonPass`]); then keyed store, sort and compaction ([`crate::store::MapStore`]) | the pass's and the store's counters (overflow check, sizes for the build) |
/// | [`build_acceleration_structure`](Tracer::build_acceleration_structure) | AABB BLAS per (kind, map), one TLAS ([`crate::accel`]) | — |
/// | [`gather`](Tracer::gather) | per pixel `radiance + weight · E` ([`crate::gather::ImageGather`]); with several photon batches, the other batches' photon pass, store, build and gather, `E` summed over them | contribution and query-point counts (16 bytes); per further batch, the photon pass's and store's counters |
/// | [`accumulate`](Tracer::accumulate) | compensated running sum | — |
///
/// # Photon batches
/// An iteration's records can need more than one storage binding holds (lavapipe: 128 MiB,
/// 1.4 M raw footprints of 96 bytes). The iteration's photons are then traced in batches of
/// at most B photons: batch `k` traces the global photon indices `[k·B, (k+1)·B)` with
/// exactly the random streams, emitters and record keys of one pass over the iteration
/// ([`PhotonPass::encode_batch`]; the flux is normalised by the iteration's photon count
/// at emission), and each batch runs photon pass → store → sort → build → gather, the
/// gather adding the batch's irradiance per pixel to a sum on the device
/// ([`crate::gather::ImageGather::encode`]); the last batch writes the iteration image,
/// accumulated once. Since the estimate is a sum over records, the batches' sum is the
/// one-pass estimate up to the order of the `f32` additions.
///
/// B starts at the iteration's photon count (one batch) or [`WgpuTracer::set_batch_photons`].
/// When a batch's records exceed what one binding of the adapter holds (raw footprints,
/// progressive photons, or the sorted progressive photons incl. the store's fallbacks),
/// B becomes 90 % of the share of the batch that would have fitted (by the batch's
/// measured record counts) and the iteration is traced again from batch 0; B then stays for
/// the following iterations of the render (it only shrinks; [`Tracer::upload_scene`]
/// resets it). [`Tracer::photon_pass`] and [`Tracer::build_acceleration_structure`] run
/// batch 0; [`Tracer::gather`] runs the other batches (their photon, build and gather
/// times are added to those stages' [`IterationStats::times`]). Counts in
/// [`IterationStats`] are summed over the batches. [`Tracer::read_footprints`] and
/// [`Tracer::read_photons`] return the records of the batch the maps hold: batch 0 after
/// the photon pass, the *last* batch after a gather of an iteration of several batches.
///
/// # Overflow
/// When the photon pass drops appends because a buffer is full (but the batch fits one
/// binding), the batch's photons are discarded, the buffers grow (to 1.25× what was
/// attempted, at least double) and the batch is traced again with the same random
/// streams, so the iteration is the one a large enough buffer gives (no bias); the dropped
/// appends are counted in [`IterationStats::overflowed`] (also those of a batch that was
/// split).
///
/// # Determinism
/// Each photon's and pixel's random stream depends only on `(seed, iteration, index)`;
/// the stored records are sorted by `(map, Morton code, photon key)`, so the maps, their
/// acceleration structure and the gather's traversal order do not depend on the order of
/// the atomic appends. Images are bit-identical for the same scene, settings and seed on
/// the same adapter and driver. The batch size is part of that key: a different B sums the
/// same contributions in another `f32` order (relative differences of a few `f32` ulps
/// per pixel), and the automatic B is a function of the scene, settings, seed and the
/// adapter's binding limit (through the record counts of the render's iterations), so a
/// render repeated on the same adapter takes the same B.
///
/// # Stage order
/// As [`arpa_core::tracer::Tracer`]; a stage whose input is missing returns
/// [`WgpuError::StageOrder`].
pub struct WgpuTracer {
    ctx: GpuContext,
    maps: PhotonMaps,
    state: Option<Box<Loaded>>,
    initial_capacity: Option<u32>,
    batch_photons: Option<u32>,
    binding_limit: Option<u64>,
}

struct Loaded {
    prepared: PreparedScene,
    settings: RenderSettings,
    scene: GpuScene,
    camera: CameraPass,
    photon: PhotonPass,
    outputs: PhotonOutputs,
    width: u32,
    height: u32,
    pixels: u32,
    queries: wgpu::Buffer,
    image: wgpu::Buffer,
    /// Per pixel, the irradiance summed over the photon batches gathered so far.
    irradiance: wgpu::Buffer,
    accumulator: DeviceAccumulator,
    /// Photons per batch (B): the iteration's photons `[k·B, (k+1)·B)` form batch `k`.
    batch_photons: u32,
    /// [`WgpuTracer::set_binding_limit`] at upload.
    binding_limit: Option<u64>,
    /// The current iteration's photon-pass setup (from [`Tracer::photon_pass`]).
    setup: Option<PhotonPassSetup>,
    /// Whether the maps on the device are batch 0's (set by the photon pass; cleared when
    /// a gather traced later batches into them).
    first_batch_in_maps: bool,
    completed: u32,
    stats: IterationStats,
    stats_for: Option<u32>,
    queries_for: Option<u32>,
    store_for: Option<u32>,
    accel_for: Option<u32>,
    image_for: Option<u32>,
}

impl Loaded {
    fn begin_stage(&mut self) {
        if self.stats_for != Some(self.completed) {
            self.stats = IterationStats { iteration: self.completed, radii: self.stats.radii, ..IterationStats::default() };
            self.stats_for = Some(self.completed);
        }
    }

    fn require(&self, have: Option<u32>, stage: &'static str, needs: &'static str) -> Result<(), WgpuError> {
        if have == Some(self.completed) { Ok(()) } else { Err(WgpuError::StageOrder { stage, needs }) }
    }

    fn check_iteration_limit(&self) -> Result<(), WgpuError> {
        if self.completed >= u32::MAX - 1 { Err(WgpuError::IterationLimit(self.completed)) } else { Ok(()) }
    }
}

/// Rejects settings no render can use ([`RenderSettings::validate`], as arpa-cpu does).
pub fn validate_settings(s: &RenderSettings) -> Result<(), WgpuError> {
    s.validate().map_err(|e| WgpuError::Settings(e.0))
}

impl WgpuTracer {
    /// A tracer on the adapter `choice` selects ([`AdapterChoice::Auto`]: a GPU with ray
    /// queries, else lavapipe); the error names the adapter when it has no ray queries.
    pub fn new(choice: &AdapterChoice) -> Result<Self, WgpuError> {
        Self::with_context(GpuContext::new(choice)?)
    }

    /// A tracer on an open device.
    pub fn with_context(ctx: GpuContext) -> Result<Self, WgpuError> {
        let maps = PhotonMaps::new(&ctx)?;
        Ok(Self { ctx, maps, state: None, initial_capacity: None, batch_photons: None, binding_limit: None })
    }

    /// Records each photon buffer holds after the next [`Tracer::upload_scene`] (`None`:
    /// [`INITIAL_RECORDS_PER_PHOTON`] per photon of a batch, within the adapter's binding). The buffers grow when an
    /// iteration overflows them; a small value exercises that path.
    pub fn set_initial_capacity(&mut self, records: Option<u32>) {
        self.initial_capacity = records;
    }

    /// Forces the photons per batch (B) of the renders uploaded after this call (`None`:
    /// automatic, see [`WgpuTracer`]'s *Photon batches*). A test hook: a small B splits an
    /// iteration into many batches. The image depends on B at f32 rounding level.
    pub fn set_batch_photons(&mut self, photons: Option<u32>) {
        self.batch_photons = photons;
    }

    /// Caps the bytes one photon-pass storage binding may hold for the renders uploaded
    /// after this call (`None`: the adapter's limit). A test hook: a small cap makes small
    /// iterations split into batches automatically, as large ones do on the adapter's limit.
    pub fn set_binding_limit(&mut self, bytes: Option<u64>) {
        self.binding_limit = bytes;
    }

    /// Photons per batch (B) the next iteration starts with (`None` before
    /// [`Tracer::upload_scene`]); the iteration has `⌈photons_per_iteration / B⌉` batches.
    pub fn batch_photons(&self) -> Option<u32> {
        self.state.as_ref().map(|s| s.batch_photons)
    }

    /// The device.
    pub fn context(&self) -> &GpuContext {
        &self.ctx
    }

    fn loaded(&self, stage: &'static str) -> Result<&Loaded, WgpuError> {
        self.state.as_deref().ok_or(WgpuError::StageOrder { stage, needs: "upload_scene" })
    }

    fn loaded_mut(&mut self, stage: &'static str) -> Result<&mut Loaded, WgpuError> {
        self.state.as_deref_mut().ok_or(WgpuError::StageOrder { stage, needs: "upload_scene" })
    }

    /// Waits until the device has finished the submitted work (stage timings).
    fn wait(&self, stage: &'static str) -> Result<(), WgpuError> {
        self.ctx.device.poll(wgpu::PollType::wait_indefinitely()).map(|_| ()).map_err(|e| WgpuError::Readback { stage, message: e.to_string() })
    }
}

/// Bytes of the largest storage binding of this device (or the test hook's smaller limit).
fn binding_bytes(ctx: &GpuContext, binding_limit: Option<u64>) -> u64 {
    let limits = ctx.device.limits();
    limits.max_storage_buffer_binding_size.min(limits.max_buffer_size).min(binding_limit.unwrap_or(u64::MAX))
}

/// The most raw footprints and progressive photons one photon-pass buffer holds on this
/// device (its storage-binding and buffer-size limits; the keyed store's 64-byte slots
/// and the sort's item limit too).
fn max_capacities(ctx: &GpuContext, binding_limit: Option<u64>) -> (u32, u32) {
    let bytes = binding_bytes(ctx, binding_limit);
    let fit = |record: usize| u32::try_from(bytes / record as u64).unwrap_or(u32::MAX);
    let sort = crate::sort::MAX_SORT_ITEMS / 2;
    (fit(std::mem::size_of::<crate::photon::KeyedFootprint>()).min(sort), fit(std::mem::size_of::<crate::photon::KeyedPhoton>()).min(sort))
}

/// Zeroes the per-iteration counts the batches sum into (not `overflowed`, which keeps
/// every dropped append of the iteration, nor the times).
fn reset_counts(stats: &mut IterationStats) {
    stats.photons_emitted = 0;
    stats.photon_segments = 0;
    stats.footprints = [0; 2];
    stats.progressive = [0; 2];
    stats.degenerate = 0;
    stats.culled = 0;
    stats.unrepresentable = 0;
    stats.differential_lost = 0;
}

/// Global photon indices of batch `k` with `batch` photons per batch.
fn batch_range(setup: &PhotonPassSetup, batch: u32, k: u32) -> std::ops::Range<u32> {
    let n = setup.photon_count() as u64;
    let start = (k as u64 * batch as u64).min(n);
    start as u32..(start + batch as u64).min(n) as u32
}

/// B for a batch of `photons` that needed `1 / fits` times what one binding holds: 90 % of
/// the share that would have fitted, strictly fewer photons, at least 1.
fn shrink(photons: u32, fits: f64) -> u32 {
    ((photons as f64 * fits * 0.9) as u32).clamp(1, photons.saturating_sub(1).max(1))
}

/// Traces the photons `range` of the iteration `setup` into the photon buffers, stores,
/// sorts and compacts them into `maps` (growing the buffers and tracing again on overflow)
/// and adds the batch's counts to the stats. `Some(B)`: the batch needs more than one
/// storage binding of this adapter holds; nothing was stored and the caller retraces the
/// iteration with B photons per batch.
fn trace_batch(ctx: &GpuContext, maps: &mut PhotonMaps, st: &mut Loaded, setup: &PhotonPassSetup, range: std::ops::Range<u32>) -> Result<Option<u32>, WgpuError> {
    let photons = range.end - range.start;
    let (fp_max, ph_max) = max_capacities(ctx, st.binding_limit);
    // Trace; on overflow discard the batch's records, grow the buffers and trace the same
    // photons again.
    let counters = loop {
        scoped(ctx, "photon_pass", || {
            let mut encoder = ctx.device.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some("arpa photon pass") });
            st.photon.encode_batch(ctx, &mut encoder, &st.scene, setup, range.clone(), &st.outputs)?;
            ctx.queue.submit([encoder.finish()]);
            Ok(())
        })?;
        let c: PhotonCounters = bytemuck::pod_read_unaligned(&read_buffer(ctx, "photon counters", st.outputs.counters(), std::mem::size_of::<PhotonCounters>() as u64)?);
        if c.overflowed() == 0 {
            break c;
        }
        st.stats.overflowed += c.overflowed();
        if c.footprint_appends > fp_max || c.photon_appends > ph_max {
            if photons <= 1 {
                return Err(WgpuError::Size(format!(
                    "one photon stores {} raw footprints and {} progressive photons; adapter {:?} binds at most {fp_max} and {ph_max}",
                    c.footprint_appends, c.photon_appends, ctx.info.name
                )));
            }
            let fits = (fp_max as f64 / c.footprint_appends.max(1) as f64).min(ph_max as f64 / c.photon_appends.max(1) as f64);
            return Ok(Some(shrink(photons, fits)));
        }
        let grow = |appends: u32, capacity: u32, max: u32| {
            if appends > capacity { capacity.saturating_mul(2).max(appends.saturating_add(appends / 4)).min(max) } else { capacity }
        };
        let fp_cap = grow(c.footprint_appends, st.outputs.footprint_capacity(), fp_max);
        let ph_cap = grow(c.photon_appends, st.outputs.photon_capacity(), ph_max);
        if crate::sort::sorted_len(fp_cap.saturating_add(ph_cap)) > crate::sort::MAX_SORT_ITEMS || fp_cap.saturating_add(ph_cap) < fp_cap {
            return Err(WgpuError::Size(format!("{} footprints and {} photons in one batch exceed the device sort's {} records", c.footprint_appends, c.photon_appends, crate::sort::MAX_SORT_ITEMS)));
        }
        // Free the old buffers before allocating the larger ones.
        st.outputs = PhotonOutputs::new(ctx, 1, 1)?;
        st.outputs = PhotonOutputs::new(ctx, fp_cap, ph_cap)?;
        maps.bind_inputs(ctx, st.outputs.footprints(), st.outputs.photons(), fp_cap, ph_cap)?;
    };
    let store = StoreSettings {
        heuristics: setup.heuristics.pack(),
        radii: setup.radii.map(|r| r as f32),
        bounds: st.prepared.bounds().to_f32_conservative(),
        raw_count: counters.footprints_written(),
        photon_count: counters.photons_written(),
    };
    let counts = maps.store_sorted(ctx, &store)?;
    // The sorted progressive photons (the pass's plus the footprints' fallbacks) must fit
    // one binding too.
    let sorted_max = binding_bytes(ctx, st.binding_limit) / std::mem::size_of::<PackedPhoton>() as u64;
    if counts.photon_items as u64 > sorted_max {
        st.stats.overflowed += counts.photon_items as u64 - sorted_max;
        if photons <= 1 {
            return Err(WgpuError::Size(format!("one photon stores {} progressive photons; adapter {:?} binds at most {sorted_max}", counts.photon_items, ctx.info.name)));
        }
        return Ok(Some(shrink(photons, sorted_max as f64 / counts.photon_items as f64)));
    }
    // The sort's device time belongs to the photon stage.
    ctx.device.poll(wgpu::PollType::wait_indefinitely()).map_err(|e| WgpuError::Readback { stage: "photon_pass", message: e.to_string() })?;
    let stats = &mut st.stats;
    stats.photons_emitted += counters.emitted as u64;
    stats.photon_segments += counters.segments as u64;
    for m in 0..2 {
        stats.footprints[m] += counts.footprints[m] as u64;
        stats.progressive[m] += counts.photons[m] as u64;
    }
    stats.degenerate += counts.degenerate as u64;
    stats.culled += counts.culled as u64;
    stats.unrepresentable += counts.unrepresentable as u64;
    stats.differential_lost += counters.differential_lost as u64;
    Ok(None)
}

/// The gather of the iteration `setup`, batch 0's maps already built: gathers them and,
/// when the iteration has more batches, traces, stores, builds and gathers each of the
/// others in turn, summing the irradiance per pixel on the device; the last batch writes
/// the image. A batch too large for the adapter shrinks B and restarts the iteration at
/// batch 0 (counts reset). Times go to the stage each step belongs to.
fn gather_batches(ctx: &GpuContext, maps: &mut PhotonMaps, st: &mut Loaded, setup: &PhotonPassSetup) -> Result<(), WgpuError> {
    let n = setup.photon_count();
    let wait = |stage: &'static str| ctx.device.poll(wgpu::PollType::wait_indefinitely()).map(|_| ()).map_err(|e| WgpuError::Readback { stage, message: e.to_string() });
    let mut k = 0u32;
    let mut traced = true;
    st.stats.times.gather = 0.0;
    loop {
        let batches = n.div_ceil(st.batch_photons).max(1);
        if !traced {
            let start = Instant::now();
            let range = batch_range(setup, st.batch_photons, k);
            let smaller = trace_batch(ctx, maps, st, setup, range)?;
            st.stats.times.photon += start.elapsed().as_secs_f64();
            if let Some(b) = smaller {
                st.batch_photons = b;
                reset_counts(&mut st.stats);
                k = 0;
                continue;
            }
            let start = Instant::now();
            maps.build(ctx)?;
            wait("build_acceleration_structure")?;
            st.stats.times.build += start.elapsed().as_secs_f64();
        }
        st.first_batch_in_maps = k == 0;
        let start = Instant::now();
        let batch = GatherBatch { first: k == 0, last: k + 1 >= batches };
        scoped(ctx, "gather", || {
            let mut encoder = ctx.device.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some("arpa gather") });
            maps.encode_gather(ctx, &mut encoder, &st.queries, &st.image, &st.irradiance, st.settings.kernel, st.pixels, batch)?;
            ctx.queue.submit([encoder.finish()]);
            Ok(())
        })?;
        wait("gather")?;
        st.stats.times.gather += start.elapsed().as_secs_f64();
        k += 1;
        traced = false;
        if k >= batches {
            return Ok(());
        }
    }
}

impl Tracer for WgpuTracer {
    type Error = WgpuError;

    fn capabilities(&self) -> Capabilities {
        let i = &self.ctx.info;
        Capabilities {
            backend: arpa_core::tracer::BackendKind::Wgpu,
            device: format!("{} ({:?}, {} {})", i.name, i.device_type, i.driver, i.driver_info),
            methods: vec![Method::Arpa, Method::Rtpm],
            // Batches lift the buffer limits; the record keys bound photons · max_depth
            // (checked by upload_scene with the settings).
            max_photons_per_iteration: None,
            deterministic: true,
        }
    }

    fn upload_scene(&mut self, scene: &Scene, settings: &RenderSettings) -> Result<(), WgpuError> {
        self.state = None;
        validate_settings(settings)?;
        if settings.photons_per_iteration as u64 * settings.max_depth as u64 > u32::MAX as u64 {
            return Err(WgpuError::Settings(format!(
                "photons_per_iteration {} × max_depth {} exceeds the u32 record keys of this backend (at most {} photons at this depth)",
                settings.photons_per_iteration,
                settings.max_depth,
                u32::MAX / settings.max_depth
            )));
        }
        if self.batch_photons == Some(0) {
            return Err(WgpuError::Settings("the forced batch size must be at least 1 photon".into()));
        }
        let prepared = PreparedScene::new(scene.clone())?;
        let (width, height) = (scene.camera.width, scene.camera.height);
        let pixels = (width as u64 * height as u64).try_into().ok().filter(|&p: &u32| (p as u64) * QUERY_BYTES <= self.ctx.device.limits().max_storage_buffer_binding_size);
        let Some(pixels) = pixels else {
            return Err(WgpuError::Size(format!("image of {width}×{height} pixels exceeds one storage buffer")));
        };
        let gpu_scene = GpuScene::upload(&self.ctx, &prepared).map_err(|e| WgpuError::SceneUpload(e.to_string()))?;
        let ctx = &self.ctx;
        let camera = CameraPass::new(ctx, &gpu_scene, &prepared, settings)?;
        let photon = PhotonPass::new(ctx, &gpu_scene, prepared.emitters().len(), settings)?;
        let (fp_max, ph_max) = max_capacities(ctx, self.binding_limit);
        let batch_photons = self.batch_photons.unwrap_or(settings.photons_per_iteration).min(settings.photons_per_iteration);
        let capacity = self.initial_capacity.unwrap_or(batch_photons.saturating_mul(INITIAL_RECORDS_PER_PHOTON)).max(1);
        let (fp_cap, ph_cap) = (capacity.min(fp_max), capacity.min(ph_max));
        let outputs = PhotonOutputs::new(ctx, fp_cap, ph_cap)?;
        self.maps.bind_inputs(ctx, outputs.footprints(), outputs.photons(), fp_cap, ph_cap)?;
        let (queries, image, irradiance, accumulator) = scoped(ctx, "allocating the image buffers", || {
            let buffer = |size: u64| {
                ctx.device.create_buffer(&wgpu::BufferDescriptor {
                    label: Some("arpa tracer"),
                    size: size.max(16),
                    usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
                    mapped_at_creation: false,
                })
            };
            Ok((buffer(pixels as u64 * QUERY_BYTES), buffer(pixels as u64 * 16), buffer(pixels as u64 * 16), DeviceAccumulator::new(&ctx.device, pixels)))
        })?;
        self.state = Some(Box::new(Loaded {
            prepared,
            settings: *settings,
            scene: gpu_scene,
            camera,
            photon,
            outputs,
            width,
            height,
            pixels,
            queries,
            image,
            irradiance,
            accumulator,
            batch_photons,
            binding_limit: self.binding_limit,
            setup: None,
            first_batch_in_maps: false,
            completed: 0,
            stats: IterationStats::default(),
            stats_for: Some(0),
            queries_for: None,
            store_for: None,
            accel_for: None,
            image_for: None,
        }));
        Ok(())
    }

    fn camera_pass(&mut self) -> Result<(), WgpuError> {
        let st = self.loaded("camera_pass")?;
        st.check_iteration_limit()?;
        let start = Instant::now();
        let ctx = &self.ctx;
        scoped(ctx, "camera_pass", || {
            let mut encoder = ctx.device.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some("arpa camera pass") });
            st.camera.encode(&mut encoder, st.completed, &st.queries);
            ctx.queue.submit([encoder.finish()]);
            Ok(())
        })?;
        self.wait("camera_pass")?;
        let st = self.loaded_mut("camera_pass")?;
        st.begin_stage();
        st.queries_for = Some(st.completed);
        st.image_for = None;
        st.stats.times.camera = start.elapsed().as_secs_f64();
        Ok(())
    }

    fn photon_pass(&mut self) -> Result<(), WgpuError> {
        let start = Instant::now();
        let st = self.state.as_deref_mut().ok_or(WgpuError::StageOrder { stage: "photon_pass", needs: "upload_scene" })?;
        st.check_iteration_limit()?;
        st.begin_stage();
        st.store_for = None;
        st.accel_for = None;
        st.image_for = None;
        st.first_batch_in_maps = false;
        let setup = PhotonPassSetup::new(&st.prepared, &st.settings, st.completed);
        st.stats.overflowed = 0;
        // Batch 0 (the whole iteration when it fits); a batch too large for one binding
        // shrinks B and is traced again.
        loop {
            reset_counts(&mut st.stats);
            let range = batch_range(&setup, st.batch_photons, 0);
            match trace_batch(&self.ctx, &mut self.maps, st, &setup, range)? {
                None => break,
                Some(smaller) => st.batch_photons = smaller,
            }
        }
        st.stats.radii = setup.radii;
        st.setup = Some(setup);
        st.first_batch_in_maps = true;
        st.store_for = Some(st.completed);
        st.stats.times.photon = start.elapsed().as_secs_f64();
        Ok(())
    }

    fn build_acceleration_structure(&mut self) -> Result<(), WgpuError> {
        let st = self.loaded("build_acceleration_structure")?;
        st.require(st.store_for, "build_acceleration_structure", "photon_pass")?;
        let start = Instant::now();
        self.maps.build(&self.ctx)?;
        self.wait("build_acceleration_structure")?;
        let st = self.loaded_mut("build_acceleration_structure")?;
        st.begin_stage();
        st.accel_for = Some(st.completed);
        st.image_for = None;
        st.stats.times.build = start.elapsed().as_secs_f64();
        Ok(())
    }

    fn gather(&mut self) -> Result<(), WgpuError> {
        let st = self.state.as_deref_mut().ok_or(WgpuError::StageOrder { stage: "gather", needs: "upload_scene" })?;
        st.require(st.queries_for, "gather", "camera_pass")?;
        st.require(st.accel_for, "gather", "build_acceleration_structure")?;
        if !st.first_batch_in_maps {
            // The maps hold a later batch of an iteration already gathered.
            return Err(WgpuError::StageOrder { stage: "gather", needs: "photon_pass" });
        }
        let Some(setup) = st.setup.take() else {
            return Err(WgpuError::StageOrder { stage: "gather", needs: "photon_pass" });
        };
        let result = gather_batches(&self.ctx, &mut self.maps, st, &setup);
        st.setup = Some(setup);
        result?;
        let total: [u32; 4] = bytemuck::pod_read_unaligned(&read_buffer(&self.ctx, "gather counts", self.maps.gathered_buffer(), 16)?);
        let st = self.loaded_mut("gather")?;
        st.begin_stage();
        st.stats.gathered = total[0] as u64 | (total[1] as u64) << 32;
        st.stats.query_points = total[2] as u64;
        st.image_for = Some(st.completed);
        Ok(())
    }

    fn accumulate(&mut self) -> Result<(), WgpuError> {
        let st = self.loaded("accumulate")?;
        st.require(st.image_for, "accumulate", "gather")?;
        let start = Instant::now();
        let ctx = &self.ctx;
        scoped(ctx, "accumulate", || {
            let mut encoder = ctx.device.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some("arpa accumulate") });
            st.accumulator.encode(&ctx.device, &mut encoder, &st.image);
            ctx.queue.submit([encoder.finish()]);
            Ok(())
        })?;
        self.wait("accumulate")?;
        let st = self.loaded_mut("accumulate")?;
        st.begin_stage();
        st.completed += 1;
        st.image_for = None;
        st.stats.iteration = st.completed;
        st.stats.times.accumulate = start.elapsed().as_secs_f64();
        Ok(())
    }

    fn iterations(&self) -> u32 {
        self.state.as_ref().map_or(0, |s| s.completed)
    }

    fn read_image(&self) -> Result<Image, WgpuError> {
        let st = self.loaded("read_image")?;
        let bytes = read_buffer(&self.ctx, "read_image", &st.accumulator.pixels, st.pixels as u64 * 32)?;
        let acc: Vec<AccumPixel> = bytemuck::pod_collect_to_vec(&bytes);
        Ok(Image { width: st.width, height: st.height, pixels: DeviceAccumulator::mean(&acc, st.completed) })
    }

    fn read_query_points(&self) -> Result<Vec<QueryRecord>, WgpuError> {
        let st = self.loaded("read_query_points")?;
        if st.queries_for.is_none() {
            return Err(WgpuError::StageOrder { stage: "read_query_points", needs: "camera_pass" });
        }
        Ok(bytemuck::pod_collect_to_vec(&read_buffer(&self.ctx, "read_query_points", &st.queries, st.pixels as u64 * QUERY_BYTES)?))
    }

    fn read_footprints(&self) -> Result<Vec<PackedFootprint>, WgpuError> {
        let st = self.loaded("read_footprints")?;
        if st.store_for.is_none() {
            return Err(WgpuError::StageOrder { stage: "read_footprints", needs: "photon_pass" });
        }
        self.maps.read_footprints(&self.ctx)
    }

    fn read_photons(&self) -> Result<Vec<PackedPhoton>, WgpuError> {
        let st = self.loaded("read_photons")?;
        if st.store_for.is_none() {
            return Err(WgpuError::StageOrder { stage: "read_photons", needs: "photon_pass" });
        }
        self.maps.read_photons(&self.ctx)
    }

    fn read_stats(&self) -> Result<IterationStats, WgpuError> {
        Ok(self.loaded("read_stats")?.stats)
    }
}
