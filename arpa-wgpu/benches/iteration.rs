//! Iteration time of the wgpu backend (`WgpuTracer`) for E-50K, E-250K and E-1000K photons
//! per iteration, both methods, on the adapter `AdapterChoice::Auto` picks (lavapipe where
//! no GPU with ray queries exists).
//!
//! ```text
//! cargo bench -p arpa-wgpu --bench iteration
//! ```
//!
//! The scene is `arpa_core::shapes::glass_room` (a closed Cornell-like room with a glass
//! sphere, a mirror block and a quad light; arpa-vk's benchmark renders it too) at 256×256 pixels
//! (`ARPA_WGPU_BENCH_RESOLUTION=WxH` overrides it, e.g. `1920x1080` on a GPU). Each size runs
//! one warm-up iteration and then `ARPA_WGPU_BENCH_ITERATIONS` (default 3) measured ones and
//! prints `name: value unit` lines: the mean iteration time and the mean of each stage, the
//! photons per second, the stored records, the photon batches per iteration and the device
//! and load average. An iteration whose records exceed one storage binding is traced in
//! photon batches (on lavapipe, whose storage bindings are 128 MiB, E-1000K needs ~2.2M raw
//! footprints of 96 bytes: two batches); the warm-up iteration finds the batch size. A size
//! the tracer rejects prints `NAME.error: ...`.
//! `ARPA_WGPU_BENCH_SIZES=50000,250000` restricts the photon counts.
//!
//! Without `--bench` (`cargo test --benches`, the smoke run) it runs one iteration of 5 000
//! photons at 32×32 per method, in a few seconds on lavapipe.

use std::time::Instant;

use arpa_core::shapes::glass_room;
use arpa_core::tracer::{IterationStats, Method, RenderSettings, StageTimes, Tracer};
use arpa_wgpu::{AdapterChoice, WgpuTracer};

fn load() -> String {
    std::fs::read_to_string("/proc/loadavg").map(|s| s.split_whitespace().take(3).collect::<Vec<_>>().join(" ")).unwrap_or_else(|_| "?".into())
}

fn env_list(name: &str) -> Option<Vec<u32>> {
    std::env::var(name).ok().map(|v| v.split(',').filter_map(|x| x.trim().parse().ok()).collect())
}

fn main() {
    let full = std::env::args().any(|a| a == "--bench");
    let (width, height) = match std::env::var("ARPA_WGPU_BENCH_RESOLUTION").ok().and_then(|r| {
        let (w, h) = r.split_once('x')?;
        Some((w.parse().ok()?, h.parse().ok()?))
    }) {
        Some(r) => r,
        None if full => (256, 256),
        None => (32, 32),
    };
    let sizes = env_list("ARPA_WGPU_BENCH_SIZES").unwrap_or(if full { vec![50_000, 250_000, 1_000_000] } else { vec![5_000] });
    let iterations = std::env::var("ARPA_WGPU_BENCH_ITERATIONS").ok().and_then(|v| v.parse().ok()).unwrap_or(if full { 3 } else { 1 });
    let mut tracer = match WgpuTracer::new(&AdapterChoice::Auto) {
        Ok(t) => t,
        Err(e) if std::env::var_os("CI").is_none() => {
            eprintln!("*** SKIPPING the wgpu iteration benchmark: {e}");
            return;
        }
        Err(e) => panic!("CI needs a ray-query adapter (lavapipe): {e}"),
    };
    println!("device: {}", tracer.capabilities().device);
    println!("resolution: {width}x{height}");
    let scene = glass_room(width, height);
    for &photons in &sizes {
        for method in [Method::Arpa, Method::Rtpm] {
            let settings = RenderSettings { method, photons_per_iteration: photons, seed: 1, ..RenderSettings::default() };
            let name = format!("E-{}K.{}", photons / 1000, method.name());
            println!("load: {}", load());
            if let Err(e) = tracer.upload_scene(&scene, &settings) {
                println!("{name}.error: {e}");
                continue;
            }
            let warm = Instant::now();
            if let Err(e) = tracer.iterate() {
                println!("{name}.error: {e}");
                continue;
            }
            let first = warm.elapsed().as_secs_f64();
            let first_overflowed = tracer.read_stats().map_or(0, |s| s.overflowed);
            let mut times = StageTimes::default();
            let mut stats = IterationStats::default();
            let start = Instant::now();
            for _ in 0..iterations {
                tracer.iterate().expect("iteration");
                let s = tracer.read_stats().expect("stats");
                times.accumulate(&s.times);
                stats.accumulate(&s);
            }
            let wall = start.elapsed().as_secs_f64() / iterations as f64;
            let n = iterations as f64;
            let image = tracer.read_image().expect("image");
            assert!(image.pixels.iter().all(|p| p.is_finite()), "non-finite pixel");
            println!("{name}.first_iteration: {:.1} ms", 1e3 * first);
            println!("{name}.iteration: {:.1} ms", 1e3 * wall);
            for (stage, t) in [("camera", times.camera), ("photon", times.photon), ("build", times.build), ("gather", times.gather), ("accumulate", times.accumulate)] {
                println!("{name}.{stage}: {:.1} ms", 1e3 * t / n);
            }
            println!("{name}.photons_per_second: {:.0}", photons as f64 / wall);
            let batch = tracer.batch_photons().unwrap_or(photons).max(1);
            println!("{name}.batches: {} of at most {batch} photons (first iteration: {} appends dropped and redone)", photons.div_ceil(batch), first_overflowed);
            println!("{name}.segments_per_iteration: {:.0}", stats.photon_segments as f64 / n);
            println!(
                "{name}.stored_per_iteration: {:.0} footprints, {:.0} photons, {:.0} overflowed",
                (stats.footprints[0] + stats.footprints[1]) as f64 / n,
                (stats.progressive[0] + stats.progressive[1]) as f64 / n,
                stats.overflowed as f64 / n
            );
        }
    }
}
