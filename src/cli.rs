//! The `arpa` command line: argument parsing (clap) and the `render` command.
//!
//! ```text
//! arpa render [SCENE.xml [-D name=value ...]] [--backend cpu|wgpu [--adapter NAME]] [--method arpa|rtpm] [--photons N]
//!             [--iterations N | --iterations A..B | --time SECONDS] [--resolution WxH] [--seed S]
//!             [--out PATH] [--no-direct] [--smoothing-caustic S_c] [--smoothing-global S_g]
//!             [--max-depth D] [--exposure E]
//!             [--reference REF.exr [--metrics-every N] [--metrics-csv FILE]]
//!             [--checkpoint STATE [--checkpoint-every N|Ns]] [--resume STATE]
//! arpa merge PART.arpastate... -o OUT [--exposure E]
//! ```
//!
//! **State files** ([`crate::state_file`]): `--checkpoint` saves the render's accumulation
//! atomically every `--checkpoint-every` iterations (`N`) or seconds (`Ns`) and at the end;
//! `--resume` continues a saved state (same scene, settings and seed; refused otherwise)
//! up to `--iterations` of the whole render, bit for bit as if it had not stopped.
//! `--iterations A..B` renders iterations `A` to `B − 1` of a render only (the same random
//! streams and radius schedule as a single run) and leaves `OUT.arpastate` beside the
//! image; `arpa merge` adds such parts (any order, no gaps or overlaps) into the image of
//! the whole range.
//!
//! With `--reference`, relMSE, SSIM and ꟻLIP ([`crate::metrics`]) of the accumulated image
//! against the reference are printed at checkpoints (every `--metrics-every` iterations,
//! by default at powers of two) and at the end, and `--metrics-csv` writes them as
//! `iteration,seconds,relmse,ssim,flip` rows; `seconds` is the render time up to that
//! iteration, excluding the time spent reading back images and computing metrics.
//!
//! The CLI is argument parsing and printing: the backend comes from the registry
//! ([`crate::backends`]), the render loop from [`crate::session`]. Every failure is an
//! error naming the problem (never a panic); `main` prints it and exits non-zero.

use crate::default_scene::default_scene;
use crate::image_io;
use anyhow::{Context, bail};
use arpa_core::propagate::classify::Smoothing;
use crate::backends::{self, BackendOptions};
use crate::session::{Budget, CheckpointRow, Checkpoints, Hooks, Reference, RenderOptions, Rendered, SaveEvery, SaveState, SessionOptions, StatTotals, auto_smoothing, render_with};
use arpa_core::propagate::classify::AutoSmoothing;
use crate::state_file::{RenderIdentity, StateFile};
use arpa_core::accumulate::image::Accumulation;
use arpa_core::render::tracer::{BackendKind, DeviceTimes, EmissionStrategy, Image, Method, RenderSettings, StageTimes};
use clap::{Args, Parser, Subcommand, ValueEnum};
use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
use std::io::IsTerminal;
use std::path::{Path, PathBuf};
use std::time::Duration;

pub use crate::session::{DEFAULT_ITERATIONS, DEFAULT_MAX_DEPTH};

/// Largest accepted image side (pixels).
pub const MAX_RESOLUTION: u32 = 16384;

/// `arpa`: progressive photon mapping with photon differentials.
#[derive(Debug, Parser)]
#[command(name = "arpa", version, about = "ARPA: progressive photon mapping with photon differentials", long_about = None)]
pub struct Cli {
    /// What to do.
    #[command(subcommand)]
    pub command: Command,
}

/// The subcommands.
#[derive(Debug, Subcommand)]
pub enum Command {
    /// Render a scene (the embedded Cornell box by default) to OpenEXR and PNG.
    Render(Box<RenderArgs>),
    /// Merge the state files of partial renders (`render --iterations A..B`) into the
    /// image of the whole range (OpenEXR and PNG) and its state file.
    Merge(MergeArgs),
    /// Run time against error over a sweep of scenes, methods, photon budgets and backends
    /// (with Mitsuba 3 peers at equal time): CSV, Table 2, plots and images in one directory.
    Bench(BenchArgs),
}

/// Arguments of `arpa bench`.
#[derive(Debug, Args)]
pub struct BenchArgs {
    /// The sweep's TOML config (e.g. `bench/table2.toml`, `bench/smoke.toml`).
    #[arg(value_name = "CONFIG.toml")]
    pub config: PathBuf,

    /// Output directory.
    #[arg(long, value_name = "DIR", default_value = "out/bench")]
    pub out: PathBuf,

    /// Wall-clock budget of each run in seconds [default: the config's].
    #[arg(long, allow_negative_numbers = true, value_name = "SECONDS", value_parser = parse_seconds)]
    pub seconds: Option<f64>,

    /// Seed of every run [default: the config's] (repeat a sweep with other seeds for its
    /// spread).
    #[arg(long, value_name = "SEED")]
    pub seed: Option<u32>,

    /// Python interpreter that runs the Mitsuba peers (`scripts/peer_mitsuba.py`).
    #[arg(long, value_name = "PYTHON", default_value = "python3")]
    pub python: String,

    /// Photon emission of every arpa run, as `render`'s.
    #[command(flatten)]
    pub emission: EmissionArgs,

    /// Skip the config's Mitsuba peers (e.g. for a second sweep that changes only our
    /// emission).
    #[arg(long)]
    pub no_peers: bool,

    /// Overrides the config's size: render at 1/N of each scene's film size (and no
    /// upscale), e.g. a paper-size config at a small size on lavapipe.
    #[arg(long, value_name = "N", value_parser = clap::value_parser!(u32).range(1..))]
    pub downscale: Option<u32>,

    /// Overrides the config's photons per iteration (comma-separated, one run each).
    #[arg(long, value_name = "N,...", value_delimiter = ',', value_parser = clap::value_parser!(u32).range(1..))]
    pub photons: Option<Vec<u32>>,
}

/// How the smoothing factors are chosen (`--smoothing`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum SmoothingMode {
    /// From a pilot iteration ([`arpa_core::propagate::classify::AutoSmoothing`]).
    Auto,
    /// The given factors.
    Fixed,
}

/// How photons are emitted (`--projection`, `--caustic-photons`), for `render` and `bench`.
#[derive(Debug, Args)]
pub struct EmissionArgs {
    /// Projection maps (arpa_core::render::projection): `on` sends global photons only where a
    /// light sees geometry and runs a caustic pass aimed at mirror and glass objects;
    /// `off` emits one pass over every light's whole domain.
    #[arg(long, value_enum, value_name = "MODE", default_value = "on")]
    pub projection: OnOff,

    /// Photons of the caustic pass per iteration [default: chosen from the power the
    /// lights send towards specular objects, arpa_core::render::emission_plan::auto_caustic_photons;
    /// 0 runs no caustic pass].
    #[arg(long, value_name = "N")]
    pub caustic_photons: Option<u32>,
}

impl EmissionArgs {
    /// The core's emission strategy these arguments select.
    pub fn strategy(&self) -> EmissionStrategy {
        EmissionStrategy { projection: self.projection == OnOff::On, caustic_photons: self.caustic_photons }
    }
}

/// The bandwidth on the command line (`--bandwidth`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum BandwidthArg {
    /// Each pixel picks its footprint scale from five nested scales (arpa_core::accumulate::bandwidth).
    PerPixel,
    /// One bandwidth for the whole image: the stored footprints as they are.
    Global,
}

impl From<BandwidthArg> for arpa_core::gather::scales::Bandwidth {
    fn from(b: BandwidthArg) -> Self {
        match b {
            BandwidthArg::PerPixel => arpa_core::gather::scales::Bandwidth::PerPixel,
            BandwidthArg::Global => arpa_core::gather::scales::Bandwidth::Global,
        }
    }
}

/// A switch on the command line.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum OnOff {
    /// On.
    On,
    /// Off.
    Off,
}

/// Density-estimation method on the command line.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum MethodArg {
    /// Photon differentials with the progressive-photon fallback (ARPA).
    Arpa,
    /// Progressive photon mapping with spherical photons (RTPM baseline).
    Rtpm,
}

impl From<MethodArg> for Method {
    fn from(m: MethodArg) -> Self {
        match m {
            MethodArg::Arpa => Method::Arpa,
            MethodArg::Rtpm => Method::Rtpm,
        }
    }
}

/// An image size in pixels.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Resolution {
    /// Width.
    pub width: u32,
    /// Height.
    pub height: u32,
}

/// Parses `WxH` (e.g. `512x512`); both sides in `1..=16384`.
pub fn parse_resolution(s: &str) -> Result<Resolution, String> {
    let bad = |why: &str| Err(format!("invalid resolution '{s}': {why}"));
    let Some((w, h)) = s.trim().split_once(['x', 'X']) else {
        return bad("expected WIDTHxHEIGHT, e.g. 512x512");
    };
    let (Ok(width), Ok(height)) = (w.trim().parse::<u32>(), h.trim().parse::<u32>()) else {
        return bad("width and height must be whole numbers, e.g. 512x512");
    };
    if width == 0 || height == 0 {
        return bad("width and height must be at least 1");
    }
    if width > MAX_RESOLUTION || height > MAX_RESOLUTION {
        return bad(&format!("width and height must be at most {MAX_RESOLUTION}"));
    }
    Ok(Resolution { width, height })
}

fn parse_positive_u32(s: &str) -> Result<u32, String> {
    match s.trim().parse::<u32>() {
        Ok(v) if v >= 1 => Ok(v),
        Ok(_) => Err(format!("'{s}' must be at least 1")),
        Err(_) => Err(format!("'{s}' is not a whole number between 1 and {}", u32::MAX)),
    }
}

fn parse_max_depth(s: &str) -> Result<u32, String> {
    match parse_positive_u32(s) {
        Ok(v) if v <= 1024 => Ok(v),
        Ok(_) => Err(format!("'{s}' is too deep (at most 1024)")),
        Err(e) => Err(e),
    }
}

fn parse_positive_f64(s: &str) -> Result<f64, String> {
    match s.trim().parse::<f64>() {
        Ok(v) if v.is_finite() && v > 0.0 => Ok(v),
        _ => Err(format!("'{s}' is not a positive finite number")),
    }
}

fn parse_seconds(s: &str) -> Result<f64, String> {
    match parse_positive_f64(s) {
        Ok(v) if v <= 1e7 => Ok(v),
        Ok(_) => Err(format!("'{s}' seconds is too long a time budget (at most 1e7)")),
        Err(e) => Err(e),
    }
}

fn parse_define_arg(s: &str) -> Result<(String, String), String> {
    crate::scene_file::parse_define(s).map_err(|e| e.to_string())
}

fn parse_positive_f32(s: &str) -> Result<f32, String> {
    match s.trim().parse::<f32>() {
        Ok(v) if v.is_finite() && v > 0.0 => Ok(v),
        _ => Err(format!("'{s}' is not a positive finite number")),
    }
}

fn parse_exposure(s: &str) -> Result<f32, String> {
    match s.trim().parse::<f32>() {
        Ok(v) if v.is_finite() && v >= 0.0 => Ok(v),
        _ => Err(format!("'{s}' is not a finite non-negative number")),
    }
}

/// Arguments of `arpa merge`.
#[derive(Debug, Args)]
pub struct MergeArgs {
    /// State files of the parts (`OUT.arpastate` of `arpa render --iterations A..B`).
    #[arg(value_name = "PART", required = true)]
    pub parts: Vec<PathBuf>,

    /// Output path: OUT.exr, OUT.png and OUT.arpastate are written (a .exr or .png
    /// extension given here is replaced).
    #[arg(short = 'o', long = "out", value_name = "OUT")]
    pub out: PathBuf,

    /// Multiplier applied to the radiance before the PNG's sRGB encoding.
    #[arg(long, allow_negative_numbers = true, value_name = "E", default_value_t = 1.0, value_parser = parse_exposure)]
    pub exposure: f32,
}

/// `--iterations`: a count `N` (iterations `0..N`) or a range `A..B` of a render's
/// iterations (0-based, `B` exclusive).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct IterationRange {
    /// First iteration.
    pub first: u32,
    /// One past the last iteration.
    pub end: u32,
    /// Whether it was given as a range (`A..B`): a partial render, which leaves a state
    /// file beside its image.
    pub partial: bool,
}

fn parse_iterations(s: &str) -> Result<IterationRange, String> {
    match s.split_once("..") {
        None => parse_positive_u32(s).map(|n| IterationRange { first: 0, end: n, partial: false }),
        Some((a, b)) => {
            let first = a.trim().parse::<u32>().map_err(|_| format!("'{a}' in '{s}' is not a whole number"))?;
            let end = b.trim().parse::<u32>().map_err(|_| format!("'{b}' in '{s}' is not a whole number"))?;
            if end <= first {
                return Err(format!("'{s}' is empty: A..B renders iterations A to B-1 and needs A < B"));
            }
            if end >= u32::MAX - 1 {
                return Err(format!("'{s}' goes beyond the iteration limit"));
            }
            Ok(IterationRange { first, end, partial: true })
        }
    }
}

/// `--checkpoint-every`: `N` iterations or `Ns` seconds.
fn parse_save_every(s: &str) -> Result<SaveEvery, String> {
    match s.trim().strip_suffix('s') {
        Some(secs) => parse_seconds(secs).map(|t| SaveEvery::Time(Duration::from_secs_f64(t))),
        None => parse_positive_u32(s).map(SaveEvery::Iterations).map_err(|e| format!("{e} (or seconds with an 's' suffix, e.g. '60s')")),
    }
}

/// Arguments of `arpa render`.
#[derive(Debug, Args)]
pub struct RenderArgs {
    /// Mitsuba 3 XML or glTF 2.0 (`.gltf`, `.glb`) scene file to render (see
    /// `arpa::scene_file` for the supported subsets); without it the embedded Cornell box
    /// with a glass sphere and a mirror block is rendered.
    #[arg(value_name = "SCENE")]
    pub scene: Option<PathBuf>,

    /// glTF scenes: the camera to render through, by its name or its node's name [default:
    /// the first camera].
    #[arg(long, value_name = "NAME")]
    pub camera: Option<String>,

    /// glTF scenes: factor on every KHR_lights_punctual light, for files whose light units
    /// are not the spec's candela and lux [default: 1].
    #[arg(long, value_name = "FACTOR", default_value_t = 1.0)]
    pub light_scale: f64,

    /// Overrides a `<default name=... value=...>` of the scene file (repeatable), e.g.
    /// `-D res_x=640` or `-Dres_x=640`.
    #[arg(short = 'D', value_name = "NAME=VALUE", value_parser = parse_define_arg, requires = "scene")]
    pub define: Vec<(String, String)>,

    /// Rendering backend (only those compiled in are accepted).
    #[arg(long, value_name = "NAME", default_value_t = BackendKind::Cpu, value_parser = backends::parse)]
    pub backend: BackendKind,

    /// GPU backends: use the adapter whose name contains NAME (case-insensitive), e.g.
    /// `llvmpipe` for lavapipe [default: a GPU with ray queries, else lavapipe].
    #[arg(long, value_name = "NAME")]
    pub adapter: Option<String>,

    /// Density-estimation method.
    #[arg(long, value_enum, default_value_t = MethodArg::Arpa)]
    pub method: MethodArg,

    /// Photons emitted per iteration.
    #[arg(long, allow_negative_numbers = true, value_name = "N", default_value_t = 250_000, value_parser = parse_positive_u32)]
    pub photons: u32,

    /// Number of iterations N, or the range A..B of a render's iterations to render (a
    /// part for `arpa merge`: iterations A to B-1, with the random streams and radii of a
    /// single run; OUT.arpastate is written beside the image) [default: 64].
    #[arg(long, allow_negative_numbers = true, value_name = "N|A..B", conflicts_with = "time", value_parser = parse_iterations)]
    pub iterations: Option<IterationRange>,

    /// Time budget in seconds instead of an iteration count: iterations run until it is
    /// spent (at least one; the last may overrun it).
    #[arg(long, allow_negative_numbers = true, value_name = "SECONDS", value_parser = parse_seconds)]
    pub time: Option<f64>,

    /// Image size WIDTHxHEIGHT [default: the scene file's film size, or 512x512 for the
    /// embedded scene].
    #[arg(long, value_name = "WxH", value_parser = parse_resolution)]
    pub resolution: Option<Resolution>,

    /// Seed of every random stream.
    #[arg(long, allow_negative_numbers = true, default_value_t = 0)]
    pub seed: u32,

    /// Output path: PATH.exr (linear radiance) and PATH.png (sRGB) are written; a .exr or
    /// .png extension given here is replaced.
    #[arg(long, value_name = "PATH", default_value = "out/render")]
    pub out: PathBuf,

    /// Disable next-event estimation (direct light then comes from the photon maps).
    #[arg(long)]
    pub no_direct: bool,

    /// Photon emission: projection maps and the caustic pass.
    #[command(flatten)]
    pub emission: EmissionArgs,

    /// Bandwidth: `per-pixel` (the gather evaluates five nested scales of every footprint
    /// and photon, down to a quarter of its size, and each pixel picks its scale from their
    /// bias and variance, arpa_core::accumulate::bandwidth) or `global` (one bandwidth for the image).
    #[arg(long, value_enum, value_name = "MODE", default_value = "per-pixel")]
    pub bandwidth: BandwidthArg,

    /// Also write OUT.scale.png: the footprint scale each pixel uses (per-pixel bandwidth),
    /// as a colour map with a legend.
    #[arg(long)]
    pub scale_map: bool,

    /// How ARPA's smoothing factors are chosen: `auto` (a pilot iteration at S = 1 picks
    /// S_c and S_g so that about 8 footprints of a map cover each point it lights,
    /// arpa_core::propagate::classify::AutoSmoothing) or `fixed` (--smoothing-caustic and
    /// --smoothing-global, 1 when not given) [default: auto, or fixed when either factor
    /// is given].
    #[arg(long, value_enum, value_name = "MODE")]
    pub smoothing: Option<SmoothingMode>,

    /// Smoothing factor S_c of caustic footprints (implies --smoothing fixed).
    #[arg(long, allow_negative_numbers = true, value_name = "S_C", value_parser = parse_positive_f64)]
    pub smoothing_caustic: Option<f64>,

    /// Smoothing factor S_g of global footprints (implies --smoothing fixed).
    #[arg(long, allow_negative_numbers = true, value_name = "S_G", value_parser = parse_positive_f64)]
    pub smoothing_global: Option<f64>,

    /// Maximum number of surface interactions of photon and camera paths [default: the
    /// scene file's integrator `max_depth` minus one (Mitsuba counts path segments, so
    /// `max_depth` 16 allows 15 surface interactions), or 10].
    #[arg(long, allow_negative_numbers = true, value_name = "N", value_parser = parse_max_depth)]
    pub max_depth: Option<u32>,

    /// Initial caustic radius of the progressive photons (scene units) [default: 0.01].
    #[arg(long, allow_negative_numbers = true, value_name = "R", value_parser = parse_positive_f64)]
    pub radius_caustic: Option<f64>,

    /// Initial global radius of the progressive photons (scene units) [default: 0.05].
    #[arg(long, allow_negative_numbers = true, value_name = "R", value_parser = parse_positive_f64)]
    pub radius_global: Option<f64>,

    /// Roughness cut-off of rough conductors and dielectrics, compared with their GGX
    /// `alpha`: at or above it diffuse, smoother perfectly specular [default: the scene's;
    /// 0.25 for scene files (RTPM's rule), 0.5 for the embedded scene].
    #[arg(long, allow_negative_numbers = true, value_name = "ALPHA", value_parser = parse_positive_f32)]
    pub roughness_cutoff: Option<f32>,

    /// Multiplier applied to the radiance before the PNG's sRGB encoding (the EXR is
    /// written unscaled).
    #[arg(long, allow_negative_numbers = true, value_name = "E", default_value_t = 1.0, value_parser = parse_exposure)]
    pub exposure: f32,

    /// Reference image (OpenEXR, linear radiance, same size as the render): relMSE, SSIM
    /// and FLIP against it are printed at checkpoints and at the end.
    #[arg(long, value_name = "FILE.exr")]
    pub reference: Option<PathBuf>,

    /// Evaluate the metrics every N iterations [default: at powers of two].
    #[arg(long, allow_negative_numbers = true, value_name = "N", requires = "reference", value_parser = parse_positive_u32)]
    pub metrics_every: Option<u32>,

    /// Write the metrics as CSV rows `iteration,seconds,relmse,ssim,flip`.
    #[arg(long, value_name = "FILE", requires = "reference")]
    pub metrics_csv: Option<PathBuf>,

    /// Save the render's state to STATE (atomically replaced) every --checkpoint-every and
    /// at the end, so that --resume STATE can continue it after a crash.
    #[arg(long, value_name = "STATE")]
    pub checkpoint: Option<PathBuf>,

    /// How often --checkpoint saves: every N iterations, or every N seconds with an 's'
    /// suffix (e.g. 60s) [default: 60s].
    #[arg(long, value_name = "N|Ns", requires = "checkpoint", value_parser = parse_save_every)]
    pub checkpoint_every: Option<SaveEvery>,

    /// Continue the render saved in STATE (by --checkpoint, or a part's OUT.arpastate):
    /// same scene, settings and seed, refused otherwise; --iterations is then the end of
    /// the whole render.
    #[arg(long, value_name = "STATE")]
    pub resume: Option<PathBuf>,
}

impl RenderArgs {
    /// Whether the smoothing factors are chosen automatically (`--smoothing`); an error when
    /// `--smoothing auto` comes with explicit factors.
    pub fn auto_smoothing(&self) -> anyhow::Result<bool> {
        let given = self.smoothing_caustic.is_some() || self.smoothing_global.is_some();
        match self.smoothing {
            Some(SmoothingMode::Auto) if given => bail!("--smoothing auto chooses S_c and S_g itself: drop --smoothing-caustic/--smoothing-global or use --smoothing fixed"),
            Some(mode) => Ok(mode == SmoothingMode::Auto),
            None => Ok(!given),
        }
    }

    /// The render options these arguments select (automatic smoothing aside: see
    /// [`RenderArgs::auto_smoothing`]).
    pub fn options(&self) -> RenderOptions {
        RenderOptions {
            method: self.method.into(),
            photons: self.photons,
            seed: self.seed,
            max_depth: self.max_depth,
            direct_lighting: !self.no_direct,
            emission: self.emission.strategy(),
            bandwidth: self.bandwidth.into(),
            smoothing: Smoothing { caustic: self.smoothing_caustic.unwrap_or(1.0), global: self.smoothing_global.unwrap_or(1.0) },
            radius_caustic: self.radius_caustic,
            radius_global: self.radius_global,
        }
    }

    /// The render settings these arguments select.
    pub fn settings(&self) -> RenderSettings {
        self.options().settings(None)
    }

    /// [`RenderArgs::settings`] for a scene file whose integrator asks for `max_depth`
    /// (Mitsuba's path depth in segments): without `--max-depth`, photon and camera paths
    /// get `max_depth - 1` surface interactions (at least 1).
    pub fn settings_for_file(&self, file_max_depth: Option<u32>) -> RenderSettings {
        self.options().settings(file_max_depth)
    }

    /// The iteration or time budget ([`Budget::Iterations`] is the end of the range).
    pub fn budget(&self) -> Budget {
        match (self.iterations, self.time) {
            (_, Some(t)) => Budget::Time(Duration::from_secs_f64(t)),
            (Some(r), None) => Budget::Iterations(r.end),
            (None, None) => Budget::Iterations(DEFAULT_ITERATIONS),
        }
    }
}

/// The files written for output path `out`: `(PATH.exr, PATH.png)`. A `.exr`/`.png`
/// extension on `out` is dropped first; any other extension is kept (`a.b` -> `a.b.exr`).
pub fn output_paths(out: &Path) -> anyhow::Result<(PathBuf, PathBuf)> {
    let s = out.as_os_str().to_string_lossy();
    if s.is_empty() || s.ends_with(std::path::MAIN_SEPARATOR) || s.ends_with('/') || out.is_dir() || out.file_name().is_none() {
        bail!("--out '{}' must name a file (without extension), not a directory", out.display());
    }
    let base = match out.extension().and_then(|e| e.to_str()) {
        Some(e) if e.eq_ignore_ascii_case("exr") || e.eq_ignore_ascii_case("png") => out.with_extension(""),
        _ => out.to_path_buf(),
    };
    let with = |ext: &str| {
        let mut p = base.clone().into_os_string();
        p.push(ext);
        PathBuf::from(p)
    };
    Ok((with(".exr"), with(".png")))
}

/// Progress reporting of a render: an indicatif bar on a terminal, nothing otherwise.
pub struct Progress {
    bar: ProgressBar,
}

impl Progress {
    /// A bar for `budget`, drawn on stderr if `visible`.
    pub fn new(budget: Budget, visible: bool) -> Self {
        let (len, template) = match budget {
            Budget::Iterations(n) => (n as u64, "{spinner} [{elapsed_precise}] {wide_bar} {pos}/{len} it  {msg}"),
            Budget::Time(t) => (t.as_millis().max(1) as u64, "{spinner} [{elapsed_precise}] {wide_bar} {msg}"),
        };
        let bar = ProgressBar::with_draw_target(Some(len), if visible { ProgressDrawTarget::stderr() } else { ProgressDrawTarget::hidden() });
        if let Ok(style) = ProgressStyle::with_template(template) {
            bar.set_style(style.progress_chars("=> "));
        }
        Self { bar }
    }

    /// A progress reporter that never draws.
    pub fn hidden() -> Self {
        Self::new(Budget::Iterations(1), false)
    }

    fn update(&self, budget: Budget, iterations: u32, elapsed: Duration, photons: u64) {
        let secs = elapsed.as_secs_f64().max(1e-9);
        let msg = format!("{:.2} it/s, {}photons/s", iterations as f64 / secs, si(photons as f64 / secs));
        match budget {
            Budget::Iterations(_) => self.bar.set_position(iterations as u64),
            Budget::Time(_) => {
                self.bar.set_position((elapsed.as_millis() as u64).min(self.bar.length().unwrap_or(u64::MAX)));
                self.bar.set_message(format!("{iterations} it, {msg}"));
                return;
            }
        }
        self.bar.set_message(msg);
    }

    fn finish(&self) {
        self.bar.finish_and_clear();
    }
}

/// `1234567.0` -> `"1.23 M"`.
fn si(v: f64) -> String {
    let (v, p) = if v >= 1e9 {
        (v / 1e9, "G")
    } else if v >= 1e6 {
        (v / 1e6, "M")
    } else if v >= 1e3 {
        (v / 1e3, "k")
    } else {
        (v, "")
    };
    format!("{v:.2} {p}")
}

/// What the photon pass skipped, one line each ("caustic pass (no specular surface)").
pub fn skipped_lines(k: &arpa_core::render::tracer::Skipped) -> Vec<String> {
    let mut out = Vec::new();
    if let Some(why) = k.caustic_pass {
        out.push(format!("caustic pass ({})", why.reason()));
    }
    if let Some(why) = k.global_pass {
        out.push(format!("global pass ({})", why.reason()));
    }
    if k.lights > 0 {
        out.push(format!("{} light(s) that reach no geometry", k.lights));
    }
    if k.power_fraction > 0.0 {
        out.push(format!("{:.2} % of the emitted power, sent where no geometry is", 100.0 * k.power_fraction));
    }
    out
}

/// The summary's device-time line: per stage the device's mean milliseconds per iteration
/// and the host's share of the iteration (host minus device time); `None` for a host
/// backend (cpu), whose stage times are its device times.
pub fn device_line(device: &DeviceTimes, host: &StageTimes) -> Option<String> {
    match device {
        DeviceTimes::Host => None,
        DeviceTimes::Unavailable => Some("device time: not available on this adapter (no timestamp queries)".into()),
        DeviceTimes::Measured(d) => Some(format!(
            "device per iteration camera {:.2} ms, photons {:.2} ms, AS build {:.2} ms, gather {:.2} ms, accumulate {:.2} ms (total {:.2} ms; host share {:.2} ms)",
            1e3 * d.camera,
            1e3 * d.photon,
            1e3 * d.build,
            1e3 * d.gather,
            1e3 * d.accumulate,
            1e3 * d.total(),
            1e3 * (host.total() - d.total())
        )),
    }
}

/// The human-readable statistics summary printed at the end of a render.
pub fn summary(r: &Rendered, settings: &RenderSettings) -> String {
    let t = &r.totals.sum;
    let secs = r.render_time.as_secs_f64().max(1e-9);
    let ms = |total: f64| 1e3 * total / r.totals.iterations.max(1) as f64;
    let m = |v: u64| format!("{:.0}", r.totals.mean(v));
    let mut s = String::new();
    s += &format!(
        "rendered {} iterations in {:.2} s ({:.2} it/s, {}photons/s) on backend '{}' ({}), method {}\n",
        r.iterations,
        secs,
        r.iterations as f64 / secs,
        si(t.photons_emitted as f64 / secs),
        r.capabilities.backend,
        r.capabilities.device,
        settings.method.name()
    );
    s += &format!("  photons emitted     {} per iteration, {} in total ({} segments per iteration)\n", m(t.photons_emitted), t.photons_emitted, m(t.photon_segments));
    if settings.emission.projection {
        s += &format!("  passes              caustic {} photons, global {} photons per iteration\n", m(t.emitted[0]), m(t.emitted[1]));
    }
    let per = t.records_per_photon();
    s += &format!("  records per photon  caustic {:.4}, global {:.4}\n", per[0], per[1]);
    for line in skipped_lines(&r.last.skipped) {
        s += &format!("  skipped: {line}\n");
    }
    s += &format!("  caustic map         {} footprints + {} progressive photons per iteration\n", m(t.footprints[0]), m(t.progressive[0]));
    s += &format!("  global map          {} footprints + {} progressive photons per iteration\n", m(t.footprints[1]), m(t.progressive[1]));
    s += &format!(
        "  fallbacks           {} degenerate, {} culled, {} unrepresentable per iteration; {} differentials lost, {} overflowed\n",
        m(t.degenerate),
        m(t.culled),
        m(t.unrepresentable),
        m(t.differential_lost),
        m(t.overflowed)
    );
    let (cand, contrib) = (t.candidates_per_query(), t.contributions_per_query());
    s += &format!("  query points        {} per iteration, {} containments gathered per iteration\n", m(t.query_points), m(t.gathered()));
    s += &format!(
        "  per query point     caustic {:.1} candidates, {:.1} contributions; global {:.1} candidates, {:.1} contributions\n",
        cand[0], contrib[0], cand[1], contrib[1]
    );
    s += &format!("  radii (last)        caustic {:.3e}, global {:.3e}\n", r.last.radii[0], r.last.radii[1]);
    s += &format!(
        "  mean per iteration  camera {:.2} ms, photons {:.2} ms, AS build {:.2} ms, gather {:.2} ms, accumulate {:.2} ms\n",
        ms(t.times.camera),
        ms(t.times.photon),
        ms(t.times.build),
        ms(t.times.gather),
        ms(t.times.accumulate)
    );
    if let Some(line) = device_line(&r.totals.mean_device_times(), &r.totals.mean_times()) {
        s += &format!("  {line}\n");
    }
    s += &format!("  total time          {:.2} s (render {:.2} s)", r.total_time.as_secs_f64(), secs);
    s
}

/// Runs the CLI.
pub fn run(cli: Cli) -> anyhow::Result<()> {
    match cli.command {
        Command::Render(args) => run_render(&args),
        Command::Merge(args) => run_merge(&args),
        Command::Bench(args) => run_bench(&args),
    }
}

/// `arpa bench`.
pub fn run_bench(args: &BenchArgs) -> anyhow::Result<()> {
    let mut cfg = crate::bench::config::LoadedConfig::load(&args.config)?;
    if let Some(k) = args.downscale {
        cfg.config.downscale = k;
        cfg.config.upscale = 1;
    }
    if let Some(p) = &args.photons {
        cfg.config.photons.clone_from(p);
    }
    let options = crate::bench::BenchOptions {
        out: args.out.clone(),
        seconds: args.seconds,
        seed: args.seed,
        python: args.python.clone(),
        emission: args.emission.strategy(),
        peers: !args.no_peers,
    };
    let results = crate::bench::run_bench(&cfg, &options)?;
    let skipped = results.iter().filter(|r| r.skipped.is_some()).count();
    if skipped > 0 {
        eprintln!("warning: {skipped} run(s) skipped (see the 'skipped' rows of runs.csv and table.md)");
    }
    eprintln!("wrote {}/runs.csv, table.md, plots/ and images/", args.out.display());
    Ok(())
}

/// `arpa render`.
pub fn run_render(args: &RenderArgs) -> anyhow::Result<()> {
    let (mut scene, file_max_depth) = match &args.scene {
        Some(path) => {
            let gltf = crate::scene_file::is_gltf(path);
            if !gltf && (args.camera.is_some() || args.light_scale != 1.0) {
                anyhow::bail!("--camera and --light-scale apply to glTF scenes; '{}' is not one", path.display());
            }
            let mut loaded = if gltf {
                let options = crate::scene_file::GltfOptions { camera: args.camera.clone(), light_scale: args.light_scale };
                crate::scene_file::load_gltf(path, &options)
            } else {
                crate::scene_file::load_scene(path, &args.define)
            }
            .with_context(|| format!("cannot load scene file '{}'", path.display()))?;
            for w in &loaded.warnings {
                eprintln!("warning: {w}");
            }
            if let Some(r) = args.resolution {
                loaded.set_resolution(r.width, r.height);
            }
            let s = &loaded.scene;
            eprintln!(
                "loaded {}: {} triangles in {} meshes, {} analytic lights, {} emissive meshes, {}x{} pixels",
                path.display(),
                loaded.triangle_count(),
                s.meshes.len(),
                s.lights.len(),
                s.meshes.iter().filter(|m| m.emission.is_some()).count(),
                s.camera.width,
                s.camera.height
            );
            loaded.scene.validate().with_context(|| format!("scene file '{}' is invalid", path.display()))?;
            (loaded.scene, loaded.max_depth)
        }
        None => {
            let mut scene = default_scene();
            if let Some(r) = args.resolution {
                scene.camera.width = r.width;
                scene.camera.height = r.height;
            }
            scene.validate().context("the embedded default scene is invalid")?;
            (scene, None)
        }
    };
    if let Some(c) = args.roughness_cutoff {
        scene.roughness_cutoff = c;
    }
    let mut settings = args.settings_for_file(file_max_depth);
    let auto = args.auto_smoothing()?;
    let budget = args.budget();
    let (exr_path, png_path) = output_paths(&args.out)?;
    if let Some(dir) = exr_path.parent().filter(|d| !d.as_os_str().is_empty()) {
        std::fs::create_dir_all(dir).with_context(|| format!("cannot create output directory '{}'", dir.display()))?;
    }

    let reference = match &args.reference {
        Some(path) => Some(Reference::load(path, scene.camera.width, scene.camera.height)?),
        None => None,
    };
    let csv = match (&reference, &args.metrics_csv) {
        (Some(_), Some(path)) => Some(MetricsCsv::create(path)?),
        _ => None,
    };
    let checkpoints = match (&reference, args.metrics_every) {
        (None, _) => Checkpoints::Never,
        (Some(_), Some(n)) => Checkpoints::Every(n),
        (Some(_), None) => Checkpoints::PowersOfTwo,
    };

    let options = BackendOptions { adapter: args.adapter.clone() };
    let mut tracer = backends::create(args.backend, &options)?;
    if auto && settings.method == Method::Arpa {
        let pilot = auto_smoothing(&mut tracer, &scene, &settings, &AutoSmoothing::default())?;
        settings.smoothing = pilot.smoothing;
        eprintln!(
            "automatic smoothing: S_c {:.3}, S_g {:.3} (pilot at S = 1: {:.2} caustic and {:.2} global footprints per lit query point; {:.2} s)",
            pilot.smoothing.caustic,
            pilot.smoothing.global,
            pilot.overlap_at_one[0],
            pilot.overlap_at_one[1],
            pilot.time.as_secs_f64()
        );
    }

    // Where the accumulation starts: a resumed state, the first iteration of a part, or 0.
    let identity = RenderIdentity::new(&scene, &settings, args.backend.name());
    let range = args.iterations.filter(|r| r.partial);
    let start = match (&args.resume, range) {
        (Some(path), _) => {
            let state = StateFile::read(path)?;
            identity.check(path, &state.identity)?;
            let a = state.accumulation;
            if let Some(r) = range
                && a.first_iteration != r.first
            {
                bail!("state file '{}' covers iterations {}..{}, not a continuation of the part {}..{}", path.display(), a.first_iteration, a.end(), r.first, r.end);
            }
            if let Budget::Iterations(end) = budget
                && a.end() > u64::from(end)
            {
                bail!("state file '{}' already covers iterations {}..{}, beyond --iterations {end}", path.display(), a.first_iteration, a.end());
            }
            eprintln!("resuming {}: iterations {}..{} accumulated", path.display(), a.first_iteration, a.end());
            Some(a)
        }
        (None, Some(r)) => Some(Accumulation::empty(scene.camera.width, scene.camera.height, r.first)),
        (None, None) => None,
    };
    let part_state = range.map(|_| exr_path.with_extension("arpastate"));
    let save_path = args.checkpoint.clone().or(part_state.clone());
    let save = save_path.as_deref().map(|path| SaveState {
        path,
        every: args.checkpoint_every.unwrap_or(SaveEvery::Time(Duration::from_secs(60))),
        identity: &identity,
    });

    let done = start.as_ref().map_or(0, |a| a.end() as u32);
    let shown = match budget {
        Budget::Iterations(end) => Budget::Iterations(end.saturating_sub(done)),
        b => b,
    };
    let progress = Progress::new(shown, std::io::stderr().is_terminal());
    let mut hooks = CliHooks { budget: shown, progress: &progress, csv };
    let session = SessionOptions { budget, checkpoints, reference: reference.as_ref(), resume: start.as_ref(), save, continued: false };
    let rendered = render_with(&mut tracer, &scene, &settings, &session, &mut hooks)?;
    progress.finish();
    if let Some(csv) = &mut hooks.csv {
        csv.finish()?;
    }

    let exr = image_io::write_exr(&exr_path, &rendered.image)?;
    let png = image_io::write_png(&png_path, &rendered.image, args.exposure)?;
    eprintln!("{}", summary(&rendered, &settings));
    if exr.non_finite_replaced > 0 || png.non_finite_replaced > 0 {
        eprintln!("warning: {} non-finite channel values were written as 0", exr.non_finite_replaced.max(png.non_finite_replaced));
    }
    eprintln!("wrote {} and {}", exr_path.display(), png_path.display());
    if args.scale_map {
        let path = exr_path.with_extension("scale.png");
        let selection = tracer.read_accumulation().map_err(|e| anyhow::anyhow!("cannot read the accumulation back for the scale map: {e}"))?.selection();
        crate::scale_map::write_scale_map(&path, rendered.image.width, rendered.image.height, &selection.scale)?;
        let share = crate::session::scale_share(&selection.scale);
        eprintln!("wrote {} (share of pixels per scale: {})", path.display(), share.map(|s| format!("{:.1} %", 100.0 * s)).join(", "));
    }
    if let Some(path) = &save_path {
        eprintln!("wrote state {}", path.display());
    }
    Ok(())
}

/// `arpa merge`.
pub fn run_merge(args: &MergeArgs) -> anyhow::Result<()> {
    let (exr_path, png_path) = output_paths(&args.out)?;
    let mut parts = Vec::with_capacity(args.parts.len());
    for path in &args.parts {
        parts.push((path, StateFile::read(path)?));
    }
    let (first_path, first) = &parts[0];
    for (path, part) in &parts[1..] {
        first.identity.check(path, &part.identity).with_context(|| format!("'{}' and '{}' are parts of different renders", first_path.display(), path.display()))?;
        if part.identity.backend != first.identity.backend {
            eprintln!(
                "warning: '{}' was rendered on backend '{}', '{}' on '{}': the merge is a valid estimate, but no single run reproduces it bit for bit",
                first_path.display(),
                first.identity.backend,
                path.display(),
                part.identity.backend
            );
        }
    }
    let accumulations: Vec<Accumulation> = parts.iter().map(|(_, p)| p.accumulation.clone()).collect();
    let merged = Accumulation::merge(&accumulations).context("cannot merge the parts")?;
    let image = Image { width: merged.width, height: merged.height, pixels: merged.mean() };
    if let Some(dir) = exr_path.parent().filter(|d| !d.as_os_str().is_empty()) {
        std::fs::create_dir_all(dir).with_context(|| format!("cannot create output directory '{}'", dir.display()))?;
    }
    image_io::write_exr(&exr_path, &image)?;
    image_io::write_png(&png_path, &image, args.exposure)?;
    let state_path = exr_path.with_extension("arpastate");
    let (first_iteration, end) = (merged.first_iteration, merged.end());
    StateFile { identity: first.identity.clone(), accumulation: merged }.write_atomic(&state_path)?;
    eprintln!("merged {} parts: iterations {first_iteration}..{end}", parts.len());
    eprintln!("wrote {}, {} and {}", exr_path.display(), png_path.display(), state_path.display());
    Ok(())
}

/// The CLI's view of a render: the progress bar, a metrics line per checkpoint on stderr
/// and the CSV rows.
struct CliHooks<'a> {
    budget: Budget,
    progress: &'a Progress,
    csv: Option<MetricsCsv>,
}

impl Hooks for CliHooks<'_> {
    fn iteration(&mut self, iterations: u32, render_time: Duration, totals: &StatTotals) {
        self.progress.update(self.budget, iterations, render_time, totals.sum.photons_emitted);
    }

    fn checkpoint(&mut self, row: &CheckpointRow, _: &Image) -> anyhow::Result<()> {
        if let Some(m) = row.metrics {
            self.progress.bar.suspend(|| eprintln!("iteration {:>6}  {:>9.3} s  relMSE {:.6e}  SSIM {:.6}  FLIP {:.6}", row.iteration, row.seconds, m.rel_mse, m.ssim, m.flip));
        }
        if let Some(csv) = &mut self.csv {
            csv.write(row)?;
        }
        Ok(())
    }
}

/// `--metrics-csv`: one `iteration,seconds,relmse,ssim,flip` row per checkpoint with
/// metrics (`seconds`: render time up to that iteration, excluding checkpoints).
pub struct MetricsCsv {
    path: PathBuf,
    writer: std::io::BufWriter<std::fs::File>,
}

impl MetricsCsv {
    /// Creates the file (and its directory) and writes the header.
    pub fn create(path: &Path) -> anyhow::Result<Self> {
        use std::io::Write;
        if let Some(dir) = path.parent().filter(|d| !d.as_os_str().is_empty()) {
            std::fs::create_dir_all(dir).with_context(|| format!("cannot create directory '{}'", dir.display()))?;
        }
        let file = std::fs::File::create(path).with_context(|| format!("cannot create metrics CSV '{}'", path.display()))?;
        let mut writer = std::io::BufWriter::new(file);
        writeln!(writer, "iteration,seconds,relmse,ssim,flip").with_context(|| format!("cannot write metrics CSV '{}'", path.display()))?;
        Ok(Self { path: path.to_path_buf(), writer })
    }

    /// Writes `row` (nothing for a row without metrics).
    pub fn write(&mut self, row: &CheckpointRow) -> anyhow::Result<()> {
        use std::io::Write;
        let Some(m) = row.metrics else { return Ok(()) };
        writeln!(self.writer, "{},{:.6},{:.9e},{:.9},{:.9}", row.iteration, row.seconds, m.rel_mse, m.ssim, m.flip).with_context(|| format!("cannot write metrics CSV '{}'", self.path.display()))
    }

    /// Flushes the file.
    pub fn finish(&mut self) -> anyhow::Result<()> {
        use std::io::Write;
        self.writer.flush().with_context(|| format!("cannot write metrics CSV '{}'", self.path.display()))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use arpa_core::accumulate::radius::RadiusSpec;

    #[test]
    fn summary_reports_counts_and_stage_times() {
        use crate::session::{Rendered, StatTotals};
        use arpa_core::render::tracer::{Capabilities, IterationStats};
        let mut totals = StatTotals::default();
        let mut it = IterationStats { photons_emitted: 1000, footprints: [10, 20], progressive: [1, 2], degenerate: 3, ..Default::default() };
        it.times.gather = 0.002;
        for _ in 0..5 {
            totals.add(&it);
        }
        let r = Rendered {
            image: Image { width: 1, height: 1, pixels: vec![Default::default()] },
            iterations: 5,
            totals,
            last: it,
            capabilities: Capabilities { backend: BackendKind::Cpu, device: "test".into(), methods: vec![Method::Arpa], max_photons_per_iteration: None, deterministic: true },
            rows: vec![],
            render_time: Duration::from_secs(1),
            checkpoint_time: Duration::ZERO,
            total_time: Duration::from_secs(1),
            stopped: false,
        };
        let text = summary(&r, &RenderSettings::default());
        assert!(text.contains("rendered 5 iterations") && text.contains("10 footprints") && text.contains("gather 2.00 ms") && text.contains("backend 'cpu'"), "{text}");
        assert!(!text.contains("device"), "a host backend has no device line: {text}");
    }

    #[test]
    fn device_line_gives_device_ms_and_the_host_share_or_says_it_is_unavailable() {
        let host = StageTimes { camera: 0.001, photon: 0.004, build: 0.001, gather: 0.003, accumulate: 0.001 };
        let device = StageTimes { camera: 0.0005, photon: 0.002, build: 0.0005, gather: 0.002, accumulate: 0.0 };
        assert_eq!(device_line(&DeviceTimes::Host, &host), None);
        let line = device_line(&DeviceTimes::Measured(device), &host).unwrap();
        assert!(line.contains("camera 0.50 ms, photons 2.00 ms") && line.contains("total 5.00 ms; host share 5.00 ms"), "{line}");
        assert_eq!(device_line(&DeviceTimes::Unavailable, &host).unwrap(), "device time: not available on this adapter (no timestamp queries)");
    }

    #[test]
    fn metrics_csv_writes_rows_with_metrics() {
        use crate::metrics::Metrics;
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("sub/m.csv");
        let mut csv = MetricsCsv::create(&path).unwrap();
        let row = |iteration, metrics| CheckpointRow { iteration, seconds: 1.5, metrics, ..Default::default() };
        csv.write(&row(2, None)).unwrap();
        csv.write(&row(3, Some(Metrics { rel_mse: 0.0, ssim: 1.0, flip: 0.0 }))).unwrap();
        csv.finish().unwrap();
        let text = std::fs::read_to_string(&path).unwrap();
        assert_eq!(text.lines().next(), Some("iteration,seconds,relmse,ssim,flip"));
        assert_eq!(text.lines().count(), 2, "{text}");
        assert!(text.lines().nth(1).unwrap().starts_with("3,1.500000,0.0"), "{text}");
    }

    #[test]
    fn argument_parsers() {
        assert_eq!(parse_resolution("640x480"), Ok(Resolution { width: 640, height: 480 }));
        assert_eq!(parse_resolution(" 3X2 "), Ok(Resolution { width: 3, height: 2 }));
        for bad in ["0x5", "5x0", "x", "12", "axb", "-1x4", "20000x1"] {
            let e = parse_resolution(bad).unwrap_err();
            assert!(e.contains(bad.trim()), "{e}");
        }
        assert!(parse_positive_f64("0").is_err() && parse_positive_f64("nan").is_err() && parse_positive_f64("2.5") == Ok(2.5));
        assert!(parse_exposure("-1").is_err() && parse_exposure("inf").is_err() && parse_exposure("0") == Ok(0.0));
    }

    #[test]
    fn output_paths_append_extensions() {
        let p = |s: &str| output_paths(Path::new(s)).map(|(a, b)| (a.display().to_string(), b.display().to_string()));
        assert_eq!(p("out/render").unwrap(), ("out/render.exr".into(), "out/render.png".into()));
        assert_eq!(p("out/render.exr").unwrap(), ("out/render.exr".into(), "out/render.png".into()));
        assert_eq!(p("a.v2").unwrap(), ("a.v2.exr".into(), "a.v2.png".into()));
        assert!(p("").is_err());
        assert!(p("out/").is_err());
    }

    #[test]
    #[cfg(feature = "cpu")] // the default backend must be compiled in
    fn cli_parses_defaults_and_rejects_conflicts() {
        let cli = Cli::try_parse_from(["arpa", "render"]).unwrap();
        let Command::Render(a) = cli.command else { panic!("render") };
        assert_eq!(a.budget(), Budget::Iterations(DEFAULT_ITERATIONS));
        assert_eq!(a.photons, 250_000);
        assert_eq!(a.out, PathBuf::from("out/render"));
        let s = a.settings();
        assert!(s.direct_lighting && s.method == Method::Arpa);
        assert!(Cli::try_parse_from(["arpa", "render", "--iterations", "1", "--time", "1"]).is_err());
        assert!(Cli::try_parse_from(["arpa", "render", "--photons", "0"]).is_err());
        let cli = Cli::try_parse_from(["arpa", "render", "--time", "2.5", "--no-direct", "--method", "rtpm", "--smoothing-caustic", "2"]).unwrap();
        let Command::Render(a) = cli.command else { panic!("render") };
        assert_eq!(a.budget(), Budget::Time(Duration::from_secs_f64(2.5)));
        let s = a.settings();
        assert!(!s.direct_lighting && s.method == Method::Rtpm && s.smoothing.caustic == 2.0);
    }

    #[test]
    #[cfg(feature = "cpu")]
    fn cli_radii_depth_and_cutoff() {
        let parse = |args: &[&str]| {
            let mut v = vec!["arpa", "render"];
            v.extend_from_slice(args);
            let Command::Render(a) = Cli::try_parse_from(v).unwrap().command else { panic!("render") };
            a
        };
        let a = parse(&[]);
        assert_eq!(a.settings().radii, RenderSettings::default().radii);
        assert_eq!(a.settings().max_depth, DEFAULT_MAX_DEPTH);
        // Mitsuba's max_depth counts segments: 16 -> 15 surface interactions.
        assert_eq!(a.settings_for_file(Some(16)).max_depth, 15);
        assert_eq!(a.settings_for_file(Some(1)).max_depth, 1);
        assert_eq!(a.settings_for_file(None).max_depth, DEFAULT_MAX_DEPTH);
        let a = parse(&["--radius-caustic", "0.03", "--radius-global", "0.09", "--max-depth", "7", "--roughness-cutoff", "0.2"]);
        let s = a.settings_for_file(Some(16));
        assert_eq!(s.max_depth, 7, "--max-depth wins over the file");
        assert_eq!(s.radii.caustic, RadiusSpec::Absolute(0.03));
        assert_eq!(s.radii.global, RadiusSpec::Absolute(0.09));
        assert_eq!(s.radii.alpha, RenderSettings::default().radii.alpha);
        assert_eq!(a.roughness_cutoff, Some(0.2));
        for bad in [&["--radius-caustic", "0"][..], &["--radius-global", "-1"], &["--roughness-cutoff", "nan"], &["--roughness-cutoff", "0"]] {
            let mut v = vec!["arpa", "render"];
            v.extend_from_slice(bad);
            assert!(Cli::try_parse_from(v).is_err(), "{bad:?} must be rejected");
        }
    }
}
