//! The device sorts of the store's items, both by `(hi, lo, value)` ascending:
//!
//! * the LSD radix sort (`path/radix.wgsl`, [`crate::gpu::shaders::RADIX`]), the store's
//!   sort: 8-bit digits, least significant first ([`radix_passes`]), each pass a
//!   per-tile digit count, one exclusive scan of the counts and a stable scatter, so after
//!   the pass over the top digit of `hi` the items are in `(hi, lo, value)` order. It runs
//!   on exactly the items given (no padding) and needs a second item buffer and
//!   [`radix_count_len`] counters;
//! * the bitonic sort (`path/sort.wgsl`, [`crate::gpu::shaders::SORT`]) on a power-of-two
//!   length, with shared-memory stages for compare distances below [`SORT_BLOCK`].
//!
//! The order is total (the whole item is the key), so both give the same result, and it does
//! not depend on the order the items were appended in.

/// One item of the device sort (`ArpaSortItem`, 12 bytes): sorted by `hi`, then `lo`, then
/// `value` (ascending). The store's items: `hi` = `map << 30 | Morton code`, `lo` = photon
/// key, `value` = slot.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, PartialOrd, Ord, Hash, bytemuck::Pod, bytemuck::Zeroable)]
pub struct SortItem {
    /// Most significant key word.
    pub hi: u32,
    /// Least significant key word.
    pub lo: u32,
    /// Payload, last tie-breaker (a slot index).
    pub value: u32,
}
layout!(SortItem, 12, { hi: 0, lo: 4, value: 8 });

/// One step of the sort (`SortStep` of `sort.wgsl` in its first 16 bytes), padded to
/// 256 bytes: the steps of one sort sit in one uniform buffer read at dynamic offsets,
/// whose alignment is at most 256 bytes.
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, Eq, bytemuck::Pod, bytemuck::Zeroable)]
pub struct SortStep {
    /// Merge size (a power of two).
    pub k: u32,
    /// Compare distance (a power of two; 0: the shared-memory stages).
    pub j: u32,
    /// Padding.
    pub pad: [[u32; 2]; 31],
}
layout!(SortStep, 256, { k: 0, j: 4 });

impl SortStep {
    /// The step of merge size `k` and distance `j`.
    pub const fn new(k: u32, j: u32) -> Self {
        Self { k, j, pad: [[0; 2]; 31] }
    }
}


/// Items per workgroup block of the shared-memory stages (`SORT_BLOCK` of `sort.wgsl`);
/// sorted lengths are powers of two of at least this.
pub const SORT_BLOCK: u32 = 512;

/// `hi` and `lo` of padding items (`SORT_INVALID`): they sort after every valid item,
/// whose `hi` (`map << 30 | Morton code`) is below 2³¹.
pub const SORT_INVALID: u32 = u32::MAX;

/// Most items one sort takes (one dispatch of `n / SORT_BLOCK` workgroups per step).
pub const MAX_SORT_ITEMS: u32 = 1 << 25;

impl SortItem {
    /// A padding item (sorts last).
    pub const INVALID: Self = Self { hi: SORT_INVALID, lo: SORT_INVALID, value: SORT_INVALID };
}

/// The length a sort of `n` items runs on: the next power of two, at least [`SORT_BLOCK`].
pub fn sorted_len(n: u32) -> u32 {
    n.max(SORT_BLOCK).next_power_of_two()
}

/// The dispatches of a sort of `n` items (`n` = [`sorted_len`] of something), each
/// `n / SORT_BLOCK` workgroups with its step as uniform: first `sort_local` (the step is
/// unused), then, for each merge size `k > SORT_BLOCK`, `sort_global` for every compare
/// distance `j ≥ SORT_BLOCK` and `sort_merge` (`j = 0`: the shared-memory tail).
#[cfg(feature = "alloc")]
#[cfg_attr(docsrs, doc(cfg(feature = "alloc")))]
pub fn sort_steps(n: u32) -> alloc::vec::Vec<SortStep> {
    let mut steps = alloc::vec![SortStep::new(0, 0)];
    let mut k = 2 * SORT_BLOCK;
    while k <= n {
        let mut j = k / 2;
        while j >= SORT_BLOCK {
            steps.push(SortStep::new(k, j));
            j /= 2;
        }
        steps.push(SortStep::new(k, 0));
        k *= 2;
    }
    steps
}

/// Items per workgroup tile of the radix sort's count and scatter (`RADIX_TILE` of
/// `radix.wgsl`).
pub const RADIX_TILE: u32 = 4096;

/// Digit values of one radix pass (8-bit digits; `RADIX_BINS` of `radix.wgsl`).
pub const RADIX_BINS: u32 = 256;

/// One pass of the radix sort (`RadixPass` of `radix.wgsl` in its first 16 bytes), padded to
/// 256 bytes like [`SortStep`] (the passes of one sort sit in one uniform buffer read at
/// dynamic offsets).
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, Eq, bytemuck::Pod, bytemuck::Zeroable)]
pub struct RadixPass {
    /// Items sorted.
    pub n: u32,
    /// Workgroup tiles: `n` / [`RADIX_TILE`] rounded up.
    pub tiles: u32,
    /// The word the digit is taken from: 0 `value`, 1 `lo`, 2 `hi`.
    pub word: u32,
    /// Bit offset of the digit in its word (0, 8, 16 or 24).
    pub shift: u32,
    /// Padding.
    pub pad: [[u32; 2]; 30],
}
layout!(RadixPass, 256, { n: 0, tiles: 4, word: 8, shift: 12 });

/// Workgroup tiles of a radix sort of `n` items.
pub fn radix_tiles(n: u32) -> u32 {
    n.div_ceil(RADIX_TILE)
}

/// Counters (`u32`) a radix sort of `n` items needs: [`RADIX_BINS`] per tile.
pub fn radix_count_len(n: u32) -> u32 {
    RADIX_BINS * radix_tiles(n)
}

/// The passes of a radix sort of `n` items whose `value`s are all below `value_bound`
/// (`u32::MAX` when unknown): the digits of `value` that can be non-zero, then the four of
/// `lo` and of `hi`, least significant first. Each pass reads one item buffer and writes the
/// other (`radix_count`, `radix_scan` with one workgroup, `radix_scatter`); after an odd
/// number of passes the sorted items are in the second buffer. None for fewer than two items.
#[cfg(feature = "alloc")]
#[cfg_attr(docsrs, doc(cfg(feature = "alloc")))]
pub fn radix_passes(n: u32, value_bound: u32) -> alloc::vec::Vec<RadixPass> {
    if n < 2 {
        return alloc::vec::Vec::new();
    }
    let value_bits = u32::BITS - value_bound.saturating_sub(1).leading_zeros();
    let value_digits = value_bits.div_ceil(8);
    let pass = |word: u32, digit: u32| RadixPass { n, tiles: radix_tiles(n), word, shift: 8 * digit, pad: [[0; 2]; 30] };
    (0..value_digits).map(|d| pass(0, d)).chain((0..4).map(|d| pass(1, d))).chain((0..4).map(|d| pass(2, d))).collect()
}

/// `n` items shaped as the store makes them, in a shuffled order (the photon pass appends
/// with atomics), for the backends' sort benchmarks: `hi` = `map << 30 | Morton code` of
/// uniform random points in the unit cube, a fifth of them caustic (map 0); `lo` = photon
/// key `photon · 8 + depth` (three records a photon); `value` = slot. Drawn from `seed`'s
/// user stream.
#[cfg(feature = "alloc")]
#[cfg_attr(docsrs, doc(cfg(feature = "alloc")))]
pub fn store_like_items(n: u32, seed: u32) -> alloc::vec::Vec<SortItem> {
    use crate::base::rng::{Rng, StreamDomain};
    let mut rng = Rng::new(seed, 0, 0, StreamDomain::User);
    let mut items: alloc::vec::Vec<SortItem> = (0..n)
        .map(|slot| {
            let p = [rng.next_f64() as f32, rng.next_f64() as f32, rng.next_f64() as f32];
            let map = u32::from(!rng.next_u32().is_multiple_of(5));
            let key = (slot / 3) * 8 + slot % 3;
            SortItem { hi: map << 30 | crate::base::morton::morton_code(p, [0.0; 3], [1.0; 3]), lo: key, value: slot }
        })
        .collect();
    for i in (1..items.len()).rev() {
        items.swap(i, rng.next_u32() as usize % (i + 1));
    }
    items
}

#[cfg(all(test, feature = "alloc"))]
mod tests {
    use super::*;

    #[test]
    fn lengths_and_steps() {
        assert_eq!(sorted_len(0), SORT_BLOCK);
        assert_eq!(sorted_len(513), 1024);
        assert_eq!(sort_steps(512).len(), 1);
        // 2048: local; k = 1024: j = 512, tail; k = 2048: j = 1024, 512, tail.
        let s: alloc::vec::Vec<(u32, u32)> = sort_steps(2048).iter().map(|s| (s.k, s.j)).collect();
        assert_eq!(s, [(0, 0), (1024, 512), (1024, 0), (2048, 1024), (2048, 512), (2048, 0)]);
    }

    #[test]
    fn radix_schedule() {
        assert!(radix_passes(0, 0).is_empty() && radix_passes(1, u32::MAX).is_empty());
        assert_eq!(radix_tiles(RADIX_TILE + 1), 2);
        assert_eq!(radix_count_len(1), RADIX_BINS);
        let words = |n, bound| radix_passes(n, bound).iter().map(|p| (p.word, p.shift)).collect::<alloc::vec::Vec<_>>();
        // Values below 1: no value digit; below 257: two; unknown: four.
        assert_eq!(words(10, 1), [(1, 0), (1, 8), (1, 16), (1, 24), (2, 0), (2, 8), (2, 16), (2, 24)]);
        assert_eq!(words(10, 257)[..3], [(0, 0), (0, 8), (1, 0)]);
        assert_eq!(words(10, 256)[..2], [(0, 0), (1, 0)]);
        assert_eq!(radix_passes(10, u32::MAX).len(), 12);
        assert!(radix_passes(RADIX_TILE * 3, 5).iter().all(|p| p.n == RADIX_TILE * 3 && p.tiles == 3));
    }
}
