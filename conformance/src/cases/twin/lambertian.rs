//! lambertian.wgsl against arpa_core::propagate::lambertian::DiffuseShading: random geometric normals,
//! shading normals tilted from them by up to 90° (either orientation), viewer, light and
//! photon directions over the whole sphere, and re-emission samples; edge cases labelled
//! like the core.
//!
//! Bounds (ε = f32::EPSILON; inputs are f32 values, so both sides see the same vectors):
//! the frame's validity and flip agree and the shading normal exactly (it is an input,
//! negated or not); cosines within 4ε; the adjoint ratio within 8ε relative times its
//! condition `1 + 1/|w·n_g|`; re-emission directions within `1e-5 + 2ε/cos θ_g` (the
//! sampling twin rounds `2u − 1` to f32, an absolute error of ε/2 in the disc radius `r`,
//! which `cos θ_g = √(1 − r²)` amplifies by `1/cos θ_g` at the disc's rim). Decisions at a
//! threshold are skipped where the tested quantity lies within 1e-5 of it (viewer in the
//! shading plane, light at either horizon, re-emission at the shading horizon, frame branch
//! of Duff's construction at n_g.z ≈ 0).

use std::cell::Cell;

use arpa_core::glam::{DVec2, DVec3};
use arpa_core::propagate::lambertian::{DiffuseShading, MAX_ADJOINT_RATIO};
use proptest::prelude::*;

use super::{check, f, fb, proptest_batches, push3, run, run_prop, v3};
use crate::kernel_runner::KernelRunner;
use crate::suite::CaseResult;

const EPS: f64 = f32::EPSILON as f64;
/// Random shading configurations per batch, and batches.
const ITEMS: usize = 4096;
const BATCHES: u32 = 4;

fn dir() -> impl Strategy<Value = DVec3> {
    (0.0..std::f64::consts::PI, 0.0..std::f64::consts::TAU).prop_map(|(t, p)| {
        DVec3::new(t.sin() * p.cos(), t.sin() * p.sin(), t.cos())
            .as_vec3()
            .as_dvec3()
    })
}

#[derive(Clone, Debug)]
struct Case {
    geometric: DVec3,
    shading: DVec3,
    toward: DVec3,
    w: DVec3,
    u: DVec2,
}

prop_compose! {
    fn case()(g in dir(), tilt in 0.0f64..(std::f64::consts::FRAC_PI_2 - 1e-4), phi in 0.0..std::f64::consts::TAU, flip in any::<bool>(), toward in dir(), w in dir(),
              u in (0.0f32..1.0, 0.0f32..1.0)) -> Case {
        let f = arpa_core::base::frame::Frame::from_normal(g);
        let s = f.to_world(DVec3::new(tilt.sin() * phi.cos(), tilt.sin() * phi.sin(), tilt.cos()));
        let s = if flip { -s } else { s };
        // The frame is built for a direction on the side of the geometric normal.
        let toward = if toward.dot(g) < 0.0 { -toward } else { toward };
        Case { geometric: g, shading: s.as_vec3().as_dvec3(), toward, w, u: DVec2::new(u.0 as f64, u.1 as f64) }
    }
}

const BODY: &str = "
    let s = arpa_diffuse_shading_new(in_v3(ib), in_v3(ib + 3u), in_v3(ib + 6u));
    out_u(ob, s.valid);
    out_v3(ob + 1u, s.shading);
    out_u(ob + 4u, select(0u, 1u, arpa_diffuse_below_shading_plane(s)));
    out_f(ob + 5u, arpa_diffuse_cosine(s, in_v3(ib + 9u)));
    out_f(ob + 6u, arpa_diffuse_adjoint_ratio(s, in_v3(ib + 9u)));
    let r = arpa_diffuse_sample_reemission(s, vec2<f32>(in_f(ib + 12u), in_f(ib + 13u)));
    out_v3(ob + 7u, r.direction);
    out_u(ob + 10u, r.valid);";

fn input(cases: &[Case]) -> Vec<u32> {
    let mut v = Vec::new();
    for c in cases {
        for x in [c.geometric, c.shading, c.toward, c.w] {
            push3(&mut v, x.as_vec3().to_array());
        }
        v.extend([fb(c.u.x as f32), fb(c.u.y as f32)]);
    }
    v
}

/// Random configurations within the bounds of the module docs, then the edge cases.
pub fn matches_core(runner: &dyn KernelRunner) -> CaseResult {
    let stats = random_shading(runner)?;
    edge_cases_are_labelled_like_core(runner)?;
    Ok(format!(
        "{stats}; edge cases (shading plane, NaN, grazing, clamped ratio) as the core"
    ))
}

fn random_shading(runner: &dyn KernelRunner) -> Result<String, String> {
    let totals = Cell::new((0usize, 0usize, 0usize));
    let strategy = prop::collection::vec(case(), ITEMS);
    proptest_batches("twin-lambertian", BATCHES, &strategy, |cases| {
        let out = run_prop(runner, "lambertian", "", BODY, &input(&cases), 14, 11)?;
        let (mut compared, mut reemitted, mut below) = (0usize, 0usize, 0usize);
        for (c, g) in cases.iter().zip(&out) {
            if c.toward.dot(c.shading).abs() < 1e-5 {
                continue;
            }
            let core = DiffuseShading::new(c.geometric, c.shading, c.toward);
            prop_assert_eq!(g[0] == 1, core.is_some(), "validity for {:?}", c);
            let Some(s) = core else { continue };
            compared += 1;
            prop_assert_eq!(v3(g, 1), s.shading, "shading normal for {:?}", c);
            prop_assert_eq!(g[4] == 1, s.below_shading_plane(), "below for {:?}", c);
            below += s.below_shading_plane() as usize;
            if c.w.dot(s.shading).abs() > 1e-5 && c.w.dot(s.geometric).abs() > 1e-5 {
                let want = s.cosine(c.w);
                prop_assert!(
                    (f(g[5]) as f64 - want).abs() <= 4.0 * EPS,
                    "cosine {} vs {} for {:?}",
                    f(g[5]),
                    want,
                    c
                );
            }
            let want = s.adjoint_ratio(c.w);
            let cg = c.w.dot(s.geometric).abs();
            if want < MAX_ADJOINT_RATIO * (1.0 - 1e-4) {
                let tol = 8.0 * EPS * (1.0 + 1.0 / cg) * want.max(1.0);
                prop_assert!(
                    (f(g[6]) as f64 - want).abs() <= tol,
                    "adjoint ratio {} vs {} for {:?}",
                    f(g[6]),
                    want,
                    c
                );
            } else if want == MAX_ADJOINT_RATIO
                && c.w.dot(s.shading).abs() > MAX_ADJOINT_RATIO * cg * (1.0 + 1e-4)
            {
                prop_assert_eq!(f(g[6]) as f64, MAX_ADJOINT_RATIO);
            }
            if s.geometric.z.abs() > 1e-5 {
                let want = s.sample_reemission(c.u);
                let d = v3(g, 7);
                if want.is_some_and(|w| w.dot(s.shading).abs() < 1e-5)
                    || d.dot(s.shading).abs() < 1e-5
                {
                    continue;
                }
                prop_assert_eq!(
                    g[10] == 1,
                    want.is_some(),
                    "re-emission validity for {:?}",
                    c
                );
                if let Some(w) = want {
                    reemitted += 1;
                    let tol = 1e-5 + 2.0 * EPS / w.dot(s.geometric);
                    prop_assert!(
                        (d - w).length() <= tol,
                        "re-emission {:?} vs {:?} for {:?}",
                        d,
                        w,
                        c
                    );
                }
            }
        }
        prop_assert!(
            compared > 3500 && reemitted > 2000 && below > 100,
            "compared {}, re-emitted {}, below {}",
            compared,
            reemitted,
            below
        );
        let (tc, tr, tb) = totals.get();
        totals.set((tc + compared, tr + reemitted, tb + below));
        Ok(())
    })?;
    let (compared, reemitted, below) = totals.get();
    Ok(format!(
        "compared {compared}, re-emitted {reemitted}, below the shading plane {below}"
    ))
}

fn edge_cases_are_labelled_like_core(runner: &dyn KernelRunner) -> Result<(), String> {
    let tilted = DVec3::new(0.6, 0.8, 0.0);
    let cases = vec![
        // Viewer exactly in the shading plane: no lobe.
        Case {
            geometric: DVec3::Y,
            shading: DVec3::X,
            toward: DVec3::Y,
            w: DVec3::Y,
            u: DVec2::splat(0.3),
        },
        // Non-finite shading normal.
        Case {
            geometric: DVec3::Y,
            shading: DVec3::new(f64::NAN, 1.0, 0.0),
            toward: DVec3::Y,
            w: DVec3::Y,
            u: DVec2::splat(0.3),
        },
        // Grazing photon under a tilted normal: clamped ratio.
        Case {
            geometric: DVec3::Y,
            shading: tilted,
            toward: DVec3::Y,
            w: DVec3::new(1.0, 1e-7, 0.0),
            u: DVec2::splat(0.3),
        },
        // Photon in the geometric plane: ratio 1/0 clamped; 0/0 (w = 0) is 0.
        Case {
            geometric: DVec3::Y,
            shading: tilted,
            toward: DVec3::Y,
            w: DVec3::X,
            u: DVec2::splat(0.3),
        },
        Case {
            geometric: DVec3::Y,
            shading: tilted,
            toward: DVec3::Y,
            w: DVec3::ZERO,
            u: DVec2::splat(0.3),
        },
        // No tilt: ratio exactly 1.
        Case {
            geometric: DVec3::Y,
            shading: DVec3::Y,
            toward: DVec3::Y,
            w: DVec3::new(0.6, 0.8, 0.0),
            u: DVec2::splat(0.3),
        },
    ];
    let out = run(runner, "lambertian edges", BODY, &input(&cases), 14, 11)?;
    for (c, g) in cases.iter().zip(&out) {
        let core = DiffuseShading::new(c.geometric, c.shading, c.toward);
        check!(
            (g[0] == 1) == core.is_some(),
            "validity of {c:?}: twin {}, core {core:?}",
            g[0]
        );
        if let Some(s) = core {
            let want = s.adjoint_ratio(c.w);
            check!(
                f(g[6]) as f64 == want,
                "adjoint ratio of {c:?}: twin {}, core {want}",
                f(g[6])
            );
        }
    }
    let ratios = [f(out[2][6]), f(out[3][6]), f(out[4][6]), f(out[5][6])];
    check!(
        ratios == [100.0, 100.0, 0.0, 1.0],
        "ratios (grazing, in-plane, w = 0, no tilt): twin {ratios:?}, expected [100, 100, 0, 1]"
    );
    Ok(())
}
