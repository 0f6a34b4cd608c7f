//! Device time of the submissions a thread makes, from timestamp queries.
//!
//! Every submission goes through [`crate::VkContext::submit_and_wait`]. Where the context's queue
//! family has timestamps ([`Timestamps`]: `timestampValidBits` > 0, `timestampPeriod` > 0,
//! both queried from the adapter), the command buffer starts by resetting a two-query pool
//! and writing a timestamp at the top of the pipe, and ends with one at the bottom; after the
//! fence wait (which the submission does anyway) both are read without another wait, and
//! `(end − begin) mod 2^validBits` ticks times the period is added to this thread's
//! [`DeviceClock`]. A stage's device time is the clock's difference across the stage
//! ([`DeviceClock::since`]): a tracer's stage calls run on the thread that calls them, so
//! tracers on other threads sharing the context do not mix in.

use std::cell::Cell;

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

/// Device time this thread's submissions took so far.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct DeviceClock {
    /// Seconds of device time of the timed submissions.
    pub seconds: f64,
    /// Submissions without a time (no timestamps on the queue, or a failed read).
    pub untimed: u64,
}

impl DeviceClock {
    /// This thread's clock now.
    pub fn now() -> Self {
        CLOCK.with(Cell::get)
    }

    /// Device seconds of this thread's submissions since `earlier`; `None` when one of
    /// them has no time.
    pub fn since(&self, earlier: &DeviceClock) -> Option<f64> {
        (self.untimed == earlier.untimed).then_some((self.seconds - earlier.seconds).max(0.0))
    }
}

thread_local! {
    static CLOCK: Cell<DeviceClock> = const { Cell::new(DeviceClock { seconds: 0.0, untimed: 0 }) };
}

/// Adds one submission's device time (`None`: not timed) to this thread's clock.
pub(crate) fn record(seconds: Option<f64>) {
    CLOCK.with(|c| {
        let mut v = c.get();
        match seconds.filter(|s| s.is_finite()) {
            Some(s) => v.seconds += s,
            None => v.untimed += 1,
        }
        c.set(v);
    });
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
    fn a_clock_difference_is_unavailable_once_a_submission_was_untimed() {
        let start = DeviceClock::now();
        record(Some(0.5));
        assert_eq!(DeviceClock::now().since(&start), Some(0.5));
        record(None);
        assert_eq!(DeviceClock::now().since(&start), None);
    }
}
