// WGSL twin of the scalar and vector built-ins the core takes from std, libm and glam, where
// a device's own may differ from them: the finiteness test (f64::is_finite), acos
// (libm::acos) to a few f32 ulps, the angle between two directions (accurate also near 0
// and pi), and glam's Vec3::normalize_or. Self-contained.
// (kernel.wgsl, footprint.wgsl, heuristics.wgsl and radius.wgsl do not use it: the store,
// gather and accumulate stages include them alone, so footprint.wgsl keeps its own
// arpa_is_finite/arpa_is_finite3 and radius.wgsl its inline exponent test.)
//
// Precision: arpa_acos agrees with the correctly rounded acos to ~1 ulp over [-1, 1] (the
// twin-math conformance case holds it to 4 eps32 relative); the device's built-in acos may
// be far less accurate (Vulkan allows thousands of ulps), hence this one.

// x is neither infinite nor NaN (f64::is_finite), by its exponent bits (no float compare, so
// no fast-math assumption can remove it).
fn arpa_finite(x: f32) -> bool {
    return (bitcast<u32>(x) & 0x7f800000u) != 0x7f800000u;
}

// Every component of v is finite.
fn arpa_finite3(v: vec3<f32>) -> bool {
    return all((bitcast<vec3<u32>>(v) & vec3<u32>(0x7f800000u)) != vec3<u32>(0x7f800000u));
}

// asin(x) for |x| <= 0.5 by its Taylor series to x^21 (truncation below 1.2e-9, under the
// f32 rounding), Horner in x^2: the coefficients are (2k)! / (4^k k!^2 (2k + 1)).
fn arpa_asin_small(x: f32) -> f32 {
    let z = x * x;
    var p = 0.008390335809616815;
    p = p * z + 0.009761609529194078;
    p = p * z + 0.011551800896139705;
    p = p * z + 0.01396484375;
    p = p * z + 0.017352764423076924;
    p = p * z + 0.022372159090909092;
    p = p * z + 0.030381944444444444;
    p = p * z + 0.044642857142857144;
    p = p * z + 0.075;
    p = p * z + 0.16666666666666666;
    return x + x * z * p;
}

// acos(x) (rad) for x in [-1, 1] (libm::acos; NaN gives NaN), to a few f32 ulps, by the
// half-angle reduction acos(x) = 2 asin(sqrt((1 - x) / 2)) outside |x| <= 0.5.
fn arpa_acos(x: f32) -> f32 {
    if x > 0.5 {
        return 2.0 * arpa_asin_small(sqrt(0.5 * (1.0 - x)));
    }
    if x < -0.5 {
        return 3.141592653589793 - 2.0 * arpa_asin_small(sqrt(0.5 * (1.0 + x)));
    }
    return 1.5707963267948966 - arpa_asin_small(x);
}

// The angle (rad, in [0, pi]) between the unit directions a and b, to a few f32 ulps at
// every angle (the core: libm::acos(a.b) in f64). acos of an f32 dot product would lose
// accuracy near 0 and pi (an ulp of a.b near 1 is 6e-8, an angle error of 6e-8 / theta), so
// the angle comes from the chord: 2 asin(|a - b| / 2) up to pi/3, pi - 2 asin(|a + b| / 2)
// from 2 pi/3, acos(a.b) between (|a.b| <= 1/2, well-conditioned). a and b need to be unit
// only to a few eps32: a length error delta moves the result by about delta.
fn arpa_angle_between(a: vec3<f32>, b: vec3<f32>) -> f32 {
    let h = 0.5 * length(a - b);
    if h <= 0.5 {
        return 2.0 * arpa_asin_small(h);
    }
    let g = 0.5 * length(a + b);
    if g <= 0.5 {
        return 3.141592653589793 - 2.0 * arpa_asin_small(g);
    }
    return arpa_acos(clamp(dot(a, b), -0.5, 0.5));
}

// glam's Vec3::normalize_or in f32: v times the reciprocal of |v|, or `fallback` when that
// reciprocal is zero or not finite (v zero, tiny, huge or not finite). The twin of the
// core's f32 normalisations (CameraFrame::direction); for f64 ones in the core, the f32
// result is within a few eps32 of the core's.
fn arpa_glam_normalize_or(v: vec3<f32>, fallback: vec3<f32>) -> vec3<f32> {
    let rcp = 1.0 / length(v);
    if arpa_finite(rcp) && rcp > 0.0 {
        return v * rcp;
    }
    return fallback;
}
