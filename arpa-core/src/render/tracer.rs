//! The backend-agnostic [`Tracer`] trait that the CPU, wgpu and Vulkan backends implement,
//! with the settings, records and statistics that cross it.
//!
//! Designed for a GPU: the backend owns the scene, photon, footprint and image buffers;
//! [`Tracer::iterate`] runs the stages without host round trips; the host reads back only
//! through the explicit `read_*` calls (the image, and the stage outputs the conformance
//! suite inspects). Stages, in order:
//!
//! ```text
//! upload_scene -> camera_pass -> photon_pass -> build_acceleration_structure -> gather -> accumulate
//! ```

use crate::accumulate::image::Accumulation;
use crate::propagate::classify::Smoothing;
use crate::store::footprint::PackedFootprint;
use crate::store::heuristics::{DampenReference, Heuristics};
use crate::gather::kernel::Kernel;
use crate::store::progressive_photon::PackedPhoton;
use crate::accumulate::radius::{ProgressiveConfig, RadiusSpec};
use crate::render::prepared_scene::PreparedScene;
use crate::render::scene::{Scene, SceneError};
use crate::{store::heuristics::ProgressiveReason, store::decision::StoredPhoton};
use alloc::format;
use alloc::string::String;
use alloc::vec::Vec;
use glam::Vec3;

/// The density-estimation method.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum Method {
    /// Photon differentials with the PPM fallback of the heuristics (ARPA).
    #[default]
    Arpa,
    /// Progressive photon mapping with photons as spheres of the progressive radius
    /// (Kern et al.'s RTPM), the baseline. Its photons carry no ray differentials (the
    /// photon pass skips their propagation) and are stored at the surface point they hit.
    Rtpm,
}

impl Method {
    /// Lower-case name as used on the command line.
    pub const fn name(self) -> &'static str {
        match self {
            Method::Arpa => "arpa",
            Method::Rtpm => "rtpm",
        }
    }
}

/// Everything that controls a render besides the scene.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RenderSettings {
    /// Density-estimation method.
    pub method: Method,
    /// Photons emitted per iteration, shared by all lights in proportion to their power.
    pub photons_per_iteration: u32,
    /// Seed of every random stream.
    pub seed: u32,
    /// Maximum number of surface interactions of a photon path and of a camera path.
    pub max_depth: u32,
    /// Direct lighting by next-event estimation at the query points (then the photon
    /// maps hold no direct `L D` photons).
    pub direct_lighting: bool,
    /// Smoothing factors `S_c`, `S_g`.
    pub smoothing: Smoothing,
    /// Footprint heuristics.
    pub heuristics: Heuristics,
    /// Progressive radii of both maps.
    pub radii: ProgressiveConfig,
    /// Kernel of the footprints (progressive photons always use the constant kernel).
    pub kernel: Kernel,
    /// How the photons of an iteration are emitted: projection maps and the caustic pass
    /// ([`crate::render::projection`]).
    pub emission: EmissionStrategy,
    /// Per-pixel or global bandwidth ([`crate::gather::scales`]): how many scales the gather
    /// evaluates and how many planes the accumulation keeps.
    pub bandwidth: crate::gather::scales::Bandwidth,
}

/// How the photon pass spends its photons ([`crate::render::projection`]).
///
/// With `projection` on, every light emits its global photons only into the cells of its
/// emission domain that see some geometry, and a separate caustic pass emits
/// `caustic_photons` photons only into the cells that see a specular (mirror, glass)
/// object; both carry the flux of the part of the domain they sample, so the estimate is
/// unchanged in expectation. Off, one pass emits `photons_per_iteration` photons over
/// every light's whole domain and stores both maps (the method of the paper).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct EmissionStrategy {
    /// Projection maps and the caustic pass on (default) or off.
    pub projection: bool,
    /// Photons of the caustic pass per iteration; `None` chooses them from the projected
    /// power ([`crate::render::emission_plan::auto_caustic_photons`]); `Some(0)` runs no caustic pass.
    /// Ignored without projection.
    pub caustic_photons: Option<u32>,
}

impl Default for EmissionStrategy {
    fn default() -> Self {
        Self { projection: true, caustic_photons: None }
    }
}

impl EmissionStrategy {
    /// One pass over every light's whole domain (projection off).
    pub const WHOLE_DOMAIN: Self = Self { projection: false, caustic_photons: None };
}

impl Default for RenderSettings {
    fn default() -> Self {
        Self {
            method: Method::Arpa,
            photons_per_iteration: 250_000,
            seed: 0,
            max_depth: 10,
            direct_lighting: true,
            smoothing: Smoothing::default(),
            heuristics: Heuristics::default(),
            radii: ProgressiveConfig::default(),
            kernel: Kernel::default(),
            emission: EmissionStrategy::default(),
            bandwidth: crate::gather::scales::Bandwidth::default(),
        }
    }
}

/// Settings no render can use, with the reason (names the field and its value).
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[error("{0}")]
pub struct InvalidSettings(pub String);

impl RenderSettings {
    /// Rejects settings no render can use: zero photons or depth, non-positive or
    /// non-finite smoothing factors and radii, `alpha` outside `(0, 1]`, and heuristic
    /// parameters outside their ranges. Every backend calls it in `upload_scene`.
    pub fn validate(&self) -> Result<(), InvalidSettings> {
        let s = self;
        let bad = |why: String| Err(InvalidSettings(why));
        let positive = |x: f64| x > 0.0 && x.is_finite();
        if s.photons_per_iteration == 0 {
            return bad("photons_per_iteration must be at least 1".into());
        }
        if s.max_depth == 0 {
            return bad("max_depth must be at least 1".into());
        }
        for (name, f) in [
            ("smoothing.caustic", s.smoothing.caustic),
            ("smoothing.global", s.smoothing.global),
        ] {
            if !positive(f) {
                return bad(format!("{name} must be positive and finite (got {f})"));
            }
        }
        for (name, spec) in [
            ("radii.caustic", s.radii.caustic),
            ("radii.global", s.radii.global),
        ] {
            let (RadiusSpec::Absolute(v) | RadiusSpec::RelativeToDiagonal(v)) = spec;
            if !positive(v) {
                return bad(format!("{name} must be positive and finite (got {v})"));
            }
        }
        if !(s.radii.alpha > 0.0 && s.radii.alpha <= 1.0) {
            return bad(format!(
                "radii.alpha must lie in (0, 1] (got {})",
                s.radii.alpha
            ));
        }
        let h = &s.heuristics;
        if let Some(d) = h.dampening {
            if !(d.exponent > 0.0 && d.exponent <= 1.0) {
                return bad(format!(
                    "dampening exponent must lie in (0, 1] (got {})",
                    d.exponent
                ));
            }
            if let DampenReference::Absolute(l) = d.reference
                && !positive(l)
            {
                return bad(format!(
                    "dampening reference length must be positive and finite (got {l})"
                ));
            }
        }
        if let Some(m) = h.h_max {
            let (crate::store::heuristics::LengthSpec::Absolute(v)
            | crate::store::heuristics::LengthSpec::RelativeToDiagonal(v)) = m.length;
            if !positive(v) {
                return bad(format!(
                    "h_max length must be positive and finite (got {v})"
                ));
            }
        }
        if let Some(d) = h.degenerate
            && !(d.fraction >= 0.0 && d.fraction.is_finite())
        {
            return bad(format!(
                "degenerate-removal fraction must be finite and >= 0 (got {})",
                d.fraction
            ));
        }
        if let Some(c) = h.culling
            && !positive(c.fraction)
        {
            return bad(format!(
                "culling fraction must be positive and finite (got {})",
                c.fraction
            ));
        }
        Ok(())
    }
}

/// The backends of the project. The one list of their names: the facade's registry
/// (`arpa::backends`), the CLI's `--backend` and the conformance suite's
/// `ARPA_REQUIRE_BACKENDS` all take these.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum BackendKind {
    /// The CPU backend on Embree 4 (`arpa-cpu`).
    Cpu,
    /// The wgpu backend on Vulkan ray queries (`arpa-wgpu`).
    Wgpu,
    /// The Vulkan backend on ray-tracing pipelines (`arpa-vk`).
    Vk,
}

impl BackendKind {
    /// Every backend, in the order reports list them.
    pub const ALL: [BackendKind; 3] = [BackendKind::Cpu, BackendKind::Wgpu, BackendKind::Vk];

    /// Lower-case name, as on the command line and in `ARPA_REQUIRE_BACKENDS`.
    pub const fn name(self) -> &'static str {
        match self {
            BackendKind::Cpu => "cpu",
            BackendKind::Wgpu => "wgpu",
            BackendKind::Vk => "vk",
        }
    }

    /// The backend called `name` (ASCII case and surrounding spaces ignored).
    pub fn from_name(name: &str) -> Option<Self> {
        let name = name.trim();
        Self::ALL.into_iter().find(|b| b.name().eq_ignore_ascii_case(name))
    }
}

impl core::fmt::Display for BackendKind {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str(self.name())
    }
}

/// The stages of an iteration, in pipeline order ([`Tracer`]'s methods of the same names).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Stage {
    /// [`Tracer::upload_scene`].
    UploadScene,
    /// [`Tracer::camera_pass`]: its output is the query records.
    CameraPass,
    /// [`Tracer::photon_pass`]: its output is the stored footprints and photons.
    PhotonPass,
    /// [`Tracer::build_acceleration_structure`]: its output is the acceleration structure.
    BuildAccelerationStructure,
    /// [`Tracer::gather`]: its output is the iteration's image.
    Gather,
    /// [`Tracer::accumulate`]: adds the iteration's image to the running estimate.
    Accumulate,
}

impl Stage {
    /// The stage's method name.
    pub const fn name(self) -> &'static str {
        match self {
            Stage::UploadScene => "upload_scene",
            Stage::CameraPass => "camera_pass",
            Stage::PhotonPass => "photon_pass",
            Stage::BuildAccelerationStructure => "build_acceleration_structure",
            Stage::Gather => "gather",
            Stage::Accumulate => "accumulate",
        }
    }

    /// The stages whose output of this iteration this stage reads.
    pub const fn needs(self) -> &'static [Stage] {
        match self {
            Stage::UploadScene | Stage::CameraPass | Stage::PhotonPass => &[],
            Stage::BuildAccelerationStructure => &[Stage::PhotonPass],
            Stage::Gather => &[Stage::CameraPass, Stage::BuildAccelerationStructure],
            Stage::Accumulate => &[Stage::Gather],
        }
    }

    /// The stages whose outputs are stale once this stage runs again: itself and every
    /// stage that reads its output, directly or not.
    const fn invalidates(self) -> &'static [Stage] {
        match self {
            Stage::UploadScene | Stage::Accumulate => &[],
            Stage::CameraPass => &[Stage::CameraPass, Stage::Gather],
            Stage::PhotonPass => &[Stage::PhotonPass, Stage::BuildAccelerationStructure, Stage::Gather],
            Stage::BuildAccelerationStructure => &[Stage::BuildAccelerationStructure, Stage::Gather],
            Stage::Gather => &[Stage::Gather],
        }
    }

    /// Index into [`StageClock`]'s outputs (stages with an output only).
    const fn output_slot(self) -> Option<usize> {
        match self {
            Stage::CameraPass => Some(0),
            Stage::PhotonPass => Some(1),
            Stage::BuildAccelerationStructure => Some(2),
            Stage::Gather => Some(3),
            Stage::UploadScene | Stage::Accumulate => None,
        }
    }
}

impl core::fmt::Display for Stage {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str(self.name())
    }
}

/// A call of [`Tracer`] that can come too early: a stage, or a `read_*` of a stage's
/// output.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Call {
    /// One of the stages.
    Stage(Stage),
    /// [`Tracer::read_image`].
    ReadImage,
    /// [`Tracer::read_query_points`].
    ReadQueryPoints,
    /// [`Tracer::read_footprints`].
    ReadFootprints,
    /// [`Tracer::read_photons`].
    ReadPhotons,
    /// [`Tracer::read_stats`].
    ReadStats,
    /// [`Tracer::read_accumulation`].
    ReadAccumulation,
    /// [`Tracer::restore_accumulation`].
    RestoreAccumulation,
}

impl From<Stage> for Call {
    fn from(stage: Stage) -> Self {
        Call::Stage(stage)
    }
}

impl core::fmt::Display for Call {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str(match self {
            Call::Stage(s) => s.name(),
            Call::ReadImage => "read_image",
            Call::ReadQueryPoints => "read_query_points",
            Call::ReadFootprints => "read_footprints",
            Call::ReadPhotons => "read_photons",
            Call::ReadStats => "read_stats",
            Call::ReadAccumulation => "read_accumulation",
            Call::RestoreAccumulation => "restore_accumulation",
        })
    }
}

/// The errors every backend shares: calls out of order, the iteration limit, and scenes
/// or settings no render can use. Each backend's error enum wraps it (`#[from]`).
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum StageError {
    /// A call came before the stage whose output it needs (in this iteration, for a stage;
    /// ever, for a `read_*`).
    #[error("{call} called before {needs}")]
    Order {
        /// What was called.
        call: Call,
        /// The stage that has to run first.
        needs: Stage,
    },
    /// `u32::MAX − 1` iterations have been accumulated: the iteration index of the random
    /// streams and the radius schedule cannot go further.
    #[error("iteration limit reached ({0} iterations)")]
    IterationLimit(u32),
    /// A render setting is out of range.
    #[error("invalid render settings: {0}")]
    Settings(#[from] InvalidSettings),
    /// The scene failed validation.
    #[error("invalid scene: {0}")]
    Scene(#[from] SceneError),
    /// An accumulation to continue from does not fit this render or this backend.
    #[error("cannot continue the accumulation: {0}")]
    Accumulation(String),
}

impl StageClock {
    /// The guard and clock of [`Tracer::restore_accumulation`]: `state` validated and sized
    /// `width × height`, and the clock that continues it.
    pub fn for_restore(state: &Accumulation, width: u32, height: u32) -> Result<StageClock, StageError> {
        state.validate().map_err(|e| StageError::Accumulation(format!("{e}")))?;
        if (state.width, state.height) != (width, height) {
            return Err(StageError::Accumulation(format!("it is {}x{} pixels, the image {width}x{height}", state.width, state.height)));
        }
        StageClock::restart_at(state.first_iteration, state.iterations)
            .filter(|c| c.completed() < u32::MAX - 1)
            .ok_or(StageError::IterationLimit(u32::MAX - 1))
    }
}

impl StageError {
    /// `call` came before `needs`.
    pub fn order(call: impl Into<Call>, needs: Stage) -> Self {
        StageError::Order { call: call.into(), needs }
    }
}

/// The uploaded state of a backend, or the error saying that `call` needs
/// [`Tracer::upload_scene`] first.
pub fn uploaded<T>(state: Option<T>, call: impl Into<Call>) -> Result<T, StageError> {
    state.ok_or_else(|| StageError::order(call, Stage::UploadScene))
}

/// Validates `settings` and `scene` and prepares the scene: what every backend's
/// [`Tracer::upload_scene`] starts with.
pub fn prepare_upload(scene: &Scene, settings: &RenderSettings) -> Result<PreparedScene, StageError> {
    settings.validate()?;
    Ok(PreparedScene::new(scene.clone())?)
}

/// The stage bookkeeping every backend shares: which iteration each stage's output
/// belongs to, the iterations accumulated, and the statistics of the iteration in progress.
///
/// A backend calls [`begin`](Self::begin) at the start of a stage (it checks the order and
/// the iteration limit, and marks the stage's output and every output derived from it
/// stale) and [`finish`](Self::finish) when the stage's output is written. The rules this
/// enforces are [`Tracer`]'s: within an iteration a stage needs the outputs of
/// [`Stage::needs`] made in this iteration; re-running a stage is allowed and makes the
/// outputs of the stages after it stale.
#[derive(Clone, Debug, PartialEq)]
pub struct StageClock {
    /// Iteration index the accumulation starts at ([`StageClock::restart_at`]).
    first: u32,
    completed: u32,
    /// Iteration each stage's output was made in (camera, photon, build, gather).
    outputs: [Option<u32>; 4],
    stats: IterationStats,
    /// Iteration whose counts `stats` holds.
    stats_for: Option<u32>,
}

impl Default for StageClock {
    fn default() -> Self {
        Self::new()
    }
}

impl StageClock {
    /// The clock of a scene just uploaded: no iteration done, no stage output.
    pub fn new() -> Self {
        Self { first: 0, completed: 0, outputs: [None; 4], stats: IterationStats::default(), stats_for: Some(0) }
    }

    /// Index of the iteration in progress (0-based): the iterations of the render so far,
    /// including those of an accumulation it continues ([`StageClock::restart_at`]). The
    /// random streams and the radius schedule use it.
    pub fn completed(&self) -> u32 {
        self.completed
    }

    /// Iterations in the backend's accumulation: [`completed`](Self::completed) minus the
    /// iteration the accumulation started at.
    pub fn accumulated(&self) -> u32 {
        self.completed - self.first
    }

    /// Index of the first iteration of the backend's accumulation.
    pub fn first_iteration(&self) -> u32 {
        self.first
    }

    /// The clock of a scene whose accumulation covers `accumulated` iterations from
    /// `first` on (a checkpoint resumed, or the start of a partial render): the next
    /// iteration is `first + accumulated`, and no stage output of this iteration exists.
    /// `None` when the index would not fit `u32`.
    pub fn restart_at(first: u32, accumulated: u32) -> Option<Self> {
        let completed = first.checked_add(accumulated)?;
        Some(Self { first, completed, stats: IterationStats { iteration: completed, ..IterationStats::default() }, stats_for: Some(completed), ..Self::new() })
    }

    /// Whether `stage`'s output was made in the iteration in progress.
    pub fn is_current(&self, stage: Stage) -> bool {
        stage.output_slot().is_some_and(|i| self.outputs[i] == Some(self.completed))
    }

    /// Starts `stage`: refuses it when an input of this iteration is missing or the
    /// iteration index cannot advance, starts the counts of the iteration in progress,
    /// and marks the stage's output and those derived from it stale.
    pub fn begin(&mut self, stage: Stage) -> Result<(), StageError> {
        if matches!(stage, Stage::CameraPass | Stage::PhotonPass) && self.completed >= u32::MAX - 1 {
            // The core computes the 1-based index `iteration + 1` of the streams.
            return Err(StageError::IterationLimit(self.completed));
        }
        if let Some(&missing) = stage.needs().iter().find(|&&n| !self.is_current(n)) {
            return Err(StageError::order(stage, missing));
        }
        if self.stats_for != Some(self.completed) {
            self.stats = IterationStats { iteration: self.completed, radii: self.stats.radii, ..IterationStats::default() };
            self.stats_for = Some(self.completed);
        }
        for s in stage.invalidates() {
            if let Some(i) = s.output_slot() {
                self.outputs[i] = None;
            }
        }
        Ok(())
    }

    /// Ends `stage`: its output now belongs to the iteration in progress. Finishing
    /// [`Stage::Accumulate`] completes the iteration.
    pub fn finish(&mut self, stage: Stage) {
        if let Some(i) = stage.output_slot() {
            self.outputs[i] = Some(self.completed);
        }
        if stage == Stage::Accumulate {
            self.completed += 1;
            self.outputs[3] = None;
            self.stats.iteration = self.completed;
        }
    }

    /// The guard of a `read_*` call: `stage` has made an output (in any iteration).
    pub fn require_output(&self, call: Call, stage: Stage) -> Result<(), StageError> {
        match stage.output_slot() {
            Some(i) if self.outputs[i].is_some() => Ok(()),
            _ => Err(StageError::order(call, stage)),
        }
    }

    /// Statistics of the iteration in progress (or the last one).
    pub fn stats(&self) -> &IterationStats {
        &self.stats
    }

    /// The statistics a stage writes its counts and time into.
    pub fn stats_mut(&mut self) -> &mut IterationStats {
        &mut self.stats
    }

    /// Runs `stage` as one call of [`Tracer`]: [`begin`](Self::begin), then `body` with
    /// this clock (for the iteration index and the counts), then the stage's wall-clock
    /// time into [`StageTimes`] (seconds) and [`finish`](Self::finish). When `body` fails
    /// the stage stays unfinished, so the stages that read its output refuse to run.
    #[cfg(feature = "std")]
    #[cfg_attr(docsrs, doc(cfg(feature = "std")))]
    pub fn run<E: From<StageError>>(&mut self, stage: Stage, body: impl FnOnce(&mut StageClock) -> Result<(), E>) -> Result<(), E> {
        self.begin(stage)?;
        let start = std::time::Instant::now();
        body(self)?;
        if let Some(t) = self.stats.times.of_mut(stage) {
            *t = start.elapsed().as_secs_f64();
        }
        self.finish(stage);
        Ok(())
    }
}

/// What a backend supports.
#[derive(Clone, Debug, PartialEq)]
pub struct Capabilities {
    /// Which backend this is.
    pub backend: BackendKind,
    /// Device description (CPU model, adapter name).
    pub device: String,
    /// Methods it implements.
    pub methods: Vec<Method>,
    /// Largest photon count per iteration it accepts (`None`: limited by memory only).
    pub max_photons_per_iteration: Option<u32>,
    /// Whether images are bit-identical for the same seed regardless of thread count.
    pub deterministic: bool,
}

impl Capabilities {
    /// A backend that implements both methods, takes any photon count per iteration its
    /// memory holds, and is deterministic (what `cpu`, `wgpu` and `vk` are); `device`
    /// describes the CPU or adapter.
    pub fn new(backend: BackendKind, device: String) -> Self {
        Self { backend, device, methods: alloc::vec![Method::Arpa, Method::Rtpm], max_photons_per_iteration: None, deterministic: true }
    }
}

/// A diffuse query point found by the camera pass, with what the gather needs.
#[derive(Clone, Copy, Debug, Default, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
#[repr(C)]
pub struct QueryRecord {
    /// Position (metres).
    pub position: [f32; 3],
    /// Pixel index (row-major) the query belongs to.
    pub pixel: u32,
    /// Unit geometric normal oriented towards the viewer, flipped where the viewer lies
    /// below the shading plane of a mesh with vertex normals (the gather's side test,
    /// [`crate::propagate::lambertian`]).
    pub normal: [f32; 3],
    /// 1 if this is a valid query point, 0 if the camera path ended elsewhere.
    pub valid: u32,
    /// Camera-path throughput up to this vertex times the Lambertian `albedo/π`
    /// (1/sr): radiance = `weight · E`.
    pub weight: [f32; 3],
    /// Padding.
    pub _pad0: u32,
    /// Radiance already known for the pixel this iteration: emission seen along the
    /// camera path and, with direct lighting on, the direct illumination (W/(m²·sr)).
    pub radiance: [f32; 3],
    /// Padding.
    pub _pad1: u32,
}

/// Wall-clock time of each stage of the last iteration, in seconds.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct StageTimes {
    /// Camera pass.
    pub camera: f64,
    /// Photon pass.
    pub photon: f64,
    /// Acceleration-structure build.
    pub build: f64,
    /// Gather.
    pub gather: f64,
    /// Accumulation.
    pub accumulate: f64,
}

/// Statistics of the last iteration (counts are per iteration, summed over the photon
/// batches of a backend that traces an iteration in several).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct IterationStats {
    /// Iterations completed so far (1-based index of the last one).
    pub iteration: u32,
    /// Photons emitted (both passes).
    pub photons_emitted: u64,
    /// Photons emitted per pass, `[caustic pass, global pass]` (without projection every
    /// photon is a global-pass photon).
    pub emitted: [u64; 2],
    /// The work the photon pass left out because the scene does not need it.
    pub skipped: Skipped,
    /// Ray segments traced by the photon pass.
    pub photon_segments: u64,
    /// Footprints stored, `[caustic, global]`.
    pub footprints: [u64; 2],
    /// Progressive photons stored, `[caustic, global]`.
    pub progressive: [u64; 2],
    /// Footprints replaced as degenerate.
    pub degenerate: u64,
    /// Footprints replaced by bounding-box culling.
    pub culled: u64,
    /// Footprints replaced because `f32` cannot resolve them.
    pub unrepresentable: u64,
    /// Photons whose differential was lost on the way.
    pub differential_lost: u64,
    /// Photons or footprints dropped because a buffer was full.
    pub overflowed: u64,
    /// Valid query points.
    pub query_points: u64,
    /// Candidate records the gather's acceleration structure handed to the exact test at
    /// the valid query points, `[caustic, global]`: the gather's work. On ray-tracing
    /// hardware (wgpu, vk) these are the records whose box contains the point; Embree's
    /// point query (cpu) also hands over the other records of the leaves it visits.
    pub candidates: [u64; 2],
    /// Records that contributed at the valid query points (inside the footprint or photon
    /// sphere, facing, non-zero), `[caustic, global]`.
    pub contributions: [u64; 2],
    /// Valid query points with at least one contribution of the map, `[caustic, global]`
    /// (on the GPU backends counted per photon batch: a point covered in two batches of
    /// an iteration counts twice).
    pub covered: [u64; 2],
    /// Progressive radii used, `[caustic, global]` (metres).
    pub radii: [f64; 2],
    /// Stage timings: host wall-clock time of each stage call (seconds).
    pub times: StageTimes,
    /// Device time of each stage, from the device's timestamps ([`DeviceTimes`]).
    pub device_times: DeviceTimes,
}

/// The device's own time for the stages of an iteration, next to the host's
/// [`IterationStats::times`]: the difference is the host's share (submission, waits,
/// readbacks, bookkeeping).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub enum DeviceTimes {
    /// The backend computes on the host (cpu): the host times are its device times.
    #[default]
    Host,
    /// The adapter cannot time its work (no timestamp queries on its queue), or a
    /// timestamp of this iteration was lost (a wrapped or out-of-order pair); the summary
    /// says "device time: not available on this adapter".
    Unavailable,
    /// Seconds the device spent per stage: for every submission of the stage, the time
    /// from a timestamp written before its commands to one written after them, summed
    /// (time the device waits for the host between submissions is not counted). The GPU
    /// backends fill it in once the iteration's accumulate has run.
    Measured(StageTimes),
}

impl DeviceTimes {
    /// The measured times, if any.
    pub fn measured(&self) -> Option<&StageTimes> {
        match self {
            DeviceTimes::Measured(t) => Some(t),
            DeviceTimes::Host | DeviceTimes::Unavailable => None,
        }
    }

    /// Adds `other` (to total several iterations): measured times add up; a total over
    /// iterations of which one is unavailable is unavailable; `Host` adds nothing.
    pub fn accumulate(&mut self, other: &DeviceTimes) {
        match (&mut *self, other) {
            (_, DeviceTimes::Host) | (DeviceTimes::Unavailable, _) => {}
            (DeviceTimes::Measured(a), DeviceTimes::Measured(b)) => a.accumulate(b),
            (DeviceTimes::Host, o) | (DeviceTimes::Measured(_), o @ DeviceTimes::Unavailable) => *self = *o,
        }
    }
}

impl StageTimes {
    /// The time of `stage` (seconds); `None` for [`Stage::UploadScene`], which is not
    /// part of an iteration.
    pub fn of_mut(&mut self, stage: Stage) -> Option<&mut f64> {
        match stage {
            Stage::UploadScene => None,
            Stage::CameraPass => Some(&mut self.camera),
            Stage::PhotonPass => Some(&mut self.photon),
            Stage::BuildAccelerationStructure => Some(&mut self.build),
            Stage::Gather => Some(&mut self.gather),
            Stage::Accumulate => Some(&mut self.accumulate),
        }
    }

    /// The time of `stage` (seconds); `None` for [`Stage::UploadScene`].
    pub fn of(&self, stage: Stage) -> Option<f64> {
        let mut t = *self;
        t.of_mut(stage).map(|v| *v)
    }

    /// The sum of the five stages (seconds).
    pub fn total(&self) -> f64 {
        self.camera + self.photon + self.build + self.gather + self.accumulate
    }

    /// Every stage's time divided by `n` (a mean over `n` iterations; `n = 0` divides by 1).
    pub fn per(&self, n: u32) -> StageTimes {
        let n = f64::from(n.max(1));
        StageTimes { camera: self.camera / n, photon: self.photon / n, build: self.build / n, gather: self.gather / n, accumulate: self.accumulate / n }
    }

    /// Adds `other`'s times (non-finite ones are skipped).
    pub fn accumulate(&mut self, other: &StageTimes) {
        for (acc, v) in [
            (&mut self.camera, other.camera),
            (&mut self.photon, other.photon),
            (&mut self.build, other.build),
            (&mut self.gather, other.gather),
            (&mut self.accumulate, other.accumulate),
        ] {
            if v.is_finite() {
                *acc += v;
            }
        }
    }
}

/// Why a photon pass does not run.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PassSkip {
    /// Caustic pass: the scene has no mirror or glass surface.
    NoSpecularSurface,
    /// Caustic pass: no light's emission domain sees a mirror or glass surface.
    SpecularUnreached,
    /// Caustic pass: the only light is an environment, which is not projected
    /// ([`crate::render::projection`]): its caustics come from the global pass.
    EnvironmentOnly,
    /// Caustic pass: the settings ask for no caustic photons (`--caustic-photons 0`).
    NoCausticPhotons,
    /// Caustic pass: so much of the light already heads for specular objects that aiming
    /// at them gains little ([`crate::render::emission_plan::MAX_AUTO_SPECULAR_SHARE`]).
    LittleToGain,
    /// Global pass: direct lighting is on and no photon can reach a second surface after
    /// a diffuse one (`max_depth` below 2, all geometry in one plane, or every diffuse
    /// surface black), so no global record can be stored.
    NothingToBounceTo,
    /// Either pass: no light reaches any geometry.
    NoLightReachesGeometry,
}

impl PassSkip {
    /// The reason in words, as the stats summary prints it.
    pub const fn reason(self) -> &'static str {
        match self {
            PassSkip::NoSpecularSurface => "no specular surface",
            PassSkip::SpecularUnreached => "no light reaches a specular surface",
            PassSkip::EnvironmentOnly => "the environment light is not projected (its caustics come from the global pass)",
            PassSkip::NoCausticPhotons => "no caustic photons requested",
            PassSkip::LittleToGain => "a quarter or more of the light heads for specular objects already",
            PassSkip::NothingToBounceTo => "direct lighting on and nothing to bounce to",
            PassSkip::NoLightReachesGeometry => "no light reaches any geometry",
        }
    }
}

/// What the photon pass of an iteration skipped ([`crate::render::projection`]).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Skipped {
    /// Why the caustic pass did not run; `None` when it ran (or projection is off).
    pub caustic_pass: Option<PassSkip>,
    /// Why the global pass did not run; `None` when it ran.
    pub global_pass: Option<PassSkip>,
    /// Lights whose emission domain sees no geometry: they emit nothing.
    pub lights: u32,
    /// Fraction of the emitted power (luminance) sent into directions or aperture cells
    /// that see no geometry, and so not emitted by the global pass (0 without projection).
    pub power_fraction: f64,
}

impl IterationStats {
    /// Records stored per photon emitted, `[caustic, global]` map (footprints and
    /// progressive photons of the map over the photons of both passes); zero without
    /// photons.
    pub fn records_per_photon(&self) -> [f64; 2] {
        [0, 1].map(|m| if self.photons_emitted > 0 { (self.footprints[m] + self.progressive[m]) as f64 / self.photons_emitted as f64 } else { 0.0 })
    }

    /// Counts one stored photon: a footprint or a progressive photon of its map, and the
    /// reason a footprint was replaced.
    #[inline]
    pub fn record_stored(&mut self, stored: &StoredPhoton) {
        match stored {
            StoredPhoton::Footprint { packed, .. } => self.footprints[packed.photon_map().index()] += 1,
            StoredPhoton::Progressive { photon, reason } => {
                self.progressive[photon.photon_map().index()] += 1;
                match reason {
                    ProgressiveReason::Degenerate => self.degenerate += 1,
                    ProgressiveReason::Culled => self.culled += 1,
                    ProgressiveReason::Unrepresentable => self.unrepresentable += 1,
                    ProgressiveReason::DifferentialLost => self.differential_lost += 1,
                    ProgressiveReason::ProgressiveMethod => {}
                }
            }
        }
    }

    /// Zeroes the photon pass's counts before a GPU backend sums its photon batches into
    /// them (not [`IterationStats::overflowed`], which keeps every dropped append of the
    /// iteration, nor the times).
    pub fn reset_photon_counts(&mut self) {
        self.photons_emitted = 0;
        self.emitted = [0; 2];
        self.photon_segments = 0;
        self.footprints = [0; 2];
        self.progressive = [0; 2];
        self.degenerate = 0;
        self.culled = 0;
        self.unrepresentable = 0;
        self.differential_lost = 0;
    }

    /// Contributions of both maps (footprint and photon containments found).
    pub fn gathered(&self) -> u64 {
        self.contributions[0] + self.contributions[1]
    }

    /// Candidates (`[caustic, global]`) per valid query point; zero without query points.
    pub fn candidates_per_query(&self) -> [f64; 2] {
        self.candidates.map(|c| if self.query_points > 0 { c as f64 / self.query_points as f64 } else { 0.0 })
    }

    /// Contributions (`[caustic, global]`) per valid query point; zero without query points.
    pub fn contributions_per_query(&self) -> [f64; 2] {
        self.contributions.map(|c| if self.query_points > 0 { c as f64 / self.query_points as f64 } else { 0.0 })
    }

    /// Contributions per covered query point (`[caustic, global]`): how many records of
    /// the map overlap where the map has light at all; zero where nothing is covered.
    pub fn overlap(&self) -> [f64; 2] {
        [0, 1].map(|m| if self.covered[m] > 0 { self.contributions[m] as f64 / self.covered[m] as f64 } else { 0.0 })
    }

    /// Adds the counts and stage times of `other` (to total several iterations, or to
    /// merge the partial counts of a parallel pass); `iteration` and `radii` become
    /// `other`'s.
    pub fn accumulate(&mut self, other: &IterationStats) {
        self.iteration = other.iteration;
        self.radii = other.radii;
        self.photons_emitted += other.photons_emitted;
        self.skipped = other.skipped;
        for p in 0..2 {
            self.emitted[p] += other.emitted[p];
        }
        self.photon_segments += other.photon_segments;
        for m in 0..2 {
            self.footprints[m] += other.footprints[m];
            self.progressive[m] += other.progressive[m];
        }
        self.degenerate += other.degenerate;
        self.culled += other.culled;
        self.unrepresentable += other.unrepresentable;
        self.differential_lost += other.differential_lost;
        self.overflowed += other.overflowed;
        self.query_points += other.query_points;
        for m in 0..2 {
            self.candidates[m] += other.candidates[m];
            self.contributions[m] += other.contributions[m];
            self.covered[m] += other.covered[m];
        }
        self.times.accumulate(&other.times);
        self.device_times.accumulate(&other.device_times);
    }
}

/// An image of linear radiance, row-major, top row first.
#[derive(Clone, Debug, PartialEq)]
pub struct Image {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// `width × height` pixels (W/(m²·sr), linear RGB), always finite.
    pub pixels: Vec<Vec3>,
}

/// A rendering backend. Errors are the backend's own `thiserror` enum; nothing panics
/// across the trait.
pub trait Tracer {
    /// The backend's error type.
    type Error: core::error::Error + Send + Sync + 'static;

    /// What this backend supports.
    fn capabilities(&self) -> Capabilities;

    /// Validates and uploads `scene`, resets the accumulation and applies `settings`.
    fn upload_scene(&mut self, scene: &Scene, settings: &RenderSettings) -> Result<(), Self::Error>;

    /// Follows a camera path per pixel through specular chains to the first diffuse
    /// query point.
    fn camera_pass(&mut self) -> Result<(), Self::Error>;

    /// Emits, propagates, classifies and stores this iteration's photons.
    fn photon_pass(&mut self) -> Result<(), Self::Error>;

    /// Builds the acceleration structure over the stored footprints and photons.
    fn build_acceleration_structure(&mut self) -> Result<(), Self::Error>;

    /// Finds every footprint and photon containing each query point and evaluates the
    /// iteration's image.
    fn gather(&mut self) -> Result<(), Self::Error>;

    /// Adds the iteration's image to the running estimate and advances the radii.
    fn accumulate(&mut self) -> Result<(), Self::Error>;

    /// One full iteration: all stages in order.
    fn iterate(&mut self) -> Result<(), Self::Error> {
        self.camera_pass()?;
        self.photon_pass()?;
        self.build_acceleration_structure()?;
        self.gather()?;
        self.accumulate()
    }

    /// Index of the next iteration: iterations of the render so far, including those of a
    /// restored accumulation ([`Tracer::restore_accumulation`]).
    fn iterations(&self) -> u32;

    /// The accumulation so far, exactly (a checkpoint): the per-pixel sums and the range of
    /// iterations they cover. Needs [`Tracer::upload_scene`].
    fn read_accumulation(&self) -> Result<Accumulation, Self::Error>;

    /// Continues from `state` after [`Tracer::upload_scene`] with the same scene and
    /// settings: the accumulation becomes `state`'s and the next iteration is
    /// `state.first_iteration + state.iterations`, so the render goes on as if it had
    /// never stopped (and an empty `state` starting at iteration `A` renders the part
    /// `A..` of a render). Refused when `state` does not fit the image or the backend
    /// cannot continue its sums exactly.
    fn restore_accumulation(&mut self, state: &Accumulation) -> Result<(), Self::Error>;

    /// The running estimate (mean over iterations).
    fn read_image(&self) -> Result<Image, Self::Error>;

    /// The query points of the last camera pass, one per pixel.
    fn read_query_points(&self) -> Result<Vec<QueryRecord>, Self::Error>;

    /// The footprints stored by the last photon pass.
    fn read_footprints(&self) -> Result<Vec<PackedFootprint>, Self::Error>;

    /// The progressive photons stored by the last photon pass.
    fn read_photons(&self) -> Result<Vec<PackedPhoton>, Self::Error>;

    /// Statistics of the last iteration.
    fn read_stats(&self) -> Result<IterationStats, Self::Error>;
}

#[cfg(test)]
mod tests {
    use super::*;
    use alloc::string::ToString;

    #[test]
    fn default_settings_are_valid() {
        assert_eq!(RenderSettings::default().validate(), Ok(()));
    }

    #[test]
    fn each_invalid_field_is_named() {
        type Spoil = fn(&mut RenderSettings);
        let cases: [(&str, Spoil); 6] = [
            ("photons_per_iteration", |s| s.photons_per_iteration = 0),
            ("max_depth", |s| s.max_depth = 0),
            ("smoothing.caustic", |s| s.smoothing.caustic = f64::NAN),
            ("radii.global", |s| s.radii.global = RadiusSpec::Absolute(-1.0)),
            ("radii.alpha", |s| s.radii.alpha = 1.5),
            ("radii.caustic", |s| s.radii.caustic = RadiusSpec::RelativeToDiagonal(f64::INFINITY)),
        ];
        for (field, spoil) in cases {
            let mut s = RenderSettings::default();
            spoil(&mut s);
            let e = s.validate().expect_err(field);
            assert!(e.0.contains(field), "{field}: {e}");
        }
    }

    #[test]
    fn backend_names_round_trip() {
        for b in BackendKind::ALL {
            assert_eq!(BackendKind::from_name(&b.name().to_ascii_uppercase()), Some(b));
        }
        assert_eq!(BackendKind::from_name(" wgpu "), Some(BackendKind::Wgpu));
        assert_eq!(BackendKind::from_name("mock"), None);
    }

    #[test]
    fn clock_enforces_the_stage_order_of_an_iteration() {
        use Stage::*;
        let mut c = StageClock::new();
        assert_eq!(c.begin(Gather), Err(StageError::order(Gather, CameraPass)));
        assert_eq!(c.begin(BuildAccelerationStructure), Err(StageError::order(BuildAccelerationStructure, PhotonPass)));
        assert_eq!(c.begin(Accumulate), Err(StageError::order(Accumulate, Gather)));
        assert!(c.require_output(Call::ReadFootprints, PhotonPass).is_err());
        // Photon pass before camera pass is allowed.
        for s in [PhotonPass, CameraPass, BuildAccelerationStructure] {
            c.begin(s).unwrap();
            c.finish(s);
        }
        // Re-running the photon pass makes the structure built from its output stale.
        c.begin(PhotonPass).unwrap();
        assert_eq!(c.begin(Gather), Err(StageError::order(Gather, BuildAccelerationStructure)));
        c.finish(PhotonPass);
        for s in [BuildAccelerationStructure, Gather] {
            c.begin(s).unwrap();
            c.finish(s);
        }
        // A new camera pass makes the image stale, not the structure.
        c.begin(CameraPass).unwrap();
        c.finish(CameraPass);
        assert!(c.is_current(BuildAccelerationStructure));
        assert_eq!(c.begin(Accumulate), Err(StageError::order(Accumulate, Gather)));
        c.begin(Gather).unwrap();
        c.finish(Gather);
        c.stats_mut().contributions = [3, 4];
        c.begin(Accumulate).unwrap();
        c.finish(Accumulate);
        assert_eq!(c.completed(), 1);
        assert_eq!(c.stats().iteration, 1);
        assert_eq!(c.stats().gathered(), 7, "the last iteration's stats stay readable");
        // The next iteration needs its own passes; the reads still see the last outputs.
        assert_eq!(c.begin(Gather), Err(StageError::order(Gather, CameraPass)));
        assert!(c.require_output(Call::ReadFootprints, PhotonPass).is_ok());
        c.begin(CameraPass).unwrap();
        assert_eq!(c.stats().gathered(), 0, "a new iteration starts new counts");
        assert_eq!(c.stats().iteration, 1);
    }

    #[test]
    fn device_times_total_only_when_every_iteration_was_measured() {
        let m = |ms: f64| DeviceTimes::Measured(StageTimes { camera: ms, photon: 2.0 * ms, build: 0.0, gather: 0.0, accumulate: 0.0 });
        let mut sum = IterationStats::default();
        sum.accumulate(&IterationStats::default());
        assert_eq!(sum.device_times, DeviceTimes::Host, "a host backend stays host");
        for ms in [1.0, 2.0] {
            sum.accumulate(&IterationStats { device_times: m(ms), ..Default::default() });
        }
        assert_eq!(sum.device_times, m(3.0));
        assert_eq!(sum.device_times.measured().map(StageTimes::total), Some(9.0));
        sum.accumulate(&IterationStats { device_times: DeviceTimes::Unavailable, ..Default::default() });
        sum.accumulate(&IterationStats { device_times: m(1.0), ..Default::default() });
        assert_eq!(sum.device_times, DeviceTimes::Unavailable, "one unmeasured iteration makes the total unavailable");
        assert_eq!(m(4.0).measured().unwrap().per(2).photon, 4.0);
        assert_eq!(m(4.0).measured().unwrap().of(Stage::PhotonPass), Some(8.0));
    }

    #[cfg(feature = "std")]
    #[test]
    fn run_times_a_finished_stage_and_leaves_a_failed_one_unfinished() {
        let mut c = StageClock::new();
        let failed: Result<(), StageError> = c.run(Stage::CameraPass, |_| Err(StageError::IterationLimit(0)));
        assert!(failed.is_err());
        assert!(!c.is_current(Stage::CameraPass), "a failed body does not finish the stage");
        let refused: Result<(), StageError> = c.run(Stage::Gather, |_| unreachable!("the order check runs first"));
        assert_eq!(refused, Err(StageError::order(Stage::Gather, Stage::CameraPass)));
        c.run::<StageError>(Stage::CameraPass, |clock| {
            clock.stats_mut().query_points = 3;
            std::thread::sleep(std::time::Duration::from_millis(2));
            Ok(())
        })
        .unwrap();
        assert!(c.is_current(Stage::CameraPass));
        assert_eq!(c.stats().query_points, 3);
        assert!(c.stats().times.camera >= 0.002, "the stage's time is its body's: {}", c.stats().times.camera);
        assert_eq!(c.stats().times.photon, 0.0, "no other stage's time is touched");
    }

    #[test]
    fn clock_stops_at_the_iteration_limit() {
        let mut c = StageClock::new();
        c.completed = u32::MAX - 1;
        assert_eq!(c.begin(Stage::CameraPass), Err(StageError::IterationLimit(u32::MAX - 1)));
        assert_eq!(c.begin(Stage::PhotonPass), Err(StageError::IterationLimit(u32::MAX - 1)));
        assert_eq!(StageError::order(Call::ReadImage, Stage::UploadScene).to_string(), "read_image called before upload_scene");
    }
}
