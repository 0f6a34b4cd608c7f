// WGSL twin of arpa_core::propagate::lambertian: the two-sided Lambertian frame with interpolated
// shading normals (Mitsuba 3's twosided + diffuse), for both directions of transport.
// Needs math.wgsl, frame.wgsl and sampling.wgsl before it.
//
// Precision: f32. Cosines and ratios agree with the core to a few eps32 (the adjoint ratio
// to a few eps32 / |w.n_g| relative); decisions at a threshold (direction in the shading
// plane, re-emission direction at the shading horizon) can differ within that rounding.

// Largest adjoint ratio |w.n_s| / |w.n_g| (lambertian::MAX_ADJOINT_RATIO).
const ARPA_MAX_ADJOINT_RATIO: f32 = 100.0;

// DiffuseShading: unit geometric normal on the side of the direction the frame was built
// for, and the unit shading normal flipped to that direction's side of the shading plane.
// valid = 0 stands for the core's None (direction in the shading plane, non-finite input):
// the diffuse lobe is zero for it.
struct ArpaDiffuseShading {
    geometric: vec3<f32>,
    valid: u32,
    shading: vec3<f32>,
    pad: u32,
}

// DiffuseShading::new(geometric, shading, toward): all unit vectors, world space.
fn arpa_diffuse_shading_new(geometric: vec3<f32>, shading: vec3<f32>, toward: vec3<f32>) -> ArpaDiffuseShading {
    let c = dot(toward, shading);
    if c == 0.0 || !arpa_finite(c) || !arpa_finite3(toward) || !arpa_finite3(shading)
        || !arpa_finite3(geometric) {
        return ArpaDiffuseShading(geometric, 0u, shading, 0u);
    }
    return ArpaDiffuseShading(geometric, 1u, select(-shading, shading, c > 0.0), 0u);
}

// DiffuseShading::below_shading_plane.
fn arpa_diffuse_below_shading_plane(s: ArpaDiffuseShading) -> bool {
    return dot(s.shading, s.geometric) < 0.0;
}

// DiffuseShading::cosine: (w.n_s)+ for the unit direction w, 0 behind the geometric face.
fn arpa_diffuse_cosine(s: ArpaDiffuseShading, w: vec3<f32>) -> f32 {
    let c = dot(w, s.shading);
    if c > 0.0 && dot(w, s.geometric) > 0.0 {
        return c;
    }
    return 0.0;
}

// DiffuseShading::adjoint_ratio: |w_in.n_s| / |w_in.n_g| in [0, ARPA_MAX_ADJOINT_RATIO]
// (0 where the core's quotient is NaN: 0/0 or a non-finite input).
fn arpa_diffuse_adjoint_ratio(s: ArpaDiffuseShading, w_in: vec3<f32>) -> f32 {
    let sn = abs(dot(w_in, s.shading));
    let g = abs(dot(w_in, s.geometric));
    if !arpa_finite(sn) || !arpa_finite(g) {
        // inf/finite = inf -> MAX; anything with NaN or inf/inf -> NaN -> 0.
        if arpa_finite(g) && sn == sn && !arpa_finite(sn) {
            return ARPA_MAX_ADJOINT_RATIO;
        }
        return 0.0;
    }
    if g == 0.0 {
        return select(0.0, ARPA_MAX_ADJOINT_RATIO, sn > 0.0);
    }
    return min(sn / g, ARPA_MAX_ADJOINT_RATIO);
}

// A re-emission direction (unit, world space); valid = 0: absorbed (below the shading plane).
struct ArpaReemissionDirection {
    direction: vec3<f32>,
    valid: u32,
}

// DiffuseShading::sample_reemission: cosine-distributed about the geometric normal from the
// unit-square sample u, absorbed where it falls below the shading plane.
fn arpa_diffuse_sample_reemission(s: ArpaDiffuseShading, u: vec2<f32>) -> ArpaReemissionDirection {
    let f = arpa_frame_from_normal(s.geometric);
    let d = arpa_frame_normalize_or(arpa_frame_to_world(f, arpa_cosine_hemisphere(u)), f.n);
    return ArpaReemissionDirection(d, select(0u, 1u, dot(d, s.shading) >= 0.0));
}
