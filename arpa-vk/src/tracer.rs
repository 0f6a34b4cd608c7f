//! [`VkTracer`]: the Vulkan backend of [`arpa_core::tracer::Tracer`] on ray-tracing
//! pipelines.

use crate::accumulate::{DeviceAccumulator, accumulate_pipeline};
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
use arpa_core::footprint::PackedFootprint;
use arpa_core::gpu::batch::{RecordLimits, grow, initial_capacity};
use arpa_core::gpu::layout::{CameraParams, StoreCounts, StoreSettings};
use arpa_core::photon_path::PhotonPassSetup;
use arpa_core::prepared_scene::PreparedScene;
use arpa_core::progressive_photon::PackedPhoton;
use arpa_core::scene::{Scene, SceneError};
use arpa_core::tracer::{
    BackendKind, Call, Capabilities, Image, InvalidSettings, IterationStats, Method, QueryRecord, RenderSettings, Stage, StageClock, StageError, Tracer,
    prepare_upload, uploaded,
};
use ash::vk;
use gpu_allocator::MemoryLocation;
use std::sync::{Arc, Mutex};
use std::time::Instant;

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
/// | [`upload_scene`](Tracer::upload_scene) | validates scene and settings, builds the triangle structures, uploads the scene tables, compiles the pipelines | the builds |
/// | [`camera_pass`](Tracer::camera_pass) | ray generation per pixel, closest-hit and miss over the triangles ([`CameraPass`]) | the trace |
/// | [`photon_pass`](Tracer::photon_pass) | ray generation per photon appending keyed footprints and photons ([`PhotonPass`]); keyed store, sort and compaction into the sorted maps and their boxes ([`MapStore`]) | the photon counters (48 bytes: overflow and the store's sizes) and the store counts (48 bytes: the sort's schedule and the build's sizes) |
/// | [`build_acceleration_structure`](Tracer::build_acceleration_structure) | AABB bottom levels per (kind, map) over the sorted boxes, one top level ([`MapAccel`]) | the build |
/// | [`gather`](Tracer::gather) | ray generation per query record, one point query through the AABB hit group (GLSL intersection: exact test; any-hit: contribution, ignore) ([`GatherPass`]) | contribution and query-point counts (16 bytes) |
/// | [`accumulate`](Tracer::accumulate) | compensated running sum ([`DeviceAccumulator`]) | the dispatch |
///
/// Each stage is one submission (or two, for the photon pass's store and sort) that the host
/// waits for: the stage times of [`IterationStats`] are the device's. Both readbacks of the
/// photon pass stay because Vulkan's indirect build takes primitive counts from device
/// memory but not the sizes of the structures, which must be allocated before the build.
///
/// # Photon records
/// One batch per iteration: the photon pass's buffers start at
/// [`arpa_core::gpu::batch::INITIAL_RECORDS_PER_PHOTON`] records per photon and grow when a
/// pass overflows them (the pass is then traced again with the same random streams, so the
/// iteration is unbiased; the dropped appends are counted in [`IterationStats::overflowed`]).
/// An iteration whose records exceed one storage binding of the adapter
/// (`maxStorageBufferRange`) is a [`VkTracerError::Size`] error.
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

struct Loaded {
    /// Dropped before the buffers it refers to.
    accel: Option<MapAccel>,
    pipelines: Arc<PassPipelines>,
    prepared: PreparedScene,
    settings: RenderSettings,
    camera: CameraPass,
    photon: PhotonPass,
    outputs: PhotonOutputs,
    store: MapStore,
    counts: StoreCounts,
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
        Ok(Self { state: None, ctx, pipelines, initial_capacity: None })
    }

    /// A tracer on an open context (e.g. one with validation, for tests); its pipelines are
    /// made at the first [`Tracer::upload_scene`] and kept for the next renders.
    pub fn with_context(ctx: VkContext) -> Self {
        Self { state: None, ctx, pipelines: Arc::default(), initial_capacity: None }
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

impl Tracer for VkTracer {
    type Error = VkTracerError;

    fn capabilities(&self) -> Capabilities {
        let i = self.ctx.info();
        Capabilities {
            backend: BackendKind::Vk,
            device: format!("{} ({}, {} {})", i.name, i.device_type, i.driver_name, i.driver_info),
            methods: vec![Method::Arpa, Method::Rtpm],
            // Bounded by one storage binding's records, which depends on the scene.
            max_photons_per_iteration: None,
            deterministic: true,
        }
    }

    fn upload_scene(&mut self, scene: &Scene, settings: &RenderSettings) -> Result<(), VkTracerError> {
        self.state = None;
        let prepared = prepare_upload(scene, settings)?;
        if u64::from(settings.photons_per_iteration) * u64::from(settings.max_depth) > u64::from(u32::MAX) {
            return Err(StageError::Settings(InvalidSettings(format!(
                "photons_per_iteration {} × max_depth {} exceeds the u32 record keys of the vk backend (at most {} photons at this depth)",
                settings.photons_per_iteration,
                settings.max_depth,
                u32::MAX / settings.max_depth
            )))
            .into());
        }
        let ctx = &self.ctx;
        let (width, height) = (scene.camera.width, scene.camera.height);
        let limits = RecordLimits::new(binding_bytes(ctx));
        let pixels = u32::try_from(u64::from(width) * u64::from(height))
            .ok()
            .filter(|&p| u64::from(p) * QUERY_RECORD_BYTES <= binding_bytes(ctx) && p <= ctx.ray_tracing().max_ray_dispatch_invocation_count);
        let Some(pixels) = pixels else {
            return Err(self.size_error(format!("an image of {width}×{height} pixels exceeds one storage binding or one ray launch")));
        };
        let pipelines = self.pass_pipelines()?;
        let vk_scene = VkScene::upload(ctx, &prepared)?;
        let storage = vk::BufferUsageFlags::STORAGE_BUFFER | vk::BufferUsageFlags::TRANSFER_SRC;
        let queries = ctx.create_buffer("query records", (u64::from(pixels) * QUERY_RECORD_BYTES).max(QUERY_RECORD_BYTES), storage, MemoryLocation::GpuOnly)?;
        let image = ctx.create_buffer("iteration image", (u64::from(pixels) * 16).max(16), storage, MemoryLocation::GpuOnly)?;
        let camera = CameraPass::new(ctx, &pipelines.camera, &vk_scene, CameraParams::new(&scene.camera, settings, width)?, &queries)?;
        let mut photon = PhotonPass::new(ctx, &pipelines.photon, prepared.emitters().len(), settings)?;
        let n = settings.photons_per_iteration;
        let fp_cap = initial_capacity(n, self.initial_capacity, limits.raw_footprints);
        let ph_cap = initial_capacity(n, self.initial_capacity, limits.photons);
        let outputs = PhotonOutputs::new(ctx, fp_cap, ph_cap)?;
        photon.bind(&vk_scene, &outputs)?;
        let store = MapStore::new(ctx, &pipelines.store, outputs.footprint_capacity(), outputs.photon_capacity())?;
        let gather = GatherPass::new(ctx, &pipelines.gather, settings.kernel, pixels)?;
        let accumulator = DeviceAccumulator::new(ctx, &pipelines.accumulate, pixels)?;
        self.state = Some(Box::new(Loaded {
            accel: None,
            pipelines,
            prepared,
            settings: *settings,
            camera,
            photon,
            outputs,
            store,
            counts: StoreCounts::default(),
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
            clock: StageClock::new(),
        }));
        Ok(())
    }

    fn camera_pass(&mut self) -> Result<(), VkTracerError> {
        let st = uploaded(self.state.as_deref_mut(), Stage::CameraPass)?;
        st.clock.begin(Stage::CameraPass)?;
        let start = Instant::now();
        st.camera.run(&self.ctx, st.clock.completed())?;
        st.clock.stats_mut().times.camera = start.elapsed().as_secs_f64();
        st.clock.finish(Stage::CameraPass);
        Ok(())
    }

    fn photon_pass(&mut self) -> Result<(), VkTracerError> {
        let adapter = self.ctx.info().name.clone();
        let ctx = &self.ctx;
        let st = uploaded(self.state.as_deref_mut(), Stage::PhotonPass)?;
        st.clock.begin(Stage::PhotonPass)?;
        let start = Instant::now();
        // The previous iteration's structure refers to the buffers the store rewrites.
        st.accel = None;
        let setup = PhotonPassSetup::new(&st.prepared, &st.settings, st.clock.completed());
        let size = |message: String| VkTracerError::Size { adapter: adapter.clone(), message };
        let mut overflowed = 0u64;
        // Trace; on overflow grow the buffers and trace the same photons again.
        let counters = loop {
            let c = st.photon.run(ctx, &setup, &mut st.outputs)?;
            if c.overflowed() == 0 {
                break c;
            }
            overflowed += c.overflowed();
            let limits = st.limits;
            if c.footprint_appends > limits.raw_footprints || c.photon_appends > limits.photons {
                return Err(size(format!(
                    "{} photons store {} raw footprints and {} progressive photons; one binding holds {} and {}",
                    setup.photon_count(),
                    c.footprint_appends,
                    c.photon_appends,
                    limits.raw_footprints,
                    limits.photons
                )));
            }
            let fp_cap = grow(c.footprint_appends, st.outputs.footprint_capacity(), limits.raw_footprints);
            let ph_cap = grow(c.photon_appends, st.outputs.photon_capacity(), limits.photons);
            // Free the old buffers before allocating the larger ones.
            st.outputs = PhotonOutputs::new(ctx, 1, 1)?;
            st.store = MapStore::new(ctx, &st.pipelines.store, 1, 1)?;
            st.outputs = PhotonOutputs::new(ctx, fp_cap, ph_cap)?;
            st.photon.bind(&st.scene, &st.outputs)?;
            st.store = MapStore::new(ctx, &st.pipelines.store, fp_cap, ph_cap)?;
        };
        let radii = setup.radii.map(|r| r as f32);
        let settings = StoreSettings {
            heuristics: setup.heuristics.pack(),
            radii,
            bounds: st.prepared.bounds().to_f32_conservative(),
            raw_count: counters.footprints_written(),
            photon_count: counters.photons_written(),
        };
        let counts = st.store.store(ctx, st.outputs.footprints(), st.outputs.photons(), &settings)?;
        let counts = st.store.sort(ctx, st.outputs.footprints(), st.outputs.photons(), &counts, &settings)?;
        if counts.overflowed > 0 {
            return Err(size(format!("{} progressive photons (with the footprints' fallbacks) exceed the sorted buffer", counts.photon_items)));
        }
        st.counts = counts;
        st.radii = radii;
        let stats = st.clock.stats_mut();
        stats.overflowed = overflowed;
        stats.photons_emitted = u64::from(counters.emitted);
        stats.photon_segments = u64::from(counters.segments);
        for m in 0..2 {
            stats.footprints[m] = u64::from(counts.footprints[m]);
            stats.progressive[m] = u64::from(counts.photons[m]);
        }
        stats.degenerate = u64::from(counts.degenerate);
        stats.culled = u64::from(counts.culled);
        stats.unrepresentable = u64::from(counts.unrepresentable);
        stats.differential_lost = u64::from(counters.differential_lost);
        stats.radii = setup.radii;
        stats.times.photon = start.elapsed().as_secs_f64();
        st.clock.finish(Stage::PhotonPass);
        Ok(())
    }

    fn build_acceleration_structure(&mut self) -> Result<(), VkTracerError> {
        let st = uploaded(self.state.as_deref_mut(), Stage::BuildAccelerationStructure)?;
        st.clock.begin(Stage::BuildAccelerationStructure)?;
        let start = Instant::now();
        st.accel = None;
        st.accel = Some(MapAccel::build(&self.ctx, st.store.footprint_boxes(), st.store.photon_boxes(), &st.counts)?);
        st.clock.stats_mut().times.build = start.elapsed().as_secs_f64();
        st.clock.finish(Stage::BuildAccelerationStructure);
        Ok(())
    }

    fn gather(&mut self) -> Result<(), VkTracerError> {
        let st = uploaded(self.state.as_deref_mut(), Stage::Gather)?;
        st.clock.begin(Stage::Gather)?;
        let start = Instant::now();
        let accel = st.accel.as_ref().ok_or_else(|| StageError::order(Stage::Gather, Stage::BuildAccelerationStructure))?;
        let inputs = GatherInputs { footprints: st.store.footprints(), photons: st.store.photons(), tlas: accel.tlas(), radii: st.radii };
        let counts = st.gather.run(&self.ctx, &st.queries, &st.image, &inputs)?;
        let stats = st.clock.stats_mut();
        stats.gathered = counts.contributions;
        stats.query_points = counts.query_points;
        stats.times.gather = start.elapsed().as_secs_f64();
        st.clock.finish(Stage::Gather);
        Ok(())
    }

    fn accumulate(&mut self) -> Result<(), VkTracerError> {
        let st = uploaded(self.state.as_deref_mut(), Stage::Accumulate)?;
        st.clock.begin(Stage::Accumulate)?;
        let start = Instant::now();
        st.accumulator.accumulate_and_wait(&self.ctx, &st.image)?;
        st.clock.stats_mut().times.accumulate = start.elapsed().as_secs_f64();
        st.clock.finish(Stage::Accumulate);
        Ok(())
    }

    fn iterations(&self) -> u32 {
        self.state.as_ref().map_or(0, |s| s.clock.completed())
    }

    fn read_image(&self) -> Result<Image, VkTracerError> {
        let st = self.loaded(Call::ReadImage)?;
        let pixels = st.accumulator.read_mean(&self.ctx, st.clock.completed())?;
        Ok(Image { width: st.width, height: st.height, pixels: pixels.into_iter().map(arpa_core::glam::Vec3::from_array).collect() })
    }

    fn read_query_points(&self) -> Result<Vec<QueryRecord>, VkTracerError> {
        let st = self.loaded(Call::ReadQueryPoints)?;
        st.clock.require_output(Call::ReadQueryPoints, Stage::CameraPass)?;
        Ok(crate::buffer::pod_vec(&self.ctx.read_back(&st.queries, 0, u64::from(st.pixels) * QUERY_RECORD_BYTES)?))
    }

    /// The last photon pass's footprints, sorted by map (caustic first), then by Morton code
    /// and key.
    fn read_footprints(&self) -> Result<Vec<PackedFootprint>, VkTracerError> {
        let st = self.loaded(Call::ReadFootprints)?;
        st.clock.require_output(Call::ReadFootprints, Stage::PhotonPass)?;
        Ok(st.store.read_footprints(&self.ctx, &st.counts)?)
    }

    /// The last photon pass's progressive photons, sorted as the footprints.
    fn read_photons(&self) -> Result<Vec<PackedPhoton>, VkTracerError> {
        let st = self.loaded(Call::ReadPhotons)?;
        st.clock.require_output(Call::ReadPhotons, Stage::PhotonPass)?;
        Ok(st.store.read_photons(&self.ctx, &st.counts)?)
    }

    fn read_stats(&self) -> Result<IterationStats, VkTracerError> {
        Ok(*self.loaded(Call::ReadStats)?.clock.stats())
    }
}
