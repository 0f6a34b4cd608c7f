//! Axis-aligned bounding boxes (world space, metres): footprint boxes for the
//! acceleration structure and the scene bounds the heuristics measure against.

use glam::DVec3;

/// An axis-aligned box `[min, max]`. An *empty* box has `min > max` on some axis.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Aabb {
    /// Lower corner.
    pub min: DVec3,
    /// Upper corner.
    pub max: DVec3,
}

impl Default for Aabb {
    fn default() -> Self {
        Self::EMPTY
    }
}

impl Aabb {
    /// The empty box (identity of [`Aabb::union`]).
    pub const EMPTY: Self = Self { min: DVec3::INFINITY, max: DVec3::NEG_INFINITY };

    /// The box `centre ± half_extent` (half extents are made non-negative).
    #[inline]
    pub fn from_centre_half_extent(centre: DVec3, half_extent: DVec3) -> Self {
        let h = half_extent.abs();
        Self { min: centre - h, max: centre + h }
    }

    /// The smallest box containing all `points`.
    pub fn from_points(points: impl IntoIterator<Item = DVec3>) -> Self {
        points.into_iter().fold(Self::EMPTY, |b, p| b.including(p))
    }

    /// `true` if the box contains no point.
    #[inline]
    pub fn is_empty(&self) -> bool {
        !(self.min.x <= self.max.x && self.min.y <= self.max.y && self.min.z <= self.max.z)
    }

    /// This box grown to contain `p`.
    #[inline]
    pub fn including(self, p: DVec3) -> Self {
        Self { min: self.min.min(p), max: self.max.max(p) }
    }

    /// Smallest box containing both.
    #[inline]
    pub fn union(self, other: Self) -> Self {
        Self { min: self.min.min(other.min), max: self.max.max(other.max) }
    }

    /// Side lengths (zero for an empty box).
    #[inline]
    pub fn extent(&self) -> DVec3 {
        if self.is_empty() { DVec3::ZERO } else { self.max - self.min }
    }

    /// Length of the main diagonal (metres).
    #[inline]
    pub fn diagonal(&self) -> f64 {
        self.extent().length()
    }

    /// Longest side (metres).
    #[inline]
    pub fn largest_extent(&self) -> f64 {
        self.extent().max_element()
    }

    /// Surface area of the box (m²).
    #[inline]
    pub fn surface_area(&self) -> f64 {
        let e = self.extent();
        2.0 * (e.x * e.y + e.y * e.z + e.z * e.x)
    }

    /// Centre of the box.
    #[inline]
    pub fn centre(&self) -> DVec3 {
        0.5 * (self.min + self.max)
    }

    /// `true` if `p` lies inside or on the boundary.
    #[inline]
    pub fn contains(&self, p: DVec3) -> bool {
        p.cmpge(self.min).all() && p.cmple(self.max).all()
    }

    /// The box as `f32` corners, rounded outwards so it still contains everything it did.
    pub fn to_f32_conservative(&self) -> ([f32; 3], [f32; 3]) {
        let down = |x: f64| {
            let f = x as f32;
            if (f as f64) > x { f.next_down() } else { f }
        };
        let up = |x: f64| {
            let f = x as f32;
            if (f as f64) < x { f.next_up() } else { f }
        };
        ([down(self.min.x), down(self.min.y), down(self.min.z)], [up(self.max.x), up(self.max.y), up(self.max.z)])
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn measures() {
        let b = Aabb::from_points([DVec3::ZERO, DVec3::new(1.0, 2.0, 3.0)]);
        assert_eq!(b.extent(), DVec3::new(1.0, 2.0, 3.0));
        assert_eq!(b.largest_extent(), 3.0);
        assert_eq!(b.surface_area(), 22.0);
        assert!((b.diagonal() - 14f64.sqrt()).abs() < 1e-15);
        assert!(Aabb::EMPTY.is_empty());
        assert_eq!(Aabb::EMPTY.surface_area(), 0.0);
        assert!(b.contains(DVec3::new(0.5, 0.5, 0.5)));
    }

    #[test]
    fn f32_rounding_is_conservative() {
        let b = Aabb { min: DVec3::splat(0.1), max: DVec3::splat(0.3) };
        let (lo, hi) = b.to_f32_conservative();
        for k in 0..3 {
            assert!((lo[k] as f64) <= 0.1 && (hi[k] as f64) >= 0.3);
        }
    }
}
