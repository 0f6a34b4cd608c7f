// WGSL twin of arpa_core::base::aabb::Aabb::padded_f32: an acceleration-structure box grown by
// the padding that keeps every point the gather's f32 tests accept inside it (relative
// padding Aabb::RELATIVE_PAD, position padding Aabb::POSITION_PAD in units of the box's
// largest coordinate magnitude, floor Aabb::PAD_FLOOR). Needs footprint.wgsl
// (arpa_max_abs, ARPA_F32_MIN_POSITIVE). Metres.
//
// Precision: the core pads in f64 and rounds each padded bound to f32 once; this twin pads
// in f32 from the box's f32 centre and half extent, so each bound carries two roundings
// (half + pad, then centre -+ that), at most eps32 * s together with s = |centre|_inf +
// |half|_inf, besides the negligible rounding of the padding itself. The position padding
// holds 9 eps32 s where the gather's f32 tests need 8 eps32 s, which leaves room for them:
// the box contains the exact box centre +- half grown by what the tests need (checked by
// arpa-wgpu's aabb_twin test), as the core's does.

const ARPA_AABB_RELATIVE_PAD: f32 = 1e-4;
const ARPA_AABB_POSITION_PAD: f32 = 9.0 * 1.1920929e-7;

// Corners of an axis-aligned box (metres).
struct ArpaBox {
    lower: vec3<f32>,
    upper: vec3<f32>,
}

// The box centre +- half (half >= 0 per axis) grown by the padding above.
fn arpa_padded_box(centre: vec3<f32>, half: vec3<f32>) -> ArpaBox {
    let scale = arpa_max_abs(centre) + max(half.x, max(half.y, half.z));
    let pad = half * ARPA_AABB_RELATIVE_PAD + ARPA_AABB_POSITION_PAD * scale + ARPA_F32_MIN_POSITIVE;
    return ArpaBox(centre - (half + pad), centre + (half + pad));
}

// The point of an inactive box (an empty slot of the store's capacity) below the scene's
// low corner lo: lo - (|lo| + 1), finite and strictly below lo (metres). Twin of
// arpa_core::base::aabb::inactive_point.
fn arpa_inactive_point(lo: vec3<f32>) -> vec3<f32> {
    return lo - (abs(lo) + vec3<f32>(1.0));
}
