//! heuristics.wgsl against `ResolvedHeuristics::store`: random footprints (centres up to
//! 1e3, differentials 1e-6 … 1e3, sin θ ≥ 1e-3) under random heuristic configurations
//! (each heuristic on or off, every mode, metric and reference), random scene bounds and
//! radii.
//!
//! Bounds (ε = f32::EPSILON): the outcome (stored / degenerate / culled / unrepresentable)
//! exactly, except within 1e-3 relative of a threshold (degenerate fraction, culling
//! threshold, f32 representability, the twin's axis-ratio resolution 16 ε). Stored
//! footprints are compared as ellipses, not as pairs of vectors: where H-max clamps the
//! axes separately both sides return principal differentials, whose directions are
//! ill-determined for a near-circle. With `κ = 1 + 1/sin θ (input) + 1/sin θ (final) +
//! σ₁/σ₂ (input)` (the f32 rounding of `D_u × D_v`, which sets `σ₂` and `M_p⁻¹`, is
//! relative `~ε κ`): the shape `D_u D_uᵀ + D_v D_vᵀ` within 1e-5 relative (the dampening
//! ratio is `exp((γ−1) ln(ℓ/ℓ_ref))` in f32: error ~ ε |ln(ℓ/ℓ_ref)|) plus `32 ε κ`; the
//! record's filter form `row_u row_uᵀ + row_v row_vᵀ` within `1e-5 + 64 ε κ` of its norm,
//! densities within the same, `n/h` within `1e-5 + 32 ε κ`; the box within 2e-5 of the
//! core's extent plus the slab's share of `n/h`'s bound, and it contains the elliptic slab
//! of the twin's own record (half-thickness `1/|row_n|`), rounded outwards.

use std::cell::Cell;
use std::f64::consts::{PI, TAU};

use arpa_core::base::aabb::Aabb;
use arpa_core::store::footprint::{Footprint, PackedFootprint, PhotonMap};
use arpa_core::glam::{DMat3, DVec3, Vec3};
use arpa_core::store::heuristics::{
    BoundingBoxCulling, CullMetric, DampenReference, Dampening, DegenerateRemoval, HMax, HMaxMode,
    HeuristicContext, Heuristics, LengthSpec, PackedHeuristics,
};
use arpa_core::store::heuristics::ProgressiveReason;
use proptest::prelude::*;

use super::{f, fb, proptest_batches, push3, run_prop, v3};
use crate::kernel_runner::KernelRunner;
use crate::suite::CaseResult;

const EPS: f64 = f32::EPSILON as f64;
/// Random footprints per batch, and batches.
const ITEMS: usize = 4096;
const BATCHES: u32 = 4;

#[derive(Clone, Debug)]
struct Case {
    fp: Footprint,
    heuristics: Heuristics,
    scene: Aabb,
    radius: f64,
}

fn unit(t: f64, p: f64) -> DVec3 {
    DVec3::new(t.sin() * p.cos(), t.sin() * p.sin(), t.cos())
}

fn r32(v: DVec3) -> DVec3 {
    v.as_vec3().as_dvec3()
}

fn heuristics() -> impl Strategy<Value = Heuristics> {
    let dampening = prop_oneof![
        1 => Just(None),
        3 => (prop_oneof![Just(0.25f64), 0.1f64..1.0], prop_oneof![Just(None), (-3.0f64..1.0).prop_map(Some)]).prop_map(|(exponent, r)| Some(Dampening {
            exponent: exponent as f32 as f64,
            reference: match r { None => DampenReference::ProgressiveDiameter, Some(e) => DampenReference::Absolute(10f64.powf(e) as f32 as f64) },
        })),
    ];
    let h_max = prop_oneof![
        1 => Just(None),
        3 => (-3.0f64..1.0, any::<bool>()).prop_map(|(e, aspect)| Some(HMax {
            length: LengthSpec::Absolute(10f64.powf(e) as f32 as f64),
            mode: if aspect { HMaxMode::PreserveAspect } else { HMaxMode::EachAxis },
        })),
    ];
    let degenerate = prop_oneof![1 => Just(None), 3 => (0.001f64..0.2).prop_map(|f| Some(DegenerateRemoval { fraction: f as f32 as f64 }))];
    let culling = prop_oneof![
        1 => Just(None),
        3 => (0.01f64..0.2, 0u32..3).prop_map(|(fraction, m)| Some(BoundingBoxCulling {
            fraction,
            metric: [CullMetric::LargestExtent, CullMetric::Diagonal, CullMetric::SurfaceArea][m as usize],
        })),
    ];
    (dampening, h_max, degenerate, culling).prop_map(|(dampening, h_max, degenerate, culling)| {
        Heuristics {
            dampening,
            h_max,
            degenerate,
            culling,
        }
    })
}

prop_compose! {
    fn case()(c in (0.0..PI, 0.0..TAU, -3.0f64..3.0), n in (0.0..PI, 0.0..TAU), alpha in 0.0..TAU,
              sin_exp in -3.0f64..0.0, lu in -4.0f64..2.0, lv_rel in -2.0f64..1.0, flux in prop::array::uniform3(0.01f64..10.0),
              map in 0u32..2, heuristics in heuristics(), scene_exp in (-1.0f64..1.5, -1.0f64..1.5, -1.0f64..1.5), r_exp in -4.0f64..-1.0) -> Case {
        let normal = r32(unit(n.0, n.1));
        let nn = unit(n.0, n.1);
        let t1 = nn.any_orthonormal_vector();
        let t2 = nn.cross(t1);
        let theta = 10f64.powf(sin_exp).asin();
        let du = (t1 * alpha.cos() + t2 * alpha.sin()) * 10f64.powf(lu);
        let dv = (t1 * (alpha + theta).cos() + t2 * (alpha + theta).sin()) * 10f64.powf(lu + lv_rel);
        let fp = Footprint {
            center: r32(unit(c.0, c.1) * 10f64.powf(c.2)),
            normal,
            du: r32(du),
            dv: r32(dv),
            flux: r32(DVec3::from_array(flux)),
            map: PhotonMap::from_index(map),
        };
        let half = DVec3::new(10f64.powf(scene_exp.0), 10f64.powf(scene_exp.1), 10f64.powf(scene_exp.2));
        Case { fp, heuristics, scene: Aabb { min: -half, max: half }, radius: 10f64.powf(r_exp) as f32 as f64 }
    }
}

const BODY: &str = "
    var hp: ArpaHeuristics;
    hp.enabled = in_u(ib); hp.dampen_reference_kind = in_u(ib + 1u); hp.h_max_mode = in_u(ib + 2u); hp.cull_metric = in_u(ib + 3u);
    hp.dampen_exponent = in_f(ib + 4u); hp.dampen_reference = in_f(ib + 5u); hp.h_max = in_f(ib + 6u);
    hp.degenerate_fraction = in_f(ib + 7u); hp.cull_threshold = in_f(ib + 8u);
    let s = arpa_store(hp, in_v3(ib + 12u), in_v3(ib + 15u), in_v3(ib + 18u), in_v3(ib + 21u), in_v3(ib + 24u), in_u(ib + 27u), in_f(ib + 28u));
    out_v3(ob, s.du); out_v3(ob + 3u, s.dv);
    out_v3(ob + 6u, s.record.center); out_u(ob + 9u, s.record.map);
    out_v3(ob + 10u, s.record.row_u); out_f(ob + 13u, s.record.flux_density_r);
    out_v3(ob + 14u, s.record.row_v); out_f(ob + 17u, s.record.flux_density_g);
    out_v3(ob + 18u, s.record.row_n); out_f(ob + 21u, s.record.flux_density_b);
    out_v3(ob + 22u, s.box_min); out_v3(ob + 25u, s.box_max); out_u(ob + 28u, s.status);";

fn status(r: &Result<(Footprint, PackedFootprint, Aabb), ProgressiveReason>) -> u32 {
    arpa_core::gpu::codes::store_code(r.as_ref().err().copied()).expect("the store gives only its own reasons")
}

/// `true` when one of the store's decisions lies within 1e-3 relative of its threshold.
fn near_threshold(c: &Case) -> bool {
    let ctx = HeuristicContext {
        radius: c.radius,
        scene_bounds: c.scene,
    };
    let fp = c
        .heuristics
        .clamp_h_max(c.heuristics.dampen(c.fp, &ctx), &ctx);
    let near =
        |x: f64, t: f64| x.is_finite() && t.is_finite() && t != 0.0 && (x / t - 1.0).abs() < 1e-3;
    let (major, minor) = fp.axis_lengths();
    if let Some(d) = c.heuristics.degenerate
        && near(minor, d.fraction * major)
    {
        return true;
    }
    // The twin's resolution of the input's axis ratio (the core's is 16 ε64).
    if c.fp.principal_axes().ratio() < 16.0 * EPS * 1.001 {
        return true;
    }
    if let Some(cull) = c.heuristics.culling {
        let b = fp.aabb(c.radius);
        let (mine, scene) = match cull.metric {
            CullMetric::LargestExtent => (b.largest_extent(), c.scene.largest_extent()),
            CullMetric::Diagonal => (b.diagonal(), c.scene.diagonal()),
            CullMetric::SurfaceArea => (b.surface_area(), c.scene.surface_area()),
        };
        if near(mine, cull.fraction * scene) {
            return true;
        }
    }
    let cross = fp.du.cross(fp.dv);
    let bound = 0.5 * cross.length() / (fp.du.length_squared() + fp.dv.length_squared()).sqrt();
    let scale = fp.center.abs().max_element().max(1e-30) * 64.0 * EPS;
    near(bound, scale)
}

fn outer(v: DVec3) -> DMat3 {
    DMat3::from_cols(v * v.x, v * v.y, v * v.z)
}

/// `|a − b|` over `|b|` (largest column norms): relative distance of two matrices.
fn mat_rel(a: DMat3, b: DMat3) -> f64 {
    let norm = |m: DMat3| m.col(0).length().max(m.col(1).length()).max(m.col(2).length());
    norm(a - b) / norm(b)
}

fn sin_between(a: DVec3, b: DVec3) -> f64 {
    a.cross(b).length() / (a.length() * b.length())
}

/// Random footprints under random configurations, within the bounds of the module docs;
/// every outcome must occur more than 25 times per batch.
pub fn matches_core(runner: &dyn KernelRunner) -> CaseResult {
    let totals = Cell::new([0usize; 4]);
    let strategy = prop::collection::vec(case(), ITEMS);
    proptest_batches("twin-heuristics", BATCHES, &strategy, |cases| {
        let mut input = Vec::new();
        for c in &cases {
            let packed: PackedHeuristics = c.heuristics.resolve(&c.scene).pack();
            input.extend_from_slice(bytemuck::cast_slice::<PackedHeuristics, u32>(
                std::slice::from_ref(&packed),
            ));
            for v in [c.fp.center, c.fp.normal, c.fp.du, c.fp.dv, c.fp.flux] {
                push3(&mut input, v.as_vec3().to_array());
            }
            input.push(c.fp.map as u32);
            input.push(fb(c.radius as f32));
        }
        let out = run_prop(runner, "heuristics store", "", BODY, &input, 29, 29)?;
        let mut counts = [0usize; 4];
        for (c, g) in cases.iter().zip(&out) {
            if near_threshold(c) {
                continue;
            }
            let want = c.heuristics.resolve(&c.scene).store(c.fp, c.radius);
            prop_assert_eq!(
                g[28],
                status(&want),
                "outcome of {:?}: core {:?}",
                c,
                want.as_ref().err()
            );
            counts[g[28] as usize] += 1;
            let Ok((fp, p, bounds)) = want else { continue };
            let close =
                |what: &str, got: DVec3, want: DVec3, tol: f64| -> Result<(), TestCaseError> {
                    prop_assert!(
                        (got - want).length() <= tol * want.length(),
                        "{}: twin {:?} core {:?} ({:e} relative > {:e}) in {:?}",
                        what,
                        got,
                        want,
                        (got - want).length() / want.length(),
                        tol,
                        c
                    );
                    Ok(())
                };
            let axes = c.fp.principal_axes();
            let kappa = 1.0
                + 1.0 / sin_between(c.fp.du, c.fp.dv)
                + 1.0 / sin_between(fp.du, fp.dv)
                + axes.semi_major / axes.semi_minor;
            let shape = |u: DVec3, v: DVec3| outer(u) + outer(v);
            let shape_err = mat_rel(shape(v3(g, 0), v3(g, 3)), shape(fp.du, fp.dv));
            prop_assert!(
                shape_err <= 1e-5 + 32.0 * EPS * kappa,
                "ellipse: twin {:?} {:?} core {:?} {:?} ({:e} relative) in {:?}",
                v3(g, 0),
                v3(g, 3),
                fp.du,
                fp.dv,
                shape_err,
                c
            );
            let tol = 1e-5 + 64.0 * EPS * kappa;
            let d3 = |a: [f32; 3]| Vec3::from_array(a).as_dvec3();
            prop_assert_eq!(v3(g, 6), d3(p.center));
            prop_assert_eq!(g[9], p.map);
            let form_err = mat_rel(
                outer(v3(g, 10)) + outer(v3(g, 14)),
                outer(d3(p.row_u)) + outer(d3(p.row_v)),
            );
            prop_assert!(
                form_err <= tol,
                "filter form: twin rows {:?} {:?} core {:?} ({:e} relative > {:e}) in {:?}",
                v3(g, 10),
                v3(g, 14),
                p,
                form_err,
                tol,
                c
            );
            let tol_n = 1e-5 + 32.0 * EPS * kappa;
            close("row_n", v3(g, 18), d3(p.row_n), tol_n)?;
            close(
                "density",
                DVec3::new(f(g[13]) as f64, f(g[17]) as f64, f(g[21]) as f64),
                p.flux_density().as_dvec3(),
                tol,
            )?;
            // The box: close to the core's, and containing the twin's own elliptic slab.
            let (bmin, bmax) = (v3(g, 22), v3(g, 25));
            let ext = bounds.max - bounds.min;
            let h_core = 1.0 / d3(p.row_n).length();
            for k in 0..3 {
                let tol_k = 2e-5 * ext.length()
                    + 4.0 * EPS * fp.center.abs()[k]
                    + tol_n * h_core * fp.normal[k].abs();
                prop_assert!(
                    (bmin[k] - bounds.min[k]).abs() <= tol_k,
                    "box min {} in {:?}",
                    k,
                    c
                );
                prop_assert!(
                    (bmax[k] - bounds.max[k]).abs() <= tol_k,
                    "box max {} in {:?}",
                    k,
                    c
                );
            }
            // The twin's record accepts the ellipse of its own D_u, D_v extruded by its own
            // half-thickness 1/|row_n|.
            let (a, b) = (0.5 * v3(g, 0), 0.5 * v3(g, 3));
            let h_twin = 1.0 / v3(g, 18).length();
            let e = (a * a + b * b).map(f64::sqrt) + (fp.normal * h_twin).abs();
            let own = Aabb::from_centre_half_extent(fp.center, e);
            prop_assert!(
                bmin.cmple(own.min).all() && bmax.cmpge(own.max).all(),
                "twin box {:?}..{:?} does not contain its slab {:?} in {:?}",
                bmin,
                bmax,
                own,
                c
            );
        }
        prop_assert!(
            counts.iter().all(|&n| n > 25),
            "outcomes (stored, degenerate, culled, unrepresentable): {:?}",
            counts
        );
        let t = totals.get();
        totals.set([
            t[0] + counts[0],
            t[1] + counts[1],
            t[2] + counts[2],
            t[3] + counts[3],
        ]);
        Ok(())
    })?;
    Ok(format!(
        "outcomes (stored, degenerate, culled, unrepresentable) = {:?}",
        totals.get()
    ))
}
