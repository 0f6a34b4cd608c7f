//! Unit vectors and orthonormal frames around them.

use glam::DVec3;

/// `v / |v|`, or zero when `v` is zero or not finite (as glam's `normalize_or_zero`), with
/// a cheap path for vectors that are unit already up to rounding (`|v·v − 1| ≤ 1e-8`:
/// normals from the scene, sampled directions): there `1/√(v·v)` is replaced by its
/// first-order expansion `(3 − v·v)/2`, whose truncation error `≤ (3/8)(v·v − 1)²`
/// (< 4e-17 relative) is below the rounding of the exact formula. Saves a square root and
/// a division on the per-photon paths.
#[inline]
pub fn unit_or_zero(v: DVec3) -> DVec3 {
    unit_or(v, DVec3::ZERO)
}

/// [`unit_or_zero`] with `fallback` instead of zero (as glam's `normalize_or`).
#[inline]
pub fn unit_or(v: DVec3, fallback: DVec3) -> DVec3 {
    let len2 = v.length_squared();
    if (len2 - 1.0).abs() <= 1e-8 { v * (1.5 - 0.5 * len2) } else { v.normalize_or(fallback) }
}

/// A right-handed orthonormal basis `(t, b, n)` with `t × b = n`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Frame {
    /// First tangent (unit).
    pub t: DVec3,
    /// Second tangent (unit), `b = n × t`.
    pub b: DVec3,
    /// The axis the frame was built around (unit).
    pub n: DVec3,
}

impl Frame {
    /// Branchless frame of Duff et al., "Building an Orthonormal Basis, Revisited"
    /// (JCGT 2017). `n` is normalised first; a zero or non-finite `n` gives the world frame
    /// around +z, so the result is always finite and orthonormal.
    #[inline]
    pub fn from_normal(n: DVec3) -> Self {
        Self::from_unit_normal(unit_or(n, DVec3::Z))
    }

    /// [`Frame::from_normal`] around `n` as given, for an `n` that is unit up to rounding
    /// already (a surface normal, a sampled direction): skips the renormalisation, so `n`
    /// is the frame's axis bit for bit. An `n` of any other length gives a frame that is
    /// not orthonormal.
    #[inline]
    pub fn from_unit_normal(n: DVec3) -> Self {
        let sign = if n.z >= 0.0 { 1.0 } else { -1.0 };
        let a = -1.0 / (sign + n.z);
        let b = n.x * n.y * a;
        let t = DVec3::new(1.0 + sign * n.x * n.x * a, sign * b, -sign * n.x);
        let bt = DVec3::new(b, sign + n.y * n.y * a, -n.y);
        Self { t, b: bt, n }
    }

    /// A frame around `n` whose first tangent is as close as possible to `hint`
    /// (the component of `hint` orthogonal to `n`). Falls back to [`Frame::from_normal`]
    /// when `hint` is (nearly) parallel to `n`, zero or non-finite.
    #[inline(always)]
    pub fn from_normal_and_hint(n: DVec3, hint: DVec3) -> Self {
        let n = unit_or(n, DVec3::Z);
        let t = hint - n * n.dot(hint);
        let len2 = t.length_squared();
        if !(len2 > 1e-24 * hint.length_squared().max(f64::MIN_POSITIVE)) || !len2.is_finite() {
            return Self::from_normal(n);
        }
        // len2 ≥ 1e-24 · f64::MIN_POSITIVE, so the reciprocal length is finite.
        let mut t = t * (1.0 / libm::sqrt(len2));
        // Second Gram–Schmidt pass: a hint nearly parallel to n (the projection lost more
        // than half its length) leaves a residue along n after the first one.
        if len2 < 0.25 * hint.length_squared() {
            t = (t - n * n.dot(t)).normalize_or_zero();
            if t == DVec3::ZERO || !t.is_finite() {
                return Self::from_normal(n);
            }
        }
        Self { t, b: n.cross(t), n }
    }

    /// Local coordinates `(x, y, z)` to world: `x t + y b + z n`.
    #[inline]
    pub fn to_world(&self, v: DVec3) -> DVec3 {
        self.t * v.x + self.b * v.y + self.n * v.z
    }

    /// World vector to local coordinates.
    #[inline]
    pub fn to_local(&self, v: DVec3) -> DVec3 {
        DVec3::new(v.dot(self.t), v.dot(self.b), v.dot(self.n))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn check(f: &Frame) {
        for (a, b) in [(f.t, f.b), (f.b, f.n), (f.t, f.n)] {
            assert!(a.dot(b).abs() < 1e-12);
        }
        for v in [f.t, f.b, f.n] {
            assert!((v.length() - 1.0).abs() < 1e-12);
        }
        assert!((f.t.cross(f.b) - f.n).length() < 1e-12);
    }

    proptest! {
        #[test]
        fn orthonormal(x in -1.0f64..1.0, y in -1.0f64..1.0, z in -1.0f64..1.0) {
            let n = DVec3::new(x, y, z);
            prop_assume!(n.length() > 1e-3);
            check(&Frame::from_normal(n));
            check(&Frame::from_normal_and_hint(n, DVec3::new(y, z, x)));
        }

        /// Around a normalised `n` (unit up to rounding), `from_unit_normal` keeps `n` bit
        /// for bit as its axis, is orthonormal, and agrees with `from_normal` (which
        /// renormalises first) to rounding.
        #[test]
        fn unit_normal_frame(x in -1.0f64..1.0, y in -1.0f64..1.0, z in -1.0f64..1.0) {
            let n = DVec3::new(x, y, z);
            prop_assume!(n.length() > 1e-3);
            let n = n.normalize();
            let f = Frame::from_unit_normal(n);
            check(&f);
            prop_assert_eq!(f.n, n);
            let g = Frame::from_normal(n);
            for (a, b) in [(f.t, g.t), (f.b, g.b), (f.n, g.n)] {
                prop_assert!((a - b).length() < 1e-15, "{:?} vs {:?}", a, b);
            }
        }
    }

    #[test]
    fn degenerate_inputs_are_finite() {
        for n in [DVec3::ZERO, DVec3::NAN, DVec3::INFINITY, DVec3::new(0.0, 0.0, -1.0)] {
            check(&Frame::from_normal(n));
            check(&Frame::from_normal_and_hint(n, n));
        }
        let f = Frame::from_normal_and_hint(DVec3::Z, DVec3::X * 2.0);
        assert!((f.t - DVec3::X).length() < 1e-15);
    }
}
