//! Physics of the whole CPU pipeline against closed-form answers: a point light inside a
//! closed diffuse sphere (the furnace) and a point light over a diffuse plane, for both
//! density-estimation methods, with the direct light from next-event estimation or from
//! the photons.

mod common;

use std::f64::consts::PI;
use std::time::Instant;

use arpa_core::glam::{DVec3, Vec3};
use arpa_core::render::tracer::{Method, QueryRecord, RenderSettings, Tracer};
use arpa_cpu::CpuTracer;
use common::*;

const SIZE: u32 = 32;

fn settings(method: Method, direct_lighting: bool, photons: u32) -> RenderSettings {
    RenderSettings {
        method,
        photons_per_iteration: photons,
        seed: 7,
        // Deep enough that truncation removes < 1e-9 of the indirect light at albedo 0.5.
        max_depth: 32,
        direct_lighting,
        ..RenderSettings::default()
    }
}

// ---------------------------------------------------------------------------- furnace

const FURNACE_INTENSITY: f64 = 1.5;
const FURNACE_ALBEDO: f64 = 0.5;

/// A point light at the centre of a closed unit icosphere (1280 triangles) of albedo 0.5;
/// the camera sits at the centre too and looks at the wall.
///
/// Analytic answer at a query point `q` on a facet with unit normal `n` (towards the
/// centre `c`): the direct irradiance is `E_d(q) = I (n·(c − q))/|c − q|³`. Every photon
/// hits the wall, so over all bounces the wall receives `Φ/(1 − ρ)` with `Φ = 4πI`, of
/// which `ρΦ/(1 − ρ)` is indirect; inside a sphere the form factor from any point to a
/// patch `dA` is `dA/(4πR²)`, the same for every point, so the indirect irradiance is
/// uniform: `E_i = ρΦ/((1 − ρ) A)` with `A` the (facetted) wall's area. The radiance is
/// `L(q) = ρ/π (E_d(q) + E_i)`; for ρ = 1/2 and a round sphere, `L = I/(πR²)`.
fn furnace(method: Method, direct_lighting: bool) -> f64 {
    furnace_with(method, direct_lighting, false)
}

/// [`furnace`]; with `face_vertex_normals` every facet gets its own three vertices whose
/// vertex normals are the facet's normal, so the shading-normal code runs with `n_s = n_g`.
fn furnace_with(method: Method, direct_lighting: bool, face_vertex_normals: bool) -> f64 {
    let mut sphere = icosphere(Vec3::ZERO, 1.0, 3, 0);
    assert_eq!(sphere.indices.len(), 1280);
    if face_vertex_normals {
        let (mut positions, mut normals, mut indices) = (vec![], vec![], vec![]);
        for t in &sphere.indices {
            let p = t.map(|i| sphere.positions[i as usize]);
            let n = (p[1] - p[0]).cross(p[2] - p[0]).normalize();
            let base = positions.len() as u32;
            positions.extend_from_slice(&p);
            normals.extend_from_slice(&[n; 3]);
            indices.push([base, base + 1, base + 2]);
        }
        sphere.positions = positions;
        sphere.normals = Some(normals);
        sphere.indices = indices;
    }
    let area = sphere.area();
    let scene = scene(
        vec![sphere],
        vec![diffuse(FURNACE_ALBEDO as f32)],
        vec![point_light(DVec3::ZERO, FURNACE_INTENSITY)],
        camera(
            Vec3::ZERO,
            Vec3::new(0.3, 0.2, 1.0),
            Vec3::Y,
            60f32.to_radians(),
            SIZE,
        ),
    );
    let rho = FURNACE_ALBEDO;
    let indirect = rho * 4.0 * PI * FURNACE_INTENSITY / ((1.0 - rho) * area);
    let expected_at = |r: &QueryRecord| {
        assert_eq!(r.valid, 1, "every camera ray hits the closed sphere");
        let q = Vec3::from_array(r.position).as_dvec3();
        let n = Vec3::from_array(r.normal).as_dvec3();
        let to_light = DVec3::ZERO - q;
        let d = to_light.length();
        let direct = FURNACE_INTENSITY * n.dot(to_light).max(0.0) / (d * d * d);
        rho / PI * (direct + indirect)
    };

    let start = Instant::now();
    let mut tracer = CpuTracer::new().unwrap();
    tracer
        .upload_scene(&scene, &settings(method, direct_lighting, 60_000))
        .unwrap();
    let mut expected = 0.0;
    let iterations = 8;
    render(&mut tracer, iterations, |records| {
        expected += records.iter().map(expected_at).sum::<f64>() / records.len() as f64;
    });
    let expected = expected / iterations as f64;
    let image = tracer.read_image().unwrap();
    assert_eq!(image.pixels.len(), (SIZE * SIZE) as usize);
    let mean = image.pixels.iter().map(|p| p.x as f64).sum::<f64>() / image.pixels.len() as f64;
    // Grey scene: the three channels agree.
    for p in &image.pixels {
        assert!(
            p.is_finite()
                && (p.x - p.y).abs() <= 1e-5 * p.x.abs()
                && (p.x - p.z).abs() <= 1e-5 * p.x.abs(),
            "{p:?}"
        );
    }
    let stats = tracer.read_stats().unwrap();
    assert_eq!(stats.iteration, iterations);
    assert_eq!(stats.query_points, (SIZE * SIZE) as u64);
    assert_eq!(tracer.embree_errors(), 0);
    let round_sphere = FURNACE_INTENSITY / PI;
    let error = percent(mean, expected);
    eprintln!(
        "furnace {:>4} direct={direct_lighting:<5}: mean radiance {mean:.5}, analytic {expected:.5} ({error:+.3}%; round-sphere value {round_sphere:.5}); \
         last iteration: {} footprints, {} progressive photons, {} gathered; {:.2} s",
        method.name(),
        stats.footprints[0] + stats.footprints[1],
        stats.progressive[0] + stats.progressive[1],
        stats.gathered(),
        start.elapsed().as_secs_f64()
    );
    match method {
        Method::Arpa => assert!(
            stats.footprints[1] > 0,
            "ARPA stored no footprint: {stats:?}"
        ),
        Method::Rtpm => assert_eq!(stats.footprints, [0, 0]),
    }
    error
}

#[test]
fn furnace_arpa_direct_lighting() {
    let e = furnace(Method::Arpa, true);
    assert!(e.abs() < 2.0, "{e:+.3}%");
}

#[test]
fn furnace_arpa_photons_only() {
    let e = furnace(Method::Arpa, false);
    assert!(e.abs() < 2.0, "{e:+.3}%");
}

/// Vertex normals equal to the facet normals run the shading-normal paths (adjoint
/// ratio, re-emission within the shading lobe, NEE cosine about `n_s`) with `n_s = n_g`:
/// the furnace stays within its tolerance and gives the face-normal result.
#[test]
fn furnace_with_vertex_normals_equal_to_face_normals_is_unchanged() {
    for direct_lighting in [false, true] {
        let plain = furnace(Method::Arpa, direct_lighting);
        let shaded = furnace_with(Method::Arpa, direct_lighting, true);
        assert!(shaded.abs() < 2.0, "{shaded:+.3}%");
        assert!((shaded - plain).abs() < 0.05, "{shaded:+.4}% vs {plain:+.4}% without vertex normals");
    }
}

#[test]
fn furnace_rtpm_direct_lighting() {
    let e = furnace(Method::Rtpm, true);
    assert!(e.abs() < 2.0, "{e:+.3}%");
}

#[test]
fn furnace_rtpm_photons_only() {
    let e = furnace(Method::Rtpm, false);
    assert!(e.abs() < 2.0, "{e:+.3}%");
}

// ---------------------------------------------------------------------------- plane

const PLANE_INTENSITY: f64 = 2.0;
const PLANE_ALBEDO: f64 = 0.5;
const LIGHT_HEIGHT: f64 = 1.0;

/// A point light at height 1 over a 20 × 20 diffuse plane; the camera looks straight
/// down and sees the square `|x|, |z| ≤ 1.5`. Direct lighting is off, so every bit of the
/// image comes from the photons: `L(q) = ρ/π · I cos θ / d²` with `cos θ = h/d`. Reflected
/// photons leave the scene (nothing above the plane). Returns the error (%) of each ring
/// of pixels `r ∈ [0, 0.5), [0.5, 1), [1, 1.5)` around the foot of the light.
fn plane(method: Method) -> Vec<f64> {
    let floor = quad(
        "floor",
        Vec3::new(-10.0, 0.0, -10.0),
        Vec3::new(0.0, 0.0, 20.0),
        Vec3::new(20.0, 0.0, 0.0),
        0,
    );
    let light = DVec3::new(0.0, LIGHT_HEIGHT, 0.0);
    let scene = scene(
        vec![floor],
        vec![diffuse(PLANE_ALBEDO as f32)],
        vec![point_light(light, PLANE_INTENSITY)],
        camera(
            Vec3::new(0.0, 3.0, 0.0),
            Vec3::ZERO,
            Vec3::new(0.0, 0.0, -1.0),
            2.0 * 0.5f32.atan(),
            SIZE,
        ),
    );
    let expected_at = |r: &QueryRecord| {
        assert_eq!(r.valid, 1, "every camera ray hits the floor");
        let q = Vec3::from_array(r.position).as_dvec3();
        let d = (light - q).length();
        PLANE_ALBEDO / PI * PLANE_INTENSITY * (LIGHT_HEIGHT / d) / (d * d)
    };

    let start = Instant::now();
    let mut tracer = CpuTracer::new().unwrap();
    tracer
        .upload_scene(&scene, &settings(method, false, 100_000))
        .unwrap();
    let pixels = (SIZE * SIZE) as usize;
    let mut expected = vec![0.0; pixels];
    let mut ring_of: Vec<Option<usize>> = Vec::new();
    let iterations = 6;
    render(&mut tracer, iterations, |records| {
        if ring_of.is_empty() {
            ring_of = records
                .iter()
                .map(|r| {
                    let rho = (r.position[0] as f64).hypot(r.position[2] as f64);
                    let ring = (rho / 0.5) as usize;
                    (ring < 3).then_some(ring)
                })
                .collect();
        }
        for (e, r) in expected.iter_mut().zip(records) {
            *e += expected_at(r) / iterations as f64;
        }
    });
    let image = tracer.read_image().unwrap();
    let stats = tracer.read_stats().unwrap();
    assert_eq!(tracer.embree_errors(), 0);
    let mut errors = Vec::new();
    for ring in 0..3 {
        let members: Vec<usize> = (0..pixels).filter(|&i| ring_of[i] == Some(ring)).collect();
        assert!(members.len() > 50, "ring {ring}: {} pixels", members.len());
        let estimate = members
            .iter()
            .map(|&i| image.pixels[i].x as f64)
            .sum::<f64>()
            / members.len() as f64;
        let analytic = members.iter().map(|&i| expected[i]).sum::<f64>() / members.len() as f64;
        let error = percent(estimate, analytic);
        eprintln!(
            "plane {:>4} ring r ∈ [{:.1}, {:.1}) ({} pixels): radiance {estimate:.5} vs analytic {analytic:.5} ({error:+.3}%)",
            method.name(),
            0.5 * ring as f64,
            0.5 * (ring + 1) as f64,
            members.len()
        );
        errors.push(error);
    }
    eprintln!(
        "plane {:>4}: last iteration {} footprints, {} progressive photons ({} degenerate, {} culled); {:.2} s",
        method.name(),
        stats.footprints[1],
        stats.progressive[1],
        stats.degenerate,
        stats.culled,
        start.elapsed().as_secs_f64()
    );
    errors
}

#[test]
fn plane_arpa_photons_only() {
    for e in plane(Method::Arpa) {
        assert!(e.abs() < 2.0, "{e:+.3}%");
    }
}

#[test]
fn plane_rtpm_photons_only() {
    for e in plane(Method::Rtpm) {
        assert!(e.abs() < 2.0, "{e:+.3}%");
    }
}

// ---------------------------------------------------------------------------- area light

/// A small tilted emissive quad (0.1 × 0.1, radiance 50, normal tilted 30° from straight
/// down) at height 1 over a 20 × 20 diffuse plane; the camera looks straight down. Direct
/// lighting is off, so the photons emitted by the mesh carry all of it:
/// `L(q) = ρ/π ∫ L_e cos θ_q cos θ_l / d² dA`, integrated numerically over the lamp.
/// The lamp is black, so light it intercepts is lost. Returns the error (%) of the mean
/// of each image quadrant (floor pixels only).
fn area_light(method: Method) -> Vec<f64> {
    let tilt = 30f32.to_radians();
    let u = Vec3::new(tilt.cos(), tilt.sin(), 0.0) * 0.1;
    let v = Vec3::new(0.0, 0.0, 0.1);
    let centre = Vec3::new(0.4, 1.0, 0.0);
    let mut lamp = quad("lamp", centre - 0.5 * u - 0.5 * v, u, v, 1);
    let radiance = 50.0;
    lamp.emission = Some(Vec3::splat(radiance as f32));
    let lamp_points: Vec<(DVec3, DVec3, f64)> = {
        // Midpoint rule on 16 × 16 cells: (point, unit normal, cell area).
        let (u, v) = (u.as_dvec3(), v.as_dvec3());
        let origin = lamp.positions[0].as_dvec3();
        let n = u.cross(v);
        let cell = n.length() / 256.0;
        let n = n.normalize();
        (0..256)
            .map(|k| {
                (
                    origin
                        + u * ((k % 16) as f64 + 0.5) / 16.0
                        + v * ((k / 16) as f64 + 0.5) / 16.0,
                    n,
                    cell,
                )
            })
            .collect()
    };
    assert!(lamp_points[0].1.y < -0.8, "the lamp faces down");
    let floor = quad(
        "floor",
        Vec3::new(-10.0, 0.0, -10.0),
        Vec3::new(0.0, 0.0, 20.0),
        Vec3::new(20.0, 0.0, 0.0),
        0,
    );
    let scene = scene(
        vec![floor, lamp],
        vec![diffuse(PLANE_ALBEDO as f32), diffuse(0.0)],
        vec![],
        camera(
            Vec3::new(0.0, 3.0, 0.0),
            Vec3::ZERO,
            Vec3::new(0.0, 0.0, -1.0),
            2.0 * 0.5f32.atan(),
            SIZE,
        ),
    );
    let expected_at = |r: &QueryRecord| {
        let q = Vec3::from_array(r.position).as_dvec3();
        let e: f64 = lamp_points
            .iter()
            .map(|&(p, n, area)| {
                let d = p - q;
                let d2 = d.length_squared();
                let cos_q = d.y / d2.sqrt();
                let cos_l = (-d).dot(n) / d2.sqrt();
                radiance * cos_q.max(0.0) * cos_l.max(0.0) * area / d2
            })
            .sum();
        PLANE_ALBEDO / PI * e
    };

    let start = Instant::now();
    let mut tracer = CpuTracer::new().unwrap();
    tracer
        .upload_scene(&scene, &settings(method, false, 200_000))
        .unwrap();
    let pixels = (SIZE * SIZE) as usize;
    let mut expected = vec![0.0; pixels];
    let mut on_floor = vec![true; pixels];
    let iterations = 8;
    render(&mut tracer, iterations, |records| {
        for ((e, f), r) in expected.iter_mut().zip(&mut on_floor).zip(records) {
            *f &= r.valid == 1 && r.position[1].abs() < 1e-3;
            *e += expected_at(r) / iterations as f64;
        }
    });
    let image = tracer.read_image().unwrap();
    let stats = tracer.read_stats().unwrap();
    assert_eq!(tracer.embree_errors(), 0);
    let mut errors = Vec::new();
    let half = SIZE / 2;
    for quadrant in 0..4 {
        let members: Vec<usize> = (0..pixels)
            .filter(|&i| {
                let (x, y) = (i as u32 % SIZE, i as u32 / SIZE);
                on_floor[i] && (x / half + 2 * (y / half)) as usize == quadrant
            })
            .collect();
        assert!(
            members.len() > 200,
            "quadrant {quadrant}: {} floor pixels",
            members.len()
        );
        let estimate = members
            .iter()
            .map(|&i| image.pixels[i].x as f64)
            .sum::<f64>()
            / members.len() as f64;
        let analytic = members.iter().map(|&i| expected[i]).sum::<f64>() / members.len() as f64;
        let error = percent(estimate, analytic);
        eprintln!(
            "area light {:>4} quadrant {quadrant}: radiance {estimate:.5} vs analytic {analytic:.5} ({error:+.3}%)",
            method.name()
        );
        errors.push(error);
    }
    eprintln!(
        "area light {:>4}: last iteration {} footprints, {} progressive photons; {:.2} s",
        method.name(),
        stats.footprints[1],
        stats.progressive[1],
        start.elapsed().as_secs_f64()
    );
    errors
}

#[test]
fn area_light_arpa_photons_only() {
    for e in area_light(Method::Arpa) {
        assert!(e.abs() < 2.0, "{e:+.3}%");
    }
}

#[test]
fn area_light_rtpm_photons_only() {
    for e in area_light(Method::Rtpm) {
        assert!(e.abs() < 2.0, "{e:+.3}%");
    }
}
