//! The ray-query gather (the core's `gather.wgsl` with arpa-wgpu's box traversal, run by
//! `support::gather` on host records) against the core's brute-force gather
//! (`IrradianceEstimate::add_footprint` over every footprint, and at every scale of the
//! bandwidth ladder `gather_brute_force_scales`, f64 sums): thousands of overlapping
//! footprints of both maps on two facing planes, queries on both planes and on their back
//! sides, all kernels, one scale and all five.
//!
//! Bound: each contribution is the same f32 expression on both sides (up to FMA
//! contraction), the device sums in f32: per map (stored scale) and per scale (both maps)
//! within `64 ε Σ|Φ W_k|`, plus, for every record whose boundary at that scale the query
//! lies within 1e-4 of (filter-space `r²` or slab of the stored ellipse, `2^k r²` of the
//! scaled one; `2^k d²/r²` of a photon), that record's density times the scale's weight
//! there (its outcome may flip). The number of contributing footprints agrees up to those
//! boundary cases. The stored scale does not depend on how many scales are evaluated: the
//! per-map sums and counts of a five-scale gather are bit for bit the one-scale gather's.


use arpa_core::gather::scales::{SCALES, inv_scale2};
use arpa_core::gather::estimate::{IrradianceEstimate, QueryPoint, gather_brute_force_scales};
use arpa_core::store::footprint::{Footprint, PackedFootprint, PhotonMap};
use arpa_core::gather::kernel::Kernel;
use arpa_core::store::progressive_photon::PackedPhoton;
use arpa_core::base::rng::{Rng, StreamDomain};
use arpa_core::gpu::layout::GatherResult;
use crate::common::*;
use crate::support::gather;
use glam::{DVec3, Vec3};
use proptest::prelude::*;

const EPS: f64 = f32::EPSILON as f64;

/// Plane k: z = 0.3 k, facing +z (k = 0) or −z (k = 1).
fn plane(k: usize) -> (f64, DVec3) {
    (0.3 * k as f64, if k == 0 { DVec3::Z } else { -DVec3::Z })
}

fn scene(seed: u32, n: usize) -> (Vec<PackedFootprint>, Vec<arpa_core::base::aabb::Aabb>) {
    let mut rng = Rng::new(seed, 0, 0, StreamDomain::User);
    let (mut fps, mut boxes) = (Vec::new(), Vec::new());
    while fps.len() < n {
        let k = (rng.next_u32() % 2) as usize;
        let (z, normal) = plane(k);
        let c = DVec3::new(rng.next_f64() - 0.5, rng.next_f64() - 0.5, z);
        let a = rng.next_f64() * std::f64::consts::TAU;
        let b = a + 0.3 + 2.5 * rng.next_f64();
        let (la, lb) = (0.02 + 0.15 * rng.next_f64(), 0.02 + 0.15 * rng.next_f64());
        let fp = Footprint {
            center: c,
            normal,
            du: DVec3::new(a.cos(), a.sin(), 0.0) * la,
            dv: DVec3::new(b.cos(), b.sin(), 0.0) * lb,
            flux: DVec3::new(rng.next_f64(), rng.next_f64(), rng.next_f64()) * 1e-3,
            map: if rng.next_u32().is_multiple_of(3) { PhotonMap::Caustic } else { PhotonMap::Global },
        };
        let radius = 0.05;
        if let Ok(p) = fp.pack(radius) {
            fps.push(p);
            boxes.push(fp.aabb(radius));
        }
    }
    (fps, boxes)
}

pub(crate) fn queries(seed: u32, n: usize) -> Vec<QueryPoint> {
    let mut rng = Rng::new(seed, 1, 0, StreamDomain::User);
    (0..n)
        .map(|_| {
            let k = (rng.next_u32() % 2) as usize;
            let (z, normal) = plane(k);
            // A quarter of the queries look at the planes' back sides.
            let back = rng.next_u32().is_multiple_of(4);
            let p = DVec3::new(1.2 * (rng.next_f64() - 0.5), 1.2 * (rng.next_f64() - 0.5), z);
            QueryPoint { position: p.as_vec3(), normal: (if back { -normal } else { normal }).as_vec3() }
        })
        .collect()
}

/// Per scale of the ladder at `q`: `Σ|e_k|` over the records' contributions (W/m², largest
/// component) and the slack of the records whose scale-`k` boundary `q` lies within 1e-4 of
/// (their density times the scale's weight near the boundary: their outcome may flip).
pub(crate) fn scale_bounds(q: &QueryPoint, fps: &[PackedFootprint], phs: &[PackedPhoton], radii: [f32; 2], kernel: Kernel) -> [(f64, f64); SCALES] {
    let mut out = [(0.0f64, 0.0f64); SCALES];
    for fp in fps {
        let e = fp.irradiance_scales(q.position, q.normal, kernel);
        let y = fp.filter_coords(q.position);
        let r2 = (y.x * y.x + y.y * y.y) as f64;
        let near_stored = (r2 - 1.0).abs() < 1e-4 || ((y.z.abs() as f64) - 1.0).abs() < 1e-4;
        let density = fp.flux_density().as_dvec3().abs().max_element();
        for (k, (abs, slack)) in out.iter_mut().enumerate() {
            let f = f64::from(inv_scale2(k));
            *abs += e[k].abs().max_element() as f64;
            if fp.faces(q.normal) && (near_stored || (r2 * f - 1.0).abs() < 1e-4 * f) {
                *slack += density * f * kernel.eval_f64(((r2 * f).min(1.0) - 1e-4 * f).max(0.0));
            }
        }
    }
    for ph in phs {
        let r = f64::from(radii[ph.photon_map().index()]);
        let e = ph.irradiance_scales(q.position, q.normal, r as f32);
        let d2 = (q.position - Vec3::from_array(ph.position)).length_squared() as f64 / (r * r);
        let lit = Vec3::from_array(ph.normal).dot(q.normal) > 0.0;
        for (k, (abs, slack)) in out.iter_mut().enumerate() {
            let f = f64::from(inv_scale2(k));
            *abs += e[k].abs().max_element() as f64;
            if lit && (d2 * f - 1.0).abs() < 1e-4 {
                *slack += Vec3::from_array(ph.flux).abs().max_element() as f64 * f / (std::f64::consts::PI * r * r);
            }
        }
    }
    out
}

/// The device's per-scale totals of `g` (scales `1..`) against the core's over the same
/// records within the bound of the module docs; the scales from `scales` on must be zero.
pub(crate) fn check_scales(q: &QueryPoint, fps: &[PackedFootprint], phs: &[PackedPhoton], radii: [f32; 2], kernel: Kernel, g: &GatherResult, scales: usize) -> Result<(), TestCaseError> {
    let want = gather_brute_force_scales(q, fps, phs, radii.map(f64::from), kernel);
    let bounds = scale_bounds(q, fps, phs, radii, kernel);
    for (k, &(abs, slack)) in bounds.iter().enumerate().skip(1) {
        let got = g.scale(k).as_dvec3();
        prop_assert!(g.scaled[k - 1][3] == 0.0, "scale {}: fourth word {}", k, g.scaled[k - 1][3]);
        if k >= scales {
            prop_assert!(got == DVec3::ZERO, "scale {} not evaluated but {:?} at {:?}", k, got, q);
            continue;
        }
        let tol = 64.0 * EPS * abs + slack + 1e-30;
        let diff = (got - want.per_scale[k]).abs().max_element();
        prop_assert!(diff <= tol, "scale {}: device {:?} core {:?} (diff {:e} > {:e}) at {:?}", k, got, want.per_scale[k], diff, tol, q);
    }
    Ok(())
}

pub(crate) fn check(fps: &[PackedFootprint], qs: &[QueryPoint], got: &[GatherResult], kernel: Kernel, scales: usize) -> Result<(usize, usize), TestCaseError> {
    let (mut contributions, mut lit) = (0usize, 0usize);
    for (q, g) in qs.iter().zip(got) {
        let mut est = IrradianceEstimate::default();
        let mut abs = [DVec3::ZERO; 2];
        let mut slack = [0.0f64; 2];
        let mut near = 0u32;
        for fp in fps {
            let e = fp.irradiance(q.position, q.normal, kernel);
            let m = fp.photon_map().index();
            abs[m] += e.abs().as_dvec3();
            est.add_footprint(fp, q, kernel);
            let y = fp.filter_coords(q.position);
            let r2 = (y.x * y.x + y.y * y.y) as f64;
            if fp.faces(q.normal) && ((r2 - 1.0).abs() < 1e-4 || ((y.z.abs() as f64) - 1.0).abs() < 1e-4) {
                near += 1;
                let k_near = kernel.eval_f64((r2.min(1.0) - 1e-4).max(0.0));
                slack[m] += fp.flux_density().as_dvec3().abs().max_element() * k_near;
            }
        }
        let got_maps = [Vec3::from_array(g.caustic).as_dvec3(), Vec3::from_array(g.global).as_dvec3()];
        for m in 0..2 {
            let tol = 64.0 * EPS * abs[m].max_element() + slack[m] + 1e-30;
            let diff = (got_maps[m] - est.per_map[m]).abs().max_element();
            prop_assert!(diff <= tol, "map {}: device {:?} core {:?} (diff {:e} > {:e}) at {:?}", m, got_maps[m], est.per_map[m], diff, tol, q);
        }
        // Every contributing record was a candidate; every candidate is a record.
        for (m, c) in [g.caustic_count, g.global_count].into_iter().enumerate() {
            prop_assert!(c <= g.candidates[m] && g.candidates[m] as usize <= fps.len(), "map {}: {} contributions, {} candidates of {} records at {:?}", m, c, g.candidates[m], fps.len(), q);
        }
        let count = g.caustic_count + g.global_count;
        prop_assert!(count.abs_diff(est.footprints) <= near, "contributing footprints: device {} core {} ({} near a boundary) at {:?}", count, est.footprints, near, q);
        check_scales(q, fps, &[], [0.0; 2], kernel, g, scales)?;
        contributions += est.footprints as usize;
        lit += (est.footprints > 0) as usize;
    }
    Ok((contributions, lit))
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 3, max_shrink_iters: 8, ..ProptestConfig::default() })]

    #[test]
    fn gather_matches_brute_force(seed in any::<u32>(), kernel in 0usize..3) {
        let Some(ctx) = gpu() else { return Ok(()) };
        let kernel = [Kernel::Constant, Kernel::Epanechnikov, Kernel::Silverman][kernel];
        let (fps, boxes) = scene(seed, 3000);
        let qs = queries(seed, 4000);
        let got = gather(ctx, &fps, &boxes, &qs, kernel, SCALES as u32);
        let (contributions, lit) = check(&fps, &qs, &got, kernel, SCALES)?;
        // Dense overlap, and both lit and unlit (back-side) queries.
        prop_assert!(contributions > 2 * qs.len() && lit > qs.len() / 2 && lit < qs.len(), "{} contributions, {} lit queries", contributions, lit);
        // The smallest scale still sees contributions (and fewer than the stored one).
        let smallest = got.iter().filter(|g| g.scale(SCALES - 1) != Vec3::ZERO).count();
        prop_assert!(smallest > qs.len() / 10 && smallest < lit, "{} queries lit at the smallest scale, {} at the stored one", smallest, lit);
        // One scale: the stored scale's sums and counts bit for bit, nothing else.
        let one = gather(ctx, &fps, &boxes, &qs, kernel, 1);
        for (a, b) in got.iter().zip(&one) {
            prop_assert!(b.scaled == [[0.0; 4]; SCALES - 1], "one scale evaluated more: {:?}", b);
            let stored = |g: &GatherResult| (g.caustic.map(f32::to_bits), g.global.map(f32::to_bits), g.caustic_count, g.global_count, g.candidates);
            prop_assert!(stored(a) == stored(b), "stored scale differs with five scales: {:?} vs {:?}", a, b);
        }
    }
}

/// One map empty, and no footprints at all: zero irradiance, no error.
#[test]
fn empty_maps() {
    let Some(ctx) = gpu() else { return };
    let (fps, boxes) = scene(7, 500);
    let qs = queries(7, 500);
    let (caustic, cboxes): (Vec<_>, Vec<_>) = fps.iter().zip(&boxes).filter(|(f, _)| f.map == 0).map(|(f, b)| (*f, *b)).unzip();
    let got = gather(ctx, &caustic, &cboxes, &qs, Kernel::Silverman, SCALES as u32);
    assert!(got.iter().all(|g| g.global == [0.0; 3] && g.global_count == 0));
    check(&caustic, &qs, &got, Kernel::Silverman, SCALES).unwrap();
    assert!(got.iter().any(|g| g.caustic_count > 0));
    let none = gather(ctx, &[], &[], &qs, Kernel::Silverman, SCALES as u32);
    assert!(none.iter().all(|g| *g == Default::default()));
}
