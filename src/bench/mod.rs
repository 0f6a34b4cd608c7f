//! `arpa bench CONFIG.toml`: run time against error over a sweep of scenes, methods, photon
//! budgets and backends, each run for the same wall-clock budget, with Mitsuba 3 peers at
//! equal time, against each scene's independent reference.
//!
//! Every run goes through the render session ([`crate::session`]) with checkpoints at powers
//! of two and at the end; each checkpoint is a CSV row (relMSE, SSIM, FLIP, the ratio of the
//! whole-image means, the per-stage mean times, the relMSE inside the scene's caustic region
//! when its entry has one, and the photon passes' rates: records per photon per map, photons
//! per pass, caustic records per second). The outputs ([`report`]) are one directory:
//! `runs.csv`, `table.md` (the layout of the paper's Table 2: SSIM, NI, ATI per scene ×
//! method × budget), `plots/SCENE.png` (log-log relMSE against time; `SCENE-region.png` the
//! region relMSE), and per run the final
//! image (EXR + PNG) and its relMSE heat map. Every output starts with the same header
//! ([`Header`]: machine, CPU, threads, backends and devices, git commit, config hash).
//!
//! Metrics ([`crate::metrics`]): relMSE on linear radiance (and the same mean over the
//! caustic region's pixels, [`crate::metrics::rel_mse_in`], for ours and the peers); SSIM of the sRGB-encoded
//! luminance clamped to `[0, 1]` (no tone mapping, exposure 1) with an 11×11 Gaussian window
//! of σ = 1.5 px; LDR-FLIP of the clamped sRGB image at 67 pixels per degree.
//!
//! A run is reproducible for a seed up to where the time budget cuts it: the iterations it
//! completes are those of a render with `--iterations NI` and the same seed.

pub mod config;
pub mod report;
pub mod results;

pub use results::{budget_label, BenchRow, Header, PhotonRates, RunKind, RunResult};

use crate::backends::{self, BackendOptions};
use crate::metrics::{self, PixelRect};
use crate::scene_file::load_scene;
use crate::session::{Budget, CheckpointRow, Checkpoints, Hooks, Reference, SessionOptions, auto_smoothing, render_with};
use arpa_core::propagate::classify::AutoSmoothing;
pub use config::BenchMethod;
use anyhow::{Context, bail};
use arpa_core::propagate::classify::Smoothing;
use arpa_core::accumulate::radius::RadiusSpec;
use arpa_core::render::tracer::{Image, Method, RenderSettings, StageTimes};
use config::{LoadedConfig, SceneEntry};
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

fn command_output(cmd: &str, args: &[&str]) -> Option<String> {
    let out = std::process::Command::new(cmd).args(args).output().ok()?;
    out.status.success().then(|| String::from_utf8_lossy(&out.stdout).trim().to_string()).filter(|s| !s.is_empty())
}

fn cpu_model() -> String {
    std::fs::read_to_string("/proc/cpuinfo")
        .ok()
        .and_then(|s| s.lines().find(|l| l.starts_with("model name")).and_then(|l| l.split_once(':')).map(|(_, v)| v.trim().to_string()))
        .unwrap_or_else(|| "unknown CPU".into())
}

/// Options of `arpa bench` besides the config.
#[derive(Clone, Debug)]
pub struct BenchOptions {
    /// Output directory.
    pub out: PathBuf,
    /// Overrides the config's seconds per run.
    pub seconds: Option<f64>,
    /// Overrides the config's seed.
    pub seed: Option<u32>,
    /// Python interpreter for the peers.
    pub python: String,
    /// Photon emission of every arpa run (projection on by default).
    pub emission: arpa_core::render::tracer::EmissionStrategy,
    /// Run the config's peers (off: only our runs, e.g. a second sweep with other
    /// emission settings).
    pub peers: bool,
}

/// Sums what one arpa run's checkpoints need into [`BenchRow`]s.
struct RowHooks<'a> {
    reference_mean: f64,
    bench_scene: &'a PreparedBenchScene,
    scene: &'a str,
    kind: &'a RunKind,
    rows: Vec<BenchRow>,
}

impl Hooks for RowHooks<'_> {
    fn checkpoint(&mut self, row: &CheckpointRow, image: &Image) -> anyhow::Result<()> {
        let m = row.metrics.context("a bench checkpoint without metrics")?;
        self.rows.push(BenchRow {
            scene: self.scene.to_string(),
            kind: self.kind.clone(),
            iteration: row.iteration,
            seconds: row.seconds,
            rel_mse: m.rel_mse,
            ssim: m.ssim,
            flip: m.flip,
            mean_ratio: metrics::mean(image) / self.reference_mean,
            times: row.times,
            device_times: row.device_times,
            candidates_per_query: row.candidates_per_query,
            contributions_per_query: row.contributions_per_query,
            region_rel_mse: self.bench_scene.region_rel_mse(image)?,
            scale_share: row.scale_share,
            photons: Some(PhotonRates::of(row)),
        });
        Ok(())
    }
}

/// A scene of the sweep, loaded at the sweep's resolution, with its reference at the same.
struct PreparedBenchScene {
    entry: SceneEntry,
    /// The scene file.
    file: PathBuf,
    scene: arpa_core::render::scene::Scene,
    max_depth: Option<u32>,
    reference: Reference,
    /// The caustic region at the sweep's resolution.
    region: Option<PixelRect>,
}

impl PreparedBenchScene {
    /// relMSE of `image` inside the caustic region, if the scene has one.
    fn region_rel_mse(&self, image: &Image) -> anyhow::Result<Option<f64>> {
        let Some(rect) = self.region else { return Ok(None) };
        let image = self.reference.at_reference_size(image)?;
        metrics::check_sizes(image.width, image.height, self.reference.image.width, self.reference.image.height)?;
        let e = metrics::rel_mse_in(&image.pixels, &self.reference.image.pixels, image.width, image.height, rect)
            .with_context(|| format!("caustic region of scene '{}' against reference '{}'", self.entry.name, self.reference.path.display()))?;
        Ok(Some(e))
    }
}

fn prepare_scene(cfg: &LoadedConfig, entry: &SceneEntry) -> anyhow::Result<PreparedBenchScene> {
    let dir = cfg.scene_dir(entry);
    let file = dir.join(&entry.file);
    let mut loaded = load_scene(&file, &[]).with_context(|| format!("cannot load scene file '{}'", file.display()))?;
    let ref_path = dir.join(&entry.reference);
    let full = crate::image_io::read_exr(&ref_path).with_context(|| format!("cannot read reference image '{}'", ref_path.display()))?;
    let (k, up) = (cfg.config.downscale, cfg.config.upscale);
    let image = metrics::downsample(&full, k).map_err(|e| anyhow::anyhow!("reference '{}': {e}", ref_path.display()))?;
    let (width, height) = match (image.width.checked_mul(up), image.height.checked_mul(up)) {
        (Some(w), Some(h)) => (w, h),
        _ => bail!("bench config '{}': upscale {up} of scene '{}' overflows the film size", cfg.path.display(), entry.name),
    };
    loaded.set_resolution(width, height);
    if (width, height) != (loaded.scene.camera.width, loaded.scene.camera.height) {
        bail!("reference '{}' does not match the scene's film", ref_path.display());
    }
    loaded.scene.validate().with_context(|| format!("scene file '{}' is invalid", file.display()))?;
    let region = match entry.region() {
        Some(r) if !r.fits(full.width, full.height) => {
            bail!("bench config '{}': scene '{}': caustic_region {r} does not lie within the {}x{} film (reference '{}')", cfg.path.display(), entry.name, full.width, full.height, ref_path.display())
        }
        r => r.map(|r| r.downscaled(k)),
    };
    Ok(PreparedBenchScene { entry: entry.clone(), file, scene: loaded.scene, max_depth: loaded.max_depth, reference: Reference { image, path: ref_path, scale: up }, region })
}

fn settings_for(s: &PreparedBenchScene, method: Method, photons: u32, seed: u32) -> RenderSettings {
    let d = RenderSettings::default();
    let e = &s.entry;
    RenderSettings {
        method,
        photons_per_iteration: photons,
        seed,
        // Mitsuba's max_depth counts segments; the core counts surface interactions.
        max_depth: s.max_depth.map_or(d.max_depth, |m| m.saturating_sub(1).clamp(1, 1024)),
        smoothing: Smoothing { caustic: e.smoothing_caustic.unwrap_or(d.smoothing.caustic), global: e.smoothing_global.unwrap_or(d.smoothing.global) },
        radii: arpa_core::accumulate::radius::ProgressiveConfig {
            caustic: e.radius_caustic.map_or(d.radii.caustic, RadiusSpec::Absolute),
            global: e.radius_global.map_or(d.radii.global, RadiusSpec::Absolute),
            ..d.radii
        },
        ..d
    }
}

/// Runs the whole sweep of `cfg` and writes every output into `options.out`. Progress (one
/// line per run with the ETA of the sweep) goes to stderr.
pub fn run_bench(cfg: &LoadedConfig, options: &BenchOptions) -> anyhow::Result<Vec<RunResult>> {
    let c = &cfg.config;
    let seconds = options.seconds.unwrap_or(c.seconds);
    if !(seconds.is_finite() && seconds > 0.0) {
        bail!("--seconds must be positive (got {seconds})");
    }
    let threads = c.threads.unwrap_or_else(|| std::thread::available_parallelism().map_or(1, |n| n.get()));
    // Pin the CPU backend's thread pool for the whole sweep (the peers get the same count).
    if let Err(e) = rayon::ThreadPoolBuilder::new().num_threads(threads).build_global()
        && rayon::current_num_threads() != threads
    {
        bail!("cannot pin the thread pool to {threads} threads: {e}");
    }
    std::fs::create_dir_all(&options.out).with_context(|| format!("cannot create output directory '{}'", options.out.display()))?;

    let mut tracers = Vec::new();
    let mut devices = Vec::new();
    for &kind in &cfg.backends {
        let t = backends::create(kind, &BackendOptions::default())?;
        devices.push(format!("{kind}: {}", t.capabilities().device));
        tracers.push((kind, t));
    }
    let header = Header {
        name: c.name.clone(),
        machine: format!("{} ({})", command_output("hostname", &[]).unwrap_or_else(|| "unknown host".into()), std::env::consts::OS),
        cpu: cpu_model(),
        threads,
        devices,
        commit: command_output("git", &["-C", env!("CARGO_MANIFEST_DIR"), "describe", "--always", "--dirty", "--abbrev=12"]).unwrap_or_else(|| "unknown".into()),
        config_hash: cfg.hash.clone(),
        seconds,
        emission: options.emission,
    };

    let per_scene = cfg.backends.len() * cfg.methods.len() * c.photons.len() + if options.peers { c.peers.len() } else { 0 };
    let total_runs = per_scene * c.scenes.len();
    let started = Instant::now();
    let mut done = 0usize;
    let mut results = Vec::new();
    let mut progress = |label: &str, note: &str| {
        done += 1;
        let elapsed = started.elapsed().as_secs_f64();
        let eta = elapsed / done as f64 * (total_runs - done) as f64;
        eprintln!("[{done}/{total_runs}] {label}: {note}  (elapsed {elapsed:.0} s, ETA {eta:.0} s)");
    };
    // Every scene, reference and caustic region is loaded and checked before the first run,
    // so a mistake in the config costs no render time.
    let scenes = c.scenes.iter().map(|entry| prepare_scene(cfg, entry)).collect::<anyhow::Result<Vec<_>>>()?;
    for (entry, scene) in c.scenes.iter().zip(&scenes) {
        let reference_mean = metrics::mean(&scene.reference.image);
        for (kind_backend, tracer) in tracers.iter_mut() {
            for &method in &cfg.methods {
                for &photons in &c.photons {
                    let kind = RunKind::Arpa { backend: kind_backend.name().to_string(), method, photons };
                    let mut settings = settings_for(scene, method.method(), photons, options.seed.unwrap_or(c.seed));
                    settings.emission = options.emission;
                    settings.bandwidth = method.bandwidth();
                    let mut budget = Duration::from_secs_f64(seconds);
                    let mut pilot_note = String::new();
                    if method.auto_smoothing() {
                        // The pilot iteration's time comes out of the run's budget.
                        let pilot = auto_smoothing(tracer, &scene.scene, &settings, &AutoSmoothing::default()).with_context(|| format!("{} {}", entry.name, kind.label()))?;
                        settings.smoothing = pilot.smoothing;
                        budget = budget.saturating_sub(pilot.time);
                        pilot_note = format!(" (pilot: overlap {:.2}/{:.2} at S = 1, S_c {:.3}, S_g {:.3})", pilot.overlap_at_one[0], pilot.overlap_at_one[1], pilot.smoothing.caustic, pilot.smoothing.global);
                    }
                    let mut hooks = RowHooks { reference_mean, bench_scene: scene, scene: &entry.name, kind: &kind, rows: Vec::new() };
                    let session = SessionOptions { budget: Budget::Time(budget), checkpoints: Checkpoints::PowersOfTwo, reference: Some(&scene.reference), resume: None, save: None, continued: false };
                    let rendered = render_with(tracer, &scene.scene, &settings, &session, &mut hooks).with_context(|| format!("{} {}", entry.name, kind.label()))?;
                    // At the reference's size (box-averaged when the sweep renders larger).
                    let image = scene.reference.at_reference_size(&rendered.image)?;
                    report::write_run_images(&options.out, &entry.name, &kind, &image, &scene.reference.image)?;
                    let last = hooks.rows.last().map_or(String::new(), |r| format!("NI {} relMSE {:.4e} SSIM {:.3}{pilot_note}", r.iteration, r.rel_mse, r.ssim));
                    progress(&format!("{} {} ({kind_backend})", entry.name, kind.label()), &last);
                    let rows = hooks.rows;
                    results.push(RunResult { scene: entry.name.clone(), kind, rows, skipped: None });
                }
            }
        }
        for integrator in c.peers.iter().filter(|_| options.peers) {
            let kind = RunKind::Peer { integrator: integrator.clone() };
            let result = run_peer(cfg, scene, &kind, integrator, seconds, threads, options, reference_mean)?;
            let note = match (&result.skipped, result.last()) {
                (Some(why), _) => format!("SKIPPED: {why}"),
                (None, Some(r)) => format!("passes {} relMSE {:.4e} SSIM {:.3}", r.iteration, r.rel_mse, r.ssim),
                (None, None) => "no image".into(),
            };
            progress(&format!("{} {}", entry.name, kind.label()), &note);
            results.push(result);
        }
    }
    report::write_all(&options.out, &header, cfg, &results)?;
    Ok(results)
}

/// JSON line of `scripts/peer_mitsuba.py`.
#[derive(serde::Deserialize)]
struct PeerLine {
    event: String,
    #[serde(default)]
    pass: u32,
    #[serde(default)]
    seconds: f64,
    #[serde(default)]
    file: Option<PathBuf>,
    #[serde(default)]
    reason: Option<String>,
}

/// Runs a Mitsuba peer through `scripts/peer_mitsuba.py` and evaluates its checkpoints. A
/// peer that is not installed is a skipped run, not an error.
#[allow(clippy::too_many_arguments)]
fn run_peer(
    cfg: &LoadedConfig,
    scene: &PreparedBenchScene,
    kind: &RunKind,
    integrator: &str,
    seconds: f64,
    threads: usize,
    options: &BenchOptions,
    reference_mean: f64,
) -> anyhow::Result<RunResult> {
    let name = &scene.entry.name;
    let skipped = |why: String| Ok(RunResult { scene: name.clone(), kind: kind.clone(), rows: Vec::new(), skipped: Some(why) });
    let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("scripts/peer_mitsuba.py");
    let work = options.out.join("peers").join(format!("{name}-{}", kind.stem()));
    let camera = &scene.scene.camera;
    let out = std::process::Command::new(&options.python)
        .arg(&script)
        .args(["--scene", &scene.file.to_string_lossy()])
        .args(["--integrator", integrator, "--seconds", &seconds.to_string(), "--threads", &threads.to_string()])
        .args(["--res", &format!("{}x{}", camera.width, camera.height), "--seed", &options.seed.unwrap_or(cfg.config.seed).to_string()])
        .arg("--out-dir")
        .arg(&work)
        .output();
    let out = match out {
        Ok(o) => o,
        Err(e) => return skipped(format!("cannot run '{}': {e}", options.python)),
    };
    let mut rows = Vec::new();
    let mut last_image = None;
    for line in String::from_utf8_lossy(&out.stdout).lines() {
        let Ok(l) = serde_json::from_str::<PeerLine>(line) else { continue };
        match l.event.as_str() {
            "skipped" => return skipped(l.reason.unwrap_or_else(|| "peer unavailable".into())),
            "checkpoint" | "done" => {
                if rows.last().is_some_and(|r: &BenchRow| r.iteration == l.pass) {
                    continue;
                }
                let file = l.file.context("peer checkpoint without a file")?;
                let image = crate::image_io::read_exr(&file).with_context(|| format!("cannot read peer image '{}'", file.display()))?;
                let m = scene.reference.compare(&image)?;
                rows.push(BenchRow {
                    scene: name.clone(),
                    kind: kind.clone(),
                    iteration: l.pass,
                    seconds: l.seconds,
                    rel_mse: m.rel_mse,
                    ssim: m.ssim,
                    flip: m.flip,
                    mean_ratio: metrics::mean(&image) / reference_mean,
                    times: StageTimes::default(),
                    device_times: arpa_core::render::tracer::DeviceTimes::Host,
                    candidates_per_query: [0.0; 2],
                    contributions_per_query: [0.0; 2],
                    scale_share: None,
                    region_rel_mse: scene.region_rel_mse(&image)?,
                    photons: None,
                });
                last_image = Some(image);
            }
            _ => {}
        }
    }
    if !out.status.success() && out.status.code() != Some(3) {
        bail!("peer {} on {name} failed: {}", kind.label(), String::from_utf8_lossy(&out.stderr).lines().last().unwrap_or("no message"));
    }
    let Some(image) = last_image else {
        return skipped(format!("the peer wrote no image ({})", String::from_utf8_lossy(&out.stderr).lines().last().unwrap_or("no message")));
    };
    report::write_run_images(&options.out, name, kind, &*scene.reference.at_reference_size(&image)?, &scene.reference.image)?;
    Ok(RunResult { scene: name.clone(), kind: kind.clone(), rows, skipped: None })
}
