//! The 30-bit Morton code of the store's sort keys (`arpa_morton_code` in `morton.wgsl`,
//! [`crate::gpu::shaders::MORTON`], bit-exact) and of the order in which a mesh's triangles go
//! into its bottom-level acceleration structure ([`crate::gpu::scene::morton_triangle_order`]).

/// `1 / (hi − lo)` per axis, 0 where that is not finite (a flat or degenerate axis puts
/// every point in cell 0 of it): the `inv_extent` of [`morton_code`].
pub fn inverse_extent(lo: [f32; 3], hi: [f32; 3]) -> [f32; 3] {
    core::array::from_fn(|k| {
        let e = hi[k] - lo[k];
        if e > 0.0 && (1.0 / e).is_finite() { 1.0 / e } else { 0.0 }
    })
}

/// 30-bit Morton code (10 bits per axis, x in the lowest bit of each triple) of `p` in the
/// box `lo + [0, 1/inv_extent]` (metres; `inv_extent` in 1/m, 0 on a flat axis). Points
/// outside the box are clamped to it; a non-finite coordinate counts as the box's low end.
pub fn morton_code(p: [f32; 3], lo: [f32; 3], inv_extent: [f32; 3]) -> u32 {
    let spread = |v: u32| {
        let mut x = v & 0x3ff;
        x = (x | (x << 16)) & 0x0300_00ff;
        x = (x | (x << 8)) & 0x0300_f00f;
        x = (x | (x << 4)) & 0x030c_30c3;
        (x | (x << 2)) & 0x0924_9249
    };
    let cell = |i: usize| {
        let c = (p[i] - lo[i]) * inv_extent[i] * 1024.0;
        // NaN compares as neither: cell 0, as the WGSL `!(c > 0.0)`.
        match c.partial_cmp(&0.0) {
            Some(core::cmp::Ordering::Greater) if c < 1023.0 => c as u32,
            Some(core::cmp::Ordering::Greater) => 1023,
            _ => 0,
        }
    };
    spread(cell(0)) | (spread(cell(1)) << 1) | (spread(cell(2)) << 2)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn codes_interleave_the_cells_and_clamp() {
        let lo = [0.0; 3];
        let inv = [1.0; 3];
        assert_eq!(morton_code([0.0; 3], lo, inv), 0);
        // Cell 1 on x only: bit 0; on y: bit 1; on z: bit 2.
        let c = 1.5 / 1024.0;
        assert_eq!(morton_code([c, 0.0, 0.0], lo, inv), 1);
        assert_eq!(morton_code([0.0, c, 0.0], lo, inv), 2);
        assert_eq!(morton_code([0.0, 0.0, c], lo, inv), 4);
        assert_eq!(morton_code([2.0, 2.0, 2.0], lo, inv), (1 << 30) - 1);
        // NaN and below the box: cell 0; infinite: the last cell, 1023 (every z bit).
        assert_eq!(morton_code([f32::NAN, -1.0, f32::INFINITY], lo, inv), 0x0924_9249 << 2);
    }

    #[test]
    fn flat_axes_have_no_extent() {
        assert_eq!(inverse_extent([0.0, 1.0, 0.0], [2.0, 1.0, f32::INFINITY]), [0.5, 0.0, 0.0]);
        assert_eq!(inverse_extent([0.0; 3], [1e-40, 1.0, -1.0]), [0.0, 1.0, 0.0]);
    }
}
