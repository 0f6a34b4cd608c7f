//! The ray-query gather (the core's `gather.wgsl` with arpa-wgpu's box traversal, run by
//! `support::gather` on host records) against the core's brute-force gather
//! (`IrradianceEstimate::add_footprint` over every footprint, f64 sums): thousands of
//! overlapping footprints of both maps on two facing planes, queries on both planes and on
//! their back sides, all kernels.
//!
//! Bound: each contribution is the same f32 expression on both sides (up to FMA
//! contraction), the device sums in f32: per map within `64 ε Σ|Φ W|`, plus, for every
//! footprint whose boundary the query lies within 1e-4 (filter-space r² or slab) of, that
//! footprint's density times the kernel's largest value there (its outcome may flip). The
//! number of contributing footprints agrees up to those boundary cases.


use arpa_core::estimate::{IrradianceEstimate, QueryPoint};
use arpa_core::footprint::{Footprint, PackedFootprint, PhotonMap};
use arpa_core::kernel::Kernel;
use arpa_core::rng::{Rng, StreamDomain};
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

fn scene(seed: u32, n: usize) -> (Vec<PackedFootprint>, Vec<arpa_core::aabb::Aabb>) {
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

pub(crate) fn check(fps: &[PackedFootprint], qs: &[QueryPoint], got: &[GatherResult], kernel: Kernel) -> Result<(usize, usize), TestCaseError> {
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
        let got = gather(ctx, &fps, &boxes, &qs, kernel);
        let (contributions, lit) = check(&fps, &qs, &got, kernel)?;
        // Dense overlap, and both lit and unlit (back-side) queries.
        prop_assert!(contributions > 2 * qs.len() && lit > qs.len() / 2 && lit < qs.len(), "{} contributions, {} lit queries", contributions, lit);
    }
}

/// One map empty, and no footprints at all: zero irradiance, no error.
#[test]
fn empty_maps() {
    let Some(ctx) = gpu() else { return };
    let (fps, boxes) = scene(7, 500);
    let qs = queries(7, 500);
    let (caustic, cboxes): (Vec<_>, Vec<_>) = fps.iter().zip(&boxes).filter(|(f, _)| f.map == 0).map(|(f, b)| (*f, *b)).unzip();
    let got = gather(ctx, &caustic, &cboxes, &qs, Kernel::Silverman);
    assert!(got.iter().all(|g| g.global == [0.0; 3] && g.global_count == 0));
    check(&caustic, &qs, &got, Kernel::Silverman).unwrap();
    assert!(got.iter().any(|g| g.caustic_count > 0));
    let none = gather(ctx, &[], &[], &qs, Kernel::Silverman);
    assert!(none.iter().all(|g| *g == Default::default()));
}
