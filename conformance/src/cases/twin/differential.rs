//! differential.wgsl against arpa_core::propagate::differential: transfer, reflection and refraction
//! (with total internal reflection) of random ray differentials whose derivatives span
//! 1e-15 … 1e15, distances up to 1e6 and unnormalised normals; bad inputs and the f32
//! overflow labelled like the core.
//!
//! Bounds (ε = f32::EPSILON, K = 32): the twin evaluates the core's formulas in f32, so each
//! output vector agrees within `K ε S κ`, where `S` is the magnitude of the terms it is
//! summed from and `κ` the condition of the step:
//! * transfer: `S = |∂P| + t|∂D|`, `κ = 1 + 1/(D·N)²` (∂t divides by the rounded cosine);
//!   `P' = P + tD` within `K ε (|P| + t)`; ∂D exactly;
//! * reflection: `S = |∂D| + |∂N|/|N|`, `κ = 1`; direction within `K ε`;
//! * refraction: `S = η|∂D| + (η|cos_i| + √k)|∂N| + (η + η²|cos_i|/√k)(|∂D| + |∂N|)` (the
//!   terms `μ = η cos_i + √k` and `∂μ/∂(D·N)` are summed from; `μ` cancels as `η → 1`),
//!   `κ = 1 + 1/k`
//!   (`cos_t = −√k`). Compared where `|D·N| ≥ 1e-3` and, for refraction, `|k| ≥ 1e-2`;
//!   labels (success, total internal reflection) must agree wherever `|k| ≥ 1e-4`.

use std::cell::Cell;

use arpa_core::propagate::differential::{
    DifferentialError, NormalDifferential, RayDifferential, RefractionEvent,
};
use arpa_core::glam::{DVec3, Vec3};
use proptest::prelude::*;

use super::{check, fb, proptest_batches, push3, run_prop, run_with, v3};
use crate::kernel_runner::KernelRunner;
use crate::suite::CaseResult;

const EPS: f64 = f32::EPSILON as f64;
const K: f64 = 32.0;
/// Random differentials per batch, and batches.
const ITEMS: usize = 4096;
const BATCHES: u32 = 4;

#[derive(Clone, Debug)]
struct Case {
    ray: [[f32; 3]; 6],
    t: f32,
    n: [f32; 3],
    nd: [[f32; 3]; 3],
    ior: f32,
}

fn dir() -> impl Strategy<Value = DVec3> {
    (0.0..std::f64::consts::PI, 0.0..std::f64::consts::TAU)
        .prop_map(|(t, p)| DVec3::new(t.sin() * p.cos(), t.sin() * p.sin(), t.cos()))
}

fn vec_in(lo: f64, hi: f64) -> impl Strategy<Value = [f32; 3]> {
    (dir(), lo..hi).prop_map(|(d, e)| (d * 10f64.powf(e)).as_vec3().to_array())
}

fn maybe_zero(s: impl Strategy<Value = [f32; 3]>) -> impl Strategy<Value = [f32; 3]> {
    prop_oneof![1 => Just([0.0f32; 3]), 3 => s]
}

prop_compose! {
    fn case()(
        p in vec_in(-3.0, 3.0), d in dir(),
        dp_du in vec_in(-15.0, 15.0), dp_dv in vec_in(-15.0, 15.0),
        dd_du in maybe_zero(vec_in(-15.0, 15.0)), dd_dv in vec_in(-15.0, 15.0),
        t in prop_oneof![1 => Just(0.0f32), 7 => (-6.0f64..6.0).prop_map(|e| 10f64.powf(e) as f32)],
        n in vec_in(-10.0, 10.0),
        nn in vec_in(-3.0, 3.0), dn_du in maybe_zero(vec_in(-15.0, 15.0)), dn_dv in maybe_zero(vec_in(-15.0, 15.0)),
        ior in (-0.5f64..0.5).prop_map(|e| 10f64.powf(e) as f32),
    ) -> Case {
        Case { ray: [p, d.as_vec3().to_array(), dp_du, dp_dv, dd_du, dd_dv], t, n, nd: [nn, dn_du, dn_dv], ior }
    }
}

fn d3(v: [f32; 3]) -> DVec3 {
    Vec3::from_array(v).as_dvec3()
}

fn core_ray(c: &Case) -> RayDifferential {
    let r = c.ray.map(d3);
    RayDifferential {
        p: r[0],
        d: r[1],
        dp_du: r[2],
        dp_dv: r[3],
        dd_du: r[4],
        dd_dv: r[5],
    }
}

fn core_normal(c: &Case) -> NormalDifferential {
    let n = c.nd.map(d3);
    NormalDifferential {
        n: n[0],
        dn_du: n[1],
        dn_dv: n[2],
    }
}

const HELPERS: &str = "
fn out_diff(o: u32, r: ArpaDiffResult) {
    out_v3(o, r.ray.p); out_v3(o + 3u, r.ray.d);
    out_v3(o + 6u, r.ray.dp_du); out_v3(o + 9u, r.ray.dp_dv);
    out_v3(o + 12u, r.ray.dd_du); out_v3(o + 15u, r.ray.dd_dv);
    out_u(o + 18u, r.status); out_u(o + 19u, r.event);
}";

const BODY: &str = "
    let r = ArpaRayDiff(in_v3(ib), in_v3(ib + 3u), in_v3(ib + 6u), in_v3(ib + 9u), in_v3(ib + 12u), in_v3(ib + 15u));
    out_diff(ob, arpa_diff_transfer(r, in_f(ib + 18u), in_v3(ib + 19u)));
    let nd = ArpaNormalDiff(in_v3(ib + 22u), in_v3(ib + 25u), in_v3(ib + 28u));
    out_diff(ob + 20u, arpa_diff_reflect(r, nd));
    out_diff(ob + 40u, arpa_diff_refract(r, nd, in_f(ib + 31u)));";

fn input(cases: &[Case]) -> Vec<u32> {
    let mut v = Vec::new();
    for c in cases {
        for x in c.ray {
            push3(&mut v, x);
        }
        v.push(fb(c.t));
        push3(&mut v, c.n);
        for x in c.nd {
            push3(&mut v, x);
        }
        v.push(fb(c.ior));
    }
    v
}

fn status_of<T>(r: &Result<T, DifferentialError>) -> u32 {
    match r {
        Ok(_) => 0,
        Err(DifferentialError::InvalidDirection) => 1,
        Err(DifferentialError::InvalidNormal) => 2,
        Err(DifferentialError::InvalidDistance) => 3,
        Err(DifferentialError::Grazing) => 4,
        Err(DifferentialError::NearCriticalAngle) => 5,
        Err(DifferentialError::NonFinite) => 6,
    }
}

fn close(what: &str, got: DVec3, want: DVec3, tol: f64, c: &Case) -> Result<f64, TestCaseError> {
    let err = (got - want).length();
    prop_assert!(
        err <= tol,
        "{}: twin {:?} core {:?}: error {:e} > bound {:e} in {:?}",
        what,
        got,
        want,
        err,
        tol,
        c
    );
    Ok(if tol > 0.0 { err / tol } else { 0.0 })
}

/// Random differentials within the bounds of the module docs, then the bad-input labels and
/// the f32 overflow.
pub fn matches_core(runner: &dyn KernelRunner) -> CaseResult {
    let stats = random_differentials(runner)?;
    bad_inputs_are_labelled_like_core(runner)?;
    f32_overflow_is_labelled_non_finite(runner)?;
    Ok(format!(
        "{stats}; bad-input labels and f32 overflow as the core"
    ))
}

fn random_differentials(runner: &dyn KernelRunner) -> Result<String, String> {
    let totals = Cell::new([0usize; 4]);
    let worst_all = Cell::new(0.0f64);
    let strategy = prop::collection::vec(case(), ITEMS);
    proptest_batches("twin-differential", BATCHES, &strategy, |cases| {
        let out = run_prop(
            runner,
            "differentials",
            HELPERS,
            BODY,
            &input(&cases),
            32,
            60,
        )?;
        let (mut n_tr, mut n_rf, mut n_rr, mut n_tir, mut worst) = (0, 0, 0, 0, 0.0f64);
        for (c, g) in cases.iter().zip(&out) {
            let r = core_ray(c);
            let nd = core_normal(c);

            // Transfer.
            let n = d3(c.n).normalize();
            let cos = r.d.dot(n);
            if cos.abs() >= 1e-3 {
                let want = r.transfer(c.t as f64, d3(c.n));
                prop_assert_eq!(g[18], status_of(&want), "transfer label {:?}", c);
                if let Ok(w) = want {
                    n_tr += 1;
                    let t = c.t as f64;
                    worst = worst.max(close(
                        "transfer p",
                        v3(g, 0),
                        w.p,
                        K * EPS * (r.p.length() + t),
                        c,
                    )?);
                    let kappa = 1.0 + 1.0 / (cos * cos);
                    for (i, dp, dd) in [(6, r.dp_du, r.dd_du), (9, r.dp_dv, r.dd_dv)] {
                        let s = dp.length() + t * dd.length();
                        let want_dp = if i == 6 { w.dp_du } else { w.dp_dv };
                        worst = worst.max(close(
                            "transfer dP",
                            v3(g, i),
                            want_dp,
                            K * EPS * s * kappa,
                            c,
                        )?);
                    }
                    prop_assert_eq!(v3(g, 12), w.dd_du);
                    prop_assert_eq!(v3(g, 15), w.dd_dv);
                }
            }

            // Reflection (no threshold involved).
            let want = r.reflect(&nd);
            prop_assert_eq!(g[38], status_of(&want), "reflect label {:?}", c);
            let nlen = nd.n.length();
            if let Ok(w) = want {
                n_rf += 1;
                prop_assert_eq!(v3(g, 20), w.p);
                worst = worst.max(close("reflect d", v3(g, 23), w.d, K * EPS, c)?);
                prop_assert_eq!(v3(g, 26), w.dp_du);
                for (i, dd, dn) in [(32, r.dd_du, nd.dn_du), (35, r.dd_dv, nd.dn_dv)] {
                    let s = dd.length() + dn.length() / nlen;
                    let want_dd = if i == 32 { w.dd_du } else { w.dd_dv };
                    worst = worst.max(close("reflect dD", v3(g, i), want_dd, K * EPS * s, c)?);
                }
            }

            // Refraction.
            let nu = nd.n / nlen;
            let (nu, eta) = if r.d.dot(nu) > 0.0 {
                (-nu, c.ior as f64)
            } else {
                (nu, 1.0 / c.ior as f64)
            };
            let cos_i = r.d.dot(nu);
            let k = 1.0 - eta * eta * (1.0 - cos_i * cos_i);
            if k.abs() >= 1e-4 {
                let want = r.refract(&nd, c.ior as f64);
                prop_assert_eq!(g[58], status_of(&want), "refract label {:?} (k {})", c, k);
                if let Ok((w, ev)) = want {
                    let ev_code = if ev == RefractionEvent::TotalInternalReflection {
                        1
                    } else {
                        0
                    };
                    prop_assert_eq!(g[59], ev_code, "refraction event {:?} (k {})", c, k);
                    if ev == RefractionEvent::TotalInternalReflection {
                        n_tir += 1;
                        worst = worst.max(close("TIR d", v3(g, 43), w.d, K * EPS, c)?);
                        for (i, dd, dn) in [(52, r.dd_du, nd.dn_du), (55, r.dd_dv, nd.dn_dv)] {
                            let s = dd.length() + dn.length() / nlen;
                            let want_dd = if i == 52 { w.dd_du } else { w.dd_dv };
                            worst = worst.max(close("TIR dD", v3(g, i), want_dd, K * EPS * s, c)?);
                        }
                    } else if k >= 1e-2 {
                        n_rr += 1;
                        let kappa = 1.0 + 1.0 / k;
                        let cos_t = -k.sqrt();
                        // Magnitudes of the terms μ and ∂μ/∂(D·N) are summed from (μ cancels
                        // when η → 1).
                        let mu = eta * cos_i.abs() + cos_t.abs();
                        let dmu = eta + eta * eta * (cos_i / cos_t).abs();
                        worst = worst.max(close(
                            "refract d",
                            v3(g, 43),
                            w.d,
                            K * EPS * (1.0 + eta) * kappa,
                            c,
                        )?);
                        for (i, dd, dn) in [(52, r.dd_du, nd.dn_du), (55, r.dd_dv, nd.dn_dv)] {
                            let (a, b) = (dd.length(), dn.length() / nlen);
                            let s = eta * a + mu.abs() * b + dmu * (a + b);
                            let want_dd = if i == 52 { w.dd_du } else { w.dd_dv };
                            worst = worst.max(close(
                                "refract dD",
                                v3(g, i),
                                want_dd,
                                K * EPS * s * kappa,
                                c,
                            )?);
                        }
                    }
                }
            }
        }
        prop_assert!(
            n_tr > 2000 && n_rf > 3000 && n_rr > 1000 && n_tir > 100,
            "compared: transfer {}, reflect {}, refract {}, TIR {}",
            n_tr,
            n_rf,
            n_rr,
            n_tir
        );
        let t = totals.get();
        totals.set([t[0] + n_tr, t[1] + n_rf, t[2] + n_rr, t[3] + n_tir]);
        worst_all.set(worst_all.get().max(worst));
        Ok(())
    })?;
    let [n_tr, n_rf, n_rr, n_tir] = totals.get();
    Ok(format!(
        "compared transfer {n_tr}, reflect {n_rf}, refract {n_rr}, TIR {n_tir}; worst error / bound {:.3}",
        worst_all.get()
    ))
}

/// Bad inputs get the core's labels.
fn bad_inputs_are_labelled_like_core(runner: &dyn KernelRunner) -> Result<(), String> {
    let base = Case {
        ray: [
            [0.1, 2.0, -0.3],
            [0.0, -1.0, 0.0],
            [0.01, 0.0, 0.0],
            [0.0, 0.0, 0.02],
            [0.03, 0.0, 0.0],
            [0.0, 0.01, 0.04],
        ],
        t: 1.5,
        n: [0.0, 1.0, 0.0],
        nd: [[0.0, 1.0, 0.0], [0.1, 0.0, 0.0], [0.0; 3]],
        ior: 1.5,
    };
    let mut grazing = base.clone();
    grazing.ray[1] = [1.0, 0.0, 0.0];
    let mut nan_p = base.clone();
    nan_p.ray[2] = [f32::NAN, 0.0, 0.0];
    let cases = vec![
        base.clone(),
        Case {
            t: -1.0,
            ..base.clone()
        },
        Case {
            t: f32::NAN,
            ..base.clone()
        },
        Case {
            n: [0.0; 3],
            nd: [[0.0; 3], [0.0; 3], [0.0; 3]],
            ..base.clone()
        },
        Case {
            nd: [[f32::NAN, 1.0, 0.0], [0.0; 3], [0.0; 3]],
            ..base.clone()
        },
        Case {
            ior: 0.0,
            ..base.clone()
        },
        Case {
            ior: -1.5,
            ..base.clone()
        },
        grazing,
        nan_p,
    ];
    let out = run_with(
        runner,
        "differential labels",
        HELPERS,
        BODY,
        &input(&cases),
        32,
        60,
    )?;
    for (c, g) in cases.iter().zip(&out) {
        let r = core_ray(c);
        let nd = core_normal(c);
        let want = [
            status_of(&r.transfer(c.t as f64, d3(c.n))),
            status_of(&r.reflect(&nd)),
            status_of(&r.refract(&nd, c.ior as f64)),
        ];
        let got = [g[18], g[38], g[58]];
        check!(got == want, "labels of {c:?}: twin {got:?}, core {want:?}");
    }
    let got = [out[1][18], out[3][18], out[5][58], out[7][18], out[8][18]];
    check!(
        got == [3, 2, 6, 4, 6],
        "labels (negative t, zero normal, ior 0, grazing, NaN dP): twin {got:?}, expected [3, 2, 6, 4, 6]"
    );
    Ok(())
}

/// Beyond the f32 range the twin reports a non-finite result where the f64 core still
/// succeeds (t ∂D = 3e48): the documented range difference, labelled, never garbage.
fn f32_overflow_is_labelled_non_finite(runner: &dyn KernelRunner) -> Result<(), String> {
    let c = Case {
        ray: [
            [0.1, 2.0, -0.3],
            [0.0, -1.0, 0.0],
            [0.01, 0.0, 0.0],
            [0.0, 0.0, 0.02],
            [3e38, 0.0, 0.0],
            [0.0, 0.01, 0.04],
        ],
        t: 1e10,
        n: [0.0, 1.0, 0.0],
        nd: [[0.0, 1.0, 0.0], [0.0; 3], [0.0; 3]],
        ior: 1.5,
    };
    check!(
        core_ray(&c).transfer(c.t as f64, d3(c.n)).is_ok(),
        "the core's f64 transfer of {c:?} failed"
    );
    let out = run_with(
        runner,
        "differential overflow",
        HELPERS,
        BODY,
        &input(&[c]),
        32,
        60,
    )?;
    check!(
        out[0][18] == 6,
        "transfer beyond f32: twin label {}, expected 6 (non-finite)",
        out[0][18]
    );
    Ok(())
}
