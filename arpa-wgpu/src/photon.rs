//! The photon pass on the device: one invocation per photon, the twin of
//! [`arpa_core::render::photon_path::trace_photon`] (emission from the iteration's prepared lights,
//! specular chains with ray differentials and the Fresnel choice, diffuse store with the
//! adjoint shading-normal ratio, re-emission with the virtual distance, caustic/global
//! classification, Russian roulette, `max_depth`), for both methods.
//!
//! What a photon stores goes into [`PhotonOutputs`] by atomic append, each record tagged with
//! the unique key `photon_index · max_depth + depth` (`depth`: 0-based index of the ray
//! segment that ended at the hit), so sorting by key gives an order independent of the
//! append order (the records are the core's [`arpa_core::gpu::layout`]):
//! * [`KeyedFootprint`]s: photons stored as footprints (method ARPA with the differential
//!   intact), *before* the heuristics: `D_u`, `D_v` projected into the tangent plane and
//!   already scaled by the map's smoothing factor (`S_c`, `S_g`). The store stage
//!   ([`crate::store`], `heuristics.wgsl`'s `arpa_store`) applies only the heuristics, and a
//!   footprint it rejects becomes a progressive photon at its centre with the same flux,
//!   normal and map (as [`arpa_core::store::decision::store_footprint`] does);
//! * [`KeyedPhoton`]s: progressive photons (method RTPM, or a lost differential);
//! * [`PhotonCounters`].
//!
//! An append beyond a buffer's capacity is dropped and counted in
//! [`PhotonCounters::footprint_overflowed`] / [`PhotonCounters::photon_overflowed`]; nothing
//! is written out of bounds. Where the photon arrived from below the shading plane the
//! stored normal is flipped (photon path's `orient_to_shading_side`: the packed record's
//! `row_n` and the fallback photon's normal then come out flipped too, exactly).

use crate::device::GpuContext;
use crate::harness::{HarnessError, storage_entry, uniform_entry};
use crate::scene::scene_pipeline;
use crate::scene::GpuScene;
use arpa_core::emit::emission::PackedLight;
use arpa_core::{gpu::layout::{EmitterRange, PhotonParams}, gpu::fill::emitter_tables};
pub use arpa_core::gpu::layout::{KeyedFootprint, KeyedPhoton, PhotonCounters};
use arpa_core::render::photon_path::PhotonPassSetup;
use arpa_core::render::tracer::RenderSettings;

/// Workgroup size of the photon pass (photons per workgroup).
pub const PHOTON_WORKGROUP_SIZE: u32 = arpa_core::gpu::codes::WORKGROUP_SIZE;

/// Why the photon pass could not be built or encoded.
#[derive(Debug, thiserror::Error)]
pub enum PhotonPassError {
    /// The keys `photon_index · max_depth + depth` (and the segment count, at most
    /// `photons · max_depth`) would not fit in `u32`.
    #[error("photon pass: {photons} photons with max depth {max_depth} exceed the u32 record keys (photons x max depth must stay below 2^32)")]
    KeyRange {
        /// Photons of the iteration.
        photons: u32,
        /// Interactions per photon.
        max_depth: u32,
    },
    /// A batch outside the iteration's photons.
    #[error("photon pass: batch {start}..{end} is not within the iteration's {photons} photons")]
    Batch {
        /// First global photon index of the batch.
        start: u32,
        /// One past its last.
        end: u32,
        /// Photons of the iteration.
        photons: u32,
    },
    /// More photons than one dispatch covers.
    #[error("photon pass: {photons} photons exceed one dispatch of this device ({max} workgroups of {PHOTON_WORKGROUP_SIZE} per dimension)")]
    TooManyPhotons {
        /// Photons of the iteration.
        photons: u32,
        /// The device's workgroups per dimension.
        max: u32,
    },
    /// The setup's emitters are not the scene's.
    #[error("photon pass: the setup has {got} emitters, the pass was built for {expected}")]
    EmitterCount {
        /// Emitters in the setup.
        got: usize,
        /// Emitters the pass was built for.
        expected: usize,
    },
    /// A capacity is zero or larger than a storage binding of this device holds.
    #[error("photon pass: {what} capacity {capacity} is zero or exceeds this device's storage binding ({max_bytes} bytes)")]
    Capacity {
        /// Which buffer.
        what: &'static str,
        /// Records asked for.
        capacity: u64,
        /// The device's largest storage binding.
        max_bytes: u64,
    },
    /// wgpu rejected the module or pipeline, or a read-back failed.
    #[error(transparent)]
    Device(#[from] HarnessError),
}

/// The output buffers of the photon pass, allocated for fixed capacities (records).
pub struct PhotonOutputs {
    footprints: wgpu::Buffer,
    photons: wgpu::Buffer,
    counters: wgpu::Buffer,
    footprint_capacity: u32,
    photon_capacity: u32,
}

impl PhotonOutputs {
    /// Buffers for `footprint_capacity` footprints and `photon_capacity` progressive
    /// photons (each at least 1 and within the device's storage binding size).
    /// Usage: `STORAGE | COPY_SRC | COPY_DST`.
    pub fn new(ctx: &GpuContext, footprint_capacity: u32, photon_capacity: u32) -> Result<Self, PhotonPassError> {
        let device = &ctx.device;
        let max_bytes = device.limits().max_storage_buffer_binding_size;
        let check = |what: &'static str, capacity: u32, size: usize| {
            let bytes = capacity as u64 * size as u64;
            if capacity == 0 || bytes > max_bytes || bytes > device.limits().max_buffer_size {
                Err(PhotonPassError::Capacity { what, capacity: capacity as u64, max_bytes })
            } else {
                Ok(bytes)
            }
        };
        let fp_bytes = check("footprint", footprint_capacity, size_of::<KeyedFootprint>())?;
        let ph_bytes = check("progressive photon", photon_capacity, size_of::<KeyedPhoton>())?;
        let usage = wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC | wgpu::BufferUsages::COPY_DST;
        let buffer = |label: &str, size: u64| device.create_buffer(&wgpu::BufferDescriptor { label: Some(label), size, usage, mapped_at_creation: false });
        Ok(Self {
            footprints: buffer("photon pass footprints", fp_bytes),
            photons: buffer("photon pass progressive photons", ph_bytes),
            counters: buffer("photon pass counters", size_of::<PhotonCounters>() as u64),
            footprint_capacity,
            photon_capacity,
        })
    }

    /// The footprint buffer (`array<KeyedFootprint>`, capacity records).
    pub fn footprints(&self) -> &wgpu::Buffer {
        &self.footprints
    }

    /// The progressive-photon buffer (`array<KeyedPhoton>`, capacity records).
    pub fn photons(&self) -> &wgpu::Buffer {
        &self.photons
    }

    /// The counters buffer (one [`PhotonCounters`]).
    pub fn counters(&self) -> &wgpu::Buffer {
        &self.counters
    }

    /// Footprint capacity (records).
    pub fn footprint_capacity(&self) -> u32 {
        self.footprint_capacity
    }

    /// Progressive-photon capacity (records).
    pub fn photon_capacity(&self) -> u32 {
        self.photon_capacity
    }
}

/// The photon pass's pipeline and per-iteration input buffers for one scene.
pub struct PhotonPass {
    pipeline: wgpu::ComputePipeline,
    layout: wgpu::BindGroupLayout,
    params: wgpu::Buffer,
    lights: wgpu::Buffer,
    ranges: wgpu::Buffer,
    /// The scene's projection cells ([`arpa_core::gpu::fill::cell_table`]), written once.
    cells: wgpu::Buffer,
    /// Sources of the setups this pass takes (twice the scene's emitters).
    emitters: usize,
    /// Per emitter, its record in the scene's texture words
    /// ([`arpa_core::gpu::texture::emitter_records`]).
    emission_records: Vec<u32>,
    settings: RenderSettings,
}

impl PhotonPass {
    /// Compiles the pass for `scene` (uploaded with its bind group 0), the upload of
    /// `prepared` (its emitters and projection cells, which are written here), and the
    /// method, seed, `max_depth`, direct-lighting flag and smoothing of `settings`.
    pub fn new(ctx: &GpuContext, scene: &GpuScene, prepared: &arpa_core::render::prepared_scene::PreparedScene, settings: &RenderSettings) -> Result<Self, PhotonPassError> {
        // A global and a caustic source per emitter (PhotonPassSetup).
        let emitters = 2 * prepared.emitters().len();
        let cell_table = arpa_core::gpu::fill::cell_table(prepared);
        let device = &ctx.device;
        let label = "photon pass";
        let scope = device.push_error_scope(wgpu::ErrorFilter::Validation);
        let module = device.create_shader_module(wgpu::ShaderModuleDescriptor { label: Some(label), source: wgpu::ShaderSource::Wgsl(crate::shaders::photon_pass().into()) });
        let layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some(label),
            entries: &[
                uniform_entry(0),
                storage_entry(1, true),
                storage_entry(2, true),
                storage_entry(3, false),
                storage_entry(4, false),
                storage_entry(5, false),
                storage_entry(6, true),
            ],
        });
        let pipeline = scene_pipeline(device, label, &module, scene, &layout, "photon_pass");
        if let Some(e) = pollster::block_on(scope.pop()) {
            return Err(HarnessError::Shader { label: label.into(), message: e.to_string() }.into());
        }
        let buffer = |size: u64, usage: wgpu::BufferUsages| {
            device.create_buffer(&wgpu::BufferDescriptor { label: Some(label), size, usage: usage | wgpu::BufferUsages::COPY_DST, mapped_at_creation: false })
        };
        let n = emitters.max(1) as u64;
        Ok(Self {
            pipeline,
            layout,
            params: buffer(size_of::<PhotonParams>() as u64, wgpu::BufferUsages::UNIFORM),
            lights: buffer(n * size_of::<PackedLight>() as u64, wgpu::BufferUsages::STORAGE),
            ranges: buffer(n * size_of::<EmitterRange>() as u64, wgpu::BufferUsages::STORAGE),
            cells: {
                let b = buffer((cell_table.len() * size_of::<u32>()) as u64, wgpu::BufferUsages::STORAGE);
                ctx.queue.write_buffer(&b, 0, bytemuck::cast_slice(&cell_table));
                b
            },
            emitters,
            emission_records: arpa_core::gpu::texture::emitter_records(prepared),
            settings: *settings,
        })
    }

    /// Uploads `setup` (the iteration's photon allocation, prepared lights with their
    /// lattice shift, iteration number; [`PhotonPassSetup::new`] with the same settings
    /// the pass was built with) with `queue.write_buffer` and records, in `encoder`, the
    /// clearing of `out`'s counters and the photon pass writing into `out`. `scene` must be
    /// the scene the pass was built for (its bind group 0).
    ///
    /// The upload takes effect at the next `queue.submit`: submit `encoder` before encoding
    /// the next iteration (or batch).
    pub fn encode(
        &self,
        ctx: &GpuContext,
        encoder: &mut wgpu::CommandEncoder,
        scene: &GpuScene,
        setup: &PhotonPassSetup,
        out: &PhotonOutputs,
    ) -> Result<(), PhotonPassError> {
        self.encode_batch(ctx, encoder, scene, setup, 0..setup.photon_count(), out)
    }

    /// As [`PhotonPass::encode`], for the photons of global indices `batch` only (a
    /// sub-range of `0..setup.photon_count()`): each traces exactly as in the pass over
    /// the whole iteration (same random stream, emitter, flux normalised by the iteration's
    /// photon count, record keys `photon_index · max_depth + depth` with the global index),
    /// so the records of consecutive batches are, together, those of one pass, bit for bit.
    /// `out`'s counters count this batch only.
    pub fn encode_batch(
        &self,
        ctx: &GpuContext,
        encoder: &mut wgpu::CommandEncoder,
        scene: &GpuScene,
        setup: &PhotonPassSetup,
        batch: std::ops::Range<u32>,
        out: &PhotonOutputs,
    ) -> Result<(), PhotonPassError> {
        if setup.lights.len() != self.emitters || setup.allocation.len() != self.emitters || setup.first_index.len() != self.emitters {
            return Err(PhotonPassError::EmitterCount { got: setup.lights.len(), expected: self.emitters });
        }
        let total = setup.photon_count();
        let s = &self.settings;
        if total as u64 * s.max_depth as u64 > u32::MAX as u64 {
            return Err(PhotonPassError::KeyRange { photons: total, max_depth: s.max_depth });
        }
        if batch.start > batch.end || batch.end > total {
            return Err(PhotonPassError::Batch { start: batch.start, end: batch.end, photons: total });
        }
        let photons = batch.end - batch.start;
        let max = ctx.device.limits().max_compute_workgroups_per_dimension;
        let groups = photons.div_ceil(PHOTON_WORKGROUP_SIZE);
        let (gx, gy) = if groups <= max { (groups, 1) } else { (max, groups.div_ceil(max)) };
        if gy > max {
            return Err(PhotonPassError::TooManyPhotons { photons, max });
        }
        let (lights, ranges) = emitter_tables(setup, &self.emission_records);
        let params = PhotonParams::new(s, setup.iteration, self.emitters as u32, batch);
        let queue = &ctx.queue;
        queue.write_buffer(&self.params, 0, bytemuck::bytes_of(&params));
        queue.write_buffer(&self.lights, 0, bytemuck::cast_slice(&lights));
        queue.write_buffer(&self.ranges, 0, bytemuck::cast_slice(&ranges));
        let bind_group = ctx.device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("photon pass"),
            layout: &self.layout,
            entries: &[
                wgpu::BindGroupEntry { binding: 0, resource: self.params.as_entire_binding() },
                wgpu::BindGroupEntry { binding: 1, resource: self.lights.as_entire_binding() },
                wgpu::BindGroupEntry { binding: 2, resource: self.ranges.as_entire_binding() },
                wgpu::BindGroupEntry { binding: 3, resource: out.footprints.as_entire_binding() },
                wgpu::BindGroupEntry { binding: 4, resource: out.photons.as_entire_binding() },
                wgpu::BindGroupEntry { binding: 5, resource: out.counters.as_entire_binding() },
                wgpu::BindGroupEntry { binding: 6, resource: self.cells.as_entire_binding() },
            ],
        });
        encoder.clear_buffer(&out.counters, 0, None);
        if photons == 0 {
            return Ok(());
        }
        let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor { label: Some("photon pass"), timestamp_writes: None });
        pass.set_pipeline(&self.pipeline);
        pass.set_bind_group(0, scene.bind_group(), &[]);
        pass.set_bind_group(1, &bind_group, &[]);
        pass.dispatch_workgroups(gx, gy, 1);
        Ok(())
    }
}
