//! Absorb and re-emit at diffuse hits (Fabianowski 2011, ARPA §4.1 eq. 2): one pair of
//! differentials is tracked through diffuse bounces by treating each bounce as absorption
//! and re-emission from a virtual point emitter placed `v` behind the hit.

use crate::differential::{DifferentialError, RayDifferential};
use crate::frame::Frame;
use glam::DVec3;

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
pub fn reemit(hit: DVec3, dp_du: DVec3, dp_dv: DVec3, direction: DVec3, reemission_length: f64) -> Result<RayDifferential, DifferentialError> {
    let area = dp_du.cross(dp_dv).length();
    let v = virtual_distance(area, reemission_length)?;
    let f = Frame::from_normal(direction);
    if !direction.is_finite() || !(direction.length() > 0.0) {
        return Err(DifferentialError::InvalidDirection);
    }
    let (du, dv) = (f.t * reemission_length, f.b * reemission_length);
    RayDifferential::new(hit, direction, du * v, dv * v, du, dv)
}
