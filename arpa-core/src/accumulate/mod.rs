//! Accumulate (`no_std`; the image types need `alloc`): iteration after iteration. The
//! progressive radius schedule, the compensated per-pixel sums and running means, and
//! the per-pixel choice among the gathered scales.

pub mod bandwidth;
pub mod image;
pub mod radius;
