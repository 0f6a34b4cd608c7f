//! What a submission carries until a wait retires it ([`crate::VkContext::submit`]): its
//! number, what it keeps alive, and its in-flight record. Both the context, which lists the
//! submissions in flight, and the buffers, which submit and retire them, use these; this
//! module uses neither.

use crate::timing::StageTicket;
use ash::vk;

/// What a submission keeps alive until the device has finished it
/// ([`crate::VkContext::submit`]): buffers, descriptor sets, structures its commands use
/// that no one else owns.
pub type KeepAlive = Vec<Box<dyn std::any::Any + Send>>;

/// A submission made by [`crate::VkContext::submit`], for
/// [`crate::VkContext::wait_for`]: numbered in submission order per context.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
pub struct Submission(u64);

impl Submission {
    /// The `n`-th submission of a context (from 0).
    pub(crate) fn new(n: u64) -> Self {
        Self(n)
    }
}

/// A submission not yet waited for: its command buffer, fence and timestamp queries, the
/// stage its device time belongs to, and what it keeps alive.
pub(crate) struct InFlight {
    pub(crate) serial: Submission,
    pub(crate) cmd: vk::CommandBuffer,
    pub(crate) fence: vk::Fence,
    pub(crate) queries: Option<vk::QueryPool>,
    pub(crate) ticket: Option<StageTicket>,
    pub(crate) keep: KeepAlive,
}

impl InFlight {
    /// Destroys the fence and queries of a submission that has completed (the context is
    /// going: its command buffer goes with the pool) and drops what it kept.
    pub(crate) fn discard(self, device: &ash::Device) {
        // SAFETY: the device is idle (the caller waited for it).
        unsafe {
            if let Some(q) = self.queries {
                device.destroy_query_pool(q, None);
            }
            device.destroy_fence(self.fence, None);
        }
        drop(self.keep);
    }
}

