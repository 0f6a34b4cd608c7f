//! emission.wgsl's `arpa_spot_falloff_at(θ, θ_b, θ_c, curve)` (the spot falloff the photon
//! pass's emission and the camera pass's next-event estimation share) against
//! `arpa_core::emit::emission::SpotLight::falloff_at`: random beams and cut-offs over `(0, π]`
//! (including beams equal to the cut-off and narrow bands down to 1e-6 rad), angles over
//! `[0, π]` and angles on and a few ulps either side of both edges, both curves.
//!
//! Bounds (ε = f32::EPSILON; angles are f32 values, so both sides see the same numbers):
//! the regions (1 inside the beam, 0 beyond the cut-off) agree exactly, since both compare
//! the same numbers; inside the band the linear curve `x = (θ_c − θ)/(θ_c − θ_b)` within 4ε
//! (two subtractions, each exact or rounded once relative to its result, and a division,
//! 2.5 ulp on Vulkan), and the smoothstep `x²(3 − 2x)` within 16ε (its slope is at most 1.5,
//! plus the rounding of three more operations).

use std::cell::Cell;

use arpa_core::emit::emission::{SpotFalloff, SpotLight};
use arpa_core::glam::DVec3;
use proptest::prelude::*;

use super::{f, fb, proptest_batches, run_prop};
use crate::kernel_runner::KernelRunner;
use crate::suite::CaseResult;

const EPS: f64 = f32::EPSILON as f64;
/// Random (angle, spot) pairs per batch, and batches.
const ITEMS: usize = 4096;
const BATCHES: u32 = 4;

const BODY: &str =
    "out_f(ob, arpa_spot_falloff_at(in_f(ib), in_f(ib + 1u), in_f(ib + 2u), in_u(ib + 3u)));";

#[derive(Clone, Copy, Debug)]
struct Case {
    theta: f32,
    beam: f32,
    cutoff: f32,
    smooth: bool,
}

fn spot(c: &Case) -> SpotLight {
    SpotLight {
        position: DVec3::ZERO,
        direction: DVec3::Z,
        intensity: DVec3::ONE,
        cutoff: c.cutoff as f64,
        beam_width: c.beam as f64,
        falloff: if c.smooth {
            SpotFalloff::SmoothstepAngle
        } else {
            SpotFalloff::LinearAngle
        },
    }
}

/// Compares one batch with the core; returns the counts (beam, band, beyond).
fn check_batch(runner: &dyn KernelRunner, cases: &[Case]) -> Result<[usize; 3], TestCaseError> {
    let input: Vec<u32> = cases
        .iter()
        .flat_map(|c| [fb(c.theta), fb(c.beam), fb(c.cutoff), c.smooth as u32])
        .collect();
    let out = run_prop(runner, "spot falloff", "", BODY, &input, 4, 1)?;
    let mut counts = [0; 3]; // beam, band, beyond
    for (c, g) in cases.iter().zip(&out) {
        let want = spot(c).falloff_at(c.theta as f64);
        let got = f(g[0]) as f64;
        if c.theta <= c.beam {
            prop_assert_eq!(got, 1.0, "{:?}", c);
            counts[0] += 1;
        } else if c.theta >= c.cutoff {
            prop_assert_eq!(got, 0.0, "{:?}", c);
            counts[2] += 1;
        } else {
            let tol = if c.smooth { 16.0 } else { 4.0 } * EPS;
            prop_assert!(
                (got - want).abs() <= tol,
                "{} vs core {} for {:?}",
                got,
                want,
                c
            );
            counts[1] += 1;
        }
    }
    Ok(counts)
}

/// Random spots and angles within the bounds of the module docs; more than 500 of each
/// batch in the beam, in the band and beyond the cut-off.
pub fn matches_core(runner: &dyn KernelRunner) -> CaseResult {
    let totals = Cell::new([0usize; 3]);
    let strategy = prop::collection::vec(
        (
            1e-3f64..std::f64::consts::PI,
            prop_oneof![2 => 0.0f64..1.0, 1 => Just(1.0), 1 => (-6.0f64..-1.0).prop_map(|e| 1.0 - 10f64.powf(e))],
            0.0f64..std::f64::consts::PI,
            any::<bool>(),
            0u32..4,
            -3i32..=3,
        ),
        ITEMS,
    );
    proptest_batches("twin-spot-falloff", BATCHES, &strategy, |cases| {
        let cases: Vec<Case> = cases
            .iter()
            .map(|&(cutoff, frac, theta, smooth, at_edge, k)| {
                let cutoff = cutoff as f32;
                let beam = (cutoff as f64 * frac) as f32;
                let edge = |x: f32| f32::from_bits((x.to_bits() as i64 + k as i64).max(0) as u32);
                let theta = match at_edge {
                    0 => edge(beam),
                    1 => edge(cutoff),
                    _ => theta as f32,
                };
                Case {
                    theta,
                    beam,
                    cutoff,
                    smooth,
                }
            })
            .collect();
        let [beam, band, beyond] = check_batch(runner, &cases)?;
        prop_assert!(
            beam > 500 && band > 500 && beyond > 500,
            "beam {}, band {}, beyond {}",
            beam,
            band,
            beyond
        );
        let t = totals.get();
        totals.set([t[0] + beam, t[1] + band, t[2] + beyond]);
        Ok(())
    })?;
    let [beam, band, beyond] = totals.get();
    Ok(format!(
        "{beam} in the beam and {beyond} beyond the cut-off exact, {band} in the band within 4 eps (linear) / 16 eps (smoothstep)"
    ))
}
