//! Soak: thousands of iterations of a small scene, with the process's resident memory
//! sampled and the running mean checked against an independent `f64` sum of the
//! iteration images. Not part of CI (minutes); run it with
//!
//! ```text
//! cargo test --release -p arpa --test soak -- --ignored --nocapture
//! ARPA_SOAK_BACKENDS=wgpu ARPA_SOAK_ITERATIONS=1000 cargo test --release -p arpa --test soak -- --ignored --nocapture
//! ```
//!
//! `ARPA_SOAK_BACKENDS` (default `cpu`) lists the backends, `ARPA_SOAK_ITERATIONS` the
//! iterations (default 10 000 on cpu, 1000 on a GPU backend). It prints the resident set
//! size (VmRSS) after warm-up and at the end, and fails when it grew by 1 % or more, or when
//! the mean drifts from the reference sum by more than the `f32` rounding of the output.
//!
//! The reference: a second tracer renders each iteration alone (an empty accumulation
//! restored at that iteration index, one iteration, `read_image`), which is exactly that
//! iteration's image; the host sums those in `f64` (Neumaier) and divides.

use arpa::backends::{BackendOptions, create};
use arpa::core::accumulate::image::{Accumulation, RunningMean};
use arpa::core::glam::DVec3;
use arpa::core::render::tracer::{BackendKind, RenderSettings, Tracer};
use arpa::default_scene::default_scene;
use std::time::Instant;

/// Resident set size of this process (KiB), from `/proc/self/status`.
fn rss_kib() -> u64 {
    let status = std::fs::read_to_string("/proc/self/status").expect("/proc/self/status");
    status
        .lines()
        .find_map(|l| l.strip_prefix("VmRSS:"))
        .and_then(|v| v.trim().trim_end_matches("kB").trim().parse().ok())
        .expect("VmRSS")
}

fn soak(kind: BackendKind, iterations: u32) {
    let mut scene = default_scene();
    (scene.camera.width, scene.camera.height) = (16, 16);
    let settings = RenderSettings { photons_per_iteration: 2000, seed: 11, ..RenderSettings::default() };
    let options = BackendOptions::default();
    let mut tracer = create(kind, &options).expect("backend");
    let mut single = create(kind, &options).expect("backend");
    tracer.upload_scene(&scene, &settings).expect("upload");
    single.upload_scene(&scene, &settings).expect("upload");
    let pixels = (scene.camera.width * scene.camera.height) as usize;
    let mut reference = vec![RunningMean::new(); pixels];
    let warm_up = (iterations / 10).max(50).min(iterations);
    let mut rss_after_warm_up = 0;
    let mut rss_max = 0;
    let start = Instant::now();
    for i in 0..iterations {
        tracer.iterate().unwrap_or_else(|e| panic!("iteration {i}: {e}"));
        single.restore_accumulation(&Accumulation::empty(scene.camera.width, scene.camera.height, i)).expect("restore");
        single.iterate().expect("single iteration");
        for (acc, p) in reference.iter_mut().zip(single.read_image().expect("image").pixels) {
            acc.add(p.as_dvec3());
        }
        if i + 1 == warm_up {
            rss_after_warm_up = rss_kib();
        }
        if i + 1 > warm_up && (i + 1) % 100 == 0 {
            rss_max = rss_max.max(rss_kib());
        }
        if (i + 1) % 1000 == 0 {
            eprintln!("{kind}: {} iterations, {:.1} s, VmRSS {} KiB", i + 1, start.elapsed().as_secs_f64(), rss_kib());
        }
    }
    let image = tracer.read_image().expect("image");
    let worst = image
        .pixels
        .iter()
        .zip(&reference)
        .map(|(p, r)| {
            let (m, e) = (p.as_dvec3(), r.mean());
            ((m - e).abs() / e.abs().max(DVec3::splat(1e-30))).max_element()
        })
        .fold(0.0f64, f64::max);
    let growth = rss_max.max(rss_after_warm_up) as f64 / rss_after_warm_up.max(1) as f64 - 1.0;
    eprintln!(
        "{kind}: {iterations} iterations in {:.1} s; VmRSS after {warm_up} iterations {rss_after_warm_up} KiB, largest after {rss_max} KiB ({:+.3} %); worst relative deviation of the mean from the f64 reference {worst:.2e}",
        start.elapsed().as_secs_f64(),
        100.0 * growth
    );
    assert!(growth < 0.01, "{kind}: resident memory grew {:.2} % after warm-up", 100.0 * growth);
    // The device accumulates in f32 with compensation, the host in f64: both are exact to
    // well within one f32 rounding of the output.
    assert!(worst <= 2.0 * f32::EPSILON as f64, "{kind}: the running mean drifts from the f64 reference by {worst:e}");
}

#[test]
#[ignore = "minutes: run with --ignored (see the module docs)"]
fn soak_memory_and_running_mean() {
    let backends = std::env::var("ARPA_SOAK_BACKENDS").unwrap_or_else(|_| "cpu".into());
    for name in backends.split(',').map(str::trim).filter(|s| !s.is_empty()) {
        let kind = BackendKind::from_name(name).unwrap_or_else(|| panic!("unknown backend '{name}'"));
        let default = if kind == BackendKind::Cpu { 10_000 } else { 1000 };
        let iterations = std::env::var("ARPA_SOAK_ITERATIONS").ok().and_then(|v| v.parse().ok()).unwrap_or(default);
        soak(kind, iterations);
    }
}
