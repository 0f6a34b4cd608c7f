//! The TOML configuration of `arpa bench`: what to sweep and where the scenes are.

use anyhow::{Context, bail};
use arpa_core::tracer::{BackendKind, Method};
use serde::Deserialize;
use std::path::{Path, PathBuf};

/// A benchmark sweep: every scene × backend × method × photon budget, each rendered for the
/// same wall-clock budget, plus the equal-time peers per scene.
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct BenchConfig {
    /// Name of the sweep (titles of the outputs).
    pub name: String,
    /// Wall-clock budget of each run, seconds (the paper: 10).
    #[serde(default = "default_seconds")]
    pub seconds: f64,
    /// Host threads of the CPU backend and of the peers (default: every core).
    #[serde(default)]
    pub threads: Option<usize>,
    /// Seed of every run.
    #[serde(default)]
    pub seed: u32,
    /// Backends to run (names as `--backend`).
    #[serde(default = "default_backends")]
    pub backends: Vec<String>,
    /// Methods to run (`arpa`, `rtpm`).
    #[serde(default = "default_methods")]
    pub methods: Vec<String>,
    /// Photons per iteration, one run each (the paper: 50k, 250k, 1000k).
    pub photons: Vec<u32>,
    /// Mitsuba 3 integrators run at the same wall-clock budget (`ptracer`, `path`).
    #[serde(default)]
    pub peers: Vec<String>,
    /// Directory of the scenes, relative to the config file (env `ARPA_SHARED_SCENES`
    /// overrides it).
    #[serde(default = "default_scenes_dir")]
    pub scenes_dir: PathBuf,
    /// Render at `1/downscale` of each scene's film size and compare with the reference
    /// box-averaged `downscale × downscale` (1: full size).
    #[serde(default = "default_downscale")]
    pub downscale: u32,
    /// The scenes.
    #[serde(rename = "scene")]
    pub scenes: Vec<SceneEntry>,
}

/// One scene of a sweep, with its per-scene options.
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SceneEntry {
    /// Short name (file names, table rows).
    pub name: String,
    /// Mitsuba XML file, relative to the scenes directory.
    pub file: PathBuf,
    /// Independent reference (OpenEXR at the film size), relative to the scenes directory.
    pub reference: PathBuf,
    /// Smoothing factor `S_c`.
    #[serde(default)]
    pub smoothing_caustic: Option<f64>,
    /// Smoothing factor `S_g`.
    #[serde(default)]
    pub smoothing_global: Option<f64>,
    /// Initial caustic radius (scene units).
    #[serde(default)]
    pub radius_caustic: Option<f64>,
    /// Initial global radius (scene units).
    #[serde(default)]
    pub radius_global: Option<f64>,
}

fn default_seconds() -> f64 {
    10.0
}
fn default_backends() -> Vec<String> {
    vec![BackendKind::Cpu.name().into()]
}
fn default_methods() -> Vec<String> {
    vec!["arpa".into(), "rtpm".into()]
}
fn default_scenes_dir() -> PathBuf {
    PathBuf::from("../../shared/scenes")
}
fn default_downscale() -> u32 {
    1
}

/// A config read from a file, checked, with its paths resolved.
#[derive(Clone, Debug)]
pub struct LoadedConfig {
    /// The config.
    pub config: BenchConfig,
    /// The config file.
    pub path: PathBuf,
    /// SHA-256 of the file's bytes (hex), in every output's header.
    pub hash: String,
    /// The scenes directory.
    pub scenes_dir: PathBuf,
    /// Backends, in sweep order.
    pub backends: Vec<BackendKind>,
    /// Methods, in sweep order.
    pub methods: Vec<BenchMethod>,
}

/// A method of the sweep: `arpa` (the scene's `S_c`, `S_g`), `arpa-auto` (automatic
/// smoothing from a pilot iteration, [`crate::session::auto_smoothing`]) or `rtpm`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum BenchMethod {
    /// ARPA with the scene entry's smoothing factors.
    Arpa,
    /// ARPA with automatic smoothing.
    ArpaAuto,
    /// RTPM.
    Rtpm,
}

impl BenchMethod {
    /// The core's method.
    pub fn method(self) -> Method {
        match self {
            BenchMethod::Arpa | BenchMethod::ArpaAuto => Method::Arpa,
            BenchMethod::Rtpm => Method::Rtpm,
        }
    }

    /// Whether the smoothing is chosen automatically.
    pub fn auto_smoothing(self) -> bool {
        self == BenchMethod::ArpaAuto
    }

    /// The config and label name: `arpa`, `arpa-auto`, `rtpm`.
    pub fn name(self) -> &'static str {
        match self {
            BenchMethod::Arpa => "arpa",
            BenchMethod::ArpaAuto => "arpa-auto",
            BenchMethod::Rtpm => "rtpm",
        }
    }

    /// The name in the Table-2 layout: `ARPA`, `ARPA auto`, `RTPM`.
    pub fn title(self) -> &'static str {
        match self {
            BenchMethod::Arpa => "ARPA",
            BenchMethod::ArpaAuto => "ARPA auto",
            BenchMethod::Rtpm => "RTPM",
        }
    }
}

impl LoadedConfig {
    /// Reads and checks `path`. Errors name the file and the field.
    pub fn load(path: &Path) -> anyhow::Result<Self> {
        let text = std::fs::read_to_string(path).with_context(|| format!("cannot read bench config '{}'", path.display()))?;
        let config: BenchConfig = toml::from_str(&text).with_context(|| format!("bench config '{}' is invalid", path.display()))?;
        let bad = |why: String| -> anyhow::Result<Self> { bail!("bench config '{}': {why}", path.display()) };
        if !(config.seconds.is_finite() && config.seconds > 0.0) {
            return bad(format!("seconds must be positive (got {})", config.seconds));
        }
        if config.photons.is_empty() || config.photons.contains(&0) {
            return bad("photons must list at least one photon count, each at least 1".into());
        }
        if config.scenes.is_empty() {
            return bad("no [[scene]]".into());
        }
        if config.downscale == 0 {
            return bad("downscale must be at least 1".into());
        }
        if config.threads == Some(0) {
            return bad("threads must be at least 1".into());
        }
        let mut backends = Vec::new();
        for b in &config.backends {
            match crate::backends::parse(b) {
                Ok(k) => backends.push(k),
                Err(e) => return bad(e),
            }
        }
        let mut methods = Vec::new();
        for m in &config.methods {
            match m.to_ascii_lowercase().as_str() {
                "arpa" => methods.push(BenchMethod::Arpa),
                "arpa-auto" => methods.push(BenchMethod::ArpaAuto),
                "rtpm" => methods.push(BenchMethod::Rtpm),
                _ => return bad(format!("unknown method '{m}' (arpa, arpa-auto, rtpm)")),
            }
        }
        for p in &config.peers {
            if !matches!(p.as_str(), "ptracer" | "path") {
                return bad(format!("unknown peer '{p}' (Mitsuba 3 integrators: ptracer, path)"));
            }
        }
        for s in &config.scenes {
            for (name, v) in [("smoothing_caustic", s.smoothing_caustic), ("smoothing_global", s.smoothing_global), ("radius_caustic", s.radius_caustic), ("radius_global", s.radius_global)] {
                if let Some(v) = v
                    && !(v.is_finite() && v > 0.0)
                {
                    return bad(format!("scene '{}': {name} must be positive and finite (got {v})", s.name));
                }
            }
        }
        let scenes_dir = match std::env::var_os("ARPA_SHARED_SCENES").filter(|d| !d.is_empty()) {
            Some(d) => PathBuf::from(d),
            None => path.parent().unwrap_or(Path::new(".")).join(&config.scenes_dir),
        };
        use sha2::Digest;
        let hash = sha2::Sha256::digest(text.as_bytes()).iter().map(|b| format!("{b:02x}")).collect();
        Ok(Self { config, path: path.to_path_buf(), hash, scenes_dir, backends, methods })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn load(text: &str) -> anyhow::Result<LoadedConfig> {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("b.toml");
        std::fs::write(&path, text).unwrap();
        LoadedConfig::load(&path)
    }

    const OK: &str = r#"
name = "t"
photons = [1000]
[[scene]]
name = "c"
file = "c/scene.xml"
reference = "c/ref.exr"
smoothing_caustic = 0.5
"#;

    #[test]
    fn a_config_loads_with_defaults_and_a_hash() {
        let c = load(OK).unwrap();
        assert_eq!(c.config.seconds, 10.0);
        assert_eq!(c.methods, vec![BenchMethod::Arpa, BenchMethod::Rtpm]);
        assert_eq!(c.hash.len(), 64);
        assert_eq!(c.config.scenes[0].smoothing_caustic, Some(0.5));
    }

    #[test]
    fn bad_configs_name_the_problem() {
        for (text, needle) in [
            (OK.replace("photons = [1000]", "photons = []"), "photons"),
            (OK.replace("name = \"t\"", "name = \"t\"\nseconds = -1"), "seconds"),
            (OK.replace("name = \"t\"", "name = \"t\"\nmethods = [\"ppm\"]"), "unknown method 'ppm'"),
            (OK.replace("name = \"t\"", "name = \"t\"\npeers = [\"bdpt\"]"), "unknown peer 'bdpt'"),
            (OK.replace("name = \"t\"", "name = \"t\"\nbackends = [\"quantum\"]"), "unknown backend 'quantum'"),
            (OK.replace("smoothing_caustic = 0.5", "smoothing_caustic = 0.0"), "smoothing_caustic"),
            (OK.replace("name = \"t\"", "name = \"t\"\ncolour = 1"), "colour"),
        ] {
            let e = format!("{:#}", load(&text).unwrap_err());
            assert!(e.contains(needle) && e.contains("b.toml"), "{needle}: {e}");
        }
    }
}
