//! Footprint geometry: the filter transform `M_p⁻¹`, the point-in-footprint test against
//! an independent parametric ellipse test, the AABB, kernel normalisation over the
//! ellipse, and re-emission with the virtual distance `v`.

use arpa_core::propagate::differential::RayDifferential;
use arpa_core::store::footprint::{Footprint, PhotonMap};
use arpa_core::gather::kernel::Kernel;
use arpa_core::propagate::reemission::{reemit, virtual_distance};
use arpa_core::base::rng::{Rng, StreamDomain};
use arpa_core::base::sampling::uniform_sphere;
use glam::{DMat2, DVec2, DVec3, Vec3};
use proptest::prelude::*;

fn unit() -> impl Strategy<Value = DVec3> {
    (0.0f64..1.0, 0.0f64..1.0).prop_map(|(a, b)| uniform_sphere(DVec2::new(a, b)))
}

/// A random non-degenerate footprint in the tangent plane of a random normal.
fn footprint() -> impl Strategy<Value = Footprint> {
    (unit(), -1e3f64..1e3, -1e3f64..1e3, -1e3f64..1e3, 1e-3f64..10.0, 1e-3f64..10.0, 0.05f64..3.09, 0.0f64..std::f64::consts::TAU).prop_map(
        |(n, x, y, z, la, lb, angle, rot)| {
            let f = arpa_core::base::frame::Frame::from_normal(n);
            let dir = |t: f64| f.t * t.cos() + f.b * t.sin();
            Footprint {
                center: DVec3::new(x, y, z),
                normal: n,
                du: dir(rot) * la,
                dv: dir(rot + angle) * lb,
                flux: DVec3::new(1.0, 0.5, 0.25),
                map: PhotonMap::Caustic,
            }
        },
    )
}

/// Independent ellipse coordinates: solve `q − x_p = α a + β b` in the least-squares sense
/// through the 2×2 Gram system (no cross products, unlike `M_p⁻¹`).
fn parametric_coords(fp: &Footprint, q: DVec3) -> DVec2 {
    let a = fp.du * 0.5;
    let b = fp.dv * 0.5;
    let delta = q - fp.center;
    let gram = DMat2::from_cols(DVec2::new(a.dot(a), a.dot(b)), DVec2::new(a.dot(b), b.dot(b)));
    gram.inverse() * DVec2::new(a.dot(delta), b.dot(delta))
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 2000, ..ProptestConfig::default() })]

    #[test]
    fn filter_transform_identities(fp in footprint()) {
        let m = fp.filter_transform().unwrap();
        let e1 = m.apply(fp.du * 0.5);
        let e2 = m.apply(fp.dv * 0.5);
        prop_assert!((e1 - DVec2::X).length() < 1e-9, "{e1}");
        prop_assert!((e2 - DVec2::Y).length() < 1e-9, "{e2}");
        let scale = m.row_u.length().max(m.row_v.length());
        prop_assert!(m.apply(fp.normal).length() < 1e-12 * scale);
        let det = m.determinant();
        let expected = 4.0 / fp.du.cross(fp.dv).length();
        prop_assert!((det - expected).abs() < 1e-9 * expected);
    }

    #[test]
    fn point_in_footprint_matches_parametric_test(fp in footprint(), s in 0.0f64..2.0, t in 0.0f64..std::f64::consts::TAU, off in -1.0f64..1.0) {
        // Points along rays from the centre, in the plane, at parametric radius s, plus a
        // normal offset inside or outside the slab.
        let radius = 0.01;
        let h = fp.half_thickness(radius);
        let a = fp.du * 0.5;
        let b = fp.dv * 0.5;
        let q = fp.center + (a * t.cos() + b * t.sin()) * s + fp.normal * (off * 2.0 * h);
        let inside_param = parametric_coords(&fp, q).length_squared() <= 1.0 && (off * 2.0).abs() <= 1.0;
        prop_assert!((parametric_coords(&fp, q).length() - s).abs() < 1e-6 * (1.0 + s));
        prop_assert_eq!(fp.contains(q, radius), inside_param);
        // The f32 record agrees away from the boundary: q − x_p is rounded to f32, which
        // moves filter coordinates by about 2 ε₃₂ |x_p| / σ₂ (σ₂ the minor semi-axis).
        let scale = fp.center.abs().max_element().max(1e-30);
        let s2 = fp.semi_axes().1;
        match fp.pack(radius) {
            Ok(packed) => {
                let margin = 1e-4 + 8.0 * f32::EPSILON as f64 * scale / s2.min(h);
                if (s - 1.0).abs() > margin && ((off * 2.0).abs() - 1.0).abs() > margin {
                    prop_assert_eq!(packed.contains(q.as_vec3()), inside_param, "s {} off {}", s, off);
                }
            }
            Err(e) => {
                prop_assert_eq!(e, arpa_core::store::footprint::FootprintError::Unrepresentable);
                prop_assert!(fp.minor_semi_axis_bound() < arpa_core::store::footprint::MIN_RELATIVE_SEMI_AXIS * scale);
                prop_assert!(s2 < std::f64::consts::SQRT_2 * arpa_core::store::footprint::MIN_RELATIVE_SEMI_AXIS * scale);
            }
        }
    }

    #[test]
    fn aabb_contains_whole_ellipse_and_slab(fp in footprint(), radius in 1e-4f64..1.0) {
        let bb = fp.aabb(radius);
        let h = fp.half_thickness(radius);
        let eps = 1e-9 * (1.0 + fp.center.abs().max_element());
        let grown = arpa_core::base::aabb::Aabb { min: bb.min - DVec3::splat(eps), max: bb.max + DVec3::splat(eps) };
        // Everything the point-in-footprint test accepts: the ellipse extruded by ±h n
        // (rim points on both faces of the slab).
        for k in 0..256 {
            let t = k as f64 / 256.0 * std::f64::consts::TAU;
            let p = fp.center + fp.du * 0.5 * t.cos() + fp.dv * 0.5 * t.sin();
            for side in [-1.0, 0.0, 1.0] {
                let q = p + fp.normal * (side * h);
                prop_assert!(grown.contains(q));
            }
        }
        // Tight along each axis: no more than the slab's parallelogram bound.
        let ext_max = (fp.du.abs() + fp.dv.abs()) * 0.5 + fp.normal.abs() * h;
        prop_assert!(bb.extent().cmple(ext_max * 2.0 + DVec3::splat(eps)).all());
    }
}

/// `∫ W_p = 1` over the ellipse for every kernel: Monte Carlo over the bounding
/// parallelogram `x_p + s a + t b`, `s, t ∈ [−1, 1]` (area `4|a × b|`), within 1%.
#[test]
fn kernels_integrate_to_one_over_ellipse() {
    let fps = [
        Footprint { center: DVec3::new(1.0, 2.0, 3.0), normal: DVec3::Y, du: DVec3::new(0.3, 0.0, 0.0), dv: DVec3::new(0.05, 0.0, 0.02), flux: DVec3::ONE, map: PhotonMap::Global },
        Footprint { center: DVec3::ZERO, normal: DVec3::new(1.0, 1.0, 1.0).normalize(), du: DVec3::new(1.0, -1.0, 0.0) * 1e-3, dv: DVec3::new(1.0, 1.0, -2.0) * 4e-3, flux: DVec3::ONE, map: PhotonMap::Global },
    ];
    for fp in fps {
        for kernel in [Kernel::Constant, Kernel::Epanechnikov, Kernel::Silverman] {
            let mut rng = Rng::new(5, 0, 0, StreamDomain::User);
            let n = 400_000;
            let a = fp.du * 0.5;
            let b = fp.dv * 0.5;
            let area = 4.0 * a.cross(b).length();
            let packed = fp.pack(1.0).unwrap();
            let (mut sum, mut sum_packed) = (0.0, 0.0);
            for _ in 0..n {
                let (s, t) = (2.0 * rng.next_f64() - 1.0, 2.0 * rng.next_f64() - 1.0);
                let q = fp.center + a * s + b * t;
                sum += fp.weight(q, 1.0, kernel);
                sum_packed += packed.irradiance(q.as_vec3(), fp.normal.as_vec3(), kernel).x as f64;
            }
            let integral = sum / n as f64 * area;
            let integral_packed = sum_packed / n as f64 * area;
            assert!((integral - 1.0).abs() < 0.01, "{kernel:?}: ∫W = {integral}");
            assert!((integral_packed - 1.0).abs() < 0.01, "{kernel:?} packed: ∫W = {integral_packed}");
        }
    }
}

/// The back side of a footprint receives nothing.
#[test]
fn back_side_gets_nothing() {
    let fp = Footprint { center: DVec3::ZERO, normal: DVec3::Y, du: DVec3::X * 0.1, dv: DVec3::Z * 0.1, flux: DVec3::ONE, map: PhotonMap::Global };
    let p = fp.pack(0.01).unwrap();
    assert!(p.irradiance(Vec3::ZERO, Vec3::Y, Kernel::Constant).x > 0.0);
    assert_eq!(p.irradiance(Vec3::ZERO, -Vec3::Y, Kernel::Constant), Vec3::ZERO);
}

/// Re-emission with `v` reproduces the absorbed footprint's area: at `t = 0` on the plane
/// perpendicular to the new direction the area is unchanged, after `t` it is `((v+t)ℓ)²`.
#[test]
fn reemission_reproduces_footprint_area() {
    let mut rng = Rng::new(9, 0, 0, StreamDomain::User);
    for _ in 0..1000 {
        // An absorbed photon: a random differential transferred onto a random plane.
        let n = uniform_sphere(rng.next_2d());
        let d = -(n + uniform_sphere(rng.next_2d()) * 0.9).normalize();
        if d.dot(n) > -0.05 {
            continue;
        }
        let mut r = || uniform_sphere(DVec2::new(rng.next_f64(), rng.next_f64())) * (0.01 + rng.next_f64());
        let ray = RayDifferential::new(DVec3::ZERO, d, r() * 0.1, r() * 0.1, r() * 0.05, r() * 0.05).unwrap().reprojected();
        let hit = ray.transfer(2.0, n).unwrap();
        let absorbed = hit.dp_du.cross(hit.dp_dv).length();
        let len = 0.01 + rng.next_f64() * 0.1;
        let new_dir = (n + uniform_sphere(rng.next_2d())).normalize_or(n);
        let out = reemit(hit.p, hit.dp_du, hit.dp_dv, new_dir, len).unwrap();
        let v = virtual_distance(absorbed, len).unwrap();
        // v² |∂D_u × ∂D_v| = A (ARPA eq. 2).
        assert!((v * v * out.dd_du.cross(out.dd_dv).length() - absorbed).abs() <= 1e-12 * absorbed.max(1e-300));
        let at0 = out.transfer(0.0, new_dir).unwrap();
        let area0 = at0.dp_du.cross(at0.dp_dv).length();
        assert!((area0 - absorbed).abs() <= 1e-9 * absorbed, "{area0} vs {absorbed}");
        let t = 1.5;
        let later = out.transfer(t, new_dir).unwrap();
        let expected = ((v + t) * len).powi(2);
        assert!((later.dp_du.cross(later.dp_dv).length() - expected).abs() <= 1e-9 * expected);
    }
}
