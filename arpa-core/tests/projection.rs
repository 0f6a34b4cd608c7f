//! Projection maps and the two photon passes (arpa_core::render::projection): the kept cells are
//! conservative (every ray that hits a target starts in one), projected emission carries
//! the kept part of the power and shares it evenly over the cells, the plan's skips and
//! weights, and the caustic power of the two passes against the exact mirror caustic.

use arpa_core::emit::emission::{DirectionalLight, EmissionParams, Light, PointLight, QuadLight, SpotFalloff, SpotLight, TriangleLight};
use arpa_core::base::frame::Frame;
use arpa_core::render::photon_path::{trace_photon, PhotonPassSetup};
use arpa_core::render::prepared_scene::PreparedScene;
use arpa_core::{render::projection::{project, DomainCells, Projector, Targets, AREA_GRID, DELTA_GRID}, render::emission_plan::EmissionPlan};
use arpa_core::render::brute_force::BruteForceCaster;
use arpa_core::base::rng::{Rng, StreamDomain};
use arpa_core::base::sampling::{cosine_hemisphere, uniform_cone, uniform_disc, uniform_sphere};
use arpa_core::render::scene::{Camera, Material, Scene, TriangleMesh};
use arpa_core::store::decision::StoredPhoton;
use arpa_core::render::tracer::{EmissionStrategy, PassSkip, RenderSettings};
use glam::{DVec2, DVec3, Vec3};
use std::f64::consts::PI;

/// Möller–Trumbore in f64: distance along the unit ray to the triangle, if it hits.
fn hit(o: DVec3, d: DVec3, t: &[DVec3; 3]) -> Option<f64> {
    let (e1, e2) = (t[1] - t[0], t[2] - t[0]);
    let p = d.cross(e2);
    let det = e1.dot(p);
    if det.abs() < 1e-300 {
        return None;
    }
    let s = o - t[0];
    let u = s.dot(p) / det;
    let q = s.cross(e1);
    let v = d.dot(q) / det;
    let dist = e2.dot(q) / det;
    (u >= 0.0 && v >= 0.0 && u + v <= 1.0 && dist > 0.0).then_some(dist)
}

/// `n` small triangles (edge about `size`) scattered in a box around `centre`.
fn scattered_triangles(n: usize, centre: DVec3, spread: f64, size: f64, seed: u32) -> Vec<[DVec3; 3]> {
    let mut rng = Rng::new(seed, 0, 0, StreamDomain::User);
    let mut r3 = || DVec3::new(rng.next_f64(), rng.next_f64(), rng.next_f64()) * 2.0 - 1.0;
    (0..n)
        .map(|_| {
            let c = centre + r3() * spread;
            [c + r3() * size, c + r3() * size, c + r3() * size]
        })
        .collect()
}

/// Every sample of a dense grid over the unit square whose ray (from `ray(u, k)`, `k`
/// indexing several origins for area lights) hits a target lies in a kept cell; returns
/// (hits, kept fraction).
fn check_conservative(cells: &DomainCells, targets: &[[DVec3; 3]], ray: impl Fn(DVec2, u32) -> (DVec3, DVec3), origins: u32) -> (usize, f64) {
    let kept: std::collections::HashSet<u32> = cells.cells.iter().copied().collect();
    let side = 640;
    let mut hits = 0;
    for j in 0..side {
        for i in 0..side {
            let u = DVec2::new((i as f64 + 0.5) / side as f64, (j as f64 + 0.5) / side as f64);
            for k in 0..origins {
                let (o, d) = ray(u, k);
                if targets.iter().any(|t| hit(o, d, t).is_some()) {
                    hits += 1;
                    if cells.grid != 0 {
                        let g = cells.grid as f64;
                        let cell = (u.x * g) as u32 + (u.y * g) as u32 * cells.grid;
                        assert!(kept.contains(&cell), "a ray through cell {cell} (u = {u:?}, origin {k}) hits a target, but the cell is not kept");
                    }
                }
            }
        }
    }
    (hits, cells.fraction())
}

#[test]
fn kept_cells_hold_every_ray_that_hits_a_target() {
    let targets = scattered_triangles(40, DVec3::new(0.3, -0.5, 0.2), 0.5, 0.06, 3);
    let spheres = Targets::new(targets.clone());
    let scene_sphere = (DVec3::ZERO, 3.0);
    let p0 = DVec3::new(0.0, 1.5, 0.0);
    // Point light.
    let point = Light::Point(PointLight { position: p0, intensity: DVec3::ONE });
    let cells = project(&point, scene_sphere, &spheres);
    let (hits, f) = check_conservative(&cells, &targets, |u, _| (p0, uniform_sphere(u)), 1);
    assert!(hits > 200 && f < 0.2, "point: {hits} hits, kept fraction {f}");
    // A point light inside the bounding sphere of large triangles (a floor and a ceiling
    // around it): their exact spherical triangles decide.
    let slabs = vec![
        [DVec3::new(-4.0, 0.0, -4.0), DVec3::new(4.0, 0.0, 4.0), DVec3::new(4.0, 0.0, -4.0)],
        [DVec3::new(-4.0, 0.0, -4.0), DVec3::new(-4.0, 0.0, 4.0), DVec3::new(4.0, 0.0, 4.0)],
        [DVec3::new(-4.0, 2.0, -4.0), DVec3::new(4.0, 2.0, -4.0), DVec3::new(4.0, 2.0, 4.0)],
    ];
    let inside = Light::Point(PointLight { position: DVec3::new(0.3, 1.0, -0.2), intensity: DVec3::ONE });
    let cells = project(&inside, scene_sphere, &Targets::new(slabs.clone()));
    let (hits, f) = check_conservative(&cells, &slabs, |u, _| (DVec3::new(0.3, 1.0, -0.2), uniform_sphere(u)), 1);
    assert!(hits > 100_000 && f < 0.95, "inside: {hits} hits, kept fraction {f}");
    // Spot light, 50° cone towards the targets.
    let axis = (DVec3::new(0.3, -0.5, 0.2) - p0).normalize();
    let spot = Light::Spot(SpotLight { position: p0, direction: axis, intensity: DVec3::ONE, cutoff: 50f64.to_radians(), beam_width: 40f64.to_radians(), falloff: SpotFalloff::LinearAngle });
    let cells = project(&spot, scene_sphere, &spheres);
    let frame = Frame::from_normal(axis);
    let cos = 50f64.to_radians().cos();
    let (hits, f) = check_conservative(&cells, &targets, |u, _| (p0, frame.to_world(uniform_cone(u, cos))), 1);
    assert!(hits > 1000 && f < 0.6, "spot: {hits} hits, kept fraction {f}");
    // Directional light.
    let dir = DVec3::new(0.2, -1.0, 0.1).normalize();
    let directional = Light::Directional(DirectionalLight { direction: dir, irradiance: DVec3::ONE });
    let cells = project(&directional, scene_sphere, &spheres);
    let frame = Frame::from_normal(dir);
    let (c, r) = scene_sphere;
    let (hits, f) = check_conservative(
        &cells,
        &targets,
        |u, _| {
            let disc = uniform_disc(u) * r;
            (c - frame.n * r + frame.t * disc.x + frame.b * disc.y, frame.n)
        },
        1,
    );
    assert!(hits > 100 && f < 0.2, "directional: {hits} hits, kept fraction {f}");
    // Area lights: directions from several points of the emitter (the map is over
    // directions, the same for every point).
    let quad = QuadLight { origin: DVec3::new(-0.3, 1.5, -0.2), edge_u: DVec3::new(0.6, 0.0, 0.0), edge_v: DVec3::new(0.0, 0.0, 0.4), radiance: DVec3::ONE };
    // edge_u × edge_v = -y: the quad emits downwards.
    let light = Light::Quad(quad);
    let cells = project(&light, scene_sphere, &spheres);
    let frame = Frame::from_normal_and_hint(quad.edge_u.cross(quad.edge_v), quad.edge_u);
    let corners = [DVec2::new(0.0, 0.0), DVec2::new(1.0, 0.0), DVec2::new(0.0, 1.0), DVec2::new(1.0, 1.0), DVec2::new(0.5, 0.5)];
    let (hits, f) = check_conservative(&cells, &targets, |u, k| (quad.origin + quad.edge_u * corners[k as usize].x + quad.edge_v * corners[k as usize].y, frame.to_world(cosine_hemisphere(u))), 5);
    assert!(hits > 1000 && f < 0.95, "quad: {hits} hits, kept fraction {f}");
    let tri = TriangleLight { p: [DVec3::new(1.2, 1.0, 0.0), DVec3::new(1.4, 1.0, 0.0), DVec3::new(1.2, 1.0, 0.2)], radiance: DVec3::ONE };
    let light = Light::Triangle(tri);
    let cells = project(&light, scene_sphere, &spheres);
    let frame = Frame::from_normal_and_hint((tri.p[1] - tri.p[0]).cross(tri.p[2] - tri.p[0]), tri.p[1] - tri.p[0]);
    let bary = [DVec3::new(1.0, 0.0, 0.0), DVec3::new(0.0, 1.0, 0.0), DVec3::new(0.0, 0.0, 1.0), DVec3::splat(1.0 / 3.0)];
    let (hits, f) = check_conservative(&cells, &targets, |u, k| (tri.p[0] * bary[k as usize].x + tri.p[1] * bary[k as usize].y + tri.p[2] * bary[k as usize].z, frame.to_world(cosine_hemisphere(u))), 4);
    assert!(f < 1.0, "triangle: kept fraction {f} ({hits} hits)");
}

/// One [`Projector`] shares its hemisphere caps over many area lights turned every way
/// (the triangles of an emissive sphere around the targets): each light's cells are those
/// of a projection of its own, and conservative.
#[test]
fn area_lights_share_their_caps() {
    let targets = scattered_triangles(40, DVec3::new(0.3, -0.5, 0.2), 0.5, 0.06, 5);
    let spheres = Targets::new(targets.clone());
    let scene_sphere = (DVec3::ZERO, 4.0);
    let mut projector = Projector::new(scene_sphere, &spheres, DELTA_GRID, AREA_GRID);
    let mut partial = 0;
    for k in 0..24 {
        // Small triangles on a sphere of radius 2 around the targets, facing every way
        // (outwards for even k, inwards for odd).
        let theta = PI * (k as f64 + 0.5) / 24.0;
        let phi = 2.4 * k as f64;
        let n = DVec3::new(theta.sin() * phi.cos(), theta.cos(), theta.sin() * phi.sin());
        let f = Frame::from_normal(n);
        let c = n * 2.0;
        let mut p = [c, c + f.t * 0.1, c + f.b * 0.1];
        if k % 2 == 1 {
            p.swap(1, 2);
        }
        let tri = TriangleLight { p, radiance: DVec3::ONE };
        let light = Light::Triangle(tri);
        let shared = projector.project(&light);
        assert_eq!(shared, project(&light, scene_sphere, &spheres), "light {k}: the shared caps keep other cells than its own projection");
        let frame = Frame::from_normal_and_hint((p[1] - p[0]).cross(p[2] - p[0]), p[1] - p[0]);
        let bary = [DVec3::new(1.0, 0.0, 0.0), DVec3::new(0.0, 1.0, 0.0), DVec3::new(0.0, 0.0, 1.0), DVec3::splat(1.0 / 3.0)];
        let (_, fraction) = check_conservative(&shared, &targets, |u, j| (p[0] * bary[j as usize].x + p[1] * bary[j as usize].y + p[2] * bary[j as usize].z, frame.to_world(cosine_hemisphere(u))), 4);
        if fraction < 0.5 {
            partial += 1;
        }
    }
    // The inward-facing half sees the targets through a small part of its hemisphere, the
    // outward-facing half through none of it.
    assert!(partial >= 20, "only {partial} of 24 lights keep less than half their domain");
}

/// Direction `d` back to its point of the unit square under `uniform_sphere`.
fn sphere_sample(d: DVec3) -> DVec2 {
    let phi = d.y.atan2(d.x) / (2.0 * PI);
    DVec2::new((1.0 - d.z) / 2.0, phi - phi.floor())
}

#[test]
fn projected_emission_carries_the_kept_power_and_shares_it_evenly() {
    let light = Light::Point(PointLight { position: DVec3::ZERO, intensity: DVec3::new(2.0, 1.0, 0.5) });
    let grid = DELTA_GRID;
    // Every 7th cell, and a block.
    let mut cells: Vec<u32> = (0..grid * grid).filter(|c| c % 7 == 3 || (c % grid < 5 && c / grid < 4)).collect();
    cells.sort_unstable();
    cells.dedup();
    let m = cells.len() as u32;
    let fraction = m as f64 / (grid * grid) as f64;
    for n in [m / 3, m, 5 * m + 17] {
        let params = EmissionParams::new(n).for_iteration(4, 2, 0).with_cells(grid, m);
        let prepared = light.prepare(&params).unwrap();
        let mut total = DVec3::ZERO;
        let mut per_cell = vec![0u32; (grid * grid) as usize];
        for i in 0..n {
            let mut rng = Rng::new(4, 2, i, StreamDomain::Photon);
            let slot = prepared.emission_slot(i, &rng);
            let p = prepared.emit_in(i, &mut rng, &cells).unwrap();
            total += p.flux;
            let u = sphere_sample(p.ray.d);
            let cell = ((u.x * grid as f64) as u32).min(grid - 1) + ((u.y * grid as f64) as u32).min(grid - 1) * grid;
            assert_eq!(cells[slot as usize], cell, "photon {i} of {n} left its cell");
            per_cell[cell as usize] += 1;
            // The differentials tile the kept part: footprint solid angle 4π f / n.
            let area = PI / 4.0 * p.ray.dd_du.cross(p.ray.dd_dv).length();
            assert!((area / (4.0 * PI * fraction / n as f64) - 1.0).abs() < 1e-9, "footprint {area}");
        }
        let expected = light.power(1.0) * fraction;
        assert!((total - expected).abs().max_element() < 1e-9 * expected.max_element(), "{total} vs {expected}");
        let (lo, hi) = (n / m, n.div_ceil(m));
        for &c in &cells {
            let k = per_cell[c as usize];
            assert!(k == lo || k == hi, "cell {c}: {k} photons, expected {lo}..={hi}");
        }
    }
    // The wrong list length is an error, not a wrong photon.
    let params = EmissionParams::new(10).with_cells(grid, m);
    let prepared = light.prepare(&params).unwrap();
    let mut rng = Rng::new(1, 0, 0, StreamDomain::Photon);
    assert!(prepared.emit_in(0, &mut rng, &cells[1..]).is_err());
    assert!(prepared.emit(0, &mut rng).is_err());
}

fn quad(name: &str, c: DVec3, u: DVec3, v: DVec3, material: u32) -> TriangleMesh {
    let p = [c - u - v, c + u - v, c + u + v, c - u + v].map(|p| p.as_vec3());
    TriangleMesh { uvs: None, name: name.into(), positions: p.to_vec(), normals: None, indices: vec![[0, 1, 2], [0, 2, 3]], material, emission: None }
}

const I: f64 = 10.0;
const R: f32 = 0.8;
const H: f64 = 1.5;

/// Centre, in-plane half-edge along the tilt and unit normal of the open scene's mirror:
/// a 0.2 m square at height 0.5, 0.5 m beside the light's foot, tilted 73° from the
/// floor to face the light, so that it throws its caustic down onto the floor.
fn mirror_frame() -> (DVec3, DVec3, DVec3) {
    let n = DVec3::new(-1.0, 0.3, 0.0).normalize();
    (DVec3::new(0.5, 0.5, 0.0), DVec3::new(0.3, 1.0, 0.0).normalize() * 0.1, n)
}

/// A point light at height `H` over a large diffuse floor, and (with `mirror`) the mirror
/// of [`mirror_frame`].
fn open_scene(mirror: bool) -> Scene {
    let mut meshes = vec![quad("floor", DVec3::ZERO, DVec3::X * 20.0, DVec3::Z * 20.0, 0)];
    if mirror {
        let (c, t, _) = mirror_frame();
        meshes.push(quad("mirror", c, t, DVec3::Z * 0.1, 1));
    }
    Scene { textures: Default::default(),
        meshes,
        materials: vec![Material::Diffuse { albedo: Vec3::splat(0.5) }, Material::Conductor { reflectance: Vec3::splat(R), roughness: 0.0 }],
        lights: vec![Light::Point(PointLight { position: DVec3::new(0.0, H, 0.0), intensity: DVec3::splat(I) })],
        camera: Camera { position: Vec3::new(0.0, 3.0, 3.0), target: Vec3::ZERO, up: Vec3::Y, vertical_fov: 60f32.to_radians(), width: 8, height: 8 },
        roughness_cutoff: 0.5,
        instancing: None,
    }
}

#[test]
fn the_plan_skips_what_the_scene_does_not_need() {
    let settings = RenderSettings { photons_per_iteration: 10_000, ..RenderSettings::default() };
    // A plane alone: no caustic pass, and with direct lighting nothing to bounce to.
    let plane = PreparedScene::new(open_scene(false)).unwrap();
    let plan = EmissionPlan::new(&plane, &settings);
    assert_eq!(plan.skipped.caustic_pass, Some(PassSkip::NoSpecularSurface));
    assert_eq!(plan.skipped.global_pass, Some(PassSkip::NothingToBounceTo));
    assert_eq!(plan.pass_photons(), [0, 0]);
    // Half the point light's power goes up, into nothing, and a band below the horizon
    // past the floor's edge (sin(atan(1.5/20))/2 = 3.7 %): 53.7 % at most; the 32² cells
    // along the horizon are kept conservatively.
    let f = plan.skipped.power_fraction;
    assert!(f > 0.42 && f <= 0.537, "{f}");
    let indirect = RenderSettings { direct_lighting: false, ..settings };
    let plan = EmissionPlan::new(&plane, &indirect);
    assert_eq!(plan.skipped.global_pass, None);
    assert_eq!(plan.pass_photons(), [0, 10_000]);
    // With the mirror: a caustic pass with a share of the photons, weights that add up.
    let scene = PreparedScene::new(open_scene(true)).unwrap();
    let plan = EmissionPlan::new(&scene, &settings);
    assert_eq!(plan.skipped.caustic_pass, None);
    assert_eq!(plan.skipped.global_pass, None);
    let [c, g] = plan.pass_photons();
    assert!(g == 10_000 && c > 0 && c <= 5_000, "{c} caustic photons");
    let l = &plan.lights[0];
    assert!(l.caustic_weight > 0.0 && (l.global_caustic_weight == 0.0 || (l.global_caustic_weight + l.caustic_weight - 1.0).abs() < 1e-12), "{l:?}");
    let none = RenderSettings { emission: EmissionStrategy { projection: true, caustic_photons: Some(0) }, ..settings };
    assert_eq!(EmissionPlan::new(&scene, &none).skipped.caustic_pass, Some(PassSkip::NoCausticPhotons));
    let off = RenderSettings { emission: EmissionStrategy::WHOLE_DOMAIN, ..settings };
    let plan = EmissionPlan::new(&scene, &off);
    assert_eq!((plan.pass_photons(), plan.skipped.caustic_pass, plan.lights[0].global_caustic_weight), ([0, 10_000], None, 1.0));
    // A spot light pointing up, away from everything: skipped.
    let mut away = open_scene(true);
    away.lights = vec![Light::Spot(SpotLight { position: DVec3::new(0.0, H, 0.0), direction: DVec3::Y, intensity: DVec3::ONE, cutoff: 0.5, beam_width: 0.4, falloff: SpotFalloff::LinearAngle })];
    let away = PreparedScene::new(away).unwrap();
    let plan = EmissionPlan::new(&away, &indirect);
    assert_eq!(plan.skipped.lights, 1);
    assert_eq!(plan.skipped.global_pass, Some(PassSkip::NoLightReachesGeometry));
    assert_eq!(plan.skipped.caustic_pass, Some(PassSkip::SpecularUnreached));
    assert_eq!(plan.pass_photons(), [0, 0]);
}

/// The caustic power on the floor (the flux of every caustic record, both passes'
/// weights included; RTPM, whose records carry their flux) against the exact `I R Ω` of the mirror (Ω its solid angle from the
/// light), with projection on (several caustic photon counts) and off.
#[test]
fn both_passes_together_carry_the_exact_caustic_power() {
    let scene = PreparedScene::new(open_scene(true)).unwrap();
    let caster = BruteForceCaster::new(&scene);
    // Solid angle of the mirror seen from the light (midpoint rule, 400²), and that all
    // of its reflection lands on the floor.
    let ((c, t, normal), n) = (mirror_frame(), 400);
    let light = DVec3::new(0.0, H, 0.0);
    let mut omega = 0.0;
    for j in 0..n {
        for i in 0..n {
            let a = -1.0 + 2.0 * (i as f64 + 0.5) / n as f64;
            let b = -1.0 + 2.0 * (j as f64 + 0.5) / n as f64;
            let p = c + t * a + DVec3::Z * (0.1 * b);
            let d = p - light;
            omega += (0.04 / (n * n) as f64) * (d.dot(normal).abs() / d.length()) / d.length_squared();
            let r = d.normalize() - 2.0 * d.normalize().dot(normal) * normal;
            assert!(r.y < -0.1 && (p.y / -r.y * r).length() < 10.0, "the reflection at {p} leaves the floor");
        }
    }
    let exact = I * R as f64 * omega;
    for (strategy, iterations) in [
        (EmissionStrategy::WHOLE_DOMAIN, 24),
        (EmissionStrategy::default(), 6),
        (EmissionStrategy { projection: true, caustic_photons: Some(200) }, 12),
        (EmissionStrategy { projection: true, caustic_photons: Some(20_000) }, 4),
    ] {
        let settings = RenderSettings { method: arpa_core::render::tracer::Method::Rtpm, photons_per_iteration: 40_000, max_depth: 3, emission: strategy, ..RenderSettings::default() };
        let mut power = 0.0;
        let mut records = 0;
        for it in 0..iterations {
            let setup = PhotonPassSetup::new(&scene, &settings, it);
            for i in 0..setup.photon_count() {
                trace_photon(&scene, &caster, &settings, &setup, i, &mut |s| {
                    // RTPM stores every record as a progressive photon with its flux.
                    let StoredPhoton::Progressive { photon, .. } = s else { panic!("RTPM stored a footprint") };
                    let (flux, map) = (photon.flux, photon.photon_map());
                    if map == arpa_core::store::footprint::PhotonMap::Caustic {
                        power += flux[0] as f64;
                        records += 1;
                    }
                });
            }
        }
        let power = power / iterations as f64;
        let err = power / exact - 1.0;
        assert!(err.abs() < 0.01, "{strategy:?}: caustic power {power} vs exact {exact} ({:+.3} %, {records} records)", 100.0 * err);
    }
}
