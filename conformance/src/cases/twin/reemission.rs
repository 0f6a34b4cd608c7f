//! reemission.wgsl against arpa_core::propagate::reemission: re-emission of random absorbed footprints
//! (differentials 1e-15 … 1e15, re-emission lengths 1e-6 … 10) and cosine-distributed
//! diffuse directions; bad inputs labelled like the core.
//!
//! Bounds (ε = f32::EPSILON): direction within 8ε; directional differentials within 16ε of
//! their length; positional ones within `16 ε (1 + 1/sin θ)` of theirs (v goes with
//! `√|D_u × D_v|`, whose rounding is relative `ε/sin θ`); diffuse directions within 1e-5.
//! Directions within 1e-5 of the xy-plane are skipped: Duff's frame (the core's and the
//! twin's) branches on the sign of z there, and rounding picks the branch.

use std::cell::Cell;

use arpa_core::glam::{DVec2, DVec3};
use arpa_core::propagate::reemission::{diffuse_direction, reemit};
use proptest::prelude::*;

use super::{check, fb, proptest_batches, push3, run, run_prop, v3};
use crate::kernel_runner::KernelRunner;
use crate::suite::CaseResult;

const EPS: f64 = f32::EPSILON as f64;
/// Random footprints per batch, and batches.
const ITEMS: usize = 4096;
const BATCHES: u32 = 4;

fn dir() -> impl Strategy<Value = DVec3> {
    (0.0..std::f64::consts::PI, 0.0..std::f64::consts::TAU).prop_map(|(t, p)| {
        DVec3::new(t.sin() * p.cos(), t.sin() * p.sin(), t.cos())
            .as_vec3()
            .as_dvec3()
    })
}

fn vec_in(lo: f64, hi: f64) -> impl Strategy<Value = DVec3> {
    (dir(), lo..hi).prop_map(|(d, e)| (d * 10f64.powf(e)).as_vec3().as_dvec3())
}

#[derive(Clone, Debug)]
struct Case {
    hit: DVec3,
    dp_du: DVec3,
    dp_dv: DVec3,
    direction: DVec3,
    length: f64,
    u: DVec2,
}

prop_compose! {
    fn case()(hit in vec_in(-3.0, 3.0), dp_du in vec_in(-15.0, 15.0), dp_dv in vec_in(-15.0, 15.0), direction in dir(),
              len_exp in -6.0f64..1.0, u in (0.0f32..1.0, 0.0f32..1.0)) -> Case {
        Case { hit, dp_du, dp_dv, direction, length: 10f64.powf(len_exp) as f32 as f64, u: DVec2::new(u.0 as f64, u.1 as f64) }
    }
}

const BODY: &str = "
    let r = arpa_reemit(in_v3(ib), in_v3(ib + 3u), in_v3(ib + 6u), in_v3(ib + 9u), in_f(ib + 12u));
    out_v3(ob, r.ray.p); out_v3(ob + 3u, r.ray.d);
    out_v3(ob + 6u, r.ray.dp_du); out_v3(ob + 9u, r.ray.dp_dv);
    out_v3(ob + 12u, r.ray.dd_du); out_v3(ob + 15u, r.ray.dd_dv);
    out_u(ob + 18u, r.status);
    out_v3(ob + 19u, arpa_diffuse_direction(in_v3(ib + 9u), vec2<f32>(in_f(ib + 13u), in_f(ib + 14u))));";

fn input(cases: &[Case]) -> Vec<u32> {
    let mut v = Vec::new();
    for c in cases {
        for x in [c.hit, c.dp_du, c.dp_dv, c.direction] {
            push3(&mut v, x.as_vec3().to_array());
        }
        v.extend([fb(c.length as f32), fb(c.u.x as f32), fb(c.u.y as f32)]);
    }
    v
}

/// Random re-emissions within the bounds of the module docs, then the bad-input labels.
pub fn matches_core(runner: &dyn KernelRunner) -> CaseResult {
    let compared = random_reemissions(runner)?;
    bad_inputs_are_labelled_like_core(runner)?;
    Ok(format!(
        "{compared} re-emissions and diffuse directions compared; bad-input labels as the core"
    ))
}

fn random_reemissions(runner: &dyn KernelRunner) -> Result<usize, String> {
    let total = Cell::new(0usize);
    let strategy = prop::collection::vec(case(), ITEMS);
    proptest_batches("twin-reemission", BATCHES, &strategy, |cases| {
        let out = run_prop(runner, "reemission", "", BODY, &input(&cases), 15, 22)?;
        let mut compared = 0;
        for (c, g) in cases.iter().zip(&out) {
            if c.direction.z.abs() < 1e-5 {
                continue;
            }
            compared += 1;
            let w = reemit(c.hit, c.dp_du, c.dp_dv, c.direction, c.length);
            prop_assert_eq!(
                g[18] == 0,
                w.is_ok(),
                "status {} vs core {:?} for {:?}",
                g[18],
                w,
                c
            );
            // Every random footprint is a valid input: the core must succeed.
            let w = w.map_err(|e| {
                TestCaseError::fail(format!("the core's reemit failed ({e:?}) for {c:?}"))
            })?;
            let close =
                |what: &str, got: DVec3, want: DVec3, tol: f64| -> Result<(), TestCaseError> {
                    prop_assert!(
                        (got - want).length() <= tol,
                        "{}: twin {:?} core {:?} (|diff| {:e} > {:e}) for {:?}",
                        what,
                        got,
                        want,
                        (got - want).length(),
                        tol,
                        c
                    );
                    Ok(())
                };
            prop_assert_eq!(v3(g, 0), w.p);
            close("d", v3(g, 3), w.d, 8.0 * EPS)?;
            let sin = c.dp_du.cross(c.dp_dv).length() / (c.dp_du.length() * c.dp_dv.length());
            // Parallel differentials: v = 0 and both sides give exact zeros.
            let kp = |l: f64| {
                if l == 0.0 {
                    0.0
                } else {
                    16.0 * EPS * (1.0 + 1.0 / sin) * l
                }
            };
            close("dP/du", v3(g, 6), w.dp_du, kp(w.dp_du.length()))?;
            close("dP/dv", v3(g, 9), w.dp_dv, kp(w.dp_dv.length()))?;
            close("dD/du", v3(g, 12), w.dd_du, 16.0 * EPS * c.length)?;
            close("dD/dv", v3(g, 15), w.dd_dv, 16.0 * EPS * c.length)?;
            close(
                "diffuse direction",
                v3(g, 19),
                diffuse_direction(c.direction, c.u),
                1e-5,
            )?;
        }
        prop_assert!(
            compared > 4000,
            "only {} of {} compared",
            compared,
            cases.len()
        );
        total.set(total.get() + compared);
        Ok(())
    })?;
    Ok(total.get())
}

fn bad_inputs_are_labelled_like_core(runner: &dyn KernelRunner) -> Result<(), String> {
    let base = Case {
        hit: DVec3::ONE,
        dp_du: DVec3::X * 0.01,
        dp_dv: DVec3::Y * 0.02,
        direction: DVec3::Z,
        length: 0.1,
        u: DVec2::splat(0.3),
    };
    let cases = vec![
        Case {
            length: 0.0,
            ..base.clone()
        },
        Case {
            length: -1.0,
            ..base.clone()
        },
        Case {
            dp_du: DVec3::new(f64::NAN, 0.0, 0.0),
            ..base.clone()
        },
        Case {
            direction: DVec3::ZERO,
            ..base.clone()
        },
        Case {
            dp_dv: DVec3::X * 0.5,
            ..base.clone()
        }, // parallel: v = 0, still a valid (point) emitter
        base,
    ];
    let out = run(runner, "reemission labels", BODY, &input(&cases), 15, 22)?;
    let codes: Vec<u32> = out.iter().map(|g| g[18]).collect();
    check!(
        codes == [6, 6, 6, 1, 0, 0],
        "labels (length 0, length < 0, NaN dP, zero direction, parallel, valid): twin {codes:?}, expected [6, 6, 6, 1, 0, 0]"
    );
    for (c, &code) in cases.iter().zip(&codes) {
        let core = reemit(c.hit, c.dp_du, c.dp_dv, c.direction, c.length);
        check!(
            core.is_ok() == (code == 0),
            "{c:?}: core {core:?}, twin label {code}"
        );
    }
    Ok(())
}
