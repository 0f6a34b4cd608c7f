//! Device time per stage from timestamp queries ([`DeviceTimer`]).
//!
//! Every submission a stage makes goes through `GpuContext::submit`: with a timer, the
//! submission is framed by two command buffers that write a timestamp before and after
//! the stage's commands, into the next two slots of one query set. The slots and the stage
//! they belong to are kept on the host; once the iteration's accumulate is submitted, the
//! accumulate stage resolves the used slots and copies them into a mapped buffer in the
//! same wait ([`DeviceTimer::resolve`], [`DeviceTimer::read`]), and every stage's device time
//! is the sum of its submissions' `end − begin`, times the queue's timestamp period.
//!
//! The timer needs [`wgpu::Features::TIMESTAMP_QUERY`] and
//! [`wgpu::Features::TIMESTAMP_QUERY_INSIDE_ENCODERS`] (timestamps between the commands of an
//! encoder, as the acceleration-structure builds are not passes); `GpuContext::new`
//! requests them only where the adapter has both. Without them the stats say
//! [`DeviceTimes::Unavailable`].

use arpa_core::render::tracer::{DeviceTimes, Stage, StageTimes};
use std::sync::Mutex;
use std::sync::mpsc::Receiver;

/// Timestamp slots per iteration: two per timed submission. An iteration that makes more
/// timed submissions than this (hundreds of photon batches) reports its device time as
/// unavailable.
pub const TIMESTAMP_SLOTS: u32 = 1024;

/// Bytes of one resolved timestamp.
const TIMESTAMP_BYTES: u64 = 8;

/// The wgpu features the timer needs.
pub const TIMER_FEATURES: wgpu::Features = wgpu::Features::TIMESTAMP_QUERY.union(wgpu::Features::TIMESTAMP_QUERY_INSIDE_ENCODERS);

/// Timestamp query set, resolve and read-back buffers, and the slots of the iteration in
/// progress.
pub struct DeviceTimer {
    set: wgpu::QuerySet,
    resolve: wgpu::Buffer,
    readback: wgpu::Buffer,
    /// Nanoseconds per timestamp tick ([`wgpu::Queue::get_timestamp_period`]).
    period_ns: f64,
    state: Mutex<Slots>,
}

/// The iteration's timed submissions.
#[derive(Default)]
struct Slots {
    /// The stage whose submissions are being timed (`None`: submissions are not timed).
    stage: Option<Stage>,
    /// Iteration whose slots these are.
    iteration: u32,
    /// Next free slot.
    next: u32,
    /// Per timed submission, its stage and its first slot (the end is the next one).
    pairs: Vec<(Stage, u32)>,
    /// A submission of the iteration found no free slot: its device time is unknown.
    lost: bool,
}

/// A read-back of the iteration's timestamps, submitted and being mapped.
pub struct Pending {
    pairs: Vec<(Stage, u32)>,
    slots: u32,
    lost: bool,
    mapped: Receiver<Result<(), wgpu::BufferAsyncError>>,
}

fn lock(m: &Mutex<Slots>) -> std::sync::MutexGuard<'_, Slots> {
    m.lock().unwrap_or_else(|e| e.into_inner())
}

impl DeviceTimer {
    /// A timer on `device` (which must have [`TIMER_FEATURES`]); `period_ns` is the queue's
    /// nanoseconds per tick.
    pub fn new(device: &wgpu::Device, period_ns: f32) -> Self {
        let bytes = u64::from(TIMESTAMP_SLOTS) * TIMESTAMP_BYTES;
        let set = device.create_query_set(&wgpu::QuerySetDescriptor { label: Some("arpa stage timestamps"), ty: wgpu::QueryType::Timestamp, count: TIMESTAMP_SLOTS });
        let buffer = |label, usage| device.create_buffer(&wgpu::BufferDescriptor { label: Some(label), size: bytes, usage, mapped_at_creation: false });
        let resolve = buffer("arpa timestamp resolve", wgpu::BufferUsages::QUERY_RESOLVE | wgpu::BufferUsages::COPY_SRC);
        let readback = buffer("arpa timestamp read-back", wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST);
        Self { set, resolve, readback, period_ns: f64::from(period_ns), state: Mutex::new(Slots::default()) }
    }

    /// Times the submissions from now on as `stage` of `iteration`. The first stage of a new
    /// iteration drops the previous iteration's slots; a stage run again in the same
    /// iteration drops its earlier submissions (as the host time keeps the last run).
    pub fn begin_stage(&self, stage: Stage, iteration: u32) {
        let mut s = lock(&self.state);
        if s.iteration != iteration {
            *s = Slots { iteration, ..Slots::default() };
        }
        s.pairs.retain(|&(st, _)| st != stage);
        s.stage = Some(stage);
    }

    /// Stops timing submissions (the stage has ended).
    pub fn end_stage(&self) {
        lock(&self.state).stage = None;
    }

    /// Submits `commands`, framed by timestamps when a stage is being timed.
    pub(crate) fn submit(&self, device: &wgpu::Device, queue: &wgpu::Queue, commands: wgpu::CommandBuffer) {
        let mut s = lock(&self.state);
        let Some(stage) = s.stage else {
            queue.submit([commands]);
            return;
        };
        if s.next + 2 > TIMESTAMP_SLOTS {
            s.lost = true;
            queue.submit([commands]);
            return;
        }
        let first = s.next;
        let stamp = |slot: u32| {
            let mut e = device.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some("arpa timestamp") });
            e.write_timestamp(&self.set, slot);
            e.finish()
        };
        queue.submit([stamp(first), commands, stamp(first + 1)]);
        s.pairs.push((stage, first));
        s.next = first + 2;
    }

    /// Submits the copy of the iteration's timestamps into the read-back buffer and starts
    /// mapping it; the caller's next wait completes it ([`DeviceTimer::read`]). Call after the
    /// iteration's last timed submission.
    pub fn resolve(&self, device: &wgpu::Device, queue: &wgpu::Queue) -> Pending {
        let mut s = lock(&self.state);
        let slots = s.next;
        let (tx, rx) = std::sync::mpsc::channel();
        if slots > 0 {
            let mut e = device.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some("arpa timestamp resolve") });
            e.resolve_query_set(&self.set, 0..slots, &self.resolve, 0);
            e.copy_buffer_to_buffer(&self.resolve, 0, &self.readback, 0, u64::from(slots) * TIMESTAMP_BYTES);
            queue.submit([e.finish()]);
            self.readback.map_async(wgpu::MapMode::Read, ..u64::from(slots) * TIMESTAMP_BYTES, move |r| {
                let _ = tx.send(r);
            });
        } else {
            let _ = tx.send(Ok(()));
        }
        let pending = Pending { pairs: std::mem::take(&mut s.pairs), slots, lost: s.lost, mapped: rx };
        let iteration = s.iteration;
        *s = Slots { iteration, ..Slots::default() };
        pending
    }

    /// The iteration's device time per stage from a resolved read-back, after the wait
    /// that completes its mapping. A lost slot or a pair whose end precedes its begin (a
    /// wrapped counter) gives [`DeviceTimes::Unavailable`].
    /// An error is the read-back's message (the tracer names the stage).
    pub fn read(&self, pending: Pending) -> Result<DeviceTimes, String> {
        if pending.slots == 0 {
            return Ok(if pending.lost { DeviceTimes::Unavailable } else { DeviceTimes::Measured(StageTimes::default()) });
        }
        let fail = |message: String| message;
        pending.mapped.recv().map_err(|e| fail(e.to_string()))?.map_err(|e| fail(e.to_string()))?;
        let ticks: Vec<u64> = {
            let view = self.readback.get_mapped_range(..u64::from(pending.slots) * TIMESTAMP_BYTES).map_err(|e| fail(e.to_string()))?;
            view.chunks_exact(8).map(|c| u64::from_le_bytes(c.try_into().unwrap_or([0; 8]))).collect()
        };
        self.readback.unmap();
        Ok(stage_times(&pending.pairs, &ticks, self.period_ns, pending.lost))
    }
}

/// Sums `end − begin` of every pair into its stage (seconds); `Unavailable` when a slot
/// was lost, a pair is out of order, or the result is not finite.
pub fn stage_times(pairs: &[(Stage, u32)], ticks: &[u64], period_ns: f64, lost: bool) -> DeviceTimes {
    if lost || !(period_ns.is_finite() && period_ns > 0.0) {
        return DeviceTimes::Unavailable;
    }
    let mut times = StageTimes::default();
    for &(stage, first) in pairs {
        let (Some(&begin), Some(&end)) = (ticks.get(first as usize), ticks.get(first as usize + 1)) else {
            return DeviceTimes::Unavailable;
        };
        let (Some(ticks), Some(t)) = (end.checked_sub(begin), times.of_mut(stage)) else {
            return DeviceTimes::Unavailable;
        };
        *t += ticks as f64 * period_ns * 1e-9;
    }
    if [times.camera, times.photon, times.build, times.gather, times.accumulate].iter().all(|v| v.is_finite()) {
        DeviceTimes::Measured(times)
    } else {
        DeviceTimes::Unavailable
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pairs_sum_into_their_stages_and_bad_pairs_are_unavailable() {
        let pairs = [(Stage::CameraPass, 0), (Stage::PhotonPass, 2), (Stage::PhotonPass, 4)];
        let ticks = [10, 30, 30, 40, 50, 100];
        let DeviceTimes::Measured(t) = stage_times(&pairs, &ticks, 2.0, false) else { panic!("not measured") };
        assert!((t.camera - 40e-9).abs() < 1e-18 && (t.photon - 120e-9).abs() < 1e-18 && t.gather == 0.0, "{t:?}");
        assert_eq!(stage_times(&pairs, &[10, 5, 30, 40, 50, 100], 1.0, false), DeviceTimes::Unavailable, "end before begin");
        assert_eq!(stage_times(&pairs, &ticks[..5], 1.0, false), DeviceTimes::Unavailable, "a missing slot");
        assert_eq!(stage_times(&pairs, &ticks, 1.0, true), DeviceTimes::Unavailable, "a lost submission");
        assert_eq!(stage_times(&pairs, &ticks, 0.0, false), DeviceTimes::Unavailable, "no period");
        assert_eq!(stage_times(&[(Stage::UploadScene, 0)], &ticks, 1.0, false), DeviceTimes::Unavailable, "not a stage of an iteration");
    }
}
