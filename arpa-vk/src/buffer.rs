//! Buffers (a `VkBuffer` bound to gpu-allocator memory), host access, staged uploads and
//! read-backs, and one-time command submissions.
//!
//! **Ownership.** A [`Buffer`] holds a reference-counted handle on its context's device and
//! allocator, so it can free itself on drop (or through [`Buffer::destroy`], which reports a
//! failure to free) and the device can never be destroyed before it. Every submission this
//! crate makes is waited for before it returns, so no buffer is in use by the device when safe
//! code drops it.

use crate::device::{Shared, VkContext, lock};
use crate::error::{VkError, VkResultExt};
use ash::vk;
use gpu_allocator::vulkan::{Allocation, AllocationCreateDesc, AllocationScheme};
use gpu_allocator::{AllocationError, MemoryLocation};
use std::sync::Arc;

/// A Vulkan buffer and its memory.
///
/// Host access ([`Buffer::write`], [`Buffer::read`]) works where the memory is host-visible
/// and host-coherent ([`Buffer::is_host_visible`]): always for [`MemoryLocation::CpuToGpu`]
/// and [`MemoryLocation::GpuToCpu`], and on lavapipe for every location. Device-local buffers
/// go through [`VkContext::upload`] and [`VkContext::read_back`].
pub struct Buffer {
    shared: Arc<Shared>,
    raw: vk::Buffer,
    /// `None` once freed.
    allocation: Option<Allocation>,
    label: String,
    size: u64,
    usage: vk::BufferUsageFlags,
    location: MemoryLocation,
    address: Option<vk::DeviceAddress>,
}

impl std::fmt::Debug for Buffer {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Buffer")
            .field("label", &self.label)
            .field("size", &self.size)
            .field("usage", &self.usage)
            .field("location", &self.location)
            .field("address", &self.address)
            .finish()
    }
}

/// Maps a gpu-allocator error while allocating `what` (`bytes` long).
pub(crate) fn allocation_error(what: &str, bytes: u64, e: AllocationError) -> VkError {
    match e {
        AllocationError::OutOfMemory => VkError::OutOfDeviceMemory { what: what.into(), bytes },
        source => VkError::Allocator { what: what.into(), source },
    }
}

/// Maps a Vulkan error of an allocating call (`vkCreateBuffer`, `vkBindBufferMemory`).
fn allocating_call_error(call: &'static str, what: &str, bytes: u64, r: vk::Result) -> VkError {
    match r {
        vk::Result::ERROR_OUT_OF_DEVICE_MEMORY => VkError::OutOfDeviceMemory { what: what.into(), bytes },
        r => VkError::from_vk(call, r),
    }
}

impl Buffer {
    /// The Vulkan handle.
    pub fn raw(&self) -> vk::Buffer {
        self.raw
    }

    /// The label given at creation (also its debug name under validation).
    pub fn label(&self) -> &str {
        &self.label
    }

    /// Size in bytes, as asked for.
    pub fn size(&self) -> u64 {
        self.size
    }

    /// The usage flags it was created with.
    pub fn usage(&self) -> vk::BufferUsageFlags {
        self.usage
    }

    /// Where its memory was asked to live.
    pub fn location(&self) -> MemoryLocation {
        self.location
    }

    /// Its device address, for buffers created with `SHADER_DEVICE_ADDRESS` usage (shader
    /// binding tables, acceleration-structure inputs and storage).
    pub fn device_address(&self) -> Option<vk::DeviceAddress> {
        self.address
    }

    /// Whether the host can read and write it directly (mapped, host-coherent memory).
    pub fn is_host_visible(&self) -> bool {
        self.allocation.as_ref().is_some_and(|a| {
            a.mapped_ptr().is_some()
                && a.memory_properties().contains(vk::MemoryPropertyFlags::HOST_VISIBLE | vk::MemoryPropertyFlags::HOST_COHERENT)
        })
    }

    fn check_range(&self, offset: u64, len: u64) -> Result<std::ops::Range<usize>, VkError> {
        let end = offset.checked_add(len).filter(|&e| e <= self.size);
        match end {
            Some(end) => Ok(offset as usize..end as usize),
            None => Err(VkError::OutOfRange { what: self.label.clone(), offset, end: offset.saturating_add(len), size: self.size }),
        }
    }

    /// Copies `data` into the buffer at `offset` bytes, through the host mapping. Visible to
    /// work submitted afterwards (the memory is host-coherent and a queue submission orders
    /// earlier host writes).
    pub fn write(&mut self, offset: u64, data: &[u8]) -> Result<(), VkError> {
        let range = self.check_range(offset, data.len() as u64)?;
        if !self.is_host_visible() {
            return Err(VkError::NotHostVisible { what: self.label.clone() });
        }
        let slice = self.allocation.as_mut().and_then(|a| a.mapped_slice_mut());
        let slice = slice.ok_or_else(|| VkError::NotHostVisible { what: self.label.clone() })?;
        slice[range].copy_from_slice(data);
        Ok(())
    }

    /// Reads `len` bytes at `offset` through the host mapping. Device writes must have been
    /// made visible to the host (a submission that ends with a host-read barrier and was waited
    /// for, as [`VkContext::read_back`] does).
    pub fn read(&self, offset: u64, len: u64) -> Result<Vec<u8>, VkError> {
        let range = self.check_range(offset, len)?;
        if !self.is_host_visible() {
            return Err(VkError::NotHostVisible { what: self.label.clone() });
        }
        let slice = self.allocation.as_ref().and_then(|a| a.mapped_slice());
        let slice = slice.ok_or_else(|| VkError::NotHostVisible { what: self.label.clone() })?;
        Ok(slice[range].to_vec())
    }

    /// Destroys the buffer and frees its memory now, reporting a failure to free (dropping
    /// does the same and ignores the failure).
    pub fn destroy(mut self) -> Result<(), VkError> {
        self.release()
    }

    fn release(&mut self) -> Result<(), VkError> {
        let Some(allocation) = self.allocation.take() else { return Ok(()) };
        // SAFETY: the buffer is not in use (every submission is waited for) and was created on
        // this device; it is destroyed before its memory is freed.
        unsafe { self.shared.device.device.destroy_buffer(self.raw, None) };
        self.raw = vk::Buffer::null();
        lock(&self.shared.allocator).free(allocation).map_err(|e| allocation_error(&self.label, self.size, e))
    }
}

impl Drop for Buffer {
    fn drop(&mut self) {
        let _ = self.release();
    }
}

/// Bytes read back as `T`s (whole records; the host copy need not be aligned for `T`).
pub(crate) fn pod_vec<T: bytemuck::Pod>(bytes: &[u8]) -> Vec<T> {
    bytes.chunks_exact(size_of::<T>()).map(bytemuck::pod_read_unaligned).collect()
}

/// Unfinished one-time submission: frees its command buffer and fence however it ends.
struct OneShot<'a> {
    device: &'a ash::Device,
    pool: vk::CommandPool,
    cmd: vk::CommandBuffer,
    fence: vk::Fence,
}

impl Drop for OneShot<'_> {
    fn drop(&mut self) {
        // SAFETY: the command buffer is not pending (the fence was waited for, or it was never
        // submitted; after a device loss nothing is pending any more).
        unsafe {
            if self.fence != vk::Fence::null() {
                self.device.destroy_fence(self.fence, None);
            }
            self.device.free_command_buffers(self.pool, &[self.cmd]);
        }
    }
}

impl VkContext {
    /// Creates a buffer of `size` bytes with `usage`, its memory at `location` (gpu-allocator's
    /// choice of memory type). `label` names it in errors and, under validation, in messages.
    /// With `SHADER_DEVICE_ADDRESS` usage the buffer gets a device address.
    ///
    /// Errors: [`VkError::EmptyBuffer`] for size 0, [`VkError::BufferTooLarge`] above
    /// `maxBufferSize` or `maxMemoryAllocationSize`, [`VkError::OutOfDeviceMemory`] when the
    /// memory heap cannot hold it.
    pub fn create_buffer(&self, label: &str, size: u64, usage: vk::BufferUsageFlags, location: MemoryLocation) -> Result<Buffer, VkError> {
        let shared = &self.shared;
        let device = &shared.device.device;
        if size == 0 {
            return Err(VkError::EmptyBuffer { what: label.into() });
        }
        let limits = &shared.memory;
        if let Some(max) = limits.max_buffer_size.filter(|&m| size > m) {
            return Err(VkError::BufferTooLarge { what: label.into(), bytes: size, limit: "maxBufferSize", max });
        }
        if size > limits.max_memory_allocation_size {
            let max = limits.max_memory_allocation_size;
            return Err(VkError::BufferTooLarge { what: label.into(), bytes: size, limit: "maxMemoryAllocationSize", max });
        }
        let info = vk::BufferCreateInfo::default().size(size).usage(usage).sharing_mode(vk::SharingMode::EXCLUSIVE);
        // SAFETY: a valid create info (size > 0 and within the limits).
        let raw = unsafe { device.create_buffer(&info, None) }.map_err(|r| allocating_call_error("vkCreateBuffer", label, size, r))?;
        let destroy_raw = || {
            // SAFETY: the buffer is unused and unbound or its memory is freed after.
            unsafe { device.destroy_buffer(raw, None) }
        };
        // SAFETY: a valid buffer.
        let requirements = unsafe { device.get_buffer_memory_requirements(raw) };
        let allocation = lock(&shared.allocator).allocate(&AllocationCreateDesc {
            name: label,
            requirements,
            location,
            linear: true,
            allocation_scheme: AllocationScheme::GpuAllocatorManaged,
        });
        let allocation = match allocation {
            Ok(a) => a,
            Err(e) => {
                destroy_raw();
                return Err(allocation_error(label, size, e));
            }
        };
        // SAFETY: the allocation satisfies the buffer's requirements.
        let bound = unsafe { device.bind_buffer_memory(raw, allocation.memory(), allocation.offset()) };
        if let Err(r) = bound {
            destroy_raw();
            let _ = lock(&shared.allocator).free(allocation);
            return Err(allocating_call_error("vkBindBufferMemory", label, size, r));
        }
        let address = usage.contains(vk::BufferUsageFlags::SHADER_DEVICE_ADDRESS).then(|| {
            // SAFETY: the buffer is bound and has SHADER_DEVICE_ADDRESS usage; the device has
            // the bufferDeviceAddress feature.
            unsafe { device.get_buffer_device_address(&vk::BufferDeviceAddressInfo::default().buffer(raw)) }
        });
        if let Some(utils) = &shared.debug_utils
            && let Ok(name) = std::ffi::CString::new(label)
        {
            let name_info = vk::DebugUtilsObjectNameInfoEXT::default().object_handle(raw).object_name(&name);
            // SAFETY: a valid handle of this device; naming is best effort.
            let _ = unsafe { utils.set_debug_utils_object_name(&name_info) };
        }
        Ok(Buffer { shared: Arc::clone(shared), raw, allocation: Some(allocation), label: label.into(), size, usage, location, address })
    }

    /// Records commands with `record` into a fresh primary command buffer, submits it to the
    /// context's queue and waits until the device has finished it. Returns what `record`
    /// returns.
    ///
    /// Errors: [`VkError::DeviceLost`] when the device is lost during the submission or the
    /// wait; [`VkError::Vulkan`] for any other failing call.
    pub fn submit_and_wait<R>(&self, record: impl FnOnce(vk::CommandBuffer) -> R) -> Result<R, VkError> {
        let shared = &self.shared;
        let device = &shared.device.device;
        let submitter = lock(&shared.submitter);
        let alloc = vk::CommandBufferAllocateInfo::default()
            .command_pool(submitter.pool)
            .level(vk::CommandBufferLevel::PRIMARY)
            .command_buffer_count(1);
        // SAFETY: the pool is externally synchronised by the submitter lock.
        let cmd = unsafe { device.allocate_command_buffers(&alloc) }.vk("vkAllocateCommandBuffers")?[0];
        let mut shot = OneShot { device, pool: submitter.pool, cmd, fence: vk::Fence::null() };
        let begin = vk::CommandBufferBeginInfo::default().flags(vk::CommandBufferUsageFlags::ONE_TIME_SUBMIT);
        // SAFETY: a fresh command buffer, recorded under the submitter lock.
        unsafe { device.begin_command_buffer(cmd, &begin) }.vk("vkBeginCommandBuffer")?;
        // The submission's device time (crate::timing): a timestamp before the commands and
        // one after, in the pool only this lock's holder uses.
        let timestamps = submitter.timestamps.zip(shared.timestamps);
        if let Some((pool, _)) = timestamps {
            // SAFETY: a pool of two timestamp queries of this device, reset before it is
            // written; the queue family has timestamps (valid bits > 0).
            unsafe {
                device.cmd_reset_query_pool(cmd, pool, 0, 2);
                device.cmd_write_timestamp(cmd, vk::PipelineStageFlags::TOP_OF_PIPE, pool, 0);
            }
        }
        let out = record(cmd);
        if let Some((pool, _)) = timestamps {
            // SAFETY: as above.
            unsafe { device.cmd_write_timestamp(cmd, vk::PipelineStageFlags::BOTTOM_OF_PIPE, pool, 1) };
        }
        // SAFETY: as above.
        unsafe { device.end_command_buffer(cmd) }.vk("vkEndCommandBuffer")?;
        // SAFETY: a valid device.
        shot.fence = unsafe { device.create_fence(&vk::FenceCreateInfo::default(), None) }.vk("vkCreateFence")?;
        let cmds = [cmd];
        let submit = vk::SubmitInfo::default().command_buffers(&cmds);
        // SAFETY: the queue is externally synchronised by the submitter lock; the command buffer
        // is fully recorded.
        unsafe { device.queue_submit(submitter.queue, &[submit], shot.fence) }.vk("vkQueueSubmit")?;
        // SAFETY: the fence belongs to this device.
        unsafe { device.wait_for_fences(&[shot.fence], true, u64::MAX) }.vk("vkWaitForFences")?;
        let seconds = timestamps.and_then(|(pool, ts)| {
            let mut ticks = [0u64; 2];
            // SAFETY: both queries were written by the submission the fence says is done.
            let read = unsafe { device.get_query_pool_results(pool, 0, &mut ticks, vk::QueryResultFlags::TYPE_64 | vk::QueryResultFlags::WAIT) };
            read.ok().map(|()| ts.seconds(ticks[0], ticks[1]))
        });
        crate::timing::record(seconds);
        drop(shot);
        Ok(out)
    }

    /// Creates a buffer of `usage` (plus `TRANSFER_DST`) in device-local memory holding `data`,
    /// copied there through a host-visible staging buffer. Errors as
    /// [`VkContext::create_buffer`] and [`VkContext::submit_and_wait`].
    pub fn upload(&self, label: &str, data: &[u8], usage: vk::BufferUsageFlags) -> Result<Buffer, VkError> {
        let size = data.len() as u64;
        let buffer = self.create_buffer(label, size, usage | vk::BufferUsageFlags::TRANSFER_DST, MemoryLocation::GpuOnly)?;
        let mut staging =
            self.create_buffer(&format!("{label} (upload staging)"), size, vk::BufferUsageFlags::TRANSFER_SRC, MemoryLocation::CpuToGpu)?;
        staging.write(0, data)?;
        let device = self.device();
        self.submit_and_wait(|cmd| {
            let region = vk::BufferCopy::default().size(size);
            // SAFETY: both buffers are alive, large enough and have the transfer usages.
            unsafe { device.cmd_copy_buffer(cmd, staging.raw(), buffer.raw(), &[region]) };
        })?;
        staging.destroy()?;
        Ok(buffer)
    }

    /// Reads `len` bytes at `offset` of `buffer` (which needs `TRANSFER_SRC` usage) through a
    /// host-visible staging copy, after all work submitted so far. Errors as
    /// [`VkContext::create_buffer`] and [`VkContext::submit_and_wait`], and
    /// [`VkError::OutOfRange`] for a range outside the buffer.
    pub fn read_back(&self, buffer: &Buffer, offset: u64, len: u64) -> Result<Vec<u8>, VkError> {
        buffer.check_range(offset, len)?;
        if len == 0 {
            return Ok(Vec::new());
        }
        if !buffer.usage.contains(vk::BufferUsageFlags::TRANSFER_SRC) {
            return Err(VkError::MissingUsage { what: buffer.label.clone(), usage: "TRANSFER_SRC" });
        }
        let staging = self.create_buffer(
            &format!("{} (read-back staging)", buffer.label),
            len,
            vk::BufferUsageFlags::TRANSFER_DST,
            MemoryLocation::GpuToCpu,
        )?;
        let device = self.device();
        self.submit_and_wait(|cmd| {
            let region = vk::BufferCopy::default().src_offset(offset).size(len);
            let to_host =
                vk::MemoryBarrier::default().src_access_mask(vk::AccessFlags::TRANSFER_WRITE).dst_access_mask(vk::AccessFlags::HOST_READ);
            // SAFETY: both buffers are alive and have the transfer usages; the range is inside
            // the source (checked above).
            unsafe {
                device.cmd_copy_buffer(cmd, buffer.raw(), staging.raw(), &[region]);
                device.cmd_pipeline_barrier(
                    cmd,
                    vk::PipelineStageFlags::TRANSFER,
                    vk::PipelineStageFlags::HOST,
                    vk::DependencyFlags::empty(),
                    &[to_host],
                    &[],
                    &[],
                );
            }
        })?;
        let out = staging.read(0, len)?;
        staging.destroy()?;
        Ok(out)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn allocation_failures_become_out_of_device_memory() {
        let e = allocation_error("photons", 1 << 40, AllocationError::OutOfMemory);
        assert!(matches!(&e, VkError::OutOfDeviceMemory { what, bytes } if what == "photons" && *bytes == 1 << 40), "{e}");
        let e = allocating_call_error("vkCreateBuffer", "sbt", 64, vk::Result::ERROR_OUT_OF_DEVICE_MEMORY);
        assert!(matches!(&e, VkError::OutOfDeviceMemory { what, bytes: 64 } if what == "sbt"), "{e}");
        let e = allocating_call_error("vkBindBufferMemory", "sbt", 64, vk::Result::ERROR_DEVICE_LOST);
        assert!(matches!(e, VkError::DeviceLost { call: "vkBindBufferMemory" }));
        let e = allocation_error("x", 1, AllocationError::NoCompatibleMemoryTypeFound);
        assert!(matches!(e, VkError::Allocator { .. }) && e.to_string().contains("\"x\""), "{e}");
    }
}
