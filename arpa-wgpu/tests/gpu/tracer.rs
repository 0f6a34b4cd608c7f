//! `WgpuTracer` (the whole iteration on the device) against the core's reference pipeline
//! run on the host with the brute-force caster (`trace_camera_path`, `trace_photon`,
//! `gather_brute_force`, f64), on the Cornell box with a glass sphere and a mirror block,
//! both methods; determinism; the overflow path; photon batches; the planes of a per-pixel
//! bandwidth (every scale against `gather_brute_force_scales` over the tracer's own records,
//! the moments, checkpoints); stage order and bad input.
//!
//! The device traces in f32: a path whose decision (Fresnel choice, Russian roulette, a
//! grazing hit) sits within f32 rounding of its threshold can go the other way, and then
//! the photon's records differ. So the counts of stored records agree to 1 %, the image's
//! mean radiance to 1e-3, and at least 97 % of the pixels agree within 1e-3 relative (the
//! rest may see a diverged photon: a margin for the few such paths of a 4000-photon
//! iteration); the image's mean equals the brute-force gather over the tracer's own
//! read-back query points and records within 1e-5 (f32 sums on the device), and so does
//! every scale's plane of the accumulation (per-pixel bandwidth, the default).

use crate::common::*;
use crate::scenes::cornell;
use arpa_core::render::camera_path::trace_camera_path;
use arpa_core::accumulate::image::Accumulation;
use arpa_core::gather::scales::{Bandwidth, PLANES, SCALES, moments};
use arpa_core::gather::estimate::{QueryPoint, gather_brute_force, gather_brute_force_scales};
use arpa_core::store::footprint::PackedFootprint;
use arpa_core::render::photon_path::{PhotonPassSetup, trace_photon};
use arpa_core::render::prepared_scene::PreparedScene;
use arpa_core::store::progressive_photon::PackedPhoton;
use arpa_core::render::brute_force::BruteForceCaster;
use arpa_core::render::scene::Scene;
use arpa_core::store::decision::StoredPhoton;
use arpa_core::render::tracer::{Call, Image, IterationStats, Method, RenderSettings, Stage, StageError, Tracer};
use arpa_wgpu::{WgpuError, WgpuTracer};
use glam::{DVec3, Vec3};

fn settings(method: Method, seed: u32) -> RenderSettings {
    RenderSettings { method, photons_per_iteration: 4000, seed, max_depth: 8, ..RenderSettings::default() }
}

fn tracer() -> Option<WgpuTracer> {
    let ctx = gpu()?;
    // A tracer of its own (the shared context is borrowed by other tests): same adapter.
    let _ = ctx;
    Some(WgpuTracer::new(&arpa_wgpu::AdapterChoice::Auto).expect("wgpu tracer"))
}

fn render(t: &mut WgpuTracer, scene: &Scene, s: &RenderSettings, iterations: u32) -> Image {
    t.upload_scene(scene, s).unwrap();
    for _ in 0..iterations {
        t.iterate().unwrap();
    }
    t.read_image().unwrap()
}

/// The core's iteration 0 on the host: image, footprints and photons per map.
fn core_iteration(scene: &Scene, s: &RenderSettings) -> (Vec<DVec3>, [usize; 2], [usize; 2]) {
    let prepared = PreparedScene::new(scene.clone()).unwrap();
    let caster = BruteForceCaster::new(&prepared);
    let setup = PhotonPassSetup::new(&prepared, s, 0);
    let (mut fps, mut phs): (Vec<PackedFootprint>, Vec<PackedPhoton>) = (Vec::new(), Vec::new());
    for index in 0..setup.photon_count() {
        trace_photon(&prepared, &caster, s, &setup, index, &mut |st| match st {
            StoredPhoton::Footprint { packed, .. } => fps.push(packed),
            StoredPhoton::Progressive { photon, .. } => phs.push(photon),
        });
    }
    let radii = setup.radii;
    let cam = scene.camera;
    let image = (0..cam.width * cam.height)
        .map(|pixel| {
            let rec = trace_camera_path(&prepared, &caster, s, 0, pixel);
            let known = Vec3::from_array(rec.radiance).as_dvec3();
            if rec.valid == 0 {
                return known;
            }
            let q = QueryPoint { position: Vec3::from_array(rec.position), normal: Vec3::from_array(rec.normal) };
            known + Vec3::from_array(rec.weight).as_dvec3() * gather_brute_force(&q, &fps, &phs, radii, s.kernel).irradiance()
        })
        .collect();
    let per_map = |maps: Vec<u32>| [maps.iter().filter(|&&m| m == 0).count(), maps.iter().filter(|&&m| m == 1).count()];
    (image, per_map(fps.iter().map(|f| f.map).collect()), per_map(phs.iter().map(|p| p.map).collect()))
}

fn compare_with_core(method: Method) {
    let Some(mut t) = tracer() else { return };
    let scene = cornell(32);
    let s = settings(method, 3);
    let image = render(&mut t, &scene, &s, 1);
    let stats = t.read_stats().unwrap();
    let (want, want_fp, want_ph) = core_iteration(&scene, &s);
    assert_eq!(stats.emitted[1], s.photons_per_iteration as u64);
    assert_eq!(stats.photons_emitted, stats.emitted[0] + stats.emitted[1]);
    assert_eq!(stats.overflowed, 0);
    let close = |a: u64, b: usize| (a as f64 - b as f64).abs() <= 0.01 * b as f64 + 2.0;
    for m in 0..2 {
        assert!(close(stats.footprints[m], want_fp[m]), "footprints map {m}: device {} core {}", stats.footprints[m], want_fp[m]);
        assert!(close(stats.progressive[m], want_ph[m]), "photons map {m}: device {} core {}", stats.progressive[m], want_ph[m]);
    }
    if method == Method::Rtpm {
        assert_eq!(stats.footprints, [0, 0]);
    } else {
        assert!(stats.footprints[0] + stats.footprints[1] > 300, "{stats:?}");
    }
    // The gather over the device's own records and query points.
    let (qs, fps, phs) = (t.read_query_points().unwrap(), t.read_footprints().unwrap(), t.read_photons().unwrap());
    let radii = stats.radii;
    let own: Vec<DVec3> = qs
        .iter()
        .map(|rec| {
            let known = Vec3::from_array(rec.radiance).as_dvec3();
            if rec.valid == 0 {
                return known;
            }
            let q = QueryPoint { position: Vec3::from_array(rec.position), normal: Vec3::from_array(rec.normal) };
            known + Vec3::from_array(rec.weight).as_dvec3() * gather_brute_force(&q, &fps, &phs, radii, s.kernel).irradiance()
        })
        .collect();
    let got: Vec<DVec3> = image.pixels.iter().map(|p| p.as_dvec3()).collect();
    assert!(got.iter().all(|p| p.is_finite()));
    let mean = |v: &[DVec3]| v.iter().fold(DVec3::ZERO, |a, b| a + *b) / v.len() as f64;
    let (mg, mw) = (mean(&got), mean(&want));
    let mo = mean(&own);
    assert!(((mg - mo).abs() / mo).max_element() < 1e-5, "mean radiance: device {mg:?}, gather over its own records {mo:?}");
    // Every plane of the per-pixel bandwidth: the scales against the brute-force gather
    // over the same records, the moments against the core's of the device's radiance
    // planes; one iteration selects the stored scale, so the image is plane 0.
    let acc = t.read_accumulation().unwrap();
    assert_eq!((acc.planes as usize, acc.pixels.len(), acc.iterations), (PLANES, PLANES * qs.len(), 1));
    assert_eq!(acc.mean(), image.pixels, "read_image is the core's mean of the accumulation");
    assert_eq!(acc.plane_mean(0), image.pixels, "one iteration: the stored scale everywhere");
    let planes: Vec<Vec<Vec3>> = (0..PLANES).map(|p| acc.plane_mean(p)).collect();
    for (k, plane) in planes.iter().enumerate().take(SCALES).skip(1) {
        let own_k: Vec<DVec3> = qs
            .iter()
            .map(|rec| {
                let known = Vec3::from_array(rec.radiance).as_dvec3();
                if rec.valid == 0 {
                    return known;
                }
                let q = QueryPoint { position: Vec3::from_array(rec.position), normal: Vec3::from_array(rec.normal) };
                known + Vec3::from_array(rec.weight).as_dvec3() * gather_brute_force_scales(&q, &fps, &phs, radii, s.kernel).per_scale[k]
            })
            .collect();
        let got_k: Vec<DVec3> = plane.iter().map(|p| p.as_dvec3()).collect();
        let (mk, mo) = (mean(&got_k), mean(&own_k));
        assert!(((mk - mo).abs() / mo).max_element() < 1e-5, "scale {k}: mean radiance: device {mk:?}, gather over its own records {mo:?}");
        eprintln!("{}: scale {k} mean {mk:?} (stored scale {mg:?})", method.name());
    }
    let ladders: Vec<[Vec3; SCALES]> = (0..qs.len()).map(|i| std::array::from_fn(|k| planes[k][i])).collect();
    for (i, l) in ladders.iter().enumerate() {
        let want = moments(l);
        for (p, &w) in want.iter().enumerate() {
            let g = planes[SCALES + p][i];
            assert!((g - w).abs().max_element() <= 16.0 * f32::EPSILON * l.iter().map(|c| c.max_element()).fold(0.0, f32::max).powi(2), "pixel {i} moment plane {p}: {g:?} vs {w:?}");
        }
    }
    assert!(((mg - mw).abs() / mw).max_element() < 1e-3, "mean radiance: device {mg:?} core {mw:?}");
    let agree = got.iter().zip(&want).filter(|(g, w)| (**g - **w).abs().max_element() <= 1e-3 * w.abs().max_element().max(1e-6)).count();
    let share = agree as f64 / got.len() as f64;
    eprintln!("{}: {:.1} % of pixels within 1e-3 of the core; mean {mg:?} vs {mw:?}; {stats:?}", method.name(), 100.0 * share);
    assert!(share >= 0.97, "{:.1} % of pixels agree", 100.0 * share);
}

#[test]
fn arpa_iteration_matches_core() {
    compare_with_core(Method::Arpa);
}

#[test]
fn rtpm_iteration_matches_core() {
    compare_with_core(Method::Rtpm);
}

fn bits(img: &Image) -> Vec<u32> {
    img.pixels.iter().flat_map(|p| p.to_array().map(f32::to_bits)).collect()
}

/// The mean of every plane of the accumulation, plane after plane.
fn every_plane(t: &WgpuTracer) -> Vec<Vec3> {
    let acc = t.read_accumulation().unwrap();
    (0..acc.planes as usize).flat_map(|p| acc.plane_mean(p)).collect()
}

/// The largest relative difference per pixel component between `a` and `b`, asserted
/// within what summing the same non-negative contributions in another `f32` order allows:
/// recursive summation of N non-negative terms in any order is within (N − 1)·2⁻²⁴ of the
/// exact sum relative to it, so two orders differ by at most 2(N − 1)·2⁻²⁴ relative;
/// `radiance + weight · E` and the running mean add a few roundings: per component
/// |a − b| ≤ (2(N − 1) + 8)·2⁻²⁴·max(|a|, |b|), with N the iteration's stored `records`
/// (an upper bound on the contributions to one pixel).
fn assert_summation_order(a: &[Vec3], b: &[Vec3], records: f64, what: &str) -> f64 {
    assert_eq!(a.len(), b.len());
    let bound = (2.0 * (records - 1.0) + 8.0) * f32::EPSILON as f64 / 2.0;
    let mut worst = 0.0f64;
    for (a, b) in a.iter().zip(b) {
        for c in 0..3 {
            let (a, b) = (a[c] as f64, b[c] as f64);
            assert!(a.is_finite() && b.is_finite());
            let scale = a.abs().max(b.abs());
            if scale > 0.0 {
                worst = worst.max((a - b).abs() / scale);
            }
            assert!((a - b).abs() <= bound * scale, "{what}: pixel component {a} vs {b} (bound {bound:e} relative)");
        }
    }
    worst
}

/// Stored records of an iteration (both kinds, both maps).
fn records(s: &IterationStats) -> f64 {
    (s.footprints[0] + s.footprints[1] + s.progressive[0] + s.progressive[1]) as f64
}

/// The same seed gives the same bits. Buffers of 64 records (no calibration): the pipelined
/// photon pass overflows, its accumulate leaves the sums alone, traces the iteration again
/// with grown buffers and accumulates that; the next iteration starts on the 64 records
/// again and is traced twice too. The records are the same as the calibrated render's, and
/// the structures are built over other capacities, so the gather visits the same records in
/// another order: the image agrees within the summation-order bound.
#[test]
fn same_seed_is_bit_identical_and_overflow_redoes_the_iteration() {
    let Some(mut t) = tracer() else { return };
    let scene = cornell(16);
    let s = settings(Method::Arpa, 5);
    let a = render(&mut t, &scene, &s, 2);
    let fitted = t.read_stats().unwrap();
    assert_eq!(fitted.overflowed, 0);
    let b = render(&mut t, &scene, &s, 2);
    assert!(bits(&a) == bits(&b), "same seed, different image");
    t.set_initial_capacity(Some(64));
    t.upload_scene(&scene, &s).unwrap();
    t.iterate().unwrap();
    let first = t.read_stats().unwrap();
    assert!(first.overflowed > 0, "no overflow with 64-record buffers");
    t.iterate().unwrap();
    let second = t.read_stats().unwrap();
    assert!(second.overflowed > 0, "the second iteration did not start on the 64-record buffers");
    assert_eq!(counts(&second), counts(&fitted), "the iteration traced again has other counts");
    let c = t.read_image().unwrap();
    let worst = assert_summation_order(&a.pixels, &c.pixels, records(&fitted), "64-record buffers");
    eprintln!("64-record buffers vs calibrated: worst relative pixel difference {worst:e}");
    t.set_initial_capacity(None);
    let d = render(&mut t, &scene, &settings(Method::Arpa, 6), 2);
    assert!(bits(&a) != bits(&d), "another seed gives the same image");
}

/// The counts of an iteration that batching must not change (everything but times,
/// overflow and the iteration number).
fn counts(s: &IterationStats) -> [u64; 13] {
    [
        s.photons_emitted,
        s.photon_segments,
        s.footprints[0],
        s.footprints[1],
        s.progressive[0],
        s.progressive[1],
        s.degenerate,
        s.culled,
        s.unrepresentable,
        s.differential_lost,
        s.query_points,
        s.gathered(),
        s.radii[0].to_bits() ^ s.radii[1].to_bits(),
    ]
}

/// The records of every photon batch of the last photon pass, as the photon pass left them
/// and after the gather (the gather traces nothing), in a canonical order.
fn records_after_each_stage(t: &mut WgpuTracer) -> (Vec<[u8; 64]>, Vec<[u8; 48]>) {
    t.camera_pass().unwrap();
    t.photon_pass().unwrap();
    let (f, p) = (t.read_footprints().unwrap(), t.read_photons().unwrap());
    t.build_acceleration_structure().unwrap();
    t.gather().unwrap();
    assert!(f == t.read_footprints().unwrap() && p == t.read_photons().unwrap(), "the gather changed the maps");
    t.accumulate().unwrap();
    let mut f: Vec<[u8; 64]> = f.iter().map(|x| bytemuck::cast(*x)).collect();
    let mut p: Vec<[u8; 48]> = p.iter().map(|x| bytemuck::cast(*x)).collect();
    f.sort_unstable();
    p.sort_unstable();
    (f, p)
}

/// Photon batches: an iteration traced in batches of 700 photons (6 batches) stores the
/// same records (bit for bit, see the photon-pass test: the maps read back hold every
/// batch's records, the same as one pass's, and the gather leaves them as the photon pass
/// made them), so it finds the same counts and
/// sums the same non-negative contributions per pixel in another `f32` order. Recursive
/// summation of N non-negative terms in any order (any summation tree) is within
/// (N − 1)·2⁻²⁴ of the exact sum relative to it, so two orders differ by at most
/// 2(N − 1)·2⁻²⁴ relative; `radiance + weight · E` and the running mean add a few
/// roundings: per component |a − b| ≤ (2(N − 1) + 8)·2⁻²⁴·max(|a|, |b|), with N the
/// iteration's stored records (an upper bound on the contributions to one pixel). Repeating
/// the batched render is bit-identical. Then the automatic split: with the photon-pass
/// bindings capped at 64 KiB (~680 raw footprints) the calibration's 4000-photon
/// iteration overflows at upload, B shrinks until a batch fits, the iterations fit, the
/// counts equal one pass's, and the image agrees with a render forced to that B within the
/// summation-order bound (the capped bindings also cap the calibrated capacities, over
/// which the structures are built).
#[test]
fn photon_batches_match_one_pass_and_split_automatically() {
    let Some(mut t) = tracer() else { return };
    let scene = cornell(16);
    for (method, iterations) in [(Method::Arpa, 2), (Method::Rtpm, 1)] {
        let s = settings(method, 9);
        render(&mut t, &scene, &s, iterations);
        let one = every_plane(&t);
        let one_stats = t.read_stats().unwrap();
        assert_eq!(t.batch_photons(), Some(4000));
        let one_records = records_after_each_stage(&mut t);
        t.set_batch_photons(Some(700));
        let batched_image = render(&mut t, &scene, &s, iterations);
        let batched = every_plane(&t);
        let stats = t.read_stats().unwrap();
        assert_eq!(t.batch_photons(), Some(700));
        assert!(records_after_each_stage(&mut t) == one_records, "{}: the batches' records differ from one pass's", method.name());
        let repeat = render(&mut t, &scene, &s, iterations);
        t.set_batch_photons(None);
        assert!(bits(&batched_image) == bits(&repeat), "{}: batched render not bit-identical on repeat", method.name());
        assert_eq!(counts(&stats), counts(&one_stats), "{}: batched counts differ from one pass", method.name());
        assert_eq!(stats.overflowed, 0);
        // Global bandwidth: the image; per pixel (the selection may tip between scales on a
        // difference of one ulp), every radiance plane of the accumulation.
        let (one, batched) = (&one[..SCALES * 16 * 16], &batched[..SCALES * 16 * 16]);
        let records = records(&stats);
        let bound = (2.0 * (records - 1.0) + 8.0) * f32::EPSILON as f64 / 2.0;
        let worst = assert_summation_order(one, batched, records, method.name());
        eprintln!("{}: batches of 700 vs one pass: worst relative pixel difference {worst:e} (bound {bound:e}); {} records", method.name(), records);
    }
    // Automatic split on a capped binding: the calibration at upload finds that one batch
    // does not fit and shrinks B; the iterations then fit.
    let s = settings(Method::Arpa, 9);
    t.set_binding_limit(Some(64 << 10));
    t.upload_scene(&scene, &s).unwrap();
    let b = t.batch_photons().unwrap();
    t.iterate().unwrap();
    let first = t.read_stats().unwrap();
    assert!(b < 4000 && first.overflowed == 0, "B {b}, {first:?}");
    let auto = t.read_image().unwrap();
    t.set_binding_limit(None);
    render(&mut t, &scene, &s, 1);
    let one = t.read_stats().unwrap();
    assert_eq!(counts(&first), counts(&one), "split iteration's counts differ from one pass");
    t.set_batch_photons(Some(b));
    let forced = render(&mut t, &scene, &s, 1);
    t.set_batch_photons(None);
    // The same B; the capped bindings may cap the calibrated capacities, and with them the
    // structures' sizes.
    assert_summation_order(&auto.pixels, &forced.pixels, records(&one), "automatic B vs forced B");
    eprintln!("64 KiB bindings: B = {b} ({} batches)", 4000u32.div_ceil(b));
}

/// The stage-order error of `r`.
fn order_error<T: std::fmt::Debug>(r: Result<T, WgpuError>) -> StageError {
    match r {
        Err(WgpuError::Stage(e)) => e,
        other => panic!("expected a stage error, got {other:?}"),
    }
}

#[test]
fn stage_order_and_bad_input_are_errors() {
    let Some(mut t) = tracer() else { return };
    assert_eq!(order_error(t.gather()), StageError::order(Stage::Gather, Stage::UploadScene));
    assert_eq!(order_error(t.read_image()), StageError::order(Call::ReadImage, Stage::UploadScene));
    let scene = cornell(8);
    let bad = RenderSettings { photons_per_iteration: 0, ..settings(Method::Arpa, 0) };
    let e = t.upload_scene(&scene, &bad).unwrap_err().to_string();
    assert!(e.contains("photons_per_iteration"), "{e}");
    let keys = RenderSettings { photons_per_iteration: u32::MAX / 4, ..settings(Method::Arpa, 0) };
    let e = t.upload_scene(&scene, &keys).unwrap_err();
    assert!(matches!(e, WgpuError::Stage(StageError::Settings(_))) && e.to_string().contains("record keys"), "{e}");
    let mut broken = scene.clone();
    broken.meshes[0].positions[0] = Vec3::NAN;
    assert!(t.upload_scene(&broken, &settings(Method::Arpa, 0)).is_err());
    t.upload_scene(&scene, &settings(Method::Arpa, 0)).unwrap();
    assert_eq!(t.read_image().unwrap().pixels, vec![Vec3::ZERO; 64], "mean before any iteration");
    assert_eq!(order_error(t.build_acceleration_structure()), StageError::order(Stage::BuildAccelerationStructure, Stage::PhotonPass));
    assert_eq!(order_error(t.read_footprints()), StageError::order(Call::ReadFootprints, Stage::PhotonPass));
    t.camera_pass().unwrap();
    assert_eq!(order_error(t.gather()), StageError::order(Stage::Gather, Stage::BuildAccelerationStructure));
    assert_eq!(order_error(t.accumulate()), StageError::order(Stage::Accumulate, Stage::Gather));
    t.photon_pass().unwrap();
    t.build_acceleration_structure().unwrap();
    t.gather().unwrap();
    t.accumulate().unwrap();
    assert_eq!(t.iterations(), 1);
    assert_eq!(t.read_query_points().unwrap().len(), 64);
}

/// A per-pixel render continued from its checkpoint (every plane's sums) is the render that
/// never stopped, bit for bit; an empty one-plane accumulation starts a part; a checkpoint of
/// the other bandwidth is refused; a global render keeps one plane and its image is that
/// plane's mean.
#[test]
fn checkpoints_keep_every_plane() {
    let Some(mut t) = tracer() else { return };
    let scene = cornell(16);
    let s = settings(Method::Arpa, 21);
    let whole = render(&mut t, &scene, &s, 3);
    t.upload_scene(&scene, &s).unwrap();
    t.iterate().unwrap();
    t.iterate().unwrap();
    let checkpoint = t.read_accumulation().unwrap();
    assert_eq!((checkpoint.planes as usize, checkpoint.iterations), (PLANES, 2));
    t.upload_scene(&scene, &s).unwrap();
    t.restore_accumulation(&checkpoint).unwrap();
    assert_eq!(t.iterations(), 2);
    t.iterate().unwrap();
    assert!(bits(&t.read_image().unwrap()) == bits(&whole), "resumed per-pixel render differs");
    assert_eq!(t.read_accumulation().unwrap().mean(), whole.pixels, "the image is the core's selection over the planes");
    // A part from an empty one-plane accumulation, and a checkpoint of another bandwidth.
    t.upload_scene(&scene, &s).unwrap();
    t.restore_accumulation(&Accumulation::empty(16, 16, 2)).unwrap();
    t.iterate().unwrap();
    let part = t.read_accumulation().unwrap();
    assert_eq!((part.planes as usize, part.first_iteration, part.iterations), (PLANES, 2, 1));
    let global = RenderSettings { bandwidth: Bandwidth::Global, ..s };
    t.upload_scene(&scene, &global).unwrap();
    let e = t.restore_accumulation(&checkpoint).unwrap_err().to_string();
    assert!(e.contains("planes"), "{e}");
    let image = render(&mut t, &scene, &global, 2);
    let acc = t.read_accumulation().unwrap();
    assert_eq!((acc.planes, acc.pixels.len()), (1, 256));
    assert_eq!(acc.plane_mean(0), image.pixels);
}

/// A per-pixel image whose planes exceed one storage binding is refused at upload, naming
/// the bandwidth (lavapipe: 128 MiB bindings; an adapter with larger bindings skips).
#[test]
fn planes_beyond_one_binding_are_refused() {
    let Some(mut t) = tracer() else { return };
    let limits = t.context().device.limits();
    let binding = limits.max_storage_buffer_binding_size.min(limits.max_buffer_size);
    let side = 1024u32;
    let needed = arpa_core::gpu::layout::ImageBufferSizes::new(side * side, Bandwidth::PerPixel).accumulator;
    if needed <= binding || u64::from(side * side) * 64 > binding {
        eprintln!("planes_beyond_one_binding_are_refused: bindings of {binding} bytes; nothing to refuse at {side}x{side}");
        return;
    }
    let e = t.upload_scene(&cornell(side), &settings(Method::Arpa, 0)).unwrap_err();
    assert!(matches!(e, WgpuError::Size(_)) && e.to_string().contains("--bandwidth global"), "{e}");
    t.upload_scene(&cornell(side), &RenderSettings { bandwidth: Bandwidth::Global, ..settings(Method::Arpa, 0) }).unwrap();
}

/// Device times of a finished iteration: measured on an adapter with timestamp queries
/// inside encoders (lavapipe has them), every stage finite and non-negative, the traced
/// passes non-zero, each stage and the total within the iteration's wall time (plus 1 ms
/// and 1 % for the two clocks' rounding).
#[test]
fn every_iteration_reports_device_time_per_stage() {
    use arpa_core::render::tracer::DeviceTimes;
    let Some(mut t) = tracer() else { return };
    let has_timestamps = t.context().timer().is_some();
    assert!(has_timestamps || !t.context().is_lavapipe(), "lavapipe has timestamp queries inside encoders");
    // Two photon batches: the photon pass makes several timed submissions.
    t.set_batch_photons(Some(2000));
    t.upload_scene(&cornell(24), &settings(Method::Arpa, 5)).unwrap();
    for _ in 0..3 {
        let start = std::time::Instant::now();
        t.iterate().unwrap();
        let wall = start.elapsed().as_secs_f64();
        let stats = t.read_stats().unwrap();
        let d = match stats.device_times {
            DeviceTimes::Measured(d) => d,
            other => {
                assert!(!has_timestamps, "the adapter has timestamps but iteration {} has device times {other:?}", stats.iteration);
                continue;
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
}

/// The gather reads nothing back: its counts come back at the accumulate's wait, and
/// `read_stats` between the two reads the same counts itself.
#[test]
fn the_gathers_counts_arrive_with_the_accumulate() {
    let Some(mut t) = tracer() else { return };
    t.set_batch_photons(Some(2000));
    t.upload_scene(&cornell(24), &settings(Method::Arpa, 7)).unwrap();
    for _ in 0..2 {
        t.camera_pass().unwrap();
        t.photon_pass().unwrap();
        t.build_acceleration_structure().unwrap();
        t.gather().unwrap();
        let early = t.read_stats().unwrap();
        t.accumulate().unwrap();
        let late = t.read_stats().unwrap();
        assert!(late.query_points > 0 && late.gathered() > 0, "{late:?}");
        assert_eq!((early.contributions, early.candidates, early.covered, early.query_points), (late.contributions, late.candidates, late.covered, late.query_points));
    }
}
