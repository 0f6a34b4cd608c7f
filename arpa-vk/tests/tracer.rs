//! The Vulkan tracer end to end on lavapipe under the validation layer: a closed box with a
//! point light, a diffuse floor and walls, a mirror panel and a glass sphere (both maps,
//! both record kinds), a few iterations of each method. The checks: every stage's counts
//! are consistent, the image is finite and lit, the validation layer reports nothing, the
//! same seed gives the same bits, and an overflowing photon buffer (tiny initial capacity)
//! gives exactly the image of a large enough one. Radiometric agreement with the other
//! backends and with analytic irradiance is the conformance suite's (`arpa-conformance`).

use arpa_core::emission::{Light, PointLight};
use arpa_core::scene::{Camera, Material, Scene};
use arpa_core::shapes::{icosphere, parallelogram};
use arpa_core::tracer::{Image, IterationStats, Method, RenderSettings, Tracer};
use arpa_vk::VkTracer;
use glam::{DVec3, Vec3};

mod support;
use support::assert_clean;

fn tracer() -> Option<VkTracer> {
    support::context("tracer").map(VkTracer::with_context)
}

fn scene() -> Scene {
    let s = 1.0;
    let meshes = vec![
        parallelogram("floor", Vec3::new(-s, 0.0, -s), Vec3::new(0.0, 0.0, 2.0 * s), Vec3::new(2.0 * s, 0.0, 0.0), 0),
        parallelogram("ceiling", Vec3::new(-s, 2.0, -s), Vec3::new(2.0 * s, 0.0, 0.0), Vec3::new(0.0, 0.0, 2.0 * s), 0),
        parallelogram("back", Vec3::new(-s, 0.0, -s), Vec3::new(2.0 * s, 0.0, 0.0), Vec3::new(0.0, 2.0, 0.0), 0),
        parallelogram("left", Vec3::new(-s, 0.0, -s), Vec3::new(0.0, 2.0, 0.0), Vec3::new(0.0, 0.0, 2.0 * s), 0),
        parallelogram("right", Vec3::new(s, 0.0, -s), Vec3::new(0.0, 0.0, 2.0 * s), Vec3::new(0.0, 2.0, 0.0), 0),
        icosphere("glass", Vec3::new(0.3, 0.5, -0.2), 0.35, 3, true, 1),
        parallelogram("mirror", Vec3::new(-0.9, 0.2, -0.6), Vec3::new(0.0, 0.8, 0.0), Vec3::new(0.3, 0.0, 0.6), 2),
    ];
    Scene {
        meshes,
        materials: vec![
            Material::Diffuse { albedo: Vec3::splat(0.6) },
            Material::Dielectric { ior: 1.5, transmittance: Vec3::ONE, roughness: 0.0 },
            Material::Conductor { reflectance: Vec3::splat(0.9), roughness: 0.0 },
        ],
        lights: vec![Light::Point(PointLight { position: DVec3::new(0.0, 1.8, 0.0), intensity: DVec3::splat(2.0) })],
        camera: Camera { position: Vec3::new(0.0, 1.0, 3.0), target: Vec3::new(0.0, 0.8, 0.0), up: Vec3::Y, vertical_fov: 0.8, width: 48, height: 40 },
        roughness_cutoff: 0.5,
    }
}

fn settings(method: Method) -> RenderSettings {
    RenderSettings { method, photons_per_iteration: 20_000, seed: 7, ..RenderSettings::default() }
}

/// Renders `iterations` and returns the image and each iteration's stats.
fn render(t: &mut VkTracer, scene: &Scene, settings: &RenderSettings, iterations: u32) -> (Image, Vec<IterationStats>) {
    t.upload_scene(scene, settings).expect("upload");
    let mut stats = Vec::new();
    for _ in 0..iterations {
        t.iterate().expect("iteration");
        stats.push(t.read_stats().expect("stats"));
    }
    (t.read_image().expect("image"), stats)
}

fn bits(image: &Image) -> Vec<u32> {
    image.pixels.iter().flat_map(|p| p.to_array().map(f32::to_bits)).collect()
}

#[test]
fn renders_both_methods_cleanly_and_deterministically() {
    let Some(mut t) = tracer() else { return };
    let log = t.context().validation_log();
    let scene = scene();
    for method in [Method::Arpa, Method::Rtpm] {
        let s = settings(method);
        let (image, stats) = render(&mut t, &scene, &s, 3);
        let pixels = (scene.camera.width * scene.camera.height) as u64;
        for (i, st) in stats.iter().enumerate() {
            // The global pass emits the settings' photons, the caustic pass its own.
            assert_eq!(st.emitted[1], u64::from(s.photons_per_iteration), "{method:?} iteration {i}: {st:?}");
            assert_eq!(st.photons_emitted, st.emitted[0] + st.emitted[1], "{method:?} iteration {i}: {st:?}");
            assert!(st.query_points > pixels / 2 && st.query_points <= pixels, "{method:?} {i}: {st:?}");
            let records: u64 = st.footprints.iter().chain(&st.progressive).sum();
            assert!(records > 1000 && st.gathered() > st.query_points, "{method:?} {i}: {st:?}");
            assert!(st.footprints[0] + st.progressive[0] > 0, "{method:?} {i}: no caustic records: {st:?}");
            if method == Method::Rtpm {
                assert_eq!(st.footprints, [0, 0], "{st:?}");
            } else {
                assert!(st.footprints[1] > 0, "{st:?}");
            }
        }
        assert!(image.pixels.iter().all(|p| p.is_finite() && p.min_element() >= 0.0), "{method:?}: non-finite or negative pixel");
        let mean: f64 = image.pixels.iter().map(|p| f64::from(p.x + p.y + p.z)).sum::<f64>() / image.pixels.len() as f64;
        assert!(mean > 1e-3, "{method:?}: image mean {mean}");
        let (again, _) = render(&mut t, &scene, &s, 3);
        assert!(bits(&image) == bits(&again), "{method:?}: the same seed gave different images");
        eprintln!("arpa-vk {method:?}: mean radiance {mean:.5}, last iteration {:?}", stats.last().map(|s| s.times));
    }
    assert_clean(&log, "while rendering");
    drop(t);
    assert_clean(&log, "while destroying");
}

#[test]
fn overflow_grows_the_buffers_without_changing_the_image() {
    let Some(mut t) = tracer() else { return };
    let scene = scene();
    let s = settings(Method::Arpa);
    let (want, _) = render(&mut t, &scene, &s, 2);
    t.set_initial_capacity(Some(64));
    let (got, stats) = render(&mut t, &scene, &s, 2);
    assert!(stats[0].overflowed > 0, "a 64-record buffer did not overflow: {:?}", stats[0]);
    assert_eq!(stats[1].overflowed, 0, "the buffers stay grown: {:?}", stats[1]);
    assert!(bits(&want) == bits(&got), "the grown buffers gave another image");
    assert_clean(&t.context().validation_log(), "while rendering");
}

#[test]
fn photon_batches_sum_to_the_single_pass_image() {
    let Some(mut t) = tracer() else { return };
    let scene = scene();
    let s = settings(Method::Arpa);
    let (want, one) = render(&mut t, &scene, &s, 2);
    let records = t.read_footprints().expect("footprints").len() + t.read_photons().expect("photons").len();
    t.set_batch_photons(Some(7_000));
    let (got, three) = render(&mut t, &scene, &s, 2);
    assert_eq!(t.batch_photons(), Some(7_000));
    // The same photons, records and contributions, in three batches.
    for (a, b) in one.iter().zip(&three) {
        assert_eq!((a.photons_emitted, a.footprints, a.progressive, a.contributions, a.candidates, a.query_points), (b.photons_emitted, b.footprints, b.progressive, b.contributions, b.candidates, b.query_points));
    }
    assert_eq!(t.read_footprints().expect("footprints").len() + t.read_photons().expect("photons").len(), records);
    // Summed in another f32 order: equal to rounding.
    let mut worst = 0.0f32;
    for (a, b) in want.pixels.iter().zip(&got.pixels) {
        let d = (*a - *b).abs().max_element() / a.max_element().max(1e-3);
        worst = worst.max(d);
    }
    assert!(worst < 1e-4, "batched image differs from the single-pass one by {worst:e} (relative)");
    assert_clean(&t.context().validation_log(), "while rendering in batches");
}
