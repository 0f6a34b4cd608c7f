//! Shading normals perturbed by a texture: tangent-space normal maps (Mitsuba 3's
//! `normalmap`, glTF's `normalTexture`) and height-field bump maps (Mitsuba 3's `bumpmap`).
//!
//! Both take the unit shading normal `n` the surface has without the map (interpolated
//! vertex normal or face normal) and the surface's texture-coordinate derivatives
//! `∂p/∂u`, `∂p/∂v` (world space, metres per unit of texture coordinate), and return the
//! perturbed unit normal. The textures are evaluated by the caller.
//!
//! Photon differentials: the map is treated as constant across a photon's footprint. A
//! mirror or dielectric reflects and refracts about the perturbed normal, and its normal
//! derivatives are those of the unperturbed interpolated normal (texel-scale curvature of
//! the map does not spread or focus the footprint).

use crate::base::frame::Frame;
use glam::{DVec2, DVec3};

/// How the second tangent of a normal map's frame is oriented.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Handedness {
    /// `t = n × s` always (Mitsuba 3's `normalmap`).
    RightHanded,
    /// `t = ±n × s`, the sign making `t` point along `∂p/∂v`'s side (MikkTSpace's bitangent
    /// sign, which glTF prescribes when a mesh carries no tangents): mirrored texture
    /// coordinates read the map's green channel the right way round.
    FollowTextureCoordinates,
}

/// The first tangent `s`: the unit part of `dp_du` perpendicular to the unit `n`, or a
/// tangent of [`Frame::from_normal`] where `dp_du` is (nearly) parallel to `n`, zero or not
/// finite.
#[inline]
fn first_tangent(n: DVec3, dp_du: DVec3) -> DVec3 {
    let s = dp_du - n * n.dot(dp_du);
    let len = s.length();
    if len > 1e-12 * dp_du.length() && len.is_finite() { s / len } else { Frame::from_normal(n).t }
}

/// The normal of a tangent-space normal map: the texel value `c` (RGB in `[0, 1]`) read as
/// `m = 2c − 1`, with `m.x`, `m.y` scaled by `scale` (glTF's `normalTexture.scale`; 1 for
/// Mitsuba), in the frame `(s, t, n)`: `s` the unit part of `dp_du` perpendicular to the unit
/// shading normal `n`, `t` as `handedness` says. Normalised, and turned to the side of the
/// unit `geometric` normal that `n` is on; `n` where the mapped normal vanishes or is not
/// finite.
pub fn normal_mapped(n: DVec3, geometric: DVec3, dp_du: DVec3, dp_dv: DVec3, c: DVec3, scale: f64, handedness: Handedness) -> DVec3 {
    let m = c * 2.0 - DVec3::ONE;
    let s = first_tangent(n, dp_du);
    let mut t = n.cross(s);
    if handedness == Handedness::FollowTextureCoordinates && t.dot(dp_dv) < 0.0 {
        t = -t;
    }
    let v = s * (m.x * scale) + t * (m.y * scale) + n * m.z;
    orient(v, n, geometric)
}

/// The normal of a bump map (Mitsuba 3's `bumpmap`): with `grad` the gradient
/// `(∂h/∂u, ∂h/∂v)` of the height `h` (the texture's single value times the map's scale),
/// the derivatives become `∂p/∂u' = ∂p/∂u + n (∂h/∂u − n·∂p/∂u)` (and for `v`), and the normal
/// is `∂p/∂u' × ∂p/∂v'` normalised and turned to the side of the unit `geometric` normal
/// that the unit shading normal `n` is on; `n` where it vanishes or is not finite.
pub fn bump_mapped(n: DVec3, geometric: DVec3, dp_du: DVec3, dp_dv: DVec3, grad: DVec2) -> DVec3 {
    let du = dp_du + n * (grad.x - n.dot(dp_du));
    let dv = dp_dv + n * (grad.y - n.dot(dp_dv));
    let v = du.cross(dv);
    // The cross product's sign follows the parametrisation's handedness: take the side of n.
    let v = if v.dot(n) < 0.0 { -v } else { v };
    orient(v, n, geometric)
}

/// `v` normalised, on the side of `geometric` that `n` is on; `n` where `v` vanishes or
/// is not finite.
#[inline]
fn orient(v: DVec3, n: DVec3, geometric: DVec3) -> DVec3 {
    let len = v.length();
    if !(len > 0.0) || !len.is_finite() {
        return n;
    }
    let v = v / len;
    if (v.dot(geometric) < 0.0) != (n.dot(geometric) < 0.0) { -v } else { v }
}

/// The texture-coordinate derivatives `(∂p/∂u, ∂p/∂v)` of the triangle `p` with texture
/// coordinates `uv` at its vertices (metres per unit): the solution of
/// `p₁ − p₀ = Δu₁ ∂p/∂u + Δv₁ ∂p/∂v`, `p₂ − p₀ = Δu₂ ∂p/∂u + Δv₂ ∂p/∂v`. `None` where the
/// texture coordinates are degenerate (zero or non-finite determinant).
pub fn texture_derivatives(p: [DVec3; 3], uv: [DVec2; 3]) -> Option<(DVec3, DVec3)> {
    let (d1, d2) = (uv[1] - uv[0], uv[2] - uv[0]);
    let (e1, e2) = (p[1] - p[0], p[2] - p[0]);
    let det = d1.x * d2.y - d1.y * d2.x;
    if !(det != 0.0) || !det.is_finite() {
        return None;
    }
    let dp_du = (e1 * d2.y - e2 * d1.y) / det;
    let dp_dv = (e2 * d1.x - e1 * d2.x) / det;
    (dp_du.is_finite() && dp_dv.is_finite()).then_some((dp_du, dp_dv))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn close(a: DVec3, b: DVec3, tol: f64) -> bool {
        (a - b).length() <= tol
    }

    #[test]
    fn flat_map_keeps_the_normal() {
        let n = DVec3::new(0.2, 1.0, -0.1).normalize();
        let m = normal_mapped(n, n, DVec3::X, DVec3::Z, DVec3::new(0.5, 0.5, 1.0), 1.0, Handedness::RightHanded);
        assert!(close(m, n, 1e-12));
    }

    #[test]
    fn tilts_follow_the_tangent_frame() {
        // Plane y = 0 with u along +x and v along -z (Mitsuba's rectangle turned to face
        // +y): a tilt towards +s leans the normal to +x, a tilt towards +t to -z.
        let (n, du, dv) = (DVec3::Y, DVec3::X * 2.0, DVec3::NEG_Z * 2.0);
        let a: f64 = 0.5;
        let c = |x: f64, y: f64| DVec3::new(0.5 + 0.5 * x, 0.5 + 0.5 * y, 0.5 + 0.5 * a.cos());
        let s_tilt = normal_mapped(n, n, du, dv, c(a.sin(), 0.0), 1.0, Handedness::RightHanded);
        assert!(close(s_tilt, DVec3::new(a.sin(), a.cos(), 0.0), 1e-12), "{s_tilt}");
        let t_tilt = normal_mapped(n, n, du, dv, c(0.0, a.sin()), 1.0, Handedness::RightHanded);
        assert!(close(t_tilt, DVec3::new(0.0, a.cos(), -a.sin()), 1e-12), "{t_tilt}");
        // Mirrored v: MikkTSpace's sign turns t towards +z, Mitsuba's frame does not.
        let mirrored = normal_mapped(n, n, du, -dv, c(0.0, a.sin()), 1.0, Handedness::FollowTextureCoordinates);
        assert!(close(mirrored, DVec3::new(0.0, a.cos(), a.sin()), 1e-12), "{mirrored}");
        let kept = normal_mapped(n, n, du, -dv, c(0.0, a.sin()), 1.0, Handedness::RightHanded);
        assert!(close(kept, t_tilt, 1e-12));
    }

    #[test]
    fn bump_of_a_linear_height_tilts_by_its_slope() {
        // h = k u on the plane y = 0 with dp/du = 2 x: the surface y = k x / 2 has the
        // normal (−k/2, 1, 0) normalised.
        let (n, du, dv) = (DVec3::Y, DVec3::X * 2.0, DVec3::NEG_Z * 2.0);
        let k = 0.6;
        let b = bump_mapped(n, n, du, dv, DVec2::new(k, 0.0));
        assert!(close(b, DVec3::new(-k / 2.0, 1.0, 0.0).normalize(), 1e-12), "{b}");
        // The other handedness of the parametrisation gives the same normal.
        let b2 = bump_mapped(n, n, du, -dv, DVec2::new(k, 0.0));
        assert!(close(b2, b, 1e-12));
        assert_eq!(bump_mapped(n, n, du, dv, DVec2::ZERO), n);
    }

    #[test]
    fn bump_matches_finite_differences_of_a_height_field() {
        // A curved patch p(u, v) = (u, 0, v) displaced by h(u, v) along +y: the bumped
        // normal is the normal of p + h n, from central differences.
        let h = |u: f64, v: f64| 0.3 * (2.0 * u).sin() * (1.5 * v).cos();
        let (u, v) = (0.4, -0.7);
        let e = 1e-6;
        let grad = DVec2::new((h(u + e, v) - h(u - e, v)) / (2.0 * e), (h(u, v + e) - h(u, v - e)) / (2.0 * e));
        let surf = |u: f64, v: f64| DVec3::new(u, h(u, v), v);
        let pu = (surf(u + e, v) - surf(u - e, v)) / (2.0 * e);
        let pv = (surf(u, v + e) - surf(u, v - e)) / (2.0 * e);
        let expected = pv.cross(pu).normalize();
        let b = bump_mapped(DVec3::Y, DVec3::Y, DVec3::X, DVec3::Z, grad);
        assert!(close(b, expected, 1e-8), "{b} vs {expected}");
    }

    #[test]
    fn degenerate_inputs_fall_back() {
        let n = DVec3::Y;
        assert_eq!(normal_mapped(n, n, DVec3::X, DVec3::Z, DVec3::splat(0.5), 1.0, Handedness::RightHanded), n);
        assert_eq!(normal_mapped(n, n, DVec3::X, DVec3::Z, DVec3::splat(f64::NAN), 1.0, Handedness::RightHanded), n);
        // dp/du along n: a frame tangent stands in, and the flat map still gives n.
        let m = normal_mapped(n, n, DVec3::Y, DVec3::Z, DVec3::new(0.5, 0.5, 1.0), 1.0, Handedness::RightHanded);
        assert!(close(m, n, 1e-12));
        assert!(bump_mapped(n, n, DVec3::X, DVec3::Z, DVec2::new(f64::INFINITY, 0.0)).is_finite());
        assert!(texture_derivatives([DVec3::ZERO, DVec3::X, DVec3::Z], [DVec2::ZERO, DVec2::X, DVec2::X * 2.0]).is_none());
    }

    #[test]
    fn texture_derivatives_invert_the_parametrisation() {
        // p = o + A (u, v) for a linear map A: the derivatives are A's columns.
        let (o, a_u, a_v) = (DVec3::new(1.0, 2.0, 3.0), DVec3::new(0.3, -1.0, 0.2), DVec3::new(0.5, 0.1, 0.9));
        let uv = [DVec2::new(0.1, 0.2), DVec2::new(0.8, 0.3), DVec2::new(0.4, 0.9)];
        let p = uv.map(|t| o + a_u * t.x + a_v * t.y);
        let (du, dv) = texture_derivatives(p, uv).unwrap();
        assert!(close(du, a_u, 1e-12) && close(dv, a_v, 1e-12));
    }
}
