//! The reference camera and photon paths on analytic scenes, with the brute-force ray
//! caster and a brute-force gather: what every backend must reproduce.

use arpa_core::render::camera_path::trace_camera_path;
use arpa_core::emit::emission::{Light, PointLight};
use arpa_core::gather::estimate::{gather_brute_force, QueryPoint};
use arpa_core::store::footprint::PackedFootprint;
use arpa_core::gather::kernel::Kernel;
use arpa_core::render::photon_path::{trace_photon, PhotonPassSetup};
use arpa_core::render::prepared_scene::PreparedScene;
use arpa_core::store::progressive_photon::PackedPhoton;
use arpa_core::render::brute_force::BruteForceCaster;
use arpa_core::render::scene::{Camera, Material, Scene, TriangleMesh};
use arpa_core::store::decision::StoredPhoton;
use arpa_core::render::tracer::{Method, QueryRecord, RenderSettings};
use glam::{DVec3, Vec3};
use std::f64::consts::PI;

const ALBEDO: f32 = 0.5;
const INTENSITY: f64 = 3.0;

fn plane_scene(size: u32) -> Scene {
    let h = 4.0;
    Scene { textures: Default::default(),
        meshes: vec![TriangleMesh { uvs: None,
            name: "floor".into(),
            positions: vec![Vec3::new(-h, 0.0, -h), Vec3::new(h, 0.0, -h), Vec3::new(h, 0.0, h), Vec3::new(-h, 0.0, h)],
            normals: None,
            indices: vec![[0, 2, 1], [0, 3, 2]],
            material: 0,
            emission: None,
        }],
        materials: vec![Material::Diffuse { albedo: Vec3::splat(ALBEDO) }],
        lights: vec![Light::Point(PointLight { position: DVec3::new(0.0, 1.0, 0.0), intensity: DVec3::splat(INTENSITY) })],
        camera: Camera { position: Vec3::new(0.0, 3.0, 0.0), target: Vec3::ZERO, up: Vec3::Z, vertical_fov: 60f32.to_radians(), width: size, height: size },
        roughness_cutoff: 0.5,
        instancing: None,
    }
}

/// The photon pass of iteration `it` by the reference paths: its setup (radii), the
/// footprints and the progressive photons it stores.
fn photon_pass(
    scene: &PreparedScene,
    caster: &BruteForceCaster,
    settings: &RenderSettings,
    it: u32,
) -> (PhotonPassSetup, Vec<PackedFootprint>, Vec<PackedPhoton>) {
    let setup = PhotonPassSetup::new(scene, settings, it);
    let (mut fps, mut phs) = (vec![], vec![]);
    for i in 0..setup.photon_count() {
        trace_photon(scene, caster, settings, &setup, i, &mut |s| match s {
            StoredPhoton::Footprint { packed, .. } => fps.push(packed),
            StoredPhoton::Progressive { photon, .. } => phs.push(photon),
        });
    }
    (setup, fps, phs)
}

/// Renders `iterations` iterations with the reference paths; returns per-pixel mean
/// radiance (red channel) and the last iteration's query records.
fn render(scene: &PreparedScene, settings: &RenderSettings, iterations: u32) -> (Vec<f64>, Vec<QueryRecord>) {
    let caster = BruteForceCaster::new(scene);
    let cam = scene.scene().camera;
    let pixels = cam.width * cam.height;
    let mut sum = vec![0.0; pixels as usize];
    let mut records = vec![];
    for it in 0..iterations {
        records = (0..pixels).map(|p| trace_camera_path(scene, &caster, settings, it, p)).collect();
        let (setup, fps, phs) = photon_pass(scene, &caster, settings, it);
        let radii = setup.radii;
        for (r, acc) in records.iter().zip(&mut sum) {
            let mut l = r.radiance[0] as f64;
            if r.valid == 1 {
                let q = QueryPoint { position: Vec3::from_array(r.position), normal: Vec3::from_array(r.normal) };
                l += r.weight[0] as f64 * gather_brute_force(&q, &fps, &phs, radii, Kernel::Silverman).irradiance().x;
            }
            *acc += l;
        }
    }
    (sum.iter().map(|s| s / iterations as f64).collect(), records)
}

fn analytic(q: [f32; 3]) -> f64 {
    let d = DVec3::new(0.0, 1.0, 0.0) - Vec3::from_array(q).as_dvec3();
    let r2 = d.length_squared();
    ALBEDO as f64 / PI * INTENSITY * (d.y / r2.sqrt()) / r2
}

/// Mean relative error over the image (pixels whose query point is within 1.5 of the
/// foot of the light; the mean over many pixels averages the per-pixel noise).
fn mean_error(img: &[f64], records: &[QueryRecord]) -> f64 {
    let (mut est, mut exact) = (0.0, 0.0);
    for (l, r) in img.iter().zip(records) {
        assert_eq!(r.valid, 1);
        if (r.position[0].powi(2) + r.position[2].powi(2)).sqrt() < 1.5 {
            est += l;
            exact += analytic(r.position);
        }
    }
    est / exact - 1.0
}

#[test]
fn point_light_over_plane_by_photons_only() {
    let scene = PreparedScene::new(plane_scene(24)).unwrap();
    for method in [Method::Arpa, Method::Rtpm] {
        let settings = RenderSettings { method, photons_per_iteration: 20_000, direct_lighting: false, max_depth: 1, ..RenderSettings::default() };
        let (img, records) = render(&scene, &settings, 8);
        let err = mean_error(&img, &records);
        eprintln!("{method:?}, photons only: mean relative error {:+.3}%", err * 100.0);
        assert!(err.abs() < 0.02, "{method:?}: {err}");
    }
}

#[test]
fn point_light_over_plane_by_next_event_estimation() {
    let scene = PreparedScene::new(plane_scene(16)).unwrap();
    let settings = RenderSettings { photons_per_iteration: 1000, direct_lighting: true, max_depth: 1, ..RenderSettings::default() };
    let (img, records) = render(&scene, &settings, 1);
    // Exact per pixel (no photons contribute: direct photons are not stored).
    for (l, r) in img.iter().zip(&records) {
        let a = analytic(r.position);
        assert!((l / a - 1.0).abs() < 1e-4, "{l} vs {a}");
    }
}

/// Irradiance on the floor below a glass slab (thickness `d`, index `n`, top at height
/// `h − a` under a point light at height `h`) at distance `rho` from the foot of the light:
/// `E = I T(θ)² sin θ / (ρ dρ/dθ)` with `ρ(θ) = (h − d) tan θ + d tan θ_t`, `sin θ_t = sin θ/n`
/// and `T = 1 − R` the Fresnel transmittance of each face (equal by reciprocity).
fn slab_irradiance(rho: f64, h: f64, d: f64, n: f64) -> f64 {
    let x = |theta: f64| (h - d) * theta.tan() + d * (theta.sin() / n).asin().tan();
    let (mut lo, mut hi) = (0.0, 1.5);
    for _ in 0..100 {
        let mid = 0.5 * (lo + hi);
        if x(mid) < rho { lo = mid } else { hi = mid }
    }
    let theta = 0.5 * (lo + hi);
    let t = 1.0 - arpa_core::propagate::fresnel::dielectric_reflectance(-theta.cos(), n);
    if rho < 1e-9 {
        return t * t * INTENSITY / (h - d + d / n).powi(2);
    }
    let eps = 1e-6;
    let dx = (x(theta + eps) - x(theta - eps)) / (2.0 * eps);
    INTENSITY * t * t * theta.sin() / (rho * dx)
}

/// A glass slab (IOR 1.5, thickness 0.2) between a point light and the floor: the caustic
/// map's irradiance matches the exact two-interface optics (refraction and Fresnel
/// transmittance at both faces) within 2%, for both methods. ARPA's footprints carry
/// differentials propagated through both refractions.
#[test]
fn glass_slab_caustic_matches_optics() {
    let (h, d, n) = (1.0f64, 0.2f64, 1.5f64);
    let mut scene = plane_scene(8);
    let s = 4.0f32;
    let (top, bottom) = (0.6f32, 0.4f32);
    // Top face (normal +y) and bottom face (normal −y) of a wide slab.
    let quad = |y: f32, up: bool| -> ([Vec3; 4], [[u32; 3]; 2]) {
        let p = [Vec3::new(-s, y, -s), Vec3::new(s, y, -s), Vec3::new(s, y, s), Vec3::new(-s, y, s)];
        (p, if up { [[0, 2, 1], [0, 3, 2]] } else { [[0, 1, 2], [0, 2, 3]] })
    };
    let (pt, it) = quad(top, true);
    let (pb, ib) = quad(bottom, false);
    let mut positions = pt.to_vec();
    positions.extend_from_slice(&pb);
    let mut indices = it.to_vec();
    indices.extend(ib.iter().map(|t| t.map(|i| i + 4)));
    scene.materials.push(Material::Dielectric { ior: n as f32, transmittance: Vec3::ONE, roughness: 0.0 });
    scene.meshes.push(TriangleMesh { uvs: None, name: "slab".into(), positions, normals: None, indices, material: 1, emission: None });
    let scene = PreparedScene::new(scene).unwrap();
    let caster = BruteForceCaster::new(&scene);
    let radii = [0.05f64, 0.25, 0.5];
    let rings: Vec<Vec<QueryPoint>> = radii
        .iter()
        .map(|&rho| {
            (0..256)
                .map(|i| {
                    let phi = i as f32 * std::f32::consts::TAU / 256.0;
                    let r = if rho == 0.05 { 0.05 * ((i % 8) as f32 + 1.0) / 8.0 } else { rho as f32 };
                    QueryPoint { position: Vec3::new(r * phi.cos(), 0.0, r * phi.sin()), normal: Vec3::Y }
                })
                .collect()
        })
        .collect();
    for method in [Method::Arpa, Method::Rtpm] {
        let settings = RenderSettings { method, photons_per_iteration: 200_000, direct_lighting: true, max_depth: 4, ..RenderSettings::default() };
        let iterations = 16;
        let mut sums = vec![0.0; rings.len()];
        let mut caustic_footprints = 0usize;
        for iteration in 0..iterations {
            let (setup, fps, phs) = photon_pass(&scene, &caster, &settings, iteration);
            caustic_footprints += fps.iter().filter(|f| f.photon_map() == arpa_core::store::footprint::PhotonMap::Caustic).count();
            let r = setup.radii;
            for (ring, sum) in rings.iter().zip(&mut sums) {
                for q in ring {
                    *sum += gather_brute_force(q, &fps, &phs, r, Kernel::Silverman).map(arpa_core::store::footprint::PhotonMap::Caustic).x;
                }
            }
        }
        if method == Method::Arpa {
            assert!(caustic_footprints > 100_000, "{caustic_footprints} caustic footprints");
        }
        for ((ring, sum), rho) in rings.iter().zip(&sums).zip(radii) {
            let estimate = sum / (iterations as usize * ring.len()) as f64;
            let exact = ring.iter().map(|q| slab_irradiance(q.position.length() as f64, h, d, n)).sum::<f64>() / ring.len() as f64;
            eprintln!("{method:?} slab caustic at ρ ≈ {rho}: {estimate:.4} vs optics {exact:.4} ({:+.2}%)", (estimate / exact - 1.0) * 100.0);
            assert!((estimate / exact - 1.0).abs() < 0.02, "{method:?} at ρ ≈ {rho}");
        }
    }
}

/// Unit shading normal of every vertex of the tilted-normal floor: 40° from the face
/// normal `+y`, towards `+x`.
fn tilted_normal() -> DVec3 {
    let t = 40f64.to_radians();
    DVec3::new(t.sin(), t.cos(), 0.0)
}

/// The floor of [`plane_scene`] with all vertex normals tilted ([`tilted_normal`]).
fn tilted_plane_scene(size: u32) -> PreparedScene {
    let mut scene = plane_scene(size);
    scene.meshes[0].normals = Some(vec![tilted_normal().as_vec3(); 4]);
    PreparedScene::new(scene).unwrap()
}

/// Mitsuba 3's two-sided diffuse with a shading normal `n_s`: `L = ρ/π · I (ω_l·n_s)⁺ / r²`
/// (the viewer above the camera is on the `n_s` side everywhere in view).
fn analytic_shaded(q: [f32; 3]) -> f64 {
    let d = DVec3::new(0.0, 1.0, 0.0) - Vec3::from_array(q).as_dvec3();
    let r2 = d.length_squared();
    ALBEDO as f64 / PI * INTENSITY * (d.dot(tilted_normal()) / r2.sqrt()).max(0.0) / r2
}

/// Next-event estimation on a flat quad whose vertex normals are tilted by 40°: the
/// cosine is the shading normal's, `I cos θ_s / r²`, exactly per pixel, and zero where the
/// light lies below the shading plane (`x > cot 40° ≈ 1.19`) though above the face.
#[test]
fn tilted_vertex_normals_shade_next_event_estimation() {
    let scene = tilted_plane_scene(24);
    let settings = RenderSettings { photons_per_iteration: 1000, direct_lighting: true, max_depth: 1, ..RenderSettings::default() };
    let (img, records) = render(&scene, &settings, 1);
    let (mut lit, mut dark, mut off_face, mut face) = (0, 0, 0.0, 0.0);
    for (l, r) in img.iter().zip(&records) {
        assert_eq!(r.valid, 1);
        let a = analytic_shaded(r.position);
        if a > 0.0 {
            lit += 1;
            assert!((l / a - 1.0).abs() < 1e-4, "{l} vs {a} at {:?}", r.position);
        } else {
            dark += 1;
            assert_eq!(*l, 0.0, "light below the shading plane at {:?}", r.position);
        }
        off_face += (l - analytic(r.position)).abs();
        face += analytic(r.position);
    }
    assert!(lit > 100 && dark > 20, "{lit} lit, {dark} dark pixels");
    // Far from what the face's cosine would give.
    assert!(off_face / face > 0.1, "{off_face} vs {face}");
}

/// The photons' density estimate on the same tilted floor (photons only, one bounce) is
/// the shading-frame irradiance `I (cos θ_s)⁺ / r²` too, zero where the light is below
/// the shading plane: each photon counts with the adjoint
/// ratio `|ω_i·n_s| / |ω_i·n_g|` (with face normals it would be `I cos θ_g / r²`, 14 % off
/// over this region).
#[test]
fn tilted_vertex_normals_weight_the_photon_estimate() {
    let scene = tilted_plane_scene(24);
    for method in [Method::Arpa, Method::Rtpm] {
        let settings = RenderSettings { method, photons_per_iteration: 20_000, direct_lighting: false, max_depth: 1, ..RenderSettings::default() };
        let (img, records) = render(&scene, &settings, 8);
        let (mut est, mut exact, mut face) = (0.0, 0.0, 0.0);
        let (mut beyond, mut beyond_face) = (0.0, 0.0);
        for (l, r) in img.iter().zip(&records) {
            let (x, z) = (r.position[0] as f64, r.position[2] as f64);
            // Light below the shading plane, viewer above it: Mitsuba's lobe is zero, and
            // the photons (stored with the flipped orientation) are not gathered.
            if x > 1.4 {
                beyond += l;
                beyond_face += analytic(r.position);
            }
            // Lit side of the shading plane, away from its edge (the estimate blurs over
            // the photon radius there).
            if x < 0.7 && (x * x + z * z).sqrt() < 1.5 {
                est += l;
                exact += analytic_shaded(r.position);
                face += analytic(r.position);
            }
        }
        let err = est / exact - 1.0;
        eprintln!("{method:?}, tilted normals, photons only: {:+.3}% (face-normal value {:+.1}%)", err * 100.0, (face / exact - 1.0) * 100.0);
        assert!((face / exact - 1.0).abs() > 0.1);
        assert!(err.abs() < 0.02, "{method:?}: {err}");
        eprintln!("{method:?}, beyond the shading plane's horizon: {:.2e} of the face-normal value", beyond / beyond_face);
        assert!(beyond_face > 0.0 && beyond < 1e-3 * beyond_face, "{method:?}: {beyond} vs {beyond_face}");
    }
}

/// Photon transport through a diffuse bounce on shading normals is the adjoint of
/// Mitsuba's radiance transport: light from the point light reflected by the tilted-normal
/// floor onto a ceiling (y = 2, flat, facing down) gives the ceiling the irradiance
/// `E(y) = ∫ L_o(x → y) cos θ_x cos θ_y / |x − y|² dA_x` with the floor's radiance from
/// Mitsuba's two-sided diffuse lobe, `L_o(x, ω) = ρ/π · I |ω_l·n_s| / r²` where `ω` and
/// the light direction `ω_l` lie on the same side of the shading plane (else 0); checked by
/// quadrature at 400 ceiling points. The face-normal transport would be 25 % off.
#[test]
fn tilted_vertex_normals_reflect_photons_by_the_adjoint() {
    let mut scene = plane_scene(4);
    scene.meshes[0].normals = Some(vec![tilted_normal().as_vec3(); 4]);
    let h = 4.0f32;
    scene.meshes.push(TriangleMesh { uvs: None,
        name: "ceiling".into(),
        positions: vec![Vec3::new(-h, 2.0, -h), Vec3::new(h, 2.0, -h), Vec3::new(h, 2.0, h), Vec3::new(-h, 2.0, h)],
        normals: None,
        indices: vec![[0, 1, 2], [0, 2, 3]],
        material: 0,
        emission: None,
    });
    let scene = PreparedScene::new(scene).unwrap();
    let caster = BruteForceCaster::new(&scene);
    // Direct photons are not stored: with two interactions the ceiling holds exactly the
    // light → floor → ceiling photons.
    // A wide progressive radius (0.3) for a low-noise estimate of this smooth irradiance.
    let radii = arpa_core::accumulate::radius::ProgressiveConfig { global: arpa_core::accumulate::radius::RadiusSpec::Absolute(0.3), ..Default::default() };
    let points: Vec<QueryPoint> = (0..400)
        .map(|i| QueryPoint { position: Vec3::new(-1.0 + 0.1 * (i % 20) as f32, 2.0, -1.0 + 0.1 * (i / 20) as f32), normal: -Vec3::Y })
        .collect();
    let quadrature = |n_s: DVec3| {
        let light = DVec3::new(0.0, 1.0, 0.0);
        let (cells, extent) = (400, 8.0);
        let da = (extent / cells as f64).powi(2);
        points
            .iter()
            .map(|q| {
                let y = q.position.as_dvec3();
                let mut e = 0.0;
                for i in 0..cells {
                    for j in 0..cells {
                        let x = DVec3::new(-4.0 + (i as f64 + 0.5) * extent / cells as f64, 0.0, -4.0 + (j as f64 + 0.5) * extent / cells as f64);
                        let (l, w) = (light - x, y - x);
                        let (r2, d2) = (l.length_squared(), w.length_squared());
                        let (wl, wo) = (l / r2.sqrt(), w / d2.sqrt());
                        if wl.dot(n_s) * wo.dot(n_s) <= 0.0 {
                            continue;
                        }
                        let radiance = ALBEDO as f64 / PI * INTENSITY * wl.dot(n_s).abs() / r2;
                        e += radiance * wo.y * wo.y / d2 * da;
                    }
                }
                e
            })
            .sum::<f64>()
    };
    let (exact, face) = (quadrature(tilted_normal()), quadrature(DVec3::Y));
    let iterations = 8;
    for method in [Method::Arpa, Method::Rtpm] {
    let settings = RenderSettings { method, photons_per_iteration: 100_000, direct_lighting: true, max_depth: 2, radii, ..RenderSettings::default() };
    let mut estimate = 0.0;
    for iteration in 0..iterations {
        let (setup, fps, phs) = photon_pass(&scene, &caster, &settings, iteration);
        let r = setup.radii;
        estimate += points.iter().map(|q| gather_brute_force(q, &fps, &phs, r, Kernel::Silverman).irradiance().x).sum::<f64>();
    }
    let estimate = estimate / iterations as f64;
    let err = estimate / exact - 1.0;
    eprintln!("{method:?}: ceiling lit by the tilted floor: photons {estimate:.5} vs quadrature {exact:.5} ({:+.2}%); face-normal transport {face:.5} ({:+.1}%)", err * 100.0, (face / exact - 1.0) * 100.0);
    assert!((face / exact - 1.0).abs() > 0.05);
    assert!(err.abs() < 0.02, "{method:?}: {err}");
    }
}

/// Which triangles take the shading-normal paths: tilted vertex normals do; vertex normals
/// equal to the face normal (either orientation), or none, shade flat with the face normal.
#[test]
fn only_triangles_with_distinct_vertex_normals_are_shaded() {
    let hit = |scene: &PreparedScene| {
        let caster = BruteForceCaster::new(scene);
        let h = arpa_core::render::ray_cast::RayCaster::intersect(&caster, Vec3::new(0.3, 2.0, 0.2), Vec3::NEG_Y, 0.0, f32::INFINITY).unwrap();
        scene.surface(&h)
    };
    let tilted = tilted_plane_scene(4);
    let s = hit(&tilted);
    assert!(tilted.has_shading_normals(&s));
    assert!((tilted.shading_normal_at(&s) - tilted_normal()).length() < 1e-7);
    for normals in [None, Some(vec![Vec3::Y; 4]), Some(vec![Vec3::NEG_Y; 4])] {
        let mut scene = plane_scene(4);
        scene.meshes[0].normals = normals.clone();
        let scene = PreparedScene::new(scene).unwrap();
        let s = hit(&scene);
        assert!(!scene.has_shading_normals(&s), "{normals:?}");
        assert_eq!(scene.shading_normal_at(&s), s.geometric_normal);
    }
}
