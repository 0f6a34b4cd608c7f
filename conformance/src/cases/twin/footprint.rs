//! footprint.wgsl + kernel.wgsl against arpa_core::store::footprint and arpa_core::gather::kernel, over
//! random footprints whose scale spans 1e-30 … 1e30 (the f32 range leaves room for the
//! products the record needs), centres up to 1e6 and angles between the differentials down
//! to sin θ = 1e-3; parallel, zero and bad inputs labelled like the core. Then
//! bandwidth.wgsl, the evaluations at every scale of the bandwidth ladder, against
//! `PackedFootprint::irradiance_scales`, `PackedPhoton::irradiance_scales`,
//! `bandwidth::luminance` and `bandwidth::moments`.
//!
//! Bounds (ε = f32::EPSILON):
//! * the record (`Footprint::pack`): the core rounds an f64 result once, the twin computes
//!   in f32; `M_p⁻¹` divides by `(D_u × D_v)·n = |D_u||D_v| sin θ`, whose f32 rounding is
//!   relative `~ε/sin θ`. Rows and flux densities must agree within `ROW_K ε (1 + 1/sin θ)`
//!   of their norm (≤ 1e-4 for sin θ ≥ 0.04); `n/h` within `1e-5` relative plus the same
//!   (the half-thickness is the minor semi-axis `σ₂ = |D_u × D_v|/(2σ₁)`); centre and
//!   map exactly; and the labels (ok / degenerate / unrepresentable) exactly, except within
//!   `1e-3` relative of the representability threshold where f32 rounding decides.
//! * the gather test on a record (`PackedFootprint`, f32 in both): the same f32 formula,
//!   differing only by FMA contraction and summation order, so each filter coordinate within
//!   `4 ε |row| |q − x_p|`; containment exactly outside that margin; irradiance within
//!   `1e-6` of the density plus the kernel's slope times that margin.
//! * the scaled footprint (`irradiance_scales`, scale `k`, `f = 2^k`): the same f32
//!   formula at `f r²` times `f`, so where the stored test and `f r²` are decided (away from
//!   1 by `f` times the `r²` margin) within `f` times the density times `1e-6` plus `2 f`
//!   times that margin; the entry of scale 0 within the stored irradiance's bound.
//! * the scaled photon (`PackedPhoton::irradiance_scales`): `flux · 2^k/(π r²)` where
//!   `2^k d² < r²`; WGSL allows 2.5 ulp for the density's division, so within `8 ε`
//!   relative, exactly where `2^k d²/r²` is more than `1e-5` from 1 (and the side test and
//!   the overflow of the product decided).
//! * the luminance (three products, two sums) within `3 ε Σ|w_i c_i|` (FMA contraction may
//!   drop roundings); the moments, squares of the luminances and of their neighbouring
//!   differences, within `8 ε Y²` (`Y = Σ|w_i c_i|` of the scales involved, summed for a
//!   difference).

use std::cell::Cell;

use arpa_core::gather::scales::{SCALES, inv_scale2, luminance, moments};
use arpa_core::store::footprint::{Footprint, FootprintError, PackedFootprint, PhotonMap};
use arpa_core::store::progressive_photon::PackedPhoton;
use arpa_core::glam::{DVec3, Vec3};
use arpa_core::gather::kernel::Kernel;
use proptest::prelude::*;

use super::{check, f, fb, proptest_batches, push3, run, run_prop, v3};
use crate::kernel_runner::KernelRunner;
use crate::suite::CaseResult;

const EPS: f64 = f32::EPSILON as f64;
const ROW_K: f64 = 32.0;
/// Random footprints (and queries) per batch, and batches of each.
const ITEMS: usize = 4096;
const BATCHES: u32 = 4;

/// One random footprint: f32 inputs and the sin θ they were built with.
#[derive(Clone, Debug)]
struct Case {
    center: [f32; 3],
    normal: [f32; 3],
    du: [f32; 3],
    dv: [f32; 3],
    flux: [f32; 3],
    map: u32,
    radius: f32,
}

fn unit(theta: f64, phi: f64) -> DVec3 {
    DVec3::new(
        theta.sin() * phi.cos(),
        theta.sin() * phi.sin(),
        theta.cos(),
    )
}

fn f3(v: DVec3) -> [f32; 3] {
    v.as_vec3().to_array()
}

fn d3(v: [f32; 3]) -> DVec3 {
    Vec3::from_array(v).as_dvec3()
}

prop_compose! {
    fn case()(
        c_dir in (0.0..std::f64::consts::PI, 0.0..std::f64::consts::TAU), c_exp in -3.0f64..6.0,
        n_dir in (0.0..std::f64::consts::PI, 0.0..std::f64::consts::TAU),
        alpha in 0.0..std::f64::consts::TAU,
        // sin θ log-uniform in [1e-3, 1] (θ or π − θ).
        sin_exp in -3.0f64..0.0, obtuse in any::<bool>(),
        lu_exp in -2.0f64..2.0, lv_exp in -2.0f64..2.0, scale_exp in -30.0f64..30.0,
        flux in prop::array::uniform3(prop_oneof![1 => Just(0.0f64), 7 => (-10.0f64..10.0).prop_map(|e| 10f64.powf(e))]),
        map in 0u32..2, r_exp in -6.0f64..1.0,
    ) -> Case {
        let n = unit(n_dir.0, n_dir.1);
        let t1 = n.any_orthonormal_vector();
        let t2 = n.cross(t1);
        let theta = { let t = 10f64.powf(sin_exp).min(1.0).asin(); if obtuse { std::f64::consts::PI - t } else { t } };
        let s = 10f64.powf(scale_exp);
        let du = (t1 * alpha.cos() + t2 * alpha.sin()) * 10f64.powf(lu_exp) * s;
        let dv = (t1 * (alpha + theta).cos() + t2 * (alpha + theta).sin()) * 10f64.powf(lv_exp) * s;
        Case {
            center: f3(unit(c_dir.0, c_dir.1) * 10f64.powf(c_exp)),
            normal: f3(n),
            du: f3(du),
            dv: f3(dv),
            flux: flux.map(|x| x as f32),
            map,
            radius: 10f64.powf(r_exp) as f32,
        }
    }
}

fn core_footprint(c: &Case) -> Footprint {
    Footprint {
        center: d3(c.center),
        normal: d3(c.normal),
        du: d3(c.du),
        dv: d3(c.dv),
        flux: d3(c.flux),
        map: PhotonMap::from_index(c.map),
    }
}

const PACK_BODY: &str = "
    let r = arpa_footprint_pack(in_v3(ib), in_v3(ib + 3u), in_v3(ib + 6u), in_v3(ib + 9u), in_v3(ib + 12u), in_u(ib + 15u), in_f(ib + 16u));
    out_v3(ob, r.fp.center); out_u(ob + 3u, r.fp.map);
    out_v3(ob + 4u, r.fp.row_u); out_f(ob + 7u, r.fp.flux_density_r);
    out_v3(ob + 8u, r.fp.row_v); out_f(ob + 11u, r.fp.flux_density_g);
    out_v3(ob + 12u, r.fp.row_n); out_f(ob + 15u, r.fp.flux_density_b);
    out_u(ob + 16u, r.status);";

fn pack_input(cases: &[Case]) -> Vec<u32> {
    let mut input = Vec::new();
    for c in cases {
        for v in [c.center, c.normal, c.du, c.dv, c.flux] {
            push3(&mut input, v);
        }
        input.push(c.map);
        input.push(fb(c.radius));
    }
    input
}

fn status_of(r: &Result<PackedFootprint, FootprintError>) -> u32 {
    match r {
        Ok(_) => 0,
        Err(FootprintError::Degenerate) => 1,
        Err(FootprintError::Unrepresentable) => 2,
        Err(FootprintError::InvalidNormal) => 3,
    }
}

/// `true` when f32 rounding may legitimately flip the core's label for this footprint.
fn near_threshold(fp: &Footprint) -> bool {
    let cross = fp.du.cross(fp.dv);
    let (la2, lb2) = (fp.du.length_squared(), fp.dv.length_squared());
    let bound = 0.5 * cross.length() / (la2 + lb2).sqrt();
    let scale = fp.center.abs().max_element().max(1e-30) * 64.0 * EPS;
    let den = cross.dot(fp.normal);
    let dens = fp.flux * (4.0 / den.abs());
    let rows = [
        fp.dv.cross(fp.normal) * (2.0 / den),
        fp.normal.cross(fp.du) * (2.0 / den),
    ];
    let near = |x: f64, t: f64| x.is_finite() && (x / t - 1.0).abs() < 1e-3;
    near(bound, scale)
        || (0..3).any(|c| fp.flux[c] != 0.0 && near(dens[c], f32::MIN_POSITIVE as f64))
        || (0..3).any(|c| near(dens[c].abs(), f32::MAX as f64))
        || rows
            .iter()
            .any(|r| (0..3).any(|c| near(r[c].abs(), f32::MAX as f64)))
}

fn sin_theta(fp: &Footprint) -> f64 {
    fp.du.cross(fp.dv).dot(fp.normal).abs() / (fp.du.length() * fp.dv.length())
}

fn check_close(what: &str, got: DVec3, want: DVec3, tol: f64) -> Result<(), TestCaseError> {
    let err = (got - want).length();
    prop_assert!(
        err <= tol * want.length(),
        "{}: twin {:?} core {:?}: error {:e} > {:e} relative",
        what,
        got,
        want,
        err / want.length(),
        tol
    );
    Ok(())
}

/// Random records, the labels of parallel, zero and bad inputs, then the gather test on
/// random records and query points, within the bounds of the module docs.
pub fn matches_core(runner: &dyn KernelRunner) -> CaseResult {
    let pack = pack_matches_core(runner)?;
    parallel_zero_and_bad_inputs_are_labelled_like_core(runner)?;
    let gather = gather_matches_core(runner)?;
    let scales = footprint_scales_match_core(runner)?;
    let photons = photon_scales_match_core(runner)?;
    let moments = moments_match_core(runner)?;
    Ok(format!(
        "pack: {pack}; labels as the core; gather: {gather}; scales: {scales}; photon scales: {photons}; moments: {moments}"
    ))
}

fn pack_matches_core(runner: &dyn KernelRunner) -> Result<String, String> {
    let totals = Cell::new((0usize, 0usize));
    let worst_all = Cell::new(0.0f64);
    let strategy = prop::collection::vec(case(), ITEMS);
    proptest_batches("twin-footprint-pack", BATCHES, &strategy, |cases| {
        let out = run_prop(
            runner,
            "footprint pack",
            "",
            PACK_BODY,
            &pack_input(&cases),
            17,
            17,
        )?;
        let (mut ok, mut compared, mut worst) = (0, 0, 0.0f64);
        for (c, g) in cases.iter().zip(&out) {
            let fp = core_footprint(c);
            let want = fp.pack(c.radius as f64);
            let (ws, gs) = (status_of(&want), g[16]);
            if near_threshold(&fp) {
                continue;
            }
            compared += 1;
            prop_assert_eq!(gs, ws, "label of {:?}: twin {} core {:?}", c, gs, want);
            let Ok(p) = want else { continue };
            ok += 1;
            let tol = ROW_K * EPS * (1.0 + 1.0 / sin_theta(&fp));
            prop_assert_eq!(v3(g, 0), d3(p.center));
            prop_assert_eq!(g[3], p.map);
            check_close("row_u", v3(g, 4), d3(p.row_u), tol)?;
            check_close("row_v", v3(g, 8), d3(p.row_v), tol)?;
            // n/h: h = σ₂ = |D_u × D_v|/(2σ₁) where below the radius, whose f32 rounding is
            // relative ~ε/sin θ like the rows'.
            check_close("row_n", v3(g, 12), d3(p.row_n), 1e-5 + tol)?;
            let gd = DVec3::new(f(g[7]) as f64, f(g[11]) as f64, f(g[15]) as f64);
            let wd = p.flux_density().as_dvec3();
            for k in 0..3 {
                prop_assert!(
                    (gd[k] - wd[k]).abs() <= tol * wd[k].abs(),
                    "density {}: twin {} core {} ({:?})",
                    k,
                    gd[k],
                    wd[k],
                    c
                );
            }
            let rel = (v3(g, 4) - d3(p.row_u)).length() / d3(p.row_u).length();
            worst = worst.max(rel * sin_theta(&fp));
        }
        // The generator must exercise both outcomes, or the test proves little.
        prop_assert!(
            ok > cases.len() / 4 && ok < compared,
            "{} ok of {} compared",
            ok,
            compared
        );
        let (t_ok, t_compared) = totals.get();
        totals.set((t_ok + ok, t_compared + compared));
        worst_all.set(worst_all.get().max(worst));
        Ok(())
    })?;
    let (ok, compared) = totals.get();
    let worst = worst_all.get();
    Ok(format!(
        "{ok} ok of {compared} compared, worst row error x sin(theta) = {worst:.2e} ({:.1} eps)",
        worst / EPS
    ))
}

fn parallel_zero_and_bad_inputs_are_labelled_like_core(
    runner: &dyn KernelRunner,
) -> Result<(), String> {
    let base = Case {
        center: [0.5, 0.0, -0.25],
        normal: [0.0, 1.0, 0.0],
        du: [0.01, 0.0, 0.0],
        dv: [0.0, 0.0, 0.02],
        flux: [1.0, 2.0, 3.0],
        map: 1,
        radius: 0.01,
    };
    let cases = vec![
        base.clone(),
        Case {
            dv: [0.02, 0.0, 0.0],
            ..base.clone()
        }, // parallel (exactly, in f32 and f64)
        Case {
            dv: [0.0; 3],
            ..base.clone()
        }, // zero
        Case {
            du: [f32::NAN, 0.0, 0.0],
            ..base.clone()
        }, // not finite
        Case {
            du: [f32::INFINITY, 0.0, 0.0],
            ..base.clone()
        },
        Case {
            du: [1e-12, 0.0, 0.0],
            ..base.clone()
        }, // thinner than f32 resolves at x_p
        Case {
            flux: [1e-30, 0.0, 0.0],
            du: [1e10, 0.0, 0.0],
            dv: [0.0, 0.0, 1e10],
            center: [1e9, 0.0, 0.0],
            ..base.clone()
        }, // density underflows
    ];
    let out = run(
        runner,
        "footprint labels",
        PACK_BODY,
        &pack_input(&cases),
        17,
        17,
    )?;
    let labels: Vec<u32> = out.iter().map(|g| g[16]).collect();
    let core: Vec<u32> = cases
        .iter()
        .map(|c| status_of(&core_footprint(c).pack(c.radius as f64)))
        .collect();
    check!(labels == core, "labels: twin {labels:?}, core {core:?}");
    check!(
        labels == [0, 1, 1, 1, 1, 2, 2],
        "labels (valid, parallel, zero, NaN, inf, too thin, density underflow): twin {labels:?}, expected [0, 1, 1, 1, 1, 2, 2]"
    );
    Ok(())
}

/// A record from the core and query points around it (filter coordinates up to 1.4 in the
/// plane and 1.6 across the slab), both normal orientations, all kernels.
#[derive(Clone, Debug)]
struct Query {
    fp: PackedFootprint,
    q: [f32; 3],
    nq: [f32; 3],
    kernel: u32,
}

prop_compose! {
    fn query()(c in case(), x in -1.4f64..1.4, y in -1.4f64..1.4, z in -1.6f64..1.6, back in any::<bool>(), kernel in 0u32..3) -> Option<Query> {
        let fp = core_footprint(&c);
        let p = fp.pack(c.radius as f64).ok()?;
        let h = fp.half_thickness(c.radius as f64);
        let q = fp.center + 0.5 * x * fp.du + 0.5 * y * fp.dv + z * h * fp.normal;
        let nq = if back { -fp.normal } else { fp.normal };
        Some(Query { fp: p, q: f3(q), nq: f3(nq), kernel })
    }
}

prop_compose! {
    /// A query of [`query`]'s kind with its in-plane offset shrunk to the size of a random
    /// scale of the bandwidth ladder (`2^{−k/2}`), so that every scale sees lit points.
    fn scaled_query()(c in case(), x in -1.4f64..1.4, y in -1.4f64..1.4, z in -1.6f64..1.6, back in any::<bool>(), kernel in 0u32..3, k in 0usize..SCALES) -> Option<Query> {
        let fp = core_footprint(&c);
        let p = fp.pack(c.radius as f64).ok()?;
        let h = fp.half_thickness(c.radius as f64);
        let s = arpa_core::gather::scales::scale(k);
        let q = fp.center + 0.5 * s * x * fp.du + 0.5 * s * y * fp.dv + z * h * fp.normal;
        let nq = if back { -fp.normal } else { fp.normal };
        Some(Query { fp: p, q: f3(q), nq: f3(nq), kernel })
    }
}

const KERNELS: [Kernel; 3] = [Kernel::Constant, Kernel::Epanechnikov, Kernel::Silverman];

const GATHER_BODY: &str = "
    var fp: ArpaPackedFootprint;
    fp.center = in_v3(ib); fp.map = in_u(ib + 3u);
    fp.row_u = in_v3(ib + 4u); fp.flux_density_r = in_f(ib + 7u);
    fp.row_v = in_v3(ib + 8u); fp.flux_density_g = in_f(ib + 11u);
    fp.row_n = in_v3(ib + 12u); fp.flux_density_b = in_f(ib + 15u);
    let q = in_v3(ib + 16u);
    let nq = in_v3(ib + 19u);
    let kernel = in_u(ib + 22u);
    out_v3(ob, arpa_footprint_filter_coords(fp, q));
    out_u(ob + 3u, u32(arpa_footprint_contains(fp, q)));
    out_u(ob + 4u, u32(arpa_footprint_faces(fp, nq)));
    out_v3(ob + 5u, arpa_footprint_irradiance(fp, q, nq, kernel));
    out_f(ob + 8u, arpa_kernel_eval(kernel, in_f(ib + 23u)));";

fn gather_matches_core(runner: &dyn KernelRunner) -> Result<String, String> {
    let totals = Cell::new((0usize, 0usize, 0usize));
    let strategy = (
        prop::collection::vec(query(), ITEMS),
        prop::collection::vec(-0.5f32..1.5, ITEMS),
    );
    proptest_batches(
        "twin-footprint-gather",
        BATCHES,
        &strategy,
        |(queries, r2s)| {
            let qs: Vec<(Query, f32)> = queries
                .into_iter()
                .zip(r2s)
                .filter_map(|(q, r2)| q.map(|q| (q, r2)))
                .collect();
            prop_assert!(qs.len() > 1000, "only {} packable footprints", qs.len());
            let mut input = Vec::new();
            for (q, r2) in &qs {
                input.extend_from_slice(bytemuck::cast_slice::<PackedFootprint, u32>(
                    std::slice::from_ref(&q.fp),
                ));
                push3(&mut input, q.q);
                push3(&mut input, q.nq);
                input.push(q.kernel);
                input.push(fb(*r2));
            }
            let out = run_prop(runner, "footprint gather", "", GATHER_BODY, &input, 24, 9)?;
            let (mut inside, mut decided) = (0, 0);
            for ((q, kr2), g) in qs.iter().zip(&out) {
                let (qv, nq) = (Vec3::from_array(q.q), Vec3::from_array(q.nq));
                let kernel = KERNELS[q.kernel as usize];
                let y = q.fp.filter_coords(qv);
                let delta = (qv - Vec3::from_array(q.fp.center)).as_dvec3().length();
                let rows = [q.fp.row_u, q.fp.row_v, q.fp.row_n].map(|r| d3(r).length());
                let gy = v3(g, 0);
                for k in 0..3 {
                    let tol = 4.0 * EPS * rows[k] * delta + f64::from(f32::MIN_POSITIVE);
                    prop_assert!(
                        (gy[k] - y[k] as f64).abs() <= tol,
                        "filter coordinate {}: twin {} core {} ({:?})",
                        k,
                        gy[k],
                        y[k],
                        q
                    );
                }
                prop_assert_eq!(g[4] == 1, q.fp.faces(nq));
                let r2 = (y.x * y.x + y.y * y.y) as f64;
                let margin_r2 = 2.0
                    * (y.x.abs() as f64 + y.y.abs() as f64 + 1.0)
                    * 4.0
                    * EPS
                    * (rows[0] + rows[1])
                    * delta;
                let margin_z = 4.0 * EPS * rows[2] * delta;
                let decisive = (r2 - 1.0).abs() > margin_r2 + 4.0 * EPS
                    && ((y.z.abs() as f64) - 1.0).abs() > margin_z + 2.0 * EPS;
                if decisive {
                    decided += 1;
                    prop_assert_eq!(g[3] == 1, q.fp.contains(qv), "containment of {:?}", q);
                    let want = q.fp.irradiance(qv, nq, kernel).as_dvec3();
                    let got = v3(g, 5);
                    let dens = q.fp.flux_density().as_dvec3();
                    for k in 0..3 {
                        let tol = dens[k].abs() * (1e-6 + 2.0 * margin_r2);
                        prop_assert!(
                            (got[k] - want[k]).abs() <= tol,
                            "irradiance {}: twin {} core {} ({:?})",
                            k,
                            got[k],
                            want[k],
                            q
                        );
                    }
                    if q.fp.contains(qv) {
                        inside += 1;
                    }
                }
                let kv = kernel.eval(*kr2) as f64;
                prop_assert!(
                    (f(g[8]) as f64 - kv).abs() <= 1e-6 * kernel.peak(),
                    "kernel {:?}({}): twin {} core {}",
                    kernel,
                    kr2,
                    f(g[8]),
                    kv
                );
            }
            prop_assert!(
                inside > decided / 10 && inside < decided,
                "{} inside of {} decided",
                inside,
                decided
            );
            let (t_q, t_d, t_i) = totals.get();
            totals.set((t_q + qs.len(), t_d + decided, t_i + inside));
            Ok(())
        },
    )?;
    let (queries, decided, inside) = totals.get();
    Ok(format!(
        "{queries} queries, {decided} decided, {inside} inside"
    ))
}

const SCALES_BODY: &str = "
    var fp: ArpaPackedFootprint;
    fp.center = in_v3(ib); fp.map = in_u(ib + 3u);
    fp.row_u = in_v3(ib + 4u); fp.flux_density_r = in_f(ib + 7u);
    fp.row_v = in_v3(ib + 8u); fp.flux_density_g = in_f(ib + 11u);
    fp.row_n = in_v3(ib + 12u); fp.flux_density_b = in_f(ib + 15u);
    let e = arpa_footprint_irradiance_scales(fp, in_v3(ib + 16u), in_v3(ib + 19u), in_u(ib + 22u), ARPA_SCALES);
    for (var k = 0u; k < ARPA_SCALES; k++) {
        out_v3(ob + 3u * k, e[k]);
    }";

/// `arpa_footprint_irradiance_scales` against `PackedFootprint::irradiance_scales` on the
/// gather's random records and query points (module docs' bound).
fn footprint_scales_match_core(runner: &dyn KernelRunner) -> Result<String, String> {
    let totals = Cell::new((0usize, [0usize; SCALES]));
    let strategy = prop::collection::vec(scaled_query(), ITEMS);
    proptest_batches("twin-footprint-scales", BATCHES, &strategy, |queries| {
        let qs: Vec<Query> = queries.into_iter().flatten().collect();
        prop_assert!(qs.len() > 1000, "only {} packable footprints", qs.len());
        let mut input = Vec::new();
        for q in &qs {
            input.extend_from_slice(bytemuck::cast_slice::<PackedFootprint, u32>(std::slice::from_ref(&q.fp)));
            push3(&mut input, q.q);
            push3(&mut input, q.nq);
            input.push(q.kernel);
        }
        let out = run_prop(runner, "footprint scales", "", SCALES_BODY, &input, 23, 3 * SCALES)?;
        let mut lit = [0usize; SCALES];
        for (q, g) in qs.iter().zip(&out) {
            let (qv, nq) = (Vec3::from_array(q.q), Vec3::from_array(q.nq));
            let kernel = KERNELS[q.kernel as usize];
            let y = q.fp.filter_coords(qv);
            let delta = (qv - Vec3::from_array(q.fp.center)).as_dvec3().length();
            let rows = [q.fp.row_u, q.fp.row_v, q.fp.row_n].map(|r| d3(r).length());
            let r2 = (y.x * y.x + y.y * y.y) as f64;
            let margin_r2 = 2.0 * (y.x.abs() as f64 + y.y.abs() as f64 + 1.0) * 4.0 * EPS * (rows[0] + rows[1]) * delta;
            let margin_z = 4.0 * EPS * rows[2] * delta;
            let stored = (r2 - 1.0).abs() > margin_r2 + 4.0 * EPS && ((y.z.abs() as f64) - 1.0).abs() > margin_z + 2.0 * EPS;
            if !stored {
                continue;
            }
            let want = q.fp.irradiance_scales(qv, nq, kernel);
            let dens = q.fp.flux_density().as_dvec3();
            for k in 0..SCALES {
                let f = f64::from(inv_scale2(k));
                if k > 0 && (r2 * f - 1.0).abs() <= f * margin_r2 + 4.0 * EPS {
                    continue;
                }
                let got = v3(g, 3 * k);
                let w = want[k].as_dvec3();
                for c in 0..3 {
                    let tol = dens[c].abs() * f * (1e-6 + 2.0 * f * margin_r2);
                    prop_assert!(
                        (got[c] - w[c]).abs() <= tol,
                        "scale {} irradiance {}: twin {} core {} ({:?})",
                        k,
                        c,
                        got[c],
                        w[c],
                        q
                    );
                }
                lit[k] += (w != DVec3::ZERO) as usize;
            }
        }
        // Every scale must see lit points, fewer at the smaller scales.
        prop_assert!(lit[SCALES - 1] >= 4 && lit[SCALES - 1] < lit[0], "lit points per scale {:?}", lit);
        let (n, l) = totals.get();
        totals.set((n + qs.len(), std::array::from_fn(|k| l[k] + lit[k])));
        Ok(())
    })?;
    let (n, lit) = totals.get();
    Ok(format!("{n} queries, lit per scale {lit:?}"))
}

/// A progressive photon and a query point around it (distance up to 1.3 radii, both sides).
#[derive(Clone, Debug)]
struct PhotonQuery {
    ph: PackedPhoton,
    radius: f32,
    q: [f32; 3],
    nq: [f32; 3],
}

prop_compose! {
    fn photon_query()(
        p_dir in (0.0..std::f64::consts::PI, 0.0..std::f64::consts::TAU), p_exp in -3.0f64..4.0,
        n_dir in (0.0..std::f64::consts::PI, 0.0..std::f64::consts::TAU),
        q_dir in (0.0..std::f64::consts::PI, 0.0..std::f64::consts::TAU), dist in 0.0f64..1.3,
        // Radii of 1e-25 m and below (r² underflows to 0 in f32, on every device: no
        // density), and from 1e-6 to 10 m (r² normal in f32).
        r_exp in prop_oneof![1 => -26.0f64..-25.0, 9 => -6.0f64..1.0],
        flux in prop::array::uniform3(prop_oneof![1 => Just(0.0f64), 7 => (-10.0f64..10.0).prop_map(|e| 10f64.powf(e))]),
        back in any::<bool>(), map in 0u32..2,
    ) -> PhotonQuery {
        let position = unit(p_dir.0, p_dir.1) * 10f64.powf(p_exp);
        let n = unit(n_dir.0, n_dir.1);
        let r = 10f64.powf(r_exp);
        // A query normal within 60° of ±n: the side test is decided.
        let t = n.any_orthonormal_vector();
        let nq = (n + t * (0.5 * (q_dir.1 / std::f64::consts::TAU - 0.5))).normalize() * if back { -1.0 } else { 1.0 };
        let q = position + unit(q_dir.0, q_dir.1) * (dist * r);
        let ph = PackedPhoton { position: f3(position), map, normal: f3(n), flux: flux.map(|x| x as f32), ..PackedPhoton::default() };
        PhotonQuery { ph, radius: r as f32, q: f3(q), nq: f3(nq) }
    }
}

const PHOTON_SCALES_BODY: &str = "
    let e = arpa_photon_irradiance_scales(in_v3(ib), in_v3(ib + 3u), in_v3(ib + 6u), in_v3(ib + 9u), in_v3(ib + 12u), in_f(ib + 15u), ARPA_SCALES);
    for (var k = 0u; k < ARPA_SCALES; k++) {
        out_v3(ob + 3u * k, e[k]);
    }";

/// `arpa_photon_irradiance_scales` against `PackedPhoton::irradiance_scales` (module docs'
/// bound).
fn photon_scales_match_core(runner: &dyn KernelRunner) -> Result<String, String> {
    let totals = Cell::new((0usize, [0usize; SCALES]));
    let strategy = prop::collection::vec(photon_query(), ITEMS);
    proptest_batches("twin-footprint-photon-scales", BATCHES, &strategy, |queries| {
        let mut input = Vec::new();
        for q in &queries {
            for v in [q.ph.position, q.ph.normal, q.ph.flux, q.q, q.nq] {
                push3(&mut input, v);
            }
            input.push(fb(q.radius));
        }
        let out = run_prop(runner, "photon scales", "", PHOTON_SCALES_BODY, &input, 16, 3 * SCALES)?;
        let mut lit = [0usize; SCALES];
        for (q, g) in queries.iter().zip(&out) {
            let (qv, nq) = (Vec3::from_array(q.q), Vec3::from_array(q.nq));
            let want = q.ph.irradiance_scales(qv, nq, q.radius);
            let r = f64::from(q.radius);
            let d2 = (qv - Vec3::from_array(q.ph.position)).as_dvec3().length_squared() / (r * r);
            for k in 0..SCALES {
                let f = f64::from(inv_scale2(k));
                let w = want[k].as_dvec3();
                // The density and the product near the f32 range's ends are rounding's call.
                let density = std::f64::consts::FRAC_1_PI / (r * r) * f;
                let product = d3(q.ph.flux).abs().max_element() * density;
                let near_range = |x: f64| x > 0.0 && ((x / f32::MAX as f64).ln().abs() < 1e-4 || (x / f32::MIN_POSITIVE as f64).ln().abs() < 1e-4);
                if (d2 * f - 1.0).abs() <= 1e-5 || near_range(density) || near_range(product) {
                    continue;
                }
                let got = v3(g, 3 * k);
                for c in 0..3 {
                    prop_assert!(
                        (got[c] - w[c]).abs() <= 8.0 * EPS * w[c].abs(),
                        "scale {} photon irradiance {}: twin {} core {} ({:?})",
                        k,
                        c,
                        got[c],
                        w[c],
                        q
                    );
                }
                lit[k] += (w != DVec3::ZERO) as usize;
            }
        }
        prop_assert!(lit[SCALES - 1] > queries.len() / 20 && lit[SCALES - 1] < lit[0] && lit[0] < queries.len(), "lit per scale {:?} of {}", lit, queries.len());
        let (n, l) = totals.get();
        totals.set((n + queries.len(), std::array::from_fn(|k| l[k] + lit[k])));
        Ok(())
    })?;
    let (n, lit) = totals.get();
    Ok(format!("{n} queries, lit per scale {lit:?}"))
}

const MOMENTS_BODY: &str = "
    var l: array<vec3<f32>, ARPA_SCALES>;
    for (var k = 0u; k < ARPA_SCALES; k++) {
        l[k] = in_v3(ib + 3u * k);
        out_f(ob + k, arpa_luminance(l[k]));
    }
    let m = arpa_moments(l);
    for (var p = 0u; p < ARPA_MOMENT_PLANES; p++) {
        out_v3(ob + ARPA_SCALES + 3u * p, m[p]);
    }";

/// `arpa_luminance` and `arpa_moments` against `bandwidth::luminance` and `moments` on
/// random per-scale radiance (magnitudes over 1e-12 … 1e12, zeros, equal scales).
fn moments_match_core(runner: &dyn KernelRunner) -> Result<String, String> {
    let count = Cell::new(0usize);
    let component = prop_oneof![1 => Just(0.0f32), 6 => (-12.0f64..12.0).prop_map(|e| 10f64.powf(e) as f32)];
    let radiance = prop::array::uniform3(component).prop_map(Vec3::from_array);
    let item = (prop::collection::vec(radiance, SCALES), any::<bool>()).prop_map(|(v, equal)| {
        let mut l: [Vec3; SCALES] = std::array::from_fn(|k| v[k]);
        // Equal neighbours: differences of exactly zero.
        if equal {
            l[SCALES - 1] = l[SCALES - 2];
        }
        l
    });
    let strategy = prop::collection::vec(item, ITEMS);
    proptest_batches("twin-footprint-moments", BATCHES, &strategy, |items| {
        let mut input = Vec::new();
        for l in &items {
            for c in l {
                push3(&mut input, c.to_array());
            }
        }
        let out = run_prop(runner, "moments", "", MOMENTS_BODY, &input, 3 * SCALES, 3 * SCALES - 1)?;
        for (l, g) in items.iter().zip(&out) {
            let big: [f64; SCALES] = std::array::from_fn(|k| (0.2126 * l[k].x as f64 + 0.7152 * l[k].y as f64 + 0.0722 * l[k].z as f64).abs());
            for k in 0..SCALES {
                let (got, want) = (f(g[k]) as f64, luminance(l[k]) as f64);
                prop_assert!((got - want).abs() <= 3.0 * EPS * big[k], "luminance of {:?}: twin {} core {}", l[k], got, want);
            }
            let want = moments(l);
            for v in 0..3 * want.len() {
                let scale = if v < SCALES { big[v] * big[v] } else { (big[v - SCALES] + big[v - SCALES + 1]).powi(2) };
                let (got, w) = (f(g[SCALES + v]) as f64, want[v / 3][v % 3] as f64);
                prop_assert!((got - w).abs() <= 8.0 * EPS * scale, "moment {} of {:?}: twin {} core {}", v, l, got, w);
            }
        }
        count.set(count.get() + items.len());
        Ok(())
    })?;
    Ok(format!("{} radiance ladders", count.get()))
}
