//! Device time of the submissions a thread makes, from timestamp queries.
//!
//! Every submission goes through [`crate::VkContext::submit`]. Where the context's queue
//! family has timestamps ([`Timestamps`]: `timestampValidBits` > 0, `timestampPeriod` > 0,
//! both queried from the adapter), the command buffer starts by resetting a two-query pool
//! of its own and writing a timestamp at the top of the pipe, and ends with one at the
//! bottom. The submission need not be waited for: when a later wait finds it done
//! ([`crate::VkContext::finish`]), both are read without another wait and
//! `(end − begin) mod 2^validBits` ticks times the period is added to the stage it was made
//! in ([`StageLedger`], through the [`StageTicket`] it took from the [`StageScope`] open on
//! the submitting thread): a tracer's stage calls run on the thread that calls them, so
//! tracers on other threads sharing the context do not mix in.

use arpa_core::render::tracer::{DeviceTimes, Stage, StageTimes};
use std::cell::RefCell;
use std::sync::{Arc, Mutex};

/// What the adapter says about timestamps on the context's queue family.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Timestamps {
    /// `timestampValidBits` of the queue family (1 to 64).
    pub valid_bits: u32,
    /// `timestampPeriod`: nanoseconds per tick.
    pub period_ns: f32,
}

impl Timestamps {
    /// The queue family's timestamps, or `None` when it has none (`valid_bits` 0) or the
    /// period is not a positive finite number.
    pub fn new(valid_bits: u32, period_ns: f32) -> Option<Self> {
        ((1..=64).contains(&valid_bits) && period_ns.is_finite() && period_ns > 0.0).then_some(Self { valid_bits, period_ns })
    }

    /// Seconds between two raw timestamps (`end` after `begin`, modulo the valid bits).
    pub fn seconds(&self, begin: u64, end: u64) -> f64 {
        let mask = if self.valid_bits >= 64 { u64::MAX } else { (1u64 << self.valid_bits) - 1 };
        let ticks = end.wrapping_sub(begin) & mask;
        ticks as f64 * f64::from(self.period_ns) * 1e-9
    }
}

/// Device time per stage of one tracer's iteration, filled in as the stage's submissions
/// retire (when a later wait finds them done, [`crate::VkContext::finish`]).
///
/// A tracer opens a [`StageScope`] around each stage call; every submission made on that
/// thread inside the scope carries a [`StageTicket`] and adds its time to the stage when it
/// retires, whichever stage is running by then. Running a stage again drops its earlier
/// run's time, including that of submissions still in flight (their tickets are of an
/// older generation); a new iteration drops every stage's.
#[derive(Debug, Default)]
pub struct StageLedger {
    state: Mutex<Ledger>,
}

#[derive(Debug, Default)]
struct Ledger {
    iteration: u32,
    /// Per stage (camera, photon, build, gather, accumulate), the run its time belongs to.
    generation: [u64; 5],
    seconds: StageTimes,
    /// A submission of this iteration had no time.
    untimed: bool,
}

/// Position of `stage` in [`Ledger::generation`]; `None` for the upload.
fn slot(stage: Stage) -> Option<usize> {
    match stage {
        Stage::UploadScene => None,
        Stage::CameraPass => Some(0),
        Stage::PhotonPass => Some(1),
        Stage::BuildAccelerationStructure => Some(2),
        Stage::Gather => Some(3),
        Stage::Accumulate => Some(4),
    }
}

/// The stage a submission's device time belongs to (see [`StageLedger`]).
#[derive(Clone, Debug)]
pub struct StageTicket {
    ledger: Arc<StageLedger>,
    stage: Stage,
    generation: u64,
}

fn lock_ledger(m: &Mutex<Ledger>) -> std::sync::MutexGuard<'_, Ledger> {
    m.lock().unwrap_or_else(|e| e.into_inner())
}

impl StageLedger {
    /// Starts `stage` of `iteration`: a new iteration clears every stage; the stage's earlier
    /// time in this iteration is dropped. Returns the run's generation.
    fn begin(&self, stage: Stage, iteration: u32) -> Option<u64> {
        let i = slot(stage)?;
        let mut l = lock_ledger(&self.state);
        if l.iteration != iteration {
            let generation = l.generation.map(|g| g + 1);
            *l = Ledger { iteration, generation, ..Ledger::default() };
        }
        l.generation[i] += 1;
        if let Some(t) = l.seconds.of_mut(stage) {
            *t = 0.0;
        }
        Some(l.generation[i])
    }

    /// Adds one retired submission's time (`None`: it had none) to its stage, unless the
    /// stage has run again since.
    fn add(&self, stage: Stage, generation: u64, seconds: Option<f64>) {
        let Some(i) = slot(stage) else { return };
        let mut l = lock_ledger(&self.state);
        if l.generation[i] != generation {
            return;
        }
        match seconds.filter(|s| s.is_finite()) {
            Some(s) => {
                if let Some(t) = l.seconds.of_mut(stage) {
                    *t += s;
                }
            }
            None => l.untimed = true,
        }
    }

    /// The device time of the iteration's stages so far (every submission retired counts):
    /// [`DeviceTimes::Unavailable`] once one of them had no time.
    pub fn times(&self) -> DeviceTimes {
        let l = lock_ledger(&self.state);
        if l.untimed { DeviceTimes::Unavailable } else { DeviceTimes::Measured(l.seconds) }
    }
}

thread_local! {
    static CURRENT: RefCell<Option<StageTicket>> = const { RefCell::new(None) };
}

/// While alive, the submissions this thread makes are timed into one stage of a
/// [`StageLedger`] ([`StageScope::enter`]).
pub struct StageScope {
    previous: Option<StageTicket>,
}

impl StageScope {
    /// Times this thread's submissions into `stage` of `iteration` on `ledger` until the
    /// scope is dropped (the stage's earlier time in this iteration is dropped).
    pub fn enter(ledger: &Arc<StageLedger>, stage: Stage, iteration: u32) -> Self {
        let ticket = ledger.begin(stage, iteration).map(|generation| StageTicket { ledger: Arc::clone(ledger), stage, generation });
        Self { previous: CURRENT.with(|c| c.replace(ticket)) }
    }
}

impl Drop for StageScope {
    fn drop(&mut self) {
        let previous = self.previous.take();
        CURRENT.with(|c| *c.borrow_mut() = previous);
    }
}

/// The ticket of a submission made now on this thread (`None` outside a [`StageScope`]).
pub(crate) fn current() -> Option<StageTicket> {
    CURRENT.with(|c| c.borrow().clone())
}

/// Adds a retired submission's device time (`None`: not timed) to the stage of its ticket.
pub(crate) fn record(ticket: Option<&StageTicket>, seconds: Option<f64>) {
    if let Some(t) = ticket {
        t.ledger.add(t.stage, t.generation, seconds);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ticks_wrap_at_the_valid_bits_and_scale_by_the_period() {
        let t = Timestamps::new(36, 2.0).unwrap();
        assert_eq!(t.seconds(10, 30), 40e-9);
        // The counter wrapped between the two: 2^36 − 5 → 3 is 8 ticks.
        assert_eq!(t.seconds((1 << 36) - 5, 3), 16e-9);
        assert_eq!(Timestamps::new(64, 1.0).unwrap().seconds(u64::MAX, 1), 2e-9);
        assert!(Timestamps::new(0, 1.0).is_none() && Timestamps::new(64, 0.0).is_none() && Timestamps::new(65, 1.0).is_none());
    }

    #[test]
    fn submissions_add_to_the_stage_they_were_made_in() {
        let ledger = Arc::new(StageLedger::default());
        let camera = {
            let _s = StageScope::enter(&ledger, Stage::CameraPass, 0);
            current()
        };
        assert!(current().is_none(), "the scope ended");
        let gather = {
            let _s = StageScope::enter(&ledger, Stage::Gather, 0);
            current()
        };
        // Retired later, in another stage's wait: each time goes to its own stage.
        record(camera.as_ref(), Some(0.25));
        record(gather.as_ref(), Some(0.5));
        let DeviceTimes::Measured(t) = ledger.times() else { panic!("{:?}", ledger.times()) };
        assert_eq!((t.camera, t.gather, t.photon), (0.25, 0.5, 0.0));
        // The gather runs again: the earlier run's late submission no longer counts.
        let again = {
            let _s = StageScope::enter(&ledger, Stage::Gather, 0);
            current()
        };
        record(gather.as_ref(), Some(1.0));
        record(again.as_ref(), Some(0.125));
        let DeviceTimes::Measured(t) = ledger.times() else { panic!() };
        assert_eq!((t.camera, t.gather), (0.25, 0.125));
        // An untimed submission makes the iteration's times unavailable; a new iteration
        // starts clean.
        record(again.as_ref(), None);
        assert_eq!(ledger.times(), DeviceTimes::Unavailable);
        let next = {
            let _s = StageScope::enter(&ledger, Stage::CameraPass, 1);
            current()
        };
        record(camera.as_ref(), Some(2.0));
        record(next.as_ref(), Some(0.5));
        let DeviceTimes::Measured(t) = ledger.times() else { panic!() };
        assert_eq!((t.camera, t.gather), (0.5, 0.0));
    }
}
