//! The core's photon pipeline through the `arpa` facade, end to end on an analytic scene:
//! a point light over a diffuse plane. Photons are emitted, transferred onto the plane,
//! classified, stored with the default smoothing and heuristics (so footprints and
//! progressive-photon fallbacks mix), gathered by brute force and accumulated over
//! iterations. The result must match `I cos θ / r²` and the stored flux must equal the
//! light's flux that reaches the plane.

use arpa::core::base::aabb::Aabb;
use arpa::core::accumulate::image::RunningMean;
use arpa::core::propagate::classify::{PathClassifier, Smoothing, SurfaceInteraction};
use arpa::core::emit::emission::{EmissionParams, Light, PointLight};
use arpa::core::gather::estimate::{gather_brute_force, QueryPoint};
use arpa::core::store::footprint::{Footprint, PackedFootprint, PhotonMap};
use arpa::core::store::heuristics::{DegenerateRemoval, HeuristicContext, Heuristics};
use arpa::core::gather::kernel::Kernel;
use arpa::core::store::progressive_photon::PackedPhoton;
use arpa::core::accumulate::radius::ProgressiveConfig;
use arpa::core::base::rng::{Rng, StreamDomain};
use arpa::core::store::decision::{store_footprint, StoredPhoton};
use glam::{DVec3, Vec3};

const HEIGHT: f64 = 1.0;
const INTENSITY: f64 = 2.0;

struct Iteration {
    footprints: Vec<PackedFootprint>,
    photons: Vec<PackedPhoton>,
    radii: [f64; 2],
    stored_flux: f64,
    floor_flux: f64,
}

fn run_iteration(light: &Light, scene: &Aabb, iteration: u32, n: u32) -> Iteration {
    let radii = ProgressiveConfig::default().radii(scene, iteration + 1);
    let (centre, radius) = (scene.centre(), 0.5 * scene.diagonal());
    let mut shift = Rng::new(3, iteration, 0, StreamDomain::Iteration);
    let params = EmissionParams { photon_count: n, scale: 1.0, scene_sphere: (centre, radius), lattice_shift: shift.next_2d(), ..EmissionParams::new(n) };
    // A strict degenerate threshold turns the footprints stretched by oblique incidence
    // (ratio of the differentials ≈ cos θ) into progressive photons beyond ρ ≈ 0.9, so both
    // kinds of stored photon meet at the query rings.
    let heuristics = Heuristics { degenerate: Some(DegenerateRemoval { fraction: 0.75 }), ..Heuristics::default() };
    let smoothing = Smoothing::default();
    let mut out = Iteration { footprints: vec![], photons: vec![], radii, stored_flux: 0.0, floor_flux: 0.0 };
    for i in 0..n {
        let mut rng = Rng::new(3, iteration, i, StreamDomain::Photon);
        let photon = light.emit(i, &params, &mut rng).expect("valid light");
        let ray = photon.ray;
        if ray.d.y >= -1e-9 {
            continue; // leaves the scene upwards
        }
        let t = -ray.p.y / ray.d.y;
        let x = ray.p + ray.d * t;
        if !scene.contains(x) {
            continue; // misses the finite floor
        }
        out.floor_flux += photon.flux.x;
        let map = PathClassifier::new().record(SurfaceInteraction::Diffuse).unwrap();
        assert_eq!(map, PhotonMap::Global, "direct light is global");
        let hit = ray.transfer(t, DVec3::Y).expect("not grazing inside the floor");
        let fp = Footprint::from_hit(&hit, DVec3::Y, photon.flux, map).unwrap();
        let ctx = HeuristicContext { radius: radii[map.index()], scene_bounds: *scene };
        match store_footprint(fp, &smoothing, &heuristics.resolve(&ctx.scene_bounds), ctx.radius) {
            StoredPhoton::Footprint { packed, .. } => {
                out.stored_flux += packed.flux_density().x as f64 * fp_parallelogram(&packed) / 4.0;
                out.footprints.push(packed);
            }
            StoredPhoton::Progressive { photon, .. } => {
                out.stored_flux += photon.flux[0] as f64;
                out.photons.push(photon);
            }
        }
    }
    out
}

/// `|D_u × D_v|` recovered from the packed rows: `4 / |row_u × row_v|`.
fn fp_parallelogram(p: &PackedFootprint) -> f64 {
    4.0 / Vec3::from_array(p.row_u).as_dvec3().cross(Vec3::from_array(p.row_v).as_dvec3()).length()
}

#[test]
fn point_light_over_plane_through_the_whole_core() {
    let light = Light::Point(PointLight { position: DVec3::new(0.0, HEIGHT, 0.0), intensity: DVec3::splat(INTENSITY) });
    let scene = Aabb { min: DVec3::new(-4.0, 0.0, -4.0), max: DVec3::new(4.0, HEIGHT, 4.0) };
    let radii_of_rings = [0.0, 0.5, 1.0, 1.5];
    let points: Vec<Vec<(f64, f64)>> = radii_of_rings
        .iter()
        .map(|&rho| {
            (0..128)
                .map(|i| {
                    let phi = i as f64 * std::f64::consts::TAU / 128.0;
                    let r = if rho == 0.0 { 0.1 * ((i % 8) as f64 + 1.0) / 8.0 } else { rho };
                    (r * phi.cos(), r * phi.sin())
                })
                .collect()
        })
        .collect();
    let mut means: Vec<Vec<RunningMean>> = points.iter().map(|p| vec![RunningMean::new(); p.len()]).collect();
    let (mut footprints, mut photons) = (0usize, 0usize);
    for it in 0..8 {
        let iteration = run_iteration(&light, &scene, it, 100_000);
        // Storing neither creates nor destroys flux.
        assert!((iteration.stored_flux / iteration.floor_flux - 1.0).abs() < 1e-5, "{} vs {}", iteration.stored_flux, iteration.floor_flux);
        footprints += iteration.footprints.len();
        photons += iteration.photons.len();
        for (ring, acc) in points.iter().zip(&mut means) {
            for (&(x, z), m) in ring.iter().zip(acc.iter_mut()) {
                let q = QueryPoint { position: Vec3::new(x as f32, 0.0, z as f32), normal: Vec3::Y };
                let e = gather_brute_force(&q, &iteration.footprints, &iteration.photons, iteration.radii, Kernel::Silverman);
                m.add(e.lambertian_radiance(DVec3::splat(0.5)));
            }
        }
    }
    eprintln!("stored {footprints} footprints and {photons} progressive photons");
    // Both kinds of stored photon took part.
    assert!(footprints > 100_000 && photons > 100_000, "footprints {footprints}, progressive photons {photons}");
    for ((rho, ring), acc) in radii_of_rings.iter().zip(&points).zip(&means) {
        let analytic: f64 = ring.iter().map(|&(x, z)| {
            let r2 = HEIGHT * HEIGHT + x * x + z * z;
            0.5 / std::f64::consts::PI * INTENSITY * (HEIGHT / r2.sqrt()) / r2
        }).sum::<f64>() / ring.len() as f64;
        let estimate: f64 = acc.iter().map(|m| m.mean().x).sum::<f64>() / acc.len() as f64;
        eprintln!("ρ = {rho}: radiance {estimate:.5} vs analytic {analytic:.5} ({:+.2}%)", (estimate / analytic - 1.0) * 100.0);
        assert!((estimate / analytic - 1.0).abs() < 0.02, "radiance at ρ = {rho}: {estimate} vs analytic {analytic}");
    }
}
