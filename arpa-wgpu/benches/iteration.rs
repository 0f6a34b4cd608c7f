//! Iteration time of the wgpu backend (`WgpuTracer`) for E-50K, E-250K and E-1000K photons
//! per iteration, both methods, on the adapter `AdapterChoice::Auto` picks (lavapipe where
//! no GPU with ray queries exists).
//!
//! ```text
//! cargo bench -p arpa-wgpu --bench iteration
//! ```
//!
//! The scene is built in code: a closed Cornell-like room (2 m cube, coloured side walls,
//! 12 triangles), a smooth glass icosphere (IOR 1.5, 1280 triangles), a mirror block and a
//! downward quad light under the ceiling; camera inside the room at 256×256 pixels
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

use arpa_core::glam::Vec3;
use arpa_core::scene::{Camera, Material, Scene};
use arpa_core::shapes::{cuboid, icosphere, parallelogram};
use arpa_core::tracer::{IterationStats, Method, RenderSettings, StageTimes, Tracer};
use arpa_wgpu::{AdapterChoice, WgpuTracer};

fn scene(width: u32, height: u32) -> Scene {
    let s = 1.0;
    let mut light = parallelogram("light", Vec3::new(-0.25, 1.98, -0.25), Vec3::new(0.5, 0.0, 0.0), Vec3::new(0.0, 0.0, 0.5), 0);
    light.emission = Some(Vec3::splat(15.0));
    let meshes = vec![
        parallelogram("floor", Vec3::new(-s, 0.0, -s), Vec3::new(0.0, 0.0, 2.0 * s), Vec3::new(2.0 * s, 0.0, 0.0), 0),
        parallelogram("ceiling", Vec3::new(-s, 2.0, -s), Vec3::new(2.0 * s, 0.0, 0.0), Vec3::new(0.0, 0.0, 2.0 * s), 0),
        parallelogram("back", Vec3::new(-s, 0.0, -s), Vec3::new(2.0 * s, 0.0, 0.0), Vec3::new(0.0, 2.0, 0.0), 0),
        parallelogram("front", Vec3::new(-s, 0.0, s), Vec3::new(0.0, 2.0, 0.0), Vec3::new(2.0 * s, 0.0, 0.0), 0),
        parallelogram("left", Vec3::new(-s, 0.0, -s), Vec3::new(0.0, 2.0, 0.0), Vec3::new(0.0, 0.0, 2.0 * s), 1),
        parallelogram("right", Vec3::new(s, 0.0, -s), Vec3::new(0.0, 0.0, 2.0 * s), Vec3::new(0.0, 2.0, 0.0), 2),
        icosphere("glass", Vec3::new(0.35, 0.45, 0.1), 0.35, 3, true, 3),
        light,
        cuboid("mirror block", Vec3::new(-0.7, 0.0, -0.7), Vec3::new(-0.2, 1.1, -0.3), 4),
    ];
    Scene {
        meshes,
        materials: vec![
            Material::Diffuse { albedo: Vec3::splat(0.75) },
            Material::Diffuse { albedo: Vec3::new(0.6, 0.06, 0.05) },
            Material::Diffuse { albedo: Vec3::new(0.1, 0.6, 0.08) },
            Material::Dielectric { ior: 1.5, transmittance: Vec3::ONE, roughness: 0.0 },
            Material::Conductor { reflectance: Vec3::splat(0.95), roughness: 0.0 },
        ],
        lights: vec![],
        camera: Camera { position: Vec3::new(0.0, 1.0, 0.97), target: Vec3::new(0.0, 0.8, 0.0), up: Vec3::Y, vertical_fov: 1.3, width, height },
        roughness_cutoff: 0.5,
    }
}

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
    let scene = scene(width, height);
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
