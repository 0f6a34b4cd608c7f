//! Locally adaptive bandwidth: every pixel picks its own footprint scale from the
//! estimates the gather made at several nested scales of the same footprints
//! ([`crate::gather::scales`]: the ladder and the moment planes).
//!
//! # The selection rule (plug-in MSE, at output time)
//! For each pixel, with `n` iterations and `Y_k` the mean luminance of scale `k`, every term
//! relative (divided by `Y_0² + ε`, `ε` 10⁻⁴ of the image's mean squared luminance, so bright
//! and dark neighbours weigh alike):
//! * variance of the mean, `v_k = (⟨y_k²⟩ − Y_k²)/(n − 1)`, averaged over a wide
//!   `(2·[VARIANCE_POOL_RADIUS] + 1)²` window. Wide, because a pixel whose small scale caught
//!   few photons by chance has a low estimate *and* a small spread: pooled over a few pixels
//!   (which share those photons) the rule would pick it exactly where it is low and darken
//!   the image; over 225 pixels its own draw hardly matters. Measured
//!   rather than modelled (`2^k v_0`), because where large footprints leak light onto a
//!   nearby surface the stored scale's spread holds that leakage too and the smaller scales
//!   are far less noisy than the model says;
//! * squared bias, the larger of two unbiased estimates, both averaged over a
//!   `(2·[POOL_RADIUS] + 1)²` window:
//!   - local, from neighbouring scales: `d_k = Y_k − Y_{k+1}` with its own variance `w_k`
//!     from the difference moments (neighbouring scales share most of their photons, so
//!     `w_k` is far below either scale's variance); for a second-order kernel in smooth
//!     light the bias grows like the kernel's area, so `b_k ≈ 2 d_k`, `b_k² ≈ 4 (d_k² − w_k)`
//!     (the smallest scale's: `d_{s−1}² − w_{s−1}`);
//!   - cumulative, against the smallest scale `s`: the window's mean of the signed
//!     `Y_k − Y_s`, squared, less the variance of that mean (`(v_s − v_k)` over the
//!     window's independent pixels, taken as a quarter of its pixels). It sees bias that
//!     builds up over several steps (leakage, a blurred edge) where each step alone is small;
//! * `MSE_k = max(b_k², 0) + v_k`; going from the largest scale down, a smaller scale is
//!   chosen only where its `MSE` is below [`PREFER_LARGER`] times the best so far;
//! * smoothing: the chosen index is averaged over a `3 × 3` tent, and the output blends the
//!   two scales around that fractional index linearly, so neighbouring pixels that choose
//!   differently meet without a seam or speckle.
//!
//! With one iteration (no spread yet) every pixel takes scale 0. On a flat, evenly lit
//! surface all scales agree, `b_k² ≈ 0`, and the variance picks the largest scale; near a
//! shadow edge or in a sharp caustic the larger scales' bias grows faster than their
//! variance falls and smaller scales win. As iterations accumulate the variances fall like
//! `1/n` and the rule moves towards smaller scales where the light has structure.
//!
//! # Memory
//! Per pixel, [`PLANES`](crate::gather::scales::PLANES) = 8 accumulated planes instead of 1: on the CPU 8 × 64 B
//! (compensated `f64` sums, [`crate::accumulate::image::PixelSum`]) and 8 × 12 B of iteration
//! image; on the GPU backends 8 × 32 B (compensated `f32` sums) and 8 × 16 B of iteration
//! image plus [`SCALES`](crate::gather::scales::SCALES) × 16 B of per-batch irradiance.

/// Half-width (pixels) of the window the selection pools its bias and variance estimates
/// over.
pub const POOL_RADIUS: usize = 3;

/// Half-width (pixels) of the window the selection pools its variance estimates over.
pub const VARIANCE_POOL_RADIUS: usize = 7;

/// A smaller scale is chosen only when its estimated error is below this fraction of the
/// best larger one's: the estimates are noisy, and a noisy choice costs more where it goes
/// smaller (more variance) than where it stays larger.
pub const PREFER_LARGER: f64 = 0.8;

#[cfg(feature = "alloc")]
pub use select::{select, Selection};

#[cfg(feature = "alloc")]
mod select {
    use super::{POOL_RADIUS, PREFER_LARGER, VARIANCE_POOL_RADIUS};
    use crate::gather::scales::{PLANES, SCALES};
    use glam::{DVec3, Vec3};
    use alloc::vec;
    use alloc::vec::Vec;

    /// The output of the selection: the image and, per pixel, the scale it uses.
    #[derive(Clone, Debug, PartialEq)]
    pub struct Selection {
        /// Row-major radiance (W/(m²·sr), linear RGB), always finite.
        pub image: Vec<Vec3>,
        /// Fractional scale index per pixel (0 = stored ellipse, `SCALES − 1` = smallest).
        pub scale: Vec<f32>,
    }

    /// Box sums of `v` (row-major `w × h`) over the `(2r + 1)²` window around each pixel
    /// (clipped at the border), and the number of pixels each window holds.
    fn box_mean(v: &[f64], w: usize, h: usize, r: usize) -> Vec<f64> {
        let mut rows = vec![0.0; v.len()];
        for y in 0..h {
            let row = &v[y * w..(y + 1) * w];
            for x in 0..w {
                let (a, b) = (x.saturating_sub(r), (x + r).min(w - 1));
                rows[y * w + x] = row[a..=b].iter().sum::<f64>() / (b - a + 1) as f64;
            }
        }
        let mut out = vec![0.0; v.len()];
        for y in 0..h {
            let (a, b) = (y.saturating_sub(r), (y + r).min(h - 1));
            for x in 0..w {
                out[y * w + x] = (a..=b).map(|yy| rows[yy * w + x]).sum::<f64>() / (b - a + 1) as f64;
            }
        }
        out
    }

    /// The image of a per-pixel accumulation: `planes` is the mean of every plane
    /// (`PLANES × w × h` values, plane-major: plane `p` of pixel `i` at `p w h + i`, as
    /// [`crate::accumulate::image::Accumulation`] keeps them) over `n` iterations. Applies the
    /// rule of the module docs. Deterministic: a function of the means alone.
    pub fn select(planes: &[DVec3], w: usize, h: usize, n: u64) -> Selection {
        let px = w * h;
        if px == 0 || planes.len() != PLANES * px {
            return Selection { image: vec![Vec3::ZERO; px], scale: vec![0.0; px] };
        }
        let plane = |p: usize, i: usize| planes[p * px + i];
        let finite = |v: DVec3| DVec3::select(v.is_finite_mask(), v, DVec3::ZERO);
        let lum = |c: DVec3| 0.2126 * c.x + 0.7152 * c.y + 0.0722 * c.z;
        let moment = |v: usize, i: usize| {
            let c = plane(SCALES + v / 3, i);
            [c.x, c.y, c.z][v % 3]
        };
        let mut choice = vec![0.0f64; px];
        if n >= 2 {
            let nf = n as f64;
            let y0_mean_sq: f64 = (0..px).map(|i| { let y = lum(plane(0, i)); y * y }).sum::<f64>() / px as f64;
            let eps = (1e-4 * y0_mean_sq).max(f64::MIN_POSITIVE);
            // Relative variance per scale, and the unbiased squared difference of means
            // between neighbouring scales, per pixel.
            let mut var = vec![vec![0.0; px]; SCALES];
            let mut step2 = vec![vec![0.0; px]; SCALES - 1];
            let mut to_smallest = vec![vec![0.0; px]; SCALES];
            for i in 0..px {
                let y: [f64; SCALES] = core::array::from_fn(|k| lum(plane(k, i)));
                let norm = y[0] * y[0] + eps;
                for k in 0..SCALES {
                    to_smallest[k][i] = (y[k] - y[SCALES - 1]) / libm::sqrt(norm);
                    var[k][i] = ((moment(k, i) - y[k] * y[k]) / (nf - 1.0)).max(0.0) / norm;
                    if k + 1 < SCALES {
                        let d = y[k] - y[k + 1];
                        let wv = ((moment(SCALES + k, i) - d * d) / (nf - 1.0)).max(0.0);
                        step2[k][i] = (d * d - wv) / norm;
                    }
                }
            }
            let var: Vec<Vec<f64>> = var.iter().map(|v| box_mean(v, w, h, VARIANCE_POOL_RADIUS)).collect();
            let step2: Vec<Vec<f64>> = step2.iter().map(|v| box_mean(v, w, h, POOL_RADIUS)).collect();
            let to_smallest: Vec<Vec<f64>> = to_smallest.iter().map(|v| box_mean(v, w, h, POOL_RADIUS)).collect();
            // Independent pixels in a pooling window: neighbouring pixels share footprints.
            let independent = ((2 * POOL_RADIUS + 1) * (2 * POOL_RADIUS + 1)) as f64 / 4.0;
            for (i, c) in choice.iter_mut().enumerate() {
                let mut best = (f64::INFINITY, 0usize);
                for (k, v) in var.iter().enumerate() {
                    // Local: b_k ≈ 2 d_k (bias ∝ kernel area); the smallest scale's is d_{s−1}.
                    let local = if k + 1 < SCALES { 4.0 * step2[k][i] } else { step2[k - 1][i] };
                    // Cumulative: the pooled signed difference to the smallest scale, less
                    // the variance of that pooled mean (v_s − v_k over the window).
                    let m = to_smallest[k][i];
                    let cumulative = m * m - (var[SCALES - 1][i] - v[i]) / independent;
                    let bias2 = local.max(cumulative).max(0.0);
                    let mse = bias2 + v[i];
                    // Strictly smaller only: ties stay with the larger scale.
                    if mse.is_finite() && mse < PREFER_LARGER * best.0 {
                        best = (mse, k);
                    }
                }
                *c = best.1 as f64;
            }
        }
        // 3 × 3 tent (1 2 1 ⊗ 1 2 1) over the choices, clipped at the border.
        let mut smooth = vec![0.0f32; px];
        for y in 0..h {
            for x in 0..w {
                let (mut sum, mut weight) = (0.0, 0.0);
                for dy in -1i64..=1 {
                    for dx in -1i64..=1 {
                        let (xx, yy) = (x as i64 + dx, y as i64 + dy);
                        if xx < 0 || yy < 0 || xx >= w as i64 || yy >= h as i64 {
                            continue;
                        }
                        let t = ((2 - dx.abs()) * (2 - dy.abs())) as f64;
                        sum += t * choice[yy as usize * w + xx as usize];
                        weight += t;
                    }
                }
                smooth[y * w + x] = (sum / weight) as f32;
            }
        }
        let image = (0..px)
            .map(|i| {
                let c = f64::from(smooth[i]).clamp(0.0, (SCALES - 1) as f64);
                let k0 = (c as usize).min(SCALES - 2);
                let t = c - k0 as f64;
                let l = if t == 0.0 { plane(k0, i) } else { plane(k0, i) * (1.0 - t) + plane(k0 + 1, i) * t };
                finite(l).as_vec3()
            })
            .map(|v| Vec3::select(v.is_finite_mask(), v, Vec3::ZERO))
            .collect();
        Selection { image, scale: smooth }
    }

    #[cfg(test)]
    mod tests {
        use super::*;
        use crate::gather::scales::{moments, MOMENT_PLANES};

        /// Planes of `n` iterations whose per-iteration luminance at scale `k` is
        /// `truth + bias[k] ± sigma[k]` (alternating signs, so the spread is exact).
        fn planes(px: usize, n: u64, truth: f64, bias: [f64; SCALES], sigma: [f64; SCALES]) -> Vec<DVec3> {
            let mut sums = vec![DVec3::ZERO; PLANES * px];
            for it in 0..n {
                let sign = if it % 2 == 0 { 1.0 } else { -1.0 };
                let l: [Vec3; SCALES] = core::array::from_fn(|k| Vec3::splat((truth + bias[k] + sign * sigma[k]) as f32));
                let m = moments(&l);
                for i in 0..px {
                    for k in 0..SCALES {
                        sums[k * px + i] += l[k].as_dvec3();
                    }
                    for p in 0..MOMENT_PLANES {
                        sums[(SCALES + p) * px + i] += m[p].as_dvec3();
                    }
                }
            }
            sums.iter().map(|s| *s / n as f64).collect()
        }

        #[test]
        fn unbiased_scales_pick_the_largest() {
            let p = planes(64, 16, 1.0, [0.0; SCALES], [0.05, 0.07, 0.1, 0.14, 0.2]);
            let s = select(&p, 8, 8, 16);
            assert!(s.scale.iter().all(|&c| c == 0.0), "{:?}", s.scale);
            assert!(s.image.iter().all(|l| (l.x - 1.0).abs() < 1e-6));
        }

        #[test]
        fn biased_large_scales_are_left() {
            // Large scales 20 % and 10 % off, noise small: scale 2 is the first unbiased one.
            let p = planes(64, 64, 1.0, [0.2, 0.1, 0.0, 0.0, 0.0], [0.01, 0.014, 0.02, 0.028, 0.04]);
            let s = select(&p, 8, 8, 64);
            assert!(s.scale.iter().all(|&c| c == 2.0), "{:?}", s.scale);
        }

        #[test]
        fn one_iteration_takes_the_stored_scale_and_nothing_is_nan() {
            let mut p = planes(4, 1, 1.0, [0.3, 0.0, 0.0, 0.0, 0.0], [0.0; SCALES]);
            p[1] = DVec3::NAN;
            let s = select(&p, 2, 2, 1);
            assert!(s.scale.iter().all(|&c| c == 0.0));
            assert!(s.image.iter().all(|l| l.is_finite()));
        }

        #[test]
        fn choices_blend_across_a_boundary() {
            // Left half biased at the large scales, right half not: the fractional index
            // changes over the tent's width, not in one step.
            let (w, h) = (12, 4);
            let left = planes(1, 64, 1.0, [0.3, 0.2, 0.1, 0.0, 0.0], [0.01; SCALES]);
            let right = planes(1, 64, 1.0, [0.0; SCALES], [0.01, 0.014, 0.02, 0.028, 0.04]);
            let mut p = vec![DVec3::ZERO; PLANES * w * h];
            for pl in 0..PLANES {
                for y in 0..h {
                    for x in 0..w {
                        p[pl * w * h + y * w + x] = if x < w / 2 { left[pl] } else { right[pl] };
                    }
                }
            }
            let s = select(&p, w, h, 64);
            let row: Vec<f32> = (0..w).map(|x| s.scale[w + x]).collect();
            assert!(row[0] >= 2.0 && row[w - 1] == 0.0, "{row:?}");
            assert!(row.iter().any(|&c| c > 0.0 && c < 3.0 && c.fract() != 0.0), "no blend: {row:?}");
        }
    }
}

