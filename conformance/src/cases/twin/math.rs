//! math.wgsl against the built-ins the core uses: `arpa_finite`/`arpa_finite3` against
//! `f32::is_finite` (bit patterns, exact), `arpa_acos` against f64 `acos`,
//! `arpa_angle_between` against the f64 angle, and `arpa_glam_normalize_or` against glam's
//! `Vec3::normalize_or` on the CPU.
//!
//! Bounds (ε = f32::EPSILON; inputs are f32 values, so both sides see the same numbers):
//! finiteness exactly; `acos` within 4ε relative to the f64 value (its own error is ~1 ulp:
//! a Taylor series truncated below 1.2e-9 and the half-angle reduction; lavapipe's built-in
//! `acos` errs by up to 1.6e-4 rad, which this bound rejects); `arpa_angle_between` within
//! `4ε (1 + θ)` of the f64 angle `atan2(|a × b|, a·b)` between the same f32 vectors, for
//! angles from 0 (and 1e-7) to π (and π − 1e-7) (the chord |a ∓ b| is formed with a
//! relative error of a few ε, the f32 unit vectors are unit to ε, and π is rounded to f32);
//! a normalised vector within 4ε (absolute, per component) of glam's, with the same choice
//! of the fallback. The fallback is compared where glam's choice is clear of the device's
//! rounding: |v| between 1e-18 and 1e18 (normalised), zero, non-finite, |v| >= 1e20 (|v|²
//! overflows, both fall back) and |v| <= 1e-24 (|v|² underflows to zero, both fall back).
//! Between those ranges the squares are subnormal or near `f32::MAX`, where Vulkan lets a
//! device flush or round differently, so glam's choice is not the device's to mirror.

use std::cell::Cell;

use arpa_core::glam::{DVec3, Vec3};
use proptest::prelude::*;

use super::{check, f, fb, proptest_batches, push3, run, run_prop, v3};
use crate::kernel_runner::KernelRunner;
use crate::suite::CaseResult;

const EPS: f64 = f32::EPSILON as f64;
/// Random items per batch, and batches (each of the random checks).
const ITEMS: usize = 4096;
const BATCHES: u32 = 4;

const ACOS_BODY: &str = "out_f(ob, arpa_acos(in_f(ib)));";

/// Finiteness on special and random bit patterns, `acos` on a grid, its seams and ends,
/// then random arguments, angles and vectors within the bounds of the module docs.
pub fn matches_core(runner: &dyn KernelRunner) -> CaseResult {
    let finite = finite_matches_is_finite_on_special_and_random_bit_patterns(runner)?;
    let grid = acos_is_accurate_on_a_grid_and_at_the_ends(runner)?;
    let acos = acos_matches_f64(runner)?;
    let angle = angle_between_matches_f64(runner)?;
    let normalize = glam_normalize_or_matches_glam(runner)?;
    Ok(format!(
        "finite: {finite}; acos: {grid}, random {acos:.3}; angle_between: worst error / bound {angle:.3}; normalize_or: {normalize}"
    ))
}

fn finite_matches_is_finite_on_special_and_random_bit_patterns(
    runner: &dyn KernelRunner,
) -> Result<String, String> {
    let mut bits: Vec<u32> = [
        0.0f32,
        -0.0,
        1.0,
        -1.0,
        f32::MIN_POSITIVE,
        1e-45,
        f32::MAX,
        f32::MIN,
        f32::INFINITY,
        f32::NEG_INFINITY,
        f32::NAN,
        -f32::NAN,
    ]
    .iter()
    .map(|x| x.to_bits())
    .collect();
    // Signalling and quiet NaN payloads, the largest finite exponent, every exponent once.
    bits.extend([
        0x7f80_0001,
        0x7fbf_ffff,
        0xff80_0001,
        0x7f7f_ffff,
        0xff7f_ffff,
    ]);
    bits.extend((0..=255u32).map(|e| (e << 23) | 0x0012_3456));
    // A pseudo-random sweep (the core's hash as the generator).
    bits.extend((0..4096u32).map(|i| arpa_core::base::rng::pcg4d([i, 77, 0, 0])[0]));
    // Items: three words, f32 bit patterns; outputs arpa_finite of the first, arpa_finite3.
    let items: Vec<[u32; 3]> = bits
        .iter()
        .enumerate()
        .map(|(i, &b)| {
            [
                b,
                bits[(i * 7 + 3) % bits.len()],
                bits[(i * 13 + 5) % bits.len()],
            ]
        })
        .collect();
    let input: Vec<u32> = items.iter().flatten().copied().collect();
    let out = run(
        runner,
        "finite",
        "out_u(ob, select(0u, 1u, arpa_finite(in_f(ib)))); out_u(ob + 1u, select(0u, 1u, arpa_finite3(in_v3(ib))));",
        &input,
        3,
        2,
    )?;
    let (mut finite, mut not_finite) = (0, 0);
    for (item, g) in items.iter().zip(&out) {
        let x = item.map(f32::from_bits);
        check!(
            (g[0] == 1) == x[0].is_finite(),
            "arpa_finite({:#x}): twin {}, is_finite {}",
            item[0],
            g[0],
            x[0].is_finite()
        );
        check!(
            (g[1] == 1) == x.iter().all(|c| c.is_finite()),
            "arpa_finite3({item:x?}): twin {}",
            g[1]
        );
        if x[0].is_finite() {
            finite += 1;
        } else {
            not_finite += 1;
        }
    }
    check!(
        finite > 100 && not_finite > 10,
        "finite {finite}, not finite {not_finite}"
    );
    Ok(format!(
        "{} bit patterns exact ({finite} finite, {not_finite} not)",
        items.len()
    ))
}

/// `arpa_acos` on `xs` within 4ε relative; the worst error / bound.
fn check_acos(runner: &dyn KernelRunner, xs: &[f32]) -> Result<f64, String> {
    let input: Vec<u32> = xs.iter().map(|&x| fb(x)).collect();
    let out = run(runner, "acos", ACOS_BODY, &input, 1, 1)?;
    let mut worst: f64 = 0.0;
    for (x, g) in xs.iter().zip(&out) {
        let want = (*x as f64).acos();
        let got = f(g[0]) as f64;
        let tol = 4.0 * EPS * want.max(1e-7);
        check!((got - want).abs() <= tol, "acos({x}) = {got}, f64 {want}");
        worst = worst.max((got - want).abs() / tol);
    }
    Ok(worst)
}

/// `arpa_acos` over a grid of `[-1, 1]`, the reduction's seams and the ends, where `acos`
/// is steepest (`1 − x` of a few ulps): within 4ε relative; NaN stays NaN.
fn acos_is_accurate_on_a_grid_and_at_the_ends(runner: &dyn KernelRunner) -> Result<String, String> {
    let n = 100_000;
    let mut xs: Vec<f32> = (0..n)
        .map(|i| -1.0 + 2.0 * (i as f32 + 0.5) / n as f32)
        .collect();
    xs.extend([
        -1.0,
        -0.5,
        0.0,
        0.5,
        1.0,
        1.0 - f32::EPSILON / 2.0,
        -1.0 + f32::EPSILON,
    ]);
    for k in 1..2000u32 {
        xs.push(f32::from_bits(1.0f32.to_bits() - k));
        xs.push(f32::from_bits((-1.0f32).to_bits() - k));
        xs.push(f32::from_bits(0.5f32.to_bits() + k));
        xs.push(f32::from_bits(0.5f32.to_bits() - k));
        xs.push(f32::from_bits((-0.5f32).to_bits() + k));
        xs.push(f32::from_bits((-0.5f32).to_bits() - k));
    }
    let worst = check_acos(runner, &xs)?;
    // NaN stays NaN (libm's acos).
    let out = run(runner, "acos nan", ACOS_BODY, &[fb(f32::NAN)], 1, 1)?;
    check!(
        f(out[0][0]).is_nan(),
        "acos(NaN) = {}, want NaN",
        f(out[0][0])
    );
    Ok(format!(
        "{} grid and end arguments, worst error / bound {worst:.3}; NaN stays NaN",
        xs.len()
    ))
}

/// Random arguments, uniform in `[-1, 1]` and clustered at ±1 (`1 − 10^-e`); the worst
/// error / bound.
fn acos_matches_f64(runner: &dyn KernelRunner) -> Result<f64, String> {
    let worst_all = Cell::new(0.0f64);
    let strategy = (
        prop::collection::vec(-1.0f32..=1.0, ITEMS / 2),
        prop::collection::vec((1.0f64..7.5, any::<bool>()), ITEMS / 2),
    );
    proptest_batches("twin-math-acos", BATCHES, &strategy, |(uniform, near)| {
        let mut xs = uniform;
        xs.extend(near.iter().map(|&(e, neg)| {
            let x = (1.0 - 10f64.powf(-e)) as f32;
            if neg { -x } else { x }
        }));
        let worst = check_acos(runner, &xs).map_err(TestCaseError::fail)?;
        worst_all.set(worst_all.get().max(worst));
        Ok(())
    })?;
    Ok(worst_all.get())
}

fn unit() -> impl Strategy<Value = DVec3> {
    (0.0..std::f64::consts::PI, 0.0..std::f64::consts::TAU)
        .prop_map(|(t, p)| DVec3::new(t.sin() * p.cos(), t.sin() * p.sin(), t.cos()))
}

/// A pair of f32 unit vectors at an angle drawn uniformly, near 0 or near π.
fn pair() -> impl Strategy<Value = (DVec3, DVec3)> {
    let pi = std::f64::consts::PI;
    let angle = prop_oneof![
        2 => 0.0..=pi,
        1 => (-7.0f64..0.0).prop_map(|e| 10f64.powf(e)),
        1 => (-7.0f64..0.0).prop_map(move |e| pi - 10f64.powf(e)),
        1 => prop::sample::select(vec![0.0, pi, pi / 3.0, 2.0 * pi / 3.0, pi / 2.0]),
    ];
    (unit(), angle, 0.0..std::f64::consts::TAU).prop_map(|(a, theta, phi)| {
        let f = arpa_core::base::frame::Frame::from_normal(a);
        let b = f.to_world(DVec3::new(
            theta.sin() * phi.cos(),
            theta.sin() * phi.sin(),
            theta.cos(),
        ));
        (a.as_vec3().as_dvec3(), b.as_vec3().as_dvec3())
    })
}

/// Random pairs: the angle within `4ε (1 + θ)`; the worst error / bound.
fn angle_between_matches_f64(runner: &dyn KernelRunner) -> Result<f64, String> {
    let worst_all = Cell::new(0.0f64);
    let strategy = prop::collection::vec(pair(), ITEMS);
    proptest_batches("twin-math-angle", BATCHES, &strategy, |pairs| {
        let mut input = Vec::new();
        for (a, b) in &pairs {
            push3(&mut input, a.as_vec3().to_array());
            push3(&mut input, b.as_vec3().to_array());
        }
        let out = run_prop(
            runner,
            "angle between",
            "",
            "out_f(ob, arpa_angle_between(in_v3(ib), in_v3(ib + 3u)));",
            &input,
            6,
            1,
        )?;
        let mut worst: f64 = 0.0;
        for ((a, b), g) in pairs.iter().zip(&out) {
            let want = a.cross(*b).length().atan2(a.dot(*b));
            let got = f(g[0]) as f64;
            let tol = 4.0 * EPS * (1.0 + want);
            prop_assert!(
                (got - want).abs() <= tol,
                "angle between {:?} and {:?}: {} vs f64 {}",
                a,
                b,
                got,
                want
            );
            worst = worst.max((got - want).abs() / tol);
        }
        worst_all.set(worst_all.get().max(worst));
        Ok(())
    })?;
    Ok(worst_all.get())
}

/// Random directions at magnitudes from 1e-30 to 1e30, zero and non-finite vectors:
/// glam's normalisation or fallback (see the module's bounds); more than 1500 normalised
/// and 1000 fallen back per batch.
fn glam_normalize_or_matches_glam(runner: &dyn KernelRunner) -> Result<String, String> {
    let totals = Cell::new((0usize, 0usize));
    let strategy = prop::collection::vec(
        (
            (0.0..std::f64::consts::PI, 0.0..std::f64::consts::TAU),
            -30.0f64..30.0,
            0u32..16,
        ),
        ITEMS,
    );
    proptest_batches("twin-math-normalize", BATCHES, &strategy, |cases| {
        let fallback = Vec3::new(0.25, -0.5, 2.0);
        let vs: Vec<Vec3> = cases
            .iter()
            .map(|&((t, p), e, special)| match special {
                0 => Vec3::ZERO,
                1 => Vec3::new(f32::NAN, 1.0, 0.0),
                2 => Vec3::new(0.0, f32::INFINITY, 1.0),
                _ => (DVec3::new(t.sin() * p.cos(), t.sin() * p.sin(), t.cos()) * 10f64.powf(e))
                    .as_vec3(),
            })
            .collect();
        let mut input = Vec::new();
        for v in &vs {
            push3(&mut input, v.to_array());
            push3(&mut input, fallback.to_array());
        }
        let out = run_prop(
            runner,
            "glam normalize_or",
            "",
            "out_v3(ob, arpa_glam_normalize_or(in_v3(ib), in_v3(ib + 3u)));",
            &input,
            6,
            3,
        )?;
        let (mut normalised, mut fell_back) = (0, 0);
        for (v, g) in vs.iter().zip(&out) {
            let len = v.as_dvec3().length();
            let clear = !len.is_finite()
                || len == 0.0
                || (1e-18..=1e18).contains(&len)
                || len >= 1e20
                || len <= 1e-24;
            if !clear {
                continue;
            }
            let want = v.normalize_or(fallback);
            let got = v3(g, 0);
            if want == fallback {
                prop_assert_eq!(got, fallback.as_dvec3(), "fallback for {:?}", v);
                fell_back += 1;
            } else {
                prop_assert!(
                    (got - want.as_dvec3()).abs().max_element() <= 4.0 * EPS,
                    "{:?} normalised to {:?}, glam {:?}",
                    v,
                    got,
                    want
                );
                normalised += 1;
            }
        }
        prop_assert!(
            normalised > 1500 && fell_back > 1000,
            "normalised {}, fell back {}",
            normalised,
            fell_back
        );
        let t = totals.get();
        totals.set((t.0 + normalised, t.1 + fell_back));
        Ok(())
    })?;
    let (normalised, fell_back) = totals.get();
    Ok(format!(
        "{normalised} normalised within 4 eps, {fell_back} fell back as glam"
    ))
}
