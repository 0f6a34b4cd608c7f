//! The Vulkan tracer end to end on lavapipe under the validation layer: a closed box with a
//! point light, a diffuse floor and walls, a mirror panel and a glass sphere (both maps,
//! both record kinds), a few iterations of each method. The checks: every stage's counts
//! are consistent, the image is finite and lit, the validation layer reports nothing, the
//! same seed gives the same bits, and an overflowing photon buffer (tiny initial capacity)
//! gives exactly the image of a large enough one. The planes of a per-pixel bandwidth (the
//! default): every plane accumulated, the image is the core's selection over them, the
//! stored scale's plane is bit for bit a global-bandwidth render's image, the moment planes
//! are the core's moments of the radiance planes, and a checkpoint of every plane resumes
//! exactly. Radiometric agreement with the other backends and with analytic irradiance is
//! the conformance suite's (`arpa-conformance`).

use arpa_core::emit::emission::{Light, PointLight};
use arpa_core::render::scene::{Camera, Material, Scene};
use arpa_core::render::shapes::{icosphere, parallelogram};
use arpa_core::accumulate::image::Accumulation;
use arpa_core::gather::scales::{Bandwidth, PLANES, SCALES, moments};
use arpa_core::render::tracer::{Image, IterationStats, Method, RenderSettings, Tracer};
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
    Scene { textures: Default::default(),
        meshes,
        materials: vec![
            Material::Diffuse { albedo: Vec3::splat(0.6) },
            Material::Dielectric { ior: 1.5, transmittance: Vec3::ONE, roughness: 0.0 },
            Material::Conductor { reflectance: Vec3::splat(0.9), roughness: 0.0 },
        ],
        lights: vec![Light::Point(PointLight { position: DVec3::new(0.0, 1.8, 0.0), intensity: DVec3::splat(2.0) })],
        camera: Camera { position: Vec3::new(0.0, 1.0, 3.0), target: Vec3::new(0.0, 0.8, 0.0), up: Vec3::Y, vertical_fov: 0.8, width: 48, height: 40 },
        roughness_cutoff: 0.5,
        instancing: None,
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

/// The means of the radiance planes of the accumulation (every scale), plane after plane.
fn radiance_planes(t: &VkTracer) -> Vec<Vec3> {
    let acc = t.read_accumulation().expect("accumulation");
    (0..(acc.planes as usize).min(SCALES)).flat_map(|p| acc.plane_mean(p)).collect()
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

/// Buffers of 64 records (no calibration): each iteration's pipelined photon pass
/// overflows them, its accumulate leaves the sums alone and traces the iteration again with
/// grown buffers, and the next iteration starts on the 64 records again. The records and
/// counts are the calibrated render's; the structures are built over other capacities, so
/// the gather sums the same contributions in another `f32` order.
#[test]
fn overflow_traces_the_iteration_again_with_the_same_records() {
    let Some(mut t) = tracer() else { return };
    let scene = scene();
    let s = settings(Method::Arpa);
    let (want, fitted) = render(&mut t, &scene, &s, 2);
    assert!(fitted.iter().all(|s| s.overflowed == 0), "the calibrated buffers overflowed: {fitted:?}");
    t.set_initial_capacity(Some(64));
    let (got, stats) = render(&mut t, &scene, &s, 2);
    for (a, b) in fitted.iter().zip(&stats) {
        assert!(b.overflowed > 0, "a 64-record buffer did not overflow: {b:?}");
        assert_eq!((a.photons_emitted, a.footprints, a.progressive, a.contributions, a.candidates, a.query_points), (b.photons_emitted, b.footprints, b.progressive, b.contributions, b.candidates, b.query_points));
    }
    let mut worst = 0.0f32;
    for (a, b) in want.pixels.iter().zip(&got.pixels) {
        assert!(b.is_finite());
        worst = worst.max((*a - *b).abs().max_element() / a.max_element().max(1e-3));
    }
    assert!(worst < 1e-4, "the iterations traced again differ from the calibrated ones by {worst:e} (relative)");
    assert_clean(&t.context().validation_log(), "while rendering");
}

#[test]
fn photon_batches_sum_to_the_single_pass_image() {
    let Some(mut t) = tracer() else { return };
    let scene = scene();
    let s = settings(Method::Arpa);
    let (_, one) = render(&mut t, &scene, &s, 2);
    // Every radiance plane (the per-pixel selection may tip between scales on one ulp).
    let want = radiance_planes(&t);
    let records = t.read_footprints().expect("footprints").len() + t.read_photons().expect("photons").len();
    t.set_batch_photons(Some(7_000));
    let (_, three) = render(&mut t, &scene, &s, 2);
    let got = radiance_planes(&t);
    assert_eq!(t.batch_photons(), Some(7_000));
    // The same photons, records and contributions, in three batches.
    for (a, b) in one.iter().zip(&three) {
        assert_eq!((a.photons_emitted, a.footprints, a.progressive, a.contributions, a.candidates, a.query_points), (b.photons_emitted, b.footprints, b.progressive, b.contributions, b.candidates, b.query_points));
    }
    assert_eq!(t.read_footprints().expect("footprints").len() + t.read_photons().expect("photons").len(), records);
    // Summed in another f32 order: equal to rounding.
    let mut worst = 0.0f32;
    for (a, b) in want.iter().zip(&got) {
        let d = (*a - *b).abs().max_element() / a.max_element().max(1e-3);
        worst = worst.max(d);
    }
    assert!(worst < 1e-4, "batched image differs from the single-pass one by {worst:e} (relative)");
    assert_clean(&t.context().validation_log(), "while rendering in batches");
}

#[test]
fn per_pixel_planes_are_accumulated_and_resume_exactly() {
    let Some(mut t) = tracer() else { return };
    let log = t.context().validation_log();
    let scene = scene();
    let s = settings(Method::Arpa);
    let px = (scene.camera.width * scene.camera.height) as usize;
    // One iteration: the stored scale's plane is a global render's image bit for bit, the
    // selection takes it everywhere, the moments are the core's of the radiance planes.
    let (global, _) = render(&mut t, &scene, &RenderSettings { bandwidth: Bandwidth::Global, ..s }, 1);
    assert_eq!(t.read_accumulation().expect("accumulation").planes, 1);
    let (image, _) = render(&mut t, &scene, &s, 1);
    let acc = t.read_accumulation().expect("accumulation");
    assert_eq!((acc.planes as usize, acc.pixels.len()), (PLANES, PLANES * px));
    assert_eq!(acc.mean(), image.pixels, "read_image is the core's mean of the accumulation");
    let planes: Vec<Vec<Vec3>> = (0..PLANES).map(|p| acc.plane_mean(p)).collect();
    assert!(bits(&global) == bits(&Image { width: 48, height: 40, pixels: planes[0].clone() }), "the stored scale differs from a global render");
    assert_eq!(image.pixels, planes[0]);
    let mut differ = 0;
    let ladders: Vec<[Vec3; SCALES]> = (0..px).map(|i| std::array::from_fn(|k| planes[k][i])).collect();
    for (i, l) in ladders.iter().enumerate() {
        differ += (l[0] != l[SCALES - 1]) as usize;
        let want = moments(l);
        let peak = l.iter().map(|c| c.max_element()).fold(0.0, f32::max);
        for (p, &w) in want.iter().enumerate() {
            let g = planes[SCALES + p][i];
            assert!((g - w).abs().max_element() <= 16.0 * f32::EPSILON * peak * peak, "pixel {i} moment plane {p}: {g:?} vs {w:?}");
        }
    }
    assert!(differ > px / 4, "the smallest scale equals the stored one in {} of {px} pixels", px - differ);
    // Three iterations straight, and two, a checkpoint, a new upload and one more.
    let (whole, _) = render(&mut t, &scene, &s, 3);
    render(&mut t, &scene, &s, 2);
    let checkpoint = t.read_accumulation().expect("checkpoint");
    t.upload_scene(&scene, &s).expect("upload");
    t.restore_accumulation(&checkpoint).expect("restore");
    t.iterate().expect("iteration");
    assert!(bits(&t.read_image().expect("image")) == bits(&whole), "the resumed per-pixel render differs");
    // An empty one-plane accumulation starts a part with every plane; a checkpoint of
    // another bandwidth is refused.
    t.upload_scene(&scene, &s).expect("upload");
    t.restore_accumulation(&Accumulation::empty(48, 40, 3)).expect("restore an empty part");
    t.iterate().expect("iteration");
    let part = t.read_accumulation().expect("part");
    assert_eq!((part.planes as usize, part.first_iteration, part.iterations), (PLANES, 3, 1));
    t.upload_scene(&scene, &RenderSettings { bandwidth: Bandwidth::Global, ..s }).expect("upload");
    let e = t.restore_accumulation(&checkpoint).expect_err("a per-pixel checkpoint into a global render").to_string();
    assert!(e.contains("planes"), "{e}");
    assert_clean(&log, "while rendering per-pixel planes");
}

/// Device times of a finished iteration: measured on an adapter with timestamps (lavapipe
/// has them), every stage finite and non-negative, the traced passes non-zero, each stage
/// and the total within the iteration's wall time (plus 1 ms and 1 % for the two clocks'
/// rounding).
fn check_device_times(stats: &IterationStats, wall: f64, has_timestamps: bool) {
    use arpa_core::render::tracer::DeviceTimes;
    let d = match stats.device_times {
        DeviceTimes::Measured(d) => d,
        other => {
            assert!(!has_timestamps, "the adapter has timestamps but iteration {} has device times {other:?}", stats.iteration);
            return;
        }
    };
    // A stage that reads nothing back returns before its device work is done, so a
    // stage's device time may exceed its host time; each is within the iteration's.
    let slack = |t: f64| t * 1.01 + 1e-3;
    for (name, dev) in [("camera", d.camera), ("photon", d.photon), ("build", d.build), ("gather", d.gather), ("accumulate", d.accumulate)] {
        assert!(dev.is_finite() && dev >= 0.0 && dev <= slack(wall), "{name}: device {dev} s, iteration wall {wall} s");
    }
    assert!(d.camera > 0.0 && d.photon > 0.0 && d.gather > 0.0, "the passes that trace take device time: {d:?}");
    assert!(d.total() <= slack(wall), "device total {} s over the iteration's wall time {wall} s", d.total());
}

#[test]
fn every_iteration_reports_device_time_per_stage() {
    let Some(mut t) = tracer() else { return };
    let has_timestamps = t.context().timestamps().is_some();
    if t.context().is_lavapipe() {
        let ts = t.context().timestamps().expect("lavapipe's queue has timestamps");
        assert!(ts.valid_bits >= 36 && ts.period_ns > 0.0, "{ts:?}");
    }
    t.upload_scene(&scene(), &RenderSettings { photons_per_iteration: 20_000, seed: 3, ..RenderSettings::default() }).unwrap();
    for _ in 0..3 {
        let start = std::time::Instant::now();
        t.iterate().unwrap();
        let wall = start.elapsed().as_secs_f64();
        check_device_times(&t.read_stats().unwrap(), wall, has_timestamps);
    }
    assert_clean(&t.context().validation_log(), "while timing stages");
}

/// No stage before the accumulate waits: each returns with its work in flight (the photon
/// pass with every batch's trace and store, three batches here), and the counts read back at
/// the iteration's one wait are what `read_stats` reads (with a wait of its own) between a
/// gather and its accumulate; the accumulate leaves nothing in flight.
#[test]
fn stages_that_read_nothing_leave_their_work_in_flight() {
    let Some(mut t) = tracer() else { return };
    t.set_batch_photons(Some(7_000));
    t.upload_scene(&scene(), &RenderSettings { photons_per_iteration: 20_000, seed: 5, ..RenderSettings::default() }).unwrap();
    t.set_batch_photons(None);
    for _ in 0..2 {
        t.camera_pass().unwrap();
        assert!(t.context().in_flight() > 0, "the camera pass waited for its trace");
        t.photon_pass().unwrap();
        assert!(t.context().in_flight() >= 4, "the photon pass waited for its batches: {} submissions in flight", t.context().in_flight());
        t.build_acceleration_structure().unwrap();
        assert!(t.context().in_flight() > 0, "the build waited for its structures");
        t.gather().unwrap();
        assert!(t.context().in_flight() > 0, "the gather waited for its trace");
        let early = t.read_stats().unwrap();
        assert_eq!(t.context().in_flight(), 0, "read_stats waits for the gather's counts");
        t.accumulate().unwrap();
        assert_eq!(t.context().in_flight(), 0, "the accumulate is the iteration's wait");
        let late = t.read_stats().unwrap();
        assert!(late.query_points > 0 && late.gathered() > 0, "{late:?}");
        assert_eq!((early.contributions, early.candidates, early.covered, early.query_points), (late.contributions, late.candidates, late.covered, late.query_points));
        assert_eq!((early.photons_emitted, early.footprints, early.progressive, early.overflowed), (late.photons_emitted, late.footprints, late.progressive, late.overflowed));
        assert!(late.footprints[0] + late.footprints[1] > 0 && late.overflowed == 0, "{late:?}");
    }
    assert_clean(&t.context().validation_log(), "with stages in flight");
}
