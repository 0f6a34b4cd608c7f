//! Each heuristic converts exactly what its definition says, in the documented order, and
//! storing never creates or destroys flux.

use arpa_core::base::aabb::Aabb;
use arpa_core::propagate::classify::Smoothing;
use arpa_core::store::footprint::{Footprint, PhotonMap};
use arpa_core::store::heuristics::*;
use arpa_core::{store::decision::{store_footprint, StoredPhoton}, store::heuristics::ProgressiveReason};
use glam::{DMat3, DVec3};

fn scene() -> Aabb {
    Aabb { min: DVec3::ZERO, max: DVec3::new(10.0, 4.0, 2.0) } // largest side 10, diagonal √120
}

fn ctx(radius: f64) -> HeuristicContext {
    HeuristicContext { radius, scene_bounds: scene() }
}

/// The ellipse's shape matrix `D_u D_uᵀ + D_v D_vᵀ` (m², `4 Σ σᵢ² eᵢeᵢᵀ`): equal for two
/// pairs exactly when they span the same centred ellipse.
fn shape(f: &Footprint) -> DMat3 {
    let outer = |v: DVec3| DMat3::from_cols(v * v.x, v * v.y, v * v.z);
    outer(f.du) + outer(f.dv)
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
    let each = Heuristics { h_max: Some(HMax { length: LengthSpec::RelativeToDiagonal(0.05), mode: HMaxMode::EachAxis }), ..Heuristics::NONE };
    let out = each.clamp_h_max(fp(DVec3::X * 3.0, DVec3::new(0.0, 0.0, 0.2)), &ctx(0.01));
    assert!((out.du - DVec3::X * h_max).length() < 1e-12);
    assert!((out.dv - DVec3::new(0.0, 0.0, 0.2)).length() < 1e-12); // shorter than h_max: kept
    let both_long = each.clamp_h_max(fp(DVec3::X * 3.0, DVec3::Z * 2.0), &ctx(0.01));
    assert!((both_long.du.length() - h_max).abs() < 1e-12 && (both_long.dv.length() - h_max).abs() < 1e-12);
    let aspect = Heuristics { h_max: Some(HMax { length: LengthSpec::Absolute(0.5), mode: HMaxMode::PreserveAspect }), ..Heuristics::NONE };
    let out = aspect.clamp_h_max(fp(DVec3::X * 2.0, DVec3::Z * 1.0), &ctx(0.01));
    assert!((out.du.length() - 0.5).abs() < 1e-12 && (out.dv.length() - 0.25).abs() < 1e-12);
    let short = fp(DVec3::X * 0.1, DVec3::Z * 0.1);
    assert_eq!(aspect.clamp_h_max(short, &ctx(0.01)), short);

    // A 57:1 sliver along x (axes 5.7 and 0.1) given by a sheared conjugate pair: each
    // principal axis is clamped along its own direction, so the result is the ellipse with
    // axes h_max = 0.5 along x and 0.1 along z, whatever pair spans the sliver.
    let each = Heuristics { h_max: Some(HMax { length: LengthSpec::Absolute(0.5), mode: HMaxMode::EachAxis }), ..Heuristics::NONE };
    let (a, b) = (DVec3::X * 5.7, DVec3::Z * 0.1);
    for phi in [0.0f64, 0.4, 1.2, 2.5] {
        let sliver = fp(a * phi.cos() + b * phi.sin(), b * phi.cos() - a * phi.sin());
        let out = each.clamp_h_max(sliver, &ctx(0.01));
        let axes = out.principal_axes();
        assert!((axes.semi_major - 0.25).abs() < 1e-12 && (axes.semi_minor - 0.05).abs() < 1e-12, "φ {phi}: {axes:?}");
        assert!(axes.major_dir.dot(DVec3::X).abs() > 1.0 - 1e-12, "φ {phi}: {axes:?}");
        assert!((out.area() - core::f64::consts::PI * 0.25 * 0.05).abs() < 1e-12);
    }
}

#[test]
fn degenerate_removal_at_its_threshold() {
    let h = Heuristics { degenerate: Some(DegenerateRemoval { fraction: 0.05 }), ..Heuristics::NONE };
    // Degenerate iff the axis ratio σ₂/σ₁ < f: for orthogonal differentials |Dv|/|Du|; for
    // equal lengths at angle α, tan(α/2) (threshold α = 5.72°); for |Dv| = 0.1 |Du|, α ≈ 30.1°.
    let major = DVec3::X * 0.2;
    for (ratio, angle, degenerate) in [(0.049, 90.0f64, true), (0.051, 90.0, false), (1.0, 5.7, true), (1.0, 5.75, false), (0.1, 29.0, true), (0.1, 31.0, false)] {
        let a = angle.to_radians();
        let dv = (DVec3::X * a.cos() + DVec3::Z * a.sin()) * 0.2 * ratio;
        let f = fp(major, dv);
        assert_eq!(h.is_degenerate(&f), degenerate, "ratio {ratio}, α {angle}°");
        let outcome = h.apply(f, &ctx(0.01));
        assert_eq!(outcome.is_err(), degenerate);
    }
    // The same ellipses spanned by orthogonal re-mixings of the pair get the same verdicts.
    for (ratio, angle, degenerate) in [(1.0, 5.7f64, true), (1.0, 5.75, false), (0.1, 29.0, true), (0.1, 31.0, false)] {
        let a = angle.to_radians();
        let dv = (DVec3::X * a.cos() + DVec3::Z * a.sin()) * 0.2 * ratio;
        for phi in [0.3f64, 1.1, 2.0, 2.9] {
            let (c, s) = (phi.cos(), phi.sin());
            let f = fp(major * c + dv * s, dv * c - major * s);
            assert_eq!(h.is_degenerate(&f), degenerate, "ratio {ratio}, α {angle}°, φ {phi}");
        }
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
        h_max: Some(HMax { length: LengthSpec::Absolute(0.3), mode: HMaxMode::EachAxis }),
        degenerate: Some(DegenerateRemoval { fraction: 0.05 }),
        culling: Some(BoundingBoxCulling { fraction: 0.05, metric: CullMetric::LargestExtent }),
    };
    // Orthogonal differentials are the principal axes: 0.0016^(1/4) = 0.2: below h_max;
    // 0.0256^(1/4) = 0.4: clamped to 0.3.
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
    use arpa_core::store::footprint::FootprintError;
    use proptest::prelude::*;

    fn heuristics() -> impl Strategy<Value = Heuristics> {
        (any::<[bool; 4]>(), prop_oneof![Just(0.25), 0.1f64..0.9], any::<bool>(), any::<bool>(), 0.01f64..0.5, 0usize..3).prop_map(|(on, gamma, lit, aspect, f, metric)| Heuristics {
            dampening: on[0].then_some(Dampening { exponent: gamma, reference: if lit { DampenReference::Absolute(1.0) } else { DampenReference::ProgressiveDiameter } }),
            h_max: on[1].then_some(HMax { length: LengthSpec::RelativeToDiagonal(0.05), mode: if aspect { HMaxMode::PreserveAspect } else { HMaxMode::EachAxis } }),
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
                    // The same ellipse (the pairs themselves may differ where a near-circle's
                    // principal directions are ill-determined).
                    let (s1, s2) = (shape(&f1), shape(&f2));
                    prop_assert!((s1 - s2).abs().to_cols_array().iter().all(|x| *x <= 1e-9 * s1.col(0).length().max(s1.col(1).length()).max(s1.col(2).length())), "{:?} vs {:?}", f1, f2);
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

/// Orthogonal re-mixing `(D_u, D_v) ↦ (D_u, D_v) Q` spans the same ellipse; every heuristic
/// and the whole store must give the same verdict and the same ellipse, area, box and
/// record for every such `Q` (rotations and reflections).
mod remixing {
    use super::*;
    use arpa_core::store::footprint::{principal_axes, MIN_RELATIVE_SEMI_AXIS};
    use arpa_core::store::decision::StoredPhoton;
    use proptest::prelude::*;
    use proptest::strategy::ValueTree;

    /// Random configurations: each heuristic on or off, every mode, metric and reference;
    /// thresholds wide enough that every verdict occurs.
    fn heuristics() -> impl Strategy<Value = Heuristics> {
        (any::<[bool; 4]>(), prop_oneof![Just(0.25), 0.1f64..0.9], any::<bool>(), -2.5f64..0.0, any::<bool>(), 0.01f64..0.3, 0.002f64..0.05, 0usize..3).prop_map(
            |(on, gamma, lit, h_exp, aspect, f, cull, metric)| Heuristics {
                dampening: on[0].then_some(Dampening { exponent: gamma, reference: if lit { DampenReference::Absolute(0.05) } else { DampenReference::ProgressiveDiameter } }),
                h_max: on[1].then_some(HMax { length: LengthSpec::Absolute(10f64.powf(h_exp)), mode: if aspect { HMaxMode::PreserveAspect } else { HMaxMode::EachAxis } }),
                degenerate: on[2].then_some(DegenerateRemoval { fraction: f }),
                culling: on[3].then_some(BoundingBoxCulling { fraction: cull, metric: [CullMetric::LargestExtent, CullMetric::Diagonal, CullMetric::SurfaceArea][metric] }),
            },
        )
    }

    /// A footprint on a random plane: lengths 3e-3 … 3 m (the shorter down to 1e-2 of the
    /// longer), the angle between the differentials down to grazing (sin α ≥ 1e-3), any
    /// orientation.
    fn footprint() -> impl Strategy<Value = Footprint> {
        (
            (-1.0f64..1.0, 0.0f64..std::f64::consts::TAU),
            (-5.0f64..5.0, -5.0f64..5.0, -2.0f64..2.0),
            (0.0f64..std::f64::consts::TAU, -3.0f64..0.0, any::<bool>(), -2.5f64..0.5, -2.0f64..0.5),
            any::<bool>(),
        )
            .prop_map(|((z, phi), (x, y, zc), (rot, sin_exp, obtuse, la, lb_rel), caustic)| {
                let r = (1.0 - z * z).sqrt();
                let normal = DVec3::new(r * phi.cos(), r * phi.sin(), z);
                let t1 = normal.any_orthonormal_vector();
                let t2 = normal.cross(t1);
                let alpha = {
                    let a = 10f64.powf(sin_exp).asin();
                    if obtuse { std::f64::consts::PI - a } else { a }
                };
                let dir = |t: f64| t1 * t.cos() + t2 * t.sin();
                let la = 10f64.powf(la);
                Footprint {
                    center: DVec3::new(x, y, zc),
                    normal,
                    du: dir(rot) * la,
                    dv: dir(rot + alpha) * la * 10f64.powf(lb_rel),
                    flux: DVec3::new(1.0, 0.5, 0.25),
                    map: if caustic { PhotonMap::Caustic } else { PhotonMap::Global },
                }
            })
    }

    /// `(D_u, D_v) Q` for the rotation by `phi`, or the reflection across the line at `phi/2`.
    fn remix(f: &Footprint, phi: f64, reflect: bool) -> Footprint {
        let (c, s) = (phi.cos(), phi.sin());
        let (du, dv) = if reflect { (f.du * c + f.dv * s, f.du * s - f.dv * c) } else { (f.du * c + f.dv * s, f.dv * c - f.du * s) };
        Footprint { du, dv, ..*f }
    }

    fn close_mat(a: DMat3, b: DMat3, tol: f64) -> bool {
        let scale = a.col(0).length().max(a.col(1).length()).max(a.col(2).length());
        (a - b).abs().to_cols_array().iter().all(|x| *x <= tol * scale)
    }

    fn close(a: f64, b: f64, tol: f64) -> bool {
        (a - b).abs() <= tol * a.abs().max(b.abs())
    }

    /// The filter's quadratic form `row_uᵀrow_u + row_vᵀrow_v` (1/m²) of a record: the same
    /// for every pair spanning the ellipse (the rows themselves rotate in filter space).
    fn filter_form(p: &arpa_core::store::footprint::PackedFootprint) -> DMat3 {
        let outer = |a: [f32; 3]| {
            let v = glam::Vec3::from_array(a).as_dvec3();
            DMat3::from_cols(v * v.x, v * v.y, v * v.z)
        };
        outer(p.row_u) + outer(p.row_v)
    }

    /// `true` when a verdict of `h` on `f` (smoothed by `smoothing`) lies within 1e-9
    /// relative of its threshold, where rounding may decide it differently for two pairs.
    fn near_threshold(h: &Heuristics, f: &Footprint, smoothing: f64, radius: f64) -> bool {
        let c = ctx(radius);
        let f = h.clamp_h_max(h.dampen(f.scaled(smoothing), &c), &c);
        let near = |x: f64, t: f64| (x / t - 1.0).abs() < 1e-9;
        let axes = f.principal_axes();
        let ratio = axes.semi_minor / axes.semi_major;
        let deg = h.degenerate.is_some_and(|d| near(ratio, d.fraction));
        let cull = h.culling.is_some_and(|cull| {
            let b = f.aabb(radius);
            let (mine, scene) = match cull.metric {
                CullMetric::LargestExtent => (b.largest_extent(), scene().largest_extent()),
                CullMetric::Diagonal => (b.diagonal(), scene().diagonal()),
                CullMetric::SurfaceArea => (b.surface_area(), scene().surface_area()),
            };
            near(mine, cull.fraction * scene)
        });
        let scale = f.center.abs().max_element().max(1e-30) * MIN_RELATIVE_SEMI_AXIS;
        deg || cull || (f.minor_semi_axis_bound() / scale - 1.0).abs() < 1e-6
    }

    proptest! {
        #![proptest_config(ProptestConfig { cases: 4000, ..ProptestConfig::default() })]

        /// The principal axes are those of the ellipse: `σ₁² + σ₂²` and `σ₁σ₂` are the
        /// trace and area invariants of `a aᵀ + b bᵀ`, the directions are orthonormal in the
        /// tangent plane, the principal differentials span the same ellipse with the same
        /// orientation, and all of it is the same for every re-mixing.
        #[test]
        fn principal_axes_are_the_ellipses_and_invariant(f in footprint(), phi in 0.0f64..std::f64::consts::TAU, reflect in any::<bool>()) {
            let axes = principal_axes(f.du, f.dv, f.normal);
            let (a, b) = (f.du * 0.5, f.dv * 0.5);
            let (s1, s2) = (axes.semi_major, axes.semi_minor);
            prop_assert!(s1 >= s2 && s2 > 0.0);
            prop_assert!(close(s1 * s1 + s2 * s2, a.length_squared() + b.length_squared(), 1e-12));
            prop_assert!(close(s1 * s2, a.cross(b).length(), 1e-9));
            prop_assert!((axes.major_dir.length() - 1.0).abs() < 1e-12 && (axes.minor_dir.length() - 1.0).abs() < 1e-12);
            prop_assert!(axes.major_dir.dot(axes.minor_dir).abs() < 1e-12 && axes.major_dir.dot(f.normal).abs() < 1e-12);
            let p = f.to_principal();
            prop_assert!(close_mat(shape(&p), shape(&f), 1e-12));
            prop_assert!(p.du.cross(p.dv).dot(f.normal) * f.du.cross(f.dv).dot(f.normal) > 0.0, "orientation changed");
            prop_assert!(close(p.area(), f.area(), 1e-9));
            let g = remix(&f, phi, reflect);
            let axes_g = g.principal_axes();
            prop_assert!(close(axes_g.semi_major, s1, 1e-12) && close(axes_g.semi_minor, s2, 1e-9));
            prop_assert!(close_mat(shape(&g.to_principal()), shape(&p), 1e-12));
            prop_assert!(close(g.half_thickness(0.01), f.half_thickness(0.01), 1e-9));
            let (bf, bg) = (f.aabb(0.01), g.aabb(0.01));
            prop_assert!((bf.min - bg.min).abs().max_element() <= 1e-12 * (1.0 + bf.diagonal()) && (bf.max - bg.max).abs().max_element() <= 1e-12 * (1.0 + bf.diagonal()));
        }

        /// Each heuristic alone and `Heuristics::apply`: the same verdict, ellipse, area and
        /// box for the footprint and any orthogonal re-mixing of its differentials.
        #[test]
        fn heuristics_are_invariant_under_remixing(h in heuristics(), f in footprint(), radius in 1e-3f64..0.1, phi in 0.0f64..std::f64::consts::TAU, reflect in any::<bool>()) {
            prop_assume!(!near_threshold(&h, &f, 1.0, radius));
            let c = ctx(radius);
            let g = remix(&f, phi, reflect);
            let (df, dg) = (h.dampen(f, &c), h.dampen(g, &c));
            prop_assert!(close_mat(shape(&df), shape(&dg), 1e-10) && close(df.area(), dg.area(), 1e-9), "dampening");
            let (cf, cg) = (h.clamp_h_max(df, &c), h.clamp_h_max(dg, &c));
            prop_assert!(close_mat(shape(&cf), shape(&cg), 1e-10) && close(cf.area(), cg.area(), 1e-9), "H-max: {:?} vs {:?}", cf, cg);
            prop_assert_eq!(h.is_degenerate(&cf), h.is_degenerate(&cg), "degenerate removal");
            prop_assert_eq!(h.is_culled(&cf.aabb(radius), &c), h.is_culled(&cg.aabb(radius), &c), "culling");
            match (h.apply(f, &c), h.apply(g, &c)) {
                (Ok((ff, bf)), Ok((fg, bg))) => {
                    prop_assert!(close_mat(shape(&ff), shape(&fg), 1e-10));
                    prop_assert!(close(ff.area(), fg.area(), 1e-9));
                    let tol = 1e-9 * bf.diagonal();
                    prop_assert!((bf.min - bg.min).abs().max_element() <= tol && (bf.max - bg.max).abs().max_element() <= tol);
                }
                (rf, rg) => prop_assert_eq!(rf.err(), rg.err()),
            }
        }

        /// `store_footprint` (smoothing, then the fused heuristics and packing): the same
        /// outcome (footprint, or progressive photon with the same reason), and for
        /// footprints the same filter (quadratic form of the rows), density (so area), slab
        /// and box.
        #[test]
        fn store_footprint_is_invariant_under_remixing(h in heuristics(), f in footprint(), radius in 1e-3f64..0.1, s in 0.3f64..3.0, phi in 0.0f64..std::f64::consts::TAU, reflect in any::<bool>()) {
            prop_assume!(!near_threshold(&h, &f, s, radius));
            let smoothing = Smoothing { caustic: s, global: s };
            let resolved = h.resolve(&scene());
            let g = remix(&f, phi, reflect);
            match (store_footprint(f, &smoothing, &resolved, radius), store_footprint(g, &smoothing, &resolved, radius)) {
                (StoredPhoton::Footprint { packed: pf, aabb: bf }, StoredPhoton::Footprint { packed: pg, aabb: bg }) => {
                    prop_assert!(close_mat(filter_form(&pf), filter_form(&pg), 1e-5), "filter {:?} vs {:?}", pf, pg);
                    for (x, y) in pf.flux_density().to_array().iter().zip(pg.flux_density().to_array()) {
                        prop_assert!(close(*x as f64, y as f64, 1e-5), "density {:?} vs {:?}", pf, pg);
                    }
                    prop_assert!((glam::Vec3::from_array(pf.row_n) - glam::Vec3::from_array(pg.row_n)).length() <= 1e-5 * glam::Vec3::from_array(pf.row_n).length());
                    let tol = 1e-9 * bf.diagonal();
                    prop_assert!((bf.min - bg.min).abs().max_element() <= tol && (bf.max - bg.max).abs().max_element() <= tol);
                }
                (StoredPhoton::Progressive { reason: rf, .. }, StoredPhoton::Progressive { reason: rg, .. }) => prop_assert_eq!(rf, rg),
                (a, b) => prop_assert!(false, "{:?} vs {:?}", a, b),
            }
        }
    }

    /// The strategies reach every verdict often, so the invariance tests above test each.
    #[test]
    fn remixing_cases_reach_every_verdict() {
        let mut runner = proptest::test_runner::TestRunner::deterministic();
        let mut counts = std::collections::HashMap::new();
        for _ in 0..4000 {
            let (h, f, radius) = (heuristics(), footprint(), 1e-3f64..0.1).new_tree(&mut runner).unwrap().current();
            let verdict = match h.resolve(&scene()).store(f, radius) {
                Ok(_) => "stored",
                Err(ProgressiveReason::Degenerate) if h.degenerate.is_some() => "degenerate",
                Err(ProgressiveReason::Culled) => "culled",
                Err(ProgressiveReason::Unrepresentable) => "unrepresentable",
                Err(_) => "other",
            };
            let clamped = h.h_max.is_some_and(|hm| h.dampen(f, &ctx(radius)).principal_axes().semi_major * 2.0 > hm.length.resolve(&scene()));
            *counts.entry(verdict).or_insert(0usize) += 1;
            if clamped && verdict == "stored" {
                *counts.entry("clamped and stored").or_insert(0usize) += 1;
            }
        }
        for v in ["stored", "degenerate", "culled", "clamped and stored"] {
            assert!(counts.get(v).copied().unwrap_or(0) > 100, "{counts:?}");
        }
    }
}
