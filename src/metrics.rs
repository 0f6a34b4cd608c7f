//! Image-comparison metrics of a rendered image against a reference: relMSE, SSIM and
//! (LDR-)ꟻLIP.
//!
//! All functions take two linear-RGB images of the same size as row-major `&[Vec3]` of
//! `width · height` pixels, the **test** image first and the **reference** second. A size
//! or buffer-length mismatch is a [`MetricsError`], never a panic. Non-finite channel
//! values (NaN, ±∞) are treated as 0 in every metric, as [`crate::image_io::write_exr`]
//! writes them.
//!
//! * [`rel_mse`]: mean over pixels and the three channels of `(a − b)² / (b² + 0.01)`
//!   (`a` test, `b` reference), computed on the linear radiance without clamping;
//!   [`rel_mse_in`] takes the same mean over a [`PixelRect`] only.
//! * [`ssim`]: the mean SSIM (Wang et al. 2004) of the *luminance* only. Luminance is
//!   `Y = 0.2126 R + 0.7152 G + 0.0722 B` of the linear values, clamped to `[0, 1]` and
//!   sRGB-encoded ([`crate::image_io::srgb_encode`]), so it lies in `[0, 1]` (dynamic range
//!   `L = 1`, `C1 = (0.01 L)²`, `C2 = (0.03 L)²`). Local statistics use the standard
//!   **Gaussian window, σ = 1.5 px, 11×11** (radius 5), applied separably; at the image
//!   border the window is truncated and its weights renormalised, so every pixel
//!   contributes to the mean and images smaller than the window still work. Identical
//!   images give exactly 1.
//! * [`flip`]: the mean of the LDR-ꟻLIP error map (NVIDIA, Andersson et al. 2020) through
//!   the `nv-flip` crate, at its default 67 pixels per degree. LDR-ꟻLIP takes 8-bit sRGB
//!   images: each linear channel is clamped to `[0, 1]` (exposure 1, no tone mapping),
//!   sRGB-encoded and rounded to 8 bits — the same encoding as the PNG written by
//!   `arpa render` at `--exposure 1`. Identical images give 0. (HDR-ꟻLIP is not exposed
//!   by `nv-flip` 0.1.)

use crate::image_io::srgb_encode;
use glam::Vec3;

/// Why two images cannot be compared.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum MetricsError {
    /// The test image and the reference differ in size.
    #[error("image sizes differ: test image is {test_width}x{test_height}, reference is {reference_width}x{reference_height}")]
    SizeMismatch {
        /// Width of the test image.
        test_width: u32,
        /// Height of the test image.
        test_height: u32,
        /// Width of the reference.
        reference_width: u32,
        /// Height of the reference.
        reference_height: u32,
    },
    /// A pixel buffer does not hold `width · height` pixels.
    #[error("the {which} image has {len} pixels, but {width}x{height} needs {expected}")]
    BufferLength {
        /// `"test"` or `"reference"`.
        which: &'static str,
        /// Pixels in the buffer.
        len: usize,
        /// Declared width.
        width: u32,
        /// Declared height.
        height: u32,
        /// `width · height`.
        expected: usize,
    },
    /// A pixel rectangle that is empty or does not lie within the film.
    #[error("pixel rectangle {rect} does not lie within the {width}x{height} film")]
    RegionOutside {
        /// The rectangle, `[x0, y0, x1, y1]`.
        rect: String,
        /// Film width.
        width: u32,
        /// Film height.
        height: u32,
    },
    /// An image without pixels.
    #[error("cannot compare empty images ({width}x{height})")]
    Empty {
        /// Width.
        width: u32,
        /// Height.
        height: u32,
    },
}

/// The three metrics of one comparison.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Metrics {
    /// [`rel_mse`].
    pub rel_mse: f64,
    /// [`ssim`].
    pub ssim: f64,
    /// [`flip`].
    pub flip: f64,
}

/// `ε` of relMSE's denominator `b² + ε`.
pub const REL_MSE_EPSILON: f64 = 0.01;

fn check(test: &[Vec3], reference: &[Vec3], width: u32, height: u32) -> Result<(), MetricsError> {
    let expected = width as usize * height as usize;
    if expected == 0 {
        return Err(MetricsError::Empty { width, height });
    }
    for (which, len) in [("test", test.len()), ("reference", reference.len())] {
        if len != expected {
            return Err(MetricsError::BufferLength { which, len, width, height, expected });
        }
    }
    Ok(())
}

fn finite(c: f32) -> f64 {
    if c.is_finite() { c as f64 } else { 0.0 }
}

/// Checks that a `test_width`x`test_height` image can be compared with a
/// `reference_width`x`reference_height` reference.
pub fn check_sizes(test_width: u32, test_height: u32, reference_width: u32, reference_height: u32) -> Result<(), MetricsError> {
    if (test_width, test_height) != (reference_width, reference_height) {
        return Err(MetricsError::SizeMismatch { test_width, test_height, reference_width, reference_height });
    }
    Ok(())
}

/// Compares two [`arpa_core::render::tracer::Image`]s (test, reference): all three metrics.
pub fn compare_images(test: &arpa_core::render::tracer::Image, reference: &arpa_core::render::tracer::Image) -> Result<Metrics, MetricsError> {
    check_sizes(test.width, test.height, reference.width, reference.height)?;
    compare(&test.pixels, &reference.pixels, test.width, test.height)
}

/// All three metrics of `test` against `reference`.
pub fn compare(test: &[Vec3], reference: &[Vec3], width: u32, height: u32) -> Result<Metrics, MetricsError> {
    Ok(Metrics { rel_mse: rel_mse(test, reference, width, height)?, ssim: ssim(test, reference, width, height)?, flip: flip(test, reference, width, height)? })
}

/// Relative mean squared error: mean over pixels and channels of `(a − b)² / (b² + 0.01)`.
pub fn rel_mse(test: &[Vec3], reference: &[Vec3], width: u32, height: u32) -> Result<f64, MetricsError> {
    let per_pixel = rel_mse_per_pixel(test, reference, width, height)?;
    Ok(per_pixel.iter().sum::<f64>() / per_pixel.len() as f64)
}

/// Per pixel, the mean over the three channels of `(a − b)² / (b² + 0.01)`: the map whose
/// mean is [`rel_mse`] (the error heat maps of `arpa bench`).
pub fn rel_mse_per_pixel(test: &[Vec3], reference: &[Vec3], width: u32, height: u32) -> Result<Vec<f64>, MetricsError> {
    check(test, reference, width, height)?;
    Ok(test
        .iter()
        .zip(reference)
        .map(|(a, b)| {
            (0..3)
                .map(|ch| {
                    let (a, b) = (finite(a[ch]), finite(b[ch]));
                    (a - b) * (a - b) / (b * b + REL_MSE_EPSILON)
                })
                .sum::<f64>()
                / 3.0
        })
        .collect())
}

/// A rectangle of pixels, half-open: columns `x0..x1` (x right) and rows `y0..y1` (y down)
/// of a film. `arpa bench` restricts relMSE to one ([`rel_mse_in`]), e.g. a scene's caustic.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct PixelRect {
    /// First column.
    pub x0: u32,
    /// First row.
    pub y0: u32,
    /// One past the last column.
    pub x1: u32,
    /// One past the last row.
    pub y1: u32,
}

impl PixelRect {
    /// `[x0, y0, x1, y1]`, or why it is not a rectangle (`x1 <= x0` or `y1 <= y0`).
    pub fn new([x0, y0, x1, y1]: [u32; 4]) -> Result<Self, String> {
        if x1 <= x0 || y1 <= y0 {
            return Err(format!("[{x0}, {y0}, {x1}, {y1}] is empty: it needs x0 < x1 and y0 < y1 (half-open pixel ranges)"));
        }
        Ok(Self { x0, y0, x1, y1 })
    }

    /// Whether it lies within a `width`×`height` film.
    pub fn fits(&self, width: u32, height: u32) -> bool {
        self.x1 <= width && self.y1 <= height
    }

    /// The rectangle on a film `k` times smaller in both axes: every pixel of the smaller
    /// film that overlaps this one (`floor(x0 / k) .. ceil(x1 / k)`, the same in y).
    pub fn downscaled(&self, k: u32) -> Self {
        let k = k.max(1);
        Self { x0: self.x0 / k, y0: self.y0 / k, x1: self.x1.div_ceil(k), y1: self.y1.div_ceil(k) }
    }

    /// Pixels inside.
    pub fn area(&self) -> u64 {
        (self.x1 - self.x0) as u64 * (self.y1 - self.y0) as u64
    }
}

impl std::fmt::Display for PixelRect {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "[{}, {}, {}, {}]", self.x0, self.y0, self.x1, self.y1)
    }
}

/// [`rel_mse`] restricted to the pixels of `rect`: the mean of [`rel_mse_per_pixel`] over
/// them. A rectangle that does not fit the film is a [`MetricsError::RegionOutside`].
pub fn rel_mse_in(test: &[Vec3], reference: &[Vec3], width: u32, height: u32, rect: PixelRect) -> Result<f64, MetricsError> {
    if !rect.fits(width, height) || rect.area() == 0 {
        return Err(MetricsError::RegionOutside { rect: rect.to_string(), width, height });
    }
    let per_pixel = rel_mse_per_pixel(test, reference, width, height)?;
    let sum: f64 = (rect.y0..rect.y1).flat_map(|y| (rect.x0..rect.x1).map(move |x| (y * width + x) as usize)).map(|i| per_pixel[i]).sum();
    Ok(sum / rect.area() as f64)
}

/// Mean over pixels and channels (non-finite values as 0): the whole-image mean whose ratio
/// to the reference's tells bias from noise.
pub fn mean(image: &arpa_core::render::tracer::Image) -> f64 {
    image.pixels.iter().map(|p| (finite(p.x) + finite(p.y) + finite(p.z)) / 3.0).sum::<f64>() / image.pixels.len().max(1) as f64
}

/// Box-averages `image` by `k` in both axes (its size must be a multiple of `k`;
/// non-finite values count as 0): a reference at the resolution of a render `k` times
/// smaller, with `k²` times less of the reference's own noise.
pub fn downsample(image: &arpa_core::render::tracer::Image, k: u32) -> Result<arpa_core::render::tracer::Image, String> {
    if k == 0 || !image.width.is_multiple_of(k) || !image.height.is_multiple_of(k) {
        return Err(format!("cannot downsample {}x{} by {k}", image.width, image.height));
    }
    let (w, h) = (image.width / k, image.height / k);
    let mut pixels = vec![Vec3::ZERO; (w * h) as usize];
    for y in 0..image.height {
        for x in 0..image.width {
            let p = image.pixels[(y * image.width + x) as usize];
            let p = if p.is_finite() { p } else { Vec3::ZERO };
            pixels[((y / k) * w + x / k) as usize] += p;
        }
    }
    let inv = 1.0 / (k * k) as f32;
    pixels.iter_mut().for_each(|p| *p *= inv);
    Ok(arpa_core::render::tracer::Image { width: w, height: h, pixels })
}

/// sRGB-encoded, clamped luminance of a linear pixel.
fn encoded_luminance(p: Vec3) -> f64 {
    let y = 0.2126 * finite(p.x) + 0.7152 * finite(p.y) + 0.0722 * finite(p.z);
    srgb_encode(y as f32) as f64
}

/// Radius of the SSIM window (11×11).
const SSIM_RADIUS: usize = 5;
/// Standard deviation of the SSIM window in pixels.
const SSIM_SIGMA: f64 = 1.5;

/// Separable Gaussian blur with border truncation and renormalisation.
fn blur(src: &[f64], width: usize, height: usize, kernel: &[f64]) -> Vec<f64> {
    let r = SSIM_RADIUS as isize;
    let pass = |src: &[f64], horizontal: bool| -> Vec<f64> {
        let mut dst = vec![0.0; src.len()];
        for y in 0..height {
            for x in 0..width {
                let (mut acc, mut wsum) = (0.0, 0.0);
                for k in -r..=r {
                    let (sx, sy) = if horizontal { (x as isize + k, y as isize) } else { (x as isize, y as isize + k) };
                    if sx < 0 || sy < 0 || sx >= width as isize || sy >= height as isize {
                        continue;
                    }
                    let w = kernel[(k + r) as usize];
                    acc += w * src[sy as usize * width + sx as usize];
                    wsum += w;
                }
                dst[y * width + x] = acc / wsum;
            }
        }
        dst
    };
    let h = pass(src, true);
    pass(&h, false)
}

/// Mean SSIM of the sRGB-encoded, clamped luminance (Gaussian window σ = 1.5, 11×11; see
/// the module documentation). 1 for identical images, lower for less similar ones.
pub fn ssim(test: &[Vec3], reference: &[Vec3], width: u32, height: u32) -> Result<f64, MetricsError> {
    check(test, reference, width, height)?;
    let (w, h) = (width as usize, height as usize);
    let kernel: Vec<f64> = (0..=2 * SSIM_RADIUS)
        .map(|i| {
            let d = i as f64 - SSIM_RADIUS as f64;
            (-d * d / (2.0 * SSIM_SIGMA * SSIM_SIGMA)).exp()
        })
        .collect();
    let x: Vec<f64> = test.iter().map(|&p| encoded_luminance(p)).collect();
    let y: Vec<f64> = reference.iter().map(|&p| encoded_luminance(p)).collect();
    let xx: Vec<f64> = x.iter().map(|v| v * v).collect();
    let yy: Vec<f64> = y.iter().map(|v| v * v).collect();
    let xy: Vec<f64> = x.iter().zip(&y).map(|(a, b)| a * b).collect();
    let (mx, my) = (blur(&x, w, h, &kernel), blur(&y, w, h, &kernel));
    let (sxx, syy, sxy) = (blur(&xx, w, h, &kernel), blur(&yy, w, h, &kernel), blur(&xy, w, h, &kernel));
    const C1: f64 = 0.01 * 0.01;
    const C2: f64 = 0.03 * 0.03;
    let mut sum = 0.0;
    for i in 0..w * h {
        let (mx, my) = (mx[i], my[i]);
        // Clamp tiny negative variances from rounding.
        let vx = (sxx[i] - mx * mx).max(0.0);
        let vy = (syy[i] - my * my).max(0.0);
        let cov = sxy[i] - mx * my;
        sum += ((2.0 * mx * my + C1) * (2.0 * cov + C2)) / ((mx * mx + my * my + C1) * (vx + vy + C2));
    }
    Ok(sum / (w * h) as f64)
}

/// 8-bit sRGB encoding of a linear image (clamped, exposure 1).
fn to_srgb8(pixels: &[Vec3]) -> Vec<u8> {
    pixels.iter().flat_map(|p| p.to_array()).map(|c| (srgb_encode(finite(c) as f32) * 255.0 + 0.5).clamp(0.0, 255.0) as u8).collect()
}

/// Mean LDR-ꟻLIP error (via `nv-flip`, 67 pixels per degree) of the 8-bit sRGB encodings;
/// 0 for identical images, at most 1.
pub fn flip(test: &[Vec3], reference: &[Vec3], width: u32, height: u32) -> Result<f64, MetricsError> {
    check(test, reference, width, height)?;
    let t = nv_flip::FlipImageRgb8::with_data(width, height, &to_srgb8(test));
    let r = nv_flip::FlipImageRgb8::with_data(width, height, &to_srgb8(reference));
    let error_map = nv_flip::flip(r, t, nv_flip::DEFAULT_PIXELS_PER_DEGREE);
    let pool = nv_flip::FlipPool::from_image(&error_map);
    Ok(pool.mean() as f64)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn downsample_is_a_box_average() {
        let img = arpa_core::render::tracer::Image {
            width: 4,
            height: 2,
            pixels: (0..8).map(|i| Vec3::splat(i as f32)).collect(),
        };
        let d = downsample(&img, 2).unwrap();
        assert_eq!((d.width, d.height), (2, 1));
        assert_eq!(d.pixels[0], Vec3::splat((0.0 + 1.0 + 4.0 + 5.0) / 4.0));
        assert_eq!(d.pixels[1], Vec3::splat((2.0 + 3.0 + 6.0 + 7.0) / 4.0));
        assert!(downsample(&img, 3).is_err());
    }

    /// A smooth colour gradient with some structure.
    fn gradient(w: u32, h: u32) -> Vec<Vec3> {
        (0..h)
            .flat_map(|y| {
                (0..w).map(move |x| {
                    let (u, v) = (x as f32 / w as f32, y as f32 / h as f32);
                    Vec3::new(0.1 + 0.6 * u, 0.2 + 0.5 * v, 0.3 + 0.3 * ((u * 9.0).sin() * (v * 7.0).cos()).abs())
                })
            })
            .collect()
    }

    /// Deterministic uniform noise in `[-1, 1]`.
    fn noise(n: usize, seed: u64) -> Vec<f32> {
        let mut s = seed.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
        (0..n)
            .map(|_| {
                s = s.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
                ((s >> 40) as f32 / (1u64 << 24) as f32) * 2.0 - 1.0
            })
            .collect()
    }

    #[test]
    fn identical_images_are_perfect() {
        let (w, h) = (40, 30);
        let a = gradient(w, h);
        let m = compare(&a, &a, w, h).unwrap();
        assert_eq!(m.rel_mse, 0.0);
        assert!((m.ssim - 1.0).abs() < 1e-12, "{}", m.ssim);
        assert_eq!(m.flip, 0.0);
        // Also a tiny image, smaller than the SSIM window, and a black one.
        let b = gradient(3, 2);
        assert!((ssim(&b, &b, 3, 2).unwrap() - 1.0).abs() < 1e-12);
        let z = vec![Vec3::ZERO; 16];
        let m = compare(&z, &z, 4, 4).unwrap();
        assert_eq!((m.rel_mse, m.flip), (0.0, 0.0));
        assert!((m.ssim - 1.0).abs() < 1e-12);
    }

    #[test]
    fn rel_mse_of_a_known_offset() {
        // Reference 0.5 everywhere, test 0.6: (0.1)² / (0.25 + 0.01) per channel.
        let (w, h) = (7, 5);
        let r = vec![Vec3::splat(0.5); 35];
        let t = vec![Vec3::splat(0.6); 35];
        let expected = 0.01 / 0.26;
        assert!((rel_mse(&t, &r, w, h).unwrap() - expected).abs() < 1e-6);
        // Only one channel of one pixel off by 2 against a reference of 0: 4 / 0.01 / (3·35).
        let r = vec![Vec3::ZERO; 35];
        let mut t = r.clone();
        t[10].y = 2.0;
        let expected = 4.0 / 0.01 / 105.0;
        assert!((rel_mse(&t, &r, w, h).unwrap() - expected).abs() < 1e-9);
        // Asymmetric: the reference is the denominator.
        assert!((rel_mse(&r, &t, w, h).unwrap() - 4.0 / 4.01 / 105.0).abs() < 1e-9);
    }

    #[test]
    fn ssim_decreases_monotonically_with_noise() {
        let (w, h) = (48, 40);
        let r = gradient(w, h);
        let n = noise(3 * r.len(), 7);
        let mut last = ssim(&r, &r, w, h).unwrap();
        let mut last_flip = 0.0;
        for amp in [0.005f32, 0.01, 0.02, 0.05, 0.1, 0.2, 0.4] {
            let t: Vec<Vec3> = r.iter().enumerate().map(|(i, p)| *p + amp * Vec3::new(n[3 * i], n[3 * i + 1], n[3 * i + 2])).collect();
            let s = ssim(&t, &r, w, h).unwrap();
            assert!(s < last, "amplitude {amp}: SSIM {s} not below {last}");
            assert!(s > -1.0 && s < 1.0);
            let f = flip(&t, &r, w, h).unwrap();
            assert!(f >= last_flip && f > 0.0 && f <= 1.0, "amplitude {amp}: FLIP {f} after {last_flip}");
            last = s;
            last_flip = f;
        }
        assert!(last < 0.5, "{last}");
    }

    #[test]
    fn rel_mse_in_a_rectangle_is_the_mean_of_its_pixels() {
        let (w, h) = (6, 4);
        let reference = vec![Vec3::ONE; (w * h) as usize];
        let mut test = reference.clone();
        // Offset 1 in every channel of the pixels x 2..4, y 1..3: relMSE 1 / 1.01 there.
        for y in 1..3 {
            for x in 2..4 {
                test[(y * w + x) as usize] = Vec3::splat(2.0);
            }
        }
        let e = 1.0 / (1.0 + REL_MSE_EPSILON);
        let inside = PixelRect::new([2, 1, 4, 3]).unwrap();
        assert!((rel_mse_in(&test, &reference, w, h, inside).unwrap() - e).abs() < 1e-12);
        let half = PixelRect::new([0, 0, 4, 4]).unwrap();
        assert!((rel_mse_in(&test, &reference, w, h, half).unwrap() - e * 4.0 / 16.0).abs() < 1e-12);
        let whole = PixelRect::new([0, 0, w, h]).unwrap();
        assert_eq!(rel_mse_in(&test, &reference, w, h, whole).unwrap(), rel_mse(&test, &reference, w, h).unwrap());
        let outside = PixelRect::new([4, 0, 7, 2]).unwrap();
        assert!(matches!(rel_mse_in(&test, &reference, w, h, outside), Err(MetricsError::RegionOutside { .. })));
        assert!(PixelRect::new([3, 0, 3, 2]).unwrap_err().contains("x0 < x1"));
        // Downscaling keeps every pixel the rectangle overlaps.
        assert_eq!(PixelRect::new([5, 2, 11, 8]).unwrap().downscaled(4), PixelRect { x0: 1, y0: 0, x1: 3, y1: 2 });
        assert_eq!(PixelRect::new([4, 4, 8, 8]).unwrap().downscaled(4), PixelRect { x0: 1, y0: 1, x1: 2, y1: 2 });
    }

    #[test]
    fn mismatches_are_errors_not_panics() {
        let a = vec![Vec3::ONE; 12];
        let b = vec![Vec3::ONE; 11];
        assert!(matches!(compare(&a, &b, 4, 3), Err(MetricsError::BufferLength { which: "reference", len: 11, expected: 12, .. })));
        assert!(matches!(compare(&b, &a, 4, 3), Err(MetricsError::BufferLength { which: "test", .. })));
        assert!(matches!(compare(&[], &[], 0, 3), Err(MetricsError::Empty { .. })));
        let e = check_sizes(32, 32, 256, 128).unwrap_err();
        assert_eq!(e.to_string(), "image sizes differ: test image is 32x32, reference is 256x128");
        let ti = arpa_core::render::tracer::Image { width: 4, height: 3, pixels: a.clone() };
        let ri = arpa_core::render::tracer::Image { width: 3, height: 4, pixels: a };
        assert!(matches!(compare_images(&ti, &ri), Err(MetricsError::SizeMismatch { .. })));
    }

    #[test]
    fn non_finite_values_count_as_zero() {
        let r = vec![Vec3::ZERO; 4];
        let t = vec![Vec3::new(f32::NAN, f32::INFINITY, 0.0); 4];
        let m = compare(&t, &r, 2, 2).unwrap();
        assert_eq!((m.rel_mse, m.flip), (0.0, 0.0));
    }
}
