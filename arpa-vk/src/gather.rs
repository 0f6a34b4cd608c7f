//! The gather on a ray-tracing pipeline: ray generation `vk_gather_raygen`
//! ([`crate::shaders::GATHER_RAYGEN`], the core's `gather.wgsl` per query record) casts one
//! ray of negligible length from each valid query point through the top level over the
//! photon maps' boxes; the AABB hit group is GLSL ([`GATHER_INTERSECTION`]: the exact
//! filter-space or sphere test; [`GATHER_ANY_HIT`]: the contribution into the payload, then
//! `ignoreIntersectionEXT`), the miss shader is WGSL. Writes, per pixel and scale `k` of the
//! bandwidth ([`arpa_core::gather::scales`]), `radiance + weight · E_k` (`E_0 = E_caustic +
//! E_global`, the stored scale) and, for a per-pixel bandwidth, the moment planes, plane-major;
//! counts contributions and valid query points.
//!
//! Descriptor set 0 as `gather.wgsl` declares it: 0 footprints, 1 photons, 2 query records,
//! 3 image (every plane), 4 parameters ([`GatherImageParams`]), 5 the counts, 6 the
//! per-scale, per-pixel irradiance summed over the photon batches gathered so far, 7 the top
//! level.
//!
//! # Order of the sum
//! The any-hit shader adds contributions in the order the traversal visits the boxes. That
//! order is a function of the acceleration structure, which is built from records sorted by
//! (map, Morton code, photon key) — independent of the order the photon pass appended them —
//! so the sum, and the image, are the same for the same seed on the same adapter and driver.
//! It is not the core's order: the image agrees with the CPU backend's to `f32` summation
//! error, not bit for bit.

use crate::accel::AccelerationStructure;
use crate::buffer::{Buffer, KeepAlive};
use crate::compute::{record_compute_barrier, record_fill};
use crate::device::VkContext;
use crate::error::VkError;
use crate::pipeline::{BindingKind, HitGroup, Resource, RtPipeline, RtPipelineDesc, ShaderEntry};
use crate::shaders::{GATHER_ANY_HIT, GATHER_INTERSECTION, GATHER_RAYGEN, GlslStage, compile_wgsl};
use arpa_core::gather::scales::Bandwidth;
use arpa_core::gpu::layout::{self, GatherBatch, GatherImageParams, ImageBufferSizes};
use arpa_core::gather::kernel::Kernel;
use ash::vk;
use std::sync::Arc;
use gpu_allocator::MemoryLocation;

/// Rays per row of the gather's launch (`(x, y, 1)`, x fastest).
const LAUNCH_WIDTH: u32 = 16_384;

/// What the records of one iteration give the gather.
pub struct GatherInputs<'a> {
    /// Sorted footprints (`PackedFootprint`), at least one record's bytes.
    pub footprints: &'a Buffer,
    /// Sorted progressive photons (`PackedPhoton`), at least one record's bytes.
    pub photons: &'a Buffer,
    /// The top level over their boxes (custom index and mask as `gather.wgsl` states).
    pub tlas: &'a AccelerationStructure,
    /// Progressive radius per map (metres).
    pub radii: [f32; 2],
}

/// The gather's pipeline (independent of scene and settings; shared by every
/// [`GatherPass`] of a context).
pub fn gather_pipeline(ctx: &VkContext) -> Result<RtPipeline, VkError> {
    let spirv = compile_wgsl("gather", &arpa_core::gpu::shaders::compose(&[&GATHER_RAYGEN]))?;
    let module = ctx.create_shader_module(&spirv)?;
    let glsl = |g: &GlslStage| ctx.create_shader_module(&g.module()?);
    let (rint, rahit) = (glsl(&GATHER_INTERSECTION)?, glsl(&GATHER_ANY_HIT)?);
    let main = |entry: &'static str| ShaderEntry { module: &module, entry };
    use BindingKind::{AccelerationStructure as As, StorageBuffer as Sb};
    RtPipeline::new(
        ctx,
        &RtPipelineDesc {
            label: "gather",
            raygen: main("vk_gather_raygen"),
            miss: &[main("vk_gather_miss")],
            hit_groups: &[HitGroup::Procedural {
                intersection: ShaderEntry { module: &rint, entry: GlslStage::ENTRY },
                any_hit: Some(ShaderEntry { module: &rahit, entry: GlslStage::ENTRY }),
                closest_hit: None,
            }],
            sets: &[&[Sb, Sb, Sb, Sb, Sb, Sb, Sb, As]],
            push_constant_size: 0,
        },
    )
}

/// The gather of one render: pipeline and its count and batch-irradiance buffers (the
/// parameters are a buffer per batch, [`GatherPass::run`]).
pub struct GatherPass {
    pipeline: Arc<RtPipeline>,
    /// The counts ([`layout::GatherCounts`]) summed over the batches since the first
    /// (host-visible).
    counts: Buffer,
    /// Per scale and pixel (scale-major), the irradiance summed over the batches so far.
    batch_irradiance: Buffer,
    kernel: Kernel,
    bandwidth: Bandwidth,
    pixels: u32,
}

/// Size of the device's counters ([`layout::GatherCounts`], bytes).
const COUNTS_BYTES: u64 = size_of::<layout::GatherCounts>() as u64;

/// Contributions and candidates summed and valid query points of one gather (from the
/// device's [`layout::GatherCounts`]).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct GatherCounts {
    /// Records that contributed, over every query point, per map.
    pub contributions: [u64; 2],
    /// Candidate records (boxes containing the query point), over every query point, per
    /// map.
    pub candidates: [u64; 2],
    /// Query records with a valid query point.
    pub query_points: u64,
    /// Valid query records with a contribution per map.
    pub covered: [u64; 2],
}

impl GatherPass {
    /// The gather of `pixels` query records with footprint kernel `kernel` into the planes
    /// of `bandwidth` on `pipeline` ([`gather_pipeline`]).
    pub fn new(ctx: &VkContext, pipeline: &Arc<RtPipeline>, kernel: Kernel, bandwidth: Bandwidth, pixels: u32) -> Result<Self, VkError> {
        let pipeline = Arc::clone(pipeline);
        let storage = vk::BufferUsageFlags::STORAGE_BUFFER;
        Ok(Self {
            pipeline,
            counts: ctx.create_buffer("gather counts", COUNTS_BYTES, storage | vk::BufferUsageFlags::TRANSFER_DST, MemoryLocation::GpuToCpu)?,
            batch_irradiance: ctx.create_buffer("gather batch irradiance", ImageBufferSizes::new(pixels.max(1), bandwidth).batch_irradiance, storage, MemoryLocation::GpuOnly)?,
            kernel,
            bandwidth,
            pixels,
        })
    }

    /// Submits the gather of every query record of `queries` from the photon batch `maps`
    /// without waiting for it ([`VkContext::submit`]; its parameters and descriptor set
    /// stay alive with the submission). The first batch starts each pixel's irradiance sums
    /// (one per scale) and zeroes the counts on the device, later ones add to both, the last
    /// writes `radiance + weight · E_k` per scale and the moments into `image` (one
    /// `vec4<f32>` per plane and pixel, plane-major: [`ImageBufferSizes::image`] bytes); with
    /// one batch, `batch` is both first and last. [`GatherPass::read_counts`] reads the
    /// counts summed over the batches after a wait.
    pub fn run(&mut self, ctx: &VkContext, queries: &Buffer, image: &Buffer, maps: &GatherInputs<'_>, batch: GatherBatch) -> Result<(), VkError> {
        if self.pixels == 0 {
            if batch.first {
                // No trace zeroes them: the host does, once nothing in flight counts.
                ctx.finish()?;
                self.counts.write(0, &[0u8; COUNTS_BYTES as usize])?;
            }
            return Ok(());
        }
        let gather_params = GatherImageParams::new(maps.radii, self.kernel, self.pixels, batch, self.bandwidth);
        // A buffer per batch: the previous batch's trace may still read its own.
        let mut params = ctx.create_buffer("gather parameters", size_of::<GatherImageParams>() as u64, vk::BufferUsageFlags::STORAGE_BUFFER, MemoryLocation::CpuToGpu)?;
        params.write(0, bytemuck::bytes_of(&gather_params))?;
        let set = [
            Resource::StorageBuffer(maps.footprints),
            Resource::StorageBuffer(maps.photons),
            Resource::StorageBuffer(queries),
            Resource::StorageBuffer(image),
            Resource::StorageBuffer(&params),
            Resource::StorageBuffer(&self.counts),
            Resource::StorageBuffer(&self.batch_irradiance),
            Resource::AccelerationStructure(maps.tlas),
        ];
        let bindings = Arc::new(self.pipeline.bind(&[&set])?);
        let x = self.pixels.min(LAUNCH_WIDTH);
        let device = ctx.device();
        let keep: KeepAlive = vec![Box::new(Arc::clone(&bindings)), Box::new(params)];
        let (recorded, _) = ctx.submit(keep, |cmd| {
            if batch.first {
                record_fill(device, cmd, &self.counts, 0);
                record_compute_barrier(device, cmd);
            }
            self.pipeline.record_framed_trace(ctx, cmd, &bindings, &[], [x, self.pixels.div_ceil(x), 1])
        })?;
        recorded
    }

    /// The counts of the gather's batches since its first, read from host-visible memory:
    /// valid once a wait ([`VkContext::finish`]) has found the last batch's trace done.
    pub fn read_counts(&self) -> Result<GatherCounts, VkError> {
        let c: layout::GatherCounts = bytemuck::pod_read_unaligned(&self.counts.read(0, COUNTS_BYTES)?);
        Ok(GatherCounts { contributions: c.contributions(), candidates: c.candidates(), query_points: u64::from(c.query_points), covered: c.covered.map(u64::from) })
    }
}
