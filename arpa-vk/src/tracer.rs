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
use arpa_core::gpu::batch::{Overflow, RecordLimits, after_overflow, for_each_batch, initial_capacity, shrink};
use arpa_core::{gpu::layout::{CameraParams, GatherBatch, ImageBufferSizes, StoreCounts, StoreSettings}, gpu::fill::check_record_keys};
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
/// | [`upload_scene`](Tracer::upload_scene) | validates scene and settings, builds the triangle structures, uploads the scene tables, compiles the pipelines | the uploads |
/// | [`camera_pass`](Tracer::camera_pass) | ray generation per pixel, closest-hit and miss over the triangles ([`CameraPass`]) | nothing |
/// | [`photon_pass`](Tracer::photon_pass) | per photon batch, in one submission: ray generation per photon appending keyed footprints and photons ([`PhotonPass`]), then the keyed store with its record counts and dispatch sizes from the pass's counters on the device (`schedule.wgsl`); then, in a second submission, sort and compaction into the batch's sorted maps and boxes ([`MapStore`]) | per batch, one wait for the first submission: the photon counters (48 bytes: overflow) and the store counts (48 bytes: the sort's schedule and the build's sizes) |
/// | [`build_acceleration_structure`](Tracer::build_acceleration_structure) | per batch, AABB bottom levels per (kind, map) over the sorted boxes and one top level ([`MapAccel`]) | nothing |
/// | [`gather`](Tracer::gather) | per batch, ray generation per query record, one point query through the AABB hit group (GLSL intersection: exact test; any-hit: contribution, ignore) ([`GatherPass`]) | nothing |
/// | [`accumulate`](Tracer::accumulate) | compensated running sum of every plane ([`DeviceAccumulator`]) | one wait for the iteration's work: the gather's counts (16 bytes) and every submission's two timestamps |
///
/// A stage that reads nothing back submits and returns ([`VkContext::submit`]); queue
/// order runs its work before the next stage's, and what its submissions use lives with
/// them until a wait retires them. [`Tracer::read_stats`] reads the gather's counts itself
/// (a wait) between a gather and its accumulate. The stage times of
/// [`IterationStats::times`] are therefore the host's encoding and submission time plus
/// the waits above (a wait also covers the device work submitted before it), and
/// [`IterationStats::device_times`] the device's own, from a timestamp before and after
/// every submission, summed per stage once the accumulate's wait has retired them all
/// ([`crate::timing`]; where the queue family has no timestamps, they are
/// [`arpa_core::render::tracer::DeviceTimes::Unavailable`]). The photon pass's wait
/// stays because the sort's passes are sized from the counts on the host and because
/// Vulkan's indirect build takes primitive counts from device memory but not the sizes of
/// the structures, which must be allocated before the build; the adapter's
/// `accelerationStructureIndirectBuild` is reported in
/// [`crate::DeviceInfo::acceleration_structure_indirect_build`] (lavapipe: off).
///
/// # Photon records and batches
/// The photon pass's buffers start at [`arpa_core::gpu::batch::INITIAL_RECORDS_PER_PHOTON`]
/// records per photon and grow when a pass overflows them (the photons are then traced again
/// with the same random streams, so the iteration is unbiased; the dropped appends are
/// counted in [`IterationStats::overflowed`]). An iteration whose records exceed one storage
/// binding of the adapter (`maxStorageBufferRange`; lavapipe: 128 MiB, ~1.4 M raw
/// footprints) is traced in photon batches, with the core's policy
/// ([`arpa_core::gpu::batch`]) as the wgpu backend: batch `k` is the global photons
/// `[k·B, (k+1)·B)`, stored and sorted into maps of its own ([`MapStore`]) with a structure
/// of its own; the gather adds each batch's irradiance per pixel in batch order. When a batch
/// does not fit, B shrinks and the photon pass starts the iteration again; B then stays for
/// the render. B is part of the determinism key (another B sums the same contributions in
/// another `f32` order).
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

/// One photon batch's maps: sorted records and boxes, their counts and structure.
struct Batch {
    /// Dropped before the buffers it refers to.
    accel: Option<MapAccel>,
    store: MapStore,
    counts: StoreCounts,
}

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

/// Traces the photons `range` of the iteration `setup` (growing the photon buffers and
/// tracing again on overflow), stores, sorts and compacts them into batch `k`'s maps, and
/// adds the batch's counts to the stats. `Some(B)`: the batch needs more than one storage
/// binding holds; the caller traces the iteration again with B photons per batch.
fn trace_batch(ctx: &VkContext, adapter: &str, st: &mut Loaded, clock: &mut StageClock, setup: &PhotonPassSetup, range: Range<u32>, k: usize) -> Result<Option<u32>, VkTracerError> {
    let photons = range.end - range.start;
    let limits = st.limits;
    let size = |message: String| VkTracerError::Size { adapter: adapter.to_string(), message };
    // The store's parameters; its record counts come from the pass's counters on the device.
    let mut settings = StoreSettings::for_iteration(setup, &st.prepared);
    // Trace and store in one submission, then one wait for both counters; on overflow
    // discard the batch's records, grow the buffers and trace the same photons again.
    let (counters, counts) = loop {
        let caps = (st.outputs.footprint_capacity(), st.outputs.photon_capacity());
        if st.batches.get(k).is_none_or(|b| b.store.capacities() != caps) {
            // Free this batch's old buffers first.
            st.batches.truncate(k);
            let store = MapStore::new(ctx, &st.pipelines.store, caps.0, caps.1)?;
            st.batches.push(Batch { accel: None, store, counts: StoreCounts::default() });
        }
        let extent = st.photon.prepare(setup, range.clone(), &mut st.outputs)?;
        let store = &st.batches[k].store;
        let outputs = &st.outputs;
        let scheduled = store.prepare_scheduled(ctx, outputs.footprints(), outputs.photons(), outputs.counters(), &settings)?;
        let photon = &st.photon;
        ctx.submit_and_wait(|cmd| {
            if let Some(extent) = extent {
                photon.record(ctx, cmd, extent)?;
            }
            store.record_scheduled(ctx.device(), cmd, &scheduled)
        })??;
        drop(scheduled);
        let c = outputs.read_counters()?;
        if c.overflowed() == 0 {
            break (c, store.read_counts()?);
        }
        clock.stats_mut().overflowed += c.overflowed();
        let (fp_cap, ph_cap) = match after_overflow(&limits, photons, c.footprint_appends, c.photon_appends, caps) {
            Overflow::Grow(f, p) => (f, p),
            Overflow::Shrink(b) => return Ok(Some(b)),
            Overflow::TooLarge => {
                return Err(size(format!(
                    "one photon stores {} raw footprints and {} progressive photons; one binding holds {} and {}",
                    c.footprint_appends, c.photon_appends, limits.raw_footprints, limits.photons
                )));
            }
        };
        // Free the old buffers before allocating the larger ones.
        st.outputs = PhotonOutputs::new(ctx, 1, 1)?;
        st.outputs = PhotonOutputs::new(ctx, fp_cap, ph_cap)?;
        st.photon.bind(&st.scene, &st.outputs)?;
    };
    // The counts the schedule kernel gave the store.
    settings.raw_count = counters.footprints_written();
    settings.photon_count = counters.photons_written();
    let outputs = &st.outputs;
    let batch = &mut st.batches[k];
    // The sorted progressive photons (the pass's plus the footprints' fallbacks) must fit one
    // binding too.
    if u64::from(counts.photon_items) > u64::from(batch.store.photons_out_capacity()) {
        clock.stats_mut().overflowed += u64::from(counts.photon_items) - u64::from(batch.store.photons_out_capacity());
        if photons <= 1 {
            return Err(size(format!("one photon stores {} progressive photons; one binding holds {}", counts.photon_items, batch.store.photons_out_capacity())));
        }
        return Ok(Some(shrink(photons, f64::from(batch.store.photons_out_capacity()) / f64::from(counts.photon_items))));
    }
    // Not waited for: nothing after it in the photon pass reads what it writes (the
    // compaction cannot overflow, the check above ensures it).
    batch.store.submit_sort(ctx, outputs.footprints(), outputs.photons(), &counts, &settings)?;
    batch.counts = counts;
    clock.stats_mut().add_photon_batch(&counters, &counts);
    Ok(None)
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
        let fp_cap = initial_capacity(batch_photons, self.initial_capacity, limits.raw_footprints);
        let ph_cap = initial_capacity(batch_photons, self.initial_capacity, limits.photons);
        let outputs = PhotonOutputs::new(ctx, fp_cap, ph_cap)?;
        photon.bind(&vk_scene, &outputs)?;
        let gather = GatherPass::new(ctx, &pipelines.gather, settings.kernel, settings.bandwidth, pixels)?;
        let accumulator = DeviceAccumulator::new(ctx, &pipelines.accumulate, entries)?;
        self.state = Some(Box::new(Loaded {
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
            clock: StageClock::new(),
        }));
        Ok(())
    }

    fn camera_pass(&mut self) -> Result<(), VkTracerError> {
        let st = uploaded(self.state.as_deref_mut(), Stage::CameraPass)?;
        timed(&st.ledger, &mut st.clock, Stage::CameraPass, |clock| Ok(st.camera.run(&self.ctx, clock.completed())?))
    }

    fn photon_pass(&mut self) -> Result<(), VkTracerError> {
        let adapter = self.ctx.info().name.clone();
        let ctx = &self.ctx;
        let st = uploaded(self.state.as_deref_mut(), Stage::PhotonPass)?;
        // The batches read and write the whole state; the clock steps out of it meanwhile.
        let mut clock = std::mem::take(&mut st.clock);
        let ledger = Arc::clone(&st.ledger);
        let result = timed(&ledger, &mut clock, Stage::PhotonPass, |clock| {
            // The previous iteration's structures refer to the buffers the store rewrites.
            for b in &mut st.batches {
                b.accel = None;
            }
            let setup = PhotonPassSetup::new(&st.prepared, &st.settings, clock.completed());
            let n = setup.photon_count();
            clock.stats_mut().overflowed = 0;
            // Every batch; a batch too large for one binding shrinks B and starts the
            // iteration again.
            let mut batch_photons = st.batch_photons;
            st.batch_count = for_each_batch(n, &mut batch_photons, |range, k, _| {
                if k == 0 {
                    clock.stats_mut().reset_photon_counts();
                }
                trace_batch(ctx, &adapter, st, clock, &setup, range, k as usize)
            })? as usize;
            st.batch_photons = batch_photons;
            st.radii = setup.radii.map(|r| r as f32);
            clock.stats_mut().radii = setup.radii;
            setup.record_plan(clock.stats_mut());
            Ok(())
        });
        st.clock = clock;
        result
    }

    fn build_acceleration_structure(&mut self) -> Result<(), VkTracerError> {
        let st = uploaded(self.state.as_deref_mut(), Stage::BuildAccelerationStructure)?;
        timed(&st.ledger, &mut st.clock, Stage::BuildAccelerationStructure, |_| {
            for b in &mut st.batches[..st.batch_count] {
                b.accel = None;
                b.accel = Some(MapAccel::build(&self.ctx, b.store.footprint_boxes(), b.store.photon_boxes(), &b.counts)?);
            }
            Ok(())
        })
    }

    fn gather(&mut self) -> Result<(), VkTracerError> {
        let st = uploaded(self.state.as_deref_mut(), Stage::Gather)?;
        timed(&st.ledger, &mut st.clock, Stage::Gather, |_| {
            let batches = st.batch_count;
            for (k, b) in st.batches[..batches].iter().enumerate() {
                let accel = b.accel.as_ref().ok_or_else(|| StageError::order(Stage::Gather, Stage::BuildAccelerationStructure))?;
                let inputs = GatherInputs { footprints: b.store.footprints(), photons: b.store.photons(), tlas: accel.tlas(), radii: st.radii };
                let batch = GatherBatch { first: k == 0, last: k + 1 == batches };
                st.gather.run(&self.ctx, &st.queries, &st.image, &inputs, batch)?;
            }
            // Its counts come back in accumulate's wait (or read_stats's).
            st.gather_counts_pending = true;
            Ok(())
        })
    }

    fn accumulate(&mut self) -> Result<(), VkTracerError> {
        let st = uploaded(self.state.as_deref_mut(), Stage::Accumulate)?;
        timed(&st.ledger, &mut st.clock, Stage::Accumulate, |clock| {
            // The iteration's one wait outside the photon pass: it retires every submission
            // of the iteration (their device times arrive in the ledger).
            st.accumulator.accumulate_and_wait(&self.ctx, &st.image)?;
            if st.gather_counts_pending {
                set_gather_counts(clock.stats_mut(), &st.gather.read_counts()?);
                st.gather_counts_pending = false;
            }
            // The structures are not read again this iteration; dropped now, while nothing is
            // in flight, they cost the next iteration no wait.
            for b in &mut st.batches {
                b.accel = None;
            }
            Ok::<(), VkTracerError>(())
        })?;
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
        for b in &st.batches[..st.batch_count] {
            all.extend(b.store.read_footprints(&self.ctx, &b.counts)?);
        }
        Ok(all)
    }

    /// The last photon pass's progressive photons, batch after batch, sorted as the
    /// footprints.
    fn read_photons(&self) -> Result<Vec<PackedPhoton>, VkTracerError> {
        let st = self.loaded(Call::ReadPhotons)?;
        st.clock.require_output(Call::ReadPhotons, Stage::PhotonPass)?;
        let mut all = Vec::new();
        for b in &st.batches[..st.batch_count] {
            all.extend(b.store.read_photons(&self.ctx, &b.counts)?);
        }
        Ok(all)
    }

    /// The stats; after a gather whose accumulate has not run yet, its counts are read here
    /// (a wait), since the gather itself does not wait for them.
    fn read_stats(&self) -> Result<IterationStats, VkTracerError> {
        let st = self.loaded(Call::ReadStats)?;
        let mut stats = *st.clock.stats();
        if st.gather_counts_pending {
            self.ctx.finish()?;
            set_gather_counts(&mut stats, &st.gather.read_counts()?);
        }
        Ok(stats)
    }
}
