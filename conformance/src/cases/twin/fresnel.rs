//! fresnel.wgsl's `arpa_dielectric_reflectance` against
//! `arpa_core::propagate::fresnel::dielectric_reflectance`, and differential.wgsl's
//! `arpa_refract_direction` against `arpa_core::propagate::differential::refract_direction`: random
//! interfaces (relative index 1.0001 to 3, inverted 0.2 to 1, exactly 1, and 1e-3 to 1e3)
//! hit at random angles, plus stress angles: grazing (|cos| down to 1e-30), near normal
//! (1 − cos down to 3e-8) and within 1e-7 to 1e-1 relative of the critical angle, from both
//! sides; and degenerate inputs (non-finite cosine or index, index <= 0).
//!
//! Bounds (ε = f32::EPSILON; inputs are f32 values, so both sides see the same numbers):
//! * reflectance: within `8ε + 2 S`, where S is the change of the core's f64 reflectance
//!   when cos_i and ior are perturbed by 4ε relative: the condition of the function at that
//!   input, measured on the core. The twin's roundings amount to relative perturbations of
//!   its inputs below that (1/ior, η², 1 − cos², sin²θ_t each round once), plus a few ε of
//!   the result itself. S is large only near the critical angle, where √(1 − sin²θ_t) turns
//!   any rounding into a large change. Total internal reflection (exactly 1) must agree
//!   wherever the core's sin²θ_t exceeds 1 by more than 1e-5, and degenerate inputs give
//!   exactly 1 as in the core.
//! * refraction: the event agrees except where the core's `k = 1 − η²(1 − cos²)` lies
//!   within `64ε (1 + η²)` of 0 (the f32 rounding of k) or `|d·n| < 8ε` (the side the ray
//!   arrives from is then decided by the rounding of the f32 dot product); η within 4ε
//!   relative (a division, 2.5 ulp allowed by Vulkan, and the core's own rounding of
//!   1/ior); a reflected direction within 8ε; a transmitted one within
//!   `16ε (1 + η + η²/√k)` (√k amplifies the rounding of k). Degenerate interfaces pass the
//!   direction through unchanged with η = 1.

use std::cell::Cell;

use arpa_core::propagate::differential::{RefractionEvent, refract_direction};
use arpa_core::propagate::fresnel::dielectric_reflectance;
use arpa_core::glam::DVec3;
use proptest::prelude::*;

use super::{check, f, fb, proptest_batches, push3, run, run_prop, v3};
use crate::kernel_runner::KernelRunner;
use crate::suite::CaseResult;

const EPS: f64 = f32::EPSILON as f64;
/// Random interfaces per batch, and batches (each of the two checks).
const ITEMS: usize = 4096;
const BATCHES: u32 = 4;

const REFLECTANCE_BODY: &str = "out_f(ob, arpa_dielectric_reflectance(in_f(ib), in_f(ib + 1u)));";

const REFRACT_BODY: &str = "
    let r = arpa_refract_direction(in_v3(ib), in_v3(ib + 3u), in_f(ib + 6u));
    out_v3(ob, r.dir);
    out_u(ob + 3u, r.event);
    out_f(ob + 4u, r.eta);";

/// A relative index of refraction (inside over outside), as f32.
fn ior() -> impl Strategy<Value = f64> {
    prop_oneof![
        4 => 1.0001f64..3.0,
        2 => 0.2f64..1.0,
        1 => Just(1.0),
        1 => (-3.0f64..3.0).prop_map(|e| 10f64.powf(e)),
    ]
    .prop_map(|x| x as f32 as f64)
}

/// A cosine between the direction of travel and the normal for an interface of index
/// `ior` (either sign: negative arrives from outside), including stress angles.
fn cosine(ior: f64) -> impl Strategy<Value = f64> {
    // From inside (cos > 0) the critical cosine is sqrt(1 - 1/ior^2) for ior > 1; from
    // outside (cos < 0) for ior < 1 it is -sqrt(1 - ior^2).
    let critical = if ior > 1.0 {
        (1.0 - 1.0 / (ior * ior)).sqrt()
    } else {
        -(1.0 - ior * ior).sqrt()
    };
    prop_oneof![
        4 => -1.0f64..=1.0,
        1 => ((0.0f64..30.0), any::<bool>()).prop_map(|(e, neg)| if neg { -(10f64.powf(-e)) } else { 10f64.powf(-e) }),
        1 => ((1.0f64..7.5), any::<bool>()).prop_map(|(e, neg)| { let c = 1.0 - 10f64.powf(-e); if neg { -c } else { c } }),
        2 => ((1.0f64..7.0), any::<bool>()).prop_map(move |(e, up)| (critical * (1.0 + if up { 1.0 } else { -1.0 } * 10f64.powf(-e))).clamp(-1.0, 1.0)),
    ]
    .prop_map(|c| c as f32 as f64)
}

/// `(cos_i, ior)`.
fn interface() -> impl Strategy<Value = (f64, f64)> {
    ior().prop_flat_map(|i| (cosine(i), Just(i)))
}

/// The core's reflectance change under 4ε relative perturbations of its inputs.
fn sensitivity(c: f64, ior: f64) -> f64 {
    let f0 = dielectric_reflectance(c, ior);
    let h = 4.0 * EPS;
    [
        (h, 0.0),
        (-h, 0.0),
        (0.0, h),
        (0.0, -h),
        (h, h),
        (-h, -h),
        (h, -h),
        (-h, h),
    ]
    .iter()
    .map(|&(dc, di)| (dielectric_reflectance(c * (1.0 + dc), ior * (1.0 + di)) - f0).abs())
    .fold(0.0, f64::max)
}

/// `(cos_i, ior)` pairs → the twin's reflectances.
fn twin_reflectance(runner: &dyn KernelRunner, cases: &[(f64, f64)]) -> Result<Vec<f32>, String> {
    let input: Vec<u32> = cases
        .iter()
        .flat_map(|&(c, i)| [fb(c as f32), fb(i as f32)])
        .collect();
    Ok(run(runner, "fresnel", REFLECTANCE_BODY, &input, 2, 1)?
        .iter()
        .map(|g| f(g[0]))
        .collect())
}

/// The core's sin²θ_t, to tell total internal reflection apart.
fn sin_t2(c: f64, ior: f64) -> f64 {
    let eta = if c < 0.0 { 1.0 / ior } else { ior };
    let ci = c.abs().min(1.0);
    eta * eta * (1.0 - ci * ci)
}

#[derive(Clone, Debug)]
struct Refraction {
    d: DVec3,
    n: DVec3,
    ior: f64,
}

prop_compose! {
    fn refraction()((c, ior) in interface(), (t, p) in (0.0..std::f64::consts::PI, 0.0..std::f64::consts::TAU), phi in 0.0..std::f64::consts::TAU) -> Refraction {
        let n = DVec3::new(t.sin() * p.cos(), t.sin() * p.sin(), t.cos());
        let f = arpa_core::base::frame::Frame::from_normal(n);
        let s = (1.0 - c * c).max(0.0).sqrt();
        let d = f.to_world(DVec3::new(s * phi.cos(), s * phi.sin(), c));
        Refraction { d: d.as_vec3().as_dvec3(), n: n.as_vec3().as_dvec3(), ior }
    }
}

fn refract_input(cases: &[Refraction]) -> Vec<u32> {
    let mut v = Vec::new();
    for c in cases {
        push3(&mut v, c.d.as_vec3().to_array());
        push3(&mut v, c.n.as_vec3().to_array());
        v.push(fb(c.ior as f32));
    }
    v
}

/// Degenerate interfaces, normal incidence and a textbook value, then random interfaces
/// and refractions within the bounds of the module docs.
pub fn matches_core(runner: &dyn KernelRunner) -> CaseResult {
    degenerate_interfaces_are_handled_like_core(runner)?;
    let reflectance = reflectance_matches_core(runner)?;
    let refraction = refract_direction_matches_core(runner)?;
    Ok(format!(
        "degenerate interfaces as the core; reflectance: {reflectance}; refract_direction: {refraction}"
    ))
}

/// Degenerate inputs: the core's reflectance is 1 and its refraction passes the direction
/// through (η = 1); the twin does the same, exactly. Normal incidence and a textbook value
/// pin the formula.
fn degenerate_interfaces_are_handled_like_core(runner: &dyn KernelRunner) -> Result<(), String> {
    let cases = [
        (f64::NAN, 1.5),
        (f64::INFINITY, 1.5),
        (-0.5, f64::NAN),
        (-0.5, f64::INFINITY),
        (-0.5, 0.0),
        (0.5, -1.5),
        (-1.0, 1.5),
        (1.0, 1.5),
    ];
    let got = twin_reflectance(runner, &cases)?;
    for (&(c, i), &g) in cases.iter().zip(&got) {
        let want = dielectric_reflectance(c, i);
        check!(
            (g as f64 - want).abs() <= 8.0 * EPS,
            "cos {c} ior {i}: {g} vs core {want}"
        );
    }
    check!(
        got[..6] == [1.0; 6],
        "degenerate interfaces reflect {:?}, want exactly 1",
        &got[..6]
    );
    // ((n − 1)/(n + 1))² = 0.04 at normal incidence, from either side.
    check!(
        (got[6] - 0.04).abs() < 1e-7 && (got[7] - 0.04).abs() < 1e-7,
        "normal incidence at ior 1.5: {:?}, want 0.04",
        &got[6..]
    );

    let d = DVec3::new(0.6, -0.8, 0.0).as_vec3().as_dvec3();
    let n = DVec3::Y;
    let cases: Vec<Refraction> = [f64::NAN, f64::INFINITY, -1.5, 0.0]
        .iter()
        .map(|&ior| Refraction { d, n, ior })
        .collect();
    let out = run(
        runner,
        "refract degenerate",
        REFRACT_BODY,
        &refract_input(&cases),
        7,
        5,
    )?;
    for (c, g) in cases.iter().zip(&out) {
        let (want, event, eta) = refract_direction(c.d, c.n, c.ior);
        check!(
            event == RefractionEvent::Transmitted,
            "core event {event:?} for ior {}",
            c.ior
        );
        let got = (v3(g, 0), g[3], f(g[4]) as f64);
        check!(
            got == (want, 0, eta),
            "ior {}: twin (direction, event, eta) {got:?}, core {:?}",
            c.ior,
            (want, 0, eta)
        );
    }
    Ok(())
}

/// Random interfaces: reflectance within `8ε + 2 S`, total internal reflection exactly 1;
/// more than 2500 compared and 200 totally reflected per batch.
fn reflectance_matches_core(runner: &dyn KernelRunner) -> Result<String, String> {
    let totals = Cell::new((0usize, 0usize));
    // Error / bound: everywhere, and outside the band where total internal reflection is
    // decided by rounding; absolute error for everyday indices (1/3 to 3) away from the
    // critical angle.
    let worst_all = Cell::new((0.0f64, 0.0f64, 0.0f64));
    let strategy = prop::collection::vec(interface(), ITEMS);
    proptest_batches("twin-fresnel-reflectance", BATCHES, &strategy, |cases| {
        let got = twin_reflectance(runner, &cases).map_err(TestCaseError::fail)?;
        let (mut worst, mut worst_off, mut worst_away) = worst_all.get();
        let (mut compared, mut total_internal) = (0, 0);
        for (&(c, i), &g) in cases.iter().zip(&got) {
            let want = dielectric_reflectance(c, i);
            let g = g as f64;
            if sin_t2(c, i) > 1.0 + 1e-5 {
                prop_assert_eq!(g, 1.0, "total internal reflection at cos {} ior {}", c, i);
                total_internal += 1;
                continue;
            }
            let tol = 8.0 * EPS + 2.0 * sensitivity(c, i);
            prop_assert!(
                (g - want).abs() <= tol,
                "reflectance {} vs core {} (bound {:e}) at cos {} ior {}",
                g,
                want,
                tol,
                c,
                i
            );
            worst = worst.max((g - want).abs() / tol);
            if (1.0 - sin_t2(c, i)).abs() > 1e-5 {
                worst_off = worst_off.max((g - want).abs() / tol);
            }
            if (1.0 - sin_t2(c, i)).abs() > 1e-3 && (1.0 / 3.0..=3.0).contains(&i) {
                worst_away = worst_away.max((g - want).abs());
            }
            compared += 1;
        }
        prop_assert!(
            compared > 2500 && total_internal > 200,
            "compared {}, total internal reflection {}",
            compared,
            total_internal
        );
        let t = totals.get();
        totals.set((t.0 + compared, t.1 + total_internal));
        worst_all.set((worst, worst_off, worst_away));
        Ok(())
    })?;
    let ((compared, total_internal), (worst, worst_off, worst_away)) =
        (totals.get(), worst_all.get());
    Ok(format!(
        "compared {compared}, TIR {total_internal}; worst error / bound {worst:.3} ({worst_off:.3} off the critical band); worst absolute error for ior in [1/3, 3] off the critical angle {worst_away:.1e}"
    ))
}

/// Random refractions: see the module's bounds; more than 2000 transmitted and 200 totally
/// reflected per batch.
fn refract_direction_matches_core(runner: &dyn KernelRunner) -> Result<String, String> {
    let totals = Cell::new([0usize; 3]);
    let worst_all = Cell::new(0.0f64);
    let strategy = prop::collection::vec(refraction(), ITEMS);
    proptest_batches("twin-fresnel-refract", BATCHES, &strategy, |cases| {
        let out = run_prop(
            runner,
            "refract_direction",
            "",
            REFRACT_BODY,
            &refract_input(&cases),
            7,
            5,
        )?;
        let (worst, [transmitted, tir, skipped]) = check_refraction(&cases, &out)?;
        prop_assert!(
            transmitted > 2000 && tir > 200,
            "transmitted {}, TIR {}, skipped {}",
            transmitted,
            tir,
            skipped
        );
        let t = totals.get();
        totals.set([t[0] + transmitted, t[1] + tir, t[2] + skipped]);
        worst_all.set(worst_all.get().max(worst));
        Ok(())
    })?;
    let [transmitted, tir, skipped] = totals.get();
    Ok(format!(
        "transmitted {transmitted}, TIR {tir}, skipped at k ~ 0: {skipped}; worst error / bound {:.3}",
        worst_all.get()
    ))
}

/// Checks one batch against the core; returns the worst error / bound and the counts
/// (transmitted, total internal reflection, skipped at k ~ 0).
fn check_refraction(
    cases: &[Refraction],
    out: &[Vec<u32>],
) -> Result<(f64, [usize; 3]), TestCaseError> {
    let mut worst: f64 = 0.0;
    let (mut transmitted, mut tir, mut skipped) = (0, 0, 0);
    for (c, g) in cases.iter().zip(out) {
        let (want, event, eta) = refract_direction(c.d, c.n, c.ior);
        let cos_i = c.d.dot(if c.d.dot(c.n) > 0.0 { -c.n } else { c.n });
        let k = 1.0 - eta * eta * (1.0 - cos_i * cos_i);
        if k.abs() < 64.0 * EPS * (1.0 + eta * eta) || cos_i.abs() < 8.0 * EPS {
            skipped += 1;
            continue;
        }
        let got_event = if g[3] == 0 {
            RefractionEvent::Transmitted
        } else {
            RefractionEvent::TotalInternalReflection
        };
        prop_assert_eq!(got_event, event, "event for {:?} (k {})", c, k);
        prop_assert!(
            (f(g[4]) as f64 - eta).abs() <= 4.0 * EPS * eta,
            "eta {} vs {} for {:?}",
            f(g[4]),
            eta,
            c
        );
        let tol = match event {
            RefractionEvent::TotalInternalReflection => {
                tir += 1;
                8.0 * EPS
            }
            RefractionEvent::Transmitted => {
                transmitted += 1;
                16.0 * EPS * (1.0 + eta + eta * eta / k.sqrt())
            }
        };
        let err = (v3(g, 0) - want).length();
        prop_assert!(
            err <= tol,
            "direction {:?} vs {:?} (error {:e}, bound {:e}) for {:?}",
            v3(g, 0),
            want,
            err,
            tol,
            c
        );
        worst = worst.max(err / tol);
    }
    Ok((worst, [transmitted, tir, skipped]))
}
