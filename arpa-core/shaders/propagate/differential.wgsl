// WGSL twin of arpa_core::propagate::differential (Igehy 1999 ray differentials, ARPA eq. 1): transfer
// to a surface, specular reflection and refraction (with total internal reflection) of a
// ray and its derivatives with respect to the two emission parameters u and v.
// Same conventions as the Rust module: d is the unit direction of travel, normals may point
// either way, `ior` is n_inside / n_outside with an outward normal. Needs math.wgsl.
//
// Precision: the core propagates in f64, this twin in f32. For inputs given in f32, the
// results agree to a norm-wise relative error of about c eps32 kappa (eps32 = 1.19e-7), with
// kappa the condition of the step: 1/|D.N| for the transfer (it divides by the cosine), and
// 1/k for refraction (k = 1 - eta^2 (1 - cos_i^2), dT grows like 1/sqrt(k)); the error of an
// output is relative to the magnitude of the terms it is summed from (|dP| + t|dD| for the
// transfer), not to the output itself, which may cancel. Magnitudes: everything stays finite
// for |P|, |dP|, |dD|, t up to ~1e18 and products of two of them below f32::MAX; the f64
// core reaches 1e30. Classifications at the thresholds (grazing, TIR when k is within
// ~1e-6 of 0, near-critical) can differ from the f64 core by the f32 rounding of D.N and k.

// Status labels (DifferentialError), 0 = success.
const ARPA_DIFF_OK: u32 = 0u;
const ARPA_DIFF_INVALID_DIRECTION: u32 = 1u;
const ARPA_DIFF_INVALID_NORMAL: u32 = 2u;
const ARPA_DIFF_INVALID_DISTANCE: u32 = 3u;
const ARPA_DIFF_GRAZING: u32 = 4u;
const ARPA_DIFF_NEAR_CRITICAL_ANGLE: u32 = 5u;
const ARPA_DIFF_NON_FINITE: u32 = 6u;
// RefractionEvent.
const ARPA_REFRACTION_TRANSMITTED: u32 = 0u;
const ARPA_REFRACTION_TIR: u32 = 1u;

// Smallest |D.N| the transfer divides by (MIN_ABS_COS).
const ARPA_MIN_ABS_COS: f32 = 1e-12;
// Smallest k for which refraction differentials are computed (MIN_REFRACTION_K).
const ARPA_MIN_REFRACTION_K: f32 = 1e-12;

// A ray with differentials (RayDifferential); world space, metres.
struct ArpaRayDiff {
    p: vec3<f32>,       // position
    d: vec3<f32>,       // unit direction of travel
    dp_du: vec3<f32>,   // dP/du (m per unit u)
    dp_dv: vec3<f32>,
    dd_du: vec3<f32>,   // dD/du (per unit u, orthogonal to d)
    dd_dv: vec3<f32>,
}

// A normal with its derivatives (NormalDifferential); either orientation.
struct ArpaNormalDiff {
    n: vec3<f32>,
    dn_du: vec3<f32>,
    dn_dv: vec3<f32>,
}

// A propagated ray, its status (ARPA_DIFF_*) and, for refraction, the event
// (ARPA_REFRACTION_*). `ray` is meaningful only when status == ARPA_DIFF_OK.
struct ArpaDiffResult {
    ray: ArpaRayDiff,
    status: u32,
    event: u32,
}

fn arpa_diff_ray_finite(r: ArpaRayDiff) -> bool {
    return arpa_finite3(r.p) && arpa_finite3(r.d) && arpa_finite3(r.dp_du)
        && arpa_finite3(r.dp_dv) && arpa_finite3(r.dd_du) && arpa_finite3(r.dd_dv);
}

// |v| computed on v scaled by its largest component (no overflow of the squares).
fn arpa_diff_length(v: vec3<f32>) -> f32 {
    let a = abs(v);
    let m = max(a.x, max(a.y, a.z));
    if !(m > 0.0) || !arpa_finite(m) {
        return m;
    }
    return m * length(v / m);
}

// v/|v|, or `fallback` when |v| is zero or not finite (glam normalize_or).
fn arpa_diff_normalize_or(v: vec3<f32>, fallback: vec3<f32>) -> vec3<f32> {
    let l = arpa_diff_length(v);
    if l > 0.0 && arpa_finite(l) && arpa_finite3(v) {
        return v / l;
    }
    return fallback;
}

fn arpa_diff_result(ray: ArpaRayDiff, status: u32, event: u32) -> ArpaDiffResult {
    return ArpaDiffResult(ray, status, event);
}

fn arpa_diff_checked(ray: ArpaRayDiff, event: u32) -> ArpaDiffResult {
    if arpa_diff_ray_finite(ray) {
        return ArpaDiffResult(ray, ARPA_DIFF_OK, event);
    }
    return ArpaDiffResult(ray, ARPA_DIFF_NON_FINITE, event);
}

// Mirror direction R = D - 2 (D.N) N.
fn arpa_reflect_direction(d: vec3<f32>, n: vec3<f32>) -> vec3<f32> {
    return d - 2.0 * dot(d, n) * n;
}

// A refracted direction (refract_direction): the unit direction, the event
// (ARPA_REFRACTION_*; under total internal reflection `dir` is the mirror direction) and
// eta = n_incident / n_transmitted (1 where the interface is meaningless).
struct ArpaRefracted {
    dir: vec3<f32>,
    event: u32,
    eta: f32,
}

// Refraction of the unit direction d at normal n (either orientation, unit) for relative
// index `ior` (inside over outside, with n outward): entering uses eta = 1/ior, leaving
// eta = ior; T = eta D - (eta cos_i + sqrt(k)) N with cos_i = D.N against the incident side,
// k = 1 - eta^2 (1 - cos_i^2); k < 0 is total internal reflection (the mirror direction).
// An ior <= 0 or non-finite passes straight through (d, transmitted, eta 1).
fn arpa_refract_direction(d: vec3<f32>, n_in: vec3<f32>, ior: f32) -> ArpaRefracted {
    var n = n_in;
    var eta = 1.0 / ior;
    if dot(d, n_in) > 0.0 {
        n = -n_in;
        eta = ior;
    }
    if !(eta > 0.0) || !arpa_finite(eta) {
        return ArpaRefracted(d, ARPA_REFRACTION_TRANSMITTED, 1.0);
    }
    let cos_i = dot(d, n);
    let k = 1.0 - eta * eta * (1.0 - cos_i * cos_i);
    if k < 0.0 {
        return ArpaRefracted(arpa_reflect_direction(d, n), ARPA_REFRACTION_TIR, eta);
    }
    let mu = eta * cos_i + sqrt(k);
    return ArpaRefracted(arpa_glam_normalize_or(eta * d - mu * n, d), ARPA_REFRACTION_TRANSMITTED, eta);
}

// Removes the component of dD along D (RayDifferential::reprojected).
fn arpa_diff_reprojected(r: ArpaRayDiff) -> ArpaRayDiff {
    var o = r;
    o.dd_du = r.dd_du - r.d * dot(r.d, r.dd_du);
    o.dd_dv = r.dd_dv - r.d * dot(r.d, r.dd_dv);
    return o;
}

// Unit normal with derivatives of the unit normal; status ARPA_DIFF_INVALID_NORMAL on a
// zero or non-finite input (NormalDifferential::validated).
struct ArpaNormalValidated {
    nd: ArpaNormalDiff,
    ok: bool,
}

fn arpa_normal_validated(nd: ArpaNormalDiff) -> ArpaNormalValidated {
    var out: ArpaNormalValidated;
    out.ok = false;
    if !arpa_finite3(nd.n) || !arpa_finite3(nd.dn_du) || !arpa_finite3(nd.dn_dv) {
        return out;
    }
    let len = arpa_diff_length(nd.n);
    if !(len > 0.0) || !arpa_finite(len) {
        return out;
    }
    let n = nd.n / len;
    out.nd = ArpaNormalDiff(n, (nd.dn_du - n * dot(n, nd.dn_du)) / len, (nd.dn_dv - n * dot(n, nd.dn_dv)) / len);
    out.ok = true;
    return out;
}

fn arpa_diff_transfer_step(dp: vec3<f32>, dd: vec3<f32>, t: f32, n: vec3<f32>, d: vec3<f32>, cos_dn: f32) -> vec3<f32> {
    let offset = dp + t * dd;
    let dt = -dot(offset, n) / cos_dn;
    let moved = offset + dt * d;
    return moved - n * dot(moved, n);
}

// Transfer over distance t (metres) to a surface with normal n (either orientation, need
// not be unit): dt = -[(dP + t dD).N]/(D.N), dP' = dP + t dD + dt D, dD' = dD.
fn arpa_diff_transfer(r: ArpaRayDiff, t: f32, n_in: vec3<f32>) -> ArpaDiffResult {
    if !(t >= 0.0) || !arpa_finite(t) {
        return arpa_diff_result(r, ARPA_DIFF_INVALID_DISTANCE, 0u);
    }
    let n = arpa_diff_normalize_or(n_in, vec3<f32>(0.0));
    if all(n == vec3<f32>(0.0)) {
        return arpa_diff_result(r, ARPA_DIFF_INVALID_NORMAL, 0u);
    }
    let cos_dn = dot(r.d, n);
    if !(abs(cos_dn) >= ARPA_MIN_ABS_COS) {
        return arpa_diff_result(r, ARPA_DIFF_GRAZING, 0u);
    }
    let out = ArpaRayDiff(
        r.p + t * r.d,
        r.d,
        arpa_diff_transfer_step(r.dp_du, r.dd_du, t, n, r.d, cos_dn),
        arpa_diff_transfer_step(r.dp_dv, r.dd_dv, t, n, r.d, cos_dn),
        r.dd_du,
        r.dd_dv);
    return arpa_diff_checked(out, 0u);
}

fn arpa_diff_reflect_dd(r: ArpaRayDiff, n: vec3<f32>, dd: vec3<f32>, dnx: vec3<f32>) -> vec3<f32> {
    let dn = dot(r.d, n);
    let d_dn = dot(dd, n) + dot(r.d, dnx);
    return dd - 2.0 * (dn * dnx + d_dn * n);
}

fn arpa_diff_reflect_unchecked(r: ArpaRayDiff, nd: ArpaNormalDiff, event: u32) -> ArpaDiffResult {
    let out = ArpaRayDiff(
        r.p,
        arpa_diff_normalize_or(arpa_reflect_direction(r.d, nd.n), r.d),
        r.dp_du,
        r.dp_dv,
        arpa_diff_reflect_dd(r, nd.n, r.dd_du, nd.dn_du),
        arpa_diff_reflect_dd(r, nd.n, r.dd_dv, nd.dn_dv));
    var res = arpa_diff_checked(out, event);
    if res.status == ARPA_DIFF_OK {
        res.ray = arpa_diff_reprojected(res.ray);
    }
    return res;
}

// Specular reflection about the shading normal (with derivatives):
// d(D.N) = dD.N + D.dN, dR = dD - 2[(D.N) dN + d(D.N) N]; invariant under N -> -N.
fn arpa_diff_reflect(r: ArpaRayDiff, normal: ArpaNormalDiff) -> ArpaDiffResult {
    let v = arpa_normal_validated(normal);
    if !v.ok {
        return arpa_diff_result(r, ARPA_DIFF_INVALID_NORMAL, 0u);
    }
    return arpa_diff_reflect_unchecked(r, v.nd, 0u);
}

// Specular refraction through the shading normal for relative index `ior` (entering uses
// eta = 1/ior, leaving eta = ior); total internal reflection falls back to reflection and
// sets event = ARPA_REFRACTION_TIR.
fn arpa_diff_refract(r: ArpaRayDiff, normal: ArpaNormalDiff, ior: f32) -> ArpaDiffResult {
    let v = arpa_normal_validated(normal);
    if !v.ok {
        return arpa_diff_result(r, ARPA_DIFF_INVALID_NORMAL, 0u);
    }
    if !(ior > 0.0) || !arpa_finite(ior) {
        return arpa_diff_result(r, ARPA_DIFF_NON_FINITE, 0u);
    }
    var nd = v.nd;
    var eta = 1.0 / ior;
    if dot(r.d, nd.n) > 0.0 {
        nd = ArpaNormalDiff(-nd.n, -nd.dn_du, -nd.dn_dv);
        eta = ior;
    }
    let n = nd.n;
    let cos_i = dot(r.d, n);
    let k = 1.0 - eta * eta * (1.0 - cos_i * cos_i);
    if k < 0.0 {
        return arpa_diff_reflect_unchecked(r, nd, ARPA_REFRACTION_TIR);
    }
    if k < ARPA_MIN_REFRACTION_K {
        return arpa_diff_result(r, ARPA_DIFF_NEAR_CRITICAL_ANGLE, ARPA_REFRACTION_TRANSMITTED);
    }
    let cos_t = -sqrt(k);
    let mu = eta * cos_i - cos_t;
    let dmu_factor = eta - eta * eta * cos_i / cos_t;
    let d_dn_u = dot(r.dd_du, n) + dot(r.d, nd.dn_du);
    let d_dn_v = dot(r.dd_dv, n) + dot(r.d, nd.dn_dv);
    let out = ArpaRayDiff(
        r.p,
        arpa_diff_normalize_or(eta * r.d - mu * n, r.d),
        r.dp_du,
        r.dp_dv,
        eta * r.dd_du - (mu * nd.dn_du + dmu_factor * d_dn_u * n),
        eta * r.dd_dv - (mu * nd.dn_dv + dmu_factor * d_dn_v * n));
    var res = arpa_diff_checked(out, ARPA_REFRACTION_TRANSMITTED);
    if res.status == ARPA_DIFF_OK {
        res.ray = arpa_diff_reprojected(res.ray);
    }
    return res;
}
