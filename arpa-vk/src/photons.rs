//! The photon pass on a ray-tracing pipeline: ray generation `vk_photon_raygen`
//! ([`crate::shaders::PHOTON_RAYGEN`], the core's `photon_pass.wgsl` per photon), its rays
//! through `scene_trace.wgsl`'s miss and triangle closest-hit shaders. Photons append keyed
//! raw footprints and keyed progressive photons with atomics into [`PhotonOutputs`] and
//! count themselves in [`PhotonCounters`]. Descriptor set 0 is the scene ([`VkScene`]);
//! set 1: the parameters ([`PhotonParams`], uniform), the packed lights, the emitter ranges,
//! the two append buffers and the counters, as `photon_pass.wgsl` declares them.

use crate::buffer::Buffer;
use crate::camera::scene_pipeline;
use crate::device::VkContext;
use crate::error::VkError;
use crate::pipeline::{BindingKind, Bindings, Resource, RtPipeline};
use crate::scene::VkScene;
use crate::shaders::PHOTON_RAYGEN;
use arpa_core::emit::emission::PackedLight;
use arpa_core::{gpu::layout::{EmitterRange, KeyedFootprint, KeyedPhoton, PhotonCounters, PhotonParams}, gpu::fill::emitter_tables};
use arpa_core::render::photon_path::PhotonPassSetup;
use arpa_core::render::tracer::RenderSettings;
use ash::vk;
use std::sync::Arc;
use gpu_allocator::MemoryLocation;

/// Rays per row of the photon pass's launch (the launch is `(x, y, 1)`, x fastest).
const LAUNCH_WIDTH: u32 = 16_384;

/// The photon pass's append buffers and counters.
pub struct PhotonOutputs {
    footprints: Buffer,
    photons: Buffer,
    counters: Buffer,
    footprint_capacity: u32,
    photon_capacity: u32,
}

impl PhotonOutputs {
    /// Buffers for `footprint_capacity` keyed footprints and `photon_capacity` keyed photons
    /// (each at least 1).
    pub fn new(ctx: &VkContext, footprint_capacity: u32, photon_capacity: u32) -> Result<Self, VkError> {
        let (fc, pc) = (footprint_capacity.max(1), photon_capacity.max(1));
        let usage = vk::BufferUsageFlags::STORAGE_BUFFER | vk::BufferUsageFlags::TRANSFER_SRC;
        Ok(Self {
            footprints: ctx.create_buffer("photon pass footprints", u64::from(fc) * size_of::<KeyedFootprint>() as u64, usage, MemoryLocation::GpuOnly)?,
            photons: ctx.create_buffer("photon pass progressive photons", u64::from(pc) * size_of::<KeyedPhoton>() as u64, usage, MemoryLocation::GpuOnly)?,
            // Zeroed on the device before each pass (PhotonPass::record_batch), copied out by
            // the tracer after its store.
            counters: ctx.create_buffer(
                "photon pass counters",
                size_of::<PhotonCounters>() as u64,
                vk::BufferUsageFlags::STORAGE_BUFFER | vk::BufferUsageFlags::TRANSFER_DST | vk::BufferUsageFlags::TRANSFER_SRC,
                MemoryLocation::GpuToCpu,
            )?,
            footprint_capacity: fc,
            photon_capacity: pc,
        })
    }

    /// The keyed raw footprints ([`KeyedFootprint`]).
    pub fn footprints(&self) -> &Buffer {
        &self.footprints
    }

    /// The keyed progressive photons ([`KeyedPhoton`]).
    pub fn photons(&self) -> &Buffer {
        &self.photons
    }

    /// Records the footprint buffer holds.
    pub fn footprint_capacity(&self) -> u32 {
        self.footprint_capacity
    }

    /// Records the photon buffer holds.
    pub fn photon_capacity(&self) -> u32 {
        self.photon_capacity
    }

    /// The counters ([`PhotonCounters`], host-visible storage), for kernels that take the
    /// pass's counts on the device.
    pub fn counters(&self) -> &Buffer {
        &self.counters
    }

    /// The counters of the last pass, once its submission has been waited for.
    pub fn read_counters(&self) -> Result<PhotonCounters, VkError> {
        Ok(bytemuck::pod_read_unaligned(&self.counters.read(0, size_of::<PhotonCounters>() as u64)?))
    }
}

/// The photon pass of one render.
pub struct PhotonPass {
    bindings: Option<Bindings>,
    pipeline: Arc<RtPipeline>,
    params: Buffer,
    lights: Buffer,
    ranges: Buffer,
    /// The scene's projection cells ([`arpa_core::gpu::fill::cell_table`]), written once.
    cells: Buffer,
    /// Sources of the setups this pass takes (twice the scene's emitters).
    emitters: usize,
    /// Per emitter, its record in the scene's texture words
    /// ([`arpa_core::gpu::texture::emitter_records`]).
    emission_records: Vec<u32>,
    settings: RenderSettings,
}

/// The photon pass's pipeline (independent of scene and settings; shared by every
/// [`PhotonPass`] of a context).
pub fn photon_pipeline(ctx: &VkContext) -> Result<RtPipeline, VkError> {
    let source = arpa_core::gpu::shaders::compose(&[&PHOTON_RAYGEN]);
    use BindingKind::{StorageBuffer as Sb, UniformBuffer as Ub};
    scene_pipeline(ctx, "photon pass", &source, "vk_photon_raygen", &[Ub, Sb, Sb, Sb, Sb, Sb, Sb])
}

impl PhotonPass {
    /// The pass on `pipeline` ([`photon_pipeline`]) for the scene `prepared` (its
    /// emitters; its projection cells are written here) under `settings`.
    pub fn new(ctx: &VkContext, pipeline: &Arc<RtPipeline>, prepared: &arpa_core::render::prepared_scene::PreparedScene, settings: &RenderSettings) -> Result<Self, VkError> {
        let pipeline = Arc::clone(pipeline);
        // A global and a caustic source per emitter (PhotonPassSetup).
        let emitters = 2 * prepared.emitters().len();
        let cell_table = arpa_core::gpu::fill::cell_table(prepared);
        let n = emitters.max(1) as u64;
        let host = MemoryLocation::CpuToGpu;
        Ok(Self {
            bindings: None,
            pipeline,
            // Written per batch inside its submission (vkCmdUpdateBuffer), so that the batches
            // of an iteration can be in flight together.
            params: ctx.create_buffer("photon pass parameters", size_of::<PhotonParams>() as u64, vk::BufferUsageFlags::UNIFORM_BUFFER | vk::BufferUsageFlags::TRANSFER_DST, MemoryLocation::GpuOnly)?,
            lights: ctx.create_buffer("photon pass lights", n * size_of::<PackedLight>() as u64, vk::BufferUsageFlags::STORAGE_BUFFER, host)?,
            ranges: ctx.create_buffer("photon pass emitter ranges", n * size_of::<EmitterRange>() as u64, vk::BufferUsageFlags::STORAGE_BUFFER, host)?,
            cells: {
                let mut b = ctx.create_buffer("photon pass projection cells", (cell_table.len() * size_of::<u32>()) as u64, vk::BufferUsageFlags::STORAGE_BUFFER, host)?;
                b.write(0, bytemuck::cast_slice(&cell_table))?;
                b
            },
            emitters,
            emission_records: arpa_core::gpu::texture::emitter_records(prepared),
            settings: *settings,
        })
    }

    /// Binds the scene and `out` (call again after `out` is replaced).
    pub fn bind(&mut self, scene: &VkScene, out: &PhotonOutputs) -> Result<(), VkError> {
        self.bindings = None;
        let pass = [
            Resource::UniformBuffer(&self.params),
            Resource::StorageBuffer(&self.lights),
            Resource::StorageBuffer(&self.ranges),
            Resource::StorageBuffer(&out.footprints),
            Resource::StorageBuffer(&out.photons),
            Resource::StorageBuffer(&out.counters),
            Resource::StorageBuffer(&self.cells),
        ];
        self.bindings = Some(self.pipeline.bind(&[&scene.resources(), &pass])?);
        Ok(())
    }

    /// Traces the photons `batch` (global indices of the iteration `setup`: their random
    /// streams, emitters and record keys are those of one pass over the whole iteration)
    /// into `out` (bound with [`PhotonPass::bind`]), waits, and returns the counters
    /// ([`PhotonPass::prepare_iteration`], [`PhotonPass::record_batch`] in a submission of
    /// its own).
    ///
    /// Errors: as [`PhotonPass::prepare_iteration`] and [`PhotonPass::record_batch`].
    pub fn run(&mut self, ctx: &VkContext, setup: &PhotonPassSetup, batch: std::ops::Range<u32>, out: &mut PhotonOutputs) -> Result<PhotonCounters, VkError> {
        self.prepare_iteration(setup)?;
        ctx.submit_and_wait(|cmd| self.record_batch(ctx, cmd, setup, batch, out))??;
        out.read_counters()
    }

    /// Checks the iteration `setup` and writes its emitter tables into host-visible memory,
    /// which every batch of the iteration reads: no submission of this pass may be in
    /// flight.
    ///
    /// Errors: [`VkError::InvalidInput`] when `setup` is for another emitter count, when the
    /// record keys `photons · max_depth` overflow `u32`, or when nothing is bound.
    pub fn prepare_iteration(&mut self, setup: &PhotonPassSetup) -> Result<(), VkError> {
        let invalid = |reason: String| VkError::InvalidInput { what: "photon pass".into(), reason };
        if setup.lights.len() != self.emitters || setup.allocation.len() != self.emitters || setup.first_index.len() != self.emitters {
            return Err(invalid(format!("{} emitters in the setup, the pass was made for {}", setup.lights.len(), self.emitters)));
        }
        let photons = setup.photon_count();
        if u64::from(photons) * u64::from(self.settings.max_depth) > u64::from(u32::MAX) {
            return Err(invalid(format!("{photons} photons × max_depth {} overflow the u32 record keys", self.settings.max_depth)));
        }
        if self.bindings.is_none() {
            return Err(invalid("no output buffers bound".into()));
        }
        let (lights, ranges) = emitter_tables(setup, &self.emission_records);
        self.lights.write(0, bytemuck::cast_slice(&lights))?;
        self.ranges.write(0, bytemuck::cast_slice(&ranges))?;
        Ok(())
    }

    /// Records batch `batch` (global photons of the iteration `setup`, whose tables
    /// [`PhotonPass::prepare_iteration`] wrote) into `cmd`: its parameters
    /// (`vkCmdUpdateBuffer`), `out`'s counters zeroed, then the trace framed by barriers
    /// (earlier writes before it, its writes before transfers and the host). An empty batch
    /// records the parameters and the zeroed counters only.
    ///
    /// Errors: [`VkError::InvalidInput`] for a batch outside the iteration, when nothing is
    /// bound or the launch is too large.
    pub fn record_batch(&self, ctx: &VkContext, cmd: vk::CommandBuffer, setup: &PhotonPassSetup, batch: std::ops::Range<u32>, out: &PhotonOutputs) -> Result<(), VkError> {
        let invalid = |reason: String| VkError::InvalidInput { what: "photon pass".into(), reason };
        let bindings = self.bindings.as_ref().ok_or_else(|| invalid("no output buffers bound".into()))?;
        let total = setup.photon_count();
        if batch.start > batch.end || batch.end > total {
            return Err(invalid(format!("photons {batch:?} of an iteration of {total}")));
        }
        let params = PhotonParams::new(&self.settings, setup.iteration, self.emitters as u32, batch.clone());
        let device = ctx.device();
        // SAFETY: live buffers with TRANSFER_DST usage; the command buffer's opening barrier
        // orders earlier submissions' reads of them before these writes.
        unsafe { device.cmd_update_buffer(cmd, self.params.raw(), 0, bytemuck::bytes_of(&params)) };
        crate::compute::record_fill(device, cmd, &out.counters, 0);
        let photons = batch.end - batch.start;
        if photons == 0 {
            crate::compute::record_compute_barrier(device, cmd);
            return Ok(());
        }
        let written = vk::MemoryBarrier::default()
            .src_access_mask(vk::AccessFlags::TRANSFER_WRITE)
            .dst_access_mask(vk::AccessFlags::UNIFORM_READ | vk::AccessFlags::SHADER_READ | vk::AccessFlags::SHADER_WRITE);
        // SAFETY: a plain barrier in a recording command buffer.
        unsafe {
            device.cmd_pipeline_barrier(cmd, vk::PipelineStageFlags::TRANSFER, vk::PipelineStageFlags::RAY_TRACING_SHADER_KHR, vk::DependencyFlags::empty(), &[written], &[], &[]);
        }
        let x = photons.min(LAUNCH_WIDTH);
        self.pipeline.record_framed_trace(ctx, cmd, bindings, &[], [x, photons.div_ceil(x), 1])
    }
}
