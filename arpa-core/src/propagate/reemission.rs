//! Absorb and re-emit at diffuse hits (Fabianowski 2011, ARPA §4.1 eq. 2): one pair of
//! differentials is tracked through diffuse bounces by treating each bounce as absorption
//! and re-emission from a virtual point emitter placed `v` behind the hit.

use crate::propagate::differential::{DifferentialError, RayDifferential};
use crate::base::frame::Frame;
use crate::base::sampling::cosine_hemisphere;
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

/// [`reemit`] in a `direction` that is unit up to rounding already (as
/// [`diffuse_direction`] and [`crate::propagate::lambertian::DiffuseShading::sample_reemission`]
/// return it): the direction is neither checked nor renormalised, and it is the new
/// ray's direction and its frame's axis as given ([`Frame::from_unit_normal`]). Same
/// errors as [`reemit`] otherwise. The photon path's re-emission.
#[inline(always)]
pub fn reemit_unit(hit: DVec3, dp_du: DVec3, dp_dv: DVec3, direction: DVec3, reemission_length: f64) -> Result<RayDifferential, DifferentialError> {
    let area = dp_du.cross(dp_dv).length();
    let v = virtual_distance(area, reemission_length)?;
    let f = Frame::from_unit_normal(direction);
    let (du, dv) = (f.t * reemission_length, f.b * reemission_length);
    // As in `reemit`: only the positional differentials can overflow.
    RayDifferential::new_unit_with_finite_dd(hit, direction, du * v, dv * v, du, dv)
}

/// A cosine-distributed direction for re-emission from a Lambertian surface, in the
/// hemisphere of `normal` (unit, oriented towards the side the photon arrived from), from
/// the unit-square sample `u`. Density `cos θ / π`, so the photon's flux is multiplied by
/// the albedo only.
#[inline(always)]
pub fn diffuse_direction(normal: DVec3, u: DVec2) -> DVec3 {
    diffuse_direction_in(&Frame::from_normal(normal), u)
}

/// [`diffuse_direction`] about a `normal` that is unit and finite already (a prepared
/// triangle's face normal): the frame is built without renormalising it. The photon
/// path's form; [`diffuse_direction`] takes any normal (a zero or non-finite one gives the
/// hemisphere of +z). Alloc only, as the photon path.
#[cfg(feature = "alloc")]
#[inline(always)]
pub(crate) fn diffuse_direction_unit(normal: DVec3, u: DVec2) -> DVec3 {
    diffuse_direction_in(&Frame::from_unit_normal(normal), u)
}

#[inline(always)]
fn diffuse_direction_in(f: &Frame, u: DVec2) -> DVec3 {
    crate::base::frame::unit_or(f.to_world(cosine_hemisphere(u)), f.n)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn diffuse_direction_stays_on_the_lit_side() {
        let n = DVec3::new(0.3, -1.0, 0.2).normalize();
        let mut rng = crate::base::rng::Rng::new(0, 0, 0, crate::base::rng::StreamDomain::User);
        let mut mean_cos = 0.0;
        for _ in 0..10_000 {
            let d = diffuse_direction(n, rng.next_2d());
            assert!(d.dot(n) >= 0.0 && (d.length() - 1.0).abs() < 1e-12);
            mean_cos += d.dot(n);
        }
        assert!((mean_cos / 10_000.0 - 2.0 / 3.0).abs() < 0.01);
    }

    /// About a unit normal, the photon path's `diffuse_direction_unit` is
    /// `diffuse_direction` up to the rounding of the renormalisation it skips.
    #[test]
    fn diffuse_direction_unit_matches_diffuse_direction() {
        let mut rng = crate::base::rng::Rng::new(4, 5, 6, crate::base::rng::StreamDomain::User);
        for _ in 0..5_000 {
            let n = (rng.next_2d().extend(rng.next_f64()) - 0.5).normalize_or(DVec3::Z);
            let u = rng.next_2d();
            let (a, b) = (diffuse_direction(n, u), diffuse_direction_unit(n, u));
            assert!((a - b).length() <= 1e-15, "{a:?} vs {b:?}");
            assert!(b.dot(n) >= 0.0 && (b.length() - 1.0).abs() <= 1e-15);
        }
    }

    /// The photon path's `reemit_unit`, on the directions `diffuse_direction` gives, is
    /// `reemit` up to the rounding of the renormalisation it skips, and fails where
    /// `reemit` fails (a zero or non-finite footprint area, a zero length).
    #[test]
    fn reemit_unit_matches_reemit() {
        let mut rng = crate::base::rng::Rng::new(1, 2, 3, crate::base::rng::StreamDomain::User);
        for i in 0..5_000 {
            let n = (rng.next_2d().extend(rng.next_f64()) - 0.5).normalize_or(DVec3::Z);
            let dir = diffuse_direction(n, rng.next_2d());
            let scale = 10f64.powi(i % 7 - 4);
            let (du, dv) = ((rng.next_2d().extend(0.3) - 0.5) * scale, (rng.next_2d().extend(-0.2) - 0.5) * scale);
            let hit = DVec3::new(1.0, -2.0, 0.5);
            let len = 0.01 + rng.next_f64();
            let a = reemit(hit, du, dv, dir, len).unwrap();
            let b = reemit_unit(hit, du, dv, dir, len).unwrap();
            assert_eq!(b.d, dir);
            assert_eq!(b.p, hit);
            for (x, y) in [(a.d, b.d), (a.dd_du, b.dd_du), (a.dd_dv, b.dd_dv)] {
                assert!((x - y).length() <= 1e-15 * len.max(1.0), "{x:?} vs {y:?}");
            }
            for (x, y) in [(a.dp_du, b.dp_du), (a.dp_dv, b.dp_dv)] {
                assert!((x - y).length() <= 1e-15 * x.length().max(1e-300), "{x:?} vs {y:?}");
            }
            // Both directional differentials are perpendicular to the direction.
            assert!(b.dd_du.dot(b.d).abs() <= 1e-15 * len && b.dd_dv.dot(b.d).abs() <= 1e-15 * len);
        }
        let d = DVec3::Z;
        for (du, dv, len) in [(DVec3::X, DVec3::Y, 0.0), (DVec3::X * f64::INFINITY, DVec3::Y, 1.0), (DVec3::X * 1e300, DVec3::Y * 1e300, 1e-300)] {
            assert_eq!(reemit_unit(DVec3::ZERO, du, dv, d, len).err(), reemit(DVec3::ZERO, du, dv, d, len).err(), "{du:?} {dv:?} {len}");
            assert!(reemit_unit(DVec3::ZERO, du, dv, d, len).is_err());
        }
    }
}
