// WGSL twin of arpa_core::gather::scales (the scale ladder of the per-pixel bandwidth) and of the
// evaluations at every scale, PackedFootprint::irradiance_scales and
// PackedPhoton::irradiance_scales. Scale k shrinks a footprint's stored ellipse by
// 2^(-k/2): weight 2^k K(2^k r^2) times the stored density, inside the stored ellipse, slab
// and side tests; a progressive photon's radius likewise: |q - x|^2 2^k < r^2, density
// 2^k / (pi r^2). The factors 2^k are exact in f32. Then the per-iteration luminance moments
// (bandwidth::luminance, bandwidth::moments) the selection compares. Needs kernel.wgsl
// (arpa_kernel_eval, ARPA_FRAC_1_PI) and footprint.wgsl (the record, its filter coordinates
// and side test, arpa_is_finite).
//
// Precision (eps32 = 2^-23), as the twin-footprint conformance case holds it:
// * the scaled weights are the core's f32 expressions (same products, same kernel), so at
//   a decided point (r^2 2^k, |y.z| and d^2 2^k / r^2 away from 1 by more than the filter
//   coordinates' rounding) each scale agrees with the core as the stored scale does: a
//   footprint's within 1e-6 of 2^k times its density plus 2^k times the kernel's slope
//   times the r^2 margin; a photon's within 8 eps32 relative (WGSL allows 2.5 ulp for the
//   density's division). Scale 0 is bit for bit arpa_footprint_irradiance's value and the
//   stored photon contribution (multiplying by 2^0 = 1 is exact).
// * the luminance is three products and two sums in the core's order; FMA contraction may
//   drop roundings, so it agrees within 3 eps32 of sum_i |w_i c_i|. The moments square
//   those luminances and their differences in f32.
//
// Planes of one pixel (plane-major in the image, plane p of pixel i at p * pixels + i):
// ARPA_SCALES radiance planes (scale k in plane k), then ARPA_MOMENT_PLANES moment planes.

// bandwidth::SCALES, MOMENT_PLANES, PLANES.
const ARPA_SCALES: u32 = 5u;
const ARPA_MOMENT_PLANES: u32 = 3u;
const ARPA_PLANES: u32 = 8u;

// bandwidth::inv_scale2: 1 / s_k^2 = 2^k (exact), the factor scale k multiplies the stored
// squared filter radius and the density by.
fn arpa_inv_scale2(k: u32) -> f32 {
    return f32(1u << k);
}

// PackedFootprint::irradiance_scales (W/m^2, RGB) for scales 0 .. min(scales, ARPA_SCALES) - 1;
// the entries from `scales` on are 0 (the core evaluates all five; a global-bandwidth gather
// asks for one). `kernel` is an ARPA_KERNEL_* id.
fn arpa_footprint_irradiance_scales(fp: ArpaPackedFootprint, q: vec3<f32>, query_normal: vec3<f32>, kernel: u32,
                                    scales: u32) -> array<vec3<f32>, ARPA_SCALES> {
    var e: array<vec3<f32>, ARPA_SCALES>;
    let y = arpa_footprint_filter_coords(fp, q);
    let r2 = y.x * y.x + y.y * y.y;
    if r2 <= 1.0 && abs(y.z) <= 1.0 && arpa_footprint_faces(fp, query_normal) {
        let d = vec3<f32>(fp.flux_density_r, fp.flux_density_g, fp.flux_density_b);
        for (var k = 0u; k < min(scales, ARPA_SCALES); k++) {
            let f = arpa_inv_scale2(k);
            // Scale k shrinks the ellipse and the slab by 2^(-k/2): |y.xy|^2 2^k < 1 and
            // y.z^2 2^k <= 1. The regions are nested: once q is outside one, it is outside the
            // smaller (the core stops there too; the entries left are 0 either way).
            if k > 0u && !(r2 * f < 1.0 && y.z * y.z * f <= 1.0) {
                break;
            }
            e[k] = d * (arpa_kernel_eval(kernel, r2 * f) * f);
        }
    }
    return e;
}

// PackedPhoton::irradiance_scales (W/m^2, RGB) of a progressive photon at `position` (metres)
// with unit `normal` and `flux` (W, RGB), at q with normal query_normal, for the progressive
// radius `radius` (metres): flux 2^k / (pi r^2) where |q - position|^2 2^k < r^2 and on the
// lit side, else 0 (also 0 where the density or the result is not finite), for scales
// 0 .. min(scales, ARPA_SCALES) - 1; later entries 0.
fn arpa_photon_irradiance_scales(position: vec3<f32>, normal: vec3<f32>, flux: vec3<f32>, q: vec3<f32>,
                                 query_normal: vec3<f32>, radius: f32, scales: u32) -> array<vec3<f32>, ARPA_SCALES> {
    var e: array<vec3<f32>, ARPA_SCALES>;
    let density = ARPA_FRAC_1_PI / (radius * radius);
    let d = q - position;
    let d2 = dot(d, d);
    if arpa_is_finite(density) && dot(normal, query_normal) > 0.0 {
        for (var k = 0u; k < min(scales, ARPA_SCALES); k++) {
            let f = arpa_inv_scale2(k);
            // The spheres are nested: once q is outside one, it is outside the smaller.
            if !(d2 * f < radius * radius) {
                break;
            }
            let s = flux * (density * f);
            if arpa_is_finite3(s) {
                e[k] = s;
            }
        }
    }
    return e;
}

// bandwidth::luminance: Rec. 709 luminance of a linear RGB radiance, in the core's order.
fn arpa_luminance(c: vec3<f32>) -> f32 {
    return 0.2126 * c.x + 0.7152 * c.y + 0.0722 * c.z;
}

// bandwidth::moments: of one iteration's radiance per scale (index = scale), value k <
// ARPA_SCALES is y_k^2 and value ARPA_SCALES + k (k < ARPA_SCALES - 1) is (y_k - y_{k+1})^2
// (neighbouring scales) with y the luminance, three values per plane in that order (x, y, z).
fn arpa_moments(radiance: array<vec3<f32>, ARPA_SCALES>) -> array<vec3<f32>, ARPA_MOMENT_PLANES> {
    var y: array<f32, ARPA_SCALES>;
    for (var k = 0u; k < ARPA_SCALES; k++) {
        y[k] = arpa_luminance(radiance[k]);
    }
    var v: array<f32, 9>;
    for (var k = 0u; k < ARPA_SCALES; k++) {
        v[k] = y[k] * y[k];
    }
    for (var k = 0u; k + 1u < ARPA_SCALES; k++) {
        let d = y[k] - y[k + 1u];
        v[ARPA_SCALES + k] = d * d;
    }
    var out: array<vec3<f32>, ARPA_MOMENT_PLANES>;
    for (var p = 0u; p < ARPA_MOMENT_PLANES; p++) {
        out[p] = vec3<f32>(v[3u * p], v[3u * p + 1u], v[3u * p + 2u]);
    }
    return out;
}
