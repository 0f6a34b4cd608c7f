//! The CPU backend's stages against the core's reference implementation, determinism
//! across thread counts, error handling of bad input, and stage ordering.

mod common;

use arpa_core::render::camera_path::trace_camera_path;
use arpa_core::emit::emission::{Light, LightError, QuadLight};
use arpa_core::gather::estimate::{QueryPoint, gather_brute_force};
use arpa_core::store::footprint::PackedFootprint;
use arpa_core::glam::{DVec3, Vec3};
use arpa_core::render::photon_path::{PhotonPassSetup, trace_photon};
use arpa_core::render::prepared_scene::PreparedScene;
use arpa_core::store::progressive_photon::PackedPhoton;
use arpa_core::render::brute_force::BruteForceCaster;
use arpa_core::render::scene::{Material, Scene, SceneError};
use arpa_core::store::decision::StoredPhoton;
use arpa_core::render::tracer::{
    BackendKind, Call, IterationStats, Method, RenderSettings, Stage, StageError, Tracer,
};
use arpa_cpu::{CpuError, CpuTracer};
use common::*;

/// An open box of a few big triangles: a diffuse floor and back wall, a mirror on the
/// left, a glass triangle above the floor (caustics), a point light and an emissive quad
/// facing down (area light). Every kind of interaction, on six quads' worth of triangles.
fn small_scene(size: u32) -> Scene {
    let meshes = vec![
        quad(
            "floor",
            Vec3::new(-1.0, 0.0, -1.0),
            Vec3::new(0.0, 0.0, 2.0),
            Vec3::new(2.0, 0.0, 0.0),
            0,
        ),
        quad(
            "back",
            Vec3::new(-1.0, 0.0, -1.0),
            Vec3::new(2.0, 0.0, 0.0),
            Vec3::new(0.0, 2.0, 0.0),
            1,
        ),
        quad(
            "mirror",
            Vec3::new(-1.0, 0.0, -1.0),
            Vec3::new(0.0, 2.0, 0.0),
            Vec3::new(0.0, 0.0, 2.0),
            2,
        ),
        mesh(
            "glass",
            vec![
                Vec3::new(0.0, 0.6, -0.2),
                Vec3::new(0.6, 0.6, -0.2),
                Vec3::new(0.3, 0.6, 0.4),
            ],
            vec![[0, 2, 1]],
            3,
        ),
        {
            let mut lamp = quad(
                "lamp",
                Vec3::new(-0.2, 1.9, -0.2),
                Vec3::new(0.4, 0.0, 0.0),
                Vec3::new(0.0, 0.0, 0.4),
                0,
            );
            lamp.emission = Some(Vec3::splat(5.0));
            lamp
        },
    ];
    let materials = vec![
        diffuse(0.7),
        Material::Diffuse {
            albedo: Vec3::new(0.6, 0.3, 0.2),
        },
        Material::Conductor {
            reflectance: Vec3::splat(0.9),
            roughness: 0.0,
        },
        Material::Dielectric {
            ior: 1.5,
            transmittance: Vec3::splat(1.0),
            roughness: 0.0,
        },
    ];
    scene(
        meshes,
        materials,
        vec![point_light(DVec3::new(0.3, 1.2, 0.2), 1.0)],
        camera(
            Vec3::new(0.0, 1.0, 2.5),
            Vec3::new(0.0, 0.5, 0.0),
            Vec3::Y,
            55f32.to_radians(),
            size,
        ),
    )
}

fn settings(method: Method, photons: u32, seed: u32) -> RenderSettings {
    RenderSettings {
        method,
        photons_per_iteration: photons,
        seed,
        max_depth: 8,
        direct_lighting: true,
        ..RenderSettings::default()
    }
}

// ---------------------------------------------------------------------------- agreement

fn close3(a: [f32; 3], b: [f32; 3], rel: f32, floor: f32) -> bool {
    let (a, b) = (Vec3::from_array(a), Vec3::from_array(b));
    (a - b).length() <= rel * b.length().max(floor)
}

fn same_footprint(a: &PackedFootprint, b: &PackedFootprint) -> bool {
    let density = |p: &PackedFootprint| p.flux_density();
    a.map == b.map
        && close3(a.center, b.center, 1e-4, 1.0)
        && close3(a.row_u, b.row_u, 1e-3, 0.0)
        && close3(a.row_v, b.row_v, 1e-3, 0.0)
        && close3(a.row_n, b.row_n, 1e-3, 0.0)
        && close3(density(a).to_array(), density(b).to_array(), 1e-3, 0.0)
}

fn same_photon(a: &PackedPhoton, b: &PackedPhoton) -> bool {
    a.map == b.map
        && close3(a.position, b.position, 1e-4, 1.0)
        && close3(a.normal, b.normal, 1e-4, 1.0)
        && close3(a.flux, b.flux, 1e-4, 0.0)
}

/// The backend's photon pass stores what `trace_photon` stores with the brute-force
/// caster (same count, same order, same content); its camera pass finds the same query
/// points as `trace_camera_path`; and its gather gives, bit for bit, what a brute-force
/// gather over its own records gives.
#[test]
fn stages_agree_with_the_core_reference() {
    for method in [Method::Arpa, Method::Rtpm] {
        let scene = small_scene(24);
        let settings = settings(method, 20_000, 11);
        let mut tracer = CpuTracer::new().unwrap();
        tracer.upload_scene(&scene, &settings).unwrap();
        tracer.photon_pass().unwrap();
        let footprints = tracer.read_footprints().unwrap();
        let photons = tracer.read_photons().unwrap();
        let stats = tracer.read_stats().unwrap();

        // Reference: every photon in index order through the brute-force caster.
        let prepared = PreparedScene::new(scene.clone()).unwrap();
        let caster = BruteForceCaster::new(&prepared);
        let setup = PhotonPassSetup::new(&prepared, &settings, 0);
        let (mut ref_fp, mut ref_ph, mut segments) = (Vec::new(), Vec::new(), 0u64);
        for index in 0..setup.photon_count() {
            let s = trace_photon(
                &prepared,
                &caster,
                &settings,
                &setup,
                index,
                &mut |p| match p {
                    StoredPhoton::Footprint { packed, .. } => ref_fp.push(packed),
                    StoredPhoton::Progressive { photon, .. } => ref_ph.push(photon),
                },
            );
            segments += s.segments as u64;
        }
        eprintln!(
            "{}: backend {} footprints + {} photons ({} segments), reference {} + {} ({} segments)",
            method.name(),
            footprints.len(),
            photons.len(),
            stats.photon_segments,
            ref_fp.len(),
            ref_ph.len(),
            segments
        );
        assert_eq!(stats.emitted[1], 20_000);
        assert_eq!(stats.photons_emitted, stats.emitted[0] + stats.emitted[1]);
        assert_eq!(
            (footprints.len(), photons.len()),
            (ref_fp.len(), ref_ph.len())
        );
        assert_eq!(stats.photon_segments, segments);
        assert!(photons.len() > 1000);
        if method == Method::Arpa {
            assert!(
                footprints.len() > 1000 && stats.footprints[0] > 0,
                "caustic footprints expected: {stats:?}"
            );
        }
        assert_eq!(
            stats.footprints.iter().sum::<u64>(),
            footprints.len() as u64
        );
        assert_eq!(stats.progressive.iter().sum::<u64>(), photons.len() as u64);
        for (i, (a, b)) in footprints.iter().zip(&ref_fp).enumerate() {
            assert!(
                same_footprint(a, b),
                "footprint {i}: {a:?} vs reference {b:?}"
            );
        }
        for (i, (a, b)) in photons.iter().zip(&ref_ph).enumerate() {
            assert!(same_photon(a, b), "photon {i}: {a:?} vs reference {b:?}");
        }

        // Camera pass.
        tracer.camera_pass().unwrap();
        let queries = tracer.read_query_points().unwrap();
        assert_eq!(queries.len(), 24 * 24);
        let mut valid = 0;
        for (pixel, q) in queries.iter().enumerate() {
            let r = trace_camera_path(&prepared, &caster, &settings, 0, pixel as u32);
            assert_eq!((q.pixel, q.valid), (r.pixel, r.valid), "pixel {pixel}");
            assert!(
                close3(q.position, r.position, 1e-4, 1.0),
                "pixel {pixel}: {q:?} vs {r:?}"
            );
            assert!(close3(q.normal, r.normal, 1e-4, 1.0), "pixel {pixel}");
            assert!(close3(q.weight, r.weight, 1e-4, 1e-6), "pixel {pixel}");
            assert!(
                close3(q.radiance, r.radiance, 1e-3, 1e-6),
                "pixel {pixel}: {q:?} vs {r:?}"
            );
            valid += q.valid;
        }
        assert!(valid > 24 * 24 / 2, "{valid} valid query points");

        // Gather: the box BVH finds exactly what testing every record finds.
        tracer.build_acceleration_structure().unwrap();
        tracer.gather().unwrap();
        tracer.accumulate().unwrap();
        let image = tracer.read_image().unwrap();
        let radii = tracer.read_stats().unwrap().radii.map(|r| r as f32);
        let mut contributions = 0u64;
        for (pixel, q) in queries.iter().enumerate() {
            let mut expected = Vec3::from_array(q.radiance).as_dvec3();
            if q.valid == 1 {
                let qp = QueryPoint {
                    position: Vec3::from_array(q.position),
                    normal: Vec3::from_array(q.normal),
                };
                let e = gather_brute_force(&qp, &footprints, &photons, radii.map(f64::from), settings.kernel);
                contributions += (e.footprints + e.photons) as u64;
                expected += Vec3::from_array(q.weight).as_dvec3() * e.irradiance();
            }
            assert_eq!(image.pixels[pixel], expected.as_vec3(), "pixel {pixel}");
        }
        assert_eq!(tracer.read_stats().unwrap().gathered(), contributions);
        assert!(contributions > 300, "{contributions} contributions");
        assert_eq!(tracer.embree_errors(), 0);
    }
}

// ---------------------------------------------------------------------------- determinism

struct Run {
    image: Vec<[u32; 3]>,
    footprints: Vec<PackedFootprint>,
    photons: Vec<PackedPhoton>,
    stats: IterationStats,
}

fn run(scene: &Scene, settings: &RenderSettings, iterations: u32) -> Run {
    let mut tracer = CpuTracer::new().unwrap();
    tracer.upload_scene(scene, settings).unwrap();
    for _ in 0..iterations {
        tracer.iterate().unwrap();
    }
    let mut stats = tracer.read_stats().unwrap();
    stats.times = Default::default();
    Run {
        image: tracer
            .read_image()
            .unwrap()
            .pixels
            .iter()
            .map(|p| p.to_array().map(f32::to_bits))
            .collect(),
        footprints: tracer.read_footprints().unwrap(),
        photons: tracer.read_photons().unwrap(),
        stats,
    }
}

fn in_pool<T: Send>(threads: usize, f: impl FnOnce() -> T + Send) -> T {
    rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .unwrap()
        .install(f)
}

/// Same seed: bit-identical images, stored photons and counts, with 1 or 2 threads (and
/// more photons than one chunk, so chunks really are spread over threads). A different
/// seed gives a different image.
#[test]
fn bit_identical_for_any_thread_count() {
    let scene = small_scene(20);
    for method in [Method::Arpa, Method::Rtpm] {
        let settings = settings(method, 3 * arpa_cpu::PHOTON_CHUNK + 123, 5);
        let one = in_pool(1, || run(&scene, &settings, 2));
        let two = in_pool(2, || run(&scene, &settings, 2));
        let again = in_pool(2, || run(&scene, &settings, 2));
        assert!(
            one.image == two.image,
            "{}: images differ between 1 and 2 threads",
            method.name()
        );
        assert!(
            two.image == again.image,
            "{}: images differ between two runs",
            method.name()
        );
        assert_eq!(one.footprints, two.footprints);
        assert_eq!(one.photons, two.photons);
        assert_eq!(one.stats, two.stats);
        assert_eq!(one.stats.iteration, 2);
        assert!(one.image.iter().any(|p| p[0] != 0), "black image");
        let other = in_pool(2, || {
            run(
                &scene,
                &RenderSettings {
                    seed: 6,
                    ..settings
                },
                2,
            )
        });
        assert!(other.image != one.image, "the seed changes nothing");
    }
}

// ---------------------------------------------------------------------------- bad input

/// The error of an upload rejected for `e`.
fn scene_err(e: SceneError) -> CpuError {
    CpuError::Stage(StageError::Scene(e))
}

fn upload_err(scene: &Scene, settings: &RenderSettings) -> CpuError {
    let mut tracer = CpuTracer::new().unwrap();
    let err = tracer.upload_scene(scene, settings).unwrap_err();
    // A failed upload leaves nothing to render.
    assert!(matches!(
        tracer.camera_pass(),
        Err(CpuError::Stage(StageError::Order {
            needs: Stage::UploadScene,
            ..
        }))
    ));
    assert!(tracer.read_image().is_err());
    eprintln!("rejected: {err}");
    err
}

#[test]
fn bad_input_is_a_documented_error() {
    let good = small_scene(8);
    let s = settings(Method::Arpa, 1000, 0);

    let mut nan = good.clone();
    nan.meshes[1].positions[2].y = f32::NAN;
    assert_eq!(
        upload_err(&nan, &s),
        scene_err(SceneError::NonFiniteVertex {
            mesh: "back".into(),
            vertex: 2,
            what: "position"
        })
    );

    let mut zero_area = good.clone();
    let lamp = zero_area
        .meshes
        .iter_mut()
        .find(|m| m.name == "lamp")
        .unwrap();
    lamp.positions = vec![
        Vec3::new(0.0, 1.9, 0.0),
        Vec3::new(0.1, 1.9, 0.0),
        Vec3::new(0.2, 1.9, 0.0),
        Vec3::new(0.3, 1.9, 0.0),
    ];
    assert_eq!(
        upload_err(&zero_area, &s),
        scene_err(SceneError::BadEmitter {
            mesh: "lamp".into(),
            why: "has zero area"
        })
    );

    let mut zero_quad = good.clone();
    zero_quad.lights.push(Light::Quad(QuadLight {
        origin: DVec3::Y,
        edge_u: DVec3::X,
        edge_v: DVec3::ZERO,
        radiance: DVec3::ONE,
    }));
    assert_eq!(
        upload_err(&zero_quad, &s),
        scene_err(SceneError::BadLight {
            index: 1,
            source: LightError::ZeroArea
        })
    );

    let mut dark = good.clone();
    dark.lights.clear();
    for m in &mut dark.meshes {
        m.emission = None;
    }
    assert_eq!(upload_err(&dark, &s), scene_err(SceneError::NoLights));

    let mut blind = good.clone();
    blind.camera.target = blind.camera.position;
    assert!(matches!(
        upload_err(&blind, &s),
        CpuError::Stage(StageError::Scene(SceneError::DegenerateCamera(_)))
    ));

    let mut bad_index = good.clone();
    bad_index.meshes[0].indices[1][2] = 99;
    assert!(matches!(
        upload_err(&bad_index, &s),
        CpuError::Stage(StageError::Scene(SceneError::IndexOutOfRange { index: 99, .. }))
    ));

    for bad in [
        RenderSettings {
            photons_per_iteration: 0,
            ..s
        },
        RenderSettings { max_depth: 0, ..s },
        RenderSettings {
            smoothing: arpa_core::propagate::classify::Smoothing {
                caustic: f64::NAN,
                global: 1.0,
            },
            ..s
        },
        RenderSettings {
            radii: arpa_core::accumulate::radius::ProgressiveConfig {
                alpha: 0.0,
                ..s.radii
            },
            ..s
        },
        RenderSettings {
            radii: arpa_core::accumulate::radius::ProgressiveConfig {
                global: arpa_core::accumulate::radius::RadiusSpec::Absolute(-1.0),
                ..s.radii
            },
            ..s
        },
    ] {
        assert!(
            matches!(
                upload_err(&good, &bad),
                CpuError::Stage(StageError::Settings(_))
            ),
            "{bad:?}"
        );
    }

    // The tracer is usable after a rejected upload.
    let mut tracer = CpuTracer::new().unwrap();
    assert!(tracer.upload_scene(&dark, &s).is_err());
    tracer.upload_scene(&good, &s).unwrap();
    tracer.iterate().unwrap();
    assert_eq!(tracer.iterations(), 1);
}

// ---------------------------------------------------------------------------- stage order

#[test]
fn stages_out_of_order_are_errors() {
    use Stage::*;
    fn order(call: impl Into<Call>, needs: Stage) -> CpuError {
        CpuError::Stage(StageError::order(call, needs))
    }
    let mut t = CpuTracer::new().unwrap();
    assert_eq!(t.camera_pass(), Err(order(CameraPass, UploadScene)));
    assert_eq!(t.photon_pass(), Err(order(PhotonPass, UploadScene)));
    assert_eq!(
        t.build_acceleration_structure(),
        Err(order(BuildAccelerationStructure, UploadScene))
    );
    assert_eq!(t.gather(), Err(order(Gather, UploadScene)));
    assert_eq!(t.accumulate(), Err(order(Accumulate, UploadScene)));
    assert!(t.iterate().is_err());
    assert!(t.read_image().is_err() && t.read_stats().is_err() && t.read_query_points().is_err());
    assert!(t.read_footprints().is_err() && t.read_photons().is_err());
    assert_eq!(t.iterations(), 0);

    t.upload_scene(&small_scene(8), &settings(Method::Arpa, 2000, 1))
        .unwrap();
    assert_eq!(t.read_image().unwrap().pixels, vec![Vec3::ZERO; 64]);
    assert_eq!(t.gather(), Err(order(Gather, CameraPass)));
    assert_eq!(
        t.build_acceleration_structure(),
        Err(order(BuildAccelerationStructure, PhotonPass))
    );
    assert_eq!(t.accumulate(), Err(order(Accumulate, Gather)));
    assert_eq!(
        t.read_query_points(),
        Err(order(Call::ReadQueryPoints, CameraPass))
    );
    assert_eq!(
        t.read_footprints(),
        Err(order(Call::ReadFootprints, PhotonPass))
    );
    t.camera_pass().unwrap();
    t.photon_pass().unwrap();
    assert_eq!(
        t.gather(),
        Err(order(Gather, BuildAccelerationStructure))
    );
    t.build_acceleration_structure().unwrap();
    // Re-running the photon pass invalidates the acceleration structure.
    t.photon_pass().unwrap();
    assert_eq!(
        t.gather(),
        Err(order(Gather, BuildAccelerationStructure))
    );
    t.build_acceleration_structure().unwrap();
    t.gather().unwrap();
    t.accumulate().unwrap();
    assert_eq!(t.iterations(), 1);
    // Each stage's output belongs to its iteration: the next iteration starts over.
    assert_eq!(t.accumulate(), Err(order(Accumulate, Gather)));
    assert_eq!(t.gather(), Err(order(Gather, CameraPass)));
    t.camera_pass().unwrap();
    assert_eq!(
        t.build_acceleration_structure(),
        Err(order(BuildAccelerationStructure, PhotonPass))
    );
    assert_eq!(
        t.gather(),
        Err(order(Gather, BuildAccelerationStructure))
    );
    // Stage outputs of the last pass stay readable.
    assert_eq!(t.read_query_points().unwrap().len(), 64);
    assert!(!t.read_photons().unwrap().is_empty());
    t.photon_pass().unwrap();
    t.build_acceleration_structure().unwrap();
    t.gather().unwrap();
    t.accumulate().unwrap();
    let stats = t.read_stats().unwrap();
    assert_eq!(stats.iteration, 2);
    assert!(stats.times.photon > 0.0 && stats.times.gather > 0.0);
    let caps = t.capabilities();
    assert_eq!(caps.backend, BackendKind::Cpu);
    assert!(
        caps.deterministic
            && caps.methods.contains(&Method::Arpa)
            && caps.methods.contains(&Method::Rtpm)
    );
    eprintln!("device: {}", caps.device);
}

/// Nothing stored: a floor under a point light with direct lighting by next-event
/// estimation (so direct photons are not stored) and nothing above it for photons to bounce
/// back from. The empty box sets work, nothing is gathered, and the image is the direct
/// light alone: `ρ/π · I cos θ/d²`.
#[test]
fn empty_photon_buffers_work() {
    // A black floor: direct photons are not stored (direct lighting on) and all die there.
    let floor = quad(
        "floor",
        Vec3::new(-5.0, 0.0, -5.0),
        Vec3::new(0.0, 0.0, 10.0),
        Vec3::new(10.0, 0.0, 0.0),
        0,
    );
    let light = DVec3::new(0.0, 1.0, 0.0);
    let scene = scene(
        vec![floor],
        vec![Material::Diffuse { albedo: Vec3::ZERO }],
        vec![point_light(light, 3.0)],
        camera(Vec3::new(0.0, 2.0, 0.0), Vec3::ZERO, Vec3::Z, 0.5, 8),
    );
    let mut t = CpuTracer::new().unwrap();
    t.upload_scene(&scene, &settings(Method::Arpa, 5000, 3))
        .unwrap();
    t.iterate().unwrap();
    let stats = t.read_stats().unwrap();
    assert_eq!(
        (stats.footprints, stats.progressive, stats.gathered()),
        ([0, 0], [0, 0], 0)
    );
    assert!(t.read_footprints().unwrap().is_empty() && t.read_photons().unwrap().is_empty());
    assert_eq!(t.read_image().unwrap().pixels, vec![Vec3::ZERO; 64]);

    // Grey floor, RTPM, no direct photons stored, nothing comes back: image = NEE only.
    let mut grey = scene.clone();
    grey.materials[0] = diffuse(0.5);
    t.upload_scene(&grey, &settings(Method::Rtpm, 5000, 3))
        .unwrap();
    t.iterate().unwrap();
    let stats = t.read_stats().unwrap();
    assert_eq!((stats.progressive, stats.gathered()), ([0, 0], 0));
    let queries = t.read_query_points().unwrap();
    let image = t.read_image().unwrap();
    for (q, p) in queries.iter().zip(&image.pixels) {
        let d = light - Vec3::from_array(q.position).as_dvec3();
        let expected = 0.5 / std::f64::consts::PI * 3.0 * (1.0 / d.length()) / d.length_squared();
        assert!(
            (p.x as f64 / expected - 1.0).abs() < 1e-5,
            "{p:?} vs {expected}"
        );
    }
}

/// On a coarse sphere (80 facets, 20° between neighbouring normals) query points near a
/// facet edge lie well off the planes of the footprints on the neighbouring facet, where
/// the elliptic cylinder a footprint's test accepts reaches beyond the box of its
/// ellipsoid: the gather must still find every footprint and photon that a brute-force
/// gather finds, bit for bit, for the constant kernel too (full weight at the rim).
#[test]
fn gather_matches_brute_force_on_a_facetted_sphere() {
    use arpa_core::gather::kernel::Kernel;
    let sphere = icosphere(Vec3::ZERO, 1.0, 1, 0);
    let scene = scene(
        vec![sphere],
        vec![diffuse(0.6)],
        vec![point_light(DVec3::new(0.2, -0.3, 0.1), 1.0)],
        camera(
            Vec3::new(0.0, 0.0, -0.3),
            Vec3::new(0.1, 0.2, 1.0),
            Vec3::Y,
            1.4,
            24,
        ),
    );
    for kernel in [Kernel::Constant, Kernel::Silverman] {
        for method in [Method::Arpa, Method::Rtpm] {
            let settings = RenderSettings {
                kernel,
                direct_lighting: false,
                ..settings(method, 40_000, 2)
            };
            let mut tracer = CpuTracer::new().unwrap();
            tracer.upload_scene(&scene, &settings).unwrap();
            tracer.iterate().unwrap();
            let (footprints, photons) = (
                tracer.read_footprints().unwrap(),
                tracer.read_photons().unwrap(),
            );
            let queries = tracer.read_query_points().unwrap();
            let stats = tracer.read_stats().unwrap();
            let radii = stats.radii.map(|r| r as f32);
            let image = tracer.read_image().unwrap();
            let mut contributions = 0u64;
            for (pixel, q) in queries.iter().enumerate() {
                assert_eq!(q.valid, 1);
                let qp = QueryPoint {
                    position: Vec3::from_array(q.position),
                    normal: Vec3::from_array(q.normal),
                };
                let e = gather_brute_force(&qp, &footprints, &photons, radii.map(f64::from), kernel);
                contributions += (e.footprints + e.photons) as u64;
                let expected = Vec3::from_array(q.radiance).as_dvec3()
                    + Vec3::from_array(q.weight).as_dvec3() * e.irradiance();
                assert_eq!(
                    image.pixels[pixel],
                    expected.as_vec3(),
                    "{kernel:?} {method:?} pixel {pixel}"
                );
            }
            eprintln!(
                "{kernel:?} {}: {} footprints, {} photons, {contributions} contributions",
                method.name(),
                footprints.len(),
                photons.len()
            );
            assert_eq!(stats.gathered(), contributions);
            assert!(contributions > 10_000);
        }
    }
}
