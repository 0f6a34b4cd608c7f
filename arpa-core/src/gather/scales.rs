//! The scale ladder of the per-pixel bandwidth: every footprint and progressive photon
//! evaluated at several nested scales in one gather, and the per-iteration moments that
//! let [`crate::accumulate::bandwidth`] choose among them per pixel.
//!
//! # The scale ladder
//! The gather evaluates every candidate footprint at [`SCALES`] nested scales of its final
//! ellipse (after smoothing and the heuristics): scale `k` shrinks both semi-axes by
//! `s_k = 2^{−k/2}` (`k = 0` is the stored ellipse and its box, so one traversal finds the
//! candidates of every scale). In filter space the scaled ellipse is the disc `|y| ≤ s_k`,
//! so its contribution is `Φ/A · 2^k K(2^k r²)` with the stored `r² = |y|²` and density
//! `Φ/A`: `1/s_k² = 2^k` is a power of two, so the scaled weights are exact scalings of the
//! stored ones in `f32` on every backend. The slab (distance from the surface) shrinks with
//! the ellipse, `2^k y_z² ≤ 1`. Progressive photons use the same scales of their radius:
//! `|q − x|² 2^k < r²`, density `2^k/(π r²)`. Each scale integrates to the photon's flux, so each is a
//! consistent estimator of its own, and each shrinks with the progressive radius as the
//! footprints do.
//!
//! Five scales span a factor 4 in footprint size (16 in area and in overlap). With automatic
//! smoothing ([`crate::propagate::classify::AutoSmoothing::per_pixel_overlap`]) the stored scale is the
//! global automatic choice (about 8 footprints per lit point per iteration), so the ladder's
//! overlaps are about 8, 4, 2, 1, ½: the stored footprints keep the gather's candidates
//! those of a global render, and the smaller scales reach footprints up to four times
//! smaller (a smoothing factor `4^{1/γ} = 256` times smaller under dampening's `γ = 1/4`).
//! Footprints larger than the stored ones are out of the ladder's reach.
//!
//! # What is accumulated
//! The iteration's image holds [`PLANES`] planes per pixel (`Bandwidth::planes`): the
//! radiance at each scale, then [`MOMENT_PLANES`] planes of per-iteration second moments
//! of the luminance ([`moments`]): `y_k²` for every scale and `(y_k − y_{k+1})²` between
//! neighbouring scales. They are summed like the radiance
//! (compensated, exact on resume and merge), so the per-iteration spread of every scale and
//! of every difference to the smallest one is known at output time.
//!
use glam::{DVec3, Vec3};

/// Number of nested scales of the ladder.
pub const SCALES: usize = 5;

/// Planes of second moments per pixel: `2 SCALES − 1` values, three per RGB plane.
pub const MOMENT_PLANES: usize = 3;

/// Planes per pixel of a per-pixel render: [`SCALES`] radiance planes and
/// [`MOMENT_PLANES`] moment planes.
pub const PLANES: usize = SCALES + MOMENT_PLANES;

/// `1/s_k² = 2^k` (exact in `f32`): the factor by which scale `k` multiplies the stored
/// squared filter radius and the density.
#[inline(always)]
pub const fn inv_scale2(k: usize) -> f32 {
    (1u32 << k) as f32
}

/// `s_k = 2^{−k/2}`: the linear size of scale `k` relative to the stored ellipse.
#[inline]
pub fn scale(k: usize) -> f64 {
    libm::exp2(-(k as f64) / 2.0)
}

/// How the image's bandwidth is chosen.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum Bandwidth {
    /// Each pixel picks its scale from multi-scale estimates (module docs; the default).
    #[default]
    PerPixel,
    /// One bandwidth for the whole image: the stored footprints as they are (one plane).
    Global,
}

impl Bandwidth {
    /// Lower-case name, as on the command line.
    pub const fn name(self) -> &'static str {
        match self {
            Bandwidth::PerPixel => "per-pixel",
            Bandwidth::Global => "global",
        }
    }

    /// Planes per pixel of the iteration image and the accumulation.
    pub const fn planes(self) -> usize {
        match self {
            Bandwidth::PerPixel => PLANES,
            Bandwidth::Global => 1,
        }
    }

    /// Scales the gather evaluates.
    pub const fn scales(self) -> usize {
        match self {
            Bandwidth::PerPixel => SCALES,
            Bandwidth::Global => 1,
        }
    }
}

/// Luminance (Rec. 709 weights) of a linear RGB radiance, in `f32`: what the moments and
/// the selection compare.
#[inline]
pub fn luminance(c: Vec3) -> f32 {
    0.2126 * c.x + 0.7152 * c.y + 0.0722 * c.z
}

/// The moment planes of one iteration's per-scale radiance `radiance` (index = scale):
/// value `k < SCALES` is `y_k²`, value `SCALES + k` (`k < SCALES − 1`) is
/// `(y_k − y_{k+1})²` with `y` the luminance, packed three to a plane in that order.
#[inline]
pub fn moments(radiance: &[Vec3; SCALES]) -> [Vec3; MOMENT_PLANES] {
    let y = radiance.map(luminance);
    let mut v = [0.0f32; 3 * MOMENT_PLANES];
    for k in 0..SCALES {
        v[k] = y[k] * y[k];
    }
    for k in 0..SCALES - 1 {
        let d = y[k] - y[k + 1];
        v[SCALES + k] = d * d;
    }
    core::array::from_fn(|p| Vec3::new(v[3 * p], v[3 * p + 1], v[3 * p + 2]))
}

/// Irradiance sums of one query point at every scale (W/m², RGB, both maps together),
/// summed in `f64` in the order the records are added.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct ScaleSums {
    /// Indexed by scale.
    pub per_scale: [DVec3; SCALES],
}

impl ScaleSums {
    /// Adds the per-scale contributions `e` of one record, each when non-zero and finite
    /// (as [`crate::gather::estimate::IrradianceEstimate::add`] does for the stored scale).
    #[inline]
    pub fn add(&mut self, e: &[Vec3; SCALES]) {
        for (s, e) in self.per_scale.iter_mut().zip(e) {
            if *e != Vec3::ZERO && e.is_finite() {
                *s += e.as_dvec3();
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ladder_is_powers_of_two_in_area() {
        for k in 0..SCALES {
            let exact = 1.0 / (scale(k) * scale(k));
            assert!((f64::from(inv_scale2(k)) / exact - 1.0).abs() < 1e-14, "{k}: {exact}");
        }
        assert!((scale(SCALES - 1) - 0.25).abs() < 1e-15);
        assert_eq!(Bandwidth::PerPixel.planes(), 8);
        assert_eq!(Bandwidth::Global.planes(), 1);
    }

    #[test]
    fn moments_pack_squares_then_differences() {
        let l: [Vec3; SCALES] = core::array::from_fn(|k| Vec3::splat(k as f32 + 1.0));
        let m = moments(&l);
        let v: [f32; 9] = [m[0].x, m[0].y, m[0].z, m[1].x, m[1].y, m[1].z, m[2].x, m[2].y, m[2].z];
        let expected = [1.0, 4.0, 9.0, 16.0, 25.0, 1.0, 1.0, 1.0, 1.0];
        assert!(v.iter().zip(expected).all(|(a, b)| (a - b).abs() < 1e-5 * b), "{v:?}");
    }
}
