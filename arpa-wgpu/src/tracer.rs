//! [`WgpuTracer`]: the wgpu backend of [`arpa_core::render::tracer::Tracer`] on ray queries.

use crate::accumulate::{AccumPixel, DeviceAccumulator};
use crate::camera::CameraPass;
use crate::device::{AdapterChoice, GpuContext};
use crate::error::WgpuError;
use crate::maps::{PhotonMaps, Readback, read_buffer, scoped};
use crate::store::BATCH_COUNTS_BYTES;
use crate::photon::{PhotonOutputs, PhotonPass};
use crate::scene::GpuScene;
use arpa_core::accumulate::image::Accumulation;
use arpa_core::store::footprint::PackedFootprint;
use arpa_core::gpu::batch::{self, Capacities, RecordLimits, WaitingBatches, batch_count, batch_range};
use arpa_core::{gpu::layout::{BatchCounts, GatherCounts, ImageBufferSizes, StoreSettings}, gpu::fill::check_record_keys};
use arpa_core::gpu::sort::{MAX_SORT_ITEMS, sorted_len};
use arpa_core::render::photon_path::PhotonPassSetup;
use arpa_core::render::prepared_scene::PreparedScene;
use arpa_core::store::progressive_photon::PackedPhoton;
use arpa_core::render::scene::Scene;
use arpa_core::render::tracer::{
    BackendKind, Call, Capabilities, DeviceTimes, Image, IterationStats, QueryRecord, RenderSettings, Stage, StageClock, StageError, Tracer,
    prepare_upload, uploaded,
};

/// Bytes of one query record ([`QueryRecord`]).
const QUERY_BYTES: u64 = std::mem::size_of::<QueryRecord>() as u64;

/// The photon-mapping pipeline on wgpu ray queries (a GPU, or lavapipe).
///
/// Every buffer lives on the device: scene ([`GpuScene`]), query records, the photon
/// pass's append buffers, the sorted maps of each photon batch and their acceleration
/// structures ([`PhotonMaps`]), the iteration image and the running mean
/// ([`DeviceAccumulator`]). The stage bookkeeping is the core's ([`StageClock`]).
///
/// | stage | on the device | the host waits for and reads back |
/// |---|---|---|
/// | [`upload_scene`](Tracer::upload_scene) | validates scene and settings ([`prepare_upload`]), uploads the scene, zeroes the accumulation; the *calibration*: iteration 0's photon pass, one wait per batch, sets the buffers' capacities and B ([`arpa_core::gpu::batch`]) | the calibration's counters |
/// | [`camera_pass`](Tracer::camera_pass) | one query record per pixel ([`CameraPass`]) | nothing |
/// | [`photon_pass`](Tracer::photon_pass) | per photon batch, one submission: photons traced into append buffers ([`PhotonPass`]), the keyed store with its sizes from the pass's counters on the device, the sort and compaction over the capacities into the batch's maps, the copy of both counters ([`crate::maps::PhotonMaps::encode_batch`]) | nothing |
/// | [`build_acceleration_structure`](Tracer::build_acceleration_structure) | per batch, an AABB BLAS per record kind over the capacity and one TLAS ([`crate::accel`]) | nothing |
/// | [`gather`](Tracer::gather) | per pixel and scale `radiance + weight · E_k`, `E_k` summed over the batches in batch order, and the moment planes ([`crate::gather::ImageGather`]) | nothing |
/// | [`accumulate`](Tracer::accumulate) | compensated running sum of every plane, left out when the iteration's status word says its photon pass dropped records | the iteration's one wait: the batches' counters (96 bytes each), the gather's counts (16 bytes) and the stage timestamps (8 bytes per timed submission) |
///
/// A stage submits its work and returns; queue order runs it before the next stage's.
/// [`Tracer::read_stats`], [`Tracer::read_footprints`] and [`Tracer::read_photons`] read
/// the counts they need themselves (a wait) when they are called before the accumulate.
///
/// # Stage times
/// [`IterationStats::times`] are the host's wall-clock time of each stage call: the
/// encoding and submission of its work, plus the waits above (the accumulate's wait covers
/// the device work of every stage before it). Where the adapter has timestamp queries inside encoders,
/// every submission of a stage is framed by two timestamps ([`crate::timing`]) and
/// [`IterationStats::device_times`] holds the device's own time per stage once the
/// iteration's accumulate has run; elsewhere it is [`DeviceTimes::Unavailable`].
///
/// # Bandwidth
/// The iteration image has [`arpa_core::gather::scales::Bandwidth::planes`] planes per pixel
/// (`RenderSettings::bandwidth`: 1 for a global bandwidth; per pixel, the radiance at every
/// scale and the moment planes, [`arpa_core::accumulate::bandwidth`]), plane-major, and so have the
/// accumulated sums: [`Tracer::read_accumulation`] returns every plane and
/// [`Tracer::read_image`] is the core's [`Accumulation::mean`] of them (the per-pixel
/// selection). The image, the batch irradiance and the sums must each fit one storage
/// binding ([`ImageBufferSizes`]; lavapipe: 128 MiB, about 520 k pixels per image with a
/// per-pixel bandwidth): [`Tracer::upload_scene`] refuses a larger image with
/// [`WgpuError::Size`].
///
/// # Photon batches
/// An iteration's records can need more than one storage binding holds (lavapipe: 128 MiB,
/// 1.4 M raw footprints of 96 bytes). The iteration's photons are then traced in *batches*
/// of at most B photons: batch `k` is the global photon indices `[k·B, (k+1)·B)`, traced
/// with exactly the random streams, emitters and record keys of one pass over the
/// iteration, and stored, sorted and kept as maps of its own; the gather adds each batch's
/// irradiance per pixel in batch order ([`arpa_core::gpu::batch`] has the policy: batch
/// ranges, buffer growth, when and how B shrinks). Since the estimate is a sum over
/// records, the batches' sum is the one-pass estimate up to the order of the `f32`
/// additions.
///
/// B starts at the iteration's photon count (one batch) or [`WgpuTracer::set_batch_photons`].
/// When a batch's records exceed what one binding of the adapter holds (raw footprints,
/// progressive photons, or the sorted progressive photons incl. the store's fallbacks), B
/// shrinks and the photon pass starts the iteration again from batch 0; B then stays for
/// the following iterations of the render ([`Tracer::upload_scene`] resets it).
///
/// The batches are part of the stage outputs: [`Tracer::photon_pass`] traces and stores
/// every batch of the iteration (its time and [`IterationStats`] counts cover all of them),
/// [`Tracer::build_acceleration_structure`] builds every batch's structure and
/// [`Tracer::gather`] gathers them all; nothing is traced after the photon pass.
/// [`Tracer::read_footprints`] and [`Tracer::read_photons`] return the iteration's records,
/// batch after batch (each batch sorted by map, caustic first, then by Morton code and
/// key); with one batch, the maps exactly. Every batch but the last is a device copy of
/// the store's output, so an iteration of several batches holds all its sorted records on
/// the device at once (a binding's worth per batch).
///
/// # Capacities and overflow
/// The store, the sort and the acceleration structures run over the append buffers'
/// capacities, so that nothing waits for a count: the slots past the records are padding
/// and inactive boxes. The capacities are calibrated at upload from iteration 0
/// ([`arpa_core::gpu::batch::calibrated_capacity`]) and every iteration starts on them.
/// When an iteration's photon pass drops appends because a buffer is full (the schedule
/// kernel sets the iteration's status word), its accumulate leaves the sums alone, finds
/// the overflow at its wait and traces the iteration again with one wait per batch: the
/// buffers grow ([`arpa_core::gpu::batch::grow`]) and the batch is traced again with the
/// same random streams, so the iteration is the one a large enough buffer gives (no bias);
/// it is then built, gathered and accumulated. The dropped appends are counted in
/// [`IterationStats::overflowed`], and the device times of the stages traced again are the
/// second trace's.
///
/// # Determinism
/// Each photon's and pixel's random stream depends only on `(seed, iteration, index)`;
/// the stored records are sorted by `(map, Morton code, photon key)`, so the maps, their
/// acceleration structures and the gather's traversal order do not depend on the order of
/// the atomic appends. Images are bit-identical for the same scene, settings and seed on
/// the same adapter and driver. The capacities are part of that key (the structures are
/// built over them, and their traversal orders the gather's `f32` sums): they are a
/// function of the render (the calibration), so a checkpoint resumed at any iteration gives
/// the same image. The batch size is part of that key too: a different B sums the
/// same contributions in another `f32` order (relative differences of a few `f32` ulps
/// per pixel), and the automatic B is a function of the scene, settings, seed and the
/// adapter's binding limit (through the record counts of the render's iterations), so a
/// render repeated on the same adapter takes the same B.
///
/// # Stage order
/// As [`arpa_core::render::tracer::Tracer`] ([`StageClock`]); a call whose input is missing returns
/// [`WgpuError::Stage`].
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
    /// The iteration image: every plane of the bandwidth, plane-major.
    image: wgpu::Buffer,
    /// Per scale and pixel, the irradiance summed over the photon batches gathered so far.
    irradiance: wgpu::Buffer,
    accumulator: DeviceAccumulator,
    /// Photons per batch (B): the iteration's photons `[k·B, (k+1)·B)` form batch `k`.
    batch_photons: u32,
    /// What one photon-pass binding holds ([`WgpuTracer::set_binding_limit`] at upload, or
    /// the adapter's limits).
    limits: RecordLimits,
    /// A gather ran and its counts are not in the stats yet (accumulate's wait reads them).
    gather_counts_pending: bool,
    /// The calibrated capacities: every iteration starts on them ([`arpa_core::gpu::batch`]).
    capacities: Capacities,
    /// The capacities of the buffers allocated now.
    allocated: Capacities,
    /// Batches of the current iteration's photon pass.
    batches: u32,
    /// A photon pass ran without waiting and its counters are still on the device only
    /// (accumulate's wait reads them).
    photon_counts_pending: bool,
    clock: StageClock,
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
    /// [`arpa_core::gpu::batch::INITIAL_RECORDS_PER_PHOTON`] per photon of a batch, within
    /// the adapter's binding). The buffers grow when an iteration overflows them; a small
    /// value exercises that path.
    pub fn set_initial_capacity(&mut self, records: Option<u32>) {
        self.initial_capacity = records;
    }

    /// Forces the photons per batch (B, at least 1) of the renders uploaded after this call
    /// (`None`: automatic, see [`WgpuTracer`]'s *Photon batches*). A test hook: a small B
    /// splits an iteration into many batches. The image depends on B at f32 rounding level.
    pub fn set_batch_photons(&mut self, photons: Option<u32>) {
        self.batch_photons = photons.map(|b| b.max(1));
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

    /// The device's sums (every plane of every pixel, plane-major), read back.
    fn read_sums(&self, st: &Loaded) -> Result<Vec<AccumPixel>, WgpuError> {
        let bytes = read_buffer(&self.ctx, "the accumulation", &st.accumulator.pixels, ImageBufferSizes::new(st.pixels, st.settings.bandwidth).accumulator)?;
        Ok(bytemuck::pod_collect_to_vec(&bytes))
    }

    /// The sums read back as the core's accumulation (every plane, exactly).
    fn accumulation(&self, st: &Loaded) -> Result<Accumulation, WgpuError> {
        let pixels = self.read_sums(st)?.iter().map(AccumPixel::to_sum).collect();
        Ok(Accumulation {
            width: st.width,
            height: st.height,
            planes: st.settings.bandwidth.planes() as u32,
            first_iteration: st.clock.first_iteration(),
            iterations: st.clock.accumulated(),
            pixels,
        })
    }

    fn loaded(&self, call: impl Into<Call>) -> Result<&Loaded, StageError> {
        uploaded(self.state.as_deref(), call)
    }

    /// The counters of the batches the maps hold, read back; an error when the last photon
    /// pass dropped records (its accumulate traces the iteration again).
    fn kept_counts(&self, st: &Loaded) -> Result<Vec<BatchCounts>, WgpuError> {
        let counts = read_batch_counts(&self.ctx, &self.maps, st)?;
        if BatchCounts::dropped_in(&counts) > 0 {
            return Err(WgpuError::Size("the last photon pass dropped records for lack of buffer space; its accumulate traces the iteration again with larger buffers".into()));
        }
        Ok(counts)
    }
}

/// Runs `stage` on `clock` ([`StageClock::run`]) with the device timer, where the adapter
/// has one, timing the stage's submissions ([`crate::timing`]).
fn timed<E: From<StageError>>(ctx: &GpuContext, clock: &mut StageClock, stage: Stage, body: impl FnOnce(&mut StageClock) -> Result<(), E>) -> Result<(), E> {
    if let Some(t) = ctx.timer() {
        t.begin_stage(stage, clock.completed());
    }
    let result = clock.run(stage, body);
    if let Some(t) = ctx.timer() {
        t.end_stage();
    }
    result
}

/// Bytes of the gather's counters ([`GatherCounts`]).
const GATHER_COUNTS_BYTES: u64 = size_of::<GatherCounts>() as u64;

/// Writes the gather's counters (`bytes`: one [`GatherCounts`] read back) into `stats`.
fn set_gather_counts(stats: &mut IterationStats, bytes: &[u8]) {
    let total: GatherCounts = bytemuck::pod_read_unaligned(bytes);
    stats.contributions = total.contributions();
    stats.candidates = total.candidates();
    stats.covered = total.covered.map(u64::from);
    stats.query_points = u64::from(total.query_points);
}

/// Waits until the device has finished the submitted work.
fn wait(ctx: &GpuContext, stage: &'static str) -> Result<(), WgpuError> {
    ctx.device.poll(wgpu::PollType::wait_indefinitely()).map(|_| ()).map_err(|e| WgpuError::Readback { stage, message: e.to_string() })
}

/// Bytes of the largest storage binding of this device (or the test hook's smaller limit).
fn binding_bytes(ctx: &GpuContext, binding_limit: Option<u64>) -> u64 {
    let limits = ctx.device.limits();
    limits.max_storage_buffer_binding_size.min(limits.max_buffer_size).min(binding_limit.unwrap_or(u64::MAX))
}

/// Reallocates the photon pass's append buffers and the store's buffers bound to them for
/// `capacities`.
fn resize(ctx: &GpuContext, maps: &mut PhotonMaps, st: &mut Loaded, capacities: Capacities) -> Result<(), WgpuError> {
    let Capacities { raw_footprints, photons, sorted_photons } = capacities;
    if sorted_len(raw_footprints.max(photons).max(sorted_photons)) > MAX_SORT_ITEMS {
        return Err(WgpuError::Size(format!("{raw_footprints} footprints, {photons} photons or {sorted_photons} sorted photons in one batch exceed the device sort's {MAX_SORT_ITEMS} records")));
    }
    // Free the old buffers before allocating the new ones.
    st.outputs = PhotonOutputs::new(ctx, 1, 1)?;
    st.outputs = PhotonOutputs::new(ctx, raw_footprints, photons)?;
    maps.bind_inputs(ctx, st.outputs.footprints(), st.outputs.photons(), st.outputs.counters(), capacities)?;
    st.allocated = capacities;
    Ok(())
}

/// Records and submits batch `k` of the iteration `setup` (its photons `range`): the
/// photon pass and the whole store ([`PhotonMaps::encode_batch`]) in one submission, which
/// first clears the iteration's status word when `clear_status`. Nothing waits.
#[allow(clippy::too_many_arguments)]
fn submit_batch(ctx: &GpuContext, maps: &mut PhotonMaps, st: &Loaded, setup: &PhotonPassSetup, settings: &StoreSettings, range: std::ops::Range<u32>, k: u32, last: bool, clear_status: bool) -> Result<(), WgpuError> {
    scoped(ctx, "photon_pass", || {
        let mut encoder = ctx.device.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some("arpa photon pass") });
        if clear_status {
            encoder.clear_buffer(maps.status(), 0, None);
        }
        st.photon.encode_batch(ctx, &mut encoder, &st.scene, setup, range, &st.outputs)?;
        maps.encode_batch(ctx, &mut encoder, settings, st.outputs.counters(), k, last)?;
        ctx.submit(encoder);
        Ok(())
    })
}

/// The photon pass without a wait: every batch of the iteration `setup` is traced and
/// stored over the calibrated capacities; the counters stay on the device until the
/// accumulate's wait (or a read of the stats or the records) reads them.
fn trace_pipelined(ctx: &GpuContext, maps: &mut PhotonMaps, st: &mut Loaded, setup: &PhotonPassSetup) -> Result<(), WgpuError> {
    let n = setup.photon_count();
    let b = st.batch_photons;
    let batches = batch_count(n, b);
    maps.begin_iteration(ctx, batches);
    let settings = StoreSettings::for_iteration(setup, &st.prepared);
    for k in 0..batches {
        submit_batch(ctx, maps, st, setup, &settings, batch_range(n, b, k), k, k + 1 == batches, k == 0)?;
    }
    st.batches = batches;
    st.photon_counts_pending = true;
    Ok(())
}

/// The photon pass with one wait per batch (the calibration, or an iteration traced again
/// after an overflow), with the core's policy ([`arpa_core::gpu::batch::trace_waiting`]).
/// Returns the most raw footprints, progressive photons and photon sort items a batch
/// appended.
fn trace_waiting(ctx: &GpuContext, maps: &mut PhotonMaps, st: &mut Loaded, stats: &mut IterationStats, setup: &PhotonPassSetup) -> Result<[u32; 3], WgpuError> {
    let (limits, mut batch_photons) = (st.limits, st.batch_photons);
    let settings = StoreSettings::for_iteration(setup, &st.prepared);
    let mut w = Waiting { ctx, maps, st, setup, settings };
    let (batches, most) = batch::trace_waiting(&mut w, setup.photon_count(), &mut batch_photons, &limits, stats)?;
    st.batch_photons = batch_photons;
    st.batches = batches;
    st.photon_counts_pending = false;
    Ok(most)
}

/// The tracer's batches traced with one wait each ([`trace_waiting`]).
struct Waiting<'a> {
    ctx: &'a GpuContext,
    maps: &'a mut PhotonMaps,
    st: &'a mut Loaded,
    setup: &'a PhotonPassSetup,
    settings: StoreSettings,
}

impl WaitingBatches for Waiting<'_> {
    type Error = WgpuError;

    fn begin(&mut self, batches: u32) -> Result<(), WgpuError> {
        self.maps.begin_iteration(self.ctx, batches);
        Ok(())
    }

    fn trace(&mut self, range: std::ops::Range<u32>, k: u32, last: bool) -> Result<BatchCounts, WgpuError> {
        // Every earlier batch fitted: the status word only tells of this one.
        submit_batch(self.ctx, self.maps, self.st, self.setup, &self.settings, range, k, last, true)?;
        let bytes = read_buffer(self.ctx, "photon_pass", self.maps.batch_counts(), (u64::from(k) + 1) * BATCH_COUNTS_BYTES)?;
        Ok(bytemuck::pod_read_unaligned(&bytes[(k as usize) * BATCH_COUNTS_BYTES as usize..]))
    }

    fn resize(&mut self, capacities: Capacities) -> Result<(), WgpuError> {
        resize(self.ctx, self.maps, self.st, capacities)
    }

    fn allocated(&self) -> Capacities {
        self.st.allocated
    }

    fn too_large(&self, batch: &BatchCounts, limits: &RecordLimits) -> WgpuError {
        let (c, s) = (&batch.photon, &batch.store);
        WgpuError::Size(format!(
            "one photon stores {} raw footprints, {} progressive photons and {} sorted progressive photons; adapter {:?} binds at most {}, {} and {}",
            c.footprint_appends, c.photon_appends, s.photon_items, self.ctx.info.name, limits.raw_footprints, limits.photons, limits.sorted_photons
        ))
    }
}

/// The counters of the iteration's batches, read back (a wait).
fn read_batch_counts(ctx: &GpuContext, maps: &PhotonMaps, st: &Loaded) -> Result<Vec<BatchCounts>, WgpuError> {
    Ok(bytemuck::pod_collect_to_vec(&read_buffer(ctx, "photon counters", maps.batch_counts(), u64::from(st.batches) * BATCH_COUNTS_BYTES)?))
}

/// Records and submits the accumulation of the iteration image (left out on the device when
/// the status word says the photon pass dropped records), with the copies of the gather's
/// counts and, for a pipelined photon pass, the batches' counters; then waits once for the
/// iteration and reads them, and the device's stage times. Returns the batches' counters
/// when they were read.
fn accumulate_and_wait(ctx: &GpuContext, maps: &PhotonMaps, st: &mut Loaded, stats: &mut IterationStats) -> Result<Option<Vec<BatchCounts>>, WgpuError> {
    let mut gather = st.gather_counts_pending.then(|| Readback::new(ctx, "gather counts", GATHER_COUNTS_BYTES));
    let batch_bytes = u64::from(st.batches) * BATCH_COUNTS_BYTES;
    let mut batches = st.photon_counts_pending.then(|| Readback::new(ctx, "photon counters", batch_bytes));
    scoped(ctx, "accumulate", || {
        let mut encoder = ctx.device.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some("arpa accumulate") });
        st.accumulator.encode(&ctx.device, &mut encoder, &st.image, Some(maps.status()));
        if let Some(r) = gather.as_mut() {
            r.copy(&mut encoder, maps.gathered_buffer(), GATHER_COUNTS_BYTES);
        }
        if let Some(r) = batches.as_mut() {
            r.copy(&mut encoder, maps.batch_counts(), batch_bytes);
        }
        ctx.submit(encoder);
        Ok(())
    })?;
    for r in [gather.as_mut(), batches.as_mut()].into_iter().flatten() {
        r.map();
    }
    // The iteration's timestamps and counters come back in the same wait as the
    // accumulation: the iteration's one wait.
    let timestamps = ctx.timer().map(|t| (t, t.resolve(&ctx.device, &ctx.queue)));
    wait(ctx, "accumulate")?;
    if let Some(r) = gather {
        set_gather_counts(stats, &r.bytes()?);
        st.gather_counts_pending = false;
    }
    stats.device_times = match timestamps {
        Some((timer, pending)) => timer.read(pending).map_err(|message| WgpuError::Readback { stage: "stage timestamps", message })?,
        None => DeviceTimes::Unavailable,
    };
    st.photon_counts_pending = false;
    batches.map(|r| r.bytes().map(|b| bytemuck::pod_collect_to_vec(&b))).transpose()
}

/// Records and submits the gather of every batch, one submission each (each writes its
/// gather parameters through the queue); its counts come back in the accumulate's wait (or
/// `read_stats`'s).
fn gather_batches(ctx: &GpuContext, maps: &PhotonMaps, st: &mut Loaded) -> Result<(), WgpuError> {
    for k in 0..maps.batch_count() {
        scoped(ctx, "gather", || {
            let mut encoder = ctx.device.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some("arpa gather") });
            maps.encode_gather(ctx, &mut encoder, k, &st.queries, &st.image, &st.irradiance, st.settings.kernel, st.settings.bandwidth, st.pixels)?;
            ctx.submit(encoder);
            Ok(())
        })?;
    }
    st.gather_counts_pending = true;
    Ok(())
}

/// Runs `body` with the device timer timing its submissions as `stage` of `iteration`, then
/// as `resume` (an iteration traced again inside the accumulate keeps its stages' times).
fn timed_as<T>(ctx: &GpuContext, stage: Stage, resume: Stage, iteration: u32, body: impl FnOnce() -> Result<T, WgpuError>) -> Result<T, WgpuError> {
    if let Some(t) = ctx.timer() {
        t.begin_stage(stage, iteration);
    }
    let out = body();
    if let Some(t) = ctx.timer() {
        t.begin_stage(resume, iteration);
    }
    out
}

impl Tracer for WgpuTracer {
    type Error = WgpuError;

    fn capabilities(&self) -> Capabilities {
        let i = &self.ctx.info;
        // Batches lift the buffer limits; the record keys bound photons · max_depth, which
        // upload_scene checks with the settings.
        Capabilities::new(BackendKind::Wgpu, format!("{} ({:?}, {} {})", i.name, i.device_type, i.driver, i.driver_info))
    }

    fn upload_scene(&mut self, scene: &Scene, settings: &RenderSettings) -> Result<(), WgpuError> {
        self.state = None;
        let prepared = prepare_upload(scene, settings)?;
        check_record_keys(settings, BackendKind::Wgpu)?;
        let (width, height) = (scene.camera.width, scene.camera.height);
        let pixels = (width as u64 * height as u64).try_into().ok().filter(|&p: &u32| (p as u64) * QUERY_BYTES <= self.ctx.device.limits().max_storage_buffer_binding_size);
        let Some(pixels) = pixels else {
            return Err(WgpuError::Size(format!("image of {width}×{height} pixels exceeds one storage buffer")));
        };
        // Every plane of the image, the batch irradiance and the sums in one binding each.
        let sizes = ImageBufferSizes::new(pixels, settings.bandwidth);
        let device_limits = self.ctx.device.limits();
        sizes.check(width, height, settings.bandwidth, device_limits.max_storage_buffer_binding_size.min(device_limits.max_buffer_size)).map_err(WgpuError::Size)?;
        let entries = u32::try_from(settings.bandwidth.planes() as u64 * u64::from(pixels)).map_err(|_| WgpuError::Size(format!("image of {width}×{height} pixels: too many planes")))?;
        let gpu_scene = GpuScene::upload(&self.ctx, &prepared).map_err(|e| WgpuError::SceneUpload(e.to_string()))?;
        let ctx = &self.ctx;
        let camera = CameraPass::new(ctx, &gpu_scene, &prepared, settings)?;
        let photon = PhotonPass::new(ctx, &gpu_scene, &prepared, settings)?;
        let limits = RecordLimits::new(binding_bytes(ctx, self.binding_limit));
        let batch_photons = self.batch_photons.unwrap_or(settings.photons_per_iteration).min(settings.photons_per_iteration);
        let initial = Capacities::initial(batch_photons, self.initial_capacity, &limits);
        let outputs = PhotonOutputs::new(ctx, initial.raw_footprints, initial.photons)?;
        self.maps.begin_iteration(ctx, 1);
        self.maps.bind_inputs(ctx, outputs.footprints(), outputs.photons(), outputs.counters(), initial)?;
        let (queries, image, irradiance, accumulator) = scoped(ctx, "allocating the image buffers", || {
            let buffer = |size: u64| {
                ctx.device.create_buffer(&wgpu::BufferDescriptor {
                    label: Some("arpa tracer"),
                    size: size.max(16),
                    usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
                    mapped_at_creation: false,
                })
            };
            Ok((buffer(pixels as u64 * QUERY_BYTES), buffer(sizes.image), buffer(sizes.batch_irradiance), DeviceAccumulator::new(&ctx.device, entries)))
        })?;
        let mut st = Box::new(Loaded {
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
            limits,
            gather_counts_pending: false,
            capacities: initial,
            allocated: initial,
            batches: 1,
            photon_counts_pending: false,
            clock: StageClock::new(),
        });
        if self.initial_capacity.is_none() {
            // The calibration: iteration 0's photon pass, waited for batch by batch, sets
            // the capacities every iteration of the render starts on (and B).
            let setup = PhotonPassSetup::new(&st.prepared, &st.settings, 0);
            let mut stats = IterationStats::default();
            let [fp, ph, items] = trace_waiting(ctx, &mut self.maps, &mut st, &mut stats, &setup)?;
            st.capacities = Capacities::calibrated(fp, ph, items, &limits);
            self.maps.begin_iteration(ctx, 1);
            // The first iteration finds its buffers allocated.
            let calibrated = st.capacities;
            resize(ctx, &mut self.maps, &mut st, calibrated)?;
        }
        self.state = Some(st);
        Ok(())
    }

    fn camera_pass(&mut self) -> Result<(), WgpuError> {
        let st = uploaded(self.state.as_deref_mut(), Stage::CameraPass)?;
        let ctx = &self.ctx;
        timed(ctx, &mut st.clock, Stage::CameraPass, |clock| {
            scoped(ctx, "camera_pass", || {
                let mut encoder = ctx.device.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some("arpa camera pass") });
                st.camera.encode(&mut encoder, clock.completed(), &st.queries);
                ctx.submit(encoder);
                Ok(())
            })
        })
    }

    fn photon_pass(&mut self) -> Result<(), WgpuError> {
        let st = uploaded(self.state.as_deref_mut(), Stage::PhotonPass)?;
        let (ctx, maps) = (&self.ctx, &mut self.maps);
        // The batches read and write the whole state; the clock steps out of it meanwhile.
        let mut clock = std::mem::take(&mut st.clock);
        let result = timed(ctx, &mut clock, Stage::PhotonPass, |clock| {
            let setup = PhotonPassSetup::new(&st.prepared, &st.settings, clock.completed());
            let stats = clock.stats_mut();
            stats.overflowed = 0;
            stats.reset_photon_counts();
            if st.allocated != st.capacities {
                // The calibration or an iteration traced again left other buffers: every
                // iteration starts on the calibrated ones.
                resize(ctx, maps, st, st.capacities)?;
            }
            trace_pipelined(ctx, maps, st, &setup)?;
            stats.radii = setup.radii;
            setup.record_plan(stats);
            Ok(())
        });
        st.clock = clock;
        result
    }

    fn build_acceleration_structure(&mut self) -> Result<(), WgpuError> {
        let st = uploaded(self.state.as_deref_mut(), Stage::BuildAccelerationStructure)?;
        timed(&self.ctx, &mut st.clock, Stage::BuildAccelerationStructure, |_| {
            self.maps.build(&self.ctx)
        })
    }

    fn gather(&mut self) -> Result<(), WgpuError> {
        let st = uploaded(self.state.as_deref_mut(), Stage::Gather)?;
        let ctx = &self.ctx;
        let maps = &self.maps;
        let mut clock = std::mem::take(&mut st.clock);
        let result = timed(ctx, &mut clock, Stage::Gather, |_| gather_batches(ctx, maps, st));
        st.clock = clock;
        result
    }

    /// The iteration's one wait ([`WgpuTracer`]'s table). When it finds that the photon pass
    /// dropped records (the accumulation was then left out on the device), the iteration is
    /// traced again here with grown buffers and one wait per batch, built, gathered and
    /// accumulated; those stages' device times are the second trace's.
    fn accumulate(&mut self) -> Result<(), WgpuError> {
        let st = uploaded(self.state.as_deref_mut(), Stage::Accumulate)?;
        let (ctx, maps) = (&self.ctx, &mut self.maps);
        let mut clock = std::mem::take(&mut st.clock);
        let result = timed(ctx, &mut clock, Stage::Accumulate, |clock| {
            let Some(counts) = accumulate_and_wait(ctx, maps, st, clock.stats_mut())? else {
                return Ok(());
            };
            let lost = BatchCounts::dropped_in(&counts);
            if lost == 0 {
                clock.stats_mut().add_photon_batches(&counts);
                return Ok(());
            }
            let iteration = clock.completed();
            let stats = clock.stats_mut();
            let setup = PhotonPassSetup::new(&st.prepared, &st.settings, iteration);
            timed_as(ctx, Stage::PhotonPass, Stage::Accumulate, iteration, || trace_waiting(ctx, maps, st, stats, &setup))?;
            stats.overflowed += lost;
            setup.record_plan(stats);
            timed_as(ctx, Stage::BuildAccelerationStructure, Stage::Accumulate, iteration, || maps.build(ctx))?;
            timed_as(ctx, Stage::Gather, Stage::Accumulate, iteration, || gather_batches(ctx, maps, st))?;
            accumulate_and_wait(ctx, maps, st, stats)?;
            Ok(())
        });
        st.clock = clock;
        result
    }

    fn iterations(&self) -> u32 {
        self.state.as_ref().map_or(0, |s| s.clock.completed())
    }

    /// The core's [`Accumulation::mean`] of the sums read back: every pixel's mean with a
    /// global bandwidth, the per-pixel selection over the planes otherwise.
    fn read_image(&self) -> Result<Image, WgpuError> {
        let st = self.loaded(Call::ReadImage)?;
        Ok(Image { width: st.width, height: st.height, pixels: self.accumulation(st)?.mean() })
    }

    /// Every plane's sums ([`Accumulation::planes`] = the bandwidth's planes), exactly.
    fn read_accumulation(&self) -> Result<Accumulation, WgpuError> {
        let st = self.loaded(Call::ReadAccumulation)?;
        self.accumulation(st)
    }

    /// Continues `state`: sums of the bandwidth's planes, or an empty accumulation (which
    /// takes them, [`Accumulation::with_planes`]).
    fn restore_accumulation(&mut self, state: &Accumulation) -> Result<(), WgpuError> {
        let st = uploaded(self.state.as_deref_mut(), Call::RestoreAccumulation)?;
        let state = state.with_planes(st.settings.bandwidth.planes() as u32).map_err(|e| StageError::Accumulation(e.to_string()))?;
        let clock = StageClock::for_restore(&state, st.width, st.height)?;
        let pixels = AccumPixel::from_accumulation(&state)?;
        st.accumulator.write_pixels(&self.ctx.queue, &pixels).ok_or_else(|| StageError::Accumulation("pixel count".into()))?;
        wait(&self.ctx, "restore_accumulation")?;
        st.clock = clock;
        Ok(())
    }

    fn read_query_points(&self) -> Result<Vec<QueryRecord>, WgpuError> {
        let st = self.loaded(Call::ReadQueryPoints)?;
        st.clock.require_output(Call::ReadQueryPoints, Stage::CameraPass)?;
        Ok(bytemuck::pod_collect_to_vec(&read_buffer(&self.ctx, "read_query_points", &st.queries, st.pixels as u64 * QUERY_BYTES)?))
    }

    /// The last photon pass's footprints: every batch's, batch after batch (see
    /// [`WgpuTracer`]'s *Photon batches*).
    fn read_footprints(&self) -> Result<Vec<PackedFootprint>, WgpuError> {
        let st = self.loaded(Call::ReadFootprints)?;
        st.clock.require_output(Call::ReadFootprints, Stage::PhotonPass)?;
        self.maps.read_footprints(&self.ctx, &self.kept_counts(st)?)
    }

    /// The last photon pass's progressive photons: every batch's, batch after batch.
    fn read_photons(&self) -> Result<Vec<PackedPhoton>, WgpuError> {
        let st = self.loaded(Call::ReadPhotons)?;
        st.clock.require_output(Call::ReadPhotons, Stage::PhotonPass)?;
        self.maps.read_photons(&self.ctx, &self.kept_counts(st)?)
    }

    /// The stats; after a gather whose accumulate has not run yet, its counts are read
    /// back here (a wait), since the gather itself does not wait for them.
    fn read_stats(&self) -> Result<IterationStats, WgpuError> {
        let st = self.loaded(Call::ReadStats)?;
        let mut stats = *st.clock.stats();
        if st.photon_counts_pending {
            let counts = read_batch_counts(&self.ctx, &self.maps, st)?;
            stats.add_photon_batches(&counts);
        }
        if st.gather_counts_pending {
            set_gather_counts(&mut stats, &read_buffer(&self.ctx, "gather counts", self.maps.gathered_buffer(), GATHER_COUNTS_BYTES)?);
        }
        Ok(stats)
    }
}
