//! [`VkTracer`]: the Vulkan backend of [`arpa_core::render::tracer::Tracer`] on ray-tracing
//! pipelines.

use crate::accumulate::{AccumPixel, DeviceAccumulator, accumulate_pipeline};
use crate::buffer::Buffer;
use crate::camera::{CameraPass, QUERY_RECORD_BYTES, camera_pipeline};
use crate::compute::ComputePipeline;
use crate::pipeline::RtPipeline;
use crate::device::{AdapterChoice, ContextOptions, VkContext};
use crate::error::VkError;
use crate::gather::{GatherInputs, GatherPass, gather_pipeline};
use crate::map_accel::MapAccel;
use crate::maps::{MapStore, StorePipelines};
use crate::photons::{PhotonOutputs, PhotonPass, photon_pipeline};
use crate::scene::VkScene;
use arpa_core::accumulate::image::Accumulation;
use arpa_core::store::footprint::PackedFootprint;
use arpa_core::gpu::batch::{self, Capacities, RecordLimits, WaitingBatches, batch_count, batch_range};
use arpa_core::{gpu::layout::{BatchCounts, CameraParams, GatherBatch, ImageBufferSizes, PhotonCounters, StoreCounts, StoreSettings}, gpu::fill::check_record_keys};
use arpa_core::render::photon_path::PhotonPassSetup;
use arpa_core::render::prepared_scene::PreparedScene;
use arpa_core::store::progressive_photon::PackedPhoton;
use arpa_core::render::scene::{Scene, SceneError};
use arpa_core::render::tracer::{
    BackendKind, Call, Capabilities, Image, IterationStats, QueryRecord, RenderSettings, Stage, StageClock, StageError, Tracer, prepare_upload,
    uploaded,
};
use crate::timing::{StageLedger, StageScope};
use ash::vk;
use gpu_allocator::MemoryLocation;
use std::ops::Range;
use std::sync::{Arc, Mutex};

/// Errors of the Vulkan backend.
#[derive(Debug, thiserror::Error)]
pub enum VkTracerError {
    /// A call out of order, the iteration limit, or a scene or settings no render can use.
    #[error(transparent)]
    Stage(#[from] StageError),
    /// The device, a Vulkan call, a shader or a resource failed (the message names the
    /// adapter, the call or the resource).
    #[error(transparent)]
    Vulkan(#[from] VkError),
    /// The camera cannot make rays (its frame is degenerate).
    #[error("camera: {0}")]
    Camera(#[from] SceneError),
    /// More records, pixels or rays than one binding, launch or structure of this adapter
    /// takes.
    #[error("size limit on {adapter:?}: {message}")]
    Size {
        /// The adapter's name.
        adapter: String,
        /// What is too large.
        message: String,
    },
}

/// The photon-mapping pipeline on Vulkan ray-tracing pipelines (a GPU, or lavapipe).
///
/// | stage | on the device | host waits for / reads back |
/// |---|---|---|
/// | [`upload_scene`](Tracer::upload_scene) | validates scene and settings, builds the triangle structures, uploads the scene tables, compiles the pipelines; the *calibration*: iteration 0's photon pass, one wait per batch, sets the buffers' capacities and B ([`arpa_core::gpu::batch`]) | the uploads, the calibration's counters |
/// | [`camera_pass`](Tracer::camera_pass) | ray generation per pixel, closest-hit and miss over the triangles ([`CameraPass`]) | nothing |
/// | [`photon_pass`](Tracer::photon_pass) | per photon batch, one submission: its parameters (`vkCmdUpdateBuffer`), ray generation per photon appending keyed footprints and photons ([`PhotonPass`]), the keyed store with its record counts and dispatch sizes from the pass's counters on the device (`schedule.wgsl`), the sort and compaction over the capacities into the batch's maps and boxes ([`MapStore`]), the copy of both counters | nothing |
/// | [`build_acceleration_structure`](Tracer::build_acceleration_structure) | per batch, an AABB bottom level per record kind over the capacity and one top level ([`MapAccel`]) | nothing |
/// | [`gather`](Tracer::gather) | per batch, ray generation per query record, one point query through the AABB hit group (GLSL intersection: exact test; any-hit: contribution, ignore) ([`GatherPass`]) | nothing |
/// | [`accumulate`](Tracer::accumulate) | compensated running sum of every plane ([`DeviceAccumulator`]), left out when the iteration's status word says its photon pass dropped records | the iteration's one wait: the batches' counters (96 bytes each), the gather's counts (16 bytes) and every submission's two timestamps |
///
/// A stage submits and returns ([`VkContext::submit`]); queue order runs its work before
/// the next stage's, and what its submissions use lives with them until a wait retires
/// them. [`Tracer::read_stats`], [`Tracer::read_footprints`] and [`Tracer::read_photons`]
/// read the counts they need themselves (a wait) before the accumulate. The stage times of
/// [`IterationStats::times`] are therefore the host's encoding and submission time plus
/// the waits above (the accumulate's covers the device work of every stage), and
/// [`IterationStats::device_times`] the device's own, from a timestamp before and after
/// every submission, summed per stage once the accumulate's wait has retired them all
/// ([`crate::timing`]; where the queue family has no timestamps, they are
/// [`arpa_core::render::tracer::DeviceTimes::Unavailable`]).
///
/// # Photon records, capacities and batches
/// The store, the sort and the structures run over the append buffers' capacities, so that
/// nothing waits for a count: the slots past the records are padding and inactive boxes
/// ([`crate::map_accel`]). The capacities are calibrated at upload from iteration 0
/// ([`arpa_core::gpu::batch::calibrated_capacity`]) and every iteration starts on them.
/// When an iteration's photon pass drops appends (the schedule kernel sets the status
/// word), its accumulate leaves the sums alone, finds the overflow at its wait and traces
/// the iteration again with one wait per batch: the buffers grow and the photons are traced
/// again with the same random streams, so the iteration is unbiased; it is then built,
/// gathered and accumulated (those stages' device times are the second trace's; the dropped
/// appends are counted in [`IterationStats::overflowed`]). An iteration whose records
/// exceed one storage binding of the adapter (`maxStorageBufferRange`; lavapipe: 128 MiB,
/// ~1.4 M raw footprints) is traced in photon batches, with the core's policy
/// ([`arpa_core::gpu::batch`]) as the wgpu backend: batch `k` is the global photons
/// `[k·B, (k+1)·B)`, stored and sorted into maps of its own ([`MapStore`]) with a structure
/// of its own; the gather adds each batch's irradiance per pixel in batch order. When a batch
/// does not fit, B shrinks and the photon pass starts the iteration again; B then stays for
/// the render. B and the capacities are part of the determinism key (another B sums the
/// same contributions in another `f32` order, other capacities give the structures, whose
/// traversal orders the gather's sums, another shape); both are functions of the render,
/// so a checkpoint resumed at any iteration gives the same image.
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
/// [`VkTracerError::Size`].
///
/// # Determinism
/// Each photon's and pixel's random stream depends only on `(seed, iteration, index)`; the
/// stored records are sorted by `(map, Morton code, photon key)`, so the maps, their
/// structures and the gather's traversal order (which orders its sum, see
/// [`crate::gather`]) do not depend on the order of the atomic appends. Images are
/// bit-identical for the same scene, settings and seed on the same adapter and driver.
pub struct VkTracer {
    state: Option<Box<Loaded>>,
    ctx: VkContext,
    pipelines: Arc<Mutex<Option<Arc<PassPipelines>>>>,
    initial_capacity: Option<u32>,
    batch_photons: Option<u32>,
}

/// Every pipeline of the passes. None depends on the scene or the settings, so they are
/// made once per context: on lavapipe a pipeline is compiled at its first trace or dispatch
/// (seconds for the camera and photon passes), and Mesa's shader cache does not spare a
/// second pipeline object in the same process that work.
struct PassPipelines {
    camera: Arc<RtPipeline>,
    photon: Arc<RtPipeline>,
    gather: Arc<RtPipeline>,
    store: Arc<StorePipelines>,
    accumulate: Arc<ComputePipeline>,
}

impl PassPipelines {
    fn new(ctx: &VkContext) -> Result<Self, VkError> {
        Ok(Self {
            camera: Arc::new(camera_pipeline(ctx)?),
            photon: Arc::new(photon_pipeline(ctx)?),
            gather: Arc::new(gather_pipeline(ctx)?),
            store: Arc::new(StorePipelines::new(ctx)?),
            accumulate: Arc::new(accumulate_pipeline(ctx)?),
        })
    }
}

/// One photon batch's maps: sorted records and boxes and their structure.
struct Batch {
    /// Dropped before the buffers it refers to.
    accel: Option<MapAccel>,
    store: MapStore,
}

/// Bytes of one batch's counters in [`Loaded::batch_counts`] ([`BatchCounts`]).
const BATCH_COUNTS_BYTES: u64 = size_of::<BatchCounts>() as u64;

struct Loaded {
    /// The iteration's photon batches (the first `batch_count` are current).
    batches: Vec<Batch>,
    batch_count: usize,
    /// Photons per batch (B).
    batch_photons: u32,
    pipelines: Arc<PassPipelines>,
    prepared: PreparedScene,
    settings: RenderSettings,
    camera: CameraPass,
    photon: PhotonPass,
    outputs: PhotonOutputs,
    radii: [f32; 2],
    gather: GatherPass,
    accumulator: DeviceAccumulator,
    scene: VkScene,
    width: u32,
    height: u32,
    pixels: u32,
    queries: Buffer,
    image: Buffer,
    limits: RecordLimits,
    /// Device time per stage of the iteration in progress.
    ledger: Arc<StageLedger>,
    /// A gather ran and its counts are not in the stats yet (accumulate's wait reads them).
    gather_counts_pending: bool,
    /// The calibrated capacities: every iteration starts on them ([`arpa_core::gpu::batch`]).
    capacities: Capacities,
    /// The capacities of the append buffers allocated now (each batch's store follows them).
    allocated: Capacities,
    /// The iteration's status word ([`crate::accumulate::STATUS_BYTES`]): set on the device
    /// when a photon pass dropped appends; the accumulation then leaves the sums alone.
    status: Buffer,
    /// Per batch of the iteration, its counters ([`BATCH_COUNTS_BYTES`] each; host-visible,
    /// written by each batch's submission).
    batch_counts: Buffer,
    /// A photon pass ran without waiting and its counters have not been read (accumulate's
    /// wait reads them).
    photon_counts_pending: bool,
    /// The last photon batch's submission (the photon pass reads the emitter tables the
    /// next one rewrites from the host).
    photon_submission: Option<crate::submission::Submission>,
    clock: StageClock,
}

impl VkTracer {
    /// A tracer on the adapter `choice` selects ([`AdapterChoice::Auto`]: a GPU with
    /// ray-tracing pipelines, else lavapipe), without validation layers. Tracers made this
    /// way in one process share one context per adapter choice, and with it the pipeline
    /// cache: on lavapipe compiling the passes' pipelines costs seconds, which a second
    /// tracer (the next render of a sweep, the next conformance case) then skips. The
    /// context lives until the process ends.
    pub fn new(choice: &AdapterChoice) -> Result<Self, VkTracerError> {
        let (ctx, pipelines) = shared_context(choice)?;
        Ok(Self { state: None, ctx, pipelines, initial_capacity: None, batch_photons: None })
    }

    /// A tracer on an open context (e.g. one with validation, for tests); its pipelines are
    /// made at the first [`Tracer::upload_scene`] and kept for the next renders.
    pub fn with_context(ctx: VkContext) -> Self {
        Self { state: None, ctx, pipelines: Arc::default(), initial_capacity: None, batch_photons: None }
    }

    /// The passes' pipelines, made on first use.
    fn pass_pipelines(&self) -> Result<Arc<PassPipelines>, VkError> {
        let mut slot = self.pipelines.lock().unwrap_or_else(|e| e.into_inner());
        if let Some(p) = slot.as_ref() {
            return Ok(Arc::clone(p));
        }
        let p = Arc::new(PassPipelines::new(&self.ctx)?);
        *slot = Some(Arc::clone(&p));
        Ok(p)
    }

    /// Records each photon buffer holds after the next [`Tracer::upload_scene`] (`None`:
    /// [`arpa_core::gpu::batch::INITIAL_RECORDS_PER_PHOTON`] per photon). The buffers grow
    /// when an iteration overflows them; a small value exercises that path.
    pub fn set_initial_capacity(&mut self, records: Option<u32>) {
        self.initial_capacity = records;
    }

    /// Forces the photons per batch (B, at least 1) of the renders uploaded after this call
    /// (`None`: automatic, see [`VkTracer`]'s *Photon records and batches*). A test hook: a
    /// small B splits an iteration into many batches. The image depends on B at `f32`
    /// rounding level.
    pub fn set_batch_photons(&mut self, photons: Option<u32>) {
        self.batch_photons = photons.map(|b| b.max(1));
    }

    /// Photons per batch (B) the next iteration starts with (`None` before
    /// [`Tracer::upload_scene`]).
    pub fn batch_photons(&self) -> Option<u32> {
        self.state.as_ref().map(|s| s.batch_photons)
    }

    /// The context.
    pub fn context(&self) -> &VkContext {
        &self.ctx
    }

    fn loaded(&self, call: impl Into<Call>) -> Result<&Loaded, StageError> {
        uploaded(self.state.as_deref(), call)
    }

    /// The counters of the batches the maps hold (a wait); an error when the last photon
    /// pass dropped records (its accumulate traces the iteration again).
    fn kept_counts(&self, st: &Loaded) -> Result<Vec<BatchCounts>, VkTracerError> {
        self.ctx.finish()?;
        let counts = read_batch_counts(st)?;
        if BatchCounts::dropped_in(&counts) > 0 {
            return Err(self.size_error("the last photon pass dropped records for lack of buffer space; its accumulate traces the iteration again with larger buffers".into()));
        }
        Ok(counts)
    }

    fn size_error(&self, message: String) -> VkTracerError {
        VkTracerError::Size { adapter: self.ctx.info().name.clone(), message }
    }

    /// The sums read back as the core's accumulation (every plane, exactly).
    fn accumulation(&self, st: &Loaded) -> Result<Accumulation, VkTracerError> {
        let pixels = st.accumulator.read_pixels(&self.ctx)?.iter().map(AccumPixel::to_sum).collect();
        Ok(Accumulation {
            width: st.width,
            height: st.height,
            planes: st.settings.bandwidth.planes() as u32,
            first_iteration: st.clock.first_iteration(),
            iterations: st.clock.accumulated(),
            pixels,
        })
    }
}

/// Runs `stage` on `clock` ([`StageClock::run`]) with the submissions this thread makes
/// meanwhile timed into `stage` of `ledger` ([`StageScope`]); their device time arrives
/// when a later wait retires them, and [`Tracer::accumulate`] copies the iteration's into
/// the stats.
fn timed<E: From<StageError>>(ledger: &Arc<StageLedger>, clock: &mut StageClock, stage: Stage, body: impl FnOnce(&mut StageClock) -> Result<(), E>) -> Result<(), E> {
    let _scope = StageScope::enter(ledger, stage, clock.completed());
    clock.run(stage, body)
}

/// Writes the gather's counts (summed over the photon batches) into `stats`.
fn set_gather_counts(stats: &mut IterationStats, counts: &crate::gather::GatherCounts) {
    stats.contributions = counts.contributions;
    stats.candidates = counts.candidates;
    stats.covered = counts.covered;
    stats.query_points = counts.query_points;
}

/// The pipelines of a context, once made.
type PipelineSlot = Arc<Mutex<Option<Arc<PassPipelines>>>>;

/// The process's context for `choice` and its pipeline slot (see [`VkTracer::new`]).
fn shared_context(choice: &AdapterChoice) -> Result<(VkContext, PipelineSlot), VkError> {
    static CONTEXTS: Mutex<Vec<(AdapterChoice, VkContext, PipelineSlot)>> = Mutex::new(Vec::new());
    let mut contexts = CONTEXTS.lock().unwrap_or_else(|e| e.into_inner());
    if let Some((_, ctx, slot)) = contexts.iter().find(|(c, _, _)| c == choice) {
        return Ok((ctx.clone(), Arc::clone(slot)));
    }
    let ctx = VkContext::new(choice, &ContextOptions::default())?;
    let slot = PipelineSlot::default();
    contexts.push((choice.clone(), ctx.clone(), Arc::clone(&slot)));
    Ok((ctx, slot))
}

/// `maxStorageBufferRange` of the context's adapter (bytes).
fn binding_bytes(ctx: &VkContext) -> u64 {
    // SAFETY: a physical device of this instance.
    let props = unsafe { ctx.instance().get_physical_device_properties(ctx.physical_device()) };
    u64::from(props.limits.max_storage_buffer_range)
}

/// A host-visible buffer for the counters of `batches` batches.
fn batch_counts_buffer(ctx: &VkContext, batches: usize) -> Result<Buffer, VkError> {
    ctx.create_buffer("batch counters", batches.max(1) as u64 * BATCH_COUNTS_BYTES, vk::BufferUsageFlags::TRANSFER_DST, MemoryLocation::GpuToCpu)
}

/// Reallocates the photon pass's append buffers for `capacities`; each batch's store
/// follows them when it is next used.
fn resize(ctx: &VkContext, st: &mut Loaded, capacities: Capacities) -> Result<(), VkError> {
    // Free the old buffers before allocating the new ones.
    st.outputs = PhotonOutputs::new(ctx, 1, 1)?;
    st.outputs = PhotonOutputs::new(ctx, capacities.raw_footprints, capacities.photons)?;
    st.photon.bind(&st.scene, &st.outputs)?;
    st.allocated = capacities;
    Ok(())
}

/// Starts an iteration's photon pass of `batches` batches: room for their counters, the
/// iteration's emitter tables (nothing of the pass may be in flight).
fn begin_iteration(ctx: &VkContext, st: &mut Loaded, setup: &PhotonPassSetup, batches: usize) -> Result<(), VkError> {
    // The previous iteration's structures refer to the buffers the stores rewrite.
    for b in &mut st.batches {
        b.accel = None;
    }
    // The emitter tables are host-visible: a photon pass run again before an accumulate
    // waits for the earlier one's batches (free once a wait has retired them).
    if let Some(last) = st.photon_submission.take() {
        ctx.wait_for(last)?;
    }
    if st.batch_counts.size() < batches as u64 * BATCH_COUNTS_BYTES {
        st.batch_counts = batch_counts_buffer(ctx, batches)?;
    }
    st.photon.prepare_iteration(setup)
}

/// Records and submits batch `k` of the iteration `setup` (its photons `range`): the photon
/// pass, the batch's whole store ([`MapStore::record_batch`]) and the copy of both counters
/// into [`Loaded::batch_counts`], in one submission that waits for nothing; it first clears
/// the iteration's status word when `clear_status`.
fn submit_batch(ctx: &VkContext, st: &mut Loaded, setup: &PhotonPassSetup, settings: &StoreSettings, range: Range<u32>, k: usize, clear_status: bool) -> Result<(), VkError> {
    let caps = st.allocated;
    if st.batches.get(k).is_none_or(|b| b.store.capacities() != caps) {
        // Free this batch's old buffers first.
        st.batches.truncate(k);
        let store = MapStore::new(ctx, &st.pipelines.store, caps)?;
        st.batches.push(Batch { accel: None, store });
    }
    let store = &st.batches[k].store;
    let outputs = &st.outputs;
    let prepared = store.prepare_batch(ctx, outputs.footprints(), outputs.photons(), outputs.counters(), &st.status, settings)?;
    let (photon, status, counts) = (&st.photon, &st.status, &st.batch_counts);
    let device = ctx.device();
    let at = k as u64 * BATCH_COUNTS_BYTES;
    let (recorded, submission) = ctx.submit(vec![Box::new(Arc::clone(&prepared))], |cmd| {
        if clear_status {
            crate::compute::record_fill(device, cmd, status, 0);
        }
        photon.record_batch(ctx, cmd, setup, range, outputs)?;
        store.record_batch(device, cmd, &prepared)?;
        let photon_bytes = size_of::<PhotonCounters>() as u64;
        // SAFETY: live buffers with the transfer usages and room for the regions; the store
        // ended with a barrier to transfers, and the copies are followed by one to the host.
        unsafe {
            device.cmd_copy_buffer(cmd, outputs.counters().raw(), counts.raw(), &[vk::BufferCopy { src_offset: 0, dst_offset: at, size: photon_bytes }]);
            device.cmd_copy_buffer(cmd, store.counts().raw(), counts.raw(), &[vk::BufferCopy { src_offset: 0, dst_offset: at + photon_bytes, size: size_of::<StoreCounts>() as u64 }]);
        }
        crate::compute::record_compute_barrier(device, cmd);
        Ok::<(), VkError>(())
    })?;
    st.photon_submission = Some(submission);
    recorded
}

/// The photon pass without a wait: every batch of the iteration `setup` is traced and
/// stored over the calibrated capacities; the counters are read at the accumulate's wait (or
/// by a read of the stats or the records).
fn trace_pipelined(ctx: &VkContext, st: &mut Loaded, setup: &PhotonPassSetup) -> Result<(), VkError> {
    let n = setup.photon_count();
    let b = st.batch_photons;
    let batches = batch_count(n, b) as usize;
    begin_iteration(ctx, st, setup, batches)?;
    let settings = StoreSettings::for_iteration(setup, &st.prepared);
    for k in 0..batches {
        submit_batch(ctx, st, setup, &settings, batch_range(n, b, k as u32), k, k == 0)?;
    }
    st.batch_count = batches;
    st.photon_counts_pending = true;
    Ok(())
}

/// The photon pass with one wait per batch (the calibration, or an iteration traced again
/// after an overflow), with the core's policy ([`arpa_core::gpu::batch::trace_waiting`]).
/// Returns the most raw footprints, progressive photons and photon sort items a batch
/// appended.
fn trace_waiting(ctx: &VkContext, adapter: &str, st: &mut Loaded, stats: &mut IterationStats, setup: &PhotonPassSetup) -> Result<[u32; 3], VkTracerError> {
    let (limits, mut batch_photons) = (st.limits, st.batch_photons);
    let settings = StoreSettings::for_iteration(setup, &st.prepared);
    let mut w = Waiting { ctx, adapter, st, setup, settings };
    let (batches, most) = batch::trace_waiting(&mut w, setup.photon_count(), &mut batch_photons, &limits, stats)?;
    st.batch_photons = batch_photons;
    st.batch_count = batches as usize;
    st.photon_counts_pending = false;
    Ok(most)
}

/// The tracer's batches traced with one wait each ([`trace_waiting`]).
struct Waiting<'a> {
    ctx: &'a VkContext,
    adapter: &'a str,
    st: &'a mut Loaded,
    setup: &'a PhotonPassSetup,
    settings: StoreSettings,
}

impl WaitingBatches for Waiting<'_> {
    type Error = VkTracerError;

    fn begin(&mut self, batches: u32) -> Result<(), VkTracerError> {
        Ok(begin_iteration(self.ctx, self.st, self.setup, batches as usize)?)
    }

    fn trace(&mut self, range: Range<u32>, k: u32, _last: bool) -> Result<BatchCounts, VkTracerError> {
        // Every earlier batch fitted: the status word only tells of this one.
        submit_batch(self.ctx, self.st, self.setup, &self.settings, range, k as usize, true)?;
        self.ctx.finish()?;
        Ok(bytemuck::pod_read_unaligned(&self.st.batch_counts.read(u64::from(k) * BATCH_COUNTS_BYTES, BATCH_COUNTS_BYTES)?))
    }

    fn resize(&mut self, capacities: Capacities) -> Result<(), VkTracerError> {
        Ok(resize(self.ctx, self.st, capacities)?)
    }

    fn allocated(&self) -> Capacities {
        self.st.allocated
    }

    fn too_large(&self, batch: &BatchCounts, limits: &RecordLimits) -> VkTracerError {
        let (c, s) = (&batch.photon, &batch.store);
        VkTracerError::Size {
            adapter: self.adapter.to_string(),
            message: format!(
                "one photon stores {} raw footprints, {} progressive photons and {} sorted progressive photons; one binding holds {}, {} and {}",
                c.footprint_appends, c.photon_appends, s.photon_items, limits.raw_footprints, limits.photons, limits.sorted_photons
            ),
        }
    }
}

/// The counters of the iteration's batches (after a wait).
fn read_batch_counts(st: &Loaded) -> Result<Vec<BatchCounts>, VkError> {
    Ok(crate::buffer::pod_vec(&st.batch_counts.read(0, st.batch_count as u64 * BATCH_COUNTS_BYTES)?))
}

/// Builds every batch's structure over its store's capacities (not waited for).
fn build_batches(ctx: &VkContext, st: &mut Loaded) -> Result<(), VkError> {
    for b in &mut st.batches[..st.batch_count] {
        b.accel = None;
        let (fp, ph) = (b.store.capacities().raw_footprints, b.store.photons_out_capacity());
        b.accel = Some(MapAccel::build(ctx, b.store.footprint_boxes(), fp, b.store.photon_boxes(), ph)?);
    }
    Ok(())
}

/// Gathers every batch (not waited for; its counts come back in the accumulate's wait).
fn gather_batches(ctx: &VkContext, st: &mut Loaded) -> Result<(), VkTracerError> {
    let batches = st.batch_count;
    for (k, b) in st.batches[..batches].iter().enumerate() {
        let accel = b.accel.as_ref().ok_or_else(|| StageError::order(Stage::Gather, Stage::BuildAccelerationStructure))?;
        let inputs = GatherInputs { footprints: b.store.footprints(), photons: b.store.photons(), tlas: accel.tlas(), radii: st.radii };
        let batch = GatherBatch { first: k == 0, last: k + 1 == batches };
        st.gather.run(ctx, &st.queries, &st.image, &inputs, batch)?;
    }
    st.gather_counts_pending = true;
    Ok(())
}

/// Accumulates the iteration image (left out on the device when the status word says the
/// photon pass dropped records) and waits for the iteration; reads the gather's counts and
/// returns the batches' counters when a pipelined photon pass left them unread.
fn accumulate_and_wait(ctx: &VkContext, st: &mut Loaded, stats: &mut IterationStats) -> Result<Option<Vec<BatchCounts>>, VkError> {
    st.accumulator.accumulate_and_wait(ctx, &st.image, Some(&st.status))?;
    if st.gather_counts_pending {
        set_gather_counts(stats, &st.gather.read_counts()?);
        st.gather_counts_pending = false;
    }
    if !std::mem::take(&mut st.photon_counts_pending) {
        return Ok(None);
    }
    read_batch_counts(st).map(Some)
}

impl Tracer for VkTracer {
    type Error = VkTracerError;

    fn capabilities(&self) -> Capabilities {
        let i = self.ctx.info();
        // Batches lift the buffer limits; the record keys bound photons · max_depth, which
        // upload_scene checks with the settings.
        Capabilities::new(BackendKind::Vk, format!("{} ({}, {} {})", i.name, i.device_type, i.driver_name, i.driver_info))
    }

    fn upload_scene(&mut self, scene: &Scene, settings: &RenderSettings) -> Result<(), VkTracerError> {
        self.state = None;
        let prepared = prepare_upload(scene, settings)?;
        check_record_keys(settings, BackendKind::Vk)?;
        let ctx = &self.ctx;
        let (width, height) = (scene.camera.width, scene.camera.height);
        let binding = binding_bytes(ctx);
        let limits = RecordLimits::new(binding);
        let pixels = u32::try_from(u64::from(width) * u64::from(height))
            .ok()
            .filter(|&p| u64::from(p) * QUERY_RECORD_BYTES <= binding && p <= ctx.ray_tracing().max_ray_dispatch_invocation_count);
        let Some(pixels) = pixels else {
            return Err(self.size_error(format!("an image of {width}×{height} pixels exceeds one storage binding or one ray launch")));
        };
        // Every plane of the image, the batch irradiance and the sums in one binding each.
        let sizes = ImageBufferSizes::new(pixels, settings.bandwidth);
        sizes.check(width, height, settings.bandwidth, binding).map_err(|m| self.size_error(m))?;
        let entries = u32::try_from(settings.bandwidth.planes() as u64 * u64::from(pixels)).map_err(|_| self.size_error(format!("an image of {width}×{height} pixels has too many planes")))?;
        let pipelines = self.pass_pipelines()?;
        let vk_scene = VkScene::upload(ctx, &prepared)?;
        let storage = vk::BufferUsageFlags::STORAGE_BUFFER | vk::BufferUsageFlags::TRANSFER_SRC;
        let queries = ctx.create_buffer("query records", (u64::from(pixels) * QUERY_RECORD_BYTES).max(QUERY_RECORD_BYTES), storage, MemoryLocation::GpuOnly)?;
        let image = ctx.create_buffer("iteration image", sizes.image.max(16), storage, MemoryLocation::GpuOnly)?;
        let camera = CameraPass::new(ctx, &pipelines.camera, &vk_scene, CameraParams::new(&scene.camera, settings, width)?, &queries)?;
        let mut photon = PhotonPass::new(ctx, &pipelines.photon, &prepared, settings)?;
        let batch_photons = self.batch_photons.unwrap_or(settings.photons_per_iteration).min(settings.photons_per_iteration);
        let initial = Capacities::initial(batch_photons, self.initial_capacity, &limits);
        let outputs = PhotonOutputs::new(ctx, initial.raw_footprints, initial.photons)?;
        photon.bind(&vk_scene, &outputs)?;
        let gather = GatherPass::new(ctx, &pipelines.gather, settings.kernel, settings.bandwidth, pixels)?;
        let accumulator = DeviceAccumulator::new(ctx, &pipelines.accumulate, entries)?;
        let status = ctx.create_buffer("iteration status", crate::accumulate::STATUS_BYTES, vk::BufferUsageFlags::STORAGE_BUFFER | vk::BufferUsageFlags::TRANSFER_DST, MemoryLocation::GpuOnly)?;
        let mut st = Box::new(Loaded {
            batches: Vec::new(),
            batch_count: 0,
            batch_photons,
            pipelines,
            prepared,
            settings: *settings,
            camera,
            photon,
            outputs,
            radii: [0.0; 2],
            gather,
            accumulator,
            scene: vk_scene,
            width,
            height,
            pixels,
            queries,
            image,
            limits,
            ledger: Arc::default(),
            gather_counts_pending: false,
            capacities: initial,
            allocated: initial,
            status,
            batch_counts: batch_counts_buffer(ctx, 1)?,
            photon_counts_pending: false,
            photon_submission: None,
            clock: StageClock::new(),
        });
        if self.initial_capacity.is_none() {
            // The calibration: iteration 0's photon pass, waited for batch by batch, sets
            // the capacities every iteration of the render starts on (and B).
            let setup = PhotonPassSetup::new(&st.prepared, &st.settings, 0);
            let mut stats = IterationStats::default();
            let adapter = ctx.info().name.clone();
            let [fp, ph, items] = trace_waiting(ctx, &adapter, &mut st, &mut stats, &setup)?;
            st.capacities = Capacities::calibrated(fp, ph, items, &limits);
            st.batch_count = 0;
            // The first iteration finds its append buffers allocated.
            let calibrated = st.capacities;
            resize(ctx, &mut st, calibrated)?;
        }
        self.state = Some(st);
        Ok(())
    }

    fn camera_pass(&mut self) -> Result<(), VkTracerError> {
        let st = uploaded(self.state.as_deref_mut(), Stage::CameraPass)?;
        timed(&st.ledger, &mut st.clock, Stage::CameraPass, |clock| Ok(st.camera.run(&self.ctx, clock.completed())?))
    }

    fn photon_pass(&mut self) -> Result<(), VkTracerError> {
        let ctx = &self.ctx;
        let st = uploaded(self.state.as_deref_mut(), Stage::PhotonPass)?;
        // The batches read and write the whole state; the clock steps out of it meanwhile.
        let mut clock = std::mem::take(&mut st.clock);
        let ledger = Arc::clone(&st.ledger);
        let result = timed(&ledger, &mut clock, Stage::PhotonPass, |clock| {
            let setup = PhotonPassSetup::new(&st.prepared, &st.settings, clock.completed());
            let stats = clock.stats_mut();
            stats.overflowed = 0;
            stats.reset_photon_counts();
            if st.allocated != st.capacities {
                // The calibration or an iteration traced again left other buffers: every
                // iteration starts on the calibrated ones.
                resize(ctx, st, st.capacities)?;
            }
            trace_pipelined(ctx, st, &setup)?;
            st.radii = setup.radii.map(|r| r as f32);
            stats.radii = setup.radii;
            setup.record_plan(stats);
            Ok(())
        });
        st.clock = clock;
        result
    }

    fn build_acceleration_structure(&mut self) -> Result<(), VkTracerError> {
        let st = uploaded(self.state.as_deref_mut(), Stage::BuildAccelerationStructure)?;
        let ctx = &self.ctx;
        let mut clock = std::mem::take(&mut st.clock);
        let ledger = Arc::clone(&st.ledger);
        let result = timed(&ledger, &mut clock, Stage::BuildAccelerationStructure, |_| Ok::<(), VkTracerError>(build_batches(ctx, st)?));
        st.clock = clock;
        result
    }

    fn gather(&mut self) -> Result<(), VkTracerError> {
        let st = uploaded(self.state.as_deref_mut(), Stage::Gather)?;
        let ctx = &self.ctx;
        let mut clock = std::mem::take(&mut st.clock);
        let ledger = Arc::clone(&st.ledger);
        let result = timed(&ledger, &mut clock, Stage::Gather, |_| gather_batches(ctx, st));
        st.clock = clock;
        result
    }

    /// The iteration's one wait ([`VkTracer`]'s table). When it finds that the photon pass
    /// dropped records (the accumulation was then left out on the device), the iteration is
    /// traced again here with grown buffers and one wait per batch, built, gathered and
    /// accumulated; those stages' device times are the second trace's.
    fn accumulate(&mut self) -> Result<(), VkTracerError> {
        let adapter = self.ctx.info().name.clone();
        let ctx = &self.ctx;
        let st = uploaded(self.state.as_deref_mut(), Stage::Accumulate)?;
        let mut clock = std::mem::take(&mut st.clock);
        let ledger = Arc::clone(&st.ledger);
        let result = timed(&ledger, &mut clock, Stage::Accumulate, |clock| {
            let iteration = clock.completed();
            let stats = clock.stats_mut();
            if let Some(counts) = accumulate_and_wait(ctx, st, stats)? {
                let lost = BatchCounts::dropped_in(&counts);
                if lost > 0 {
                    let setup = PhotonPassSetup::new(&st.prepared, &st.settings, iteration);
                    {
                        let _scope = StageScope::enter(&ledger, Stage::PhotonPass, iteration);
                        trace_waiting(ctx, &adapter, st, stats, &setup)?;
                    }
                    stats.overflowed += lost;
                    setup.record_plan(stats);
                    {
                        let _scope = StageScope::enter(&ledger, Stage::BuildAccelerationStructure, iteration);
                        build_batches(ctx, st)?;
                    }
                    {
                        let _scope = StageScope::enter(&ledger, Stage::Gather, iteration);
                        gather_batches(ctx, st)?;
                    }
                    accumulate_and_wait(ctx, st, stats)?;
                } else {
                    stats.add_photon_batches(&counts);
                }
            }
            // The structures are not read again this iteration; dropped now, while nothing is
            // in flight, they cost the next iteration no wait.
            for b in &mut st.batches {
                b.accel = None;
            }
            Ok::<(), VkTracerError>(())
        });
        st.clock = clock;
        result?;
        // The accumulation's own submission has retired too.
        st.clock.stats_mut().device_times = st.ledger.times();
        Ok(())
    }

    fn iterations(&self) -> u32 {
        self.state.as_ref().map_or(0, |s| s.clock.completed())
    }

    /// Every plane's sums ([`Accumulation::planes`] = the bandwidth's planes), exactly.
    fn read_accumulation(&self) -> Result<Accumulation, VkTracerError> {
        let st = self.loaded(Call::ReadAccumulation)?;
        self.accumulation(st)
    }

    /// Continues `state`: sums of the bandwidth's planes, or an empty accumulation (which
    /// takes them, [`Accumulation::with_planes`]).
    fn restore_accumulation(&mut self, state: &Accumulation) -> Result<(), VkTracerError> {
        let st = uploaded(self.state.as_deref_mut(), Call::RestoreAccumulation)?;
        let state = state.with_planes(st.settings.bandwidth.planes() as u32).map_err(|e| StageError::Accumulation(e.to_string()))?;
        let clock = StageClock::for_restore(&state, st.width, st.height)?;
        let pixels = AccumPixel::from_accumulation(&state)?;
        st.accumulator.write_pixels(&self.ctx, &pixels)?;
        st.clock = clock;
        Ok(())
    }

    /// The core's [`Accumulation::mean`] of the sums read back: every pixel's mean with a
    /// global bandwidth, the per-pixel selection over the planes otherwise.
    fn read_image(&self) -> Result<Image, VkTracerError> {
        let st = self.loaded(Call::ReadImage)?;
        Ok(Image { width: st.width, height: st.height, pixels: self.accumulation(st)?.mean() })
    }

    fn read_query_points(&self) -> Result<Vec<QueryRecord>, VkTracerError> {
        let st = self.loaded(Call::ReadQueryPoints)?;
        st.clock.require_output(Call::ReadQueryPoints, Stage::CameraPass)?;
        Ok(crate::buffer::pod_vec(&self.ctx.read_back(&st.queries, 0, u64::from(st.pixels) * QUERY_RECORD_BYTES)?))
    }

    /// The last photon pass's footprints, batch after batch, each batch sorted by map
    /// (caustic first), then by Morton code and key.
    fn read_footprints(&self) -> Result<Vec<PackedFootprint>, VkTracerError> {
        let st = self.loaded(Call::ReadFootprints)?;
        st.clock.require_output(Call::ReadFootprints, Stage::PhotonPass)?;
        let mut all = Vec::new();
        for (b, c) in st.batches[..st.batch_count].iter().zip(self.kept_counts(st)?) {
            all.extend(b.store.read_footprints(&self.ctx, &c.store)?);
        }
        Ok(all)
    }

    /// The last photon pass's progressive photons, batch after batch, sorted as the
    /// footprints.
    fn read_photons(&self) -> Result<Vec<PackedPhoton>, VkTracerError> {
        let st = self.loaded(Call::ReadPhotons)?;
        st.clock.require_output(Call::ReadPhotons, Stage::PhotonPass)?;
        let mut all = Vec::new();
        for (b, c) in st.batches[..st.batch_count].iter().zip(self.kept_counts(st)?) {
            all.extend(b.store.read_photons(&self.ctx, &c.store)?);
        }
        Ok(all)
    }

    /// The stats; after a gather whose accumulate has not run yet, its counts are read here
    /// (a wait), since the gather itself does not wait for them.
    fn read_stats(&self) -> Result<IterationStats, VkTracerError> {
        let st = self.loaded(Call::ReadStats)?;
        let mut stats = *st.clock.stats();
        if st.photon_counts_pending {
            self.ctx.finish()?;
            let counts = read_batch_counts(st)?;
            stats.add_photon_batches(&counts);
        }
        if st.gather_counts_pending {
            self.ctx.finish()?;
            set_gather_counts(&mut stats, &st.gather.read_counts()?);
        }
        Ok(stats)
    }
}
