//! Warping of uniform unit-square samples to the distributions photon emission and
//! scattering need. Every function takes a point `u` of the unit square (values outside
//! `[0, 1]` or NaN are clamped into it) and returns a finite result. Directions are in the
//! local frame of the distribution (axis = +z) unless stated otherwise.

use core::f64::consts::{FRAC_PI_4, PI, TAU};
use glam::{DVec2, DVec3};

/// Clamps to `[0, 1]`, mapping NaN to 0.
#[inline]
fn unit(x: f64) -> f64 {
    if x >= 0.0 { if x <= 1.0 { x } else { 1.0 } } else { 0.0 }
}

/// The point `local` of the unit square placed in cell `cell` (`ix + iy · grid`) of a
/// `grid` × `grid` grid over the unit square: `((ix, iy) + local) / grid`. With an
/// equal-area map behind it, sampling a list of cells this way samples their union
/// uniformly (the projection maps, [`crate::render::projection`]).
#[inline]
pub fn cell_point(local: DVec2, cell: u32, grid: u32) -> DVec2 {
    let g = grid.max(1);
    let (ix, iy) = ((cell % g) as f64, (cell / g) as f64);
    DVec2::new((ix + unit(local.x)) / g as f64, (iy + unit(local.y)) / g as f64)
}

/// Largest projection grid (cells per side): `m ≤ 256²` cells keep [`round_robin`]'s
/// products within `u32` on the device.
pub const MAX_CELL_GRID: u32 = 256;

/// Photon `i` of `n` shared over `m` cells (at most `256²`), from an offset `offset` (a
/// uniform `u32`, `s = ⌊offset · m / 2³²⌋`): `(slot, j, n_j)`, the photon's slot in the cell
/// list, its index among that cell's photons and their number. With `n ≥ m`, round robin
/// from slot `s` (`⌊n/m⌋` or one more photons each, [`round_robin_weight`]); with `n < m`,
/// the evenly spaced slots `⌊(i m + s) / n⌋`, one photon each, so that every cell is
/// taken with probability `n/m` and the taken ones spread over the list. All integer, so
/// the core and the shaders agree exactly; `offset` is drawn anew each iteration.
#[inline]
pub fn round_robin(i: u32, n: u32, m: u32, offset: u32) -> (u32, u32, u32) {
    let m = m.max(1);
    let start = ((offset as u64 * m as u64) >> 32) as u32;
    if n < m {
        let slot = ((i as u64 * m as u64 + start as u64) / n.max(1) as u64) as u32;
        return (slot.min(m - 1), 0, 1);
    }
    let (r, j) = (i % m, i / m);
    let count = n / m + u32::from(r < n % m);
    ((r + start) % m, j, count.max(1))
}

/// The flux weight of a photon of a cell that holds `n_j` of the `n` photons shared round
/// robin over `m` cells ([`round_robin`]): `(n/m) / n_j` when every cell has a photon
/// (`n ≥ m`), so that each cell carries exactly its share of the power whether it got
/// `⌊n/m⌋` or one more photon (stratified: without it, the cells that get the extra
/// photon, a contiguous run of the list, would be brighter by up to `1/⌊n/m⌋` each
/// iteration); 1 when `n < m` (then the random start of the round robin alone keeps the
/// estimate unbiased).
#[inline]
pub fn round_robin_weight(n: u32, m: u32, n_j: u32) -> f64 {
    if n >= m && n_j > 0 { (n as f64 / m.max(1) as f64) / n_j as f64 } else { 1.0 }
}

/// A uniform `u32` draw split into a uniform slot among `m` and a uniform fraction within
/// it: `(⌊word · m / 2³²⌋, frac(word · m / 2³²))`, exact in integers (the shaders take the
/// fraction to 24 bits).
#[inline]
pub fn split_draw(word: u32, m: u32) -> (u32, f64) {
    let x = word as u64 * m.max(1) as u64;
    ((x >> 32) as u32, (x & 0xffff_ffff) as f64 * (1.0 / 4_294_967_296.0))
}

/// Uniform direction on the unit sphere (Archimedes' equal-area map: `z` uniform in
/// `[-1, 1]`). Density `1 / (4π)` per steradian.
#[inline]
pub fn uniform_sphere(u: DVec2) -> DVec3 {
    let z = 1.0 - 2.0 * unit(u.x);
    let r = libm::sqrt((1.0 - z * z).max(0.0));
    let (sin, cos) = sincos_turns(unit(u.y));
    DVec3::new(r * cos, r * sin, z)
}

/// Uniform direction inside the cone of half-angle `acos(cos_max)` around +z
/// (equal-area map). Density `1 / (2π (1 - cos_max))`. `cos_max` is clamped to `[-1, 1]`.
#[inline]
pub fn uniform_cone(u: DVec2, cos_max: f64) -> DVec3 {
    let cos_max = if cos_max >= -1.0 { cos_max.min(1.0) } else { -1.0 };
    let z = 1.0 - unit(u.x) * (1.0 - cos_max);
    let r = libm::sqrt((1.0 - z * z).max(0.0));
    let (sin, cos) = sincos_turns(unit(u.y));
    DVec3::new(r * cos, r * sin, z)
}

/// Solid angle of a cone with half-angle `acos(cos_max)`, in steradians.
#[inline]
pub fn cone_solid_angle(cos_max: f64) -> f64 {
    TAU * (1.0 - cos_max.clamp(-1.0, 1.0))
}

/// Solid angle of a cone of half-angle `theta` (radians), `4π sin²(θ/2)`: exact also for
/// tiny cones, where `2π(1 − cos θ)` cancels to 0.
#[inline]
pub fn cone_solid_angle_from_angle(theta: f64) -> f64 {
    let s = libm::sin(0.5 * theta.clamp(0.0, PI));
    2.0 * TAU * s * s
}

/// Uniform point on the unit disc (Shirley–Chiu concentric map, area-preserving and
/// low-distortion).
#[inline]
pub fn uniform_disc(u: DVec2) -> DVec2 {
    let a = 2.0 * unit(u.x) - 1.0;
    let b = 2.0 * unit(u.y) - 1.0;
    if a == 0.0 && b == 0.0 {
        return DVec2::ZERO;
    }
    // θ = φ (|a| > |b|) or π/2 − φ, with φ = (π/4)·ratio in [−π/4, π/4]; sin and cos of
    // π/2 − φ are cos φ and sin φ. So `sincos` only ever sees |φ| ≤ π/4, where it needs
    // no argument reduction and takes the same branch every time.
    let wide = a * a > b * b;
    let (r, ratio) = if wide { (a, b / a) } else { (b, a / b) };
    let (sin, cos) = sincos_octant(FRAC_PI_4 * ratio);
    if wide { DVec2::new(r * cos, r * sin) } else { DVec2::new(r * sin, r * cos) }
}

/// `libm::sincos(x)` for `|x| ≤ π/4`, bit for bit, inlined: the same fdlibm kernels
/// (`__kernel_sin`, `__kernel_cos` with no reduction remainder) that `libm::sincos` runs in
/// that range, sharing `x²` and without the call, the range dispatch and the NaN checks.
/// The samplers only ever pass such angles (the concentric map's `(π/4)·ratio`, and the
/// quarter-turn remainder of [`sincos_turns`]); outside that range the result is not
/// `sin`, `cos`. Tested against `libm::sincos` over the whole range.
#[inline(always)]
fn sincos_octant(x: f64) -> (f64, f64) {
    const S1: f64 = -1.666_666_666_666_663_2e-1;
    const S2: f64 = 8.333_333_333_322_49e-3;
    const S3: f64 = -1.984_126_982_985_795e-4;
    const S4: f64 = 2.755_731_370_707_006_8e-6;
    const S5: f64 = -2.505_076_025_340_686_3e-8;
    const S6: f64 = 1.589_690_995_211_55e-10;
    const C1: f64 = 4.166_666_666_666_66e-2;
    const C2: f64 = -1.388_888_888_887_411e-3;
    const C3: f64 = 2.480_158_728_947_673e-5;
    const C4: f64 = -2.755_731_435_139_066_3e-7;
    const C5: f64 = 2.087_572_321_298_175e-9;
    const C6: f64 = -1.135_964_755_778_819_5e-11;
    // libm returns (x, 1) where the high word of |x| is below 0x3e46a09e (|x| ≲ 2⁻²⁷·√2),
    // keeping the sign of a zero; for non-negative doubles that is `|x| < 0x3e46a09e_00000000`.
    if x.abs() < f64::from_bits(0x3e46_a09e_0000_0000) {
        return (x, 1.0);
    }
    let z = x * x;
    let w = z * z;
    let rs = S2 + z * (S3 + z * S4) + z * w * (S5 + z * S6);
    let sin = x + z * x * (S1 + z * rs);
    let rc = z * (C1 + z * (C2 + z * C3)) + w * w * (C4 + z * (C5 + z * C6));
    let hz = 0.5 * z;
    let wc = 1.0 - hz;
    // fdlibm's `z·r − x·y` with the remainder `y = 0`: `z·r − (±0)` is `z·r`.
    let cos = wc + (((1.0 - wc) - hz) + z * rc);
    (sin, cos)
}

/// `(sin 2πt, cos 2πt)` for `t` in `[0, 1]` (turns). The quadrant is split off exactly
/// (`t − k/4` is exact for the nearest quarter `k/4`), so `sincos` only sees
/// `|2π(t − k/4)| ≤ π/4`, where it needs no argument reduction; the quadrant then swaps
/// and negates without branches.
#[inline]
fn sincos_turns(t: f64) -> (f64, f64) {
    // k = round(4t) in 0..=4; t − k/4 in [−1/8, 1/8] is exact (Sterbenz: t and k/4 are
    // within a factor of two of each other, or k = 0).
    let k = (4.0 * t + 0.5) as u32;
    let (s, c) = sincos_octant(TAU * (t - 0.25 * k as f64));
    // Rotation by k quarter turns: (s, c) → (c, −s) → (−s, −c) → (−c, s).
    let (s, c) = if k & 1 == 1 { (c, -s) } else { (s, c) };
    if k & 2 == 2 { (-s, -c) } else { (s, c) }
}

/// Cosine-weighted direction in the hemisphere around +z (Malley's method on the
/// concentric disc). Density `cos θ / π`.
#[inline]
pub fn cosine_hemisphere(u: DVec2) -> DVec3 {
    let d = uniform_disc(u);
    let z = libm::sqrt((1.0 - d.length_squared()).max(0.0));
    DVec3::new(d.x, d.y, z)
}

/// Uniform point on a triangle as barycentric weights `(b0, b1, b2)` of its vertices
/// (`b0 = 1 - √u₀`, `b1 = u₁ √u₀`). Density `1 / area`.
#[inline]
pub fn uniform_triangle(u: DVec2) -> DVec3 {
    let s = libm::sqrt(unit(u.x));
    let b1 = unit(u.y) * s;
    DVec3::new(1.0 - s, b1, s - b1)
}

/// The golden-ratio conjugate `(√5 − 1) / 2` used by [`fibonacci_lattice`].
pub const GOLDEN_RATIO_CONJUGATE: f64 = 0.618_033_988_749_894_9;

/// Point `i` of an `n`-point Fibonacci (rank-1) lattice in the unit square, randomly
/// shifted by `shift` (Cranley–Patterson rotation, one shift per iteration). The `n`
/// points cover the square evenly, so emitted photons tile their emission domain and the
/// footprints built from them overlap uniformly. `n = 0` is treated as 1.
#[inline]
pub fn fibonacci_lattice(i: u32, n: u32, shift: DVec2) -> DVec2 {
    let n = n.max(1) as f64;
    let x = (i as f64 + 0.5) / n + unit(shift.x);
    let y = i as f64 * GOLDEN_RATIO_CONJUGATE + unit(shift.y);
    // x, y ≥ 0 and far below 2^63: truncation is `floor` (and needs no libm call on
    // x86-64's baseline, which has no rounding instruction; signed conversions are single
    // instructions there, unsigned ones are not).
    DVec2::new(x - (x as i64) as f64, y - (y as i64) as f64)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::base::rng::{Rng, StreamDomain};
    use approx::assert_relative_eq;

    fn samples(n: u32) -> impl Iterator<Item = DVec2> {
        let mut rng = Rng::new(1, 0, 0, StreamDomain::User);
        (0..n).map(move |_| rng.next_2d())
    }

    #[test]
    fn sphere_is_unit_and_centred() {
        let n = 200_000;
        let mut mean = DVec3::ZERO;
        let mut upper = 0;
        for u in samples(n) {
            let d = uniform_sphere(u);
            assert_relative_eq!(d.length(), 1.0, epsilon = 1e-12);
            mean += d;
            if d.z > 0.5 {
                upper += 1;
            }
        }
        assert!((mean / n as f64).length() < 1e-2);
        // Cap above z = 0.5 holds a quarter of the sphere's area.
        assert_relative_eq!(upper as f64 / n as f64, 0.25, epsilon = 5e-3);
    }

    #[test]
    fn cone_stays_inside_and_is_uniform() {
        let cos_max = libm::cos(0.5);
        let n = 200_000;
        let mut inner = 0;
        let cos_half = libm::cos(0.25);
        for u in samples(n) {
            let d = uniform_cone(u, cos_max);
            assert!(d.z >= cos_max - 1e-12);
            if d.z > cos_half {
                inner += 1;
            }
        }
        let expected = cone_solid_angle(cos_half) / cone_solid_angle(cos_max);
        assert_relative_eq!(inner as f64 / n as f64, expected, epsilon = 5e-3);
    }

    #[test]
    fn cosine_hemisphere_moments() {
        // E[cos θ] under cos θ / π is 2/3.
        let n = 200_000;
        let mut sum = 0.0;
        for u in samples(n) {
            let d = cosine_hemisphere(u);
            assert!(d.z >= 0.0);
            assert_relative_eq!(d.length(), 1.0, epsilon = 1e-9);
            sum += d.z;
        }
        assert_relative_eq!(sum / n as f64, 2.0 / 3.0, epsilon = 3e-3);
    }

    #[test]
    fn disc_and_triangle_are_uniform() {
        let n = 200_000;
        let (mut inner, mut corner) = (0, 0);
        for u in samples(n) {
            let p = uniform_disc(u);
            assert!(p.length() <= 1.0 + 1e-12);
            if p.length() < 0.5 {
                inner += 1;
            }
            let b = uniform_triangle(u);
            assert!(b.min_element() >= 0.0);
            assert_relative_eq!(b.element_sum(), 1.0, epsilon = 1e-12);
            // Sub-triangle near vertex 0 with half the edge lengths holds a quarter of the area.
            if b.x > 0.5 {
                corner += 1;
            }
        }
        assert_relative_eq!(inner as f64 / n as f64, 0.25, epsilon = 5e-3);
        assert_relative_eq!(corner as f64 / n as f64, 0.25, epsilon = 5e-3);
    }

    #[test]
    fn lattice_strata_are_each_hit_once() {
        // A 1-D projection of the lattice puts exactly one point in each of n strata.
        let n = 1000;
        let mut hit = [false; 1000];
        for i in 0..n {
            let p = fibonacci_lattice(i, n, DVec2::new(0.37, 0.91));
            let k = (p.x * n as f64) as usize;
            assert!(!hit[k]);
            hit[k] = true;
        }
    }

    #[test]
    fn out_of_range_and_nan_inputs_are_finite() {
        for u in [DVec2::NAN, DVec2::new(-5.0, 7.0), DVec2::INFINITY, DVec2::NEG_INFINITY, DVec2::ONE] {
            assert!(uniform_sphere(u).is_finite());
            assert!(uniform_cone(u, f64::NAN).is_finite());
            assert!(uniform_disc(u).is_finite());
            assert!(cosine_hemisphere(u).is_finite());
            assert!(uniform_triangle(u).is_finite());
            assert!(fibonacci_lattice(3, 0, u).is_finite());
        }
    }

    /// `sincos_octant` is `libm::sincos` bit for bit wherever libm takes its no-reduction
    /// branch (`|x| ≤ π/4` by the high word), which covers every angle the samplers pass.
    #[test]
    fn sincos_octant_is_libm_sincos() {
        // The kernel's range, its ends, the tiny-argument branch and its boundary, signed
        // zeros and subnormals; then random angles across [−π/4, π/4], and random
        // magnitudes over every exponent below 1 (capped at π/4).
        let limit = f64::from_bits(0x3fe9_21fb_ffff_ffff); // libm's |x| ≤ π/4 test
        let tiny = f64::from_bits(0x3e46_a09e_0000_0000);
        let mut xs = alloc::vec![0.0, -0.0, f64::MIN_POSITIVE, 5e-324, 1e-300, 1e-9, tiny, limit, FRAC_PI_4];
        xs.extend([tiny, limit].iter().flat_map(|&x| [f64::from_bits(x.to_bits() - 1), f64::from_bits(x.to_bits() + 1)]));
        let mut rng = Rng::new(9, 9, 9, StreamDomain::User);
        for _ in 0..200_000 {
            let u = rng.next_f64();
            xs.push(FRAC_PI_4 * (2.0 * u - 1.0));
            xs.push(f64::from_bits(rng.next_u32() as u64 | ((rng.next_u32() as u64 & 0x3ff) << 52)).min(FRAC_PI_4));
        }
        for x in xs {
            for x in [x, -x] {
                if x.abs() > limit {
                    continue;
                }
                let (s, c) = sincos_octant(x);
                let (s0, c0) = libm::sincos(x);
                assert_eq!((s.to_bits(), c.to_bits()), (s0.to_bits(), c0.to_bits()), "x = {x:e}");
            }
        }
    }

    /// `sincos_turns(t)` is `sincos(2πt)` to within a few ulps over the whole unit
    /// interval, including the quadrant boundaries, their neighbours and the ends.
    #[test]
    fn sincos_turns_matches_libm() {
        let mut ts: alloc::vec::Vec<f64> = samples(100_000).map(|u| u.x).collect();
        for k in 0..=8 {
            let b = k as f64 / 8.0;
            ts.extend([b, b.next_up(), b.next_down(), b + 1e-12, b - 1e-12]);
        }
        for t in ts.into_iter().filter(|t| (0.0..=1.0).contains(t)) {
            let (s, c) = sincos_turns(t);
            let (s0, c0) = libm::sincos(TAU * t);
            // The reference's own angle TAU·t rounds by up to half an ulp of 2π (4.4e-16),
            // which moves sin and cos by as much; allow that plus a few ulps of 1.
            assert!((s - s0).abs() <= 1e-15 && (c - c0).abs() <= 1e-15, "t = {t}: ({s}, {c}) vs ({s0}, {c0})");
            assert!((s * s + c * c - 1.0).abs() <= 4.0 * f64::EPSILON);
        }
    }

    /// The concentric map evaluates `sincos` only on `[−π/4, π/4]`; it agrees with the
    /// textbook form (`θ = π/2 − (π/4)(a/b)` in the second wedge).
    #[test]
    fn concentric_disc_matches_the_textbook_form() {
        for u in samples(100_000) {
            let d = uniform_disc(u);
            let (a, b) = (2.0 * u.x - 1.0, 2.0 * u.y - 1.0);
            let (r, theta) = if a * a > b * b { (a, FRAC_PI_4 * (b / a)) } else { (b, 0.5 * PI - FRAC_PI_4 * (a / b)) };
            let (s, c) = libm::sincos(theta);
            assert!((d - DVec2::new(r * c, r * s)).abs().max_element() <= 4e-16, "{u:?}");
        }
    }

    /// Truncation is `floor` for the lattice's non-negative coordinates.
    #[test]
    fn lattice_coordinates_are_fractional_parts() {
        for i in [0u32, 1, 2, 1000, 123_456, u32::MAX] {
            for shift in [DVec2::ZERO, DVec2::new(0.999_999, 0.5), DVec2::ONE] {
                let p = fibonacci_lattice(i, 1000, shift);
                let n = 1000.0;
                let x = (i as f64 + 0.5) / n + shift.x;
                let y = i as f64 * GOLDEN_RATIO_CONJUGATE + shift.y;
                assert_eq!(p, DVec2::new(x - libm::floor(x), y - libm::floor(y)));
            }
        }
    }
}
