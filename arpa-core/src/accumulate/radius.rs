//! Progressive radius schedule (Knaus & Zwicker 2011, "Progressive photon mapping: a
//! probabilistic approach"): one global radius per map and iteration,
//! `r_{i+1}² = r_i² (i + α)/(i + 1)` for iterations `i = 1, 2, …`, so that
//! `r_i² ≈ r_1² Γ(1+α)⁻¹ i^{α−1}` shrinks and the estimate is consistent.

use crate::base::aabb::Aabb;
use crate::store::footprint::PhotonMap;

/// Smallest radius the schedule returns (metres), as in RTPM: avoids `f32` trouble with
/// `1/(π r²)` after very many iterations.
pub const MIN_RADIUS: f64 = 1e-5;

/// An initial radius in scene units or relative to the scene diagonal.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum RadiusSpec {
    /// Metres (scene units).
    Absolute(f64),
    /// Fraction of the scene bounding-box diagonal.
    RelativeToDiagonal(f64),
}

impl RadiusSpec {
    /// The radius in metres for scene bounds `scene`.
    pub fn resolve(self, scene: &Aabb) -> f64 {
        match self {
            RadiusSpec::Absolute(r) => r,
            RadiusSpec::RelativeToDiagonal(f) => f * scene.diagonal(),
        }
    }
}

/// The radius schedule of one map.
///
/// # Example
/// ```
/// use arpa_core::accumulate::radius::RadiusSchedule;
///
/// let s = RadiusSchedule { initial: 0.1, alpha: 2.0 / 3.0 };
/// assert_eq!(s.radius(1), 0.1);
/// // The closed form and the recurrence agree; the radius shrinks every iteration.
/// let mut r = s.radius(1);
/// for i in 1..100 {
///     let next = s.next(r, i);
///     assert!(next < r && (next / s.radius(i + 1) - 1.0).abs() < 1e-12);
///     r = next;
/// }
/// // r_i² ∝ i^{α−1} for large i: quadrupling i shrinks r² by 4^{α−1}.
/// let ratio = (s.radius(4000) / s.radius(1000)).powi(2);
/// assert!((ratio - 4f64.powf(2.0 / 3.0 - 1.0)).abs() < 1e-3);
/// ```
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RadiusSchedule {
    /// Radius of the first iteration, `r_1` (metres).
    pub initial: f64,
    /// `α ∈ (0, 1]` (1 = no shrinking).
    pub alpha: f64,
}

impl RadiusSchedule {
    /// Radius of iteration `i` (1-based; `0` is treated as 1), in closed form
    /// `r_i² = r_1² Γ(i + α) / (Γ(1 + α) Γ(i + 1))`, clamped to [`MIN_RADIUS`] and finite.
    pub fn radius(&self, iteration: u32) -> f64 {
        let i = iteration.max(1) as f64;
        let alpha = self.alpha_clamped();
        let log_ratio = libm::lgamma(i + alpha) - libm::lgamma(1.0 + alpha) - libm::lgamma(i + 1.0);
        let r = self.initial_clamped() * libm::exp(0.5 * log_ratio);
        if r.is_finite() { r.max(MIN_RADIUS) } else { MIN_RADIUS }
    }

    /// Applies the recurrence once: the radius of iteration `i + 1` from that of `i`.
    pub fn next(&self, radius: f64, iteration: u32) -> f64 {
        let i = iteration.max(1) as f64;
        let alpha = self.alpha_clamped();
        let r = radius * libm::sqrt((i + alpha) / (i + 1.0));
        if r.is_finite() { r.max(MIN_RADIUS) } else { MIN_RADIUS }
    }

    fn alpha_clamped(&self) -> f64 {
        if self.alpha > 0.0 { self.alpha.min(1.0) } else { 2.0 / 3.0 }
    }

    fn initial_clamped(&self) -> f64 {
        if self.initial > 0.0 && self.initial.is_finite() { self.initial } else { MIN_RADIUS }
    }
}

/// Configuration of both maps' radii.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ProgressiveConfig {
    /// Initial caustic radius (ARPA: 0.01 scene units).
    pub caustic: RadiusSpec,
    /// Initial global radius (ARPA: 0.05 scene units).
    pub global: RadiusSpec,
    /// `α` (default 2/3, the asymptotically optimal value; RTPM uses 0.7).
    pub alpha: f64,
}

impl Default for ProgressiveConfig {
    fn default() -> Self {
        Self { caustic: RadiusSpec::Absolute(0.01), global: RadiusSpec::Absolute(0.05), alpha: 2.0 / 3.0 }
    }
}

impl ProgressiveConfig {
    /// The schedule of `map` for a scene with bounds `scene`.
    pub fn schedule(&self, map: PhotonMap, scene: &Aabb) -> RadiusSchedule {
        let spec = match map {
            PhotonMap::Caustic => self.caustic,
            PhotonMap::Global => self.global,
        };
        RadiusSchedule { initial: spec.resolve(scene), alpha: self.alpha }
    }

    /// Both radii `[caustic, global]` at iteration `i` (1-based).
    pub fn radii(&self, scene: &Aabb, iteration: u32) -> [f64; 2] {
        PhotonMap::ALL.map(|m| self.schedule(m, scene).radius(iteration))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn closed_form_follows_recurrence() {
        for alpha in [0.5, 2.0 / 3.0, 0.7, 1.0] {
            let s = RadiusSchedule { initial: 0.05, alpha };
            let mut r = s.initial;
            for i in 1..=100_000u32 {
                let closed = s.radius(i);
                assert!((closed - r).abs() <= 1e-9 * r, "alpha {alpha} i {i}: {closed} vs {r}");
                // Squared radius ratio is exactly (i + α)/(i + 1).
                let next = s.next(r, i);
                assert!(((next * next) / (r * r) - (i as f64 + alpha) / (i as f64 + 1.0)).abs() < 1e-14);
                r = next;
            }
        }
    }

    #[test]
    fn asymptotics_and_clamps() {
        let s = RadiusSchedule { initial: 0.01, alpha: 2.0 / 3.0 };
        // r_i² Γ(1+α) i^{1−α} / r_1² → 1.
        let i = 100_000u32;
        let r = s.radius(i);
        let gamma = libm::tgamma(1.0 + 2.0 / 3.0);
        let lim = r * r * gamma * (i as f64).powf(1.0 / 3.0) / (0.01 * 0.01);
        assert!((lim - 1.0).abs() < 1e-4, "{lim}");
        assert_eq!(RadiusSchedule { initial: 1e-9, alpha: 0.5 }.radius(5), MIN_RADIUS);
        assert_eq!(RadiusSchedule { initial: f64::NAN, alpha: f64::NAN }.radius(5), MIN_RADIUS);
        assert_eq!(s.radius(0), s.radius(1));
        assert_eq!(s.radius(1), 0.01);
    }

    #[test]
    fn relative_spec() {
        let scene = Aabb { min: glam::DVec3::ZERO, max: glam::DVec3::new(3.0, 4.0, 0.0) };
        let cfg = ProgressiveConfig { caustic: RadiusSpec::RelativeToDiagonal(0.01), ..Default::default() };
        assert_eq!(cfg.radii(&scene, 1), [0.05, 0.05]);
    }
}
