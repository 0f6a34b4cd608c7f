// WGSL twin of arpa_core::store::footprint: the f32 footprint record (PackedFootprint, same 64-byte
// layout), its construction from a footprint (Footprint::pack: M_p^-1 rows, slab, flux
// density, the same error labels), the point-in-footprint test and the irradiance of one
// footprint at a query point. Needs kernel.wgsl (arpa_kernel_eval) for the irradiance.
//
// Precision: the Rust core builds the record in f64 and rounds once; this twin works in
// f32 throughout. Products are formed on vectors pre-scaled by their largest component, so
// nothing overflows or underflows unless the stored value itself does (inputs of any
// normal-f32 magnitude work). The rows carry a relative error of about c eps32 / sin(theta),
// theta the angle between D_u and D_v, and the degenerate test uses 16 eps32 where the core
// uses 16 eps64: D_u, D_v closer to parallel than sin(theta) ~ 2e-6 are labelled degenerate
// here (f32 cannot resolve them) although the f64 core may still pack them. The slab
// half-thickness is the minor semi-axis sigma_2 = |D_u x D_v| / (2 sigma_1) (clamped to
// the radius), relative error ~ eps32 sigma_1/sigma_2 (the f32 rounding of the cross product).

const ARPA_F32_EPSILON: f32 = 1.1920929e-7;
const ARPA_F32_MAX: f32 = 0x1.fffffep+127f;
const ARPA_F32_MIN_POSITIVE: f32 = 1.17549435e-38;
// MIN_RELATIVE_SEMI_AXIS = 64 eps32.
const ARPA_MIN_RELATIVE_SEMI_AXIS: f32 = 64.0 * 1.1920929e-7;

// Footprint status labels (FootprintError).
const ARPA_FOOTPRINT_OK: u32 = 0u;
const ARPA_FOOTPRINT_DEGENERATE: u32 = 1u;
const ARPA_FOOTPRINT_UNREPRESENTABLE: u32 = 2u;
const ARPA_FOOTPRINT_INVALID_NORMAL: u32 = 3u;

// PackedFootprint (64 bytes; vec3 + scalar groups). y = (row_u, row_v, row_n) . (q - center)
// is the filter transform: inside iff y.x^2 + y.y^2 <= 1 and |y.z| <= 1.
struct ArpaPackedFootprint {
    center: vec3<f32>,        // x_p (metres)
    map: u32,                 // 0 caustic, 1 global
    row_u: vec3<f32>,         // first row of M_p^-1 (1/m)
    flux_density_r: f32,      // Phi 4/|D_u x D_v| (W/m^2)
    row_v: vec3<f32>,         // second row of M_p^-1 (1/m)
    flux_density_g: f32,
    row_n: vec3<f32>,         // n/h (1/m)
    flux_density_b: f32,
}

// A packed record and the status of its construction (ARPA_FOOTPRINT_*); the record is
// meaningful only when status == ARPA_FOOTPRINT_OK.
struct ArpaPackResult {
    fp: ArpaPackedFootprint,
    status: u32,
}

// true when x is neither infinite nor NaN (bit test; needs no NaN-aware comparison).
fn arpa_is_finite(x: f32) -> bool {
    return (bitcast<u32>(x) & 0x7f800000u) != 0x7f800000u;
}

fn arpa_is_finite3(v: vec3<f32>) -> bool {
    return arpa_is_finite(v.x) && arpa_is_finite(v.y) && arpa_is_finite(v.z);
}

fn arpa_max_abs(v: vec3<f32>) -> f32 {
    let a = abs(v);
    return max(a.x, max(a.y, a.z));
}

// |v| without overflow or underflow of the squares (metres in, metres out).
fn arpa_safe_length(v: vec3<f32>) -> f32 {
    let m = arpa_max_abs(v);
    if !(m > 0.0) || !arpa_is_finite(m) {
        return m;
    }
    return m * length(v / m);
}

// (2 sigma_1)^2 in the units of la2: the larger eigenvalue of the Gram matrix
// [[la2, uv], [uv, lb2]] of two differentials (arpa_core::store::footprint::principal_axes).
fn arpa_major_axis2(la2: f32, lb2: f32, uv: f32) -> f32 {
    let h = 0.5 * (la2 - lb2);
    return 0.5 * (la2 + lb2) + sqrt(h * h + uv * uv);
}

// Principal axis lengths (2 sigma_1, 2 sigma_2) in metres of the ellipse spanned by the
// tangent differentials du, dv (Footprint::axis_lengths): the Gram matrix of the vectors
// pre-scaled by their largest component, 2 sigma_2 = |du x dv| / (2 sigma_1).
fn arpa_footprint_axes(du: vec3<f32>, dv: vec3<f32>) -> vec2<f32> {
    let m = max(arpa_max_abs(du), arpa_max_abs(dv));
    if !(m > 0.0) || !arpa_is_finite(m) {
        return vec2<f32>(m, 0.0);
    }
    let uh = du / m;
    let vh = dv / m;
    let l1 = sqrt(arpa_major_axis2(dot(uh, uh), dot(vh, vh), dot(uh, vh)));
    let l2 = min(length(cross(uh, vh)) / l1, l1);
    return m * vec2<f32>(l1, l2);
}

// Slab half-thickness (metres) for principal axis lengths major = 2 sigma_1, minor =
// 2 sigma_2: min(minor/2, radius), at least 8 eps32 (|x_p|_inf + major).
fn arpa_half_thickness(center: vec3<f32>, major: f32, minor: f32, radius: f32) -> f32 {
    let floor_h = 8.0 * ARPA_F32_EPSILON * (arpa_max_abs(center) + major);
    return max(min(0.5 * minor, radius), floor_h);
}

// Footprint::pack: the record of the footprint (center, unit normal, tangent differentials
// du, dv in metres, RGB flux in W, map) with the slab of progressive radius `radius` (m).
fn arpa_footprint_pack(center: vec3<f32>, normal: vec3<f32>, du: vec3<f32>, dv: vec3<f32>,
                       flux: vec3<f32>, map: u32, radius: f32) -> ArpaPackResult {
    var out: ArpaPackResult;
    out.status = ARPA_FOOTPRINT_DEGENERATE;
    let su = arpa_max_abs(du);
    let sv = arpa_max_abs(dv);
    if !(su > 0.0) || !(sv > 0.0) || !arpa_is_finite(su) || !arpa_is_finite(sv) || !arpa_is_finite3(normal) {
        return out;
    }
    let uh = du / su;
    let vh = dv / sv;
    let lu2 = dot(uh, uh);
    let lv2 = dot(vh, vh);
    let ch = cross(uh, vh);
    // (D_u x D_v) . n = su sv den_h.
    let den_h = dot(ch, normal);
    let k = 16.0 * ARPA_F32_EPSILON;
    if !(den_h * den_h > k * k * lu2 * lv2) {
        return out;
    }
    let axes = arpa_footprint_axes(du, dv);
    let h = arpa_half_thickness(center, axes.x, axes.y, radius);
    // Representability: |a x b| / sqrt(|a|^2 + |b|^2) (a, b = D/2) >= 64 eps32 max(|x_p|, 1e-30).
    out.status = ARPA_FOOTPRINT_UNREPRESENTABLE;
    let m = max(su, sv);
    let ru = su / m;
    let rv = sv / m;
    let bound = 0.5 * min(su, sv) * length(ch) / sqrt(ru * ru * lu2 + rv * rv * lv2);
    let scale = max(arpa_max_abs(center), 1e-30) * ARPA_MIN_RELATIVE_SEMI_AXIS;
    if !(bound >= scale) || !(h > 0.0) {
        return out;
    }
    let two_over = 2.0 / den_h;
    let row_u = cross(vh, normal) * (two_over / su);
    let row_v = cross(normal, uh) * (two_over / sv);
    // Phi 4/|D_u x D_v| = Phi (4/|den_h|) / (su sv): the scales' exponents are applied
    // last and exactly (ldexp), so no intermediate leaves the normal range early.
    let fm = frexp(su);
    let fn_ = frexp(sv);
    let density = ldexp(flux * (2.0 * abs(two_over) / (fm.fract * fn_.fract)), vec3<i32>(-(fm.exp + fn_.exp)));
    for (var c = 0; c < 3; c++) {
        if flux[c] != 0.0 && !(abs(density[c]) >= ARPA_F32_MIN_POSITIVE) {
            return out;
        }
    }
    let row_n = normal * (1.0 / h);
    if !(arpa_is_finite3(center) && arpa_is_finite3(row_u) && arpa_is_finite3(row_v)
         && arpa_is_finite3(row_n) && arpa_is_finite3(density)) {
        return out;
    }
    out.fp = ArpaPackedFootprint(center, map, row_u, density.x, row_v, density.y, row_n, density.z);
    out.status = ARPA_FOOTPRINT_OK;
    return out;
}

// Filter-space coordinates (row_u.D, row_v.D, row_n.D), D = q - x_p (dimensionless);
// far queries are clamped to +-f32::MAX and NaN maps to +f32::MAX (outside), as in Rust.
fn arpa_footprint_filter_coords(fp: ArpaPackedFootprint, q: vec3<f32>) -> vec3<f32> {
    let delta = q - fp.center;
    var y = vec3<f32>(dot(fp.row_u, delta), dot(fp.row_v, delta), dot(fp.row_n, delta));
    for (var c = 0; c < 3; c++) {
        let bits = bitcast<u32>(y[c]) & 0x7fffffffu;
        if bits > 0x7f800000u {
            y[c] = ARPA_F32_MAX;
        } else {
            y[c] = clamp(y[c], -ARPA_F32_MAX, ARPA_F32_MAX);
        }
    }
    return y;
}

// Point-in-footprint test: inside the ellipse and within the slab.
fn arpa_footprint_contains(fp: ArpaPackedFootprint, q: vec3<f32>) -> bool {
    let y = arpa_footprint_filter_coords(fp, q);
    return y.x * y.x + y.y * y.y <= 1.0 && abs(y.z) <= 1.0;
}

// true if a query with (geometric) normal query_normal sees the lit side.
fn arpa_footprint_faces(fp: ArpaPackedFootprint, query_normal: vec3<f32>) -> bool {
    return dot(fp.row_n, query_normal) > 0.0;
}

// Irradiance (W/m^2, RGB) of this footprint at q with normal query_normal: Phi W_p(q) when
// q is inside and on the lit side, else 0. `kernel` is an ARPA_KERNEL_* id (kernel.wgsl).
fn arpa_footprint_irradiance(fp: ArpaPackedFootprint, q: vec3<f32>, query_normal: vec3<f32>, kernel: u32) -> vec3<f32> {
    let y = arpa_footprint_filter_coords(fp, q);
    let r2 = y.x * y.x + y.y * y.y;
    if r2 <= 1.0 && abs(y.z) <= 1.0 && arpa_footprint_faces(fp, query_normal) {
        return vec3<f32>(fp.flux_density_r, fp.flux_density_g, fp.flux_density_b) * arpa_kernel_eval(kernel, r2);
    }
    return vec3<f32>(0.0);
}
