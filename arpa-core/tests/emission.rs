//! Emission: fluxes sum to the light's power, point-light footprints tile the sphere, and
//! footprint density estimates reproduce analytic irradiance.

use arpa_core::emit::emission::*;
use std::collections::HashMap;
use arpa_core::store::footprint::{Footprint, PackedFootprint, PhotonMap};
use arpa_core::gather::kernel::Kernel;
use arpa_core::base::rng::{Rng, StreamDomain};
use glam::{DVec2, DVec3, Vec3};
use std::f64::consts::PI;

fn params(n: u32, iteration: u32) -> EmissionParams {
    let mut r = Rng::new(1, iteration, 0, StreamDomain::Iteration);
    EmissionParams { photon_count: n, scale: 1.0, scene_sphere: (DVec3::new(0.0, 1.0, 0.0), 3.0), lattice_shift: r.next_2d(), ..EmissionParams::new(n) }
}

fn emit_all(light: &Light, p: &EmissionParams, iteration: u32) -> Vec<EmittedPhoton> {
    (0..p.photon_count)
        .map(|i| {
            let mut rng = Rng::new(7, iteration, i, StreamDomain::Photon);
            light.emit(i, p, &mut rng).unwrap()
        })
        .collect()
}

fn lights() -> Vec<Light> {
    vec![
        Light::Point(PointLight { position: DVec3::new(0.0, 2.0, 0.0), intensity: DVec3::new(10.0, 5.0, 1.0) }),
        Light::Spot(SpotLight { position: DVec3::new(0.0, 2.0, 0.0), direction: -DVec3::Y, intensity: DVec3::new(100.0, 80.0, 60.0), cutoff: 0.6, beam_width: 0.5, falloff: SpotFalloff::LinearAngle }),
        Light::Spot(SpotLight { position: DVec3::ZERO, direction: DVec3::new(1.0, -1.0, 0.0), intensity: DVec3::ONE, cutoff: 1.2, beam_width: 0.2, falloff: SpotFalloff::SmoothstepAngle }),
        Light::Directional(DirectionalLight { direction: DVec3::new(0.3, -1.0, 0.2), irradiance: DVec3::new(2.0, 2.0, 1.0) }),
        Light::Triangle(TriangleLight { p: [DVec3::new(0.0, 2.0, 0.0), DVec3::new(0.0, 2.0, 0.5), DVec3::new(0.4, 2.0, 0.0)], radiance: DVec3::splat(3.0) }),
        Light::Quad(QuadLight { origin: DVec3::new(-0.2, 2.0, -0.2), edge_u: DVec3::new(0.0, 0.0, 0.4), edge_v: DVec3::new(0.4, 0.0, 0.0), radiance: DVec3::new(1.0, 2.0, 3.0) }),
    ]
}

#[test]
fn fluxes_sum_to_light_power() {
    for light in lights() {
        let p = params(20_000, 0);
        let sum: DVec3 = emit_all(&light, &p, 0).iter().map(|e| e.flux).sum();
        let power = light.power(p.scene_sphere.1);
        let rel = ((sum - power).abs() / power).max_element();
        // Exact for uniform-flux lights; spot falloff is integrated by the stratified
        // lattice (quasi-Monte Carlo), so allow 0.1%.
        assert!(rel < 1e-3, "{light:?}: photons carry {sum}, light emits {power}");
    }
}

/// The analytic spot power `2πI[1 − (sin θc − sin θb)/(θc − θb)]` of a linear falloff
/// against brute-force quadrature of the falloff.
#[test]
fn spot_power_closed_form() {
    let s = SpotLight { position: DVec3::ZERO, direction: DVec3::Y, intensity: DVec3::ONE, cutoff: 0.9, beam_width: 0.3, falloff: SpotFalloff::LinearAngle };
    let n = 1_000_000;
    let h = PI / n as f64;
    let numeric: f64 = (0..n).map(|i| {
        let t = (i as f64 + 0.5) * h;
        s.falloff_at(t) * t.sin()
    }).sum::<f64>() * 2.0 * PI * h;
    assert!((numeric - s.falloff_solid_angle()).abs() < 1e-9);
}

/// From a point light, `N` footprints on a sphere of radius `r` around it cover
/// `4πr²` within 2%.
#[test]
fn point_light_footprints_tile_sphere() {
    let light = Light::Point(PointLight { position: DVec3::new(1.0, 2.0, 3.0), intensity: DVec3::ONE });
    for n in [1_000u32, 50_000] {
        let p = params(n, 3);
        let r = 2.5;
        let total: f64 = emit_all(&light, &p, 3)
            .iter()
            .map(|e| {
                let hit = e.ray.transfer(r, e.ray.d).unwrap();
                Footprint::from_hit(&hit, e.ray.d, e.flux, PhotonMap::Global).unwrap().area()
            })
            .sum();
        let sphere = 4.0 * PI * r * r;
        assert!((total / sphere - 1.0).abs() < 0.02, "N = {n}: footprints cover {total}, sphere {sphere}");
    }
}

/// Footprints on the floor `y = 0`, bucketed in a uniform grid over x and z so that a
/// query only tests the footprints whose boxes overlap its cell.
struct FloorFootprints {
    cell: f64,
    footprints: Vec<PackedFootprint>,
    buckets: HashMap<(i64, i64), Vec<u32>>,
}

impl FloorFootprints {
    fn candidates(&self, x: f64, z: f64) -> impl Iterator<Item = &PackedFootprint> {
        let key = ((x / self.cell).floor() as i64, (z / self.cell).floor() as i64);
        self.buckets.get(&key).into_iter().flatten().map(|&i| &self.footprints[i as usize])
    }
}

/// Packed footprints of every photon that lands on the plane `y = 0`.
fn footprints_on_floor(light: &Light, n: u32, iteration: u32, smoothing: f64) -> FloorFootprints {
    let p = params(n, iteration);
    let cell = 0.05;
    let mut buckets: HashMap<(i64, i64), Vec<u32>> = HashMap::new();
    let mut footprints = vec![];
    for e in emit_all(light, &p, iteration).iter().filter(|e| e.ray.d.y < -1e-6) {
        let t = -e.ray.p.y / e.ray.d.y;
        let Ok(hit) = e.ray.transfer(t, DVec3::Y) else { continue };
        let Ok(fp) = Footprint::from_hit(&hit, DVec3::Y, e.flux, PhotonMap::Global) else { continue };
        let fp = fp.scaled(smoothing);
        let Ok(packed) = fp.pack(1.0) else { continue };
        // Only the square |x|, |z| ≤ QUERY_EXTENT is ever queried: clip the boxes to it.
        let bb = fp.aabb(1.0);
        let lo = bb.min.max(DVec3::splat(-QUERY_EXTENT));
        let hi = bb.max.min(DVec3::splat(QUERY_EXTENT));
        if lo.x > hi.x || lo.z > hi.z {
            continue;
        }
        // Every query point lies within QUERY_RADIUS of the origin: a footprint whose box
        // stays outside that disc cannot contain one. Leaving such boxes out keeps the long
        // grazing footprints from far away from filling the whole grid.
        let nearest = DVec3::ZERO.clamp(bb.min, bb.max);
        if (nearest.x * nearest.x + nearest.z * nearest.z).sqrt() > QUERY_RADIUS {
            continue;
        }
        let (x0, x1) = ((lo.x / cell).floor() as i64, (hi.x / cell).floor() as i64);
        let (z0, z1) = ((lo.z / cell).floor() as i64, (hi.z / cell).floor() as i64);
        for i in x0..=x1 {
            for j in z0..=z1 {
                buckets.entry((i, j)).or_default().push(footprints.len() as u32);
            }
        }
        footprints.push(packed);
    }
    FloorFootprints { cell, footprints, buckets }
}


/// Mean estimate over each set of points in `sets` and over PASSES iterations, for each
/// kernel (one filter transform per footprint and point, three kernel evaluations).
fn mean_estimates(light: &Light, sets: &[Vec<(f64, f64)>]) -> Vec<[f64; 3]> {
    let kernels = [Kernel::Constant, Kernel::Epanechnikov, Kernel::Silverman];
    let mut sums = vec![[0.0; 3]; sets.len()];
    // One iteration in memory at a time.
    for fps in (0..PASSES).map(|it| footprints_on_floor(light, PHOTONS, it, SMOOTHING)) {
        for (points, sum) in sets.iter().zip(&mut sums) {
            for &(x, z) in points {
                let q = Vec3::new(x as f32, 0.0, z as f32);
                for fp in fps.candidates(x, z) {
                    for (k, kernel) in kernels.iter().enumerate() {
                        sum[k] += fp.irradiance(q, Vec3::Y, *kernel).x as f64;
                    }
                }
            }
        }
    }
    sums.iter().zip(sets).map(|(s, points)| s.map(|v| v / (PASSES as usize * points.len()) as f64)).collect()
}

/// `count` points on the circle of radius `rho` around the origin (for 0: on eight circles
/// of radii up to 0.1).
fn ring(rho: f64, count: usize) -> Vec<(f64, f64)> {
    (0..count)
        .map(|i| {
            let phi = i as f64 * std::f64::consts::TAU / count as f64;
            let r = if rho == 0.0 { 0.1 * ((i % 8) as f64 + 1.0) / 8.0 } else { rho };
            (r * phi.cos(), r * phi.sin())
        })
        .collect()
}

/// Irradiance on a plane below a point light, estimated from the footprints alone,
/// matches `I cos θ / r²` within 2% away from the horizon (θ ≤ 70°), for each kernel.
///
/// A single footprint estimate fluctuates with the query's position relative to the
/// emission lattice (each photon's footprint covers its own `1/N` share, so only a few
/// overlap any point); the estimator is unbiased over the per-iteration lattice shifts.
/// The test therefore averages PASSES iterations and POINTS points of equal analytic irradiance
/// (a circle around the foot of the light), like an image averages iterations.
#[test]
fn point_light_irradiance_on_plane() {
    let h = 1.0;
    let intensity = 4.0;
    let light = Light::Point(PointLight { position: DVec3::new(0.0, h, 0.0), intensity: DVec3::splat(intensity) });
    let mut worst: f64 = 0.0;
    let radii = [0.0f64, 0.3, 0.7, 1.0, 1.5, 2.0, 2.7];
    let sets: Vec<_> = radii.iter().map(|&rho| ring(rho, POINTS)).collect();
    for ((rho, points), estimates) in radii.iter().zip(&sets).zip(mean_estimates(&light, &sets)) {
        let analytic = points.iter().map(|&(x, z)| {
            let r2 = h * h + x * x + z * z;
            intensity * (h / r2.sqrt()) / r2
        }).sum::<f64>() / points.len() as f64;
        for (k, est) in estimates.into_iter().enumerate() {
            let rel = (est / analytic - 1.0).abs();
            worst = worst.max(rel);
            assert!(rel < 0.02, "kernel #{k} at ρ = {rho}: estimate {est}, analytic {analytic} ({:.2}% off)", rel * 100.0);
        }
    }
    eprintln!("point light over plane: worst relative error {:.3}%", worst * 100.0);
}

/// A directional light on the plane: irradiance `E cos θ` everywhere inside the aperture.
#[test]
fn directional_light_irradiance_on_plane() {
    let dir = DVec3::new(0.5, -1.0, 0.0).normalize();
    let e = 3.0;
    let light = Light::Directional(DirectionalLight { direction: dir, irradiance: DVec3::splat(e) });
    let analytic = e * dir.dot(-DVec3::Y);
    let radii = [0.0, 0.5, 1.0];
    let sets: Vec<_> = radii.iter().map(|&rho| ring(rho, POINTS)).collect();
    for (rho, estimates) in radii.iter().zip(mean_estimates(&light, &sets)) {
        for (k, est) in estimates.into_iter().enumerate() {
            assert!((est / analytic - 1.0).abs() < 0.02, "kernel #{k} at ρ = {rho}: {est} vs {analytic}");
        }
    }
}

/// A quad area light above the plane: the footprint estimate matches the irradiance of
/// a Lambertian rectangle computed by quadrature, `E(q) = ∫ L cos θ_q cos θ_l / d² dA`.
#[test]
fn quad_light_irradiance_on_plane() {
    let l = QuadLight { origin: DVec3::new(-0.25, 1.0, -0.25), edge_u: DVec3::new(0.5, 0.0, 0.0), edge_v: DVec3::new(0.0, 0.0, 0.5), radiance: DVec3::splat(2.0) };
    // edge_u × edge_v = +x × +z = −y: emits downwards.
    let light = Light::Quad(l);
    let exact = |q: DVec3| {
        let m = 200;
        let mut e = 0.0;
        for i in 0..m {
            for j in 0..m {
                let p = l.origin + l.edge_u * ((i as f64 + 0.5) / m as f64) + l.edge_v * ((j as f64 + 0.5) / m as f64);
                let d = p - q;
                let d2 = d.length_squared();
                let cos = d.y / d2.sqrt();
                e += 2.0 * cos * cos / d2;
            }
        }
        e * 0.25 / (m * m) as f64
    };
    let radii = [0.0, 0.6, 1.2];
    let sets: Vec<_> = radii.iter().map(|&rho| ring(rho, POINTS)).collect();
    for ((rho, points), estimates) in radii.iter().zip(&sets).zip(mean_estimates(&light, &sets)) {
        let analytic = points.iter().map(|&(x, z)| exact(DVec3::new(x, 0.0, z))).sum::<f64>() / points.len() as f64;
        for (k, est) in estimates.into_iter().enumerate() {
            assert!((est / analytic - 1.0).abs() < 0.02, "kernel #{k} at ρ = {rho}: {est} vs {analytic}");
        }
    }
}

#[test]
fn invalid_lights_are_rejected() {
    let p = params(10, 0);
    let mut rng = Rng::new(0, 0, 0, StreamDomain::Photon);
    let zero_area = Light::Quad(QuadLight { origin: DVec3::ZERO, edge_u: DVec3::X, edge_v: DVec3::X * 2.0, radiance: DVec3::ONE });
    assert_eq!(zero_area.emit(0, &p, &mut rng), Err(EmissionError::Light(LightError::ZeroArea)));
    let nan = Light::Point(PointLight { position: DVec3::NAN, intensity: DVec3::ONE });
    assert_eq!(nan.validate(1.0), Err(LightError::NonFinite));
    let dark = Light::Point(PointLight { position: DVec3::ZERO, intensity: DVec3::ZERO });
    assert_eq!(dark.validate(1.0), Err(LightError::ZeroPower));
    let neg = Light::Point(PointLight { position: DVec3::ZERO, intensity: -DVec3::ONE });
    assert_eq!(neg.validate(1.0), Err(LightError::NegativeEmission));
    let spot = Light::Spot(SpotLight { position: DVec3::ZERO, direction: DVec3::Y, intensity: DVec3::ONE, cutoff: 0.2, beam_width: 0.3, falloff: SpotFalloff::LinearAngle });
    assert_eq!(spot.validate(1.0), Err(LightError::BadSpotAngles));
    let dir = Light::Directional(DirectionalLight { direction: DVec3::Y, irradiance: DVec3::ONE });
    assert_eq!(dir.validate(0.0), Err(LightError::NoSceneBounds));
    let ok = Light::Point(PointLight { position: DVec3::ZERO, intensity: DVec3::ONE });
    let none = EmissionParams { photon_count: 0, ..p };
    assert_eq!(ok.emit(0, &none, &mut rng), Err(EmissionError::Light(LightError::NoPhotons)));
    let _ = DVec2::ZERO;
}
/// Smoothing factor of the footprints in the irradiance tests.
const SMOOTHING: f64 = 2.0;
/// Half-size of the square of the floor that holds every query point.
const QUERY_EXTENT: f64 = 3.0;
/// Every query point lies within this distance of the origin.
const QUERY_RADIUS: f64 = 2.8;
/// Iterations averaged.
const PASSES: u32 = 16;
/// Query points per circle.
const POINTS: usize = 1024;
/// Photons per iteration.
const PHOTONS: u32 = 100_000;
