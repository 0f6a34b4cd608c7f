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
//! * each pixel's plane `k` (per-pixel bandwidth: every scale of the ladder) is
//!   `radiance + weight · E_k` with `E_k` the brute-force gather (`gather_brute_force`,
//!   `gather_brute_force_scales`, f64) over the device's own records, within the `gather`
//!   test's bound (64 ε Σ|contributions| plus the contributions of records whose boundary
//!   at that scale the query lies within 1e-4 of); invalid records give their radiance,
//!   non-finite ones 0; the moment planes are `bandwidth::moments` of the device's own
//!   radiance planes (f32 on both sides: within 16 ε of the squared sum of the luminance
//!   terms, FMA contraction); a global bandwidth writes the stored scale's plane only, bit
//!   for bit the per-pixel render's plane 0;
//! * the running mean of n equal images is the image (compensated sum, within 2 ε);
//! * appending in another order gives bit-identical records, photons and image.

use crate::common::*;
use crate::store::{core_footprint, near_threshold, raw, scene_bounds};
use arpa_core::propagate::classify::Smoothing;
use arpa_core::gather::scales::{Bandwidth, PLANES, SCALES, moments};
use arpa_core::gather::estimate::{QueryPoint, gather_brute_force, gather_brute_force_scales};
use arpa_core::store::footprint::PhotonMap;
use arpa_core::store::heuristics::Heuristics;
use arpa_core::gather::kernel::Kernel;
use arpa_core::store::progressive_photon::PackedPhoton;
use arpa_core::base::rng::{Rng, StreamDomain};
use arpa_core::store::decision::{StoredPhoton, store_footprint};
use arpa_core::render::tracer::QueryRecord;
use crate::support::{HostRun, run_from_host, store_status};
use arpa_core::gpu::layout::{KeyedFootprint, KeyedPhoton, RawFootprint, StoreSettings};
use arpa_core::base::morton::morton_code;
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

fn run(ctx: &arpa_wgpu::GpuContext, input: &Input, kernel: Kernel, bandwidth: Bandwidth) -> HostRun {
    run_from_host(ctx, &input.raw, &input.photons, &settings(input), &input.records, kernel, bandwidth, 3)
}

#[test]
fn chain_matches_core() {
    let Some(ctx) = gpu() else { return };
    let kernel = Kernel::Epanechnikov;
    let input = input(11);
    let out = run(ctx, &input, kernel, Bandwidth::PerPixel);
    let c = out.counts;
    assert_eq!(c.total_footprints() as usize, out.footprints.len());
    assert_eq!(c.total_photons() as usize, out.photons.len());
    assert_eq!(c.total_footprints() + c.total_photons(), (input.raw.len() + input.photons.len()) as u32, "every raw footprint and photon is stored once");

    // Store outcomes against the core.
    let heuristics = Heuristics::default();
    let resolved = heuristics.resolve(&scene_bounds());
    let smoothing = Smoothing { caustic: SMOOTHING[0] as f64, global: SMOOTHING[1] as f64 };
    let fp_by_center: std::collections::HashMap<[u32; 3], &arpa_core::store::footprint::PackedFootprint> =
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

    // Gather against the brute-force gather over the device's records, every scale.
    let px = input.records.len();
    assert_eq!(out.image.len(), PLANES * px);
    let plane = |p: usize, i: usize| Vec3::from_array(out.image[p * px + i]);
    let mut lit = 0;
    let mut gathered = 0u64;
    let mut scales_differ = 0;
    for (i, rec) in input.records.iter().enumerate() {
        let radiance = Vec3::from_array(rec.radiance).as_dvec3();
        let finite = |v: DVec3| DVec3::select(v.is_finite_mask(), v, DVec3::ZERO);
        let l: [Vec3; SCALES] = std::array::from_fn(|k| plane(k, i));
        if rec.valid == 0 {
            for (k, got) in l.iter().enumerate() {
                assert_eq!(got.as_dvec3(), finite(radiance), "invalid record {rec:?}, scale {k}");
            }
        } else {
            let q = QueryPoint { position: Vec3::from_array(rec.position), normal: Vec3::from_array(rec.normal) };
            let e = gather_brute_force(&q, &out.footprints, &out.photons, RADII.map(f64::from), kernel);
            let es = gather_brute_force_scales(&q, &out.footprints, &out.photons, RADII.map(f64::from), kernel);
            let bounds = crate::gather::scale_bounds(&q, &out.footprints, &out.photons, RADII, kernel);
            gathered += (e.footprints + e.photons) as u64;
            let weight = Vec3::from_array(rec.weight).as_dvec3();
            for k in 0..SCALES {
                let (abs, slack) = bounds[k];
                let ek = if k == 0 { e.irradiance() } else { es.per_scale[k] };
                let want = finite(radiance + weight * ek);
                let tol = weight.max_element() * (64.0 * EPS * abs + slack) + 4.0 * EPS * radiance.abs().max_element() + 1e-30;
                let got = l[k].as_dvec3();
                let diff = (got - want).abs().max_element();
                assert!(diff <= tol, "pixel {} scale {k}: device {got:?} core {want:?} (diff {diff:e} > {tol:e})", rec.pixel);
            }
            lit += (e.footprints + e.photons > 0) as usize;
            scales_differ += (l[0] != l[SCALES - 1]) as usize;
        }
        // Moments of the device's own radiance planes, in f32.
        let want = moments(&l);
        let y_abs: [f64; SCALES] = std::array::from_fn(|k| (0.2126 * l[k].x.abs() + 0.7152 * l[k].y.abs() + 0.0722 * l[k].z.abs()) as f64);
        for (p, w) in want.iter().enumerate() {
            let got = plane(SCALES + p, i);
            for c in 0..3 {
                let v = 3 * p + c;
                let scale = if v < SCALES { y_abs[v] * y_abs[v] } else { (y_abs[v - SCALES] + y_abs[v - SCALES + 1]).powi(2) };
                let diff = (got[c] as f64 - w[c] as f64).abs();
                assert!(diff <= 16.0 * EPS * scale + 1e-37, "pixel {} moment {v}: device {} core {} (diff {diff:e})", rec.pixel, got[c], w[c]);
            }
        }
    }
    assert!(lit > 1500, "{lit} lit pixels");
    assert!(scales_differ > lit / 2, "the smallest scale equals the stored one in {} of {lit} lit pixels", lit - scales_differ);
    let rel = (out.gathered as f64 - gathered as f64).abs() / gathered as f64;
    assert!(rel < 1e-3, "contributions: device {} core {gathered}", out.gathered);

    // A global bandwidth: one plane, the per-pixel render's stored scale bit for bit.
    let global = run(ctx, &input, kernel, Bandwidth::Global);
    assert_eq!(global.image.len(), px);
    let bits = |img: &[[f32; 3]]| img.iter().flat_map(|p| p.map(f32::to_bits)).collect::<Vec<_>>();
    assert!(bits(&global.image) == bits(&out.image[..px]), "the global image differs from the per-pixel plane 0");

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
    let a = run(ctx, &input, Kernel::Silverman, Bandwidth::PerPixel);
    let mut permuted = Input { unsmoothed: Vec::new(), raw: input.raw.clone(), photons: input.photons.clone(), records: input.records.clone() };
    permuted.raw.reverse();
    permuted.raw.rotate_left(777);
    permuted.photons.rotate_left(123);
    permuted.photons.reverse();
    let b = run(ctx, &permuted, Kernel::Silverman, Bandwidth::PerPixel);
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
    let out = run(ctx, &input, Kernel::Constant, Bandwidth::PerPixel);
    assert_eq!(out.counts, Default::default());
    let px = input.records.len();
    for (i, rec) in input.records.iter().enumerate() {
        let want = rec.radiance.map(|x| if x.is_finite() { x } else { 0.0 });
        for k in 0..SCALES {
            assert_eq!(out.image[k * px + i], want, "scale {k}");
        }
        // Equal scales: the difference moments are zero.
        assert_eq!(out.image[(PLANES - 1) * px + i], [0.0; 3]);
    }
    let _ = PhotonMap::Caustic;
}

/// The store over too few photon sort items: the items past the capacity are dropped and
/// counted (`StoreCounts::overflowed`), the store check sets the iteration's status word, and
/// the accumulation guarded by it leaves the sums alone; with room for every item, neither.
#[test]
fn dropped_photon_items_stop_the_accumulation() {
    let Some(ctx) = gpu() else { return };
    let input = input(14);
    let s = settings(&input);
    let (counts, status, sum) = store_status(ctx, &input.raw, &input.photons, &s, 8);
    assert!(counts.photon_items > 8, "too few photon items to overflow 8: {counts:?}");
    assert_eq!((counts.overflowed, status, sum), (counts.photon_items - 8, 1, 0.0), "{counts:?}");
    let room = (input.raw.len() + input.photons.len()) as u32;
    let (counts, status, sum) = store_status(ctx, &input.raw, &input.photons, &s, room);
    assert_eq!((counts.overflowed, status, sum), (0, 0, 1.0), "{counts:?}");
}
