//! Buffers (a `VkBuffer` bound to gpu-allocator memory), host access, staged uploads and
//! read-backs, and one-time command submissions.
//!
//! **Ownership.** A [`Buffer`] holds a reference-counted handle on its context's device and
//! allocator, so it can free itself on drop (or through [`Buffer::destroy`], which reports a
//! failure to free) and the device can never be destroyed before it.
//!
//! **Submissions in flight.** [`VkContext::submit`] returns without waiting; what the
//! submission uses and nobody else keeps (parameters, descriptor sets, scratch) goes into
//! its [`KeepAlive`] and is released once a later wait ([`VkContext::finish`], which
//! [`VkContext::submit_and_wait`] and every read-back make) finds it done. Dropping a
//! buffer, a descriptor set or an acceleration structure while any submission is in flight
//! first waits for them all, so safe code can never free what the device may still use;
//! the stages keep what their submissions need alive so that this costs no wait in an
//! iteration.

use crate::device::{Shared, VkContext, lock};
pub use crate::submission::{KeepAlive, Submission};
use crate::submission::InFlight;
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
        settle(&self.shared);
        // SAFETY: the buffer is not in use (no submission is in flight after `settle`) and was
        // created on this device; it is destroyed before its memory is freed.
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

/// A submission being recorded: frees its command buffer, fence and queries if it fails
/// before it is submitted.
struct OneShot<'a> {
    device: &'a ash::Device,
    pool: vk::CommandPool,
    cmd: vk::CommandBuffer,
    fence: vk::Fence,
    queries: Option<vk::QueryPool>,
}

impl Drop for OneShot<'_> {
    fn drop(&mut self) {
        // SAFETY: the command buffer was never submitted (a submitted one is disarmed by
        // nulling its handles); the pool is guarded by the submitter lock its creator holds.
        unsafe {
            if self.fence != vk::Fence::null() {
                self.device.destroy_fence(self.fence, None);
            }
            if let Some(q) = self.queries {
                self.device.destroy_query_pool(q, None);
            }
            if self.cmd != vk::CommandBuffer::null() {
                self.device.free_command_buffers(self.pool, &[self.cmd]);
            }
        }
    }
}

/// Waits for every submission in flight on `shared` and releases them (their timestamps
/// into their stages, their fences, queries and what they kept); nothing to do when none is.
/// Errors are those of `vkWaitForFences` (a lost device); the submissions then stay listed.
pub(crate) fn settle_checked(shared: &Shared) -> Result<(), VkError> {
    let device = &shared.device.device;
    let done: Vec<InFlight> = {
        let mut in_flight = lock(&shared.in_flight);
        if in_flight.is_empty() {
            return Ok(());
        }
        let fences: Vec<vk::Fence> = in_flight.iter().map(|f| f.fence).collect();
        // SAFETY: fences of this device, each submitted with its command buffer.
        unsafe { device.wait_for_fences(&fences, true, u64::MAX) }.vk("vkWaitForFences")?;
        std::mem::take(&mut *in_flight)
    };
    let mut spent = Vec::with_capacity(done.len());
    for f in done {
        let seconds = f.queries.zip(shared.timestamps).and_then(|(pool, ts)| {
            let mut ticks = [0u64; 2];
            // SAFETY: both queries were written by the submission its fence says is done.
            let read = unsafe { device.get_query_pool_results(pool, 0, &mut ticks, vk::QueryResultFlags::TYPE_64 | vk::QueryResultFlags::WAIT) };
            read.ok().map(|()| ts.seconds(ticks[0], ticks[1]))
        });
        crate::timing::record(f.ticket.as_ref(), seconds);
        spent.push(f.cmd);
        // What it kept goes now, outside every lock (a buffer's drop settles again: a no-op).
        f.discard(device);
    }
    // The command pool needs the submitter lock: the next submission frees them.
    lock(&shared.spent).extend(spent);
    Ok(())
}

/// [`settle_checked`] for drops, which cannot report: on a lost device nothing runs any more.
pub(crate) fn settle(shared: &Shared) {
    let _ = settle_checked(shared);
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
    /// context's queue and waits until the device has finished it and every submission
    /// before it ([`VkContext::submit`], [`VkContext::finish`]). Returns what `record`
    /// returns.
    ///
    /// Errors: [`VkError::DeviceLost`] when the device is lost during the submission or the
    /// wait; [`VkError::Vulkan`] for any other failing call.
    pub fn submit_and_wait<R>(&self, record: impl FnOnce(vk::CommandBuffer) -> R) -> Result<R, VkError> {
        let (out, _) = self.submit(KeepAlive::new(), record)?;
        self.finish()?;
        Ok(out)
    }

    /// Records commands with `record` into a fresh primary command buffer and submits it to
    /// the context's queue without waiting; `keep` stays alive until a later wait
    /// ([`VkContext::finish`]) finds the submission done. The command buffer starts with a
    /// global memory barrier, so every earlier submission's writes are visible to its
    /// commands (submissions in flight run in queue order); host writes made before the
    /// call are visible to it (queue submission), and commands whose results the host reads
    /// after [`VkContext::finish`] must end with a barrier to the host stage. Where the queue
    /// family has timestamps, two framing timestamps time it into the stage the calling
    /// thread is in ([`crate::timing`]).
    ///
    /// Host-visible memory the submission reads must not be written by the host until it
    /// is done.
    ///
    /// Errors: [`VkError::DeviceLost`] when the device is lost; [`VkError::Vulkan`] for any
    /// other failing call (then nothing was submitted).
    pub fn submit<R>(&self, keep: KeepAlive, record: impl FnOnce(vk::CommandBuffer) -> R) -> Result<(R, Submission), VkError> {
        let shared = &self.shared;
        let device = &shared.device.device;
        let submitter = lock(&shared.submitter);
        let spent = std::mem::take(&mut *lock(&shared.spent));
        if !spent.is_empty() {
            // SAFETY: command buffers of retired submissions, from this pool, guarded by the
            // submitter lock.
            unsafe { device.free_command_buffers(submitter.pool, &spent) };
        }
        let alloc = vk::CommandBufferAllocateInfo::default()
            .command_pool(submitter.pool)
            .level(vk::CommandBufferLevel::PRIMARY)
            .command_buffer_count(1);
        // SAFETY: the pool is externally synchronised by the submitter lock.
        let cmd = unsafe { device.allocate_command_buffers(&alloc) }.vk("vkAllocateCommandBuffers")?[0];
        let mut shot = OneShot { device, pool: submitter.pool, cmd, fence: vk::Fence::null(), queries: None };
        let begin = vk::CommandBufferBeginInfo::default().flags(vk::CommandBufferUsageFlags::ONE_TIME_SUBMIT);
        // SAFETY: a fresh command buffer, recorded under the submitter lock.
        unsafe { device.begin_command_buffer(cmd, &begin) }.vk("vkBeginCommandBuffer")?;
        let earlier = vk::MemoryBarrier::default()
            .src_access_mask(vk::AccessFlags::MEMORY_WRITE)
            .dst_access_mask(vk::AccessFlags::MEMORY_READ | vk::AccessFlags::MEMORY_WRITE);
        // SAFETY: a plain barrier in a recording command buffer.
        unsafe {
            device.cmd_pipeline_barrier(
                cmd,
                vk::PipelineStageFlags::ALL_COMMANDS,
                vk::PipelineStageFlags::ALL_COMMANDS,
                vk::DependencyFlags::empty(),
                &[earlier],
                &[],
                &[],
            );
        }
        // The submission's device time (crate::timing): a timestamp before the commands and
        // one after, in a two-query pool of its own (the submission may still run when the
        // next one is recorded). Without a pool the submission goes untimed.
        shot.queries = shared.timestamps.and_then(|_| {
            let info = vk::QueryPoolCreateInfo::default().query_type(vk::QueryType::TIMESTAMP).query_count(2);
            // SAFETY: a valid device; the pool is destroyed when the submission retires.
            unsafe { device.create_query_pool(&info, None) }.ok()
        });
        if let Some(pool) = shot.queries {
            // SAFETY: a fresh pool of two timestamp queries, reset before it is written; the
            // queue family has timestamps (valid bits > 0).
            unsafe {
                device.cmd_reset_query_pool(cmd, pool, 0, 2);
                device.cmd_write_timestamp(cmd, vk::PipelineStageFlags::TOP_OF_PIPE, pool, 0);
            }
        }
        let out = record(cmd);
        if let Some(pool) = shot.queries {
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
        let serial = Submission::new(shared.submissions.fetch_add(1, std::sync::atomic::Ordering::Relaxed));
        let entry = InFlight { serial, cmd, fence: shot.fence, queries: shot.queries.take(), ticket: crate::timing::current(), keep };
        shot.cmd = vk::CommandBuffer::null();
        shot.fence = vk::Fence::null();
        lock(&shared.in_flight).push(entry);
        drop(submitter);
        Ok((out, serial))
    }

    /// Waits for `submission` (and with it every submission in flight,
    /// [`VkContext::finish`]) unless it has been waited for already, which costs nothing.
    ///
    /// Errors: as [`VkContext::finish`].
    pub fn wait_for(&self, submission: Submission) -> Result<(), VkError> {
        let pending = lock(&self.shared.in_flight).iter().any(|f| f.serial <= submission);
        if pending { self.finish() } else { Ok(()) }
    }

    /// Submissions made and not waited for yet ([`VkContext::submit`]; another thread's
    /// wait may retire them at any time).
    pub fn in_flight(&self) -> usize {
        lock(&self.shared.in_flight).len()
    }

    /// Waits until the device has finished every submission made so far and releases what
    /// they kept (their device times go to their stages, [`crate::timing`]).
    ///
    /// Errors: [`VkError::DeviceLost`] when the device is lost during the wait.
    pub fn finish(&self) -> Result<(), VkError> {
        settle_checked(&self.shared)
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
