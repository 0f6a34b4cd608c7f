//! The render loop as a library: upload a scene to any [`Tracer`], run iterations within a
//! [`Budget`], and at [`Checkpoints`] read the image back and compare it with an optional
//! [`Reference`]. [`render_with`] returns the image, the summed statistics and one
//! [`CheckpointRow`] per checkpoint (iteration, seconds, stage times, metrics); it prints
//! nothing. Callers that want to show progress (the CLI's bar, its metrics lines and CSV)
//! implement [`Hooks`].
//!
//! Time accounting: [`Rendered::render_time`] and [`CheckpointRow::seconds`] count the
//! iterations only; reading images back at checkpoints, the metrics and the hooks' own
//! work are excluded, also from a [`Budget::Time`].

use crate::image_io;
use crate::metrics::{Metrics, compare_images};
use crate::state_file::{RenderIdentity, StateFile};
use anyhow::{Context, bail};
use arpa_core::accumulate::image::Accumulation;
use arpa_core::accumulate::radius::{ProgressiveConfig, RadiusSpec};
use arpa_core::propagate::classify::{AutoSmoothing, Smoothing};
use arpa_core::render::scene::Scene;
use arpa_core::render::tracer::{Capabilities, DeviceTimes, Image, IterationStats, RenderSettings, StageTimes, Tracer};
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

/// How long to render.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Budget {
    /// Exactly this many iterations.
    Iterations(u32),
    /// Iterations until this much wall-clock time has passed (at least one).
    Time(Duration),
}

/// Default number of iterations of a render given neither an iteration count nor a time.
pub const DEFAULT_ITERATIONS: u32 = 64;

/// Default maximum number of surface interactions when neither the caller nor the scene
/// file gives one.
pub const DEFAULT_MAX_DEPTH: u32 = 10;

/// The render settings a user chooses, as the CLI (`arpa render`) and the Python package
/// take them; [`RenderOptions::settings`] turns them into [`RenderSettings`], so both give
/// the same settings (and the same image) for the same choices.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RenderOptions {
    /// Density-estimation method.
    pub method: arpa_core::render::tracer::Method,
    /// Photons emitted per iteration.
    pub photons: u32,
    /// Seed of every random stream.
    pub seed: u32,
    /// Maximum number of surface interactions; `None`: the scene file's integrator
    /// `max_depth` minus one, or [`DEFAULT_MAX_DEPTH`].
    pub max_depth: Option<u32>,
    /// Next-event estimation.
    pub direct_lighting: bool,
    /// Projection maps and the caustic pass.
    pub emission: arpa_core::render::tracer::EmissionStrategy,
    /// Per-pixel or global bandwidth.
    pub bandwidth: arpa_core::gather::scales::Bandwidth,
    /// Fixed smoothing factors (the starting point of [`auto_smoothing`] when chosen
    /// automatically).
    pub smoothing: Smoothing,
    /// Initial caustic radius of the progressive photons; `None`: the core's default.
    pub radius_caustic: Option<f64>,
    /// Initial global radius of the progressive photons; `None`: the core's default.
    pub radius_global: Option<f64>,
}

impl Default for RenderOptions {
    /// The CLI's defaults: ARPA, 250k photons, seed 0, next-event estimation, projection
    /// maps, per-pixel bandwidth, `S = 1`.
    fn default() -> Self {
        RenderOptions {
            method: arpa_core::render::tracer::Method::Arpa,
            photons: 250_000,
            seed: 0,
            max_depth: None,
            direct_lighting: true,
            emission: arpa_core::render::tracer::EmissionStrategy::default(),
            bandwidth: arpa_core::gather::scales::Bandwidth::PerPixel,
            smoothing: Smoothing { caustic: 1.0, global: 1.0 },
            radius_caustic: None,
            radius_global: None,
        }
    }
}

impl RenderOptions {
    /// The settings for a scene whose file asks for `file_max_depth` (Mitsuba's path depth
    /// in segments): without [`RenderOptions::max_depth`], photon and camera paths get
    /// `max_depth - 1` surface interactions (at least 1), else [`DEFAULT_MAX_DEPTH`].
    pub fn settings(&self, file_max_depth: Option<u32>) -> RenderSettings {
        let defaults = RenderSettings::default();
        let max_depth = match (self.max_depth, file_max_depth) {
            (Some(d), _) => d,
            (None, Some(d)) => d.saturating_sub(1).clamp(1, 1024),
            (None, None) => DEFAULT_MAX_DEPTH,
        };
        RenderSettings {
            method: self.method,
            photons_per_iteration: self.photons,
            seed: self.seed,
            max_depth,
            direct_lighting: self.direct_lighting,
            emission: self.emission,
            bandwidth: self.bandwidth,
            smoothing: self.smoothing,
            radii: ProgressiveConfig {
                caustic: self.radius_caustic.map_or(defaults.radii.caustic, RadiusSpec::Absolute),
                global: self.radius_global.map_or(defaults.radii.global, RadiusSpec::Absolute),
                ..defaults.radii
            },
            ..defaults
        }
    }
}

/// When to evaluate intermediate images (the final image is always evaluated).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Checkpoints {
    /// Never (only the final image).
    Never,
    /// At iterations 1, 2, 4, 8, ...
    PowersOfTwo,
    /// At every multiple of N.
    Every(u32),
}

impl Checkpoints {
    /// Whether `iteration` (1-based) is a checkpoint.
    pub fn contains(self, iteration: u32) -> bool {
        match self {
            Checkpoints::Never => false,
            Checkpoints::PowersOfTwo => iteration.is_power_of_two(),
            Checkpoints::Every(n) => n > 0 && iteration.is_multiple_of(n),
        }
    }
}

/// Sums of the per-iteration statistics.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct StatTotals {
    /// Iterations summed.
    pub iterations: u32,
    /// Counts and stage times summed over those iterations.
    pub sum: IterationStats,
}

impl StatTotals {
    /// Adds one iteration's statistics.
    pub fn add(&mut self, s: &IterationStats) {
        self.iterations += 1;
        self.sum.accumulate(s);
    }

    /// Per-iteration mean of a count.
    pub fn mean(&self, total: u64) -> f64 {
        total as f64 / self.iterations.max(1) as f64
    }

    /// Per-iteration mean time of each stage (seconds).
    pub fn mean_times(&self) -> StageTimes {
        let n = self.iterations.max(1) as f64;
        let t = &self.sum.times;
        StageTimes { camera: t.camera / n, photon: t.photon / n, build: t.build / n, gather: t.gather / n, accumulate: t.accumulate / n }
    }

    /// Per-iteration mean device time of each stage (seconds): measured only when every
    /// iteration summed was ([`DeviceTimes::accumulate`]).
    pub fn mean_device_times(&self) -> DeviceTimes {
        match self.sum.device_times {
            DeviceTimes::Measured(t) => DeviceTimes::Measured(t.per(self.iterations)),
            d => d,
        }
    }
}

/// An independent reference image the checkpoints are compared with.
#[derive(Clone, Debug)]
pub struct Reference {
    /// The reference (linear radiance).
    pub image: Image,
    /// Where it was read from (for messages).
    pub path: PathBuf,
    /// The render's size over the reference's (1: the same size): a render `scale` times
    /// larger is box-averaged `scale × scale` before it is compared.
    pub scale: u32,
}

impl Reference {
    /// Reads an OpenEXR reference, which must be `width`×`height` pixels (the render's size).
    pub fn load(path: &Path, width: u32, height: u32) -> anyhow::Result<Self> {
        let image = image_io::read_exr(path).with_context(|| format!("cannot read reference image '{}'", path.display()))?;
        if (image.width, image.height) != (width, height) {
            bail!(
                "reference image '{}' is {}x{} pixels but the render is {}x{}; render at --resolution {}x{} or use a matching reference",
                path.display(),
                image.width,
                image.height,
                width,
                height,
                image.width,
                image.height
            );
        }
        Ok(Self { image, path: path.to_path_buf(), scale: 1 })
    }

    /// `image` at the reference's size: box-averaged [`Reference::scale`]` × scale`
    /// (borrowed as it is at scale 1).
    pub fn at_reference_size<'a>(&self, image: &'a Image) -> anyhow::Result<std::borrow::Cow<'a, Image>> {
        if self.scale <= 1 {
            return Ok(std::borrow::Cow::Borrowed(image));
        }
        crate::metrics::downsample(image, self.scale).map(std::borrow::Cow::Owned).map_err(|e| anyhow::anyhow!("render for reference '{}': {e}", self.path.display()))
    }

    /// relMSE, SSIM and FLIP of `image` (at the reference's size, [`Reference::at_reference_size`])
    /// against the reference.
    pub fn compare(&self, image: &Image) -> anyhow::Result<Metrics> {
        let image = self.at_reference_size(image)?;
        compare_images(&image, &self.image).with_context(|| format!("cannot compare with reference '{}'", self.path.display()))
    }
}

/// The state of the render at one checkpoint.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct CheckpointRow {
    /// Iterations accumulated.
    pub iteration: u32,
    /// Render time up to this iteration (seconds), excluding checkpoints.
    pub seconds: f64,
    /// Mean time per iteration of each stage so far (seconds, host wall clock).
    pub times: StageTimes,
    /// Mean device time per iteration of each stage so far ([`StatTotals::mean_device_times`]).
    pub device_times: DeviceTimes,
    /// Metrics against the [`Reference`], when there is one.
    pub metrics: Option<Metrics>,
    /// Gather candidates per valid query point so far, `[caustic, global]`
    /// ([`IterationStats::candidates`]).
    pub candidates_per_query: [f64; 2],
    /// Gather contributions per valid query point so far, `[caustic, global]`.
    pub contributions_per_query: [f64; 2],
    /// Records stored per photon emitted so far, `[caustic, global]` map
    /// ([`IterationStats::records_per_photon`] of the sums).
    pub records_per_photon: [f64; 2],
    /// Mean photons emitted per iteration so far, `[caustic pass, global pass]`
    /// ([`IterationStats::emitted`]).
    pub emitted_per_iteration: [f64; 2],
    /// Records stored so far (footprints and progressive photons), `[caustic, global]` map.
    pub records: [u64; 2],
    /// With a per-pixel bandwidth ([`arpa_core::accumulate::bandwidth`]): the share of the pixels
    /// using each scale of the ladder (index 0 = the stored footprints), a pixel between
    /// two scales split by its blend weights; `None` with a global bandwidth.
    pub scale_share: Option<[f64; arpa_core::gather::scales::SCALES]>,
}

/// The share of pixels per scale of a per-pixel selection's fractional scale indices
/// (each pixel split between the two scales it blends, by their weights).
pub fn scale_share(scale: &[f32]) -> [f64; arpa_core::gather::scales::SCALES] {
    let mut share = [0.0; arpa_core::gather::scales::SCALES];
    let top = (arpa_core::gather::scales::SCALES - 1) as f64;
    for &c in scale {
        let c = f64::from(c).clamp(0.0, top);
        let k = (c as usize).min(arpa_core::gather::scales::SCALES - 2);
        let t = c - k as f64;
        share[k] += 1.0 - t;
        share[k + 1] += t;
    }
    let n = scale.len().max(1) as f64;
    share.map(|s| s / n)
}

/// What a render produced.
#[derive(Clone, Debug)]
pub struct Rendered {
    /// The accumulated image.
    pub image: Image,
    /// Iterations run by this call (those of a resumed accumulation are not counted).
    pub iterations: u32,
    /// Summed statistics.
    pub totals: StatTotals,
    /// Statistics of the last iteration.
    pub last: IterationStats,
    /// The backend's capabilities.
    pub capabilities: Capabilities,
    /// One row per checkpoint, the last one for the final image.
    pub rows: Vec<CheckpointRow>,
    /// Wall-clock time of the iterations (excluding upload, read-back and checkpoints).
    pub render_time: Duration,
    /// Wall-clock time spent in checkpoints (read-backs, metrics and [`Hooks::checkpoint`]).
    pub checkpoint_time: Duration,
    /// Wall-clock time of upload, iterations and read-back.
    pub total_time: Duration,
    /// Whether [`Hooks::stop`] ended the render before its budget was spent (the image is
    /// then that of the iterations done, and the state file, if any, holds them).
    pub stopped: bool,
}

/// What a render looks at besides the scene and settings.
#[derive(Clone, Copy, Debug)]
pub struct SessionOptions<'a> {
    /// How long to render. [`Budget::Iterations`] counts iteration indices: with
    /// [`SessionOptions::resume`], the render stops at iteration `n` of the whole render.
    pub budget: Budget,
    /// When to read the image back and make a [`CheckpointRow`].
    pub checkpoints: Checkpoints,
    /// What to compare the checkpoints with.
    pub reference: Option<&'a Reference>,
    /// An accumulation to continue, restored after the upload: a resumed state file, or an
    /// empty accumulation starting at the first iteration of a partial render.
    pub resume: Option<&'a Accumulation>,
    /// Where and how often to write the render's state ([`StateFile`]); it is also written
    /// once at the end.
    pub save: Option<SaveState<'a>>,
    /// The tracer already holds `scene` with `settings` and the accumulation of an earlier
    /// [`render_with`] on it: render on from its iteration without uploading again (for
    /// progressive use, e.g. the Python package's `Renderer.step`). [`SessionOptions::resume`]
    /// must then be `None`.
    pub continued: bool,
}

impl SessionOptions<'_> {
    /// `budget`, no intermediate checkpoints, no reference, a fresh accumulation, no state
    /// file, a fresh upload.
    pub fn budget(budget: Budget) -> Self {
        SessionOptions { budget, checkpoints: Checkpoints::Never, reference: None, resume: None, save: None, continued: false }
    }
}

/// How often the state is saved.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum SaveEvery {
    /// After every `n` iterations.
    Iterations(u32),
    /// After the first iteration that ends at least this long after the last save.
    Time(Duration),
}

/// Where a render saves its state, and how often.
#[derive(Clone, Copy, Debug)]
pub struct SaveState<'a> {
    /// The state file, replaced atomically at each save.
    pub path: &'a Path,
    /// How often.
    pub every: SaveEvery,
    /// The render the state belongs to (written into the file).
    pub identity: &'a RenderIdentity,
}

impl SaveState<'_> {
    /// Reads the accumulation from `tracer` and writes it atomically.
    fn write<T: Tracer>(&self, tracer: &T) -> anyhow::Result<()> {
        let accumulation = tracer.read_accumulation().context("cannot read the accumulation back")?;
        StateFile { identity: self.identity.clone(), accumulation }.write_atomic(self.path)?;
        Ok(())
    }
}

/// Callbacks of [`render_with`], for progress display and cancellation. All default to
/// doing nothing.
pub trait Hooks {
    /// Asked before each iteration: `true` ends the render there as if its budget were
    /// spent (the image so far is read back and returned, the state file written), with
    /// [`Rendered::stopped`] set. For cancellation, e.g. Ctrl-C in the Python package.
    fn stop(&mut self) -> bool {
        false
    }

    /// After each iteration: iterations done, render time so far, the sums so far.
    fn iteration(&mut self, _iterations: u32, _render_time: Duration, _totals: &StatTotals) {}

    /// At each checkpoint (and once for the final image), with the image read back. Its
    /// time is excluded from the render time.
    fn checkpoint(&mut self, _row: &CheckpointRow, _image: &Image) -> anyhow::Result<()> {
        Ok(())
    }
}

/// [`Hooks`] that do nothing.
pub struct NoHooks;

impl Hooks for NoHooks {}

/// Uploads `scene` to `tracer` and runs iterations within `budget`; returns the image and
/// statistics. Backend errors are returned with the stage and iteration that failed.
pub fn render<T: Tracer>(tracer: &mut T, scene: &Scene, settings: &RenderSettings, budget: Budget) -> anyhow::Result<Rendered> {
    render_with(tracer, scene, settings, &SessionOptions::budget(budget), &mut NoHooks)
}

/// What the pilot of [`auto_smoothing`] measured and chose.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SmoothingPilot {
    /// The chosen `S_c`, `S_g`.
    pub smoothing: Smoothing,
    /// Overlap per map at `S = 1` (contributions per covered query point,
    /// [`IterationStats::overlap`]).
    pub overlap_at_one: [f64; 2],
    /// The pilot's wall-clock time (upload and one iteration).
    pub time: Duration,
}

/// Automatic smoothing ([`AutoSmoothing`]): uploads `scene` with `settings` at `S = 1`,
/// renders iteration 0 as a pilot, and returns the smoothing `auto` chooses from its
/// overlap. The pilot is deterministic (the same seed, iteration and backend give the same
/// choice), so a resumed render or a part of a distributed one chooses the same `S`. The
/// caller renders with the result in `settings.smoothing` ([`render_with`] uploads again
/// and starts afresh). RTPM has no footprints: its settings come back unchanged.
pub fn auto_smoothing<T: Tracer>(tracer: &mut T, scene: &Scene, settings: &RenderSettings, auto: &AutoSmoothing) -> anyhow::Result<SmoothingPilot> {
    let start = Instant::now();
    if settings.method != arpa_core::render::tracer::Method::Arpa {
        return Ok(SmoothingPilot { smoothing: settings.smoothing, overlap_at_one: [0.0; 2], time: start.elapsed() });
    }
    let capabilities = tracer.capabilities();
    // The pilot only measures the stored scale's overlap: one plane is enough.
    let pilot = RenderSettings { smoothing: Smoothing { caustic: 1.0, global: 1.0 }, bandwidth: arpa_core::gather::scales::Bandwidth::Global, ..*settings };
    tracer.upload_scene(scene, &pilot).with_context(|| format!("backend '{}' could not load the scene for the smoothing pilot", capabilities.backend))?;
    tracer.iterate().with_context(|| format!("backend '{}' failed in the smoothing pilot", capabilities.backend))?;
    let stats = tracer.read_stats().context("cannot read the smoothing pilot's statistics")?;
    let overlap_at_one = stats.overlap();
    let smoothing = auto.for_bandwidth(settings.bandwidth).resolve(overlap_at_one, settings.heuristics.dampening.as_ref());
    Ok(SmoothingPilot { smoothing, overlap_at_one, time: start.elapsed() })
}

fn read_checked<T: Tracer>(tracer: &T, capabilities: &Capabilities) -> anyhow::Result<Image> {
    let image = tracer.read_image().context("cannot read back the image")?;
    let expected = image.width as u64 * image.height as u64;
    if image.pixels.len() as u64 != expected {
        bail!("backend '{}' returned a {}x{} image with {} pixels", capabilities.backend, image.width, image.height, image.pixels.len());
    }
    Ok(image)
}

/// [`render`] with checkpoints, a reference and hooks: at each checkpoint (and for the final
/// image) the image is read back, compared with the reference and handed to
/// [`Hooks::checkpoint`], and a [`CheckpointRow`] is kept.
pub fn render_with<T: Tracer, H: Hooks + ?Sized>(
    tracer: &mut T,
    scene: &Scene,
    settings: &RenderSettings,
    options: &SessionOptions<'_>,
    hooks: &mut H,
) -> anyhow::Result<Rendered> {
    let start = Instant::now();
    let capabilities = tracer.capabilities();
    if !capabilities.methods.contains(&settings.method) {
        bail!("backend '{}' does not implement method '{}'", capabilities.backend, settings.method.name());
    }
    if let Some(max) = capabilities.max_photons_per_iteration
        && settings.photons_per_iteration > max
    {
        bail!("backend '{}' accepts at most {max} photons per iteration, {} requested", capabilities.backend, settings.photons_per_iteration);
    }
    if options.continued {
        if options.resume.is_some() {
            bail!("a continued render cannot also resume a state (the tracer already holds its accumulation)");
        }
    } else {
        tracer.upload_scene(scene, settings).with_context(|| format!("backend '{}' could not load the scene", capabilities.backend))?;
    }
    if let Some(state) = options.resume {
        tracer
            .restore_accumulation(state)
            .with_context(|| format!("backend '{}' cannot continue the accumulation of iterations {}..{}", capabilities.backend, state.first_iteration, state.end()))?;
    }

    let render_start = Instant::now();
    let mut totals = StatTotals::default();
    let mut last = IterationStats::default();
    let mut rows = Vec::new();
    let mut iterations = 0u32;
    let mut checkpoint_time = Duration::ZERO;
    let mut stopped = false;
    let rendering = |checkpoint_time: Duration| render_start.elapsed().saturating_sub(checkpoint_time);
    // Reads the image back, evaluates it and hands it to the hooks; returns the image.
    let checkpoint = |tracer: &T, hooks: &mut H, i: u32, at: Duration, totals: &StatTotals, rows: &mut Vec<CheckpointRow>| -> anyhow::Result<Image> {
        let image = read_checked(tracer, &capabilities)?;
        let metrics = options.reference.map(|r| r.compare(&image)).transpose()?;
        let scale_share = if settings.bandwidth == arpa_core::gather::scales::Bandwidth::PerPixel {
            let accumulation = tracer.read_accumulation().context("cannot read the accumulation back")?;
            Some(scale_share(&accumulation.selection().scale))
        } else {
            None
        };
        let row = CheckpointRow {
            scale_share,
            iteration: i,
            seconds: at.as_secs_f64(),
            times: totals.mean_times(),
            device_times: totals.mean_device_times(),
            metrics,
            candidates_per_query: totals.sum.candidates_per_query(),
            contributions_per_query: totals.sum.contributions_per_query(),
            records_per_photon: totals.sum.records_per_photon(),
            emitted_per_iteration: totals.sum.emitted.map(|n| totals.mean(n)),
            records: [0, 1].map(|m| totals.sum.footprints[m] + totals.sum.progressive[m]),
        };
        hooks.checkpoint(&row, &image)?;
        rows.push(row);
        Ok(image)
    };
    let mut last_save = (tracer.iterations(), Instant::now());
    loop {
        let more = match options.budget {
            Budget::Iterations(n) => tracer.iterations() < n,
            Budget::Time(t) => iterations == 0 || rendering(checkpoint_time) < t,
        };
        if !more {
            break;
        }
        if hooks.stop() {
            stopped = true;
            break;
        }
        // The iteration's 1-based index in the whole render.
        let i = tracer.iterations() + 1;
        tracer.iterate().with_context(|| format!("iteration {i} failed"))?;
        last = tracer.read_stats().with_context(|| format!("cannot read the statistics of iteration {i}"))?;
        totals.add(&last);
        iterations += 1;
        let last_iteration = matches!(options.budget, Budget::Iterations(n) if i >= n);
        if options.checkpoints.contains(i) && !last_iteration {
            let at = rendering(checkpoint_time);
            let t0 = Instant::now();
            checkpoint(tracer, hooks, i, at, &totals, &mut rows)?;
            checkpoint_time += t0.elapsed();
        }
        if let Some(save) = &options.save {
            let due = match save.every {
                SaveEvery::Iterations(n) => i - last_save.0 >= n.max(1),
                SaveEvery::Time(t) => last_save.1.elapsed() >= t,
            };
            if due && !last_iteration {
                let t0 = Instant::now();
                save.write(tracer)?;
                last_save = (i, Instant::now());
                checkpoint_time += t0.elapsed();
            }
        }
        hooks.iteration(iterations, rendering(checkpoint_time), &totals);
    }
    let render_time = rendering(checkpoint_time);
    let end = tracer.iterations();
    let image = if rows.last().is_some_and(|r| r.iteration == end) {
        read_checked(tracer, &capabilities)?
    } else {
        let t0 = Instant::now();
        let image = checkpoint(tracer, hooks, end, render_time, &totals, &mut rows)?;
        checkpoint_time += t0.elapsed();
        image
    };
    if let Some(save) = &options.save {
        let t0 = Instant::now();
        save.write(tracer)?;
        checkpoint_time += t0.elapsed();
    }
    Ok(Rendered { image, iterations, totals, last, capabilities, rows, render_time, checkpoint_time, total_time: start.elapsed(), stopped })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::default_scene::default_scene;
    use arpa_core::accumulate::image::Accumulation;
    use arpa_core::store::footprint::PackedFootprint;
    use arpa_core::glam::Vec3;
    use arpa_core::store::progressive_photon::PackedPhoton;
    use arpa_core::render::tracer::{BackendKind, Method, QueryRecord};

    #[derive(Debug, thiserror::Error)]
    #[error("mock failure")]
    pub(crate) struct MockError;

    /// A backend that renders a constant grey and reports fixed counts.
    #[derive(Default)]
    pub(crate) struct Mock {
        pub size: (u32, u32),
        pub photons: u32,
        pub iterations: u32,
        pub fail_at: Option<u32>,
        pub sleep: Duration,
        pub first: u32,
    }

    impl Tracer for Mock {
        type Error = MockError;
        fn capabilities(&self) -> Capabilities {
            Capabilities { backend: BackendKind::Cpu, device: "test".into(), methods: vec![Method::Arpa], max_photons_per_iteration: None, deterministic: true }
        }
        fn upload_scene(&mut self, scene: &Scene, settings: &RenderSettings) -> Result<(), MockError> {
            self.size = (scene.camera.width, scene.camera.height);
            self.photons = settings.photons_per_iteration;
            (self.iterations, self.first) = (0, 0);
            Ok(())
        }
        fn camera_pass(&mut self) -> Result<(), MockError> {
            Ok(())
        }
        fn photon_pass(&mut self) -> Result<(), MockError> {
            std::thread::sleep(self.sleep);
            Ok(())
        }
        fn build_acceleration_structure(&mut self) -> Result<(), MockError> {
            Ok(())
        }
        fn gather(&mut self) -> Result<(), MockError> {
            if self.fail_at == Some(self.iterations + 1) { Err(MockError) } else { Ok(()) }
        }
        fn accumulate(&mut self) -> Result<(), MockError> {
            self.iterations += 1;
            Ok(())
        }
        fn iterations(&self) -> u32 {
            self.iterations
        }
        fn read_image(&self) -> Result<Image, MockError> {
            Ok(Image { width: self.size.0, height: self.size.1, pixels: vec![Vec3::splat(0.5); (self.size.0 * self.size.1) as usize] })
        }
        fn read_query_points(&self) -> Result<Vec<QueryRecord>, MockError> {
            Ok(vec![])
        }
        fn read_footprints(&self) -> Result<Vec<PackedFootprint>, MockError> {
            Ok(vec![])
        }
        fn read_photons(&self) -> Result<Vec<PackedPhoton>, MockError> {
            Ok(vec![])
        }
        fn read_accumulation(&self) -> Result<Accumulation, MockError> {
            let n = self.iterations - self.first;
            let mut a = Accumulation::empty(self.size.0, self.size.1, self.first);
            a.iterations = n;
            a.pixels.iter_mut().for_each(|p| p.sum = [0.5 * n as f64; 3]);
            Ok(a)
        }
        fn restore_accumulation(&mut self, state: &Accumulation) -> Result<(), MockError> {
            self.first = state.first_iteration;
            self.iterations = state.end() as u32;
            Ok(())
        }
        fn read_stats(&self) -> Result<IterationStats, MockError> {
            let mut s = IterationStats { iteration: self.iterations, photons_emitted: self.photons as u64, footprints: [10, 20], progressive: [1, 2], degenerate: 3, ..Default::default() };
            s.times.gather = 0.002;
            Ok(s)
        }
    }

    pub(crate) fn small_scene() -> Scene {
        let mut s = default_scene();
        s.camera.width = 8;
        s.camera.height = 4;
        s
    }

    #[test]
    fn renders_the_requested_iterations_and_sums_statistics() {
        let mut t = Mock::default();
        let settings = RenderSettings { photons_per_iteration: 1000, ..Default::default() };
        let r = render(&mut t, &small_scene(), &settings, Budget::Iterations(5)).unwrap();
        assert_eq!(r.iterations, 5);
        assert_eq!((r.image.width, r.image.height, r.image.pixels.len()), (8, 4, 32));
        assert_eq!(r.totals.sum.photons_emitted, 5000);
        assert_eq!(r.totals.sum.footprints, [50, 100]);
        assert_eq!(r.totals.mean(r.totals.sum.degenerate), 3.0);
        assert!((r.totals.sum.times.gather - 0.01).abs() < 1e-12);
        assert_eq!(r.rows.len(), 1, "the final image is a row");
        assert!((r.rows[0].times.gather - 0.002).abs() < 1e-12 && r.rows[0].metrics.is_none());
    }

    #[test]
    fn time_budget_runs_at_least_one_iteration_and_stops() {
        let mut t = Mock { sleep: Duration::from_millis(20), ..Default::default() };
        let r = render(&mut t, &small_scene(), &RenderSettings::default(), Budget::Time(Duration::from_millis(1))).unwrap();
        assert_eq!(r.iterations, 1);
        let mut t = Mock { sleep: Duration::from_millis(5), ..Default::default() };
        let r = render(&mut t, &small_scene(), &RenderSettings::default(), Budget::Time(Duration::from_millis(60))).unwrap();
        assert!(r.iterations >= 2 && r.iterations < 40, "{}", r.iterations);
    }

    #[test]
    fn backend_errors_name_the_iteration_and_unsupported_methods_fail() {
        let mut t = Mock { fail_at: Some(3), ..Default::default() };
        let e = render(&mut t, &small_scene(), &RenderSettings::default(), Budget::Iterations(5)).unwrap_err();
        assert_eq!(format!("{e:#}"), "iteration 3 failed: mock failure");
        let settings = RenderSettings { method: Method::Rtpm, ..Default::default() };
        let e = render(&mut Mock::default(), &small_scene(), &settings, Budget::Iterations(1)).unwrap_err();
        assert!(e.to_string().contains("does not implement method 'rtpm'"), "{e}");
    }

    struct Recorder(Vec<u32>);
    impl Hooks for Recorder {
        fn checkpoint(&mut self, row: &CheckpointRow, image: &Image) -> anyhow::Result<()> {
            assert_eq!(image.pixels.len(), 32);
            self.0.push(row.iteration);
            Ok(())
        }
    }

    #[test]
    fn checkpoints_at_powers_of_two_multiples_and_the_end() {
        let run = |checkpoints: Checkpoints, n: u32| {
            let mut rec = Recorder(vec![]);
            let options = SessionOptions { checkpoints, ..SessionOptions::budget(Budget::Iterations(n)) };
            let r = render_with(&mut Mock::default(), &small_scene(), &RenderSettings::default(), &options, &mut rec).unwrap();
            assert_eq!(r.iterations, n);
            assert_eq!(r.rows.iter().map(|r| r.iteration).collect::<Vec<_>>(), rec.0, "one row per checkpoint");
            rec.0
        };
        assert_eq!(run(Checkpoints::PowersOfTwo, 10), vec![1, 2, 4, 8, 10]);
        assert_eq!(run(Checkpoints::PowersOfTwo, 8), vec![1, 2, 4, 8]);
        assert_eq!(run(Checkpoints::Every(3), 7), vec![3, 6, 7]);
        assert_eq!(run(Checkpoints::Never, 5), vec![5]);
    }

    #[test]
    fn rows_carry_metrics_against_the_reference() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("ref.exr");
        image_io::write_exr(&path, &Image { width: 4, height: 2, pixels: vec![Vec3::ONE; 8] }).unwrap();
        let e = Reference::load(&path, 8, 4).err().unwrap();
        assert!(format!("{e:#}").contains("is 4x2 pixels but the render is 8x4"), "{e:#}");
        let grey = Reference { image: Image { width: 8, height: 4, pixels: vec![Vec3::splat(0.5); 32] }, path: path.clone(), scale: 1 };
        let double = Reference { image: Image { width: 8, height: 4, pixels: vec![Vec3::ONE; 32] }, path, scale: 1 };
        let options = SessionOptions { checkpoints: Checkpoints::Every(2), reference: Some(&grey), ..SessionOptions::budget(Budget::Iterations(3)) };
        let r = render_with(&mut Mock::default(), &small_scene(), &RenderSettings::default(), &options, &mut NoHooks).unwrap();
        assert_eq!(r.rows.len(), 2);
        assert!(r.rows.iter().all(|row| row.metrics.is_some_and(|m| m.rel_mse == 0.0)), "{:?}", r.rows);
        // The mock's 0.5 against 1.0: relMSE = (0.5)² / (1² + 0.01).
        let options = SessionOptions { reference: Some(&double), ..options };
        let r = render_with(&mut Mock::default(), &small_scene(), &RenderSettings::default(), &options, &mut NoHooks).unwrap();
        let m = r.rows[1].metrics.unwrap();
        assert!(m.rel_mse > 0.2 && m.rel_mse < 0.26, "{m:?}");
        assert!(r.rows[0].seconds <= r.rows[1].seconds);
    }
}
