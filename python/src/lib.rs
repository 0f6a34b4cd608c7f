//! `arpa._arpa`: the extension module of the `arpa` Python package.
//!
//! A thin layer over the facade: scenes come from [`arpa::scene_file`], settings from
//! [`arpa::session::RenderOptions`] (the CLI's own mapping), the render loop is
//! [`arpa::session::render_with`] and state files are [`arpa::state_file`]'s, so a render
//! here equals the CLI's for the same settings bit for bit. The Python side
//! (`pysrc/arpa/__init__.py`) adds `render`, `load_dict` (a Mitsuba dict converted to the
//! XML the loader reads) and progress bars.
//!
//! The GIL is released while rendering; between iterations the render re-acquires it to
//! call the progress callback and to look for a pending Ctrl-C (SIGINT), which stops the
//! render after the current iteration with the image so far. Errors are Python exceptions
//! ([`SceneError`] with the file and line of the loader's message, [`RenderError`]); a panic
//! is caught and raised as a `RuntimeError`, never unwound into Python.

use arpa::backends::{self, BackendOptions, DynTracer};
use arpa::core::accumulate::image::Accumulation;
use arpa::core::gather::scales::Bandwidth;
use arpa::core::propagate::classify::{AutoSmoothing, Smoothing};
use arpa::core::render::scene::Scene as CoreScene;
use arpa::core::render::tracer::{BackendKind, EmissionStrategy, Image, Method, RenderSettings};
use arpa::image_io;
use arpa::scene_file::{self, SceneFileError};
use arpa::session::{self, Budget, Hooks, RenderOptions, SaveEvery, SaveState, SessionOptions, SmoothingPilot, StatTotals};
use arpa::state_file::{RenderIdentity, StateFile};
use numpy::{PyArray1, PyArrayMethods};
use pyo3::create_exception;
use pyo3::exceptions::{PyKeyboardInterrupt, PyRuntimeError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::PyDict;
use std::panic::{AssertUnwindSafe, catch_unwind};
use std::path::PathBuf;
use std::sync::{Arc, Mutex};
use std::time::Duration;

create_exception!(arpa, SceneError, PyValueError, "A scene that cannot be loaded: the loader's message, with `file` and `line` (None where the message names no line) as attributes.");
create_exception!(arpa, RenderError, PyRuntimeError, "A render that failed: a backend error, a state file that does not match, a file that cannot be written.");

/// Runs `f`, turning a panic into a `RuntimeError` (a bug: nothing in arpa should panic).
fn guarded<T>(f: impl FnOnce() -> PyResult<T>) -> PyResult<T> {
    match catch_unwind(AssertUnwindSafe(f)) {
        Ok(r) => r,
        Err(payload) => {
            let what = payload.downcast_ref::<&str>().map(|s| s.to_string()).or_else(|| payload.downcast_ref::<String>().cloned()).unwrap_or_else(|| "unknown panic".into());
            Err(PyRuntimeError::new_err(format!("arpa: internal error (please report it): {what}")))
        }
    }
}

/// The file and line a loader error names, if any.
fn error_location(e: &SceneFileError) -> (Option<PathBuf>, Option<usize>) {
    use SceneFileError as E;
    match e {
        E::Xml { path, line, .. } | E::Unsupported { path, line, .. } | E::Invalid { path, line, .. } | E::UndefinedVariable { path, line, .. } | E::Mesh { path, line, .. } => (Some(path.clone()), Some(*line)),
        E::Io { path, .. } | E::Ply { path, .. } | E::Obj { path, .. } | E::Texture { path, .. } | E::Serialized { path, .. } | E::Gltf { path, .. } | E::Scene { path, .. } => (Some(path.clone()), None),
        _ => (None, None),
    }
}

/// A [`SceneError`] carrying the loader's message and its file and line.
fn scene_error(py: Python<'_>, e: &SceneFileError) -> PyErr {
    let err = SceneError::new_err(e.to_string());
    let (file, line) = error_location(e);
    let value = err.value(py);
    // Setting attributes on a fresh exception instance cannot fail in practice; if it did,
    // the message still names the file and line.
    let _ = value.setattr("file", file.map(|p| p.display().to_string()));
    let _ = value.setattr("line", line);
    err
}

fn render_error(e: impl std::fmt::Display) -> PyErr {
    RenderError::new_err(format!("{e:#}"))
}

fn render_error_any(e: anyhow::Error) -> PyErr {
    RenderError::new_err(format!("{e:#}"))
}

/// A loaded scene (`arpa.load_file`, `arpa.load_dict`): immutable; render it with
/// `arpa.render` or `arpa.Renderer`.
#[pyclass(module = "arpa", name = "Scene", frozen)]
struct Scene {
    scene: Arc<CoreScene>,
    max_depth: Option<u32>,
    source: String,
    warnings: Vec<String>,
}

#[pymethods]
impl Scene {
    /// Image width in pixels (the film's).
    #[getter]
    fn width(&self) -> u32 {
        self.scene.camera.width
    }

    /// Image height in pixels (the film's).
    #[getter]
    fn height(&self) -> u32 {
        self.scene.camera.height
    }

    /// The loader's warnings (ignored parameters, approximations), each naming its line.
    #[getter]
    fn warnings(&self) -> Vec<String> {
        self.warnings.clone()
    }

    /// Where the scene came from (its file).
    #[getter]
    fn source(&self) -> String {
        self.source.clone()
    }

    /// The integrator's `max_depth` of the file (Mitsuba's path depth), if it gives one.
    #[getter]
    fn max_depth(&self) -> Option<u32> {
        self.max_depth
    }

    fn __repr__(&self) -> String {
        let s = &self.scene;
        format!(
            "arpa.Scene('{}': {}x{} pixels, {} meshes, {} analytic lights, {} warnings)",
            self.source,
            s.camera.width,
            s.camera.height,
            s.meshes.len(),
            s.lights.len(),
            self.warnings.len()
        )
    }
}

fn finish_load(py: Python<'_>, loaded: Result<scene_file::LoadedScene, SceneFileError>, source: String) -> PyResult<Scene> {
    let loaded = loaded.map_err(|e| scene_error(py, &e))?;
    let path = loaded.path.clone();
    loaded.scene.validate().map_err(|source| scene_error(py, &SceneFileError::Scene { path, source }))?;
    Ok(Scene {
        scene: Arc::new(loaded.scene),
        max_depth: loaded.max_depth,
        source,
        warnings: loaded.warnings.iter().map(|w| w.to_string()).collect(),
    })
}

/// Loads a Mitsuba 3 XML (or glTF 2.0) scene file; `defines` override its `<default>`s.
#[pyfunction]
#[pyo3(signature = (path, defines=Vec::new()))]
fn load_file(py: Python<'_>, path: PathBuf, defines: Vec<(String, String)>) -> PyResult<Scene> {
    guarded(|| {
        let loaded = py.detach(|| {
            if scene_file::is_gltf(&path) {
                if !defines.is_empty() {
                    return Err(SceneFileError::BadDefine(format!("{}: glTF files take no <default> overrides", path.display())));
                }
                scene_file::load_gltf(&path, &scene_file::GltfOptions::default())
            } else {
                scene_file::load_scene(&path, &defines)
            }
        });
        finish_load(py, loaded, path.display().to_string())
    })
}

/// Loads a scene from Mitsuba 3 XML text; `path` names it in messages and its directory
/// resolves relative file names (`arpa.load_dict` loads through this).
#[pyfunction]
fn load_string(py: Python<'_>, xml: &str, path: PathBuf) -> PyResult<Scene> {
    guarded(|| {
        let loaded = py.detach(|| scene_file::load_scene_str(xml, &path, &[]));
        finish_load(py, loaded, path.display().to_string())
    })
}

/// What a render reports between iterations: the progress callback, Ctrl-C, and errors
/// raised by the callback.
struct PyHooks<'a> {
    progress: Option<&'a Py<PyAny>>,
    interrupted: bool,
    error: Option<PyErr>,
}

impl PyHooks<'_> {
    /// Keeps a Python error: a KeyboardInterrupt stops the render with its image, any
    /// other error is raised once the render has stopped.
    fn keep(&mut self, py: Python<'_>, e: PyErr) {
        if e.is_instance_of::<PyKeyboardInterrupt>(py) {
            self.interrupted = true;
        } else if self.error.is_none() {
            self.error = Some(e);
        }
    }
}

impl Hooks for PyHooks<'_> {
    fn stop(&mut self) -> bool {
        if self.interrupted || self.error.is_some() {
            return true;
        }
        Python::attach(|py| {
            if let Err(e) = py.check_signals() {
                self.keep(py, e);
            }
        });
        self.interrupted || self.error.is_some()
    }

    fn iteration(&mut self, iterations: u32, render_time: Duration, _totals: &StatTotals) {
        let Some(callback) = self.progress else { return };
        Python::attach(|py| {
            if let Err(e) = callback.bind(py).call1((iterations, render_time.as_secs_f64())) {
                self.keep(py, e);
            }
        });
    }
}

struct State {
    tracer: Box<dyn DynTracer>,
    backend: BackendKind,
    settings: RenderSettings,
    pilot: Option<SmoothingPilot>,
    identity: RenderIdentity,
    /// An accumulation to continue at the first step (a resumed state file).
    resume: Option<Accumulation>,
    /// Whether the tracer holds the scene (after the first step).
    uploaded: bool,
    checkpoint: Option<(PathBuf, SaveEvery)>,
    image: Option<Image>,
    totals: StatTotals,
    render_time: Duration,
    interrupted: bool,
    /// A step failed: the tracer's state is unknown, so the renderer refuses to go on.
    failed: bool,
}

impl State {
    /// Iterations accumulated: the tracer's once it holds the scene (before that it may
    /// hold the smoothing pilot's iteration), else the resumed state's.
    fn done(&self) -> u32 {
        if self.uploaded { self.tracer.iterations() } else { self.resume.as_ref().map_or(0, |a| a.end() as u32) }
    }
}

/// A progressive render of one scene with fixed settings: `step` adds iterations, `image`
/// reads the image so far. See `arpa.Renderer` in the Python stubs for the arguments.
#[pyclass(module = "arpa", name = "Renderer", frozen)]
struct Renderer {
    scene: Arc<CoreScene>,
    state: Mutex<State>,
}

fn parse_method(s: &str) -> PyResult<Method> {
    match s {
        "arpa" => Ok(Method::Arpa),
        "rtpm" => Ok(Method::Rtpm),
        _ => Err(PyValueError::new_err(format!("unknown method '{s}' (known: 'arpa', 'rtpm')"))),
    }
}

fn parse_bandwidth(s: &str) -> PyResult<Bandwidth> {
    match s {
        "per-pixel" => Ok(Bandwidth::PerPixel),
        "global" => Ok(Bandwidth::Global),
        _ => Err(PyValueError::new_err(format!("unknown bandwidth '{s}' (known: 'per-pixel', 'global')"))),
    }
}

fn parse_save_every(s: &str) -> PyResult<SaveEvery> {
    let bad = || PyValueError::new_err(format!("checkpoint_every '{s}': give N iterations or 'Ns' seconds (e.g. 100 or '60s')"));
    if let Some(secs) = s.strip_suffix('s') {
        let t: f64 = secs.trim().parse().map_err(|_| bad())?;
        if !(t.is_finite() && t > 0.0) {
            return Err(bad());
        }
        Ok(SaveEvery::Time(Duration::from_secs_f64(t)))
    } else {
        let n: u32 = s.trim().parse().map_err(|_| bad())?;
        if n == 0 {
            return Err(bad());
        }
        Ok(SaveEvery::Iterations(n))
    }
}

fn positive(name: &str, v: Option<f64>) -> PyResult<Option<f64>> {
    match v {
        Some(x) if !(x.is_finite() && x > 0.0) => Err(PyValueError::new_err(format!("{name} must be a positive number, got {x}"))),
        _ => Ok(v),
    }
}

/// The image as a `float32` array `(H, W, 3)`, non-finite values written as 0 (as the
/// EXR writer does); the pixels move into the array without another copy.
fn image_array<'py>(py: Python<'py>, image: &Image) -> PyResult<Bound<'py, PyAny>> {
    let mut flat = Vec::with_capacity(image.pixels.len() * 3);
    for p in &image.pixels {
        for c in p.to_array() {
            flat.push(if c.is_finite() { c } else { 0.0 });
        }
    }
    let array = PyArray1::from_vec(py, flat);
    Ok(array.reshape([image.height as usize, image.width as usize, 3])?.into_any())
}

#[pymethods]
impl Renderer {
    #[new]
    #[pyo3(signature = (scene, *, backend="cpu", method="arpa", photons=250_000, seed=0, max_depth=None, smoothing=None, bandwidth="per-pixel", projection=true, caustic_photons=None, direct=true, radius_caustic=None, radius_global=None, adapter=None, resume=None, checkpoint=None, checkpoint_every=None))]
    #[allow(clippy::too_many_arguments)]
    fn new(
        py: Python<'_>,
        scene: PyRef<'_, Scene>,
        backend: &str,
        method: &str,
        photons: u32,
        seed: u32,
        max_depth: Option<u32>,
        smoothing: Option<(f64, f64)>,
        bandwidth: &str,
        projection: bool,
        caustic_photons: Option<u32>,
        direct: bool,
        radius_caustic: Option<f64>,
        radius_global: Option<f64>,
        adapter: Option<String>,
        resume: Option<PathBuf>,
        checkpoint: Option<PathBuf>,
        checkpoint_every: Option<Bound<'_, PyAny>>,
    ) -> PyResult<Self> {
        guarded(|| {
            let kind = backends::parse(backend).map_err(PyValueError::new_err)?;
            if photons == 0 {
                return Err(PyValueError::new_err("photons must be at least 1"));
            }
            if max_depth == Some(0) {
                return Err(PyValueError::new_err("max_depth must be at least 1"));
            }
            if let Some((c, g)) = smoothing {
                positive("smoothing", Some(c))?;
                positive("smoothing", Some(g))?;
            }
            let options = RenderOptions {
                method: parse_method(method)?,
                photons,
                seed,
                max_depth,
                direct_lighting: direct,
                emission: EmissionStrategy { projection, caustic_photons },
                bandwidth: parse_bandwidth(bandwidth)?,
                smoothing: smoothing.map_or(Smoothing { caustic: 1.0, global: 1.0 }, |(c, g)| Smoothing { caustic: c, global: g }),
                radius_caustic: positive("radius_caustic", radius_caustic)?,
                radius_global: positive("radius_global", radius_global)?,
            };
            let checkpoint_every = match checkpoint_every {
                None => None,
                Some(v) => Some(match v.extract::<u32>() {
                    Ok(n) => parse_save_every(&n.to_string())?,
                    Err(_) => parse_save_every(&v.extract::<String>().map_err(|_| PyValueError::new_err("checkpoint_every: give N iterations or 'Ns' seconds"))?)?,
                }),
            };
            if checkpoint_every.is_some() && checkpoint.is_none() {
                return Err(PyValueError::new_err("checkpoint_every needs checkpoint=PATH"));
            }
            let scene_arc = scene.scene.clone();
            let max_depth_file = scene.max_depth;
            let state = py.detach(|| -> anyhow::Result<State> {
                let mut tracer = backends::create(kind, &BackendOptions { adapter })?;
                let mut settings = options.settings(max_depth_file);
                // Automatic smoothing unless factors are given: the CLI's pilot.
                let pilot = if smoothing.is_none() && settings.method == Method::Arpa {
                    let pilot = session::auto_smoothing(&mut tracer, &scene_arc, &settings, &AutoSmoothing::default())?;
                    settings.smoothing = pilot.smoothing;
                    Some(pilot)
                } else {
                    None
                };
                let identity = RenderIdentity::new(&scene_arc, &settings, kind.name());
                let resume = match &resume {
                    Some(path) => {
                        let state = StateFile::read(path)?;
                        identity.check(path, &state.identity)?;
                        Some(state.accumulation)
                    }
                    None => None,
                };
                Ok(State {
                    tracer,
                    backend: kind,
                    settings,
                    pilot,
                    identity,
                    resume,
                    uploaded: false,
                    checkpoint: checkpoint.map(|p| (p, checkpoint_every.unwrap_or(SaveEvery::Time(Duration::from_secs(60))))),
                    image: None,
                    totals: StatTotals::default(),
                    render_time: Duration::ZERO,
                    interrupted: false,
                    failed: false,
                })
            });
            let state = state.map_err(render_error_any)?;
            Ok(Renderer { scene: scene.scene.clone(), state: Mutex::new(state) })
        })
    }

    /// Renders `n` more iterations, or iterations for `seconds` (at least one). Returns
    /// False when Ctrl-C (or a KeyboardInterrupt from `progress`) stopped it early, the
    /// image then holding the iterations done. `progress(iterations, seconds)` (iterations
    /// of this step, their render time) is called after each iteration.
    #[pyo3(signature = (n=None, *, seconds=None, progress=None))]
    fn step(&self, py: Python<'_>, n: Option<u32>, seconds: Option<f64>, progress: Option<Py<PyAny>>) -> PyResult<bool> {
        guarded(|| {
            let mut guard = self.state.lock().map_err(|_| RenderError::new_err("this Renderer failed in an earlier call and cannot go on"))?;
            let state = &mut *guard;
            if state.failed {
                return Err(RenderError::new_err("this Renderer failed in an earlier step and cannot go on; make a new one"));
            }
            let done = state.done();
            let budget = match (n, seconds) {
                (Some(_), Some(_)) => return Err(PyValueError::new_err("give n or seconds, not both")),
                (_, Some(t)) if !(t.is_finite() && t > 0.0) => return Err(PyValueError::new_err(format!("seconds must be positive, got {t}"))),
                (_, Some(t)) => Budget::Time(Duration::from_secs_f64(t)),
                (Some(n), None) => Budget::Iterations(done.checked_add(n).ok_or_else(|| PyValueError::new_err("too many iterations"))?),
                (None, None) => Budget::Iterations(done + 1),
            };
            if n == Some(0) && state.uploaded {
                return Ok(true);
            }
            let mut hooks = PyHooks { progress: progress.as_ref(), interrupted: false, error: None };
            let scene = &self.scene;
            let rendered = py.detach(|| {
                let save = state.checkpoint.as_ref().map(|(path, every)| SaveState { path, every: *every, identity: &state.identity });
                let options = SessionOptions {
                    resume: if state.uploaded { None } else { state.resume.as_ref() },
                    continued: state.uploaded,
                    save,
                    ..SessionOptions::budget(budget)
                };
                session::render_with(&mut state.tracer, scene, &state.settings, &options, &mut hooks)
            });
            let rendered = match rendered {
                Ok(r) => r,
                Err(e) => {
                    // The tracer may have stopped mid-iteration: nothing after this is exact.
                    state.failed = true;
                    return Err(render_error_any(e));
                }
            };
            state.uploaded = true;
            state.resume = None;
            let t = &mut state.totals;
            let sum = rendered.totals;
            t.iterations += sum.iterations;
            t.sum.accumulate(&sum.sum);
            state.render_time += rendered.render_time;
            state.image = Some(rendered.image);
            state.interrupted = hooks.interrupted;
            if let Some(e) = hooks.error {
                return Err(e);
            }
            Ok(!hooks.interrupted)
        })
    }

    /// The image so far: `float32` array `(H, W, 3)`, linear radiance (zeros before the
    /// first step).
    fn image<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        let state = self.state.lock().map_err(|_| RenderError::new_err("this Renderer failed in an earlier call"))?;
        match &state.image {
            Some(image) => image_array(py, image),
            None => {
                let (w, h) = (self.scene.camera.width, self.scene.camera.height);
                image_array(py, &Image { width: w, height: h, pixels: vec![Default::default(); (w as usize) * (h as usize)] })
            }
        }
    }

    /// Iterations accumulated (a resumed state's included).
    #[getter]
    fn iterations(&self) -> PyResult<u32> {
        let state = self.state.lock().map_err(|_| RenderError::new_err("this Renderer failed in an earlier call"))?;
        Ok(state.done())
    }

    /// Statistics as a dict: iterations, render time, photons, smoothing, per-stage mean
    /// times (ms), records per photon, whether Ctrl-C interrupted the last step.
    fn stats<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let state = self.state.lock().map_err(|_| RenderError::new_err("this Renderer failed in an earlier call"))?;
        let d = PyDict::new(py);
        let caps = state.tracer.capabilities();
        d.set_item("backend", state.backend.name())?;
        d.set_item("device", caps.device)?;
        d.set_item("method", state.settings.method.name())?;
        d.set_item("seed", state.settings.seed)?;
        d.set_item("photons_per_iteration", state.settings.photons_per_iteration)?;
        d.set_item("max_depth", state.settings.max_depth)?;
        d.set_item("iterations", state.done())?;
        d.set_item("iterations_rendered", state.totals.iterations)?;
        d.set_item("render_seconds", state.render_time.as_secs_f64())?;
        d.set_item("photons_emitted", state.totals.sum.photons_emitted)?;
        d.set_item("smoothing", (state.settings.smoothing.caustic, state.settings.smoothing.global))?;
        d.set_item("smoothing_pilot_seconds", state.pilot.map(|p| p.time.as_secs_f64()))?;
        let times = state.totals.mean_times();
        let stage = PyDict::new(py);
        for (k, v) in [("camera", times.camera), ("photon", times.photon), ("build", times.build), ("gather", times.gather), ("accumulate", times.accumulate)] {
            stage.set_item(k, v * 1e3)?;
        }
        d.set_item("stage_ms", stage)?;
        d.set_item("records_per_photon", state.totals.sum.records_per_photon())?;
        d.set_item("interrupted", state.interrupted)?;
        Ok(d)
    }

    /// Saves by the extension of `path`: `.exr` (linear, as the CLI writes it), `.png`
    /// (sRGB, `exposure` applied), `.arpastate` (the render's state, for `resume=`).
    #[pyo3(signature = (path, exposure=1.0))]
    fn save(&self, py: Python<'_>, path: PathBuf, exposure: f32) -> PyResult<()> {
        guarded(|| {
            let mut guard = self.state.lock().map_err(|_| RenderError::new_err("this Renderer failed in an earlier call"))?;
            // `&mut` (Send) rather than `&` (which would need Sync) crosses into the detached closure.
            let state = &mut *guard;
            let ext = path.extension().and_then(|e| e.to_str()).unwrap_or("").to_ascii_lowercase();
            py.detach(move || -> anyhow::Result<()> {
                let state: &mut State = state;
                match ext.as_str() {
                    "exr" | "png" => {
                        let image = state.image.as_ref().ok_or_else(|| anyhow::anyhow!("nothing rendered yet: call step() first"))?;
                        if ext == "exr" {
                            image_io::write_exr(&path, image)?;
                        } else {
                            image_io::write_png(&path, image, exposure)?;
                        }
                    }
                    "arpastate" => {
                        if !state.uploaded {
                            anyhow::bail!("nothing rendered yet: call step() first");
                        }
                        let accumulation = state.tracer.read_accumulation().map_err(|e| anyhow::anyhow!("cannot read the accumulation back: {e}"))?;
                        StateFile { identity: state.identity.clone(), accumulation }.write_atomic(&path)?;
                    }
                    _ => anyhow::bail!("cannot save '{}': give a .exr, .png or .arpastate path", path.display()),
                }
                Ok(())
            })
            .map_err(render_error_any)
        })
    }

    fn __repr__(&self) -> String {
        match self.state.lock() {
            Ok(s) => format!("arpa.Renderer(backend='{}', method='{}', {} iterations)", s.backend.name(), s.settings.method.name(), s.done()),
            Err(_) => "arpa.Renderer(failed)".into(),
        }
    }
}

/// Reads an OpenEXR image (e.g. a reference, or the CLI's output) as a `float32` array
/// `(H, W, 3)`.
#[pyfunction]
fn read_exr<'py>(py: Python<'py>, path: PathBuf) -> PyResult<Bound<'py, PyAny>> {
    guarded(|| {
        let image = py.detach(|| image_io::read_exr(&path)).map_err(render_error)?;
        image_array(py, &image)
    })
}

/// Names of the backends compiled into this build.
#[pyfunction]
fn backends_compiled() -> Vec<String> {
    BackendKind::ALL.iter().filter(|k| backends::entry(**k).is_some()).map(|k| k.name().to_string()).collect()
}

/// The extension module.
#[pymodule]
fn _arpa(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(load_file, m)?)?;
    m.add_function(wrap_pyfunction!(load_string, m)?)?;
    m.add_function(wrap_pyfunction!(backends_compiled, m)?)?;
    m.add_function(wrap_pyfunction!(read_exr, m)?)?;
    m.add_class::<Scene>()?;
    m.add_class::<Renderer>()?;
    m.add("SceneError", m.py().get_type::<SceneError>())?;
    m.add("RenderError", m.py().get_type::<RenderError>())?;
    Ok(())
}
