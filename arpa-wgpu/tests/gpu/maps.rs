//! The tracer's device chain (`arpa_wgpu::maps`: keyed store → sort → compaction → AABB
//! build → image gather → running mean, run by `support::run_from_host`) on raw footprints
//! and photons uploaded as a photon pass would append them, against the core:
//! * every raw footprint's outcome (footprint or progressive fallback, per map) is
//!   `store_footprint`'s after the map's smoothing (applied by the photon pass, so
//!   here by the test in f32), except within 1e-3 of a heuristic threshold (as in `store`);
//!   a footprint handed over with its normal flipped (below the shading plane) comes out
//!   as the core's record or photon of the unflipped one with the orientation flipped
//!   (`orient_to_shading_side`); photons pass through unchanged;
//! * the outputs are sorted by map, photons by Morton code within a map;
//! * each pixel is `radiance + weight · E` with `E` the brute-force gather
//!   (`gather_brute_force`, f64) over the device's own records, within the `gather` test's
//!   bound (64 ε Σ|contributions| plus the contributions of records whose boundary the
//!   query lies within 1e-4 of); invalid records give their radiance, non-finite ones 0;
//! * the running mean of n equal images is the image (compensated sum, within 2 ε);
//! * appending in another order gives bit-identical records, photons and image.

use crate::common::*;
use crate::store::{core_footprint, near_threshold, raw, scene_bounds};
use arpa_core::classify::Smoothing;
use arpa_core::estimate::{QueryPoint, gather_brute_force};
use arpa_core::footprint::PhotonMap;
use arpa_core::heuristics::Heuristics;
use arpa_core::kernel::Kernel;
use arpa_core::progressive_photon::PackedPhoton;
use arpa_core::rng::{Rng, StreamDomain};
use arpa_core::store::{StoredPhoton, store_footprint};
use arpa_core::tracer::QueryRecord;
use crate::support::{HostRun, run_from_host};
use arpa_core::gpu::layout::{KeyedFootprint, KeyedPhoton, RawFootprint, StoreSettings};
use arpa_core::gpu::morton::morton_code;
use glam::{DVec3, Vec3};

const RADII: [f32; 2] = [0.02, 0.05];
const SMOOTHING: [f32; 2] = [0.8, 1.3];
const EPS: f64 = f32::EPSILON as f64;

struct Input {
    /// Before smoothing and flip (what the core takes), with the flip flag.
    unsmoothed: Vec<(RawFootprint, bool)>,
    raw: Vec<KeyedFootprint>,
    photons: Vec<KeyedPhoton>,
    records: Vec<QueryRecord>,
}

fn input(seed: u32) -> Input {
    let mut rng = Rng::new(seed, 7, 0, StreamDomain::User);
    let unsmoothed: Vec<(RawFootprint, bool)> = raw(seed, 3000).into_iter().map(|r| (r, rng.next_u32().is_multiple_of(5))).collect();
    let raw = unsmoothed
        .iter()
        .enumerate()
        .map(|(i, (r, flip))| {
            let s = SMOOTHING[r.map as usize];
            let sign = if *flip { -1.0 } else { 1.0 };
            let footprint = RawFootprint { du: r.du.map(|x| x * s), dv: r.dv.map(|x| x * s), normal: r.normal.map(|x| sign * x), ..*r };
            KeyedFootprint { footprint, key: 2 * i as u32 + 1, pad: [0; 3] }
        })
        .collect();
    let photons = (0..1500u32)
        .map(|i| {
            let k = rng.next_u32() % 2;
            let (z, nz) = if k == 0 { (0.0, 1.0) } else { (0.3, -1.0) };
            let f = |v: f64| v as f32;
            let ph = PackedPhoton {
                position: [f(rng.next_f64() - 0.5), f(rng.next_f64() - 0.5), z],
                map: rng.next_u32() % 2,
                normal: [0.0, 0.0, nz],
                flux: [f(rng.next_f64() * 1e-3), f(rng.next_f64() * 1e-3), f(rng.next_f64() * 1e-3)],
                ..Default::default()
            };
            KeyedPhoton { photon: ph, key: 2 * i, pad: [0; 3] }
        })
        .collect();
    let records = (0..4000u32)
        .map(|i| {
            let k = rng.next_u32() % 2;
            let (z, nz) = if k == 0 { (0.0f32, 1.0f32) } else { (0.3, -1.0) };
            let back = rng.next_u32().is_multiple_of(4);
            let valid = !rng.next_u32().is_multiple_of(8);
            let mut radiance = [rng.next_f64() as f32 * 0.1, 0.0, 0.05];
            if i % 401 == 0 {
                radiance[1] = f32::NAN;
            }
            QueryRecord {
                position: [1.2 * (rng.next_f64() as f32 - 0.5), 1.2 * (rng.next_f64() as f32 - 0.5), z],
                pixel: i,
                normal: [0.0, 0.0, if back { -nz } else { nz }],
                valid: valid as u32,
                weight: [rng.next_f64() as f32 * 0.3, rng.next_f64() as f32 * 0.3, rng.next_f64() as f32 * 0.3],
                radiance,
                ..Default::default()
            }
        })
        .collect();
    Input { unsmoothed, raw, photons, records }
}

fn settings(input: &Input) -> StoreSettings {
    let b = scene_bounds();
    StoreSettings {
        heuristics: Heuristics::default().resolve(&b).pack(),
        radii: RADII,
        bounds: (b.min.as_vec3().to_array(), b.max.as_vec3().to_array()),
        raw_count: input.raw.len() as u32,
        photon_count: input.photons.len() as u32,
    }
}

fn run(ctx: &arpa_wgpu::GpuContext, input: &Input, kernel: Kernel) -> HostRun {
    run_from_host(ctx, &input.raw, &input.photons, &settings(input), &input.records, kernel, 3)
}

#[test]
fn chain_matches_core() {
    let Some(ctx) = gpu() else { return };
    let kernel = Kernel::Epanechnikov;
    let input = input(11);
    let out = run(ctx, &input, kernel);
    let c = out.counts;
    assert_eq!(c.total_footprints() as usize, out.footprints.len());
    assert_eq!(c.total_photons() as usize, out.photons.len());
    assert_eq!(c.total_footprints() + c.total_photons(), (input.raw.len() + input.photons.len()) as u32, "every raw footprint and photon is stored once");

    // Store outcomes against the core.
    let heuristics = Heuristics::default();
    let resolved = heuristics.resolve(&scene_bounds());
    let smoothing = Smoothing { caustic: SMOOTHING[0] as f64, global: SMOOTHING[1] as f64 };
    let fp_by_center: std::collections::HashMap<[u32; 3], &arpa_core::footprint::PackedFootprint> =
        out.footprints.iter().map(|f| (f.center.map(f32::to_bits), f)).collect();
    let ph_by_pos: std::collections::HashMap<[u32; 3], &PackedPhoton> = out.photons.iter().map(|p| (p.position.map(f32::to_bits), p)).collect();
    let (mut checked, mut fallbacks, mut flipped) = (0, 0, 0);
    for (r, flip) in &input.unsmoothed {
        let flip = *flip;
        let fp = core_footprint(r);
        let radius = RADII[r.map as usize] as f64;
        if near_threshold(&heuristics, &smoothing.apply(fp), radius) {
            continue;
        }
        let sign = if flip { -1.0 } else { 1.0 };
        let key = r.center.map(f32::to_bits);
        match store_footprint(fp, &smoothing, &resolved, radius) {
            StoredPhoton::Footprint { packed, .. } => {
                let got = fp_by_center.get(&key).unwrap_or_else(|| panic!("footprint {r:?} missing"));
                assert_eq!(got.map, packed.map);
                let n = Vec3::from_array(got.row_n).normalize();
                assert!((n - sign * Vec3::from_array(r.normal)).length() < 1e-5, "orientation of {r:?}: {n:?}");
            }
            StoredPhoton::Progressive { photon, .. } => {
                let got = ph_by_pos.get(&key).unwrap_or_else(|| panic!("fallback photon {r:?} missing"));
                let mut want = photon;
                if flip {
                    want.normal = want.normal.map(|x| -x);
                }
                assert_eq!(**got, want);
                fallbacks += 1;
            }
        }
        flipped += flip as usize;
        checked += 1;
    }
    assert!(checked > 2500 && fallbacks > 100 && flipped > 300, "{checked} checked, {fallbacks} fallbacks, {flipped} flipped");
    for p in &input.photons {
        assert_eq!(**ph_by_pos.get(&p.photon.position.map(f32::to_bits)).expect("photon missing"), p.photon);
    }

    // Sorted: by map, photons by Morton code within a map.
    let b = scene_bounds();
    let (lo, hi) = (b.min.as_vec3(), b.max.as_vec3());
    let inv = (Vec3::ONE / (hi - lo)).to_array();
    assert!(out.footprints.windows(2).all(|w| w[0].map <= w[1].map));
    assert_eq!(out.footprints.iter().filter(|f| f.map == 0).count(), c.footprints[0] as usize);
    let key = |p: &PackedPhoton| (p.map, morton_code(p.position, lo.to_array(), inv));
    assert!(out.photons.windows(2).all(|w| key(&w[0]) <= key(&w[1])), "photons not in (map, Morton) order");

    // Gather against the brute-force gather over the device's records.
    let mut lit = 0;
    let mut gathered = 0u64;
    for (rec, got) in input.records.iter().zip(&out.image) {
        let got = Vec3::from_array(*got).as_dvec3();
        let radiance = Vec3::from_array(rec.radiance).as_dvec3();
        if rec.valid == 0 {
            let want = DVec3::select(radiance.is_finite_mask(), radiance, DVec3::ZERO);
            assert_eq!(got, want, "invalid record {rec:?}");
            continue;
        }
        let q = QueryPoint { position: Vec3::from_array(rec.position), normal: Vec3::from_array(rec.normal) };
        let e = gather_brute_force(&q, &out.footprints, &out.photons, RADII.map(f64::from), kernel);
        gathered += (e.footprints + e.photons) as u64;
        let (mut abs, mut slack) = (0.0f64, 0.0f64);
        for fp in &out.footprints {
            abs += fp.irradiance(q.position, q.normal, kernel).abs().max_element() as f64;
            let y = fp.filter_coords(q.position);
            let r2 = (y.x * y.x + y.y * y.y) as f64;
            if fp.faces(q.normal) && ((r2 - 1.0).abs() < 1e-4 || (y.z.abs() as f64 - 1.0).abs() < 1e-4) {
                slack += fp.flux_density().abs().max_element() as f64 * kernel.eval_f64((r2.min(1.0) - 1e-4).max(0.0));
            }
        }
        for ph in &out.photons {
            let r = RADII[ph.map as usize];
            let e = ph.irradiance(q.position, q.normal, r).abs().max_element() as f64;
            abs += e;
            let d2 = (q.position - Vec3::from_array(ph.position)).length_squared() as f64 / (r as f64 * r as f64);
            if (d2 - 1.0).abs() < 1e-4 && Vec3::from_array(ph.normal).dot(q.normal) > 0.0 {
                slack += Vec3::from_array(ph.flux).abs().max_element() as f64 / (std::f64::consts::PI * (r as f64).powi(2));
            }
        }
        let weight = Vec3::from_array(rec.weight).as_dvec3();
        let want = radiance + weight * e.irradiance();
        let want = DVec3::select(want.is_finite_mask(), want, DVec3::ZERO);
        let tol = weight.max_element() * (64.0 * EPS * abs + slack) + 4.0 * EPS * radiance.abs().max_element() + 1e-30;
        let diff = (got - want).abs().max_element();
        assert!(diff <= tol, "pixel {}: device {got:?} core {want:?} (diff {diff:e} > {tol:e})", rec.pixel);
        lit += (e.footprints + e.photons > 0) as usize;
    }
    assert!(lit > 1500, "{lit} lit pixels");
    let rel = (out.gathered as f64 - gathered as f64).abs() / gathered as f64;
    assert!(rel < 1e-3, "contributions: device {} core {gathered}", out.gathered);

    // Running mean of three equal images.
    for (m, p) in out.mean.iter().zip(&out.image) {
        let p = Vec3::from_array(*p);
        assert!((*m - p).abs().max_element() <= 2.0 * f32::EPSILON * p.abs().max_element(), "mean {m:?} of {p:?}");
        assert!(m.is_finite());
    }
}

#[test]
fn chain_is_independent_of_append_order() {
    let Some(ctx) = gpu() else { return };
    let input = input(12);
    let a = run(ctx, &input, Kernel::Silverman);
    let mut permuted = Input { unsmoothed: Vec::new(), raw: input.raw.clone(), photons: input.photons.clone(), records: input.records.clone() };
    permuted.raw.reverse();
    permuted.raw.rotate_left(777);
    permuted.photons.rotate_left(123);
    permuted.photons.reverse();
    let b = run(ctx, &permuted, Kernel::Silverman);
    assert_eq!(a.counts, b.counts);
    assert!(a.footprints == b.footprints, "footprints differ");
    assert!(a.photons == b.photons, "photons differ");
    let bits = |img: &[[f32; 3]]| img.iter().flat_map(|p| p.map(f32::to_bits)).collect::<Vec<_>>();
    assert!(bits(&a.image) == bits(&b.image), "images differ");
    assert!(a.image.iter().any(|p| p[0] > 0.0));
}

/// Nothing stored: the image is the records' known radiance.
#[test]
fn empty_maps_give_the_known_radiance() {
    let Some(ctx) = gpu() else { return };
    let mut input = input(13);
    input.raw.clear();
    input.photons.clear();
    let out = run(ctx, &input, Kernel::Constant);
    assert_eq!(out.counts, Default::default());
    for (rec, got) in input.records.iter().zip(&out.image) {
        let want = rec.radiance.map(|x| if x.is_finite() { x } else { 0.0 });
        assert_eq!(*got, want);
    }
    let _ = PhotonMap::Caustic;
}
