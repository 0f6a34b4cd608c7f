//! Density-estimation kernels, normalised over the unit disc of filter space.
//!
//! A footprint maps onto the unit disc through `M_p⁻¹` (see [`crate::store::footprint`]); a kernel
//! `K(r²)` with `∫_{|y|≤1} K(|y|²) dy = 1` times the Jacobian `4/|D_u × D_v|` then integrates
//! to exactly one over the footprint ellipse, so a photon deposits exactly its flux.
//!
//! **Default: [`Kernel::Silverman`]** (Silverman's second-order biweight
//! `3/π (1 − r²)²`). It is the kernel of the public implementation of Frisvad et al.'s
//! photon-differential splatting, whose light-source framework ARPA adopts; it is smooth
//! (C¹) at the ellipse boundary, so the elliptical outlines of individual footprints do not
//! show in the image; and the Silverman and Epanechnikov estimators are consistent where
//! the cone filter is not (Garcia et al., TVCG 2014). Progressive photons use
//! [`Kernel::Constant`] as RTPM does. Mixing kernels keeps energy because each is
//! normalised.

use core::f64::consts::PI;

/// A radial kernel on the unit disc, evaluated at squared radius `r²`.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum Kernel {
    /// `1/π` (box).
    Constant,
    /// `2/π (1 − r²)`.
    Epanechnikov,
    /// `3/π (1 − r²)²` (Silverman's biweight; the default).
    #[default]
    Silverman,
}

impl Kernel {
    /// `K(r²)` for `r² < 1`, else 0. NaN gives 0. Units: per unit filter-space area.
    #[inline]
    pub fn eval(self, r2: f32) -> f32 {
        if !(r2 < 1.0) {
            return 0.0;
        }
        let r2 = r2.max(0.0);
        let s = 1.0 - r2;
        match self {
            Kernel::Constant => core::f32::consts::FRAC_1_PI,
            Kernel::Epanechnikov => 2.0 * core::f32::consts::FRAC_1_PI * s,
            Kernel::Silverman => 3.0 * core::f32::consts::FRAC_1_PI * s * s,
        }
    }

    /// Double-precision [`Kernel::eval`].
    #[inline]
    pub fn eval_f64(self, r2: f64) -> f64 {
        if !(r2 < 1.0) {
            return 0.0;
        }
        let s = 1.0 - r2.max(0.0);
        match self {
            Kernel::Constant => 1.0 / PI,
            Kernel::Epanechnikov => 2.0 / PI * s,
            Kernel::Silverman => 3.0 / PI * s * s,
        }
    }

    /// Value at the centre, `K(0)`: the largest value the kernel takes.
    #[inline]
    pub fn peak(self) -> f64 {
        self.eval_f64(0.0)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Polar quadrature: ∫ K dA = 2π ∫₀¹ K(r²) r dr.
    #[test]
    fn normalised_on_unit_disc() {
        for k in [Kernel::Constant, Kernel::Epanechnikov, Kernel::Silverman] {
            let n = 100_000;
            let h = 1.0 / n as f64;
            let integral: f64 = (0..n).map(|i| {
                let r = (i as f64 + 0.5) * h;
                k.eval_f64(r * r) * r
            }).sum::<f64>() * 2.0 * PI * h;
            assert!((integral - 1.0).abs() < 1e-8, "{k:?}: {integral}");
            assert_eq!(k.eval(1.0), 0.0);
            assert_eq!(k.eval(f32::NAN), 0.0);
            assert!((k.eval(0.3) as f64 - k.eval_f64(0.3)).abs() < 1e-6);
        }
    }
}
