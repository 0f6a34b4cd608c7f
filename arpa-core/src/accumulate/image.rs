//! Accumulation of per-iteration estimates into a running mean that stays exact over
//! very many iterations: `f64` sums with Neumaier compensation. Non-finite samples are
//! rejected and counted, so no NaN or Inf ever reaches an output pixel.

use glam::DVec3;

/// A compensated running mean of RGB samples.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct RunningMean {
    sum: DVec3,
    compensation: DVec3,
    count: u64,
    rejected: u64,
}

#[inline]
fn neumaier(sum: f64, c: f64, x: f64) -> (f64, f64) {
    let t = sum + x;
    let c = if sum.abs() >= x.abs() { c + ((sum - t) + x) } else { c + ((x - t) + sum) };
    (t, c)
}

/// `(a + b, e)` with `a + b = (a ⊕ b) + e` exactly (Knuth's TwoSum, any magnitudes).
#[inline]
fn two_sum(a: f64, b: f64) -> (f64, f64) {
    let s = a + b;
    let bb = s - a;
    (s, (a - (s - bb)) + (b - bb))
}

/// The mean of a pixel whose samples sum to `total` (`sum + compensation`, W/(m²·sr))
/// over `iterations` iterations, as an output pixel: divided in `f64`, rounded to `f32`,
/// 0 before any iteration and wherever it is not finite in `f32` (so no NaN or Inf
/// reaches an output pixel). Every backend's image and [`Accumulation::mean`] use it.
#[inline]
pub fn output_mean(total: DVec3, iterations: u64) -> glam::Vec3 {
    if iterations == 0 {
        return glam::Vec3::ZERO;
    }
    let m = (total / iterations as f64).as_vec3();
    glam::Vec3::select(m.is_finite_mask(), m, glam::Vec3::ZERO)
}

/// The sums of one pixel as a checkpoint or a partial render keeps them: the compensated
/// sum of the finite samples and the count of rejected ones (`f64`, W/(m²·sr), RGB; 64
/// bytes). [`RunningMean::to_sum`] and the GPU backends' accumulators give it exactly.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
pub struct PixelSum {
    /// Sum of the finite samples.
    pub sum: [f64; 3],
    /// Neumaier compensation of `sum`: the exact sum is `sum + compensation` as long as
    /// the compensation's own additions are exact (see [`Accumulation::merge`]).
    pub compensation: [f64; 3],
    /// Non-finite samples rejected (each counted as an iteration that contributed 0).
    pub rejected: u64,
    /// Padding (zero).
    pub pad: u64,
}

impl PixelSum {
    /// `sum + compensation` in `f64`: the exact sum rounded once.
    #[inline]
    pub fn total(&self) -> DVec3 {
        DVec3::from_array(self.sum) + DVec3::from_array(self.compensation)
    }

    /// The sums of two disjoint sets of iterations together: the sums added with their
    /// rounding error moved into the compensation, so `total()` is the same rounded exact
    /// sum a single sequential accumulation of both sets gives.
    #[inline]
    pub fn merged(&self, other: &PixelSum) -> PixelSum {
        let mut out = PixelSum { rejected: self.rejected + other.rejected, ..PixelSum::default() };
        for c in 0..3 {
            let (s, e) = two_sum(self.sum[c], other.sum[c]);
            out.sum[c] = s;
            out.compensation[c] = (self.compensation[c] + other.compensation[c]) + e;
        }
        out
    }
}

impl RunningMean {
    /// Empty mean.
    pub const fn new() -> Self {
        Self { sum: DVec3::ZERO, compensation: DVec3::ZERO, count: 0, rejected: 0 }
    }

    /// The running mean whose sums are `sum` after `count` iterations (as
    /// [`RunningMean::to_sum`] gave them): resuming an accumulation.
    pub fn from_sum(sum: &PixelSum, count: u64) -> Self {
        Self { sum: DVec3::from_array(sum.sum), compensation: DVec3::from_array(sum.compensation), count, rejected: sum.rejected }
    }

    /// The sums, exactly (for a checkpoint).
    pub fn to_sum(&self) -> PixelSum {
        PixelSum { sum: self.sum.to_array(), compensation: self.compensation.to_array(), rejected: self.rejected, pad: 0 }
    }

    /// Adds one iteration's value. A non-finite value counts as an iteration that
    /// contributed 0 (so the estimate stays unbiased for finite values) and is tallied in
    /// [`RunningMean::rejected`].
    #[inline]
    pub fn add(&mut self, x: DVec3) {
        self.count += 1;
        if !x.is_finite() {
            self.rejected += 1;
            return;
        }
        let (sx, cx) = neumaier(self.sum.x, self.compensation.x, x.x);
        let (sy, cy) = neumaier(self.sum.y, self.compensation.y, x.y);
        let (sz, cz) = neumaier(self.sum.z, self.compensation.z, x.z);
        self.sum = DVec3::new(sx, sy, sz);
        self.compensation = DVec3::new(cx, cy, cz);
    }

    /// Iterations added.
    pub const fn count(&self) -> u64 {
        self.count
    }

    /// Non-finite samples rejected.
    pub const fn rejected(&self) -> u64 {
        self.rejected
    }

    /// The mean (0 before any sample); always finite.
    #[inline]
    pub fn mean(&self) -> DVec3 {
        if self.count == 0 {
            return DVec3::ZERO;
        }
        let m = (self.sum + self.compensation) / self.count as f64;
        DVec3::select(m.is_finite_mask(), m, DVec3::ZERO)
    }
}

/// Running mean of whole images.
#[cfg(feature = "alloc")]
#[cfg_attr(docsrs, doc(cfg(feature = "alloc")))]
#[derive(Clone, Debug, PartialEq)]
pub struct ImageAccumulator {
    width: u32,
    height: u32,
    planes: u32,
    pixels: alloc::vec::Vec<RunningMean>,
    iterations: u64,
}

/// The iteration's image has the wrong size.
#[derive(Clone, Copy, Debug, PartialEq, Eq, thiserror::Error)]
#[error("image has {got} pixels, accumulator expects {expected}")]
pub struct SizeMismatch {
    /// Pixels expected.
    pub expected: usize,
    /// Pixels given.
    pub got: usize,
}

#[cfg(feature = "alloc")]
#[cfg_attr(docsrs, doc(cfg(feature = "alloc")))]
impl ImageAccumulator {
    /// An accumulator for `width × height` pixels, row-major, one plane.
    pub fn new(width: u32, height: u32) -> Self {
        Self::with_planes(width, height, 1)
    }

    /// An accumulator for `planes` planes of `width × height` pixels each, plane-major
    /// ([`crate::gather::scales::Bandwidth::planes`]).
    pub fn with_planes(width: u32, height: u32, planes: u32) -> Self {
        Self { width, height, planes, pixels: alloc::vec![RunningMean::new(); planes as usize * width as usize * height as usize], iterations: 0 }
    }

    /// Width and height in pixels.
    pub fn size(&self) -> (u32, u32) {
        (self.width, self.height)
    }

    /// Iterations accumulated.
    pub fn iterations(&self) -> u64 {
        self.iterations
    }

    /// Adds one iteration's image (radiance per pixel, row-major; every plane, plane-major).
    pub fn add_iteration(&mut self, image: &[glam::Vec3]) -> Result<(), SizeMismatch> {
        if image.len() != self.pixels.len() {
            return Err(SizeMismatch { expected: self.pixels.len(), got: image.len() });
        }
        for (acc, x) in self.pixels.iter_mut().zip(image) {
            acc.add(x.as_dvec3());
        }
        self.iterations += 1;
        Ok(())
    }

    /// The current estimate, always finite: [`Accumulation::mean`] of the sums so far.
    pub fn mean(&self) -> alloc::vec::Vec<glam::Vec3> {
        self.to_accumulation(0).mean()
    }

    /// The sums of every pixel, exactly, as iterations `first_iteration ..
    /// first_iteration + iterations()` of a render (a checkpoint).
    pub fn to_accumulation(&self, first_iteration: u32) -> Accumulation {
        Accumulation {
            width: self.width,
            height: self.height,
            planes: self.planes,
            first_iteration,
            iterations: self.iterations as u32,
            pixels: self.pixels.iter().map(RunningMean::to_sum).collect(),
        }
    }

    /// The accumulator that continues `state` (its sums and iteration count).
    pub fn from_accumulation(state: &Accumulation) -> Self {
        let count = u64::from(state.iterations);
        Self { width: state.width, height: state.height, planes: state.planes, pixels: state.pixels.iter().map(|p| RunningMean::from_sum(p, count)).collect(), iterations: count }
    }

    /// Total non-finite samples rejected.
    pub fn rejected(&self) -> u64 {
        self.pixels.iter().map(|p| p.rejected()).sum()
    }
}

/// The accumulated sums of a render over the iterations `first_iteration ..
/// first_iteration + iterations` (0-based iteration indices): what a checkpoint stores,
/// what a partial render (`--iterations A..B`) produces and what [`Accumulation::merge`]
/// combines. [`Tracer::read_accumulation`](crate::render::tracer::Tracer::read_accumulation)
/// gives it and [`Tracer::restore_accumulation`](crate::render::tracer::Tracer::restore_accumulation)
/// continues from it; since every random stream and the radius schedule depend only on
/// the seed and the iteration index, a render continued from it is the render that was
/// never interrupted.
#[cfg(feature = "alloc")]
#[cfg_attr(docsrs, doc(cfg(feature = "alloc")))]
#[derive(Clone, Debug, PartialEq)]
pub struct Accumulation {
    /// Image width (pixels).
    pub width: u32,
    /// Image height (pixels).
    pub height: u32,
    /// Planes per pixel: 1, or [`crate::gather::scales::PLANES`] for a per-pixel bandwidth
    /// render (the radiance at every scale, then the moment planes).
    pub planes: u32,
    /// Index of the first iteration the sums cover.
    pub first_iteration: u32,
    /// Iterations the sums cover.
    pub iterations: u32,
    /// Per-pixel sums, row-major, plane after plane (plane `p` of pixel `i` at
    /// `p · width · height + i`).
    pub pixels: alloc::vec::Vec<PixelSum>,
}

/// Why accumulations cannot be merged, or an accumulation cannot be used.
#[cfg(feature = "alloc")]
#[cfg_attr(docsrs, doc(cfg(feature = "alloc")))]
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum AccumulationError {
    /// No parts to merge.
    #[error("nothing to merge")]
    Empty,
    /// The pixel array does not match `width × height`, or parts differ in size.
    #[error("image size mismatch: {0}")]
    Size(alloc::string::String),
    /// Parts cover the same iterations.
    #[error("iterations {first}..{end} are covered twice")]
    Overlap {
        /// First iteration covered twice.
        first: u32,
        /// End (exclusive) of the overlap.
        end: u32,
    },
    /// No part covers these iterations.
    #[error("iterations {first}..{end} are missing")]
    Gap {
        /// First missing iteration.
        first: u32,
        /// End (exclusive) of the gap.
        end: u32,
    },
    /// The iteration range does not fit `u32`.
    #[error("iteration range {first} + {iterations} overflows")]
    Range {
        /// First iteration.
        first: u32,
        /// Iterations.
        iterations: u32,
    },
    /// A sum is NaN or infinite (a corrupt state: the accumulators keep only finite sums).
    #[error("pixel {0} has a non-finite sum")]
    NonFinite(usize),
}

#[cfg(feature = "alloc")]
#[cfg_attr(docsrs, doc(cfg(feature = "alloc")))]
impl Accumulation {
    /// No iterations yet, starting at iteration `first_iteration` (the start of a partial
    /// render). One plane; a backend that accumulates more continues it with its own
    /// planes ([`Accumulation::with_planes`]).
    pub fn empty(width: u32, height: u32, first_iteration: u32) -> Self {
        Self::empty_planes(width, height, 1, first_iteration)
    }

    /// [`Accumulation::empty`] with `planes` planes per pixel.
    pub fn empty_planes(width: u32, height: u32, planes: u32, first_iteration: u32) -> Self {
        Self { width, height, planes, first_iteration, iterations: 0, pixels: alloc::vec![PixelSum::default(); planes as usize * width as usize * height as usize] }
    }

    /// This accumulation as one with `planes` planes: itself when it has them, an empty
    /// one of `planes` planes at the same first iteration when it covers no iteration yet;
    /// otherwise an error (the sums of a render with another bandwidth cannot continue).
    pub fn with_planes(&self, planes: u32) -> Result<alloc::borrow::Cow<'_, Accumulation>, AccumulationError> {
        if self.planes == planes {
            Ok(alloc::borrow::Cow::Borrowed(self))
        } else if self.iterations == 0 {
            Ok(alloc::borrow::Cow::Owned(Self::empty_planes(self.width, self.height, planes, self.first_iteration)))
        } else {
            Err(AccumulationError::Size(alloc::format!("sums of {} planes per pixel, the render accumulates {planes} (another --bandwidth)", self.planes)))
        }
    }

    /// Pixels per plane (`width × height`).
    pub fn pixel_count(&self) -> usize {
        self.width as usize * self.height as usize
    }
    /// The iteration after the last one covered (`first_iteration + iterations`).
    pub fn end(&self) -> u64 {
        u64::from(self.first_iteration) + u64::from(self.iterations)
    }

    /// Checks that the pixels match the size, the range fits `u32` and every sum is
    /// finite.
    pub fn validate(&self) -> Result<(), AccumulationError> {
        if self.planes != 1 && self.planes as usize != crate::gather::scales::PLANES {
            return Err(AccumulationError::Size(alloc::format!("{} planes per pixel (1 or {} expected)", self.planes, crate::gather::scales::PLANES)));
        }
        let expected = self.planes as u64 * self.width as u64 * self.height as u64;
        if self.pixels.len() as u64 != expected {
            return Err(AccumulationError::Size(alloc::format!("{} pixel sums for {}x{} pixels of {} planes", self.pixels.len(), self.width, self.height, self.planes)));
        }
        if self.end() > u64::from(u32::MAX) {
            return Err(AccumulationError::Range { first: self.first_iteration, iterations: self.iterations });
        }
        match self.pixels.iter().position(|p| !(p.total().is_finite() && DVec3::from_array(p.sum).is_finite())) {
            Some(i) => Err(AccumulationError::NonFinite(i)),
            None => Ok(()),
        }
    }

    /// The image, the same values the backend that accumulated it reads back: with one
    /// plane every pixel's mean over the covered iterations ([`output_mean`]); with the
    /// planes of a per-pixel bandwidth render, the selection of [`crate::accumulate::bandwidth::select`].
    pub fn mean(&self) -> alloc::vec::Vec<glam::Vec3> {
        if self.planes == 1 {
            self.pixels.iter().map(|p| output_mean(p.total(), u64::from(self.iterations))).collect()
        } else {
            self.selection().image
        }
    }

    /// The per-pixel selection ([`crate::accumulate::bandwidth::select`]) of these sums: the image and
    /// the scale each pixel uses. With one plane, the mean and scale 0 everywhere.
    pub fn selection(&self) -> crate::accumulate::bandwidth::Selection {
        if self.planes == 1 {
            return crate::accumulate::bandwidth::Selection { image: self.mean(), scale: alloc::vec![0.0; self.pixel_count()] };
        }
        let n = u64::from(self.iterations);
        let means: alloc::vec::Vec<DVec3> = self.pixels.iter().map(|p| if n == 0 { DVec3::ZERO } else { p.total() / n as f64 }).collect();
        crate::accumulate::bandwidth::select(&means, self.width as usize, self.height as usize, n)
    }

    /// The mean of plane `plane` over the covered iterations ([`output_mean`] per pixel).
    pub fn plane_mean(&self, plane: usize) -> alloc::vec::Vec<glam::Vec3> {
        let px = self.pixel_count();
        self.pixels[plane * px..(plane + 1) * px].iter().map(|p| output_mean(p.total(), u64::from(self.iterations))).collect()
    }

    /// The accumulation of all `parts` together. They may come in any order but must be
    /// the same size and cover one contiguous range of iterations exactly once; a gap or an
    /// overlap is refused. The sums are added pairwise with their rounding errors kept
    /// ([`PixelSum::merged`]), so the merged image is bit for bit the one a single render
    /// of the whole range gives, as long as each pixel's compensation stays exact (its
    /// terms are rounding errors of the samples, exactly representable; their sum is exact
    /// while the binades of one pixel's samples and the iteration count stay within the
    /// 53-bit significand, which any real render does).
    pub fn merge(parts: &[Accumulation]) -> Result<Accumulation, AccumulationError> {
        let mut order: alloc::vec::Vec<&Accumulation> = parts.iter().collect();
        order.sort_by_key(|p| (p.first_iteration, p.iterations));
        let Some(&first) = order.first() else { return Err(AccumulationError::Empty) };
        first.validate()?;
        let mut out = first.clone();
        for p in &order[1..] {
            p.validate()?;
            if (p.width, p.height) != (out.width, out.height) {
                return Err(AccumulationError::Size(alloc::format!("a part of {}x{} pixels and one of {}x{}", out.width, out.height, p.width, p.height)));
            }
            if p.planes != out.planes {
                return Err(AccumulationError::Size(alloc::format!("a part of {} planes per pixel and one of {} (renders of another --bandwidth)", out.planes, p.planes)));
            }
            let end = out.end() as u32;
            if p.first_iteration < end {
                return Err(AccumulationError::Overlap { first: p.first_iteration, end: end.min(p.end() as u32) });
            }
            if p.first_iteration > end {
                return Err(AccumulationError::Gap { first: end, end: p.first_iteration });
            }
            if out.end() + u64::from(p.iterations) > u64::from(u32::MAX) {
                return Err(AccumulationError::Range { first: out.first_iteration, iterations: u32::MAX });
            }
            for (a, b) in out.pixels.iter_mut().zip(&p.pixels) {
                *a = a.merged(b);
            }
            out.iterations += p.iterations;
        }
        Ok(out)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// 100k iterations of a value that is not representable in binary stay exact, where a
    /// naive f32 running sum drifts visibly.
    #[test]
    fn exact_over_100k_iterations() {
        let mut m = RunningMean::new();
        let mut naive = 0.0f32;
        let n = 100_000;
        for i in 0..n {
            // Alternating magnitudes make cancellation worse.
            let x = if i % 2 == 0 { 0.1 } else { 1e4 + 0.1 };
            m.add(DVec3::splat(x));
            naive += x as f32;
        }
        let exact = 0.1 + 1e4 / 2.0; // mean of {0.1, 1e4 + 0.1}
        assert!((m.mean().x - exact).abs() <= 1e-12 * exact, "{}", m.mean().x);
        let naive_mean = naive as f64 / n as f64;
        assert!((naive_mean - exact).abs() > 1e-6 * exact, "f32 sum unexpectedly exact: the test proves nothing");
    }

    #[test]
    fn nonfinite_rejected() {
        let mut m = RunningMean::new();
        m.add(DVec3::ONE);
        m.add(DVec3::NAN);
        m.add(DVec3::new(f64::INFINITY, 0.0, 0.0));
        m.add(DVec3::ONE);
        assert_eq!(m.rejected(), 2);
        assert_eq!(m.mean(), DVec3::splat(0.5));
        assert!(RunningMean::new().mean().is_finite());
    }

    #[cfg(feature = "alloc")]
    #[test]
    fn image_size_checked() {
        let mut a = ImageAccumulator::new(2, 2);
        assert!(a.add_iteration(&[glam::Vec3::ONE; 3]).is_err());
        a.add_iteration(&[glam::Vec3::ONE; 4]).unwrap();
        a.add_iteration(&[glam::Vec3::NAN; 4]).unwrap();
        assert_eq!(a.mean(), alloc::vec![glam::Vec3::splat(0.5); 4]);
        assert_eq!(a.rejected(), 4);
    }
}
