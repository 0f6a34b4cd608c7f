//! radius.wgsl against arpa_core::accumulate::radius::RadiusSchedule over every u32 iteration,
//! α ∈ (0, 1] and the invalid inputs the core maps to defaults.
//!
//! Bound of the closed form: the twin (product, then asymptotic series, in f32) is good to
//! ~2e-6 relative; the core computes `lgamma(i + α) − lgamma(1 + α) − lgamma(i + 1)` in f64,
//! which cancels: its own error is up to ~ε₆₄ lgamma(i + 1) in the logarithm, half of that
//! in the radius (1.3e-5 relative at i = 2³² − 1, α = 0.79, where the twin agrees with a
//! 40-digit evaluation to 2.5e-7). Tolerance: `2e-6 + 4 ε₆₄ lgamma(i + 1)` relative,
//! at most 4.2e-5. The recurrence: 1e-6.

use std::cell::Cell;

use arpa_core::accumulate::radius::{MIN_RADIUS, RadiusSchedule};
use proptest::prelude::*;

use super::{check, f, fb, proptest_batches, run, run_prop};
use crate::kernel_runner::KernelRunner;
use crate::suite::CaseResult;

const BODY: &str = "
    out_f(ob, arpa_radius(in_f(ib), in_f(ib + 1u), in_u(ib + 2u)));
    out_f(ob + 1u, arpa_radius_next(in_f(ib), in_f(ib + 1u), in_u(ib + 2u)));";

/// Random schedules per batch, and batches.
const ITEMS: usize = 4096;
const BATCHES: u32 = 4;

fn iteration() -> impl Strategy<Value = u32> {
    prop_oneof![
        0u32..40,
        (1.0f64..32.0).prop_map(|e| 2f64.powf(e).min(u32::MAX as f64) as u32),
        Just(u32::MAX)
    ]
}

fn alpha() -> impl Strategy<Value = f32> {
    prop_oneof![4 => 1e-3f32..1.0, 1 => Just(2.0f32 / 3.0), 1 => Just(0.7f32), 1 => Just(1.0f32), 1 => Just(-0.5f32), 1 => Just(0.0f32), 1 => 1.0f32..5.0]
}

fn initial() -> impl Strategy<Value = f32> {
    prop_oneof![8 => (-6.0f64..3.0).prop_map(|e| 10f64.powf(e) as f32), 1 => Just(0.0f32), 1 => Just(-1.0f32), 1 => Just(f32::INFINITY)]
}

/// Random schedules within the bounds of the module docs, then the closed form against its
/// own recurrence.
pub fn matches_core(runner: &dyn KernelRunner) -> CaseResult {
    let worst = random_schedules(runner)?;
    closed_form_follows_its_own_recurrence(runner)?;
    Ok(format!(
        "{} schedules, worst relative error {worst:.2e}; r_(i+1)^2/r_i^2 = (i+a)/(i+1) within 4e-6 for i < 3000",
        ITEMS * BATCHES as usize
    ))
}

fn random_schedules(runner: &dyn KernelRunner) -> Result<f64, String> {
    let worst_all = Cell::new(0.0f64);
    let strategy = prop::collection::vec((initial(), alpha(), iteration()), ITEMS);
    proptest_batches("twin-radius", BATCHES, &strategy, |cases| {
        let mut input = Vec::new();
        for &(r, a, i) in &cases {
            input.extend([fb(r), fb(a), i]);
        }
        let out = run_prop(runner, "radius", "", BODY, &input, 3, 2)?;
        let mut worst = 0.0f64;
        for (&(r, a, i), g) in cases.iter().zip(&out) {
            let s = RadiusSchedule {
                initial: r as f64,
                alpha: a as f64,
            };
            let want = s.radius(i);
            let got = f(g[0]) as f64;
            let rel = (got - want).abs() / want;
            worst = worst.max(rel);

            let tol = 2e-6 + 4.0 * f64::EPSILON * libm::lgamma(i.max(1) as f64 + 1.0);
            prop_assert!(
                rel <= tol,
                "radius(r1 {}, alpha {}, i {}): twin {} core {} ({:e} relative)",
                r,
                a,
                i,
                got,
                want,
                rel
            );
            prop_assert!(got >= MIN_RADIUS as f32 as f64);
            let want_next = s.next(r as f64, i);
            let got_next = f(g[1]) as f64;
            prop_assert!(
                (got_next - want_next).abs() <= 1e-6 * want_next,
                "next(r {}, alpha {}, i {}): twin {} core {}",
                r,
                a,
                i,
                got_next,
                want_next
            );
        }
        worst_all.set(worst_all.get().max(worst));
        Ok(())
    })?;
    Ok(worst_all.get())
}

/// The series branch joins the product branch smoothly (i = 16 | 17) and follows the
/// recurrence over many iterations, independently of the core.
fn closed_form_follows_its_own_recurrence(runner: &dyn KernelRunner) -> Result<(), String> {
    let alpha = 2.0f32 / 3.0;
    let its: Vec<u32> = (1..=3000).collect();
    let input: Vec<u32> = its.iter().flat_map(|&i| [fb(0.05), fb(alpha), i]).collect();
    let out = run(runner, "radius recurrence", BODY, &input, 3, 2)?;
    for w in out.windows(2).zip(&its) {
        let ((a, b), i) = ((&w.0[0], &w.0[1]), *w.1);
        let (ri, rj) = (f(a[0]) as f64, f(b[0]) as f64);
        let ratio = (rj * rj) / (ri * ri);
        let exact = (i as f64 + alpha as f64) / (i as f64 + 1.0);
        check!(
            (ratio - exact).abs() <= 4e-6,
            "i {i}: r_(i+1)^2/r_i^2 = {ratio}, want {exact}"
        );
    }
    Ok(())
}
