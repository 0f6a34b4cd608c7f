// 30-bit Morton code (10 bits per axis, x in the lowest bit of each triple) of a point in
// the box [lo, lo + 1/inv_extent] (metres; inv_extent in 1/m, 0 on a flat axis): the WGSL
// twin of arpa_core::base::morton::morton_code, bit-exact. Points outside the box are
// clamped to it; a non-finite coordinate counts as the box's low end. Self-contained.

fn arpa_morton_spread10(v: u32) -> u32 {
    var x = v & 0x3ffu;
    x = (x | (x << 16u)) & 0x030000ffu;
    x = (x | (x << 8u)) & 0x0300f00fu;
    x = (x | (x << 4u)) & 0x030c30c3u;
    x = (x | (x << 2u)) & 0x09249249u;
    return x;
}

// Cell of a coordinate scaled to [0, 1]: 1024 cells per axis; NaN fails both comparisons
// and lands in cell 0.
fn arpa_morton_cell(x: f32) -> u32 {
    let c = x * 1024.0;
    if !(c > 0.0) {
        return 0u;
    }
    if !(c < 1023.0) {
        return 1023u;
    }
    return u32(c);
}

fn arpa_morton_code(p: vec3<f32>, lo: vec3<f32>, inv_extent: vec3<f32>) -> u32 {
    let u = (p - lo) * inv_extent;
    return arpa_morton_spread10(arpa_morton_cell(u.x)) | (arpa_morton_spread10(arpa_morton_cell(u.y)) << 1u)
        | (arpa_morton_spread10(arpa_morton_cell(u.z)) << 2u);
}
