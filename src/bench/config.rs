//! The TOML configuration of `arpa bench`: what to sweep and where the scenes are.

use crate::metrics::PixelRect;
use anyhow::{Context, bail};
use arpa_core::render::tracer::{BackendKind, Method};
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
    /// overrides it; a scene's own `dir` overrides both).
    #[serde(default = "default_scenes_dir")]
    pub scenes_dir: PathBuf,
    /// Render at `1/downscale` of each scene's film size and compare with the reference
    /// box-averaged `downscale × downscale` (1: full size).
    #[serde(default = "default_downscale")]
    pub downscale: u32,
    /// Render at `upscale` times each scene's film size and compare the render box-averaged
    /// `upscale × upscale` with the reference (1: full size; with `downscale` 1 only). For
    /// timing at sizes beyond the references' (the paper's 1920×1080).
    #[serde(default = "default_downscale")]
    pub upscale: u32,
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
    /// Directory of this scene's `file` and `reference`, relative to the config file (or
    /// absolute), instead of the sweep's scenes directory; `ARPA_SHARED_SCENES` does not
    /// change it. For scenes kept in the repository (`bench/scenes/`).
    #[serde(default)]
    pub dir: Option<PathBuf>,
    /// Mitsuba XML file, relative to the scenes directory.
    pub file: PathBuf,
    /// Independent reference (OpenEXR at the film size), relative to the scenes directory.
    pub reference: PathBuf,
    /// Pixel rectangle `[x0, y0, x1, y1]` of the caustic on the film at full size (x right,
    /// y down, half-open), where `region_relmse` is measured; with `downscale`, every
    /// pixel of the smaller film that it overlaps ([`crate::metrics::PixelRect::downscaled`]).
    #[serde(default)]
    pub caustic_region: Option<[u32; 4]>,
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

impl SceneEntry {
    /// The caustic region at full size (checked at load: not empty).
    pub fn region(&self) -> Option<PixelRect> {
        self.caustic_region.and_then(|r| PixelRect::new(r).ok())
    }
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
    /// ARPA with automatic smoothing and one bandwidth for the whole image.
    ArpaAuto,
    /// ARPA with automatic smoothing of the stored scale and a per-pixel bandwidth
    /// ([`arpa_core::accumulate::bandwidth`]).
    ArpaPerPixel,
    /// RTPM.
    Rtpm,
}

impl BenchMethod {
    /// The core's method.
    pub fn method(self) -> Method {
        match self {
            BenchMethod::Arpa | BenchMethod::ArpaAuto | BenchMethod::ArpaPerPixel => Method::Arpa,
            BenchMethod::Rtpm => Method::Rtpm,
        }
    }

    /// Whether the smoothing is chosen automatically.
    pub fn auto_smoothing(self) -> bool {
        matches!(self, BenchMethod::ArpaAuto | BenchMethod::ArpaPerPixel)
    }

    /// The bandwidth: per-pixel for `arpa-pp`, global for the others (the baselines it is
    /// compared with).
    pub fn bandwidth(self) -> arpa_core::gather::scales::Bandwidth {
        match self {
            BenchMethod::ArpaPerPixel => arpa_core::gather::scales::Bandwidth::PerPixel,
            _ => arpa_core::gather::scales::Bandwidth::Global,
        }
    }

    /// The config and label name: `arpa`, `arpa-auto`, `arpa-pp`, `rtpm`.
    pub fn name(self) -> &'static str {
        match self {
            BenchMethod::Arpa => "arpa",
            BenchMethod::ArpaAuto => "arpa-auto",
            BenchMethod::ArpaPerPixel => "arpa-pp",
            BenchMethod::Rtpm => "rtpm",
        }
    }

    /// The name in the Table-2 layout: `ARPA`, `ARPA auto`, `RTPM`.
    pub fn title(self) -> &'static str {
        match self {
            BenchMethod::Arpa => "ARPA",
            BenchMethod::ArpaAuto => "ARPA auto",
            BenchMethod::ArpaPerPixel => "ARPA per-pixel",
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
        if config.downscale == 0 || config.upscale == 0 {
            return bad("downscale and upscale must be at least 1".into());
        }
        if config.downscale > 1 && config.upscale > 1 {
            return bad(format!("downscale {} and upscale {}: set one of them", config.downscale, config.upscale));
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
                "arpa-pp" => methods.push(BenchMethod::ArpaPerPixel),
                "rtpm" => methods.push(BenchMethod::Rtpm),
                _ => return bad(format!("unknown method '{m}' (arpa, arpa-auto, arpa-pp, rtpm)")),
            }
        }
        for p in &config.peers {
            if !matches!(p.as_str(), "ptracer" | "path") {
                return bad(format!("unknown peer '{p}' (Mitsuba 3 integrators: ptracer, path)"));
            }
        }
        for s in &config.scenes {
            if let Some(r) = s.caustic_region
                && let Err(e) = PixelRect::new(r)
            {
                return bad(format!("scene '{}': caustic_region {e}", s.name));
            }
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

    /// The directory of `entry`'s files: its own `dir` (relative to the config file), else
    /// the sweep's scenes directory.
    pub fn scene_dir(&self, entry: &SceneEntry) -> PathBuf {
        match &entry.dir {
            Some(d) => self.path.parent().unwrap_or(Path::new(".")).join(d),
            None => self.scenes_dir.clone(),
        }
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
        assert_eq!((c.config.downscale, c.config.upscale), (1, 1));
        assert_eq!(c.methods, vec![BenchMethod::Arpa, BenchMethod::Rtpm]);
        assert_eq!(c.hash.len(), 64);
        assert_eq!(c.config.scenes[0].smoothing_caustic, Some(0.5));
        assert_eq!(c.config.scenes[0].region(), None);
    }

    #[test]
    fn a_scene_can_have_its_own_directory_and_a_caustic_region() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("sub").join("b.toml");
        std::fs::create_dir_all(path.parent().unwrap()).unwrap();
        let text = OK.replace("smoothing_caustic = 0.5", "dir = \"../mine\"\ncaustic_region = [1, 2, 30, 40]");
        std::fs::write(&path, format!("{text}[[scene]]\nname = \"d\"\nfile = \"d.xml\"\nreference = \"d.exr\"\n")).unwrap();
        let c = LoadedConfig::load(&path).unwrap();
        let [own, shared] = [&c.config.scenes[0], &c.config.scenes[1]];
        assert_eq!(c.scene_dir(own), dir.path().join("sub").join("../mine"));
        assert_eq!(c.scene_dir(shared), c.scenes_dir);
        assert_eq!(own.region(), Some(PixelRect { x0: 1, y0: 2, x1: 30, y1: 40 }));
        assert_eq!(shared.region(), None);
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
            (OK.replace("smoothing_caustic = 0.5", "caustic_region = [10, 0, 10, 5]"), "scene 'c': caustic_region [10, 0, 10, 5] is empty"),
            (OK.replace("smoothing_caustic = 0.5", "caustic_region = [0, 9, 5, 3]"), "caustic_region [0, 9, 5, 3] is empty"),
            (OK.replace("smoothing_caustic = 0.5", "caustic_region = [0, 1, 2]"), "caustic_region"),
            (OK.replace("smoothing_caustic = 0.5", "caustic_region = [-1, 0, 2, 2]"), "caustic_region"),
            (OK.replace("name = \"t\"", "name = \"t\"\nupscale = 0"), "upscale must be at least 1"),
            (OK.replace("name = \"t\"", "name = \"t\"\nupscale = 6\ndownscale = 2"), "downscale 2 and upscale 6: set one of them"),
        ] {
            let e = format!("{:#}", load(&text).unwrap_err());
            assert!(e.contains(needle) && e.contains("b.toml"), "{needle}: {e}");
        }
    }
}
