//! radius.wgsl against arpa_core::radius::RadiusSchedule over every u32 iteration,
//! α ∈ (0, 1] and the invalid inputs the core maps to defaults.
//!
//! Bound of the closed form: the twin (product, then asymptotic series, in f32) is good to
//! ~2e-6 relative; the core computes `lgamma(i + α) − lgamma(1 + α) − lgamma(i + 1)` in f64,
//! which cancels: its own error is up to ~ε₆₄ lgamma(i + 1) in the logarithm, half of that
//! in the radius (1.3e-5 relative was seen at i = 2³² − 1, α = 0.79, where the twin agreed
//! with a 40-digit evaluation to 2.5e-7). Tolerance: `2e-6 + 4 ε₆₄ lgamma(i + 1)` relative,
//! at most 4.2e-5. The recurrence: 1e-6.


use arpa_core::radius::{MIN_RADIUS, RadiusSchedule};
use crate::common::*;
use proptest::prelude::*;

const BODY: &str = "
    out_f(ob, arpa_radius(in_f(ib), in_f(ib + 1u), in_u(ib + 2u)));
    out_f(ob + 1u, arpa_radius_next(in_f(ib), in_f(ib + 1u), in_u(ib + 2u)));";

fn iteration() -> impl Strategy<Value = u32> {
    prop_oneof![0u32..40, (1.0f64..32.0).prop_map(|e| 2f64.powf(e).min(u32::MAX as f64) as u32), Just(u32::MAX)]
}

fn alpha() -> impl Strategy<Value = f32> {
    prop_oneof![4 => 1e-3f32..1.0, 1 => Just(2.0f32 / 3.0), 1 => Just(0.7f32), 1 => Just(1.0f32), 1 => Just(-0.5f32), 1 => Just(0.0f32), 1 => 1.0f32..5.0]
}

fn initial() -> impl Strategy<Value = f32> {
    prop_oneof![8 => (-6.0f64..3.0).prop_map(|e| 10f64.powf(e) as f32), 1 => Just(0.0f32), 1 => Just(-1.0f32), 1 => Just(f32::INFINITY)]
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 4, max_shrink_iters: 32, ..ProptestConfig::default() })]

    #[test]
    fn radius_matches_core(cases in prop::collection::vec((initial(), alpha(), iteration()), 4096)) {
        let Some(ctx) = gpu() else { return Ok(()) };
        let mut input = Vec::new();
        for &(r, a, i) in &cases {
            input.extend([fb(r), fb(a), i]);
        }
        let out = run(ctx, "radius", BODY, &input, 3, 2);
        let mut worst = 0.0f64;
        for (&(r, a, i), g) in cases.iter().zip(&out) {
            let s = RadiusSchedule { initial: r as f64, alpha: a as f64 };
            let want = s.radius(i);
            let got = f(g[0]) as f64;
            let rel = (got - want).abs() / want;
            worst = worst.max(rel);

            let tol = 2e-6 + 4.0 * f64::EPSILON * libm::lgamma(i.max(1) as f64 + 1.0);
            prop_assert!(rel <= tol, "radius(r1 {}, alpha {}, i {}): twin {} core {} ({:e} relative)", r, a, i, got, want, rel);
            prop_assert!(got >= MIN_RADIUS as f32 as f64);
            let want_next = s.next(r as f64, i);
            let got_next = f(g[1]) as f64;
            prop_assert!((got_next - want_next).abs() <= 1e-6 * want_next, "next(r {}, alpha {}, i {}): twin {} core {}", r, a, i, got_next, want_next);
        }
        eprintln!("radius: worst relative error {worst:e}");
    }
}

/// The series branch joins the product branch smoothly (i = 16 | 17) and follows the
/// recurrence over many iterations, independently of the core.
#[test]
fn closed_form_follows_its_own_recurrence() {
    let Some(ctx) = gpu() else { return };
    let alpha = 2.0f32 / 3.0;
    let its: Vec<u32> = (1..=3000).collect();
    let input: Vec<u32> = its.iter().flat_map(|&i| [fb(0.05), fb(alpha), i]).collect();
    let out = run(ctx, "radius recurrence", BODY, &input, 3, 2);
    for w in out.windows(2).zip(&its) {
        let ((a, b), i) = ((&w.0[0], &w.0[1]), *w.1);
        let (ri, rj) = (f(a[0]) as f64, f(b[0]) as f64);
        let ratio = (rj * rj) / (ri * ri);
        let exact = (i as f64 + alpha as f64) / (i as f64 + 1.0);
        assert!((ratio - exact).abs() <= 4e-6, "i {i}: r_(i+1)^2/r_i^2 = {ratio}, want {exact}");
    }
}
