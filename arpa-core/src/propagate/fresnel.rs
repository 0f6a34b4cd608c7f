//! Fresnel reflectance of smooth dielectric and conductor interfaces (unpolarised light),
//! and the cosine-weighted hemispherical average (albedo) of a conductor's reflectance.

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

/// Fraction of unpolarised light reflected by a smooth conductor with complex index
/// `eta + i k` (relative to the outside medium) for incidence cosine `cos_i` (either
/// sign; only `|cos_i|` matters). Exact Fresnel equations (the real-valued form of
/// pbrt's `FrConductor`); always in `[0, 1]`. With `k = 0` it equals
/// [`dielectric_reflectance`] from outside.
pub fn conductor_reflectance(cos_i: f64, eta: f64, k: f64) -> f64 {
    if !(cos_i.is_finite() && eta.is_finite() && k.is_finite()) || eta < 0.0 || k < 0.0 {
        return 1.0;
    }
    let c = cos_i.abs().min(1.0);
    let c2 = c * c;
    let s2 = 1.0 - c2;
    let (eta2, k2) = (eta * eta, k * k);
    let t0 = eta2 - k2 - s2;
    let a2_plus_b2 = libm::sqrt(t0 * t0 + 4.0 * eta2 * k2);
    let a = libm::sqrt((0.5 * (a2_plus_b2 + t0)).max(0.0));
    let t1 = a2_plus_b2 + c2;
    let t2 = 2.0 * c * a;
    let rs = if t1 + t2 > 0.0 { (t1 - t2) / (t1 + t2) } else { 1.0 };
    let t3 = c2 * a2_plus_b2 + s2 * s2;
    let t4 = t2 * s2;
    let rp = if t3 + t4 > 0.0 { rs * (t3 - t4) / (t3 + t4) } else { 1.0 };
    (0.5 * (rs + rp)).clamp(0.0, 1.0)
}

/// Number of Simpson intervals of [`conductor_albedo`] (error below 1e-9 for the
/// conductors and dielectrics tested).
const ALBEDO_INTERVALS: u32 = 512;

/// Cosine-weighted hemispherical average of [`conductor_reflectance`],
/// `2 ∫₀¹ F(μ) μ dμ`: the fraction of uniform (diffuse) incident light a smooth conductor
/// reflects. It is the single reflectance that conserves the reflected energy when the
/// conductor is rendered with a direction-independent reflectance (as a perfect mirror
/// or, above the roughness cut-off, as a diffuse surface). Composite Simpson rule.
pub fn conductor_albedo(eta: f64, k: f64) -> f64 {
    let n = ALBEDO_INTERVALS;
    let h = 1.0 / n as f64;
    let f = |mu: f64| 2.0 * mu * conductor_reflectance(mu, eta, k);
    let mut sum = f(0.0) + f(1.0);
    for i in 1..n {
        sum += f(i as f64 * h) * if i % 2 == 1 { 4.0 } else { 2.0 };
    }
    (sum * h / 3.0).clamp(0.0, 1.0)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Closed form of the hemispherical (cosine-weighted) reflectance of a dielectric of
    /// index `n > 1` seen from outside (Stern 1964; e.g. d'Eon & Irving 2011, eq. 26).
    fn dielectric_albedo_closed_form(n: f64) -> f64 {
        let (n2, n4) = (n * n, n * n * n * n);
        0.5 + (n - 1.0) * (3.0 * n + 1.0) / (6.0 * (n + 1.0) * (n + 1.0))
            + n2 * (n2 - 1.0) * (n2 - 1.0) / ((n2 + 1.0) * (n2 + 1.0) * (n2 + 1.0)) * libm::log((n - 1.0) / (n + 1.0))
            - 2.0 * n * n2 * (n2 + 2.0 * n - 1.0) / ((n2 + 1.0) * (n4 - 1.0))
            + 8.0 * n4 * (n4 + 1.0) / ((n2 + 1.0) * (n4 - 1.0) * (n4 - 1.0)) * libm::log(n)
    }

    #[test]
    fn conductor_reduces_to_dielectric_without_absorption() {
        for n in [1.1, 1.25, 1.5, 1.8, 2.4] {
            for i in 0..=200 {
                let c = i as f64 / 200.0;
                let a = conductor_reflectance(c, n, 0.0);
                let b = dielectric_reflectance(-c, n);
                assert!((a - b).abs() < 1e-12, "n {n} cos {c}: conductor {a} dielectric {b}");
            }
        }
    }

    #[test]
    fn conductor_normal_incidence_and_grazing() {
        // Veach-bidir's lamp (copper-like), per channel.
        for (eta, k) in [(2.865601, 3.032326), (2.119182, 2.056108), (1.940077, 1.616293), (0.2, 3.9)] {
            let f0 = ((eta - 1.0) * (eta - 1.0) + k * k) / ((eta + 1.0) * (eta + 1.0) + k * k);
            assert!((conductor_reflectance(1.0, eta, k) - f0).abs() < 1e-12);
            assert!((conductor_reflectance(-1.0, eta, k) - f0).abs() < 1e-12);
            assert!(conductor_reflectance(1e-9, eta, k) > 0.999_999);
            // The albedo is not simply above F0: the p-polarised dip before grazing can
            // outweigh the rise at grazing (it does for the lamp's red channel).
            let a = conductor_albedo(eta, k);
            assert!(a > 0.0 && a < 1.0, "albedo {a} vs F0 {f0}");
        }
        assert_eq!(conductor_reflectance(f64::NAN, 1.0, 1.0), 1.0);
    }

    #[test]
    fn albedo_matches_the_closed_form_of_a_dielectric() {
        for n in [1.25, 1.5, 2.0, 3.0] {
            let a = conductor_albedo(n, 0.0);
            let e = dielectric_albedo_closed_form(n);
            assert!((a - e).abs() < 1e-7, "n {n}: Simpson {a} closed form {e}");
        }
        // The textbook value for glass: about 9.2 % of diffuse light is reflected.
        assert!((conductor_albedo(1.5, 0.0) - 0.0918).abs() < 1e-4);
    }

    #[test]
    fn albedo_matches_monte_carlo_over_the_hemisphere() {
        // Independent estimate: cosine-weighted directions (μ = sqrt(u)) with a stratified u.
        let (eta, k) = (2.865601, 3.032326);
        let n = 100_000;
        let mc: f64 = (0..n).map(|i| conductor_reflectance(libm::sqrt((i as f64 + 0.5) / n as f64), eta, k)).sum::<f64>() / n as f64;
        assert!((conductor_albedo(eta, k) - mc).abs() < 1e-6);
    }

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
