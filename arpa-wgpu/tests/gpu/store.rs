//! Store → acceleration structure → gather on the device in one submission
//! (`support::store_and_gather`: the twin's heuristics, then the gather's box traversal),
//! against the core: every raw footprint's outcome
//! equals `ResolvedHeuristics::store`'s (except within 1e-3 of a threshold, as in the
//! conformance case `twin-heuristics`), the stored records' centres are the core's, the
//! gather over the device-built structure (rejected footprints as far zero-size boxes)
//! equals the brute-force gather over the device's records within `gather`'s bound, and a
//! second run is bit-identical (deterministic slots, no atomics).

use crate::common::*;
use crate::gather::{check, queries};
use arpa_core::base::aabb::Aabb;
use arpa_core::store::footprint::{Footprint, PackedFootprint, PhotonMap};
use arpa_core::store::heuristics::{HeuristicContext, Heuristics};
use arpa_core::gpu::codes::store_code;
use arpa_core::gather::kernel::Kernel;
use arpa_core::base::rng::{Rng, StreamDomain};
use arpa_core::gpu::layout::RawFootprint;
use crate::support::store_and_gather;
use glam::DVec3;
use proptest::prelude::*;

const RADII: [f32; 2] = [0.01, 0.05];

pub(crate) fn raw(seed: u32, n: usize) -> Vec<RawFootprint> {
    let mut rng = Rng::new(seed, 2, 0, StreamDomain::User);
    (0..n)
        .map(|_| {
            let k = rng.next_u32() % 2;
            let (z, nz) = if k == 0 { (0.0, 1.0) } else { (0.3, -1.0) };
            let a = rng.next_f64() * std::f64::consts::TAU;
            // Angles down to near-parallel (degenerate), lengths up to culled sizes.
            let b = a + 0.02 + 3.0 * rng.next_f64();
            let (la, lb) = (0.005 + 0.3 * rng.next_f64(), 0.005 + 0.3 * rng.next_f64());
            let f = |v: f64| v as f32;
            RawFootprint {
                center: [f(rng.next_f64() - 0.5), f(rng.next_f64() - 0.5), z],
                map: rng.next_u32() % 2,
                normal: [0.0, 0.0, nz],
                du: [f(a.cos() * la), f(a.sin() * la), 0.0],
                dv: [f(b.cos() * lb), f(b.sin() * lb), 0.0],
                flux: [f(rng.next_f64() * 1e-3), f(rng.next_f64() * 1e-3), f(rng.next_f64() * 1e-3)],
                ..Default::default()
            }
        })
        .collect()
}

pub(crate) fn core_footprint(r: &RawFootprint) -> Footprint {
    let d = |v: [f32; 3]| glam::Vec3::from_array(v).as_dvec3();
    Footprint { center: d(r.center), normal: d(r.normal), du: d(r.du), dv: d(r.dv), flux: d(r.flux), map: PhotonMap::from_index(r.map) }
}

pub(crate) fn scene_bounds() -> Aabb {
    Aabb { min: DVec3::new(-1.0, -1.0, -0.2), max: DVec3::new(1.0, 1.0, 0.5) }
}

/// Within 1e-3 relative of the degenerate or culling threshold.
pub(crate) fn near_threshold(h: &Heuristics, fp: &Footprint, radius: f64) -> bool {
    let ctx = HeuristicContext { radius, scene_bounds: scene_bounds() };
    let fp = h.clamp_h_max(h.dampen(*fp, &ctx), &ctx);
    let near = |x: f64, t: f64| (x / t - 1.0).abs() < 1e-3;
    let (major, minor) = fp.axis_lengths();
    let deg = h.degenerate.is_some_and(|d| near(minor, d.fraction * major));
    let cull = h.culling.is_some_and(|c| near(fp.aabb(radius).largest_extent(), c.fraction * scene_bounds().largest_extent()));
    deg || cull
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 3, max_shrink_iters: 4, ..ProptestConfig::default() })]

    #[test]
    fn store_then_gather_matches_core(seed in any::<u32>()) {
        let Some(ctx) = gpu() else { return Ok(()) };
        let heuristics = Heuristics::default();
        let resolved = heuristics.resolve(&scene_bounds());
        let raws = raw(seed, 3000);
        let qs = queries(seed, 3000);
        let out = store_and_gather(ctx, &raws, resolved.pack(), RADII, &qs, Kernel::Silverman);
        let mut counts = [0usize; 4];
        for (i, r) in raws.iter().enumerate() {
            let fp = core_footprint(r);
            let radius = RADII[r.map as usize] as f64;
            if near_threshold(&heuristics, &fp, radius) {
                continue;
            }
            let want = resolved.store(fp, radius);
            let code = store_code(want.as_ref().err().copied()).expect("the store gives only its own reasons");
            prop_assert_eq!(out.status[i], code, "footprint {}: {:?}", i, r);
            counts[code as usize] += 1;
            match want {
                Ok((_, p, _)) => prop_assert_eq!(out.records[i].center, p.center),
                Err(_) => prop_assert_eq!(out.records[i], PackedFootprint::default()),
            }
        }
        prop_assert!(counts[0] > 500 && counts[1] > 50 && counts[2] > 50, "outcomes {:?}", counts);
        let stored: Vec<PackedFootprint> = out.records.iter().zip(&out.status).filter(|(_, s)| **s == 0).map(|(r, _)| *r).collect();
        check(&stored, &qs, &out.gathered, Kernel::Silverman, 1)?;
        let again = store_and_gather(ctx, &raws, resolved.pack(), RADII, &qs, Kernel::Silverman);
        prop_assert_eq!(&again.status, &out.status);
        prop_assert!(again.records == out.records && again.gathered == out.gathered, "second run differs");
    }
}
