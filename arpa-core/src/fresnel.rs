//! Fresnel reflectance of a smooth dielectric interface (unpolarised light).

/// Fraction of light reflected at a smooth interface, for the cosine `cos_i` between
/// the incident direction and the normal (either sign) and relative index `ior`
/// (inside over outside; `cos_i < 0` means arriving from outside). Returns 1 under total
/// internal reflection; always in `[0, 1]`.
#[inline]
pub fn dielectric_reflectance(cos_i: f64, ior: f64) -> f64 {
    if !(ior > 0.0) || !ior.is_finite() || !cos_i.is_finite() {
        return 1.0;
    }
    // η = n_incident / n_transmitted.
    let eta = if cos_i < 0.0 { 1.0 / ior } else { ior };
    let ci = cos_i.abs().min(1.0);
    let sin_t2 = eta * eta * (1.0 - ci * ci);
    if sin_t2 >= 1.0 {
        return 1.0;
    }
    let ct = libm::sqrt(1.0 - sin_t2);
    let rs = (eta * ci - ct) / (eta * ci + ct);
    let rp = (ci - eta * ct) / (ci + eta * ct);
    (0.5 * (rs * rs + rp * rp)).clamp(0.0, 1.0)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn known_values() {
        // Normal incidence: ((n − 1)/(n + 1))², both ways.
        let r0 = (0.5f64 / 2.5).powi(2);
        assert!((dielectric_reflectance(-1.0, 1.5) - r0).abs() < 1e-15);
        assert!((dielectric_reflectance(1.0, 1.5) - r0).abs() < 1e-15);
        // Brewster angle from outside: p-polarised part vanishes.
        let brewster = libm::atan(1.5);
        let r = dielectric_reflectance(-libm::cos(brewster), 1.5);
        let ct = libm::sqrt(1.0 - (libm::sin(brewster) / 1.5).powi(2));
        let rs = (libm::cos(brewster) / 1.5 - ct) / (libm::cos(brewster) / 1.5 + ct);
        assert!((r - 0.5 * rs * rs).abs() < 1e-12);
        // Beyond the critical angle inside glass: total reflection.
        assert_eq!(dielectric_reflectance(libm::cos(0.8), 1.5), 1.0);
        // Grazing: everything reflects.
        assert!(dielectric_reflectance(-1e-9, 1.5) > 0.999_999);
        assert_eq!(dielectric_reflectance(f64::NAN, 1.5), 1.0);
    }
}
