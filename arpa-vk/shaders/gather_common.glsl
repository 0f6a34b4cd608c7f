// GLSL copy of the gather's exact tests and contributions, shared by gather.rint and
// gather.rahit (the stages naga 30 cannot express). Each function mirrors one function of
// arpa_core and of its WGSL twin, operation for operation:
//   arpa_footprint_filter_coords      PackedFootprint::filter_coords      (footprint.wgsl)
//   arpa_footprint_contains           PackedFootprint::contains           (footprint.wgsl)
//   arpa_kernel_eval                  Kernel::eval                        (kernel.wgsl)
//   arpa_inv_scale2                   bandwidth::inv_scale2               (bandwidth.wgsl)
//   arpa_footprint_irradiance_scales  PackedFootprint::irradiance_scales  (bandwidth.wgsl)
//   arpa_photon_contains              PackedPhoton::contains
//   arpa_photon_irradiance_scales     PackedPhoton::irradiance_scales     (bandwidth.wgsl)
// The *_scales functions give every scale of the bandwidth ladder the parameters ask for;
// their scale 0 is PackedFootprint::irradiance and PackedPhoton::irradiance bit for bit
// (scale 0 multiplies by 2^0 = 1, exact). Dot products are written out in glam's order (x,
// then y, then z) and `precise` forbids contracting them into fused multiply-adds, so on a
// conforming device the tests decide as the core's f32 code does. Covered by
// arpa-vk/tests/gather_hit_group.rs (against arpa_core::gather::estimate::gather_brute_force and
// gather_brute_force_scales); edit with the core and the WGSL twin.
//
// Records: instance custom index = ARPA_INSTANCE_PHOTON_BIT for progressive photons, plus
// the index of the instance's first record (ARPA_INSTANCE_INDEX_MASK); primitive i of the
// instance is record first + i (arpa_core::gpu::codes::INSTANCE_*, as gather.wgsl); the
// map is the record's.


const uint ARPA_INSTANCE_PHOTON_BIT = 0x800000u;
const uint ARPA_INSTANCE_INDEX_MASK = 0x7fffffu;
const float ARPA_F32_MAX = 3.40282347e38; // f32::MAX
const float ARPA_FRAC_1_PI = 0.31830988618379067;
// 3 FRAC_1_PI as the core forms it, an f32 product (bits 0x3f747644); glslang folds
// `3.0 * ARPA_FRAC_1_PI` in double and rounds once, which gives 0.95492965, one ulp above,
// and made every Silverman contribution differ. (2 FRAC_1_PI is exact either way.)
const float ARPA_3_FRAC_1_PI = 0.9549296;

// hitKind reported by the intersection shader.
const uint ARPA_HIT_FOOTPRINT = 0u;
const uint ARPA_HIT_PHOTON = 1u;
// Added to the hit kind of a candidate whose record does not contain the query point.
const uint ARPA_HIT_OUTSIDE = 2u;

// arpa_core::store::footprint::PackedFootprint (64 bytes).
struct ArpaPackedFootprint {
    vec3 center;
    uint map;
    vec3 row_u;
    float flux_density_r;
    vec3 row_v;
    float flux_density_g;
    vec3 row_n;
    float flux_density_b;
};

// arpa_core::store::progressive_photon::PackedPhoton (48 bytes).
struct ArpaPackedPhoton {
    vec3 position;
    uint map;
    vec3 normal;
    uint pad0;
    vec3 flux;
    uint pad1;
};

// Bindings of set 0 as arpa-core's path/gather.wgsl declares them (the ray generation is
// that file's arpa_gather_pixel, composed by arpa-vk): 0 footprints, 1 photons, 4 the
// parameters, 7 the top level over the record boxes.
//
// The gather's parameters (arpa_core::gpu::layout::GatherImageParams, 32 bytes): progressive
// radius per map (metres), the footprints' kernel id (ARPA_KERNEL_*: 0 constant,
// 1 Epanechnikov, 2 Silverman), the number of query records, the batch flags (unused here),
// the scales to evaluate (1, or ARPA_SCALES for a per-pixel bandwidth; clamped to
// 1 ..= ARPA_SCALES).
layout(set = 0, binding = 4, std430) readonly buffer ArpaGatherParams {
    vec2 radii;
    uint kernel;
    uint query_count;
    uint batch;
    uint scales;
    uint pad1;
    uint pad2;
} arpa_params;

// arpa_core::gather::scales::SCALES (bandwidth.wgsl's ARPA_SCALES).
const uint ARPA_SCALES = 5u;

layout(set = 0, binding = 0, std430) readonly buffer ArpaFootprints { ArpaPackedFootprint arpa_footprints[]; };
layout(set = 0, binding = 1, std430) readonly buffer ArpaPhotons { ArpaPackedPhoton arpa_photons[]; };

bool arpa_is_finite(float x) {
    return (floatBitsToUint(x) & 0x7f800000u) != 0x7f800000u;
}

bool arpa_is_finite3(vec3 v) {
    return arpa_is_finite(v.x) && arpa_is_finite(v.y) && arpa_is_finite(v.z);
}

// a . b in glam's order, without contraction.
float arpa_dot(vec3 a, vec3 b) {
    precise float d = a.x * b.x + a.y * b.y + a.z * b.z;
    return d;
}

// Filter-space coordinates; far queries clamp to +-f32::MAX, NaN maps to +f32::MAX.
vec3 arpa_footprint_filter_coords(ArpaPackedFootprint fp, vec3 q) {
    precise vec3 delta = q - fp.center;
    vec3 y = vec3(arpa_dot(fp.row_u, delta), arpa_dot(fp.row_v, delta), arpa_dot(fp.row_n, delta));
    for (int c = 0; c < 3; c++) {
        uint bits = floatBitsToUint(y[c]) & 0x7fffffffu;
        y[c] = bits > 0x7f800000u ? ARPA_F32_MAX : clamp(y[c], -ARPA_F32_MAX, ARPA_F32_MAX);
    }
    return y;
}

float arpa_r2(vec3 y) {
    precise float r2 = y.x * y.x + y.y * y.y;
    return r2;
}

bool arpa_footprint_contains(ArpaPackedFootprint fp, vec3 q) {
    vec3 y = arpa_footprint_filter_coords(fp, q);
    return arpa_r2(y) <= 1.0 && abs(y.z) <= 1.0;
}

// K(r2) for r2 < 1, else 0 (NaN gives 0).
float arpa_kernel_eval(uint kernel, float r2_in) {
    if (!(r2_in < 1.0)) {
        return 0.0;
    }
    precise float s = 1.0 - max(r2_in, 0.0);
    precise float k;
    if (kernel == 0u) {
        k = ARPA_FRAC_1_PI;
    } else if (kernel == 1u) {
        k = 2.0 * ARPA_FRAC_1_PI * s;
    } else {
        k = ARPA_3_FRAC_1_PI * s * s;
    }
    return k;
}

// bandwidth::inv_scale2: 2^k (exact), the factor scale k multiplies r^2 and the density by.
float arpa_inv_scale2(uint k) {
    return float(1u << k);
}

// The scales actually evaluated: arpa_params.scales clamped to 1 ..= ARPA_SCALES.
uint arpa_scales() {
    return clamp(arpa_params.scales, 1u, ARPA_SCALES);
}

// PackedFootprint::irradiance_scales into e for scales 0 .. scales - 1 (later entries 0):
// density 2^k K(2^k r^2) inside the ellipse and slab shrunk by 2^(-k/2) and on the lit side.
void arpa_footprint_irradiance_scales(ArpaPackedFootprint fp, vec3 q, vec3 query_normal, uint kernel, uint scales,
                                      out vec3 e[ARPA_SCALES]) {
    for (uint k = 0u; k < ARPA_SCALES; k++) {
        e[k] = vec3(0.0);
    }
    vec3 y = arpa_footprint_filter_coords(fp, q);
    float r2 = arpa_r2(y);
    if (r2 <= 1.0 && abs(y.z) <= 1.0 && arpa_dot(fp.row_n, query_normal) > 0.0) {
        vec3 density = vec3(fp.flux_density_r, fp.flux_density_g, fp.flux_density_b);
        for (uint k = 0u; k < min(scales, ARPA_SCALES); k++) {
            float f = arpa_inv_scale2(k);
            precise float x = r2 * f;
            precise float z = y.z * y.z * f;
            // Scale k shrinks the ellipse and the slab by 2^(-k/2); the regions are nested:
            // once q is outside one, it is outside the smaller.
            if (k > 0u && !(x < 1.0 && z <= 1.0)) {
                break;
            }
            precise vec3 s = density * (arpa_kernel_eval(kernel, x) * f);
            e[k] = s;
        }
    }
}

// Sphere test |q - x_p|^2 < radius^2.
bool arpa_photon_contains(ArpaPackedPhoton ph, vec3 q, float radius) {
    precise vec3 d = q - ph.position;
    precise float r2 = radius * radius;
    return arpa_dot(d, d) < r2;
}

// PackedPhoton::irradiance_scales into e for scales 0 .. scales - 1 (later entries 0):
// flux 2^k / (pi r^2) where |q - x_p|^2 2^k < r^2 and on the lit side (0 where the density
// or the result is not finite).
void arpa_photon_irradiance_scales(ArpaPackedPhoton ph, vec3 q, vec3 query_normal, float radius, uint scales,
                                   out vec3 e[ARPA_SCALES]) {
    for (uint k = 0u; k < ARPA_SCALES; k++) {
        e[k] = vec3(0.0);
    }
    precise float density = ARPA_FRAC_1_PI / (radius * radius);
    precise vec3 d = q - ph.position;
    float d2 = arpa_dot(d, d);
    precise float r2 = radius * radius;
    if (arpa_is_finite(density) && arpa_dot(ph.normal, query_normal) > 0.0) {
        for (uint k = 0u; k < min(scales, ARPA_SCALES); k++) {
            float f = arpa_inv_scale2(k);
            precise float x = d2 * f;
            // The spheres are nested: once q is outside one, it is outside the smaller.
            if (!(x < r2)) {
                break;
            }
            precise vec3 s = ph.flux * (density * f);
            if (arpa_is_finite3(s)) {
                e[k] = s;
            }
        }
    }
}

// sum + (e, 0) when e is non-zero and finite (IrradianceEstimate::add), else sum: a scale's
// total in the payload.
vec4 arpa_add_scaled(vec4 sum, vec3 e) {
    if (any(notEqual(e, vec3(0.0))) && arpa_is_finite3(e)) {
        return vec4(sum.xyz + e, sum.w);
    }
    return sum;
}
