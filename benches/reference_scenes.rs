//! Photon-segment rays/s of the CPU backend against raw Embree on the paper's reference
//! scenes (`../shared/scenes/*/scene.xml`), one thread.
//!
//! ```text
//! cargo bench --bench reference_scenes
//! ```
//!
//! For every scene and both methods (`arpa`, `rtpm`), with default [`RenderSettings`],
//! seed 1 and 250,000 photons per iteration:
//! - the rays of iteration 0's photon pass are recorded in photon order (origin,
//!   direction, `t_min`, `t_max`, through a wrapping [`RayCaster`]);
//! - `raw`: those rays replayed through [`arpa::cpu::EmbreeScene::intersect`] (`rtcIntersect1`
//!   on the caster's own BVH), ns per ray;
//! - `pass`: [`CpuTracer::photon_pass`] of iteration 0 on a one-thread rayon pool, ns per
//!   segment (the recorded casts are its `photon_segments` plus the re-casts past a left triangle);
//! - `ratio`: pass segments/s over raw rays/s, i.e. `E / (E + C)` with `E` Embree's time
//!   per ray and `C` the core's per segment (DEVELOPERS.md, "The CPU photon pass").
//!
//! The two are measured in alternation (raw, pass, raw, pass, …) and each keeps its best
//! time, so that a slow phase of the machine does not land on one side only. Prints plain
//! `name: value unit` lines and a summary table. `cpu_backend` (in arpa-cpu) measures the
//! same ratio on its in-code room, with a core-only replay and the gather.
//!
//! Without `--bench` (`cargo test --benches`) each scene runs once with 2,000 photons, as
//! a smoke test. Outside CI, missing shared scenes skip with a loud message.
//! `ARPA_BENCH_SCENES=name,...` restricts the scenes (directory names),
//! `ARPA_BENCH_METHODS=arpa|rtpm` the methods (for a profiler).

use std::path::Path;
use std::sync::Mutex;
use std::time::{Duration, Instant};

use arpa::core::glam::Vec3;
use arpa::core::render::photon_path::{PhotonPassSetup, trace_photon};
use arpa::core::render::prepared_scene::PreparedScene;
use arpa::core::render::ray_cast::{LEAVE_RECASTS, RayCaster, RayHit};
use arpa::core::render::tracer::{Method, RenderSettings, Tracer};
use arpa::cpu::{CpuTracer, Device, EmbreeCaster};

#[path = "../tests/common/mod.rs"]
mod common;

/// Embree's ray start, as [`EmbreeCaster`] uses it.
const T_NEAR: f32 = f32::MIN_POSITIVE;

/// One recorded photon segment.
#[derive(Clone, Copy)]
struct Segment {
    origin: [f32; 3],
    direction: [f32; 3],
    t_min: f32,
    t_max: f32,
}

/// Records every segment the photon pass casts, in call order.
struct Recorder<'a> {
    inner: &'a EmbreeCaster,
    log: Mutex<Vec<Segment>>,
}

impl RayCaster for Recorder<'_> {
    fn intersect(&self, origin: Vec3, direction: Vec3, t_min: f32, t_max: f32) -> Option<RayHit> {
        self.log.lock().expect("recorder lock").push(Segment { origin: origin.to_array(), direction: direction.to_array(), t_min, t_max });
        self.inner.intersect(origin, direction, t_min, t_max)
    }
    fn occluded(&self, origin: Vec3, direction: Vec3, t_min: f32, t_max: f32) -> bool {
        self.inner.occluded(origin, direction, t_min, t_max)
    }
}

struct Config {
    full: bool,
    photons: u32,
    /// Alternating (raw, pass) rounds at least, and at least this long in all.
    rounds: usize,
    min_time: Duration,
}

/// Result of one scene and method.
struct Row {
    scene: String,
    method: Method,
    triangles: usize,
    segments_per_photon: f64,
    raw_ns: f64,
    pass_ns: f64,
}

fn measure(cfg: &Config, name: &str, path: &Path, method: Method) -> Row {
    let loaded = arpa::scene_file::load_scene(path, &[]).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    let scene = loaded.scene;
    let settings = RenderSettings { method, photons_per_iteration: cfg.photons, seed: 1, ..RenderSettings::default() };

    // The rays of iteration 0, on a caster built like the tracer's own (same BVH).
    let prepared = PreparedScene::new(scene.clone()).expect("validated scene");
    let device = Device::new().expect("Embree device");
    let caster = EmbreeCaster::new(&device, &prepared).expect("BVH");
    let setup = PhotonPassSetup::new(&prepared, &settings, 0);
    let recorder = Recorder { inner: &caster, log: Mutex::new(Vec::new()) };
    for index in 0..setup.photon_count() {
        trace_photon(&prepared, &recorder, &settings, &setup, index, &mut |_| {});
    }
    let segments = recorder.log.into_inner().expect("recorder lock");
    let n = segments.len() as f64;
    let embree = caster.scene();

    let pool = rayon::ThreadPoolBuilder::new().num_threads(1).build().expect("rayon pool");
    let mut tracer = CpuTracer::new().expect("Embree device");
    tracer.upload_scene(&scene, &settings).expect("upload");

    let (mut raw, mut pass) = (f64::INFINITY, f64::INFINITY);
    let started = Instant::now();
    for round in 0.. {
        let t0 = Instant::now();
        let hits = segments
            .iter()
            .filter(|r| matches!(embree.intersect(r.origin, r.direction, r.t_min.max(T_NEAR), r.t_max), Ok(Some(_))))
            .count();
        raw = raw.min(t0.elapsed().as_secs_f64());
        std::hint::black_box(hits);

        pool.install(|| tracer.photon_pass()).expect("photon pass");
        let stats = tracer.read_stats().expect("stats");
        // Each segment is one cast, plus a re-cast where a ray leaving a surface first met
        // the triangle it leaves (arpa_core::render::ray_cast::RayStart).
        let casts = segments.len() as u64;
        assert!(
            stats.photon_segments <= casts && casts <= stats.photon_segments * (1 + u64::from(LEAVE_RECASTS)),
            "{name}: the photon pass traced {} segments, the recording {casts} casts",
            stats.photon_segments
        );
        pass = pass.min(stats.times.photon);
        if round + 1 >= cfg.rounds && started.elapsed() >= cfg.min_time {
            break;
        }
    }
    Row {
        scene: name.into(),
        method,
        triangles: loaded_triangles(&scene),
        segments_per_photon: n / setup.photon_count().max(1) as f64,
        raw_ns: raw / n * 1e9,
        pass_ns: pass / n * 1e9,
    }
}

fn loaded_triangles(scene: &arpa::core::render::scene::Scene) -> usize {
    scene.meshes.iter().map(|m| m.indices.len()).sum()
}

fn main() {
    let full = std::env::args().any(|a| a == "--bench");
    let cfg = if full {
        Config { full, photons: 250_000, rounds: 5, min_time: Duration::from_secs(3) }
    } else {
        Config { full, photons: 2_000, rounds: 1, min_time: Duration::ZERO }
    };
    let Some(dir) = common::shared_scenes() else { return };
    let only: Option<Vec<String>> = std::env::var("ARPA_BENCH_SCENES").ok().map(|s| s.split(',').map(|x| x.trim().to_string()).collect());
    let mut names: Vec<String> = std::fs::read_dir(&dir)
        .expect("shared scenes directory")
        .filter_map(|e| e.ok())
        .filter(|e| e.path().join("scene.xml").is_file())
        .map(|e| e.file_name().to_string_lossy().into_owned())
        .filter(|n| only.as_ref().is_none_or(|o| o.contains(n)))
        .collect();
    names.sort();
    println!(
        "# photon-segment rays/s vs raw Embree on the reference scenes ({} mode, 1 thread, {} photons, load: {})",
        if cfg.full { "full" } else { "smoke" },
        cfg.photons,
        std::fs::read_to_string("/proc/loadavg").unwrap_or_default().split_whitespace().take(3).collect::<Vec<_>>().join(" ")
    );
    let mut rows = Vec::new();
    for name in &names {
        let path = dir.join(name).join("scene.xml");
        // A shared scene the loader cannot read yet (crytek-sponza needs textures) is
        // reported and left out, not a crash of the whole benchmark.
        if let Err(e) = arpa::scene_file::load_scene(&path, &[]) {
            println!("# {name}: skipped, the loader refuses it: {e}");
            continue;
        }
        for method in [Method::Arpa, Method::Rtpm] {
            if std::env::var("ARPA_BENCH_METHODS").is_ok_and(|m| !m.split(',').any(|x| x.trim() == method.name())) {
                continue;
            }
            let row = measure(&cfg, name, &path, method);
            let m = method.name();
            println!("{name}.triangles: {}", row.triangles);
            println!("{name}.{m}.segments_per_photon: {:.3}", row.segments_per_photon);
            println!("{name}.{m}.embree_raw: {:.1} ns/ray", row.raw_ns);
            println!("{name}.{m}.photon_pass: {:.1} ns/segment", row.pass_ns);
            println!("{name}.{m}.ratio_to_raw: {:.1} %", 100.0 * row.raw_ns / row.pass_ns);
            rows.push(row);
        }
    }
    println!("\n| scene | triangles | method | segments/photon | raw Embree ns/ray | photon pass ns/segment | ratio |");
    println!("|---|---|---|---|---|---|---|");
    for r in &rows {
        println!(
            "| {} | {} | {} | {:.2} | {:.1} | {:.1} | {:.1} % |",
            r.scene,
            r.triangles,
            r.method.name(),
            r.segments_per_photon,
            r.raw_ns,
            r.pass_ns,
            100.0 * r.raw_ns / r.pass_ns
        );
    }
}
