//! Two-sided Lambertian scattering with interpolated shading normals, as Mitsuba 3's
//! `twosided` + `diffuse` BSDF defines it, for both directions of transport.
//!
//! **Radiance (camera side).** Mitsuba evaluates the BSDF in the shading frame: the frame
//! is flipped to the side of the viewer direction `ω_v` (`twosided`), and the diffuse lobe
//! is `f = ρ/π` only where both `ω_v·n_s > 0` and `ω_l·n_s > 0`, with the cosine of the
//! light direction `ω_l` taken about `n_s`:
//! `L_o(ω_v) = ∫ ρ/π · L_i(ω_l) · (ω_l·n_s)⁺ dω_l`. [`DiffuseShading::cosine`] is that
//! cosine for next-event estimation.
//!
//! **Flux (photon side).** Photons carry flux, whose density on the surface is per unit of
//! *geometric* area: `dΦ = L_i |ω_i·n_g| dA dω_i`. Rewriting the radiance integral in
//! photons, a photon arriving from `ω_i` (pointing back along its path) stands for the
//! radiance-side weight `a(ω_i) = |ω_i·n_s| / |ω_i·n_g|` times its flux
//! ([`DiffuseShading::adjoint_ratio`]), and a photon re-emitted into `ω_o` leaves with the
//! adjoint BSDF's flux (Veach 1997 §5.3, eq. 5.17: the adjoint of a shading-normal BSDF is
//! not the BSDF itself)
//!
//! `Φ_o = Φ_i · f · |ω_o·n_g| · a(ω_i) / p(ω_o)`.
//!
//! Sampling `ω_o` with density `|ω_o·n_s|/π` (cosine about `n_s`) gives the weight
//! `ρ · a(ω_i) · |ω_o·n_g| / |ω_o·n_s|` — Veach's factor
//! `|ω_i·n_s| |ω_o·n_g| / (|ω_i·n_g| |ω_o·n_s|)` (pbrt-v3's `CorrectShadingNormal` in
//! importance mode, with its `wo` our `ω_i` and its `wi` our `ω_o`), which is unbounded as
//! `ω_o` nears the shading horizon and has infinite variance. We sample the *equivalent
//! bounded form* instead ([`DiffuseShading::sample_reemission`]): `ω_o` cosine-distributed
//! about the geometric normal (density `|ω_o·n_g|/π`), kept only where the shading lobe is
//! non-zero (`ω_o·n_s > 0`), weight `ρ · a(ω_i)`. Both have the same expectation
//! `ρ/π · a(ω_i) · |ω_o·n_g|` per steradian over `{ω_o·n_s > 0, ω_o·n_g > 0}`; this one has
//! a 0/1 direction weight, and where `n_s = n_g` it is exactly the plain cosine re-emission.
//!
//! **Density estimate.** The gather keeps `L = ρ/π · Σ Φ_p W_p` with no per-photon factor
//! (records hold no direction): the adjoint ratio `a(ω_i)` is already in the stored flux,
//! so `Σ Φ_p W_p` estimates the *shading-frame* irradiance `∫ L_i (ω_i·n_s)⁺ dω_i` that
//! Mitsuba's radiance integral needs (pbrt-v3's SPPM instead evaluates `f` in the shading
//! frame at the gather and applies no ratio anywhere, i.e. it counts photon density per
//! geometric area as if it were per shading-projected area). Mitsuba's lobe is zero unless
//! viewer and light lie on the same side of the shading plane; the records carry that side
//! in their orientation (photon path's `orient_to_shading_side`, the query normal of
//! [`crate::render::camera_path`]), so the gather's facing test applies it. The stored `a` uses
//! the shading normal at the photon's hit, not at the query point (the same up to the
//! normal's variation over the footprint).
//!
//! **Through the surface.** Directions on the other side of the *geometric* surface
//! (`ω·n_g ≤ 0`) get nothing on either side: next-event estimation ignores lights behind
//! the face and re-emission into the face absorbs the photon. Mitsuba lets such paths
//! through when the shading frame says "above" (light leaks through open sheets); on
//! closed objects (the shared scenes) the path would hit the object's own inside and carry
//! nothing either way.
//!
//! **Bound.** `a(ω_i)` grows as `1/|ω_i·n_g|` for photons arriving at grazing geometric
//! angles under a tilted shading normal (its second moment diverges logarithmically), so it
//! is clamped to [`MAX_ADJOINT_RATIO`]: a bias only for photons arriving within
//! `acos(1/MAX_ADJOINT_RATIO)` ≈ 89.4° of the geometric normal *and* much steeper in the
//! shading frame, a fraction below `1/MAX_ADJOINT_RATIO² = 0.01 %` of the cosine-weighted
//! incident flux. (A clamp as low as 10 darkens indirectly lit regions under strongly
//! tilted normals against the reference, such as sponza-standin's foreground arch; the
//! variance a clamp admits grows only with `log(MAX_ADJOINT_RATIO)`.)

use crate::base::frame::Frame;
use crate::base::sampling::cosine_hemisphere;
use glam::{DVec2, DVec3};

/// Largest adjoint ratio `|ω_i·n_s| / |ω_i·n_g|` a photon's flux is scaled by
/// (dimensionless; see the module docs).
pub const MAX_ADJOINT_RATIO: f64 = 100.0;

/// The frame of a two-sided Lambertian point seen from one side: the unit geometric
/// normal `n_g` and the unit shading normal `n_s`, both world space.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DiffuseShading {
    /// Geometric normal on the side of the direction the frame was built for.
    pub geometric: DVec3,
    /// Shading normal flipped to that direction's side of the *shading* plane (Mitsuba's
    /// `twosided`).
    pub shading: DVec3,
}

impl DiffuseShading {
    /// The frame seen from the unit direction `toward` (to the viewer on the camera side,
    /// back along the photon's path on the photon side), which must lie on the side of
    /// `geometric` (unit, the side the ray came from). `shading` is the unit interpolated
    /// normal, either orientation. `None` where `toward` lies in the shading plane (or an
    /// input is not finite): the diffuse lobe is zero for it.
    #[inline(always)]
    pub fn new(geometric: DVec3, shading: DVec3, toward: DVec3) -> Option<Self> {
        let c = toward.dot(shading);
        if !(c != 0.0) || !c.is_finite() || !geometric.is_finite() {
            return None;
        }
        Some(Self { geometric, shading: if c > 0.0 { shading } else { -shading } })
    }

    /// Whether the direction the frame was built for lies below the shading plane on its
    /// side of the face, i.e. the shading normal had to be flipped away from the geometric
    /// one (only possible where they differ).
    #[inline(always)]
    pub fn below_shading_plane(&self) -> bool {
        self.shading.dot(self.geometric) < 0.0
    }

    /// The cosine `(ω·n_s)⁺` of the unit direction `w` (towards a light) in the shading
    /// frame; 0 also when `w` lies behind the geometric surface (`ω·n_g ≤ 0`).
    #[inline(always)]
    pub fn cosine(&self, w: DVec3) -> f64 {
        let c = w.dot(self.shading);
        if c > 0.0 && w.dot(self.geometric) > 0.0 { c } else { 0.0 }
    }

    /// The adjoint ratio `a(ω_i) = |ω_i·n_s| / |ω_i·n_g|` of the unit direction `w_in`
    /// back along an arriving photon's path (dimensionless, in `[0, MAX_ADJOINT_RATIO]`;
    /// exactly 1 where `n_s = n_g`).
    #[inline(always)]
    pub fn adjoint_ratio(&self, w_in: DVec3) -> f64 {
        let (s, g) = (w_in.dot(self.shading).abs(), w_in.dot(self.geometric).abs());
        let a = s / g;
        if a < MAX_ADJOINT_RATIO { a } else if a.is_nan() { 0.0 } else { MAX_ADJOINT_RATIO }
    }

    /// Re-emission direction from the unit-square sample `u`: cosine-distributed about the
    /// geometric normal, `None` (absorbed) where it falls below the shading plane. With
    /// flux weight `ρ · a(ω_i)` this is the adjoint transport of the module docs.
    #[inline(always)]
    pub fn sample_reemission(&self, u: DVec2) -> Option<DVec3> {
        let f = Frame::from_normal(self.geometric);
        let d = crate::base::frame::unit_or(f.to_world(cosine_hemisphere(u)), f.n);
        (d.dot(self.shading) >= 0.0).then_some(d)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use core::f64::consts::PI;

    fn tilted(deg: f64) -> DVec3 {
        let t = deg.to_radians();
        DVec3::new(libm::sin(t), libm::cos(t), 0.0)
    }

    #[test]
    fn frame_flips_to_the_side_of_the_direction() {
        let s = DiffuseShading::new(DVec3::Y, tilted(80.0), DVec3::new(-0.9, 0.1, 0.0).normalize()).unwrap();
        assert!(s.shading.x < 0.0);
        assert!(DiffuseShading::new(DVec3::Y, DVec3::X, DVec3::Y).is_none());
        assert!(DiffuseShading::new(DVec3::Y, DVec3::NAN, DVec3::Y).is_none());
    }

    #[test]
    fn cosine_is_zero_below_either_plane() {
        let s = DiffuseShading::new(DVec3::Y, tilted(30.0), DVec3::Y).unwrap();
        let w = DVec3::new(0.6, 0.8, 0.0);
        assert!((s.cosine(w) - w.dot(tilted(30.0))).abs() < 1e-15);
        // Above the face, below the shading plane.
        assert_eq!(s.cosine(DVec3::new(-0.95, 0.3122, 0.0).normalize()), 0.0);
        // Above the shading plane, behind the face.
        assert_eq!(s.cosine(DVec3::new(0.99, -0.1, 0.0).normalize()), 0.0);
    }

    #[test]
    fn adjoint_ratio_is_one_without_tilt_and_bounded() {
        let s = DiffuseShading::new(DVec3::Y, DVec3::Y, DVec3::Y).unwrap();
        assert_eq!(s.adjoint_ratio(DVec3::new(0.3, 0.5, 0.1).normalize()), 1.0);
        let s = DiffuseShading::new(DVec3::Y, tilted(60.0), DVec3::Y).unwrap();
        assert_eq!(s.adjoint_ratio(DVec3::new(1.0, 1e-9, 0.0)), MAX_ADJOINT_RATIO);
        assert_eq!(s.adjoint_ratio(DVec3::X * 0.0), 0.0);
    }

    /// The sampled re-emission has the expectation of Veach's cosine-about-`n_s` form:
    /// `E[g(ω_o)]` for a test function `g` under both, the latter by quadrature.
    #[test]
    fn reemission_matches_the_shading_normal_form_in_expectation() {
        let s = DiffuseShading::new(DVec3::Y, tilted(50.0), DVec3::Y).unwrap();
        let g = |w: DVec3| 1.0 + w.x + 0.5 * w.z * w.z;
        let mut rng = crate::base::rng::Rng::new(3, 0, 0, crate::base::rng::StreamDomain::User);
        let n = 400_000;
        let mut sum = 0.0;
        for _ in 0..n {
            if let Some(w) = s.sample_reemission(rng.next_2d()) {
                assert!(w.dot(s.geometric) >= 0.0 && w.dot(s.shading) >= 0.0);
                sum += g(w);
            }
        }
        let mc = sum / n as f64;
        // ∫ over {ω·n_s > 0} of (|ω·n_g|/|ω·n_s|)·1[ω·n_g > 0] · g(ω) · |ω·n_s|/π dω.
        let f = Frame::from_normal(s.shading);
        let (nt, np) = (400, 800);
        let mut quad = 0.0;
        for i in 0..nt {
            let theta = (i as f64 + 0.5) / nt as f64 * PI / 2.0;
            for j in 0..np {
                let phi = (j as f64 + 0.5) / np as f64 * 2.0 * PI;
                let w = f.to_world(DVec3::new(theta.sin() * phi.cos(), theta.sin() * phi.sin(), theta.cos()));
                let (cs, cg) = (w.dot(s.shading), w.dot(s.geometric));
                if cg > 0.0 {
                    quad += cg / cs * g(w) * cs / PI * theta.sin() * (PI / 2.0 / nt as f64) * (2.0 * PI / np as f64);
                }
            }
        }
        assert!((mc / quad - 1.0).abs() < 0.005, "{mc} vs {quad}");
    }
}
