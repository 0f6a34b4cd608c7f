// WGSL twin of arpa_core::propagate::normal_map: shading normals perturbed by a tangent-space
// normal map (Mitsuba 3's normalmap, glTF's normalTexture) or a bump map's height gradient
// (Mitsuba 3's bumpmap), and a triangle's texture-coordinate derivatives. Needs math.wgsl
// and frame.wgsl.
//
// Precision: f32 throughout; the perturbed normal agrees with the f64 core to a few eps32
// times the conditioning of the frame (1/|s| before normalisation, with s the part of
// dp/du perpendicular to n). A dp/du within sin ~ 1e-6 of n is taken as parallel (the f64
// core: 1e-12), since f32 cannot resolve its tangent direction.

// normal_map::first_tangent.
fn arpa_normal_first_tangent(n: vec3<f32>, dp_du: vec3<f32>) -> vec3<f32> {
    let s = dp_du - n * dot(n, dp_du);
    let a = abs(s);
    let m = max(a.x, max(a.y, a.z));
    let ad = abs(dp_du);
    let md = max(ad.x, max(ad.y, ad.z));
    if m > 1e-6 * md && arpa_finite3(s) {
        return arpa_frame_normalize_or(s, n);
    }
    return arpa_frame_from_normal(n).t;
}

// normal_map::orient: v normalised, on the side of `geometric` that n is on; n where v
// vanishes or is not finite.
fn arpa_normal_orient(v: vec3<f32>, n: vec3<f32>, geometric: vec3<f32>) -> vec3<f32> {
    let a = abs(v);
    let m = max(a.x, max(a.y, a.z));
    if !(m > 0.0) || !arpa_finite3(v) {
        return n;
    }
    let w = v / m;
    let u = w / length(w);
    if (dot(u, geometric) < 0.0) != (dot(n, geometric) < 0.0) {
        return -u;
    }
    return u;
}

// normal_map::normal_mapped: texel value c read as 2c - 1 in the frame (s, t, n), x and y
// scaled by `scale`; follow_uv: t turned to dp_dv's side (Handedness::FollowTextureCoordinates).
fn arpa_normal_mapped(n: vec3<f32>, geometric: vec3<f32>, dp_du: vec3<f32>, dp_dv: vec3<f32>, c: vec3<f32>, scale: f32, follow_uv: bool) -> vec3<f32> {
    let m = c * 2.0 - vec3<f32>(1.0);
    let s = arpa_normal_first_tangent(n, dp_du);
    var t = cross(n, s);
    if follow_uv && dot(t, dp_dv) < 0.0 {
        t = -t;
    }
    let v = s * (m.x * scale) + t * (m.y * scale) + n * m.z;
    return arpa_normal_orient(v, n, geometric);
}

// normal_map::bump_mapped: grad = (dh/du, dh/dv) of the height.
fn arpa_bump_mapped(n: vec3<f32>, geometric: vec3<f32>, dp_du: vec3<f32>, dp_dv: vec3<f32>, grad: vec2<f32>) -> vec3<f32> {
    let du = dp_du + n * (grad.x - dot(n, dp_du));
    let dv = dp_dv + n * (grad.y - dot(n, dp_dv));
    var v = cross(du, dv);
    if dot(v, n) < 0.0 {
        v = -v;
    }
    return arpa_normal_orient(v, n, geometric);
}

// normal_map::texture_derivatives: (dp/du, dp/dv) of the triangle p0 p1 p2 with texture
// coordinates uv0 uv1 uv2; ok = false where they are degenerate.
struct ArpaTextureDerivatives {
    dp_du: vec3<f32>,
    dp_dv: vec3<f32>,
    ok: bool,
}

fn arpa_texture_derivatives(p0: vec3<f32>, p1: vec3<f32>, p2: vec3<f32>, uv0: vec2<f32>, uv1: vec2<f32>, uv2: vec2<f32>) -> ArpaTextureDerivatives {
    let d1 = uv1 - uv0;
    let d2 = uv2 - uv0;
    let e1 = p1 - p0;
    let e2 = p2 - p0;
    let det = d1.x * d2.y - d1.y * d2.x;
    var out: ArpaTextureDerivatives;
    out.ok = false;
    if !(det != 0.0) || !arpa_finite(det) {
        return out;
    }
    out.dp_du = (e1 * d2.y - e2 * d1.y) / det;
    out.dp_dv = (e2 * d1.x - e1 * d2.x) / det;
    out.ok = arpa_finite3(out.dp_du) && arpa_finite3(out.dp_dv);
    return out;
}
