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

    /// Relative padding of an acceleration-structure box, on top of `f32` rounding.
    ///
    /// The gather's exact tests run in `f32` (`PackedFootprint::irradiance`,
    /// `PackedPhoton::irradiance`) on records rounded from `f64`, and may accept a point a
    /// few ulps outside the exact (`f64`) shape the core's box bounds; the padding keeps
    /// every such point inside the box, so an acceleration structure over padded boxes
    /// finds exactly what a brute-force gather over the same records finds. The WGSL twin
    /// is `arpa_padded_box` (`aabb.wgsl`).
    pub const RELATIVE_PAD: f64 = 1e-4;
    /// Absolute padding in units of the box's largest coordinate magnitude (`f32` ulps of
    /// the position: covers the rounding of the record's centre and rows), plus one more to
    /// cover the round-to-nearest conversion of the padded box to `f32`.
    pub const POSITION_PAD: f64 = 9.0 * f32::EPSILON as f64;
    /// Absolute floor of the padding (covers rounding in `f32`'s subnormal range).
    pub const PAD_FLOOR: f64 = f32::MIN_POSITIVE as f64;

    /// The box grown by the padding above, as `f32` corners `(lower, upper)`: the box an
    /// acceleration structure over the gather's records takes.
    ///
    /// The conversion rounds to nearest (cheap, vectorisable), which is conservative here:
    /// it moves a bound by at most half an `f32` ulp, `2⁻²⁴ |x|` (or `2⁻¹⁵⁰` among
    /// subnormals), where every bound has `|x| ≤ (1 + 10⁻⁴ + 9ε₃₂) s` with
    /// `s = |centre|_∞ + |half|_∞`, and the padding holds `ε₃₂ s` (`≥ 2⁻²⁴ |x|` with room to
    /// spare) plus [`Self::PAD_FLOOR`] beyond the `8 ε₃₂ s` and relative padding the
    /// gather's `f32` tests need. So the result contains what
    /// [`Self::to_f32_conservative`] of the box grown by that padding contains.
    #[inline]
    pub fn padded_f32(&self) -> ([f32; 3], [f32; 3]) {
        let centre = 0.5 * (self.min + self.max);
        let half = 0.5 * (self.max - self.min);
        let scale = centre.abs().max_element() + half.max_element();
        let pad = half * Self::RELATIVE_PAD + DVec3::splat(Self::POSITION_PAD * scale + Self::PAD_FLOOR);
        ((self.min - pad).as_vec3().to_array(), (self.max + pad).as_vec3().to_array())
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

/// Where a device store puts the box of an empty slot (an *inactive* box: min = max = this
/// point, metres), given the low corner `lo` of the scene's `f32` bounds: `lo − (|lo| + 1)`
/// per axis, finite and strictly below `lo`, so that no point of the scene, and no point
/// query of negligible length started there, meets it. The acceleration structures are
/// built over the store's whole capacity and these boxes fill what an iteration leaves
/// empty; a degenerate box is used rather than a NaN one, which some builders (lavapipe)
/// mishandle. Twin: `arpa_inactive_point` of `store/aabb.wgsl`.
pub fn inactive_point(lo: [f32; 3]) -> [f32; 3] {
    lo.map(|x| x - (x.abs() + 1.0))
}

#[cfg(test)]
mod tests {
    #[test]
    fn inactive_points_lie_below_the_scene() {
        for x in [0.0f32, -0.0, 1.0, -1.0, 3.5, -7.25, 1e8, -1e8, 1e30, -1e30, f32::MIN_POSITIVE, 16_777_217.0] {
            let p = super::inactive_point([x; 3]);
            assert!(p.iter().all(|v| v.is_finite() && *v < x), "{x}: {p:?}");
        }
    }

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

    /// The padded box contains the box grown by the padding the `f32` tests need, rounded
    /// outwards (so the round-to-nearest conversion is conservative), and stays tight; for
    /// boxes near and far from the origin, large and tiny, straddling zero or not.
    #[test]
    fn padded_box_contains_the_exact_box_and_is_tight() {
        let mut boxes = alloc::vec![
            Aabb { min: DVec3::new(0.1, -2.0, 1e-9), max: DVec3::new(0.3, -1.9, 2e-9) },
            Aabb { min: DVec3::splat(-1e-40), max: DVec3::splat(1e-40) },
        ];
        // SplitMix64 in [-1, 1).
        let mut state = 11u64;
        let mut f = || {
            state = state.wrapping_add(0x9E37_79B9_7F4A_7C15);
            let mut z = state;
            z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
            z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
            z ^= z >> 31;
            (z >> 11) as f64 / (1u64 << 52) as f64 - 1.0
        };
        for i in 0..20_000 {
            let scale = libm::pow(10.0, 8.0 * f());
            let centre = DVec3::new(f(), f(), f()) * scale * if i % 4 == 0 { 1e-3 } else { 1.0 };
            let half = (DVec3::new(f(), f(), f()).abs() + DVec3::splat(1e-12)) * scale * libm::pow(10.0, -4.0 * f().abs());
            boxes.push(Aabb::from_centre_half_extent(centre, half));
        }
        for b in &boxes {
            let (lower, upper) = b.padded_f32();
            let centre = 0.5 * (b.min + b.max);
            let half = 0.5 * (b.max - b.min);
            let s = centre.abs().max_element() + half.max_element();
            let need = half * Aabb::RELATIVE_PAD + DVec3::splat(8.0 * f32::EPSILON as f64 * s);
            let (lo, hi) = Aabb { min: b.min - need, max: b.max + need }.to_f32_conservative();
            for k in 0..3 {
                assert!(lower[k] <= lo[k] && upper[k] >= hi[k], "{b:?}: {lower:?} {upper:?} vs {lo:?} {hi:?}");
                let size = b.max[k] - b.min[k];
                let slack = 20.0 * f32::EPSILON as f64 * s;
                assert!((upper[k] - lower[k]) as f64 <= size * 1.001 + 2.0 * slack + 1e-37, "{b:?}: {lower:?} {upper:?}");
            }
        }
    }
}
