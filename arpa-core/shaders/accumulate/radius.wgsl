// WGSL twin of arpa_core::accumulate::radius::RadiusSchedule (Knaus & Zwicker 2011): the progressive
// radius of iteration i, r_i^2 = r_1^2 Gamma(i + alpha) / (Gamma(1 + alpha) Gamma(i + 1)),
// and the one-step recurrence r_{i+1} = r_i sqrt((i + alpha)/(i + 1)). Self-contained.
//
// WGSL has no lgamma, and the core's lgamma difference would cancel catastrophically in f32
// (lgamma(1e5) ~ 1e6). Instead: for i <= 16 the exact product
// prod_{k=1}^{i-1} (k + alpha)/(k + 1); beyond, that product at 16 times the ratio
// Gamma(i+alpha)Gamma(17) / (Gamma(i+1)Gamma(16+alpha)) from the asymptotic series of
// ln Gamma(z+a) - ln Gamma(z+b) (DLMF 5.11.13) with four Bernoulli-polynomial terms, whose
// truncation error at z >= 16 is below 1e-9. Relative error of the radius: a few f32 ulps
// times (1 + |alpha - 1| ln i), below 2e-6 for every u32 iteration.

// Smallest radius returned (metres), as in the core.
const ARPA_MIN_RADIUS: f32 = 1e-5;
const ARPA_RADIUS_SERIES_START: u32 = 16u;

fn arpa_radius_alpha(alpha: f32) -> f32 {
    if alpha > 0.0 {
        return min(alpha, 1.0);
    }
    return 2.0 / 3.0;
}

fn arpa_radius_initial(initial: f32) -> f32 {
    if initial > 0.0 && (bitcast<u32>(initial) & 0x7f800000u) != 0x7f800000u {
        return initial;
    }
    return ARPA_MIN_RADIUS;
}

fn arpa_radius_finite_or_min(r: f32) -> f32 {
    if (bitcast<u32>(r) & 0x7f800000u) != 0x7f800000u {
        return max(r, ARPA_MIN_RADIUS);
    }
    return ARPA_MIN_RADIUS;
}

// Sum_{n=1}^{4} (-1)^{n+1} (B_{n+1}(a) - B_{n+1}(1)) / (n (n+1) z^n): the series part of
// ln Gamma(z + a) - ln Gamma(z + 1) - (a - 1) ln z.
fn arpa_lgamma_ratio_series(a: f32, z: f32) -> f32 {
    let a2 = a * a;
    let a3 = a2 * a;
    let a4 = a3 * a;
    let a5 = a4 * a;
    let t1 = (a2 - a) / 2.0;                                      // (B2(a) - 1/6) / 2
    let t2 = -(a3 - 1.5 * a2 + 0.5 * a) / 6.0;                   // -(B3(a) - 0) / 6
    let t3 = (a4 - 2.0 * a3 + a2) / 12.0;                        // (B4(a) + 1/30) / 12
    let t4 = -(a5 - 2.5 * a4 + (5.0 / 3.0) * a3 - a / 6.0) / 20.0; // -(B5(a) - 0) / 20
    let w = 1.0 / z;
    return w * (t1 + w * (t2 + w * (t3 + w * t4)));
}

// Radius of iteration `iteration` (1-based; 0 is treated as 1) for first radius `initial`
// (metres) and alpha in (0, 1], clamped to ARPA_MIN_RADIUS and finite (RadiusSchedule::radius).
fn arpa_radius(initial: f32, alpha_in: f32, iteration: u32) -> f32 {
    let i = max(iteration, 1u);
    let alpha = arpa_radius_alpha(alpha_in);
    let r1 = arpa_radius_initial(initial);
    var ratio = 1.0; // r_i^2 / r_1^2 up to min(i, 16)
    let last = min(i, ARPA_RADIUS_SERIES_START);
    for (var k = 1u; k < last; k++) {
        ratio *= (f32(k) + alpha) / f32(k + 1u);
    }
    if i <= ARPA_RADIUS_SERIES_START {
        return arpa_radius_finite_or_min(r1 * sqrt(ratio));
    }
    let z0 = f32(ARPA_RADIUS_SERIES_START);
    let zi = f32(i);
    let log_ratio = (alpha - 1.0) * log(zi / z0)
        + arpa_lgamma_ratio_series(alpha, zi) - arpa_lgamma_ratio_series(alpha, z0);
    return arpa_radius_finite_or_min(r1 * sqrt(ratio) * exp(0.5 * log_ratio));
}

// The radius of iteration i + 1 from that of i (RadiusSchedule::next).
fn arpa_radius_next(radius: f32, alpha_in: f32, iteration: u32) -> f32 {
    let i = f32(max(iteration, 1u));
    let alpha = arpa_radius_alpha(alpha_in);
    return arpa_radius_finite_or_min(radius * sqrt((i + alpha) / (i + 1.0)));
}
