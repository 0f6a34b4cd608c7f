//! What a bench run produces: the rows of `table.csv`, each run's result and the
//! header that says where and with what it ran (`report` writes them).

use super::config::BenchMethod;
use crate::session::CheckpointRow;
use arpa_core::render::tracer::{DeviceTimes, StageTimes};

/// What produced a row: one of ours or a peer.
#[derive(Clone, Debug, PartialEq)]
pub enum RunKind {
    /// An arpa render.
    Arpa {
        /// Backend name.
        backend: String,
        /// Method.
        method: BenchMethod,
        /// Photons per iteration.
        photons: u32,
    },
    /// A Mitsuba 3 integrator (`ptracer`, `path`).
    Peer {
        /// Integrator name.
        integrator: String,
    },
}

impl RunKind {
    /// The label of a line in the plots and of a column in the table, e.g. `arpa E-250K`,
    /// `mitsuba ptracer`.
    pub fn label(&self) -> String {
        match self {
            RunKind::Arpa { method, photons, .. } => format!("{} E-{}", method.name(), budget_label(*photons)),
            RunKind::Peer { integrator } => format!("mitsuba {integrator}"),
        }
    }

    /// A file-name stem, e.g. `arpa-E250K-cpu`, `mitsuba-ptracer`.
    pub fn stem(&self) -> String {
        match self {
            RunKind::Arpa { backend, method, photons } => format!("{}-E{}-{backend}", method.name(), budget_label(*photons)),
            RunKind::Peer { integrator } => format!("mitsuba-{integrator}"),
        }
    }
}

/// `50000` -> `50K`, `1000000` -> `1000K` (the paper's E-50K, E-1000K).
pub fn budget_label(photons: u32) -> String {
    if photons.is_multiple_of(1000) { format!("{}K", photons / 1000) } else { photons.to_string() }
}

/// One checkpoint of one run.
#[derive(Clone, Debug, PartialEq)]
pub struct BenchRow {
    /// Scene name.
    pub scene: String,
    /// The run.
    pub kind: RunKind,
    /// Iterations (arpa) or passes (peer) so far.
    pub iteration: u32,
    /// Render time so far (seconds).
    pub seconds: f64,
    /// relMSE against the reference.
    pub rel_mse: f64,
    /// SSIM against the reference.
    pub ssim: f64,
    /// FLIP against the reference.
    pub flip: f64,
    /// Whole-image mean over the reference's.
    pub mean_ratio: f64,
    /// Mean per-iteration stage times (seconds, host wall clock; zero for peers).
    pub times: StageTimes,
    /// Mean per-iteration device time of each stage ([`DeviceTimes::Host`] for the cpu
    /// backend and the peers).
    pub device_times: DeviceTimes,
    /// Gather candidates per valid query point, `[caustic, global]` (zero for peers).
    pub candidates_per_query: [f64; 2],
    /// Gather contributions per valid query point, `[caustic, global]` (zero for peers).
    pub contributions_per_query: [f64; 2],
    /// relMSE inside the scene's caustic region (`None` without one).
    pub region_rel_mse: Option<f64>,
    /// Share of the pixels per scale of a per-pixel bandwidth run
    /// ([`crate::session::CheckpointRow::scale_share`]; `None` otherwise).
    pub scale_share: Option<[f64; arpa_core::gather::scales::SCALES]>,
    /// The photon passes' rates (`None` for peers).
    pub photons: Option<PhotonRates>,
}

/// What the photon passes of an arpa run stored, summed from its first iteration to a
/// checkpoint.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PhotonRates {
    /// Records stored per photon emitted (both passes), `[caustic, global]` map.
    pub records_per_photon: [f64; 2],
    /// Mean photons emitted per iteration, `[caustic pass, global pass]`.
    pub emitted_per_iteration: [f64; 2],
    /// Caustic-map records (footprints and progressive photons) stored per second of render
    /// time (the checkpoint's `seconds`).
    pub caustic_records_per_second: f64,
}

impl PhotonRates {
    /// The rates of a session checkpoint.
    pub fn of(row: &CheckpointRow) -> Self {
        Self {
            records_per_photon: row.records_per_photon,
            emitted_per_iteration: row.emitted_per_iteration,
            caustic_records_per_second: if row.seconds > 0.0 { row.records[0] as f64 / row.seconds } else { 0.0 },
        }
    }
}

/// The outcome of one run.
#[derive(Clone, Debug)]
pub struct RunResult {
    /// Scene name.
    pub scene: String,
    /// The run.
    pub kind: RunKind,
    /// Its checkpoints, the last one the final image (empty when skipped).
    pub rows: Vec<BenchRow>,
    /// Why it did not run (a peer that is not installed).
    pub skipped: Option<String>,
}

impl RunResult {
    /// The final checkpoint.
    pub fn last(&self) -> Option<&BenchRow> {
        self.rows.last()
    }
}

/// What every output's header says.
#[derive(Clone, Debug)]
pub struct Header {
    /// Sweep name.
    pub name: String,
    /// Host name and OS.
    pub machine: String,
    /// CPU model.
    pub cpu: String,
    /// Host threads the runs used.
    pub threads: usize,
    /// `backend: device` of each backend run.
    pub devices: Vec<String>,
    /// `git describe`-style commit of the working tree.
    pub commit: String,
    /// SHA-256 of the config file.
    pub config_hash: String,
    /// Wall-clock budget of each run (seconds).
    pub seconds: f64,
    /// The photon emission of our runs ([`arpa_core::render::tracer::EmissionStrategy`]).
    pub emission: arpa_core::render::tracer::EmissionStrategy,
}

impl Header {
    /// The header as `key: value` lines.
    pub fn lines(&self) -> Vec<String> {
        vec![
            format!("bench: {}", self.name),
            format!("machine: {}", self.machine),
            format!("cpu: {}", self.cpu),
            format!("threads: {} (pinned)", self.threads),
            format!("devices: {}", self.devices.join("; ")),
            format!("commit: {}", self.commit),
            format!("config sha256: {}", self.config_hash),
            format!("budget per run: {} s", self.seconds),
            format!(
                "emission: projection {}, caustic photons {}",
                if self.emission.projection { "on" } else { "off" },
                self.emission.caustic_photons.map_or("auto".to_string(), |n| n.to_string())
            ),
        ]
    }
}
