//! Absorb and re-emit at diffuse hits (Fabianowski 2011, ARPA §4.1 eq. 2): one pair of
//! differentials is tracked through diffuse bounces by treating each bounce as absorption
//! and re-emission from a virtual point emitter placed `v` behind the hit.

use crate::differential::{DifferentialError, RayDifferential};
use crate::frame::Frame;
use crate::sampling::cosine_hemisphere;
use glam::{DVec2, DVec3};

/// Virtual distance `v = √(|D_u × D_v| / |D_φω' × D_θω'|)` (ARPA eq. 2) with both new
/// directional differentials of length `reemission_length` (so the denominator is
/// `reemission_length²`). Metres. Errors on a zero or non-finite length.
pub fn virtual_distance(parallelogram_area: f64, reemission_length: f64) -> Result<f64, DifferentialError> {
    if !(reemission_length > 0.0) || !reemission_length.is_finite() || !(parallelogram_area >= 0.0) || !parallelogram_area.is_finite() {
        return Err(DifferentialError::NonFinite);
    }
    let v = libm::sqrt(parallelogram_area) / reemission_length;
    if v.is_finite() { Ok(v) } else { Err(DifferentialError::NonFinite) }
}

/// Re-emits a photon absorbed with positional differentials `dp_du`, `dp_dv` at `hit`,
/// in the new unit `direction`. The directional differentials are reset to
/// `reemission_length` along a frame perpendicular to `direction`, and the positional
/// ones to `v` times them, so the photon behaves like a point emitter `v` behind `hit`:
/// after a transfer over `t` its differential is `(v + t) ∂D`, and at `t = 0` the
/// footprint area equals the absorbed one.
///
/// Uses the photon's own (unsmoothed, un-dampened) footprint, so the smoothing factor and
/// heuristics, which shape only what is *stored*, do not compound along a path.
#[inline(always)]
pub fn reemit(hit: DVec3, dp_du: DVec3, dp_dv: DVec3, direction: DVec3, reemission_length: f64) -> Result<RayDifferential, DifferentialError> {
    let area = dp_du.cross(dp_dv).length();
    let v = virtual_distance(area, reemission_length)?;
    let f = Frame::from_normal(direction);
    if !direction.is_finite() || !(direction.length_squared() > 0.0) {
        return Err(DifferentialError::InvalidDirection);
    }
    let (du, dv) = (f.t * reemission_length, f.b * reemission_length);
    // `du`, `dv` are finite: unit frame vectors (from a finite direction) times a finite
    // length. Only the positional ones, scaled by `v`, can overflow.
    RayDifferential::new_with_finite_dd(hit, direction, du * v, dv * v, du, dv)
}

/// A cosine-distributed direction for re-emission from a Lambertian surface, in the
/// hemisphere of `normal` (unit, oriented towards the side the photon arrived from), from
/// the unit-square sample `u`. Density `cos θ / π`, so the photon's flux is multiplied by
/// the albedo only.
#[inline(always)]
pub fn diffuse_direction(normal: DVec3, u: DVec2) -> DVec3 {
    let f = Frame::from_normal(normal);
    crate::frame::unit_or(f.to_world(cosine_hemisphere(u)), f.n)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn diffuse_direction_stays_on_the_lit_side() {
        let n = DVec3::new(0.3, -1.0, 0.2).normalize();
        let mut rng = crate::rng::Rng::new(0, 0, 0, crate::rng::StreamDomain::User);
        let mut mean_cos = 0.0;
        for _ in 0..10_000 {
            let d = diffuse_direction(n, rng.next_2d());
            assert!(d.dot(n) >= 0.0 && (d.length() - 1.0).abs() < 1e-12);
            mean_cos += d.dot(n);
        }
        assert!((mean_cos / 10_000.0 - 2.0 / 3.0).abs() < 0.01);
    }
}
