//! Derivatives of interpolated (Phong) shading normals on triangles, which make caustics
//! from curved, finely tessellated glass focus and defocus (Igehy's barycentric gradients).

use crate::propagate::differential::{DifferentialError, NormalDifferential};
use glam::DVec3;

/// A triangle with per-vertex shading normals (world space).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ShadedTriangle {
    /// Vertex positions (metres).
    pub p: [DVec3; 3],
    /// Vertex normals (need not be unit; interpolated then normalised).
    pub n: [DVec3; 3],
}

impl ShadedTriangle {
    /// Unit geometric normal `(p1 − p0) × (p2 − p0)` normalised, or an error for a
    /// zero-area or non-finite triangle.
    pub fn geometric_normal(&self) -> Result<DVec3, DifferentialError> {
        let c = (self.p[1] - self.p[0]).cross(self.p[2] - self.p[0]);
        let len = c.length();
        if !(len > 0.0) || !len.is_finite() {
            return Err(DifferentialError::InvalidNormal);
        }
        Ok(c / len)
    }

    /// Gradient of each barycentric coordinate with respect to position in the triangle's
    /// plane, `∇bᵢ = N_g × (p_{i+2} − p_{i+1}) / |(p₁ − p₀) × (p₂ − p₀)|` (1/metres).
    /// Constant over the triangle.
    pub fn barycentric_gradients(&self) -> Result<[DVec3; 3], DifferentialError> {
        let c = (self.p[1] - self.p[0]).cross(self.p[2] - self.p[0]);
        let twice_area = c.length();
        if !(twice_area > 0.0) || !twice_area.is_finite() {
            return Err(DifferentialError::InvalidNormal);
        }
        let ng = c / twice_area;
        Ok(core::array::from_fn(|i| ng.cross(self.p[(i + 2) % 3] - self.p[(i + 1) % 3]) / twice_area))
    }

    /// The interpolated unit shading normal at barycentrics `b` (weights of `p0, p1, p2`)
    /// and its derivatives along the positional differentials `dp_du`, `dp_dv` of a ray that
    /// has been transferred onto this triangle:
    /// `∂bᵢ = ∇bᵢ·∂P`, `∂m = Σ ∂bᵢ nᵢ`, `∂N = [∂m − N (N·∂m)] / |m|` with `m = Σ bᵢ nᵢ`.
    pub fn normal_differential(&self, b: DVec3, dp_du: DVec3, dp_dv: DVec3) -> Result<NormalDifferential, DifferentialError> {
        self.normal_differential_with(self.barycentric_gradients()?, b, dp_du, dp_dv)
    }

    /// [`ShadedTriangle::normal_differential`] with the triangle's
    /// [`ShadedTriangle::barycentric_gradients`] `grads` (1/metres) computed beforehand
    /// (they are constant over the triangle).
    #[inline(always)]
    pub fn normal_differential_with(&self, grads: [DVec3; 3], b: DVec3, dp_du: DVec3, dp_dv: DVec3) -> Result<NormalDifferential, DifferentialError> {
        let m = self.n[0] * b.x + self.n[1] * b.y + self.n[2] * b.z;
        let len = m.length();
        if !(len > 0.0) || !len.is_finite() {
            return Err(DifferentialError::InvalidNormal);
        }
        let n = m / len;
        let dn = |dp: DVec3| {
            let dm = self.n[0] * grads[0].dot(dp) + self.n[1] * grads[1].dot(dp) + self.n[2] * grads[2].dot(dp);
            (dm - n * n.dot(dm)) / len
        };
        let out = NormalDifferential { n, dn_du: dn(dp_du), dn_dv: dn(dp_dv) };
        if out.dn_du.is_finite() && out.dn_dv.is_finite() { Ok(out) } else { Err(DifferentialError::NonFinite) }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_relative_eq;

    fn tri() -> ShadedTriangle {
        ShadedTriangle {
            p: [DVec3::new(0.0, 0.0, 0.0), DVec3::new(1.0, 0.1, 0.0), DVec3::new(0.2, 0.0, 1.3)],
            n: [DVec3::new(0.1, 1.0, 0.0), DVec3::new(-0.3, 1.0, 0.2), DVec3::new(0.0, 1.0, -0.4)],
        }
    }

    fn bary(t: &ShadedTriangle, q: DVec3) -> DVec3 {
        // Independent: areas of sub-triangles.
        let ng = t.geometric_normal().unwrap();
        let area = |a: DVec3, b: DVec3, c: DVec3| (b - a).cross(c - a).dot(ng);
        let total = area(t.p[0], t.p[1], t.p[2]);
        DVec3::new(area(q, t.p[1], t.p[2]), area(t.p[0], q, t.p[2]), area(t.p[0], t.p[1], q)) / total
    }

    #[test]
    fn gradients_match_finite_differences() {
        let t = tri();
        let g = t.barycentric_gradients().unwrap();
        let q = (t.p[0] + t.p[1] + t.p[2]) / 3.0;
        let ng = t.geometric_normal().unwrap();
        for dir in [t.p[1] - t.p[0], t.p[2] - t.p[0]] {
            let dir = dir - ng * ng.dot(dir);
            let h = 1e-6;
            let fd = (bary(&t, q + dir * h) - bary(&t, q - dir * h)) / (2.0 * h);
            for i in 0..3 {
                assert_relative_eq!(g[i].dot(dir), fd[i], epsilon = 1e-8);
            }
        }
    }

    #[test]
    fn normal_derivative_matches_finite_differences() {
        let t = tri();
        let q = t.p[0] * 0.2 + t.p[1] * 0.5 + t.p[2] * 0.3;
        let ng = t.geometric_normal().unwrap();
        let dp = DVec3::new(0.3, 0.0, 0.2);
        let dp = dp - ng * ng.dot(dp);
        let nd = t.normal_differential(bary(&t, q), dp, DVec3::ZERO).unwrap();
        let h = 1e-6;
        let shade = |p: DVec3| {
            let b = bary(&t, p);
            (t.n[0] * b.x + t.n[1] * b.y + t.n[2] * b.z).normalize()
        };
        let fd = (shade(q + dp * h) - shade(q - dp * h)) / (2.0 * h);
        assert_relative_eq!(nd.dn_du, fd, epsilon = 1e-8);
        assert_eq!(nd.dn_dv, DVec3::ZERO);
    }

    #[test]
    fn degenerate_triangle_is_an_error() {
        let mut t = tri();
        t.p[2] = t.p[1];
        assert!(t.normal_differential(DVec3::splat(1.0 / 3.0), DVec3::X, DVec3::Z).is_err());
        let mut t = tri();
        t.n = [DVec3::ZERO; 3];
        assert!(t.normal_differential(DVec3::splat(1.0 / 3.0), DVec3::X, DVec3::Z).is_err());
    }
}
