//! The device sort of the store's items (`path/sort.wgsl`, [`crate::gpu::shaders::SORT`]): a
//! bitonic sort of [`SortItem`]s by `(hi, lo, value)` on a power-of-two length, with
//! shared-memory stages for compare distances below [`SORT_BLOCK`]. The order is total, so
//! the result does not depend on the order the items were appended in.

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
}
