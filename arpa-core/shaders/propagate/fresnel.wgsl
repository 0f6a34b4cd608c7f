// WGSL twin of arpa_core::propagate::fresnel::dielectric_reflectance: the fraction of unpolarised light
// a smooth dielectric interface reflects. Needs math.wgsl.
//
// Precision: f32 with the core's formula. For inputs given in f32 the reflectance agrees
// with the f64 core to an absolute error of about eps32 (1 + eta^2) / cos_t (eps32 = 1.2e-7,
// cos_t = sqrt(1 - sin_t^2)): a few eps32 at everyday angles, growing near the critical
// angle, where total internal reflection (exactly 1) may also be decided the other way
// within the f32 rounding of sin_t^2.

// Reflected fraction in [0, 1] for the cosine cos_i = d.n between the unit direction of
// travel and the normal (either sign; cos_i < 0 means arriving from outside, against an
// outward normal) and the relative index ior (inside over outside). 1 under total internal
// reflection and for a non-finite input or ior <= 0.
fn arpa_dielectric_reflectance(cos_i: f32, ior: f32) -> f32 {
    if !(ior > 0.0) || !arpa_finite(ior) || !arpa_finite(cos_i) {
        return 1.0;
    }
    // eta = n_incident / n_transmitted.
    let eta = select(ior, 1.0 / ior, cos_i < 0.0);
    let ci = min(abs(cos_i), 1.0);
    let sin_t2 = eta * eta * (1.0 - ci * ci);
    if sin_t2 >= 1.0 {
        return 1.0;
    }
    let ct = sqrt(1.0 - sin_t2);
    let rs = (eta * ci - ct) / (eta * ci + ct);
    let rp = (ci - eta * ct) / (ci + eta * ct);
    return clamp(0.5 * (rs * rs + rp * rp), 0.0, 1.0);
}
