//! Each heuristic converts exactly what its definition says, in the documented order, and
//! storing never creates or destroys flux.

use arpa_core::aabb::Aabb;
use arpa_core::classify::Smoothing;
use arpa_core::footprint::{Footprint, PhotonMap};
use arpa_core::heuristics::*;
use arpa_core::store::{store_footprint, ProgressiveReason, StoredPhoton};
use glam::DVec3;

fn scene() -> Aabb {
    Aabb { min: DVec3::ZERO, max: DVec3::new(10.0, 4.0, 2.0) } // largest side 10, diagonal √120
}

fn ctx(radius: f64) -> HeuristicContext {
    HeuristicContext { radius, scene_bounds: scene() }
}

fn fp(du: DVec3, dv: DVec3) -> Footprint {
    Footprint { center: DVec3::new(5.0, 0.0, 1.0), normal: DVec3::Y, du, dv, flux: DVec3::new(2.0, 1.0, 0.5), map: PhotonMap::Caustic }
}

#[test]
fn dampening_follows_its_formula() {
    let h = Heuristics { dampening: Some(Dampening { exponent: 0.25, reference: DampenReference::ProgressiveDiameter }), ..Heuristics::NONE };
    let c = ctx(0.01); // reference 0.02
    for major in [1e-4, 0.02, 0.3, 5.0] {
        let f = fp(DVec3::X * major, DVec3::Z * major * 0.3);
        let out = h.dampen(f, &c);
        let expected = 0.02 * (major / 0.02f64).powf(0.25);
        assert!((out.du.length() - expected).abs() < 1e-12 * expected, "major {major}");
        // Minor dampened by the same ratio: aspect ratio and directions kept.
        assert!((out.dv.length() / out.du.length() - 0.3).abs() < 1e-12);
        assert!(out.du.normalize().dot(DVec3::X) > 1.0 - 1e-15);
    }
    // Literal reading ℓ^(1/4) in scene units.
    let lit = Heuristics { dampening: Some(Dampening { exponent: 0.25, reference: DampenReference::Absolute(1.0) }), ..Heuristics::NONE };
    let out = lit.dampen(fp(DVec3::X * 0.0625, DVec3::Z * 0.01), &c);
    assert!((out.du.length() - 0.5).abs() < 1e-12);
    // Off: identity.
    let f = fp(DVec3::X, DVec3::Z);
    assert_eq!(Heuristics::NONE.dampen(f, &c), f);
}

#[test]
fn h_max_clamps_exactly() {
    let h_max = 0.05 * scene().diagonal();
    let each = Heuristics { h_max: Some(HMax { length: LengthSpec::RelativeToDiagonal(0.05), mode: HMaxMode::EachDifferential }), ..Heuristics::NONE };
    let out = each.clamp_h_max(fp(DVec3::X * 3.0, DVec3::new(0.0, 0.0, 0.2)), &ctx(0.01));
    assert!((out.du.length() - h_max).abs() < 1e-12);
    assert_eq!(out.dv, DVec3::new(0.0, 0.0, 0.2)); // shorter than h_max: untouched
    let both_long = each.clamp_h_max(fp(DVec3::X * 3.0, DVec3::Z * 2.0), &ctx(0.01));
    assert!((both_long.du.length() - h_max).abs() < 1e-12 && (both_long.dv.length() - h_max).abs() < 1e-12);
    let aspect = Heuristics { h_max: Some(HMax { length: LengthSpec::Absolute(0.5), mode: HMaxMode::PreserveAspect }), ..Heuristics::NONE };
    let out = aspect.clamp_h_max(fp(DVec3::X * 2.0, DVec3::Z * 1.0), &ctx(0.01));
    assert!((out.du.length() - 0.5).abs() < 1e-12 && (out.dv.length() - 0.25).abs() < 1e-12);
    let short = fp(DVec3::X * 0.1, DVec3::Z * 0.1);
    assert_eq!(aspect.clamp_h_max(short, &ctx(0.01)), short);
}

#[test]
fn degenerate_removal_at_its_threshold() {
    let h = Heuristics { degenerate: Some(DegenerateRemoval { fraction: 0.05 }), ..Heuristics::NONE };
    // |Du × Dv| / |Dmajor|² = (|Dv|/|Du|) sin α.
    let major = DVec3::X * 0.2;
    for (ratio, angle, degenerate) in [(0.049, 90.0f64, true), (0.051, 90.0, false), (1.0, 2.8, true), (1.0, 2.9, false), (0.1, 29.0, true), (0.1, 31.0, false)] {
        let a = angle.to_radians();
        let dv = (DVec3::X * a.cos() + DVec3::Z * a.sin()) * 0.2 * ratio;
        let f = fp(major, dv);
        assert_eq!(h.is_degenerate(&f), degenerate, "ratio {ratio}, α {angle}°");
        let outcome = h.apply(f, &ctx(0.01));
        assert_eq!(outcome.is_err(), degenerate);
    }
    // Zero and parallel differentials are degenerate, even with the heuristic off.
    assert!(h.is_degenerate(&fp(DVec3::ZERO, DVec3::ZERO)));
    assert_eq!(Heuristics::NONE.apply(fp(DVec3::X, DVec3::X * 2.0), &ctx(0.01)), Err(ProgressiveReason::Degenerate));
    assert_eq!(Heuristics::NONE.apply(fp(DVec3::ZERO, DVec3::Z), &ctx(0.01)), Err(ProgressiveReason::Degenerate));
}

#[test]
fn culling_at_five_percent() {
    // Scene largest side 10 → footprint boxes wider than 0.5 are culled.
    let h = Heuristics { culling: Some(BoundingBoxCulling { fraction: 0.05, metric: CullMetric::LargestExtent }), ..Heuristics::NONE };
    for (len, culled) in [(0.49, false), (0.51, true)] {
        // Box side along x is |Du_x| (half-extent |Du|/2 on each side) for Du ∥ x.
        let f = fp(DVec3::X * len, DVec3::Z * 0.1);
        assert_eq!(h.is_culled(&f.aabb(0.01), &ctx(0.01)), culled, "len {len}");
        assert_eq!(h.apply(f, &ctx(0.01)).err(), culled.then_some(ProgressiveReason::Culled));
    }
    let by_area = Heuristics { culling: Some(BoundingBoxCulling { fraction: 0.05, metric: CullMetric::SurfaceArea }), ..Heuristics::NONE };
    let scene_area = scene().surface_area(); // 2(40 + 8 + 20) = 136 → threshold 6.8
    assert_eq!(scene_area, 136.0);
    let big = fp(DVec3::X * 2.0, DVec3::Z * 1.5); // box ≈ 2 × 2h × 1.5
    let area = big.aabb(0.01).surface_area();
    assert_eq!(by_area.is_culled(&big.aabb(0.01), &ctx(0.01)), area > 6.8);
    let by_diag = Heuristics { culling: Some(BoundingBoxCulling { fraction: 0.05, metric: CullMetric::Diagonal }), ..Heuristics::NONE };
    let d = big.aabb(0.01).diagonal();
    assert_eq!(by_diag.is_culled(&big.aabb(0.01), &ctx(0.01)), d > 0.05 * scene().diagonal());
}

#[test]
fn order_dampen_then_clamp_then_degenerate_then_cull() {
    // Dampening (literal reading, ℓ^(1/4)) grows a small footprint; h-max then clamps it.
    let h = Heuristics {
        dampening: Some(Dampening { exponent: 0.25, reference: DampenReference::Absolute(1.0) }),
        h_max: Some(HMax { length: LengthSpec::Absolute(0.3), mode: HMaxMode::EachDifferential }),
        degenerate: Some(DegenerateRemoval { fraction: 0.05 }),
        culling: Some(BoundingBoxCulling { fraction: 0.05, metric: CullMetric::LargestExtent }),
    };
    // 0.0016^(1/4) = 0.2: below h_max; 0.0256^(1/4) = 0.4: clamped to 0.3.
    let (out, bb) = h.apply(fp(DVec3::X * 0.0256, DVec3::Z * 0.0256), &ctx(0.01)).unwrap();
    assert!((out.du.length() - 0.3).abs() < 1e-12 && (out.dv.length() - 0.3).abs() < 1e-12);
    assert_eq!(bb, out.aabb(0.01));
    // Without the clamp the dampened footprint (0.4 wide) survives culling (≤ 0.5) too, but a
    // larger one is culled only because the clamp is off.
    let no_clamp = Heuristics { h_max: None, ..h };
    assert_eq!(no_clamp.apply(fp(DVec3::X * 0.2, DVec3::Z * 0.2), &ctx(0.01)).err(), Some(ProgressiveReason::Culled)); // 0.2^(1/4) = 0.67
    assert!(h.apply(fp(DVec3::X * 0.2, DVec3::Z * 0.2), &ctx(0.01)).is_ok());
}

#[test]
fn storing_conserves_flux_and_map() {
    let smoothing = Smoothing { caustic: 0.5, global: 2.0 };
    let h = Heuristics::default();
    let c = ctx(0.01);
    // Accepted: flux density × ellipse area = flux.
    let f = fp(DVec3::X * 0.03, DVec3::Z * 0.02);
    match store_footprint(f, &smoothing, &h.resolve(&c.scene_bounds), c.radius) {
        StoredPhoton::Footprint { packed, aabb } => {
            assert_eq!(packed.photon_map(), PhotonMap::Caustic);
            let (expected, expected_box) = h.apply(smoothing.apply(f), &c).unwrap();
            assert!((aabb.min - expected_box.min).abs().max_element() < 1e-12 && (aabb.max - expected_box.max).abs().max_element() < 1e-12);
            // The density is Φ · 4/|Du×Dv| of the final (smoothed, dampened) footprint.
            let recovered = packed.flux_density().as_dvec3() * expected.parallelogram_area() / 4.0;
            assert!((recovered - f.flux).abs().max_element() < 1e-6 * f.flux.max_element(), "{recovered}");
        }
        other => panic!("expected a footprint, got {other:?}"),
    }
    // Rejected: a progressive photon with the same flux, normal and map.
    let thin = fp(DVec3::X * 0.03, DVec3::new(0.03, 0.0, 0.0001));
    match store_footprint(thin, &smoothing, &h.resolve(&c.scene_bounds), c.radius) {
        StoredPhoton::Progressive { photon, reason } => {
            assert_eq!(reason, ProgressiveReason::Degenerate);
            assert_eq!(photon.flux, [2.0, 1.0, 0.5]);
            assert_eq!(photon.normal, [0.0, 1.0, 0.0]);
            assert_eq!(photon.photon_map(), PhotonMap::Caustic);
        }
        other => panic!("expected a progressive photon, got {other:?}"),
    }
    // Smoothing scales the differentials of the photon's own map only.
    let g = Footprint { map: PhotonMap::Global, ..f };
    assert_eq!(smoothing.apply(g).du, g.du * 2.0);
    assert_eq!(smoothing.apply(f).du, f.du * 0.5);
}

mod fused_path {
    use super::*;
    use arpa_core::footprint::FootprintError;
    use proptest::prelude::*;

    fn heuristics() -> impl Strategy<Value = Heuristics> {
        (any::<[bool; 4]>(), prop_oneof![Just(0.25), 0.1f64..0.9], any::<bool>(), any::<bool>(), 0.01f64..0.5, 0usize..3).prop_map(|(on, gamma, lit, aspect, f, metric)| Heuristics {
            dampening: on[0].then_some(Dampening { exponent: gamma, reference: if lit { DampenReference::Absolute(1.0) } else { DampenReference::ProgressiveDiameter } }),
            h_max: on[1].then_some(HMax { length: LengthSpec::RelativeToDiagonal(0.05), mode: if aspect { HMaxMode::PreserveAspect } else { HMaxMode::EachDifferential } }),
            degenerate: on[2].then_some(DegenerateRemoval { fraction: f }),
            culling: on[3].then_some(BoundingBoxCulling { fraction: 0.05, metric: [CullMetric::LargestExtent, CullMetric::Diagonal, CullMetric::SurfaceArea][metric] }),
        })
    }

    fn footprint() -> impl Strategy<Value = Footprint> {
        (-6.0f64..6.0, -6.0f64..6.0, -3.0f64..3.0, 0.0f64..6.3, 0.0f64..3.2, -4.0f64..0.5, -4.0f64..0.5).prop_map(|(x, z, y, rot, angle, la, lb)| {
            let dir = |t: f64| DVec3::new(t.cos(), 0.0, t.sin());
            Footprint { center: DVec3::new(x, y, z), normal: DVec3::Y, du: dir(rot) * 10f64.powf(la), dv: dir(rot + angle) * 10f64.powf(lb), flux: DVec3::ONE, map: PhotonMap::Global }
        })
    }

    proptest! {
        #![proptest_config(ProptestConfig { cases: 10_000, ..ProptestConfig::default() })]

        /// The fused per-photon path decides exactly as `Heuristics::apply` + `Footprint::pack`.
        #[test]
        fn fused_store_decides_like_apply_then_pack(h in heuristics(), fp in footprint(), radius in 1e-4f64..0.1) {
            let c = ctx(radius);
            let reference = h.apply(fp, &c).and_then(|(f, b)| match f.pack(radius) {
                Ok(p) => Ok((f, p, b)),
                Err(FootprintError::Degenerate) => Err(ProgressiveReason::Degenerate),
                Err(_) => Err(ProgressiveReason::Unrepresentable),
            });
            let fused = h.resolve(&scene()).store(fp, radius);
            match (reference, fused) {
                (Ok((f1, p1, b1)), Ok((f2, p2, b2))) => {
                    let tol = 1e-9 * f1.du.length().max(f1.dv.length());
                    prop_assert!((f1.du - f2.du).length() <= tol && (f1.dv - f2.dv).length() <= tol);
                    let scale = (b1.max - b1.min).max_element();
                    prop_assert!((b1.min - b2.min).abs().max_element() <= 1e-9 * scale && (b1.max - b2.max).abs().max_element() <= 1e-9 * scale);
                    let (a, b): (&[f32; 16], &[f32; 16]) = (bytemuck::cast_ref(&p1), bytemuck::cast_ref(&p2));
                    for (x, y) in a.iter().zip(b) {
                        prop_assert!((x - y).abs() <= 1e-5 * x.abs().max(y.abs()).max(1e-30), "{:?} vs {:?}", p1, p2);
                    }
                }
                (Err(r1), Err(r2)) => prop_assert_eq!(r1, r2),
                (r1, r2) => prop_assert!(false, "reference {:?} vs fused {:?}", r1.map(|x| x.2), r2.map(|x| x.2)),
            }
        }
    }
}
