//! The photon-batch policy of the GPU backends: how an iteration whose stored records need
//! more than one storage binding of the device holds is traced in batches, as functions of
//! numbers only (the backends supply the binding limit and the counts they read back).
//!
//! A *batch* is a contiguous range of the iteration's global photon indices: with `B`
//! photons per batch, batch `k` traces `[k·B, (k+1)·B)` ([`batch_range`]) with exactly the
//! random streams, emitters and record keys of one pass over the iteration (the flux is
//! normalised by the iteration's photon count at emission), so the batches' records are,
//! together, the iteration's. Each batch is stored, sorted and gathered on its own, and the
//! gather sums each pixel's irradiance over the batches in batch order
//! ([`crate::gpu::layout::GatherBatch`]): the estimate is a sum over records, so this is
//! the one-pass estimate up to the order of the `f32` additions.
//!
//! `B` starts at the iteration's photon count (one batch). The photon pass's append buffers
//! start at [`INITIAL_RECORDS_PER_PHOTON`] records per photon of a batch and grow
//! ([`grow`]) when a batch overflows them, within what one binding holds
//! ([`RecordLimits`]); the batch is then traced again with the same random streams, so the
//! iteration is the one a large enough buffer gives. When a batch's records exceed what one
//! binding holds, `B` shrinks ([`shrink`]) and the iteration is traced again from batch 0;
//! `B` only shrinks during a render, so a render repeated on the same device takes the same
//! batches.
//!
//! # Capacities and the iteration without waits
//! The sort and the acceleration structures run over the buffers' whole capacity (empty
//! slots sorted last, with inactive boxes: [`crate::base::aabb::inactive_point`]), so an
//! iteration needs no count on the host before its accumulate. The acceleration structure
//! over a capacity depends on it (the gather's `f32` sums follow its traversal order), so
//! the capacity an iteration runs with is a function of the render, not of its history: at
//! upload, a *calibration* traces iteration 0's photon pass (growing and splitting as
//! above) and sets each append buffer to [`calibrated_capacity`] of the most records a
//! batch appended, and the sorted progressive photons to [`calibrated_sorted_photons`]. An iteration whose photon pass overflows those is found at its accumulate,
//! traced again with grown buffers, and the next iteration returns to the calibrated ones;
//! checkpoints resumed at any iteration therefore run with the same capacities.

use core::ops::Range;

use crate::gpu::layout::{KeyedFootprint, KeyedPhoton};
use crate::store::progressive_photon::PackedPhoton;

/// Stored records per photon of a batch the photon pass's append buffers start with (each
/// buffer).
pub const INITIAL_RECORDS_PER_PHOTON: u32 = 2;

/// The share of a batch that would have fitted one binding that the next `B` takes
/// ([`shrink`]): a margin for the next batches' different record counts.
pub const SHRINK_MARGIN: f64 = 0.9;

/// Batches of an iteration of `photons` photons with `batch` photons per batch (at least
/// one, also for no photons).
pub fn batch_count(photons: u32, batch: u32) -> u32 {
    photons.div_ceil(batch.max(1)).max(1)
}

/// Global photon indices of batch `k` of an iteration of `photons` photons with `batch`
/// photons per batch (empty beyond the last batch).
pub fn batch_range(photons: u32, batch: u32, k: u32) -> Range<u32> {
    let n = photons as u64;
    let start = (k as u64 * batch as u64).min(n);
    start as u32..(start + batch as u64).min(n) as u32
}

/// `B` for a batch of `photons` photons whose records needed `1 / fits` times what one
/// binding holds (`fits < 1`): [`SHRINK_MARGIN`] of the share that would have fitted,
/// strictly fewer photons, at least 1.
pub fn shrink(photons: u32, fits: f64) -> u32 {
    ((photons as f64 * fits * SHRINK_MARGIN) as u32).clamp(1, photons.saturating_sub(1).max(1))
}

/// The capacity of an append buffer of `capacity` records after a batch attempted
/// `appends` appends: unchanged if they fitted, else 1.25× the appends and at least
/// double, at most `max`.
pub fn grow(appends: u32, capacity: u32, max: u32) -> u32 {
    if appends > capacity { capacity.saturating_mul(2).max(appends.saturating_add(appends / 4)).min(max) } else { capacity }
}

/// What one storage binding of `binding_bytes` bytes holds of each record a batch stores.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct RecordLimits {
    /// Raw footprints ([`KeyedFootprint`]) of the photon pass's footprint buffer; also at
    /// most half the sort's items ([`crate::gpu::sort::MAX_SORT_ITEMS`]).
    pub raw_footprints: u32,
    /// Progressive photons ([`KeyedPhoton`]) of its photon buffer; also at most half the
    /// sort's items.
    pub photons: u32,
    /// Sorted progressive photons ([`PackedPhoton`]: the pass's plus the store's fallbacks).
    pub sorted_photons: u64,
}

impl RecordLimits {
    /// The limits of a binding of `binding_bytes` bytes.
    pub fn new(binding_bytes: u64) -> Self {
        let fit = |record: usize| u32::try_from(binding_bytes / record as u64).unwrap_or(u32::MAX);
        let sort = crate::gpu::sort::MAX_SORT_ITEMS / 2;
        Self {
            raw_footprints: fit(size_of::<KeyedFootprint>()).min(sort),
            photons: fit(size_of::<KeyedPhoton>()).min(sort),
            sorted_photons: binding_bytes / size_of::<PackedPhoton>() as u64,
        }
    }

    /// The share of a batch that fits when its photon pass attempted `footprint_appends`
    /// and `photon_appends` appends (below 1: the batch must shrink).
    pub fn fits(&self, footprint_appends: u32, photon_appends: u32) -> f64 {
        (self.raw_footprints as f64 / footprint_appends.max(1) as f64).min(self.photons as f64 / photon_appends.max(1) as f64)
    }
}

/// What a backend does after a batch's photon pass overflowed its append buffers
/// ([`after_overflow`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Overflow {
    /// Grow the buffers to these capacities (raw footprints, progressive photons) and trace
    /// the batch again.
    Grow(u32, u32),
    /// The batch needs more than one binding holds: trace the iteration again with this `B`.
    Shrink(u32),
    /// A single photon needs more than one binding holds: nothing can trace it.
    TooLarge,
}

/// The policy after a batch of `photons` photons attempted `footprint_appends` raw
/// footprints and `photon_appends` progressive photons into buffers of `capacities` (raw
/// footprints, progressive photons) and overflowed them.
pub fn after_overflow(limits: &RecordLimits, photons: u32, footprint_appends: u32, photon_appends: u32, capacities: (u32, u32)) -> Overflow {
    if footprint_appends > limits.raw_footprints || photon_appends > limits.photons {
        if photons <= 1 {
            return Overflow::TooLarge;
        }
        return Overflow::Shrink(shrink(photons, limits.fits(footprint_appends, photon_appends)));
    }
    Overflow::Grow(grow(footprint_appends, capacities.0, limits.raw_footprints), grow(photon_appends, capacities.1, limits.photons))
}

/// Runs an iteration of `photons` photons in batches of `*batch_photons`: `trace(range, k,
/// batches)` traces batch `k` of `batches` (global photons `range`) and returns `Some(B)`
/// when the batch does not fit one binding; the iteration then starts again from batch 0
/// with `*batch_photons = B` (`trace` sees `k == 0` again: the place to drop what the
/// earlier attempt kept). Returns the number of batches of the iteration that completed.
pub fn for_each_batch<E>(photons: u32, batch_photons: &mut u32, mut trace: impl FnMut(Range<u32>, u32, u32) -> Result<Option<u32>, E>) -> Result<u32, E> {
    'iteration: loop {
        let batches = batch_count(photons, *batch_photons);
        for k in 0..batches {
            if let Some(smaller) = trace(batch_range(photons, *batch_photons, k), k, batches)? {
                *batch_photons = smaller;
                continue 'iteration;
            }
        }
        return Ok(batches);
    }
}

/// Headroom of the calibrated capacities over the records the calibration counted
/// ([`calibrated_capacity`]): iterations differ from iteration 0 by their random streams.
pub const CALIBRATION_HEADROOM: f64 = 1.25;

/// Records an append buffer holds after the calibration counted `appends` in it (the most
/// of any batch): [`CALIBRATION_HEADROOM`] times that plus 256 (small iterations vary
/// more), at least 1 and at most `max`.
pub fn calibrated_capacity(appends: u32, max: u32) -> u32 {
    ((appends as f64 * CALIBRATION_HEADROOM) as u32).saturating_add(256).clamp(1, max.max(1))
}

/// Headroom of the calibrated sorted-photon capacity over the photon sort items the
/// calibration counted ([`calibrated_sorted_photons`]): larger than
/// [`CALIBRATION_HEADROOM`], since the footprints that fall back to progressive photons
/// depend on the progressive radius, which shrinks from iteration to iteration.
pub const SORTED_PHOTON_HEADROOM: f64 = 1.5;

/// Photon sort items a batch's store holds after the calibration counted `items` (the
/// most of any batch): [`SORTED_PHOTON_HEADROOM`] times that plus 256, at least 1 and at
/// most `total` (the two append buffers' capacities together: every photon item is an
/// appended photon or footprint) and `max` (one binding of sorted photons).
pub fn calibrated_sorted_photons(items: u32, total: u32, max: u32) -> u32 {
    ((items as f64 * SORTED_PHOTON_HEADROOM) as u32).saturating_add(256).min(total).clamp(1, max.max(1))
}

/// The record capacities of a photon batch's buffers.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Capacities {
    /// Raw footprints of the photon pass's footprint buffer (and the store's footprint
    /// slots, sort items and sorted footprints).
    pub raw_footprints: u32,
    /// Progressive photons of the photon pass's photon buffer.
    pub photons: u32,
    /// Photon sort items and sorted progressive photons of the store (the pass's photons
    /// and the footprints' fallbacks).
    pub sorted_photons: u32,
}

impl Capacities {
    /// The capacities a render starts with for batches of `batch` photons
    /// ([`initial_capacity`] for both append buffers, room for every appended record as a
    /// sorted photon), within `limits`.
    pub fn initial(batch: u32, forced: Option<u32>, limits: &RecordLimits) -> Self {
        let raw_footprints = initial_capacity(batch, forced, limits.raw_footprints);
        let photons = initial_capacity(batch, forced, limits.photons);
        Self { raw_footprints, photons, sorted_photons: Self::sorted_within(raw_footprints.saturating_add(photons), limits) }
    }

    /// The calibrated capacities ([`calibrated_capacity`], [`calibrated_sorted_photons`])
    /// for the most raw footprints, progressive photons and photon sort items a batch of the
    /// calibration appended, within `limits`.
    pub fn calibrated(raw_footprints: u32, photons: u32, photon_items: u32, limits: &RecordLimits) -> Self {
        let raw = calibrated_capacity(raw_footprints, limits.raw_footprints);
        let ph = calibrated_capacity(photons, limits.photons);
        let sorted = calibrated_sorted_photons(photon_items, raw.saturating_add(ph), Self::sorted_within(u32::MAX, limits));
        Self { raw_footprints: raw, photons: ph, sorted_photons: sorted }
    }

    /// `n` sorted photons, at least 1 and at most what one binding holds.
    fn sorted_within(n: u32, limits: &RecordLimits) -> u32 {
        n.clamp(1, u32::try_from(limits.sorted_photons).unwrap_or(u32::MAX).max(1))
    }

    /// The capacities with the sorted photons grown ([`grow`]) for `items` photon sort
    /// items, within `limits`.
    pub fn with_sorted_photons_for(self, items: u32, limits: &RecordLimits) -> Self {
        Self { sorted_photons: grow(items, self.sorted_photons, Self::sorted_within(u32::MAX, limits)), ..self }
    }
}

/// What to do with a photon batch traced with one wait, once its counters are read
/// ([`after_batch`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum BatchOutcome {
    /// Nothing was dropped: keep the batch.
    Kept,
    /// Records were dropped: trace the batch again with these capacities.
    Grow(Capacities),
    /// The batch needs more than one binding holds: trace the iteration again with this
    /// many photons per batch.
    Shrink(u32),
    /// One photon's records exceed one binding.
    TooLarge,
}

/// The outcome of a batch of `photons` photons traced into buffers of `allocated`
/// capacities, whose counters are `batch`, within `limits`: appends past the photon pass's
/// buffers grow them ([`after_overflow`]; the sorted photons keep room for every record of
/// the grown buffers), photon sort items past the store's capacity grow that
/// ([`Capacities::with_sorted_photons_for`]) or, past one binding, shrink the batch.
pub fn after_batch(limits: &RecordLimits, photons: u32, batch: &crate::gpu::layout::BatchCounts, allocated: Capacities) -> BatchOutcome {
    let (c, s) = (&batch.photon, &batch.store);
    if c.overflowed() > 0 {
        return match after_overflow(limits, photons, c.footprint_appends, c.photon_appends, (allocated.raw_footprints, allocated.photons)) {
            Overflow::Grow(f, p) => {
                let sorted = allocated.sorted_photons.max(Capacities::sorted_within(f.saturating_add(p), limits));
                BatchOutcome::Grow(Capacities { raw_footprints: f, photons: p, sorted_photons: sorted })
            }
            Overflow::Shrink(b) => BatchOutcome::Shrink(b),
            Overflow::TooLarge => BatchOutcome::TooLarge,
        };
    }
    if s.overflowed == 0 {
        return BatchOutcome::Kept;
    }
    if u64::from(s.photon_items) > limits.sorted_photons {
        return if photons <= 1 { BatchOutcome::TooLarge } else { BatchOutcome::Shrink(shrink(photons, limits.sorted_photons as f64 / f64::from(s.photon_items.max(1)))) };
    }
    BatchOutcome::Grow(allocated.with_sorted_photons_for(s.photon_items, limits))
}

/// A backend's photon batches traced with one wait each, for [`trace_waiting`].
#[cfg(feature = "alloc")]
#[cfg_attr(docsrs, doc(cfg(feature = "alloc")))]
pub trait WaitingBatches {
    /// The backend's error.
    type Error;
    /// Starts an iteration of `batches` batches (batch 0 follows).
    fn begin(&mut self, batches: u32) -> Result<(), Self::Error>;
    /// Traces and stores batch `k` (the photons `range`; `last`: the iteration's last
    /// batch) into the buffers allocated now, waits, and returns its counters.
    fn trace(&mut self, range: Range<u32>, k: u32, last: bool) -> Result<crate::gpu::layout::BatchCounts, Self::Error>;
    /// Reallocates the buffers for `capacities`.
    fn resize(&mut self, capacities: Capacities) -> Result<(), Self::Error>;
    /// The capacities allocated now.
    fn allocated(&self) -> Capacities;
    /// The error for a photon whose records alone exceed one binding (`batch`, `limits`).
    fn too_large(&self, batch: &crate::gpu::layout::BatchCounts, limits: &RecordLimits) -> Self::Error;
}

/// Traces an iteration of `photons` photons in batches of `*batch_photons` with one wait
/// each (the calibration, or an iteration traced again after an overflow): each batch is
/// checked as soon as it ran ([`after_batch`]) and traced again into grown buffers when it
/// dropped records; a batch too large for one binding shrinks `*batch_photons` and starts
/// the iteration again ([`for_each_batch`]). The batches' counts go into `stats` (its
/// photon counts and `overflowed` reset first). Returns the number of batches and the most
/// raw footprints, progressive photons and photon sort items a batch appended.
#[cfg(feature = "alloc")]
#[cfg_attr(docsrs, doc(cfg(feature = "alloc")))]
pub fn trace_waiting<W: WaitingBatches>(
    w: &mut W,
    photons: u32,
    batch_photons: &mut u32,
    limits: &RecordLimits,
    stats: &mut crate::render::tracer::IterationStats,
) -> Result<(u32, [u32; 3]), W::Error> {
    stats.overflowed = 0;
    let mut most = [0u32; 3];
    let batches = for_each_batch(photons, batch_photons, |range, k, batches| {
        if k == 0 {
            stats.reset_photon_counts();
            w.begin(batches)?;
            most = [0; 3];
        }
        let n = range.end - range.start;
        loop {
            let batch = w.trace(range.clone(), k, k + 1 == batches)?;
            match after_batch(limits, n, &batch, w.allocated()) {
                BatchOutcome::Kept => {
                    stats.add_photon_batch(&batch.photon, &batch.store);
                    let appended = [batch.photon.footprint_appends, batch.photon.photon_appends, batch.store.photon_items];
                    most = core::array::from_fn(|i| most[i].max(appended[i]));
                    return Ok(None);
                }
                BatchOutcome::Grow(c) => {
                    stats.overflowed += batch.dropped();
                    w.resize(c)?;
                }
                BatchOutcome::Shrink(b) => {
                    stats.overflowed += batch.dropped();
                    return Ok(Some(b));
                }
                BatchOutcome::TooLarge => return Err(w.too_large(&batch, limits)),
            }
        }
    })?;
    Ok((batches, most))
}

/// Records each append buffer starts with for batches of `batch` photons (`forced`: a
/// caller's choice), at least 1 and at most `max`.
pub fn initial_capacity(batch: u32, forced: Option<u32>, max: u32) -> u32 {
    forced.unwrap_or(batch.saturating_mul(INITIAL_RECORDS_PER_PHOTON)).max(1).min(max)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn batches_cover_the_iteration() {
        assert_eq!(batch_count(4000, 700), 6);
        assert_eq!(batch_count(0, 700), 1);
        let ranges: [Range<u32>; 3] = core::array::from_fn(|k| batch_range(1000, 400, k as u32));
        assert_eq!(ranges, [0..400, 400..800, 800..1000]);
        assert!(batch_range(1000, 400, 3).is_empty());
        assert_eq!(batch_range(u32::MAX, u32::MAX, 1), u32::MAX..u32::MAX);
    }

    #[test]
    fn shrink_and_grow() {
        assert_eq!(shrink(4000, 0.5), 1800);
        assert_eq!(shrink(4000, 0.9999), 3599);
        assert_eq!(shrink(2, 1e-9), 1);
        assert_eq!(grow(10, 100, 1000), 100);
        assert_eq!(grow(101, 100, 1000), 200);
        assert_eq!(grow(400, 100, 1000), 500);
        assert_eq!(grow(4000, 100, 1000), 1000);
    }

    #[test]
    fn overflow_grows_then_shrinks() {
        let l = RecordLimits::new(96 * 1000);
        assert_eq!(after_overflow(&l, 100, 300, 10, (200, 200)), Overflow::Grow(400, 200));
        assert_eq!(after_overflow(&l, 100, 2000, 10, (200, 200)), Overflow::Shrink(45));
        assert_eq!(after_overflow(&l, 1, 2000, 10, (200, 200)), Overflow::TooLarge);
    }

    #[test]
    fn batches_restart_when_one_does_not_fit() {
        let mut b = 1000;
        let mut seen = alloc::vec::Vec::new();
        let n = for_each_batch::<()>(1000, &mut b, |r, k, of| {
            seen.push((r.clone(), k, of));
            Ok((of == 1).then_some(400))
        })
        .unwrap();
        assert_eq!((n, b), (3, 400));
        assert_eq!(seen, [(0..1000, 0, 1), (0..400, 0, 3), (400..800, 1, 3), (800..1000, 2, 3)]);
    }

    #[test]
    fn limits_of_a_binding() {
        let l = RecordLimits::new(128 << 20);
        assert_eq!((l.raw_footprints, l.photons, l.sorted_photons), ((128 << 20) / 96, 1 << 21, (128 << 20) / 48));
        assert!(l.fits(l.raw_footprints, 1) >= 1.0 && l.fits(2 * l.raw_footprints, 1) == 0.5);
        assert_eq!(initial_capacity(1000, None, 5000), 2000);
        assert_eq!(initial_capacity(0, None, 5000), 1);
        assert_eq!(initial_capacity(1000, Some(64), 50), 50);
        assert_eq!(calibrated_capacity(1000, 5000), 1506);
        assert_eq!(calibrated_capacity(0, 5000), 256);
        assert_eq!(calibrated_capacity(10_000, 5000), 5000);
        assert_eq!(calibrated_capacity(u32::MAX, u32::MAX), u32::MAX);
        assert_eq!(calibrated_sorted_photons(1000, 5000, 4000), 1756);
        assert_eq!(calibrated_sorted_photons(1000, 1200, 4000), 1200);
        assert_eq!(calibrated_sorted_photons(1000, 5000, 1000), 1000);
        let c = Capacities::initial(1000, None, &l);
        assert_eq!((c.raw_footprints, c.photons, c.sorted_photons), (2000, 2000, 4000));
        let c = Capacities::calibrated(1000, 10, 300, &l);
        assert_eq!((c.raw_footprints, c.photons, c.sorted_photons), (1506, 268, 706));
        assert_eq!(c.with_sorted_photons_for(800, &l).sorted_photons, 1412);
        assert_eq!(c.with_sorted_photons_for(700, &l), c);
    }

    #[test]
    fn batches_grow_what_overflowed() {
        use crate::gpu::layout::{BatchCounts, PhotonCounters, StoreCounts};
        let l = RecordLimits::new(96 * 1000);
        let caps = Capacities { raw_footprints: 200, photons: 200, sorted_photons: 300 };
        let batch = |fp: u32, ph: u32, items: u32, dropped: u32| BatchCounts {
            photon: PhotonCounters { footprint_appends: fp, photon_appends: ph, footprint_overflowed: fp.saturating_sub(200), photon_overflowed: ph.saturating_sub(200), ..Default::default() },
            store: StoreCounts { photon_items: items, overflowed: dropped, ..Default::default() },
        };
        assert_eq!(after_batch(&l, 100, &batch(150, 10, 100, 0), caps), BatchOutcome::Kept);
        // Appends: the append buffer grows, the sorted photons keep room for both.
        assert_eq!(after_batch(&l, 100, &batch(300, 10, 100, 0), caps), BatchOutcome::Grow(Capacities { raw_footprints: 400, photons: 200, sorted_photons: 600 }));
        assert_eq!(after_batch(&l, 100, &batch(2000, 10, 100, 0), caps), BatchOutcome::Shrink(45));
        assert_eq!(after_batch(&l, 1, &batch(2000, 10, 100, 0), caps), BatchOutcome::TooLarge);
        // Photon sort items past the store's capacity: that grows, or past a binding
        // (2000 sorted photons here) the batch shrinks.
        assert_eq!(after_batch(&l, 100, &batch(150, 150, 350, 50), caps), BatchOutcome::Grow(Capacities { sorted_photons: 600, ..caps }));
        assert_eq!(after_batch(&l, 100, &batch(150, 150, 4000, 3700), caps), BatchOutcome::Shrink(45));
        assert_eq!(after_batch(&l, 1, &batch(150, 150, 4000, 3700), caps), BatchOutcome::TooLarge);
    }
}
