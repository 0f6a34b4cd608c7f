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

impl RunningMean {
    /// Empty mean.
    pub const fn new() -> Self {
        Self { sum: DVec3::ZERO, compensation: DVec3::ZERO, count: 0, rejected: 0 }
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
    /// An accumulator for `width × height` pixels, row-major.
    pub fn new(width: u32, height: u32) -> Self {
        Self { width, height, pixels: alloc::vec![RunningMean::new(); width as usize * height as usize], iterations: 0 }
    }

    /// Width and height in pixels.
    pub fn size(&self) -> (u32, u32) {
        (self.width, self.height)
    }

    /// Iterations accumulated.
    pub fn iterations(&self) -> u64 {
        self.iterations
    }

    /// Adds one iteration's image (radiance per pixel, row-major).
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

    /// The current estimate, always finite.
    pub fn mean(&self) -> alloc::vec::Vec<glam::Vec3> {
        self.pixels.iter().map(|p| p.mean().as_vec3()).collect()
    }

    /// Total non-finite samples rejected.
    pub fn rejected(&self) -> u64 {
        self.pixels.iter().map(|p| p.rejected()).sum()
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
