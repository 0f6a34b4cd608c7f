//! Photon footprints: the ellipse a photon differential leaves on a diffuse surface, the
//! filter-space transform `M_p⁻¹` (ARPA eq. 3, after Frisvad et al. 2014), the
//! point-in-footprint test, the kernel weight and the acceleration-structure box.
//!
//! With `a = D_u/2` and `b = D_v/2` the footprint is the ellipse
//! `{x_p + a cos θ + b sin θ}` in the surface's tangent plane (`a`, `b` are conjugate
//! semi-diameters, not necessarily orthogonal). Its area is `π|a × b| = (π/4)|D_u × D_v|`.
//!
//! Any orthogonal re-mixing `(D_u, D_v) ↦ (D_u, D_v) Q` (`QᵀQ = I`) spans the same ellipse
//! and the same filter (`M_p⁻¹` changes by a rotation or reflection of filter space, so
//! `|M_p⁻¹ Δ|`, the density and the box do not change). Everything here that describes the
//! footprint's shape therefore goes through the ellipse's principal axes
//! ([`principal_axes`]), not through the lengths of `D_u` and `D_v`.

use crate::base::aabb::Aabb;
use crate::propagate::differential::RayDifferential;
use crate::gather::kernel::Kernel;
use core::f64::consts::PI;
use glam::{DVec2, DVec3, Vec3};

/// Which photon map a stored photon belongs to.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
#[repr(u32)]
pub enum PhotonMap {
    /// Paths `L S⁺ D`: at least one specular event and no diffuse event before this hit.
    Caustic = 0,
    /// Every other diffuse hit, including direct `L D` hits.
    Global = 1,
}

impl PhotonMap {
    /// Both maps, in index order.
    pub const ALL: [PhotonMap; 2] = [PhotonMap::Caustic, PhotonMap::Global];

    /// Index 0 (caustic) or 1 (global), for per-map arrays.
    #[inline]
    pub const fn index(self) -> usize {
        self as usize
    }

    /// Inverse of [`PhotonMap::index`] (anything but 0 is global).
    #[inline]
    pub const fn from_index(i: u32) -> Self {
        if i == 0 { PhotonMap::Caustic } else { PhotonMap::Global }
    }
}

/// Why a footprint cannot be used as an ellipse.
#[derive(Clone, Copy, Debug, PartialEq, Eq, thiserror::Error)]
pub enum FootprintError {
    /// `D_u` and `D_v` are parallel or zero (or not finite): `M_p⁻¹` does not exist.
    #[error("footprint differentials are parallel, zero or not finite")]
    Degenerate,
    /// The surface normal is zero or not finite.
    #[error("footprint normal is zero or not finite")]
    InvalidNormal,
    /// The ellipse cannot be resolved in `f32` storage: its minor semi-axis is below
    /// [`MIN_RELATIVE_SEMI_AXIS`] times the magnitude of its centre, or a stored value
    /// overflows `f32`.
    #[error("footprint too small or too large for f32 storage")]
    Unrepresentable,
}

/// Smallest minor semi-axis (its lower bound [`Footprint::minor_semi_axis_bound`]) of a
/// storable footprint relative to `max(|x_p|_∞, 1e-30)` (64 `f32` ulps): below it
/// `q − x_p` computed in `f32` no longer resolves the ellipse.
pub const MIN_RELATIVE_SEMI_AXIS: f64 = 64.0 * f32::EPSILON as f64;

/// A photon footprint in double precision: what the heuristics operate on.
///
/// # Example: filter transform and density
/// An ellipse with conjugate semi-diameters `D_u/2`, `D_v/2` on the floor: `M_p⁻¹` maps
/// them to the unit vectors, and the density `W_p` integrates to 1 over the plane, so a
/// footprint spreads exactly its flux.
/// ```
/// use arpa_core::store::footprint::{Footprint, PhotonMap};
/// use arpa_core::glam::{DVec2, DVec3};
/// use arpa_core::gather::kernel::Kernel;
///
/// let fp = Footprint {
///     center: DVec3::ZERO,
///     normal: DVec3::Z,
///     du: DVec3::new(0.2, 0.0, 0.0),
///     dv: DVec3::new(0.05, 0.1, 0.0), // sheared: not perpendicular to D_u
///     flux: DVec3::ONE,
///     map: PhotonMap::Caustic,
/// };
/// let m = fp.filter_transform().unwrap();
/// assert!((m.apply(fp.du * 0.5) - DVec2::X).length() < 1e-12);
/// assert!((m.apply(fp.dv * 0.5) - DVec2::Y).length() < 1e-12);
/// // ∫ W_p dA over a grid covering the ellipse (1 mm cells); the slab limit 0.01 m only
/// // bounds the thickness along the normal.
/// let cell = 1e-3;
/// let integral: f64 = (-150..150)
///     .flat_map(|i| (-100..100).map(move |j| DVec3::new((i as f64 + 0.5) * cell, (j as f64 + 0.5) * cell, 0.0)))
///     .map(|q| fp.weight(q, 0.01, Kernel::Silverman) * cell * cell)
///     .sum();
/// assert!((integral - 1.0).abs() < 0.01, "{integral}");
/// ```
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Footprint {
    /// Centre `x_p` (metres, world space).
    pub center: DVec3,
    /// Unit surface normal `n_p`, oriented towards the side the photon arrived from.
    pub normal: DVec3,
    /// Positional differential `D_u` in the tangent plane (metres).
    pub du: DVec3,
    /// Positional differential `D_v` in the tangent plane (metres).
    pub dv: DVec3,
    /// Flux carried (W, linear RGB).
    pub flux: DVec3,
    /// Map the photon is stored in.
    pub map: PhotonMap,
}

/// The first two rows of `M_p⁻¹` (1/metres): `y = M_p⁻¹ (q − x_p)` maps `D_u/2 ↦ (1,0)`,
/// `D_v/2 ↦ (0,1)` and the normal to 0.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FilterTransform {
    /// `2 (D_v × n) / (D_u · (D_v × n))`.
    pub row_u: DVec3,
    /// `2 (n × D_u) / (D_u · (D_v × n))`.
    pub row_v: DVec3,
}

impl FilterTransform {
    /// Filter-space coordinates of the offset `delta = q − x_p`.
    #[inline]
    pub fn apply(&self, delta: DVec3) -> DVec2 {
        DVec2::new(self.row_u.dot(delta), self.row_v.dot(delta))
    }

    /// Jacobian of the map restricted to the tangent plane, `|row_u × row_v|`, which equals
    /// `4/|D_u × D_v|` (1/m²): the factor that turns a unit-disc kernel into a density
    /// over the ellipse.
    #[inline]
    pub fn determinant(&self) -> f64 {
        self.row_u.cross(self.row_v).length()
    }
}

impl Footprint {
    /// The footprint of a photon whose differential has just been transferred onto a
    /// surface with geometric normal `geometric_normal` (either orientation). The normal
    /// is oriented towards the arriving photon and the differentials are projected into
    /// the tangent plane.
    #[inline(always)]
    pub fn from_hit(ray: &RayDifferential, geometric_normal: DVec3, flux: DVec3, map: PhotonMap) -> Result<Self, FootprintError> {
        let n = crate::base::frame::unit_or_zero(geometric_normal);
        if n == DVec3::ZERO || !n.is_finite() {
            return Err(FootprintError::InvalidNormal);
        }
        // The projection is exactly invariant under n → −n, so it does not wait for the
        // orientation test.
        let project = |v: DVec3| v - n * n.dot(v);
        let (du, dv) = (project(ray.dp_du), project(ray.dp_dv));
        let n = if ray.d.dot(n) > 0.0 { -n } else { n };
        Ok(Self { center: ray.p, normal: n, du, dv, flux, map })
    }

    /// [`Footprint::from_hit`] for a ray that [`RayDifferential::transfer_unit_normal`]
    /// just moved onto the surface with this unit `normal` (either orientation): its
    /// positional differentials already lie in the tangent plane (the transfer removes
    /// their component along `normal`) and the normal is unit and finite, so nothing is
    /// projected or normalised again. The photon pass's path.
    #[inline(always)]
    pub fn from_transferred(ray: &RayDifferential, normal: DVec3, flux: DVec3, map: PhotonMap) -> Self {
        let n = if ray.d.dot(normal) > 0.0 { -normal } else { normal };
        Self { center: ray.p, normal: n, du: ray.dp_du, dv: ray.dp_dv, flux, map }
    }

    /// Both differentials scaled by `s` (the smoothing factor `S`); the flux is unchanged.
    #[inline]
    pub fn scaled(mut self, s: f64) -> Self {
        self.du *= s;
        self.dv *= s;
        self
    }

    /// `|D_u × D_v|`: area of the parallelogram spanned by the differentials (m²).
    #[inline]
    pub fn parallelogram_area(&self) -> f64 {
        self.du.cross(self.dv).length()
    }

    /// Area of the footprint ellipse, `(π/4)|D_u × D_v|` (m²).
    #[inline]
    pub fn area(&self) -> f64 {
        0.25 * PI * self.parallelogram_area()
    }

    /// Lengths `(|D_major|, |D_minor|)` of the longer and shorter differential (metres).
    /// These depend on how `D_u`, `D_v` parametrise the ellipse; its axes are
    /// [`Footprint::principal_axes`].
    #[inline]
    pub fn major_minor(&self) -> (f64, f64) {
        let (a, b) = (self.du.length(), self.dv.length());
        if a >= b { (a, b) } else { (b, a) }
    }

    /// Principal semi-axes `(σ₁, σ₂)` of the ellipse (metres): see [`principal_axes`].
    #[inline]
    pub fn semi_axes(&self) -> (f64, f64) {
        let (l1, l2) = self.axis_lengths();
        (0.5 * l1, 0.5 * l2)
    }

    /// Full lengths `(2σ₁, 2σ₂)` of the ellipse's principal axes (metres), the lengths of
    /// the principal differentials ([`PrincipalAxes::differentials`]).
    #[inline]
    pub fn axis_lengths(&self) -> (f64, f64) {
        principal_lengths(self.du.length_squared(), self.dv.length_squared(), self.du.dot(self.dv), self.parallelogram_area())
    }

    /// The ellipse's principal axes ([`principal_axes`] of `D_u`, `D_v` around the normal).
    #[inline]
    pub fn principal_axes(&self) -> PrincipalAxes {
        principal_axes(self.du, self.dv, self.normal)
    }

    /// The same footprint with `D_u`, `D_v` replaced by its principal differentials
    /// `2σ₁e₁`, `2σ₂e₂` ([`PrincipalAxes::differentials`]): the same ellipse, orientation,
    /// density and box, with orthogonal differentials along the axes.
    #[inline]
    pub fn to_principal(self) -> Self {
        let (du, dv) = self.principal_axes().differentials();
        Self { du, dv, ..self }
    }

    /// `M_p⁻¹` (ARPA eq. 3). Errors when `D_u`, `D_v` are parallel or zero.
    pub fn filter_transform(&self) -> Result<FilterTransform, FootprintError> {
        let dv_n = self.dv.cross(self.normal);
        let den = self.du.cross(self.dv).dot(self.normal);
        if degenerate_denominator(den, self.du.length_squared(), self.dv.length_squared()) {
            return Err(FootprintError::Degenerate);
        }
        let s = 2.0 / den;
        let t = FilterTransform { row_u: dv_n * s, row_v: self.normal.cross(self.du) * s };
        if t.row_u.is_finite() && t.row_v.is_finite() { Ok(t) } else { Err(FootprintError::Degenerate) }
    }

    /// Half-thickness of the footprint along its normal: the minor semi-axis `σ₂` (half
    /// the minor principal differential), clamped to `slab_limit` (metres; a photon pass
    /// passes the map's current progressive radius, ARPA §4.2, fig. 3), but never thinner
    /// than `f32` can resolve at the footprint's position ([`half_thickness`]), in metres.
    /// `slab_limit` only bounds this thickness: the ellipse, its density and the in-plane
    /// extent do not depend on it. A function of the ellipse alone (the same for any
    /// orthogonal re-mixing of `D_u`, `D_v`).
    #[inline]
    pub fn half_thickness(&self, slab_limit: f64) -> f64 {
        let (major, minor) = self.axis_lengths();
        half_thickness(self.center, major, minor, slab_limit)
    }

    /// `true` if `q` lies inside the ellipse (`|M_p⁻¹(q − x_p)| ≤ 1`) and within the
    /// slab `|n·(q − x_p)| ≤ h` of [`Footprint::half_thickness`]`(slab_limit)` (metres).
    pub fn contains(&self, q: DVec3, slab_limit: f64) -> bool {
        let Ok(m) = self.filter_transform() else { return false };
        let delta = q - self.center;
        m.apply(delta).length_squared() <= 1.0 && self.normal.dot(delta).abs() <= self.half_thickness(slab_limit)
    }

    /// The footprint's density at `q`: `W_p(q) = 4/|D_u × D_v| · K(|M_p⁻¹(q − x_p)|²)`
    /// (1/m²), zero outside the ellipse or the slab of
    /// [`Footprint::half_thickness`]`(slab_limit)` (metres). Irradiance contributed is
    /// `Φ_p W_p(q)` ([`Footprint::irradiance`] adds the facing test).
    pub fn weight(&self, q: DVec3, slab_limit: f64, kernel: Kernel) -> f64 {
        let Ok(m) = self.filter_transform() else { return 0.0 };
        let delta = q - self.center;
        if self.normal.dot(delta).abs() > self.half_thickness(slab_limit) {
            return 0.0;
        }
        m.determinant() * kernel.eval_f64(m.apply(delta).length_squared())
    }

    /// Irradiance (W/m², RGB) this footprint contributes at `q` (metres) with unit normal
    /// `query_normal`, in `f64`: `Φ_p W_p(q)` ([`Footprint::weight`] with `slab_limit`)
    /// when the query sees the lit side (`n · query_normal > 0`), else 0. The `f64` twin
    /// of [`PackedFootprint::irradiance`], for estimates before packing.
    pub fn irradiance(&self, q: DVec3, query_normal: DVec3, slab_limit: f64, kernel: Kernel) -> DVec3 {
        if !(self.normal.dot(query_normal) > 0.0) {
            return DVec3::ZERO;
        }
        let e = self.flux * self.weight(q, slab_limit, kernel);
        if e.is_finite() { e } else { DVec3::ZERO }
    }

    /// Bounding box for the acceleration structure: `x_p ± e` with
    /// `e_k = √(a_k² + b_k²) + |h n_k|`, the exact box of the elliptic slab the
    /// point-in-footprint test accepts (ellipse with conjugate semi-diameters
    /// `a = D_u/2`, `b = D_v/2`, extruded by `±h n`, `h` =
    /// [`Footprint::half_thickness`]`(slab_limit)`), in metres.
    #[inline]
    pub fn aabb(&self, slab_limit: f64) -> Aabb {
        let a = 0.5 * self.du;
        let b = 0.5 * self.dv;
        let h = self.normal * self.half_thickness(slab_limit);
        let e = (a * a + b * b).map(libm::sqrt) + h.abs();
        Aabb::from_centre_half_extent(self.center, e)
    }

    /// A lower bound of the minor semi-axis `σ₂`: `|a × b| / √(|a|² + |b|²)` with
    /// `a = D_u/2`, `b = D_v/2` (metres). `σ₂` lies between it and `√2` times it; it needs
    /// no eigen-decomposition, so the storage check stays cheap.
    #[inline]
    pub fn minor_semi_axis_bound(&self) -> f64 {
        let norm2 = 0.25 * (self.du.length_squared() + self.dv.length_squared());
        if !(norm2 > 0.0) {
            return 0.0;
        }
        0.25 * self.du.cross(self.dv).length() / libm::sqrt(norm2)
    }

    /// The `f32` record the gather reads (see [`PackedFootprint`]), with the slab
    /// half-thickness of [`Footprint::half_thickness`]`(slab_limit)` (metres; the map's
    /// current progressive radius in a photon pass). Fails when `M_p⁻¹` does not
    /// exist, or when `f32` cannot resolve the ellipse: [`Footprint::minor_semi_axis_bound`]
    /// below [`MIN_RELATIVE_SEMI_AXIS`] times the largest centre coordinate, or a stored
    /// value overflows.
    pub fn pack(&self, slab_limit: f64) -> Result<PackedFootprint, FootprintError> {
        let la2 = self.du.length_squared();
        let lb2 = self.dv.length_squared();
        let cross = self.du.cross(self.dv);
        let den = cross.dot(self.normal);
        if degenerate_denominator(den, la2, lb2) {
            return Err(FootprintError::Degenerate);
        }
        let (major, minor) = principal_lengths(la2, lb2, self.du.dot(self.dv), cross.length());
        let h = half_thickness(self.center, major, minor, slab_limit);
        pack_parts(self, la2, lb2, cross, den, h)
    }
}

/// The principal axes of a footprint ellipse (see [`principal_axes`]): semi-axes in
/// metres, unit directions in world space, in the tangent plane.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PrincipalAxes {
    /// Semi-major axis `σ₁ ≥ σ₂` (metres).
    pub semi_major: f64,
    /// Semi-minor axis `σ₂ = |a × b|/σ₁` (metres): 0 for parallel or zero differentials.
    pub semi_minor: f64,
    /// Unit direction `e₁` of the major axis (world space, tangent plane); zero when
    /// both differentials are zero.
    pub major_dir: DVec3,
    /// Unit direction `e₂ = ±n × e₁` of the minor axis (world space, tangent plane), the
    /// sign chosen so that `(e₁ × e₂)·n` has the sign of `(D_u × D_v)·n` (positive when
    /// that is 0): the principal differentials keep the footprint's orientation.
    pub minor_dir: DVec3,
}

impl PrincipalAxes {
    /// The principal differentials `(D₁, D₂) = (2σ₁e₁, 2σ₂e₂)` (metres, world space):
    /// orthogonal conjugate diameters of the same ellipse, usable as `D_u`, `D_v` (same
    /// `|M_p⁻¹ Δ|`, density and box).
    #[inline]
    pub fn differentials(&self) -> (DVec3, DVec3) {
        (self.major_dir * (2.0 * self.semi_major), self.minor_dir * (2.0 * self.semi_minor))
    }

    /// Axis ratio `σ₂/σ₁` (dimensionless, in `[0, 1]`); 0 when `σ₁` is 0 or not finite.
    #[inline]
    pub fn ratio(&self) -> f64 {
        let r = self.semi_minor / self.semi_major;
        if r >= 0.0 && r.is_finite() { r.min(1.0) } else { 0.0 }
    }
}

/// The principal axes of the ellipse `{a cos θ + b sin θ}`, `a = D_u/2`, `b = D_v/2`, for
/// differentials `du`, `dv` (metres) in the tangent plane of the unit `normal`: the
/// singular value decomposition of the 2×2 matrix `[D_u D_v]` in that plane.
///
/// Closed form through the symmetric Gram matrix `G = [[|D_u|², D_u·D_v], [D_u·D_v, |D_v|²]]`:
/// with `h = (|D_u|² − |D_v|²)/2` and `d = √(h² + (D_u·D_v)²)`, `(2σ₁)² = (|D_u|² + |D_v|²)/2 + d`
/// (a sum, no cancellation), `2σ₂ = |D_u × D_v| / (2σ₁)` (accurate for a thin ellipse,
/// where the smaller eigenvalue of `G` would cancel), and `e₁ ∝ w₀ D_u + w₁ D_v` for the
/// eigenvector `w` of `G` for `(2σ₁)²`, taken as `(d + h, D_u·D_v)` when `h ≥ 0` and as
/// `(D_u·D_v, d − h)` otherwise (the form whose first or second entry has no cancellation).
/// A near-circular ellipse (`d` small against `|D_u|² + |D_v|²`) has an ill-determined
/// `e₁`, but any axis pair describes it to rounding: `σ₁² − σ₂² = d` is small. This is the
/// singular value decomposition of the 3×2 matrix `[D_u D_v]`; `D_u`, `D_v` should lie in
/// the tangent plane of `normal` (every [`Footprint`]'s do), which `e₂ = ±n × e₁` assumes.
///
/// ```
/// use arpa_core::store::footprint::principal_axes;
/// use arpa_core::glam::DVec3;
///
/// // A sheared pair spanning the ellipse with semi-axes 2 along x and 1 along y.
/// let (c, s) = (0.6f64, 0.8f64);
/// let du = DVec3::new(4.0 * c, 2.0 * s, 0.0);
/// let dv = DVec3::new(-4.0 * s, 2.0 * c, 0.0);
/// let axes = principal_axes(du, dv, DVec3::Z);
/// assert!((axes.semi_major - 2.0).abs() < 1e-12 && (axes.semi_minor - 1.0).abs() < 1e-12);
/// assert!(axes.major_dir.dot(DVec3::X).abs() > 1.0 - 1e-12);
/// ```
pub fn principal_axes(du: DVec3, dv: DVec3, normal: DVec3) -> PrincipalAxes {
    let (la2, lb2, uv) = (du.length_squared(), dv.length_squared(), du.dot(dv));
    let cross = du.cross(dv);
    let den = cross.dot(normal);
    let (l1, l2) = principal_lengths(la2, lb2, uv, cross.length());
    let e1 = unit_scaled(major_differential(du, dv, la2, lb2, uv));
    let e2 = normal.cross(e1);
    PrincipalAxes { semi_major: 0.5 * l1, semi_minor: 0.5 * l2, major_dir: e1, minor_dir: if den < 0.0 { -e2 } else { e2 } }
}

/// `(2σ₁)²`, the larger eigenvalue of the Gram matrix of `D_u`, `D_v` (m²), from
/// `|D_u|²`, `|D_v|²` and `D_u·D_v` (see [`principal_axes`]).
#[inline(always)]
pub(crate) fn major_axis2(la2: f64, lb2: f64, uv: f64) -> f64 {
    let h = 0.5 * (la2 - lb2);
    0.5 * (la2 + lb2) + libm::sqrt(h * h + uv * uv)
}

/// Principal axis lengths `(2σ₁, 2σ₂)` (metres) from `|D_u|²`, `|D_v|²`, `D_u·D_v` and
/// `area = |D_u × D_v|` (see [`principal_axes`]); `2σ₂ ≤ 2σ₁` also after rounding.
#[inline(always)]
pub(crate) fn principal_lengths(la2: f64, lb2: f64, uv: f64, area: f64) -> (f64, f64) {
    let l1 = libm::sqrt(major_axis2(la2, lb2, uv));
    let l2 = if l1 > 0.0 { (area / l1).min(l1) } else { 0.0 };
    (l1, l2)
}

/// The major principal differential `2σ₁e₁` (metres, up to rounding of its length) as the
/// combination of `du`, `dv` given by [`principal_axes`]'s eigenvector; `du` itself for a
/// circle spanned by orthogonal equal-length differentials (and for non-finite input).
#[inline]
pub(crate) fn major_differential(du: DVec3, dv: DVec3, la2: f64, lb2: f64, uv: f64) -> DVec3 {
    let h = 0.5 * (la2 - lb2);
    let d = libm::sqrt(h * h + uv * uv);
    let (w0, w1) = if h >= 0.0 { (d + h, uv) } else { (uv, d - h) };
    let m = w0.abs().max(w1.abs());
    if !(m > 0.0) || !m.is_finite() {
        return du;
    }
    let (w0, w1) = (w0 / m, w1 / m);
    let norm = libm::sqrt(w0 * w0 + w1 * w1);
    du * (w0 / norm) + dv * (w1 / norm)
}

/// `v/|v|` for any finite magnitude (scaled by its largest component first, so tiny or
/// huge vectors do not underflow or overflow in `|v|²`); zero for zero or non-finite `v`.
#[inline]
pub(crate) fn unit_scaled(v: DVec3) -> DVec3 {
    let m = v.abs().max_element();
    if !(m > 0.0) || !m.is_finite() {
        return DVec3::ZERO;
    }
    let w = v / m;
    w / libm::sqrt(w.length_squared())
}

/// `true` when `M_p⁻¹`'s denominator `(D_u × D_v)·n` is zero up to rounding: below
/// `16 ε |D_u||D_v|` (parallel or zero differentials), or not finite.
#[inline]
pub(crate) fn degenerate_denominator(den: f64, la2: f64, lb2: f64) -> bool {
    // Compared in squares: den² > (16 ε)² |D_u|² |D_v|².
    const K2: f64 = 256.0 * f64::EPSILON * f64::EPSILON;
    !(den * den > K2 * la2 * lb2) || !den.is_finite()
}

/// Slab half-thickness (metres) of a footprint centred at `center` with principal axis
/// lengths `major = 2σ₁`, `minor = 2σ₂` (metres, [`Footprint::axis_lengths`]):
/// `min(minor/2, slab_limit)`, but at least `8 ε₃₂ (|x_p|_∞ + major)` so that the `f32`
/// record still accepts points in its own plane.
#[inline]
pub fn half_thickness(center: DVec3, major: f64, minor: f64, slab_limit: f64) -> f64 {
    let floor = 8.0 * f32::EPSILON as f64 * (center.abs().max_element() + major);
    (0.5 * minor).min(slab_limit).max(floor)
}

/// [`Footprint::pack`] with the squared differential lengths, `D_u × D_v`, the
/// denominator `den = (D_u × D_v)·n` (already checked with [`degenerate_denominator`]) and
/// the slab half-thickness `h` already known.
#[inline(always)]
#[allow(clippy::eq_op)] // `x - x` is the finiteness test, not a zero
pub(crate) fn pack_parts(fp: &Footprint, la2: f64, lb2: f64, cross: DVec3, den: f64, h: f64) -> Result<PackedFootprint, FootprintError> {
    // σ₂ ≥ |a × b|/√(|a|² + |b|²) ≥ k·scale, compared in squares:
    // |D_u × D_v|² ≥ 4 (|D_u|² + |D_v|²) (k·scale)².
    let scale = fp.center.abs().max_element().max(1e-30) * MIN_RELATIVE_SEMI_AXIS;
    if !(cross.length_squared() >= 4.0 * (la2 + lb2) * scale * scale) || !(h > 0.0) {
        return Err(FootprintError::Unrepresentable);
    }
    let inv = 2.0 / den;
    let row_u = fp.dv.cross(fp.normal) * inv;
    let row_v = fp.normal.cross(fp.du) * inv;
    let density = fp.flux * (2.0 * inv.abs());
    // A density that underflows f32 would silently drop the photon's flux (checked for
    // all three channels without short-circuiting: one well-predicted branch).
    let d32 = density.as_vec3();
    let underflow = |c: usize| fp.flux[c] != 0.0 && !(d32[c].abs() >= f32::MIN_POSITIVE);
    if underflow(0) | underflow(1) | underflow(2) {
        return Err(FootprintError::Unrepresentable);
    }
    let (c, ru, rv, rn) = (fp.center.as_vec3(), row_u.as_vec3(), row_v.as_vec3(), (fp.normal * (1.0 / h)).as_vec3());
    // Every stored float finite: `x − x` is 0 for finite `x` and NaN otherwise, and a NaN
    // survives the sum (checked on the values in registers, one branch).
    let zero = (c - c) + (ru - ru) + (rv - rv) + (rn - rn) + (d32 - d32);
    if zero.x + zero.y + zero.z != 0.0 {
        return Err(FootprintError::Unrepresentable);
    }
    Ok(PackedFootprint {
        center: c.to_array(),
        map: fp.map as u32,
        row_u: ru.to_array(),
        flux_density_r: d32.x,
        row_v: rv.to_array(),
        flux_density_g: d32.y,
        row_n: rn.to_array(),
        flux_density_b: d32.z,
    })
}

/// The 64-byte `f32` footprint record of the gather stage, laid out as four
/// `vec4<f32>`-sized groups for GPU storage buffers (WGSL: `vec3<f32>` + scalar).
///
/// `y = (row_u·Δ, row_v·Δ, row_n·Δ)` with `Δ = q − x_p` is the full filter transform:
/// `q` is inside iff `y.x² + y.y² ≤ 1` and `|y.z| ≤ 1` (the slab). `row_n = n/h` also
/// carries the orientation: a query whose normal has `n_q·row_n ≤ 0` sees the back side.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
pub struct PackedFootprint {
    /// Centre `x_p` (metres).
    pub center: [f32; 3],
    /// [`PhotonMap`] as `u32`.
    pub map: u32,
    /// First row of `M_p⁻¹` (1/m).
    pub row_u: [f32; 3],
    /// Red flux density `Φ · 4/|D_u × D_v|` (W/m²).
    pub flux_density_r: f32,
    /// Second row of `M_p⁻¹` (1/m).
    pub row_v: [f32; 3],
    /// Green flux density (W/m²).
    pub flux_density_g: f32,
    /// Normal over slab half-thickness, `n/h` (1/m), `n` towards the arrival side
    /// (flipped where the photon arrived from below the shading plane, see
    /// [`crate::propagate::lambertian`]).
    pub row_n: [f32; 3],
    /// Blue flux density (W/m²).
    pub flux_density_b: f32,
}

impl PackedFootprint {
    /// Filter-space coordinates `(row_u·Δ, row_v·Δ, row_n·Δ)` of `q` (dimensionless).
    #[inline]
    pub fn filter_coords(&self, q: Vec3) -> Vec3 {
        let delta = q - Vec3::from_array(self.center);
        // Far queries can overflow to ±∞ or NaN (∞ − ∞); clamping keeps them finite and
        // outside (f32::max maps NaN to the other operand).
        Vec3::new(
            Vec3::from_array(self.row_u).dot(delta),
            Vec3::from_array(self.row_v).dot(delta),
            Vec3::from_array(self.row_n).dot(delta),
        )
        .clamp(Vec3::splat(-f32::MAX), Vec3::splat(f32::MAX))
    }

    /// Point-in-footprint test: inside the ellipse and within the slab.
    #[inline]
    pub fn contains(&self, q: Vec3) -> bool {
        let y = self.filter_coords(q);
        y.x * y.x + y.y * y.y <= 1.0 && y.z.abs() <= 1.0
    }

    /// `true` if a query whose (geometric) normal is `query_normal` sees the lit side.
    #[inline]
    pub fn faces(&self, query_normal: Vec3) -> bool {
        Vec3::from_array(self.row_n).dot(query_normal) > 0.0
    }

    /// Flux density `Φ · 4/|D_u × D_v|` (W/m², RGB).
    #[inline]
    pub fn flux_density(&self) -> Vec3 {
        Vec3::new(self.flux_density_r, self.flux_density_g, self.flux_density_b)
    }

    /// Map of this footprint.
    #[inline]
    pub fn photon_map(&self) -> PhotonMap {
        PhotonMap::from_index(self.map)
    }

    /// Irradiance (W/m², RGB) this footprint contributes at query point `q` with
    /// normal `query_normal`: `Φ_p W_p(q)` when `q` is inside and on the lit side, else 0.
    #[inline]
    pub fn irradiance(&self, q: Vec3, query_normal: Vec3, kernel: Kernel) -> Vec3 {
        let y = self.filter_coords(q);
        let r2 = y.x * y.x + y.y * y.y;
        if r2 <= 1.0 && y.z.abs() <= 1.0 && self.faces(query_normal) {
            self.flux_density() * kernel.eval(r2)
        } else {
            Vec3::ZERO
        }
    }

    /// [`PackedFootprint::irradiance`] at every scale of the bandwidth ladder
    /// ([`crate::gather::scales`]): scale `k` is the stored ellipse and its slab shrunk by
    /// `2^{−k/2}` (`2^k |y_xy|² < 1`, `2^k y_z² ≤ 1` in filter space), so its weight is
    /// `2^k K(2^k r²)` times the stored density (exact scalings in `f32`); the side test is
    /// the stored one. Scale 0 equals [`PackedFootprint::irradiance`] bit for bit. The slab
    /// shrinks with the ellipse because a thick slab lets a large footprint light a nearby
    /// parallel surface (a table top under a lamp, the two sides of a thin object), a bias
    /// that no smaller ellipse over the stored slab would remove.
    #[inline]
    pub fn irradiance_scales(&self, q: Vec3, query_normal: Vec3, kernel: Kernel) -> [Vec3; crate::gather::scales::SCALES] {
        let y = self.filter_coords(q);
        let r2 = y.x * y.x + y.y * y.y;
        if r2 <= 1.0 && y.z.abs() <= 1.0 && self.faces(query_normal) {
            let d = self.flux_density();
            let mut e = [Vec3::ZERO; crate::gather::scales::SCALES];
            for (k, e) in e.iter_mut().enumerate() {
                let f = crate::gather::scales::inv_scale2(k);
                // The discs are nested: once q is outside one, it is outside the smaller.
                if k > 0 && !(r2 * f < 1.0 && y.z * y.z * f <= 1.0) {
                    break;
                }
                *e = d * (kernel.eval(r2 * f) * f);
            }
            e
        } else {
            [Vec3::ZERO; crate::gather::scales::SCALES]
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn packed_is_64_bytes() {
        assert_eq!(core::mem::size_of::<PackedFootprint>(), 64);
        assert_eq!(core::mem::align_of::<PackedFootprint>(), 4);
    }
}
