//! The running mean of the iteration images on the device (the core's `accumulate.wgsl`,
//! entry `accumulate`, as a compute pipeline): per entry of the image (every plane of every
//! pixel, plane-major) a compensated `f32` sum and a count of rejected non-finite samples
//! ([`AccumPixel`]); the tracer turns a read-back into the core's
//! [`arpa_core::accumulate::image::Accumulation`], whose mean is the image, so the mean is the
//! core's and arpa-wgpu's.

use std::sync::Arc;
use crate::buffer::Buffer;
use crate::compute::{ComputePipeline, record_compute_barrier, record_fill};
use crate::device::VkContext;
use crate::error::VkError;
use crate::pipeline::{BindingKind, Bindings, Resource};
pub use arpa_core::gpu::layout::AccumPixel;
use ash::vk;
use gpu_allocator::MemoryLocation;

/// Bytes of one image pixel the accumulation reads (`vec4<f32>`, RGB used; W/(m²·sr)).
pub const IMAGE_PIXEL_BYTES: u64 = 16;

/// Bytes of an iteration's status word buffer (`schedule.wgsl`, `accumulate.wgsl`: four
/// `u32`, the first used; non-zero when the iteration's photon pass dropped records, and
/// the accumulation then leaves the sums alone).
pub const STATUS_BYTES: u64 = 16;

/// The running mean's compute pipeline (the core's `accumulate.wgsl`), shared by every
/// [`DeviceAccumulator`] of a context.
///
/// Errors: [`VkError::Shader`] if naga rejects the core's WGSL; device errors.
pub fn accumulate_pipeline(ctx: &VkContext) -> Result<ComputePipeline, VkError> {
    let source = arpa_core::gpu::shaders::compose(&[&arpa_core::gpu::shaders::ACCUMULATE]);
    use BindingKind::StorageBuffer as Sb;
    ComputePipeline::from_wgsl(ctx, "arpa accumulate", &source, "accumulate", &[&[Sb, Sb, Sb]])
}

/// The accumulation buffer of one image size (entries = planes × pixels), with the shared
/// pipeline.
pub struct DeviceAccumulator {
    pipeline: Arc<ComputePipeline>,
    /// `count` × [`AccumPixel`] (exactly: the kernel bounds itself by its length).
    pixels: Buffer,
    count: u32,
    /// A status word that is always zero, for additions no iteration status guards.
    clear: Buffer,
}

impl DeviceAccumulator {
    /// A zeroed accumulator of `pixels` entries (an image's planes × pixels; at least one;
    /// one submission waited for).
    ///
    /// Errors: [`VkError::InvalidInput`] for 0 pixels; [`VkError::Shader`] if naga rejects
    /// the core's WGSL; device errors.
    pub fn new(ctx: &VkContext, pipeline: &Arc<ComputePipeline>, pixels: u32) -> Result<Self, VkError> {
        if pixels == 0 {
            return Err(VkError::InvalidInput { what: "accumulator".into(), reason: "0 pixels".into() });
        }
        let pipeline = Arc::clone(pipeline);
        use vk::BufferUsageFlags as U;
        let buffer = ctx.create_buffer(
            "arpa accumulator",
            u64::from(pixels) * size_of::<AccumPixel>() as u64,
            U::STORAGE_BUFFER | U::TRANSFER_SRC | U::TRANSFER_DST,
            MemoryLocation::GpuOnly,
        )?;
        let clear = ctx.create_buffer("arpa clear status", STATUS_BYTES, U::STORAGE_BUFFER | U::TRANSFER_DST, MemoryLocation::GpuOnly)?;
        let device = ctx.device();
        ctx.submit_and_wait(|cmd| {
            record_fill(device, cmd, &buffer, 0);
            record_fill(device, cmd, &clear, 0);
            record_compute_barrier(device, cmd);
        })?;
        Ok(Self { pipeline, pixels: buffer, count: pixels, clear })
    }

    /// Entries of the image (planes × pixels).
    pub fn pixel_count(&self) -> u32 {
        self.count
    }

    /// The per-pixel sums ([`AccumPixel`], 32 bytes each).
    pub fn pixels(&self) -> &Buffer {
        &self.pixels
    }

    /// Descriptor sets for adding `image` (a storage buffer of at least
    /// [`DeviceAccumulator::pixel_count`] `vec4<f32>`) unless the iteration's `status` word
    /// ([`STATUS_BYTES`]; `None`: always add) is non-zero when the addition runs, for
    /// [`DeviceAccumulator::record`]; keep them, `image` and `status` until the submission is
    /// waited for.
    ///
    /// Errors: [`VkError::InvalidInput`] for an image smaller than the accumulator.
    pub fn bind(&self, image: &Buffer, status: Option<&Buffer>) -> Result<Bindings, VkError> {
        if image.size() < u64::from(self.count) * IMAGE_PIXEL_BYTES {
            return Err(VkError::InvalidInput {
                what: "accumulator".into(),
                reason: format!("image {:?} of {} bytes for {} pixels", image.label(), image.size(), self.count),
            });
        }
        self.pipeline.bind(&[&[Resource::StorageBuffer(image), Resource::StorageBuffer(&self.pixels), Resource::StorageBuffer(status.unwrap_or(&self.clear))]])
    }

    /// Records the addition of the image `bindings` name (from [`DeviceAccumulator::bind`]) to
    /// the sums, then a compute barrier (the sums are visible to a later addition, transfer
    /// or host read). The image's writes must be visible to compute shaders.
    pub fn record(&self, ctx: &VkContext, cmd: vk::CommandBuffer, bindings: &Bindings) -> Result<(), VkError> {
        self.pipeline.record_dispatch_linear(cmd, bindings, &[], self.count)?;
        record_compute_barrier(ctx.device(), cmd);
        Ok(())
    }

    /// Adds `image` to the sums (unless `status` says otherwise, [`DeviceAccumulator::bind`])
    /// in one submission and waits (a barrier before, so earlier transfer and compute writes
    /// of the image are visible).
    pub fn accumulate_and_wait(&self, ctx: &VkContext, image: &Buffer, status: Option<&Buffer>) -> Result<(), VkError> {
        let bindings = self.bind(image, status)?;
        ctx.submit_and_wait(|cmd| {
            record_compute_barrier(ctx.device(), cmd);
            self.record(ctx, cmd, &bindings)
        })??;
        Ok(())
    }

    /// Replaces the sums with `pixels` (one per entry; a checkpoint resumed).
    ///
    /// Errors: [`VkError::InvalidInput`] for a wrong pixel count; device errors.
    pub fn write_pixels(&mut self, ctx: &VkContext, pixels: &[AccumPixel]) -> Result<(), VkError> {
        if pixels.len() != self.count as usize {
            return Err(VkError::InvalidInput { what: "accumulator".into(), reason: format!("{} pixels for an accumulator of {}", pixels.len(), self.count) });
        }
        use vk::BufferUsageFlags as U;
        let buffer = ctx.upload("arpa accumulator", bytemuck::cast_slice(pixels), U::STORAGE_BUFFER | U::TRANSFER_SRC)?;
        std::mem::replace(&mut self.pixels, buffer).destroy()
    }

    /// The per-pixel accumulators, read back.
    pub fn read_pixels(&self, ctx: &VkContext) -> Result<Vec<AccumPixel>, VkError> {
        Ok(crate::buffer::pod_vec(&ctx.read_back(&self.pixels, 0, self.pixels.size())?))
    }

    /// The mean over `iterations` iterations per pixel (RGB, W/(m²·sr); [`AccumPixel::mean`]:
    /// 0 before any iteration and where not finite).
    pub fn read_mean(&self, ctx: &VkContext, iterations: u32) -> Result<Vec<[f32; 3]>, VkError> {
        Ok(self.read_pixels(ctx)?.iter().map(|p| p.mean(iterations).to_array()).collect())
    }
}
