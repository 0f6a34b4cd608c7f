//! Iteration time per stage of the GPU backends side by side: each backend compiled in
//! (default `wgpu,vk`; `ARPA_BENCH_BACKENDS=cpu,wgpu,vk` picks others) renders
//! `arpa_core::render::shapes::glass_room` (a closed Cornell-like room with a glass sphere, a mirror
//! block and a quad light) at E-50K, E-250K and E-1000K photons per iteration, both methods,
//! on the adapter each backend picks (lavapipe where there is no GPU).
//!
//! ```text
//! cargo bench -p arpa --bench backends
//! ```
//!
//! 256×256 pixels (`ARPA_BENCH_RESOLUTION=WxH`, e.g. `1920x1080` on a GPU). Each size runs
//! one warm-up iteration, then `ARPA_BENCH_ITERATIONS` (default 3) measured ones, and prints
//! `BACKEND.E-NK.METHOD.NAME: value unit` lines: the mean iteration time and each stage's
//! mean, photons per second, stored records per iteration, and the device and load average.
//! `ARPA_BENCH_SIZES=50000,250000` restricts the photon counts. A backend that cannot start
//! or a size it rejects prints `BACKEND...error: ...` and the run goes on.
//!
//! Without `--bench` (`cargo test --benches`, the smoke run) it runs one iteration of 5 000
//! photons at 32×32 per backend and method.

use std::time::Instant;

use arpa::backends::{BackendOptions, REGISTRY, create};
use arpa_core::render::shapes::glass_room;
use arpa_core::render::tracer::{BackendKind, IterationStats, Method, RenderSettings, StageTimes};

fn load() -> String {
    std::fs::read_to_string("/proc/loadavg").map(|s| s.split_whitespace().take(3).collect::<Vec<_>>().join(" ")).unwrap_or_else(|_| "?".into())
}

fn env_list(name: &str) -> Option<Vec<u32>> {
    std::env::var(name).ok().map(|v| v.split(',').filter_map(|x| x.trim().parse().ok()).collect())
}

fn main() {
    let full = std::env::args().any(|a| a == "--bench");
    let (width, height) = match std::env::var("ARPA_BENCH_RESOLUTION").ok().and_then(|r| {
        let (w, h) = r.split_once('x')?;
        Some((w.parse().ok()?, h.parse().ok()?))
    }) {
        Some(r) => r,
        None if full => (256, 256),
        None => (32, 32),
    };
    let sizes = env_list("ARPA_BENCH_SIZES").unwrap_or(if full { vec![50_000, 250_000, 1_000_000] } else { vec![5_000] });
    let iterations: u32 = std::env::var("ARPA_BENCH_ITERATIONS").ok().and_then(|v| v.parse().ok()).unwrap_or(if full { 3 } else { 1 });
    let wanted: Vec<BackendKind> = match std::env::var("ARPA_BENCH_BACKENDS") {
        Ok(list) => list.split(',').filter_map(|n| BackendKind::from_name(n.trim())).collect(),
        Err(_) => vec![BackendKind::Wgpu, BackendKind::Vk],
    };
    println!("resolution: {width}x{height}");
    let scene = glass_room(width, height);
    for entry in REGISTRY.iter().filter(|e| wanted.contains(&e.kind)) {
        let backend = entry.kind.name();
        let mut tracer = match create(entry.kind, &BackendOptions::default()) {
            Ok(t) => t,
            Err(e) if std::env::var_os("CI").is_none() => {
                println!("{backend}.error: {e}");
                continue;
            }
            Err(e) => panic!("CI runs every backend (lavapipe for the GPU ones): {e}"),
        };
        println!("{backend}.device: {}", tracer.capabilities().device);
        for &photons in &sizes {
            for method in [Method::Arpa, Method::Rtpm] {
                let settings = RenderSettings { method, photons_per_iteration: photons, seed: 1, ..RenderSettings::default() };
                let name = format!("{backend}.E-{}K.{}", photons / 1000, method.name());
                println!("load: {}", load());
                let warm = Instant::now();
                if let Err(e) = tracer.upload_scene(&scene, &settings).and_then(|()| tracer.iterate()) {
                    println!("{name}.error: {e}");
                    continue;
                }
                let first = warm.elapsed().as_secs_f64();
                let mut times = StageTimes::default();
                let mut stats = IterationStats::default();
                let start = Instant::now();
                for _ in 0..iterations {
                    tracer.iterate().expect("iteration");
                    let s = tracer.read_stats().expect("stats");
                    times.accumulate(&s.times);
                    stats.accumulate(&s);
                }
                let wall = start.elapsed().as_secs_f64() / f64::from(iterations);
                let n = f64::from(iterations);
                let image = tracer.read_image().expect("image");
                assert!(image.pixels.iter().all(|p| p.is_finite()), "{name}: non-finite pixel");
                println!("{name}.upload_and_first_iteration: {:.1} ms", 1e3 * first);
                println!("{name}.iteration: {:.1} ms", 1e3 * wall);
                for (stage, t) in [("camera", times.camera), ("photon", times.photon), ("build", times.build), ("gather", times.gather), ("accumulate", times.accumulate)] {
                    println!("{name}.{stage}: {:.1} ms", 1e3 * t / n);
                }
                println!("{name}.photons_per_second: {:.0}", f64::from(photons) / wall);
                println!(
                    "{name}.stored_per_iteration: {:.0} footprints, {:.0} photons, {:.0} overflowed",
                    (stats.footprints[0] + stats.footprints[1]) as f64 / n,
                    (stats.progressive[0] + stats.progressive[1]) as f64 / n,
                    stats.overflowed as f64 / n
                );
            }
        }
    }
}
