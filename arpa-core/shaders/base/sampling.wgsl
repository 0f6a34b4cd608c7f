// WGSL twin of arpa_core::base::sampling: warps of unit-square samples (clamped into [0, 1], NaN
// to 0) to the distributions emission and scattering need, in the local frame (axis +z).
// Self-contained.
//
// Precision: f32, written so that nothing cancels: 1 - z^2 is formed as (1 - z)(1 + z)
// from the sample itself, the cone takes 1 - cos(theta_max) precomputed on the host (f32
// cannot form it for narrow cones), and the Fibonacci lattice takes the fractional part of
// i * phi in 64-bit fixed point (an f32 product would keep no fractional bits for
// i >= 2^24); it is exact where the core's f64 product i * phi rounds (by up to 2.4e-7 at
// i ~ 2^32). Results agree with the f64 core to a few eps32 absolute.

const ARPA_TAU: f32 = 6.283185307179586;
const ARPA_FRAC_PI_4: f32 = 0.7853981633974483;
const ARPA_FRAC_PI_2: f32 = 1.5707963267948966;

fn arpa_unit(x: f32) -> f32 {
    if x >= 0.0 {
        return min(x, 1.0);
    }
    return 0.0;
}

// Uniform direction on the unit sphere (z uniform in [-1, 1]); density 1/(4 pi).
fn arpa_uniform_sphere(u: vec2<f32>) -> vec3<f32> {
    let ux = arpa_unit(u.x);
    let z = 1.0 - 2.0 * ux;
    let r = sqrt(max(4.0 * ux * (1.0 - ux), 0.0));
    let phi = ARPA_TAU * arpa_unit(u.y);
    return vec3<f32>(r * cos(phi), r * sin(phi), z);
}

// Uniform direction in the cone around +z with 1 - cos(half-angle) = one_minus_cos_max
// (clamped to [0, 2]); density 1/(2 pi one_minus_cos_max).
fn arpa_uniform_cone(u: vec2<f32>, one_minus_cos_max: f32) -> vec3<f32> {
    let w = clamp(one_minus_cos_max, 0.0, 2.0);
    let a = arpa_unit(u.x) * w; // 1 - z
    let z = 1.0 - a;
    let r = sqrt(max(a * (2.0 - a), 0.0));
    let phi = ARPA_TAU * arpa_unit(u.y);
    return vec3<f32>(r * cos(phi), r * sin(phi), z);
}

// Concentric map in polar form: (r, theta) with r in [-1, 1] taken from the sample itself,
// so 1 - r^2 can be formed without cancellation.
fn arpa_concentric_polar(u: vec2<f32>) -> vec2<f32> {
    let a = 2.0 * arpa_unit(u.x) - 1.0;
    let b = 2.0 * arpa_unit(u.y) - 1.0;
    if a == 0.0 && b == 0.0 {
        return vec2<f32>(0.0);
    }
    if a * a > b * b {
        return vec2<f32>(a, ARPA_FRAC_PI_4 * (b / a));
    }
    return vec2<f32>(b, ARPA_FRAC_PI_2 - ARPA_FRAC_PI_4 * (a / b));
}

// Uniform point on the unit disc (Shirley-Chiu concentric map).
fn arpa_uniform_disc(u: vec2<f32>) -> vec2<f32> {
    let p = arpa_concentric_polar(u);
    return vec2<f32>(p.x * cos(p.y), p.x * sin(p.y));
}

// Cosine-weighted direction around +z (Malley's method); density cos(theta)/pi.
fn arpa_cosine_hemisphere(u: vec2<f32>) -> vec3<f32> {
    let p = arpa_concentric_polar(u);
    let r = abs(p.x);
    return vec3<f32>(p.x * cos(p.y), p.x * sin(p.y), sqrt(max((1.0 - r) * (1.0 + r), 0.0)));
}

// Uniform point on a triangle as barycentric weights (b0, b1, b2); density 1/area.
fn arpa_uniform_triangle(u: vec2<f32>) -> vec3<f32> {
    let s = sqrt(arpa_unit(u.x));
    let b1 = arpa_unit(u.y) * s;
    return vec3<f32>(1.0 - s, b1, s - b1);
}

// High 32 bits of the 64-bit product a * b.
fn arpa_mul_hi_u32(a: u32, b: u32) -> u32 {
    let a_lo = a & 0xffffu;
    let a_hi = a >> 16u;
    let b_lo = b & 0xffffu;
    let b_hi = b >> 16u;
    let ll = a_lo * b_lo;
    let lh = a_lo * b_hi;
    let hl = a_hi * b_lo;
    let hh = a_hi * b_hi;
    let mid = (ll >> 16u) + (lh & 0xffffu) + (hl & 0xffffu);
    return hh + (lh >> 16u) + (hl >> 16u) + (mid >> 16u);
}

// Fractional part of i * GOLDEN_RATIO_CONJUGATE as a 32-bit fixed-point fraction: i times
// the core's f64 constant 0.6180339887498949, which is exactly 0x9E3779B97F4A8000 / 2^64,
// modulo 2^64, top word. Exact up to the final truncation to 32 bits.
fn arpa_golden_fraction_bits(i: u32) -> u32 {
    let hi = 0x9E3779B9u;
    let lo = 0x7F4A8000u;
    return i * hi + arpa_mul_hi_u32(i, lo);
}

// Point i of the n-point Fibonacci lattice shifted by `shift` (Cranley-Patterson);
// n = 0 is treated as 1 (sampling::fibonacci_lattice).
fn arpa_fibonacci_lattice(i: u32, n: u32, shift: vec2<f32>) -> vec2<f32> {
    let nf = f32(max(n, 1u));
    let x = (f32(i) + 0.5) / nf + arpa_unit(shift.x);
    // 24 bits of the fraction, exactly representable.
    let g = f32(arpa_golden_fraction_bits(i) >> 8u) * (1.0 / 16777216.0);
    let y = g + arpa_unit(shift.y);
    return vec2<f32>(x - floor(x), y - floor(y));
}

// sampling::cell_point: the point `local` of the unit square placed in cell `cell`
// (ix + iy * grid) of a grid x grid grid over the unit square.
fn arpa_cell_point(local: vec2<f32>, cell: u32, grid: u32) -> vec2<f32> {
    let g = max(grid, 1u);
    let ix = f32(cell % g);
    let iy = f32(cell / g);
    return vec2<f32>((ix + arpa_unit(local.x)) / f32(g), (iy + arpa_unit(local.y)) / f32(g));
}

// sampling::round_robin: photon i of n over m <= 256^2 cells from `offset`: (slot, j, n_j);
// with n < m the evenly spaced slots (i m + s) / n (i m + s < n m <= 2^32: no overflow).
fn arpa_round_robin(i: u32, n: u32, m_in: u32, offset: u32) -> vec3<u32> {
    let m = max(m_in, 1u);
    if n < m {
        let s = arpa_mul_hi_u32(offset, m);
        return vec3<u32>(min((i * m + s) / max(n, 1u), m - 1u), 0u, 1u);
    }
    let r = i % m;
    let j = i / m;
    var count = n / m;
    if r < n % m {
        count += 1u;
    }
    let start = arpa_mul_hi_u32(offset, m);
    return vec3<u32>((r + start) % m, j, max(count, 1u));
}

// sampling::round_robin_weight: (n/m)/n_j when every cell has a photon (n >= m), else 1.
fn arpa_round_robin_weight(n: u32, m: u32, n_j: u32) -> f32 {
    if n >= m && n_j > 0u {
        return (f32(n) / f32(max(m, 1u))) / f32(n_j);
    }
    return 1.0;
}

// sampling::split_draw: slot floor(word m / 2^32) and the fraction within (24 bits).
fn arpa_split_draw_slot(word: u32, m: u32) -> u32 {
    return arpa_mul_hi_u32(word, max(m, 1u));
}

fn arpa_split_draw_fraction(word: u32, m: u32) -> f32 {
    return f32((word * max(m, 1u)) >> 8u) * (1.0 / 16777216.0);
}
