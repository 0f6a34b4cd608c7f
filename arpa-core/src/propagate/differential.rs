//! Ray differentials (Igehy 1999) as carried by every photon (ARPA eq. 1).
//!
//! A [`RayDifferential`] holds a point `P`, a unit direction `D` and, for the two
//! emission parameters `u` and `v`, the derivatives `∂P/∂u, ∂P/∂v, ∂D/∂u, ∂D/∂v`
//! (world space; positional derivatives in metres per unit parameter, directional ones in
//! radians per unit parameter). `u` and `v` never mix.
//!
//! Conventions, fixed once because sign mistakes here are a known trap (pbrt-v2 PR #38):
//! * `D` is the direction of travel (incoming at a surface, pointing *into* it).
//! * Normals may point either way; functions orient them as they need.
//! * For refraction, `ior` is the relative index of the side the normal points *away*
//!   from over the side it points *into* (`n_inside / n_outside` with an outward normal).
//!
//! Functions return `Err(DifferentialError)` when the differential cannot be propagated
//! (grazing transfer, non-finite result, …). The photon's *position and direction* stay
//! valid in that case ([`reflect_direction`], [`refract_direction`]); the caller marks the
//! photon as having lost its differential and stores it as a progressive photon from then on.

use glam::DVec3;

/// Why a differential could not be propagated.
#[derive(Clone, Copy, Debug, PartialEq, Eq, thiserror::Error)]
pub enum DifferentialError {
    /// The ray direction is zero, non-unit beyond repair, or not finite.
    #[error("ray direction is zero or not finite")]
    InvalidDirection,
    /// The surface normal is zero or not finite.
    #[error("surface normal is zero or not finite")]
    InvalidNormal,
    /// The travel distance is negative or not finite.
    #[error("travel distance is negative or not finite")]
    InvalidDistance,
    /// `|D·N|` is below [`MIN_ABS_COS`]: the transfer divides by it.
    #[error("ray grazes the surface: |D·N| is below the grazing limit")]
    Grazing,
    /// Refraction within [`MIN_REFRACTION_K`] of the critical angle, where `∂T` diverges.
    #[error("refraction too close to the critical angle")]
    NearCriticalAngle,
    /// The result overflowed or produced NaN (inputs of extreme magnitude).
    #[error("differential is not finite")]
    NonFinite,
}

/// Smallest `|D·N|` for which [`RayDifferential::transfer`] divides by `D·N`.
pub const MIN_ABS_COS: f64 = 1e-12;

/// Smallest `k = 1 − η²(1 − cos²θᵢ)` for which refraction differentials are computed; below
/// it (but ≥ 0) the refracted direction is still returned but its derivative, which grows
/// like `1/√k`, is reported as [`DifferentialError::NearCriticalAngle`].
pub const MIN_REFRACTION_K: f64 = 1e-12;

/// A ray with differentials with respect to two parameters `u` and `v` (see module docs).
///
/// # Example: transfer, reflect, refract
/// ```
/// use arpa_core::propagate::differential::{NormalDifferential, RayDifferential, RefractionEvent};
/// use arpa_core::glam::DVec3;
///
/// // Straight down from 1 m, the directions fanning out by 0.01 rad per unit u and v.
/// let ray = RayDifferential::new(DVec3::Z, -DVec3::Z, DVec3::ZERO, DVec3::ZERO, DVec3::X * 0.01, DVec3::Y * 0.01).unwrap();
/// // Transfer 1 m to the floor z = 0: the positional spread grows by t ∂D.
/// let floor = ray.transfer(1.0, DVec3::Z).unwrap();
/// assert!(floor.p.length() < 1e-15 && (floor.dp_du - DVec3::X * 0.01).length() < 1e-15);
/// // A flat mirror there sends it back up; the fan keeps opening: 2 cm after one more metre.
/// let up = floor.reflect(&NormalDifferential::flat(DVec3::Z)).unwrap();
/// assert!((up.d - DVec3::Z).length() < 1e-15);
/// let ceiling = up.transfer(1.0, -DVec3::Z).unwrap();
/// assert!((ceiling.dp_du - DVec3::X * 0.02).length() < 1e-15);
///
/// // Into glass (ior 1.5, outward normal +z) at 45°: Snell's law, sin θₜ = sin 45° / 1.5.
/// let slanted = RayDifferential::new(DVec3::Z, DVec3::new(1.0, 0.0, -1.0), DVec3::ZERO, DVec3::ZERO, DVec3::ZERO, DVec3::ZERO).unwrap();
/// let hit = slanted.transfer(1.0, DVec3::Z).unwrap();
/// let (inside, event) = hit.refract(&NormalDifferential::flat(DVec3::Z), 1.5).unwrap();
/// assert_eq!(event, RefractionEvent::Transmitted);
/// assert!((inside.d.x - core::f64::consts::FRAC_1_SQRT_2 / 1.5).abs() < 1e-15);
/// ```
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RayDifferential {
    /// Origin or current position (metres, world space).
    pub p: DVec3,
    /// Unit direction of travel (world space).
    pub d: DVec3,
    /// `∂P/∂u` (metres per unit `u`).
    pub dp_du: DVec3,
    /// `∂P/∂v` (metres per unit `v`).
    pub dp_dv: DVec3,
    /// `∂D/∂u` (per unit `u`; orthogonal to `d`).
    pub dd_du: DVec3,
    /// `∂D/∂v` (per unit `v`; orthogonal to `d`).
    pub dd_dv: DVec3,
}

/// A unit normal with its derivatives with respect to the photon's `u` and `v`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct NormalDifferential {
    /// Unit normal (world space, either orientation).
    pub n: DVec3,
    /// `∂N/∂u` (orthogonal to `n`).
    pub dn_du: DVec3,
    /// `∂N/∂v` (orthogonal to `n`).
    pub dn_dv: DVec3,
}

impl NormalDifferential {
    /// A normal that does not vary (flat surface): `∂N = 0`.
    #[inline]
    pub fn flat(n: DVec3) -> Self {
        Self { n, dn_du: DVec3::ZERO, dn_dv: DVec3::ZERO }
    }

    #[inline(always)]
    fn validated(&self) -> Result<Self, DifferentialError> {
        if !self.n.is_finite() || !self.dn_du.is_finite() || !self.dn_dv.is_finite() {
            return Err(DifferentialError::InvalidNormal);
        }
        let len = self.n.length();
        if !(len > 0.0) || !len.is_finite() {
            return Err(DifferentialError::InvalidNormal);
        }
        // Treat the input as an unnormalised normal m with derivatives ∂m: the unit normal's
        // derivative is (∂m − N (N·∂m)) / |m| (a no-op for an already-unit, consistent input).
        let n = self.n / len;
        let unit = |dm: DVec3| (dm - n * n.dot(dm)) / len;
        Ok(Self { n, dn_du: unit(self.dn_du), dn_dv: unit(self.dn_dv) })
    }

    fn flipped(self) -> Self {
        Self { n: -self.n, dn_du: -self.dn_du, dn_dv: -self.dn_dv }
    }
}

/// The event that produced a refracted ray.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum RefractionEvent {
    /// The ray crossed the interface.
    Transmitted,
    /// `k < 0`: total internal reflection; the ray and differential are the mirror ones.
    TotalInternalReflection,
}

/// Mirror reflection of direction `d` about normal `n` (either orientation, unit):
/// `R = D − 2 (D·N) N`.
#[inline]
pub fn reflect_direction(d: DVec3, n: DVec3) -> DVec3 {
    d - 2.0 * d.dot(n) * n
}

/// The refracted direction of unit `d` at unit normal `n` for relative index `ior`
/// (module conventions), with the relative index `η = n_incident / n_transmitted` used.
/// Returns the mirror direction and [`RefractionEvent::TotalInternalReflection`] when `k < 0`.
#[inline]
pub fn refract_direction(d: DVec3, n: DVec3, ior: f64) -> (DVec3, RefractionEvent, f64) {
    let (n, eta) = if d.dot(n) > 0.0 { (-n, ior) } else { (n, 1.0 / ior) };
    if !(eta > 0.0) || !eta.is_finite() {
        // No meaningful interface (ior 0 or non-finite): pass straight through.
        return (d, RefractionEvent::Transmitted, 1.0);
    }
    let cos_i = d.dot(n);
    let k = 1.0 - eta * eta * (1.0 - cos_i * cos_i);
    if k < 0.0 {
        return (reflect_direction(d, n), RefractionEvent::TotalInternalReflection, eta);
    }
    let mu = eta * cos_i + libm::sqrt(k);
    (crate::base::frame::unit_or(eta * d - mu * n, d), RefractionEvent::Transmitted, eta)
}

/// `true` when every component is finite, without a branch per component: `c − c` is
/// `+0` for finite `c` and NaN for an infinity or NaN, and a NaN survives the sum.
#[inline]
#[allow(clippy::eq_op)] // `c - c` is the finiteness test, not a zero
fn all_finite(v: &[DVec3]) -> bool {
    let zero = v.iter().fold(DVec3::ZERO, |acc, &c| acc + (c - c));
    zero.x + zero.y + zero.z == 0.0
}

/// `d` normalised: the cheap renormalisation when it is unit up to rounding (see
/// `frame::unit_or_zero`), else a division by its length; fails on a zero or non-finite
/// `d`. The result is always finite.
#[inline(always)]
fn unit_direction(d: DVec3) -> Result<DVec3, DifferentialError> {
    let len2 = d.length_squared();
    if (len2 - 1.0).abs() <= 1e-8 {
        Ok(d * (1.5 - 0.5 * len2))
    } else {
        let len = libm::sqrt(len2);
        if !(len > 0.0) || !len.is_finite() || !d.is_finite() {
            return Err(DifferentialError::InvalidDirection);
        }
        Ok(d / len)
    }
}

impl RayDifferential {
    /// A ray differential from its parts. `d` is normalised (its derivatives are assumed to
    /// be those of the unit direction already); fails on a zero or non-finite direction.
    #[inline(always)]
    pub fn new(p: DVec3, d: DVec3, dp_du: DVec3, dp_dv: DVec3, dd_du: DVec3, dd_dv: DVec3) -> Result<Self, DifferentialError> {
        Self { p, d: unit_direction(d)?, dp_du, dp_dv, dd_du, dd_dv }.checked()
    }

    /// [`RayDifferential::new`] for a caller whose direction differentials `dd_du`,
    /// `dd_dv` are finite by construction: only `p`, `dp_du` and `dp_dv` are checked (the
    /// normalised direction is finite whenever it is returned). Same result as `new` for
    /// such inputs.
    #[inline(always)]
    pub(crate) fn new_with_finite_dd(p: DVec3, d: DVec3, dp_du: DVec3, dp_dv: DVec3, dd_du: DVec3, dd_dv: DVec3) -> Result<Self, DifferentialError> {
        Self::new_unit_with_finite_dd(p, unit_direction(d)?, dp_du, dp_dv, dd_du, dd_dv)
    }

    /// [`RayDifferential::new_with_finite_dd`] for a `d` that is unit up to rounding
    /// already: `d` is taken as given (not checked, not renormalised).
    #[inline(always)]
    pub(crate) fn new_unit_with_finite_dd(p: DVec3, d: DVec3, dp_du: DVec3, dp_dv: DVec3, dd_du: DVec3, dd_dv: DVec3) -> Result<Self, DifferentialError> {
        if all_finite(&[p, dp_du, dp_dv]) { Ok(Self { p, d, dp_du, dp_dv, dd_du, dd_dv }) } else { Err(DifferentialError::NonFinite) }
    }

    /// From an *unnormalised* direction `w(u, v)` with derivatives `∂w/∂u`, `∂w/∂v`:
    /// `D = w/|w|`, `∂D = [(w·w) ∂w − (w·∂w) w] / (w·w)^{3/2}` (Igehy §1.2).
    pub fn from_unnormalised(p: DVec3, w: DVec3, dp_du: DVec3, dp_dv: DVec3, dw_du: DVec3, dw_dv: DVec3) -> Result<Self, DifferentialError> {
        let len = w.length();
        if !(len > 0.0) || !len.is_finite() {
            return Err(DifferentialError::InvalidDirection);
        }
        // Scale-free form: with d = w/|w|, ∂D = (∂w − (d·∂w) d) / |w|.
        let d = w / len;
        let dd = |dw: DVec3| (dw - d * d.dot(dw)) / len;
        Self { p, d, dp_du, dp_dv, dd_du: dd(dw_du), dd_dv: dd(dw_dv) }.checked()
    }

    /// `true` when every component is finite.
    #[inline]
    pub fn is_finite(&self) -> bool {
        all_finite(&[self.p, self.d, self.dp_du, self.dp_dv, self.dd_du, self.dd_dv])
    }

    #[inline]
    fn checked(self) -> Result<Self, DifferentialError> {
        if self.is_finite() { Ok(self) } else { Err(DifferentialError::NonFinite) }
    }

    /// Removes the component of `∂D` along `D`, restoring `D·∂D = 0`, the derivative of
    /// `|D| = 1`. Cheap guard against drift after many interactions.
    #[inline]
    pub fn reprojected(mut self) -> Self {
        self.dd_du -= self.d * self.d.dot(self.dd_du);
        self.dd_dv -= self.d * self.d.dot(self.dd_dv);
        self
    }

    /// Transfer over distance `t` (metres) to a surface whose unit normal at
    /// `P' = P + tD` is `n` (use the geometric normal so that the footprint lies in the
    /// surface plane; either orientation):
    ///
    /// `∂t = −[(∂P + t ∂D)·N] / (D·N)`, `∂P' = ∂P + t ∂D + ∂t D`, `∂D' = ∂D`.
    ///
    /// Afterwards `∂P'·N = 0`. Valid for any surface (Igehy's addendum).
    pub fn transfer(&self, t: f64, n: DVec3) -> Result<Self, DifferentialError> {
        if !(t >= 0.0) || !t.is_finite() {
            return Err(DifferentialError::InvalidDistance);
        }
        let n = n.normalize_or_zero();
        if n == DVec3::ZERO || !n.is_finite() {
            return Err(DifferentialError::InvalidNormal);
        }
        self.transfer_unit_normal(t, n)
    }

    /// [`RayDifferential::transfer`] to a surface whose normal `n` is unit already (a
    /// cached triangle normal): skips the normalisation, which may move a unit `n` by an
    /// ulp. Errors like `transfer` (a zero or non-finite `n` is an invalid normal).
    #[inline]
    pub fn transfer_unit_normal(&self, t: f64, n: DVec3) -> Result<Self, DifferentialError> {
        if !(t >= 0.0) || !t.is_finite() {
            return Err(DifferentialError::InvalidDistance);
        }
        if n == DVec3::ZERO || !n.is_finite() {
            return Err(DifferentialError::InvalidNormal);
        }
        self.transfer_valid(t, n)
    }

    /// [`RayDifferential::transfer_unit_normal`] to a surface whose `n` is known to be unit
    /// and finite (a [`crate::render::prepared_scene::SurfacePoint`]'s geometric normal, which
    /// [`crate::render::prepared_scene::PreparedScene`] keeps unit, `+y` on a degenerate triangle):
    /// skips the check of `n`. The photon path's transfer (alloc only, as the photon path).
    #[cfg(feature = "alloc")]
    #[inline(always)]
    pub(crate) fn transfer_finite_unit_normal(&self, t: f64, n: DVec3) -> Result<Self, DifferentialError> {
        debug_assert!(n.is_finite() && n != DVec3::ZERO, "{n:?}");
        if !(t >= 0.0) || !t.is_finite() {
            return Err(DifferentialError::InvalidDistance);
        }
        self.transfer_valid(t, n)
    }

    /// The transfer once `t` (finite, `≥ 0`) and the unit `n` have been checked.
    #[inline(always)]
    fn transfer_valid(&self, t: f64, n: DVec3) -> Result<Self, DifferentialError> {
        let cos = self.d.dot(n);
        if !(cos.abs() >= MIN_ABS_COS) {
            return Err(DifferentialError::Grazing);
        }
        // |cos| ≥ MIN_ABS_COS, so its reciprocal is finite: one division for both steps.
        let inv_cos = 1.0 / cos;
        let step = |dp: DVec3, dd: DVec3| {
            let offset = dp + t * dd;
            let dt = -offset.dot(n) * inv_cos;
            let moved = offset + dt * self.d;
            // Remove the rounding residue along n so the footprint lies exactly in the plane.
            moved - n * moved.dot(n)
        };
        let out = Self {
            p: self.p + t * self.d,
            d: self.d,
            dp_du: step(self.dp_du, self.dd_du),
            dp_dv: step(self.dp_dv, self.dd_dv),
            dd_du: self.dd_du,
            dd_dv: self.dd_dv,
        };
        // Checking the three new vectors is checking all six: a non-finite `D` fails the
        // grazing test above or makes `P'` = `P + tD` non-finite (t·∞ is ∞, 0·∞ is NaN), and
        // a non-finite `∂D` makes its `∂P'` non-finite the same way (through `t ∂D`).
        if all_finite(&[out.p, out.dp_du, out.dp_dv]) { Ok(out) } else { Err(DifferentialError::NonFinite) }
    }

    /// Specular reflection about the shading normal `normal` (with its derivatives):
    ///
    /// `∂(D·N) = ∂D·N + D·∂N`, `∂R = ∂D − 2[(D·N) ∂N + ∂(D·N) N]`, `∂P` unchanged.
    ///
    /// Invariant under `N → −N`.
    #[inline(always)]
    pub fn reflect(&self, normal: &NormalDifferential) -> Result<Self, DifferentialError> {
        let nd = normal.validated()?;
        Ok(self.reflect_unchecked(&nd)?.reprojected())
    }

    #[inline(always)]
    fn reflect_unchecked(&self, nd: &NormalDifferential) -> Result<Self, DifferentialError> {
        let n = nd.n;
        let dn = self.d.dot(n);
        let dr = |dd: DVec3, dnx: DVec3| {
            let d_dn = dd.dot(n) + self.d.dot(dnx);
            dd - 2.0 * (dn * dnx + d_dn * n)
        };
        Self {
            p: self.p,
            d: crate::base::frame::unit_or(reflect_direction(self.d, n), self.d),
            dp_du: self.dp_du,
            dp_dv: self.dp_dv,
            dd_du: dr(self.dd_du, nd.dn_du),
            dd_dv: dr(self.dd_dv, nd.dn_dv),
        }
        .checked()
    }

    /// Specular refraction through the shading normal (with derivatives) for relative index
    /// `ior` (module conventions; both orientations handled: entering uses `η = 1/ior`,
    /// leaving `η = ior`). With `N` oriented against `D` and `k = 1 − η²(1 − (D·N)²)`:
    ///
    /// `T·N = −√k`, `μ = η(D·N) − T·N`, `T = ηD − μN`,
    /// `∂μ = [η − η²(D·N)/(T·N)] ∂(D·N)`, `∂T = η∂D − [μ∂N + ∂μ N]`, `∂P` unchanged.
    ///
    /// Total internal reflection (`k < 0`) falls back to [`RayDifferential::reflect`] and is
    /// reported in the returned event.
    #[inline]
    pub fn refract(&self, normal: &NormalDifferential, ior: f64) -> Result<(Self, RefractionEvent), DifferentialError> {
        let mut nd = normal.validated()?;
        if !(ior > 0.0) || !ior.is_finite() {
            return Err(DifferentialError::NonFinite);
        }
        let eta = if self.d.dot(nd.n) > 0.0 {
            nd = nd.flipped();
            ior
        } else {
            1.0 / ior
        };
        let n = nd.n;
        let cos_i = self.d.dot(n);
        let k = 1.0 - eta * eta * (1.0 - cos_i * cos_i);
        if k < 0.0 {
            return Ok((self.reflect_unchecked(&nd)?.reprojected(), RefractionEvent::TotalInternalReflection));
        }
        if k < MIN_REFRACTION_K {
            return Err(DifferentialError::NearCriticalAngle);
        }
        let cos_t = -libm::sqrt(k);
        let mu = eta * cos_i - cos_t;
        let dmu_factor = eta - eta * eta * cos_i / cos_t;
        let dt = |dd: DVec3, dnx: DVec3| {
            let d_dn = dd.dot(n) + self.d.dot(dnx);
            eta * dd - (mu * dnx + dmu_factor * d_dn * n)
        };
        let out = Self {
            p: self.p,
            d: crate::base::frame::unit_or(eta * self.d - mu * n, self.d),
            dp_du: self.dp_du,
            dp_dv: self.dp_dv,
            dd_du: dt(self.dd_du, nd.dn_du),
            dd_dv: dt(self.dd_dv, nd.dn_dv),
        }
        .checked()?;
        Ok((out.reprojected(), RefractionEvent::Transmitted))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_relative_eq;

    fn ray() -> RayDifferential {
        RayDifferential::new(
            DVec3::new(0.1, 2.0, -0.3),
            DVec3::new(0.2, -1.0, 0.1),
            DVec3::new(0.01, 0.0, 0.0),
            DVec3::new(0.0, 0.0, 0.02),
            DVec3::new(0.03, 0.0, 0.0),
            DVec3::new(0.0, 0.01, 0.04),
        )
        .unwrap()
        .reprojected()
    }

    /// The photon path's transfer (the normal's check skipped) gives the bits of
    /// `transfer_unit_normal` on unit normals, and the same errors for bad distances and
    /// grazing incidence.
    #[test]
    fn transfer_to_a_known_unit_normal_is_transfer_unit_normal() {
        let r = ray();
        for n in [DVec3::Y, DVec3::new(0.3, 0.9, -0.2).normalize(), DVec3::new(-1.0, 0.2, 0.1).normalize(), DVec3::new(1.0, 0.2, 0.0).normalize()] {
            for t in [0.0, 0.5, 3.0, -1.0, f64::NAN, f64::INFINITY] {
                assert_eq!(r.transfer_finite_unit_normal(t, n), r.transfer_unit_normal(t, n), "t {t}, n {n:?}");
            }
        }
        let grazing = DVec3::new(1.0, 0.2, 0.0).cross(r.d).normalize();
        assert_eq!(r.transfer_finite_unit_normal(1.0, grazing), Err(DifferentialError::Grazing));
    }

    #[test]
    fn transfer_lands_in_plane() {
        let r = ray().transfer(1.7, DVec3::new(0.1, 1.0, 0.0)).unwrap();
        let n = DVec3::new(0.1, 1.0, 0.0).normalize();
        assert!(r.dp_du.dot(n).abs() < 1e-15);
        assert!(r.dp_dv.dot(n).abs() < 1e-15);
    }

    #[test]
    fn reflection_is_orientation_invariant() {
        let nd = NormalDifferential { n: DVec3::new(0.0, 1.0, 0.2).normalize(), dn_du: DVec3::new(0.1, 0.0, 0.0), dn_dv: DVec3::ZERO };
        let a = ray().reflect(&nd).unwrap();
        let b = ray().reflect(&nd.flipped()).unwrap();
        assert_relative_eq!(a.d, b.d, epsilon = 1e-15);
        assert_relative_eq!(a.dd_du, b.dd_du, epsilon = 1e-15);
    }

    #[test]
    fn tir_falls_back_to_reflection() {
        // Leaving glass (ior 1.5) at 60 degrees incidence: beyond the critical angle 41.8.
        let d = DVec3::new(libm::sin(1.047), libm::cos(1.047), 0.0);
        let r = RayDifferential::new(DVec3::ZERO, d, DVec3::X, DVec3::Z, DVec3::ZERO, DVec3::ZERO).unwrap();
        let nd = NormalDifferential::flat(DVec3::Y);
        let (out, ev) = r.refract(&nd, 1.5).unwrap();
        assert_eq!(ev, RefractionEvent::TotalInternalReflection);
        assert_relative_eq!(out.d, reflect_direction(d, DVec3::Y), epsilon = 1e-15);
        let (dir, ev2, _) = refract_direction(d, DVec3::Y, 1.5);
        assert_eq!(ev2, RefractionEvent::TotalInternalReflection);
        assert_relative_eq!(dir, out.d, epsilon = 1e-15);
    }

    #[test]
    fn snell_holds_both_ways() {
        for &(d, ior) in &[(DVec3::new(0.5, -1.0, 0.0), 1.5), (DVec3::new(0.3, 1.0, 0.1), 1.33)] {
            let d = d.normalize();
            let (t, ev, eta) = refract_direction(d, DVec3::Y, ior);
            assert_eq!(ev, RefractionEvent::Transmitted);
            let sin_i = d.cross(DVec3::Y).length();
            let sin_t = t.cross(DVec3::Y).length();
            assert_relative_eq!(sin_t, eta * sin_i, epsilon = 1e-12);
            // Transmitted ray continues to the far side.
            assert!(t.y * d.y > 0.0);
        }
    }

    #[test]
    fn bad_inputs_are_labelled() {
        let r = ray();
        assert_eq!(r.transfer(-1.0, DVec3::Y), Err(DifferentialError::InvalidDistance));
        assert_eq!(r.transfer(f64::NAN, DVec3::Y), Err(DifferentialError::InvalidDistance));
        assert_eq!(r.transfer(1.0, DVec3::ZERO), Err(DifferentialError::InvalidNormal));
        let grazing = RayDifferential::new(DVec3::ZERO, DVec3::X, DVec3::Y, DVec3::Z, DVec3::ZERO, DVec3::ZERO).unwrap();
        assert_eq!(grazing.transfer(1.0, DVec3::Y), Err(DifferentialError::Grazing));
        assert_eq!(r.reflect(&NormalDifferential::flat(DVec3::NAN)), Err(DifferentialError::InvalidNormal));
        assert_eq!(RayDifferential::new(DVec3::ZERO, DVec3::ZERO, DVec3::X, DVec3::X, DVec3::X, DVec3::X), Err(DifferentialError::InvalidDirection));
    }
}
