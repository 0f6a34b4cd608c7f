// WGSL twin of arpa_core::propagate::reemission (Fabianowski 2011, ARPA eq. 2): absorb at a diffuse
// hit and re-emit from a virtual point emitter v behind it. Needs math.wgsl, frame.wgsl,
// sampling.wgsl and differential.wgsl.
//
// Precision: f32. The virtual distance sqrt(|D_u x D_v|)/l is formed from the scaled
// differentials (no overflow of the cross product for any normal-f32 input); results agree
// with the core to a few eps32 relative.

// A re-emitted ray and its status (ARPA_DIFF_*; ARPA_DIFF_NON_FINITE for a bad length or
// area, as the core's DifferentialError::NonFinite).
struct ArpaReemitted {
    ray: ArpaRayDiff,
    status: u32,
}

// Virtual distance v = sqrt(parallelogram_area) / reemission_length (metres), or a negative
// value when either input is not finite or out of range (virtual_distance's error).
fn arpa_virtual_distance(parallelogram_area: f32, reemission_length: f32) -> f32 {
    let ok = reemission_length > 0.0 && arpa_finite(reemission_length)
        && parallelogram_area >= 0.0 && arpa_finite(parallelogram_area);
    if !ok {
        return -1.0;
    }
    let v = sqrt(parallelogram_area) / reemission_length;
    if arpa_finite(v) {
        return v;
    }
    return -1.0;
}

// Re-emits a photon absorbed at `hit` with positional differentials dp_du, dp_dv in the unit
// `direction`, directional differentials of length `reemission_length` (rad) along a frame
// perpendicular to it and positional ones v times them (reemission::reemit).
fn arpa_reemit(hit: vec3<f32>, dp_du: vec3<f32>, dp_dv: vec3<f32>, direction: vec3<f32>, reemission_length: f32) -> ArpaReemitted {
    var out: ArpaReemitted;
    // sqrt(|a x b|) taken as sqrt(sa) sqrt(sb) sqrt(|a^ x b^|) so that nothing overflows.
    let sa = max(abs(dp_du.x), max(abs(dp_du.y), abs(dp_du.z)));
    let sb = max(abs(dp_dv.x), max(abs(dp_dv.y), abs(dp_dv.z)));
    var root_area = 0.0;
    if sa > 0.0 && sb > 0.0 {
        root_area = sqrt(sa) * sqrt(sb) * sqrt(length(cross(dp_du / sa, dp_dv / sb)));
    }
    let finite_in = arpa_finite3(dp_du) && arpa_finite3(dp_dv);
    let ok_len = reemission_length > 0.0 && arpa_finite(reemission_length);
    if !finite_in || !ok_len {
        out.status = ARPA_DIFF_NON_FINITE;
        return out;
    }
    let v = root_area / reemission_length;
    if !arpa_finite(v) {
        out.status = ARPA_DIFF_NON_FINITE;
        return out;
    }
    let f = arpa_frame_from_normal(direction);
    if !arpa_finite3(direction) || !(length(direction) > 0.0) {
        out.status = ARPA_DIFF_INVALID_DIRECTION;
        return out;
    }
    let du = f.t * reemission_length;
    let dv = f.b * reemission_length;
    let r = arpa_ray_new_checked(hit, direction, du * v, dv * v, du, dv);
    out.ray = r.ray;
    out.status = r.status;
    return out;
}

// RayDifferential::new (also in emission.wgsl as arpa_ray_new; repeated here under its own
// name so reemission.wgsl does not need emission.wgsl).
fn arpa_ray_new_checked(p: vec3<f32>, d: vec3<f32>, dp_du: vec3<f32>, dp_dv: vec3<f32>, dd_du: vec3<f32>, dd_dv: vec3<f32>) -> ArpaDiffResult {
    let dn = arpa_diff_normalize_or(d, vec3<f32>(0.0));
    let r = ArpaRayDiff(p, dn, dp_du, dp_dv, dd_du, dd_dv);
    if all(dn == vec3<f32>(0.0)) {
        return ArpaDiffResult(r, ARPA_DIFF_INVALID_DIRECTION, 0u);
    }
    return arpa_diff_checked(r, 0u);
}

// Cosine-distributed direction in the hemisphere of the unit `normal` from the sample u
// (reemission::diffuse_direction).
fn arpa_diffuse_direction(normal: vec3<f32>, u: vec2<f32>) -> vec3<f32> {
    let f = arpa_frame_from_normal(normal);
    return arpa_frame_normalize_or(arpa_frame_to_world(f, arpa_cosine_hemisphere(u)), f.n);
}
