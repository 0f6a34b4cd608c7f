// WGSL twin of arpa_core::base::frame: right-handed orthonormal frames (t, b, n), t x b = n.
// Needs math.wgsl.
//
// Precision: f32; frames are orthonormal to a few eps32. from_normal_and_hint treats hints
// within sin ~ 1e-6 of the normal as parallel (the f64 core: 1e-12), since f32 cannot
// resolve the tangent direction of such a hint.

struct ArpaFrame {
    t: vec3<f32>,
    b: vec3<f32>,
    n: vec3<f32>,
}

// v/|v| with the largest component scaled out first, or `fallback` when v is zero or not
// finite.
fn arpa_frame_normalize_or(v: vec3<f32>, fallback: vec3<f32>) -> vec3<f32> {
    let a = abs(v);
    let m = max(a.x, max(a.y, a.z));
    let finite = arpa_finite3(v);
    if !(m > 0.0) || !finite {
        return fallback;
    }
    let w = v / m;
    return w / length(w);
}

// Branchless frame of Duff et al. (JCGT 2017) around n (normalised first; zero or
// non-finite n gives the frame around +z), Frame::from_normal.
fn arpa_frame_from_normal(n_in: vec3<f32>) -> ArpaFrame {
    let n = arpa_frame_normalize_or(n_in, vec3<f32>(0.0, 0.0, 1.0));
    let sign = select(-1.0, 1.0, n.z >= 0.0);
    let a = -1.0 / (sign + n.z);
    let b = n.x * n.y * a;
    let t = vec3<f32>(1.0 + sign * n.x * n.x * a, sign * b, -sign * n.x);
    let bt = vec3<f32>(b, sign + n.y * n.y * a, -n.y);
    return ArpaFrame(t, bt, n);
}

// A frame around n whose first tangent is the part of `hint` orthogonal to n
// (Frame::from_normal_and_hint); falls back to arpa_frame_from_normal for a hint that is
// (nearly) parallel to n, zero or not finite.
fn arpa_frame_from_normal_and_hint(n_in: vec3<f32>, hint_in: vec3<f32>) -> ArpaFrame {
    let n = arpa_frame_normalize_or(n_in, vec3<f32>(0.0, 0.0, 1.0));
    let ah = abs(hint_in);
    let m = max(ah.x, max(ah.y, ah.z));
    let finite = arpa_finite3(hint_in);
    if !(m > 0.0) || !finite {
        return arpa_frame_from_normal(n);
    }
    let hint = hint_in / m;
    let hint2 = dot(hint, hint);
    var t = hint - n * dot(n, hint);
    let len2 = dot(t, t);
    if !(len2 > 1e-12 * hint2) {
        return arpa_frame_from_normal(n);
    }
    t = t / sqrt(len2);
    if len2 < 0.25 * hint2 {
        t = t - n * dot(n, t);
        t = t / length(t);
    }
    return ArpaFrame(t, cross(n, t), n);
}

// Local (x, y, z) to world: x t + y b + z n.
fn arpa_frame_to_world(f: ArpaFrame, v: vec3<f32>) -> vec3<f32> {
    return f.t * v.x + f.b * v.y + f.n * v.z;
}

// World vector to local coordinates.
fn arpa_frame_to_local(f: ArpaFrame, v: vec3<f32>) -> vec3<f32> {
    return vec3<f32>(dot(v, f.t), dot(v, f.b), dot(v, f.n));
}
