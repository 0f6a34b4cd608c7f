//! Throughput and memory of the CPU backend (`CpuTracer` on Embree 4), all on one scene.
//!
//! ```text
//! CARGO_TARGET_DIR=/work/target-cpubench cargo bench -p arpa-cpu --bench cpu_backend
//! ```
//!
//! The scene is built in code: a closed Cornell-like room (2 m cube, coloured side walls),
//! a smooth glass icosphere (IOR 1.5, 5120 triangles with radial shading normals), a
//! rotated mirror block and a small downward quad light under the ceiling; 256×256 camera
//! inside the room. Prints plain `name: value unit` lines:
//!
//! 1. `embree_raw.*`: raw Embree closest-hit rays/s ([`arpa_cpu::EmbreeScene::intersect`]) on the
//!    very rays of one photon pass (origins/directions recorded through a wrapping
//!    [`RayCaster`], replayed in photon order), on 1 thread and on all threads (rayon
//!    pools). `embree_caster.*` replays them through [`EmbreeCaster`] (the core's
//!    `RayCaster` interface), `core_only.*` replays the recorded *hits* without Embree (the
//!    propagation/differential/store cost of `trace_photon` alone).
//! 2. `photon_pass.*`: [`CpuTracer::photon_pass`] segments/s (`photon_segments` / stage
//!    time) on the same thread counts, and its ratio to (1). `interleaved.*` measures (1)
//!    and both methods' passes again round by round, alternating, and gives the ratios of
//!    their best times: the three are timed under the same conditions, so these ratios do
//!    not depend on changes in the machine's speed between sections.
//! 3. `gather.*`: gather queries/s and footprints + photons per query.
//! 4. `memory.*`: bytes per footprint: `size_of::<PackedFootprint>()`, the box (held from the
//!    photon pass until the build, handed to Embree without a copy and freed after it), and
//!    the Embree box BVH measured as the RSS delta of building the box scene over the boxes
//!    of a real 1M-photon pass (in a fresh child process, after `malloc_trim`).
//! 5. `peak_rss.*`: `VmHWM` of a fresh child process during two iterations at 1,000,000
//!    photons, per stage (peak reset through `/proc/self/clear_refs` before each stage).
//! 6. `breakdown.*`: stage times for E-50K, E-250K (in-process) and E-1000K (from the
//!    runs of 5) photons per iteration, both methods (mean over the iterations after a
//!    warm-up one; `first_iteration` is the warm-up).
//!
//! The load average is printed next to each section (`load: ...`). Every multi-threaded
//! figure also gives the cores the process really kept busy (`busy cores`, from
//! `/proc/self/stat`) and the rate per CPU-second, so that numbers taken while other
//! processes hold cores can be told apart (and compared through the CPU-time figures).
//!
//! `ARPA_CPU_BENCH_PROFILE=photon|gather|build|camera[:arpa|rtpm[:threads]]` repeats one
//! stage for ~5 s and exits, for `perf record -g -- <bench binary> --bench`.
//!
//! Without `--bench` (`cargo test --benches`) everything runs once on a tiny version of the
//! scene (32×32, 320 triangles of glass, a few thousand photons), as a smoke test.
//! `ARPA_CPU_BENCH_ONLY=raw,pass,gather,memory,peak,breakdown` restricts the sections.
//! `ARPA_CPU_BENCH_SUBDIVISIONS=k` subdivides the glass icosphere `k` times instead of 4
//! (20·4^k triangles): how the photon pass's ratio to raw Embree, and the core's time per
//! segment (`core_only.*`), move as the BVH grows.
//!
//! `ARPA_CPU_BENCH_PACKETS=1` adds `packets.*` to section 1: the recorded photon segments
//! through Embree's packet kernels ([`arpa_cpu::EmbreeScene::intersect8`] / `intersect16`, 8 or
//! 16 consecutive segments per packet, and the same on a fixed shuffle of the segments)
//! next to `rtcIntersect1` one ray at a time (1 thread), and how many packet answers
//! differ from `rtcIntersect1`'s in any bit. It measures what a wavefront photon pass
//! (several photons in flight per thread, their segments traced as one packet) could
//! gain on the Embree side; the ratio of section 2 keeps `rtcIntersect1` as its baseline.

use std::hint::black_box;
use std::process::Command;
use std::sync::Mutex;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::time::{Duration, Instant};

use arpa_core::emit::emission::{Light, QuadLight};
use arpa_core::store::footprint::PackedFootprint;
use arpa_core::glam::{DVec3, Vec3};
use arpa_core::render::photon_path::{PhotonPassSetup, trace_photon};
use arpa_core::render::prepared_scene::PreparedScene;
use arpa_core::store::progressive_photon::PackedPhoton;
use arpa_core::render::ray_cast::{LEAVE_RECASTS, RayCaster, RayHit};
use arpa_core::render::scene::{Camera, Material, Scene, TriangleMesh};
use arpa_core::render::shapes::parallelogram as quad;
use arpa_core::store::decision::StoredPhoton;
use arpa_core::render::tracer::{IterationStats, Method, RenderSettings, StageTimes, Tracer};
use arpa_cpu::{BuildQuality, CpuTracer, Device, EmbreeBox, EmbreeCaster, EmbreeSceneBuilder};
use rayon::prelude::*;

/// Child-process mode (memory measurements in a fresh address space).
const CHILD_ENV: &str = "ARPA_CPU_BENCH_CHILD";
/// `tnear` of every photon segment, as `EmbreeCaster` uses it.
const T_NEAR: f32 = f32::MIN_POSITIVE;

// ---------------------------------------------------------------------------------------
// Configuration
// ---------------------------------------------------------------------------------------

#[derive(Clone, Debug)]
struct Config {
    full: bool,
    /// Image side (pixels).
    size: u32,
    /// Icosphere subdivisions (20·4^k triangles).
    subdivisions: u32,
    /// Photons per iteration of the ray measurements (1, 2) and the gather (3).
    photons: u32,
    /// Minimum time of one timed measurement.
    min_time: Duration,
    /// Timed repetitions (best is reported).
    reps: usize,
    /// Photons of the memory measurements (4, 5).
    memory_photons: u32,
    /// `(label, photons, measured iterations)` of the breakdown (6), measured in-process.
    breakdown: Vec<(&'static str, u32, u32)>,
}

impl Config {
    fn full() -> Self {
        Self {
            full: true,
            size: 256,
            subdivisions: 4,
            photons: 250_000,
            min_time: Duration::from_millis(400),
            reps: 3,
            memory_photons: 1_000_000,
            breakdown: vec![("E-50K", 50_000, 3), ("E-250K", 250_000, 2)],
        }
    }
    fn smoke() -> Self {
        Self {
            full: false,
            size: 32,
            subdivisions: 2,
            photons: 5_000,
            min_time: Duration::ZERO,
            reps: 1,
            memory_photons: 10_000,
            breakdown: vec![("E-2K", 2_000, 1), ("E-5K", 5_000, 1)],
        }
    }
}

// ---------------------------------------------------------------------------------------
// Scene
// ---------------------------------------------------------------------------------------

fn mesh(name: &str, positions: Vec<Vec3>, indices: Vec<[u32; 3]>, material: u32) -> TriangleMesh {
    TriangleMesh { uvs: None,
        name: name.into(),
        positions,
        normals: None,
        indices,
        material,
        emission: None,
    }
}


/// The glass sphere: an icosphere with smooth normals ([`arpa_core::render::shapes::icosphere`]).
fn icosphere(centre: Vec3, radius: f32, subdivisions: u32, material: u32) -> TriangleMesh {
    arpa_core::render::shapes::icosphere("glass sphere", centre, radius, subdivisions, true, material)
}

/// A box of half-extents `half` around `centre`, rotated by `angle` about +y, outward
/// winding (12 triangles).
fn block(centre: Vec3, half: Vec3, angle: f32, material: u32) -> TriangleMesh {
    let (s, c) = angle.sin_cos();
    let corner = |i: u32| {
        let l = Vec3::new(
            if i & 1 != 0 { half.x } else { -half.x },
            if i & 2 != 0 { half.y } else { -half.y },
            if i & 4 != 0 { half.z } else { -half.z },
        );
        centre + Vec3::new(c * l.x + s * l.z, l.y, -s * l.x + c * l.z)
    };
    let positions = (0..8).map(corner).collect();
    // Faces as quads (a, b, c, d) counter-clockwise seen from outside.
    let faces = [
        [0, 4, 6, 2],
        [1, 3, 7, 5],
        [0, 1, 5, 4],
        [2, 6, 7, 3],
        [0, 2, 3, 1],
        [4, 5, 7, 6],
    ];
    let indices = faces
        .iter()
        .flat_map(|&[a, b, c, d]| [[a, b, c], [a, c, d]])
        .collect();
    mesh("mirror block", positions, indices, material)
}

/// The benchmark scene (see the module docs).
fn build_scene(size: u32, subdivisions: u32) -> Scene {
    let (x, y, z) = (Vec3::X * 2.0, Vec3::Y * 2.0, Vec3::Z * 2.0);
    let o = Vec3::new(-1.0, 0.0, -1.0);
    let meshes = vec![
        quad("floor", o, z, x, 0),
        quad("ceiling", o + y, x, z, 0),
        quad("back", o, x, y, 0),
        quad("front", o + z, y, x, 0),
        quad("left", o, y, z, 1),
        quad("right", o + x, z, y, 2),
        icosphere(Vec3::new(0.4, 0.41, 0.0), 0.4, subdivisions, 3),
        block(
            Vec3::new(-0.45, 0.6, -0.45),
            Vec3::new(0.25, 0.6, 0.25),
            0.4,
            4,
        ),
    ];
    let materials = vec![
        Material::Diffuse {
            albedo: Vec3::splat(0.75),
        },
        Material::Diffuse {
            albedo: Vec3::new(0.65, 0.1, 0.1),
        },
        Material::Diffuse {
            albedo: Vec3::new(0.1, 0.6, 0.1),
        },
        Material::Dielectric {
            ior: 1.5,
            transmittance: Vec3::ONE,
            roughness: 0.0,
        },
        Material::Conductor {
            reflectance: Vec3::splat(0.95),
            roughness: 0.0,
        },
    ];
    // 0.5 m × 0.5 m, emitting downwards (edge_u × edge_v = −y).
    let light = Light::Quad(QuadLight {
        origin: DVec3::new(-0.25, 1.98, -0.25),
        edge_u: DVec3::new(0.5, 0.0, 0.0),
        edge_v: DVec3::new(0.0, 0.0, 0.5),
        radiance: DVec3::splat(20.0),
    });
    let camera = Camera {
        position: Vec3::new(0.0, 1.0, 0.97),
        target: Vec3::new(0.0, 0.8, -1.0),
        up: Vec3::Y,
        vertical_fov: 62f32.to_radians(),
        width: size,
        height: size,
    };
    Scene { textures: Default::default(),
        meshes,
        materials,
        lights: vec![light],
        camera,
        roughness_cutoff: 0.5,
        instancing: None,
    }
}

fn settings(method: Method, photons: u32) -> RenderSettings {
    RenderSettings {
        method,
        photons_per_iteration: photons,
        seed: 1,
        ..RenderSettings::default()
    }
}

// ---------------------------------------------------------------------------------------
// Helpers
// ---------------------------------------------------------------------------------------

fn load() -> String {
    std::fs::read_to_string("/proc/loadavg")
        .map(|s| s.split_whitespace().take(3).collect::<Vec<_>>().join(" "))
        .unwrap_or_else(|_| "?".into())
}

fn section(title: &str) {
    println!("# {title} (load: {})", load());
}

/// A `kB` field of `/proc/self/status`, in bytes.
fn status_bytes(field: &str) -> Option<u64> {
    let s = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = s.lines().find(|l| l.starts_with(field))?;
    let kb: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kb * 1024)
}

fn rss() -> u64 {
    status_bytes("VmRSS:").unwrap_or(0)
}

fn hwm() -> u64 {
    status_bytes("VmHWM:").unwrap_or(0)
}

/// Resets `VmHWM` to the current RSS (Linux ≥ 4.0); false where not permitted.
fn reset_hwm() -> bool {
    std::fs::write("/proc/self/clear_refs", "5").is_ok()
}

unsafe extern "C" {
    /// glibc: returns free heap memory to the kernel.
    fn malloc_trim(pad: usize) -> i32;
}

fn trim() {
    // SAFETY: plain glibc call without pointers.
    unsafe { malloc_trim(0) };
}

fn mib(b: u64) -> f64 {
    b as f64 / (1024.0 * 1024.0)
}

fn pool(threads: usize) -> rayon::ThreadPool {
    rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .expect("rayon pool")
}

fn all_threads() -> usize {
    std::thread::available_parallelism().map_or(1, |n| n.get())
}

/// CPU time (user + system) of the whole process so far, in seconds (`/proc/self/stat`,
/// assuming the usual 100 ticks per second).
fn cpu_seconds() -> f64 {
    let Ok(s) = std::fs::read_to_string("/proc/self/stat") else {
        return 0.0;
    };
    // Fields after the parenthesised command name; utime and stime are fields 14 and 15.
    let rest = s.rsplit_once(')').map_or("", |(_, r)| r);
    let f: Vec<u64> = rest
        .split_whitespace()
        .skip(11)
        .take(2)
        .filter_map(|x| x.parse().ok())
        .collect();
    f.iter().sum::<u64>() as f64 / 100.0
}

/// Measures the CPU cores the process kept busy (CPU time / wall time) while it lives.
struct CpuMeter {
    wall: Instant,
    cpu: f64,
}

impl CpuMeter {
    fn start() -> Self {
        Self {
            wall: Instant::now(),
            cpu: cpu_seconds(),
        }
    }
    /// CPU seconds used since the start.
    fn cpu(&self) -> f64 {
        cpu_seconds() - self.cpu
    }
    /// `"busy cores X.XX"`, or `n/a` under 0.2 s (the tick counters are too coarse).
    fn cores(&self) -> String {
        let wall = self.wall.elapsed().as_secs_f64();
        if wall < 0.2 {
            return "n/a".into();
        }
        format!("{:.2}", (cpu_seconds() - self.cpu) / wall)
    }
}

/// A timed measurement.
struct Timing {
    /// Best wall time per call (s).
    best: f64,
    /// Mean CPU time per call (s), all threads of the process: robust to other processes
    /// taking cores away (with 10 ms tick resolution).
    cpu: f64,
    /// Cores kept busy.
    cores: String,
}

/// Best time per call of `f` over `reps` repetitions, each of at least `min_time`
/// (`f` returns a value kept alive through `black_box`), and the CPU time it used.
fn best_time<T>(cfg: &Config, mut f: impl FnMut() -> T) -> Timing {
    let meter = CpuMeter::start();
    let mut best = f64::INFINITY;
    let mut total = 0u32;
    for _ in 0..cfg.reps {
        let start = Instant::now();
        let mut calls = 0u32;
        loop {
            black_box(f());
            calls += 1;
            if start.elapsed() >= cfg.min_time {
                break;
            }
        }
        total += calls;
        best = best.min(start.elapsed().as_secs_f64() / calls as f64);
    }
    Timing {
        best,
        cpu: meter.cpu() / total as f64,
        cores: meter.cores(),
    }
}

/// `100 a/b` as `"X.X"`, or `n/a` unless both are finite and positive.
fn pct(a: f64, b: f64) -> String {
    if a.is_finite() && b.is_finite() && a > 0.0 && b > 0.0 {
        format!("{:.1}", 100.0 * a / b)
    } else {
        "n/a".into()
    }
}

/// `"X.XXX M<unit> per CPU-second"`, or `n/a` when the CPU time is below the tick
/// resolution.
fn per_cpu(count: f64, cpu: f64) -> String {
    if cpu > 0.05 {
        format!("{:.3}", count / cpu / 1e6)
    } else {
        "n/a".into()
    }
}

fn tracer(scene: &Scene, settings: &RenderSettings) -> CpuTracer {
    let mut t = CpuTracer::new().expect("Embree device");
    t.upload_scene(scene, settings).expect("upload");
    t
}

// ---------------------------------------------------------------------------------------
// 1. Raw Embree rays on the photon segments
// ---------------------------------------------------------------------------------------

/// Records every photon segment (origin, direction) and its answer, in call order.
struct Recorder<'a> {
    inner: &'a EmbreeCaster,
    log: Mutex<Vec<(Segment, Option<RayHit>)>>,
}

#[derive(Clone, Copy)]
struct Segment {
    origin: [f32; 3],
    direction: [f32; 3],
    t_min: f32,
    t_max: f32,
}

impl RayCaster for Recorder<'_> {
    fn intersect(&self, origin: Vec3, direction: Vec3, t_min: f32, t_max: f32) -> Option<RayHit> {
        let hit = self.inner.intersect(origin, direction, t_min, t_max);
        let seg = Segment {
            origin: origin.to_array(),
            direction: direction.to_array(),
            t_min,
            t_max,
        };
        self.log.lock().unwrap().push((seg, hit));
        hit
    }
    fn occluded(&self, origin: Vec3, direction: Vec3, t_min: f32, t_max: f32) -> bool {
        self.inner.occluded(origin, direction, t_min, t_max)
    }
}

/// Answers the recorded hits in order, without tracing: the photon pass minus Embree.
struct Replay<'a> {
    hits: &'a [Option<RayHit>],
    next: AtomicUsize,
}

impl RayCaster for Replay<'_> {
    fn intersect(&self, _: Vec3, _: Vec3, _: f32, _: f32) -> Option<RayHit> {
        let i = self.next.fetch_add(1, Ordering::Relaxed);
        self.hits.get(i).copied().flatten()
    }
}

/// Replays `segments` on the threads of `p` in chunks of 4,096, counting those for which
/// `hit` (one closest-hit query) answers `true`.
fn count_hits(p: &rayon::ThreadPool, segments: &[Segment], hit: impl Fn(&Segment) -> bool + Sync) -> usize {
    p.install(|| segments.par_chunks(4096).map(|c| c.iter().filter(|r| hit(r)).count()).sum())
}

/// One photon pass of `tr` on the threads of `p`, and the statistics it leaves.
fn run_photon_pass(tr: &mut CpuTracer, p: &rayon::ThreadPool) -> IterationStats {
    p.install(|| tr.photon_pass()).expect("photon pass");
    tr.read_stats().unwrap()
}

/// Rates of one thread count: wall-clock and per CPU-second.
#[derive(Clone, Copy, Default)]
struct Rate {
    wall: f64,
    cpu: f64,
}

fn bench_rays(cfg: &Config, scene: &Scene, raw_rate: &mut [Rate; 2], pass_rate: &mut [Rate; 2], interleaved: &mut [f64; 2]) {
    let threads = [1, all_threads()];
    let pools = threads.map(pool);
    let device = Device::new().expect("Embree device");
    let s = settings(Method::Arpa, cfg.photons);
    let prepared = PreparedScene::new(scene.clone()).expect("scene");
    // Same builder settings as the tracer's own caster: same BVH.
    let caster = EmbreeCaster::new(&device, &prepared).expect("BVH");
    let setup = PhotonPassSetup::new(&prepared, &s, 0);
    let count = setup.photon_count();

    // Record the photon segments of iteration 0 in photon order.
    let rec = Recorder {
        inner: &caster,
        log: Mutex::new(Vec::new()),
    };
    let mut stored = 0u64;
    for index in 0..count {
        trace_photon(&prepared, &rec, &s, &setup, index, &mut |_| stored += 1);
    }
    let log = rec.log.into_inner().unwrap();
    let segments: Vec<Segment> = log.iter().map(|(s, _)| *s).collect();
    let hits: Vec<Option<RayHit>> = log.iter().map(|(_, h)| *h).collect();
    drop(log);
    let n = segments.len() as f64;
    let hit_fraction = hits.iter().filter(|h| h.is_some()).count() as f64 / n;
    println!(
        "scene.triangles: {} triangles",
        prepared
            .scene()
            .meshes
            .iter()
            .map(|m| m.indices.len())
            .sum::<usize>()
    );
    println!("rays.photons: {count} photons");
    println!("rays.segments: {} segments", segments.len());
    println!("rays.segments_per_photon: {:.3} segments", n / count as f64);
    println!("rays.hit_fraction: {:.4}", hit_fraction);
    println!(
        "rays.stored_per_photon: {:.3} records",
        stored as f64 / count as f64
    );

    let emb = caster.scene();
    // The raw baseline: the recorded segments through `EmbreeScene::intersect` on the threads of
    // `p`; returns the number of hits.
    let raw_replay = |p: &rayon::ThreadPool| {
        count_hits(p, &segments, |r| {
            matches!(emb.intersect(r.origin, r.direction, r.t_min.max(T_NEAR), r.t_max), Ok(Some(_)))
        })
    };
    for (k, p) in pools.iter().enumerate() {
        let t = best_time(cfg, || raw_replay(p));
        raw_rate[k] = Rate {
            wall: n / t.best,
            cpu: n / t.cpu,
        };
        println!(
            "embree_raw.threads_{}: {:.3} Mrays/s (busy cores {}; {} Mrays per CPU-second)",
            threads[k],
            n / t.best / 1e6,
            t.cores,
            per_cpu(n, t.cpu)
        );
    }
    for (k, p) in pools.iter().enumerate() {
        let t = best_time(cfg, || {
            count_hits(p, &segments, |r| {
                caster
                    .intersect(Vec3::from_array(r.origin), Vec3::from_array(r.direction), r.t_min, r.t_max)
                    .is_some()
            })
        });
        println!(
            "embree_caster.threads_{}: {:.3} Mrays/s (busy cores {}; {} Mrays per CPU-second)",
            threads[k],
            n / t.best / 1e6,
            t.cores,
            per_cpu(n, t.cpu)
        );
    }
    if std::env::var_os("ARPA_CPU_BENCH_PACKETS").is_some() {
        let prays: Vec<arpa_cpu::PacketRay> = segments
            .iter()
            .map(|r| arpa_cpu::PacketRay { origin: r.origin, dir: r.direction, tnear: r.t_min.max(T_NEAR), tfar: r.t_max })
            .collect();
        // A fixed pseudo-random permutation (incoherent packets).
        let mut perm: Vec<usize> = (0..prays.len()).collect();
        let mut x = 0x9E37_79B9_7F4A_7C15u64;
        for i in (1..perm.len()).rev() {
            x ^= x << 13; x ^= x >> 7; x ^= x << 17;
            perm.swap(i, (x % (i as u64 + 1)) as usize);
        }
        let shuffled: Vec<arpa_cpu::PacketRay> = perm.iter().map(|&i| prays[i]).collect();
        for width in [8usize, 16] {
            let mut hits = [None; 16];
            let mut diff = 0usize;
            for ch in prays.chunks(width) {
                if width == 8 { emb.intersect8(ch, &mut hits).unwrap() } else { emb.intersect16(ch, &mut hits).unwrap() }
                for (r, h) in ch.iter().zip(&hits) {
                    let one = emb.intersect(r.origin, r.dir, r.tnear, r.tfar).unwrap();
                    let same = match (one, h) {
                        (None, None) => true,
                        (Some(a), Some(b)) => a.t.to_bits() == b.t.to_bits() && a.u.to_bits() == b.u.to_bits() && a.v.to_bits() == b.v.to_bits() && a.prim_id == b.prim_id && a.geom_id == b.geom_id,
                        _ => false,
                    };
                    diff += (!same) as usize;
                }
            }
            println!("packets.differ_from_intersect1.width_{width}: {diff} of {} rays", prays.len());
        }
        for (label, rays) in [("ordered", &prays), ("shuffled", &shuffled)] {
            let t1 = best_time(cfg, || {
                rays.iter().filter(|r| matches!(emb.intersect(r.origin, r.dir, r.tnear, r.tfar), Ok(Some(_)))).count()
            });
            let t8 = best_time(cfg, || {
                let mut hits = [None; 8];
                let mut c = 0;
                for ch in rays.chunks(8) {
                    emb.intersect8(ch, &mut hits).unwrap();
                    c += hits[..ch.len()].iter().filter(|h| h.is_some()).count();
                }
                c
            });
            let t16 = best_time(cfg, || {
                let mut hits = [None; 16];
                let mut c = 0;
                for ch in rays.chunks(16) {
                    emb.intersect16(ch, &mut hits).unwrap();
                    c += hits[..ch.len()].iter().filter(|h| h.is_some()).count();
                }
                c
            });
            println!(
                "packets.{label}: rtcIntersect1 {:.1} ns/ray, rtcIntersect8 {:.1} ns/ray, rtcIntersect16 {:.1} ns/ray",
                t1.best / n * 1e9,
                t8.best / n * 1e9,
                t16.best / n * 1e9
            );
        }
    }
    // The core's share: trace_photon over the recorded hits (single thread, no Embree).
    {
        let t = best_time(cfg, || {
            let replay = Replay {
                hits: &hits,
                next: AtomicUsize::new(0),
            };
            let mut sink_count = 0u64;
            for index in 0..count {
                trace_photon(
                    &prepared,
                    &replay,
                    &s,
                    &setup,
                    index,
                    &mut |p: StoredPhoton| {
                        black_box(&p);
                        sink_count += 1
                    },
                );
            }
            assert_eq!(
                replay.next.load(Ordering::Relaxed),
                hits.len(),
                "replay diverged"
            );
            sink_count
        });
        println!(
            "core_only.threads_1: {:.3} Msegments/s (busy cores {})",
            n / t.best / 1e6,
            t.cores
        );
        println!("core_only.ns_per_segment: {:.1} ns", t.best / n * 1e9);
        println!(
            "embree_raw.ns_per_segment: {:.1} ns",
            1e9 / raw_rate[0].wall
        );
    }

    // 2. arpa's photon pass on the same photons (and RTPM's); the tracers serve the
    // interleaved rounds below too.
    let methods = [Method::Arpa, Method::Rtpm];
    let mut passes = methods.map(|m| tracer(scene, &settings(m, cfg.photons)));
    for (method, tr) in methods.into_iter().zip(&mut passes) {
        for (k, p) in pools.iter().enumerate() {
            let mut best = f64::INFINITY;
            let mut stats = IterationStats::default();
            let started = Instant::now();
            let meter = CpuMeter::start();
            let mut calls = 0;
            for rep in 0.. {
                calls += 1;
                stats = run_photon_pass(tr, p);
                best = best.min(stats.times.photon);
                if rep + 1 >= cfg.reps && started.elapsed() >= cfg.min_time {
                    break;
                }
            }
            if method == Method::Arpa {
                // One cast per segment, plus the re-casts past a left triangle (RayStart).
                let casts = segments.len() as u64;
                assert!(
                    stats.photon_segments <= casts && casts <= stats.photon_segments * (1 + u64::from(LEAVE_RECASTS)),
                    "photon pass traced {} segments, the recording {casts} casts",
                    stats.photon_segments
                );
            }
            let segs = stats.photon_segments as f64;
            let cpu = meter.cpu() / calls as f64;
            let rate = Rate {
                wall: segs / best,
                cpu: segs / cpu,
            };
            let name = method.name();
            println!(
                "photon_pass.{name}.threads_{}: {:.3} Msegments/s ({:.3} s, busy cores {}; {} Msegments per CPU-second)",
                threads[k],
                rate.wall / 1e6,
                best,
                meter.cores(),
                per_cpu(segs, cpu)
            );
            println!(
                "photon_pass.{name}.threads_{}.ratio_to_raw: {:.1} % (per CPU-second: {} %)",
                threads[k],
                100.0 * rate.wall / raw_rate[k].wall,
                pct(rate.cpu, raw_rate[k].cpu)
            );
            if method == Method::Arpa {
                pass_rate[k] = rate;
            }
        }
    }

    // The same ratios with the raw replay and both passes interleaved round by round, so
    // that all three see the same phases of the machine (whose speed can change between
    // the measurements above, taken apart). Best of each over the rounds.
    let rounds = if cfg.full { 8 } else { cfg.reps.max(2) };
    for (k, p) in pools.iter().enumerate() {
        let mut raw = f64::INFINITY;
        let mut pass = [(f64::INFINITY, 0u64); 2];
        for _ in 0..rounds {
            let start = Instant::now();
            black_box(raw_replay(p));
            raw = raw.min(start.elapsed().as_secs_f64());
            for (tr, best) in passes.iter_mut().zip(&mut pass) {
                let stats = run_photon_pass(tr, p);
                *best = (best.0.min(stats.times.photon), stats.photon_segments);
            }
        }
        let raw_ns = raw / n * 1e9;
        let [arpa, rtpm] = pass.map(|(t, segs)| t / segs as f64 * 1e9);
        let [arpa_ratio, rtpm_ratio] = [arpa, rtpm].map(|ns| 100.0 * raw_ns / ns);
        interleaved[k] = arpa_ratio;
        println!(
            "interleaved.threads_{}: raw {raw_ns:.1} ns/ray, arpa {arpa:.1} ns/segment ({arpa_ratio:.1} % of raw rays/s), rtpm {rtpm:.1} ns/segment ({rtpm_ratio:.1} %), best of {rounds} rounds",
            threads[k]
        );
    }
}

// ---------------------------------------------------------------------------------------
// 3. Gather
// ---------------------------------------------------------------------------------------

fn bench_gather(cfg: &Config, scene: &Scene) {
    let threads = [1, all_threads()];
    for method in [Method::Arpa, Method::Rtpm] {
        let mut tr = tracer(scene, &settings(method, cfg.photons));
        tr.camera_pass().unwrap();
        tr.photon_pass().unwrap();
        tr.build_acceleration_structure().unwrap();
        let name = method.name();
        for &n in &threads {
            let p = pool(n);
            let mut best = f64::INFINITY;
            let mut stats = IterationStats::default();
            let meter = CpuMeter::start();
            for _ in 0..cfg.reps {
                p.install(|| tr.gather()).unwrap();
                stats = tr.read_stats().unwrap();
                best = best.min(stats.times.gather);
            }
            let q = stats.query_points as f64;
            println!(
                "gather.{name}.threads_{n}: {:.3} Mqueries/s ({:.4} s, {} queries, busy cores {})",
                q / best / 1e6,
                best,
                stats.query_points,
                meter.cores()
            );
        }
        let stats = tr.read_stats().unwrap();
        let q = stats.query_points as f64;
        println!(
            "gather.{name}.gathered_per_query: {:.2} records",
            stats.gathered() as f64 / q
        );
        let stored = (stats.footprints[0] + stats.footprints[1]) as f64;
        let photons = (stats.progressive[0] + stats.progressive[1]) as f64;
        println!("gather.{name}.stored: {stored} footprints, {photons} photons");
        // Broad phase: how many boxes the BVH hands to the exact test per query (own box
        // scene over the same records, the same iteration-0 photon pass traced again;
        // boxes without the tracer's padding).
        let r = stats.radii.map(|r| r as f32);
        let mut boxes = footprint_boxes(scene, &settings(method, cfg.photons));
        assert_eq!(boxes.len() as f64, stored);
        boxes.extend(tr.read_photons().unwrap().iter().map(|p| {
            let (c, r) = (Vec3::from_array(p.position), r[p.photon_map().index()]);
            EmbreeBox {
                lower: (c - r).to_array(),
                upper: (c + r).to_array(),
            }
        }));
        if !boxes.is_empty() {
            let device = Device::new().unwrap();
            let mut b = EmbreeSceneBuilder::new(&device)
                .unwrap()
                .build_quality(BuildQuality::Low);
            b.add_boxes(&boxes).unwrap();
            let bvh = b.commit().unwrap();
            let (mut candidates, mut inside) = (0u64, 0u64);
            for qr in tr
                .read_query_points()
                .unwrap()
                .iter()
                .filter(|q| q.valid != 0)
            {
                bvh.point_query(qr.position, 0.0, |c| {
                    candidates += 1;
                    inside += u64::from(boxes[c.prim_id as usize].contains(qr.position));
                })
                .unwrap();
            }
            println!(
                "gather.{name}.box_candidates_per_query: {:.2} boxes",
                candidates as f64 / q
            );
            println!(
                "gather.{name}.boxes_containing_per_query: {:.2} boxes",
                inside as f64 / q
            );
        }
    }
}

// ---------------------------------------------------------------------------------------
// 4. Memory per footprint (child process)
// ---------------------------------------------------------------------------------------

/// The footprint boxes of a real photon pass as `CpuTracer` makes them: the core's box
/// of each footprint's slab ([`StoredPhoton::Footprint`]'s `aabb`) rounded outwards to
/// `f32` (the tracer's small padding does not change the size).
fn footprint_boxes(scene: &Scene, settings: &RenderSettings) -> Vec<EmbreeBox> {
    let prepared = PreparedScene::new(scene.clone()).expect("scene");
    let device = Device::new().expect("device");
    let caster = EmbreeCaster::new(&device, &prepared).expect("BVH");
    let setup = PhotonPassSetup::new(&prepared, settings, 0);
    let count = setup.photon_count();
    let chunks: Vec<Vec<EmbreeBox>> = (0..count.div_ceil(4096))
        .into_par_iter()
        .map(|c| {
            let mut out = Vec::new();
            for index in c * 4096..(c * 4096 + 4096).min(count) {
                trace_photon(&prepared, &caster, settings, &setup, index, &mut |p| {
                    if let StoredPhoton::Footprint { aabb, .. } = p {
                        let (lower, upper) = aabb.to_f32_conservative();
                        out.push(EmbreeBox { lower, upper });
                    }
                });
            }
            out
        })
        .collect();
    chunks.concat()
}

fn child_memory(cfg: &Config) {
    let scene = build_scene(cfg.size, cfg.subdivisions);
    let boxes = footprint_boxes(&scene, &settings(Method::Arpa, cfg.memory_photons));
    let kind = "footprint";
    let photon_boxes: Vec<EmbreeBox> = {
        let mut tr = tracer(&scene, &settings(Method::Rtpm, cfg.memory_photons));
        tr.photon_pass().unwrap();
        let r = tr.read_stats().unwrap().radii[1] as f32;
        tr.read_photons()
            .unwrap()
            .iter()
            .map(|p: &PackedPhoton| {
                let c = Vec3::from_array(p.position);
                EmbreeBox {
                    lower: (c - r).to_array(),
                    upper: (c + r).to_array(),
                }
            })
            .collect()
    };
    let device = Device::new().unwrap();
    println!(
        "memory.size_of_packed_footprint: {} bytes",
        size_of::<PackedFootprint>()
    );
    println!(
        "memory.size_of_packed_photon: {} bytes",
        size_of::<PackedPhoton>()
    );
    println!(
        "memory.size_of_aabb: {} bytes (PhotonStore::footprint_boxes from the photon pass until the build; moved into the Embree scene, freed after the build)",
        size_of::<EmbreeBox>()
    );
    for (kind, boxes) in [(kind, boxes), ("photon", photon_boxes)] {
        let n = boxes.len() as f64;
        println!("memory.{kind}_boxes: {} boxes", boxes.len());
        trim();
        let r_boxes = rss();
        // As CpuTracer builds: the boxes move into the scene (no copy) ...
        let mut b = EmbreeSceneBuilder::new(&device)
            .unwrap()
            .build_quality(BuildQuality::Low);
        b.add_boxes_owned(boxes).unwrap();
        let r0 = rss();
        let reset = reset_hwm();
        let built = Instant::now();
        let mut scene = b.commit().unwrap();
        let t = built.elapsed().as_secs_f64();
        let (r1, h1) = (rss(), hwm());
        // ... and are freed once the BVH is built.
        drop(scene.release_boxes());
        trim();
        let r2 = rss();
        black_box(&scene);
        println!(
            "memory.{kind}.box_copy_per_record: {:.1} bytes (RSS delta of add_boxes_owned)",
            (r0 as f64 - r_boxes as f64) / n
        );
        println!(
            "memory.{kind}.embree_bvh_per_record: {:.1} bytes (RSS delta of commit)",
            (r1 as f64 - r0 as f64) / n
        );
        println!(
            "memory.{kind}.boxes_freed_per_record: {:.1} bytes (RSS delta of release_boxes)",
            (r1 as f64 - r2 as f64) / n
        );
        let record = if kind == "footprint" {
            size_of::<PackedFootprint>()
        } else {
            size_of::<PackedPhoton>()
        };
        if reset {
            println!(
                "memory.{kind}.embree_build_peak_per_record: {:.1} bytes (VmHWM delta of commit)",
                (h1 as f64 - r0 as f64) / n
            );
            println!(
                "memory.{kind}.build_peak_total_per_record: {:.1} bytes (record + box + VmHWM delta of commit)",
                record as f64 + size_of::<EmbreeBox>() as f64 + (h1 as f64 - r0 as f64) / n
            );
        }
        println!("memory.{kind}.bvh_build_time: {:.4} s", t);
        let total = record as f64 + (r2 as f64 - r_boxes as f64) / n + size_of::<EmbreeBox>() as f64;
        println!(
            "memory.{kind}.total_per_record: {total:.1} bytes (steady state after the build: record + BVH; boxes freed)"
        );
        drop(scene);
    }
}

// ---------------------------------------------------------------------------------------
// 5 + 6. Peak RSS and stage times of whole iterations (child process at 1M photons)
// ---------------------------------------------------------------------------------------

fn print_breakdown(label: &str, method: Method, stats: &[IterationStats]) {
    let k = stats.len() as f64;
    let mean = |f: fn(&StageTimes) -> f64| stats.iter().map(|s| f(&s.times)).sum::<f64>() / k;
    let (c, p, b, g, a) = (
        mean(|t| t.camera),
        mean(|t| t.photon),
        mean(|t| t.build),
        mean(|t| t.gather),
        mean(|t| t.accumulate),
    );
    let s = stats.last().unwrap();
    let name = format!("breakdown.{label}.{}", method.name());
    println!(
        "{name}: camera {c:.4} s, photon {p:.4} s, build {b:.4} s, gather {g:.4} s, accumulate {a:.4} s, total {:.4} s (mean of {} iterations)",
        c + p + b + g + a,
        stats.len()
    );
    println!(
        "{name}.counts: {} segments, {} footprints, {} photons, {} queries, {:.2} gathered/query",
        s.photon_segments,
        s.footprints[0] + s.footprints[1],
        s.progressive[0] + s.progressive[1],
        s.query_points,
        s.gathered() as f64 / s.query_points.max(1) as f64
    );
}

fn child_peak(cfg: &Config, method: Method) {
    let scene = build_scene(cfg.size, cfg.subdivisions);
    let label = if cfg.full {
        "E-1000K".to_string()
    } else {
        format!("E-{}", cfg.memory_photons)
    };
    let name = method.name();
    let mut tr = tracer(&scene, &settings(method, cfg.memory_photons));
    println!(
        "peak_rss.{name}.after_upload: {:.1} MiB (VmHWM so far {:.1} MiB)",
        mib(rss()),
        mib(hwm())
    );
    let mut stats = Vec::new();
    for i in 1..=2 {
        let mut peak = 0u64;
        let mut stages = Vec::new();
        let mut reset = true;
        type Stage = fn(&mut CpuTracer) -> Result<(), arpa_cpu::CpuError>;
        let run: [(&str, Stage); 5] = [
            ("camera", |t| t.camera_pass()),
            ("photon", |t| t.photon_pass()),
            ("build", |t| t.build_acceleration_structure()),
            ("gather", |t| t.gather()),
            ("accumulate", |t| t.accumulate()),
        ];
        for (stage, f) in run {
            reset &= reset_hwm();
            f(&mut tr).unwrap();
            let h = hwm();
            peak = peak.max(h);
            stages.push(format!("{stage} {:.0}/{:.0}", mib(h), mib(rss())));
        }
        if reset {
            println!(
                "peak_rss.{name}.iteration_{i}: {:.1} MiB (VmHWM during the iteration)",
                mib(peak)
            );
            println!(
                "peak_rss.{name}.iteration_{i}.per_stage: {} MiB (peak/after)",
                stages.join(", ")
            );
        } else {
            println!(
                "peak_rss.{name}.process_up_to_iteration_{i}: {:.1} MiB (VmHWM; clear_refs not permitted)",
                mib(hwm())
            );
        }
        stats.push(tr.read_stats().unwrap());
    }
    // The first iteration allocates the buffers: report the second one.
    print_breakdown(&label, method, &stats[1..]);
    print_breakdown(&format!("{label}.first_iteration"), method, &stats[..1]);
}

fn run_child(cfg: &Config, what: &str) {
    let exe = std::env::current_exe().expect("own executable");
    let mut cmd = Command::new(exe);
    cmd.env(CHILD_ENV, what);
    if cfg.full {
        cmd.arg("--bench");
    }
    let out = cmd.output().expect("child process");
    print!("{}", String::from_utf8_lossy(&out.stdout));
    if !out.status.success() {
        eprint!("{}", String::from_utf8_lossy(&out.stderr));
        panic!("child {what} failed: {}", out.status);
    }
}

fn bench_breakdown(cfg: &Config, scene: &Scene) {
    for (label, photons, iterations) in &cfg.breakdown {
        for method in [Method::Arpa, Method::Rtpm] {
            let mut tr = tracer(scene, &settings(method, *photons));
            tr.iterate().unwrap(); // warm-up: allocates the buffers
            let stats: Vec<IterationStats> = (0..*iterations)
                .map(|_| {
                    tr.iterate().unwrap();
                    tr.read_stats().unwrap()
                })
                .collect();
            print_breakdown(label, method, &stats);
        }
    }
}

/// `ARPA_CPU_BENCH_PROFILE=<stage>[:method[:threads]]`: repeats one stage (`photon`,
/// `gather`, `build`, `camera`) for about 5 s (0 in smoke mode) and exits; for profilers
/// (`perf record -g -- <bench binary> --bench`). `build` runs a photon pass before each
/// build (a tracer does not rebuild a BVH that is current).
fn profile_loop(cfg: &Config, spec: &str) {
    let mut it = spec.split(':');
    let stage = it.next().unwrap_or("photon");
    let method = match it.next() {
        Some("rtpm") => Method::Rtpm,
        _ => Method::Arpa,
    };
    let threads = it.next().and_then(|t| t.parse().ok()).unwrap_or(1);
    let scene = build_scene(cfg.size, cfg.subdivisions);
    let mut tr = tracer(&scene, &settings(method, cfg.photons));
    tr.camera_pass().unwrap();
    tr.photon_pass().unwrap();
    tr.build_acceleration_structure().unwrap();
    let p = pool(threads);
    let start = Instant::now();
    let mut calls = 0;
    while calls == 0 || (cfg.full && start.elapsed() < Duration::from_secs(5)) {
        p.install(|| match stage {
            "photon" => tr.photon_pass(),
            "gather" => tr.gather(),
            // The tracer keeps a BVH that is current: give it new buffers each time.
            "build" => tr
                .photon_pass()
                .and_then(|()| tr.build_acceleration_structure()),
            "camera" => tr.camera_pass(),
            other => panic!("unknown stage {other}"),
        })
        .unwrap();
        calls += 1;
    }
    println!(
        "profile.{stage}.{}.threads_{threads}: {calls} calls in {:.2} s",
        method.name(),
        start.elapsed().as_secs_f64()
    );
}

// ---------------------------------------------------------------------------------------

fn main() {
    let full = std::env::args().any(|a| a == "--bench");
    let mut cfg = if full {
        Config::full()
    } else {
        Config::smoke()
    };
    if let Some(k) = std::env::var("ARPA_CPU_BENCH_SUBDIVISIONS").ok().and_then(|v| v.parse().ok()) {
        cfg.subdivisions = k;
    }
    if let Ok(what) = std::env::var(CHILD_ENV) {
        match what.as_str() {
            "memory" => child_memory(&cfg),
            "peak-arpa" => child_peak(&cfg, Method::Arpa),
            "peak-rtpm" => child_peak(&cfg, Method::Rtpm),
            other => panic!("unknown child mode {other}"),
        }
        return;
    }
    if let Ok(stage) = std::env::var("ARPA_CPU_BENCH_PROFILE") {
        profile_loop(&cfg, &stage);
        return;
    }
    let only = std::env::var("ARPA_CPU_BENCH_ONLY").ok();
    let on = |s: &str| only.as_deref().is_none_or(|o| o.split(',').any(|x| x == s));
    let start = Instant::now();
    println!(
        "# arpa-cpu backend benchmark ({} mode, {} threads)",
        if full { "full" } else { "smoke" },
        all_threads()
    );
    let scene = build_scene(cfg.size, cfg.subdivisions);
    println!("image: {}x{} pixels", cfg.size, cfg.size);

    let (mut raw, mut pass) = ([Rate::default(); 2], [Rate::default(); 2]);
    let mut interleaved = [0.0f64; 2];
    if on("raw") || on("pass") {
        section(&format!("1+2. rays of the photon pass, E-{}", cfg.photons));
        bench_rays(&cfg, &scene, &mut raw, &mut pass, &mut interleaved);
    }
    if on("gather") {
        section(&format!("3. gather, E-{}", cfg.photons));
        bench_gather(&cfg, &scene);
    }
    if on("memory") {
        section(&format!("4. bytes per footprint, E-{}", cfg.memory_photons));
        run_child(&cfg, "memory");
    }
    if on("breakdown") {
        section("6. iteration breakdown");
        bench_breakdown(&cfg, &scene);
    }
    if on("peak") {
        section(&format!(
            "5+6. peak RSS and breakdown, E-{}",
            cfg.memory_photons
        ));
        run_child(&cfg, "peak-arpa");
        run_child(&cfg, "peak-rtpm");
    }
    if raw[0].wall > 0.0 {
        let ratio = |k: usize| {
            format!(
                "{:.1} % (per CPU-second: {} %)",
                100.0 * pass[k].wall / raw[k].wall,
                pct(pass[k].cpu, raw[k].cpu)
            )
        };
        let threads = [1, all_threads()];
        for (k, n) in threads.iter().enumerate() {
            println!("summary.photon_pass_to_raw_embree.threads_{n}: {}", ratio(k));
        }
        // The ratios of the alternating rounds (raw replay and pass timed together).
        for (n, ratio) in threads.iter().zip(&interleaved) {
            println!("summary.photon_pass_to_raw_embree.interleaved.threads_{n}: {ratio:.1} %");
        }
    }
    println!(
        "# done in {:.1} s (load: {})",
        start.elapsed().as_secs_f64(),
        load()
    );
}
