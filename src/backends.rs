//! The backend registry: every backend compiled into this build (one cargo feature each),
//! by [`BackendKind`], with its constructor behind the object-safe [`DynTracer`].
//!
//! The CLI (`--backend`, `--adapter`) and the conformance suite both take backends from
//! here; [`BackendKind`] (in the core) is the one list of backend names. Adding a backend
//! is its crate, one cargo feature of this crate, and one entry in [`REGISTRY`].

use arpa_core::accumulate::image::Accumulation;
use arpa_core::store::footprint::PackedFootprint;
use arpa_core::store::progressive_photon::PackedPhoton;
use arpa_core::render::scene::Scene;
use arpa_core::render::tracer::{BackendKind, Capabilities, Image, IterationStats, QueryRecord, RenderSettings, Tracer};

pub mod error;
pub mod kernel_runner;

pub use error::BoxError;
pub use kernel_runner::{KernelJob, KernelRunner, MakeKernelRunner, WORKGROUP_SIZE};

/// How to create a backend.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct BackendOptions {
    /// Use the device adapter whose name contains this (case-insensitive); `None`: the
    /// backend's automatic choice. Only backends with [`BackendEntry::takes_adapter`]
    /// accept it.
    pub adapter: Option<String>,
}

/// Creates a backend's tracer; an error means it cannot run here (no device, no driver).
pub type CreateTracer = fn(&BackendOptions) -> Result<Box<dyn DynTracer>, BoxError>;

/// One backend compiled into this build.
#[derive(Clone, Copy)]
pub struct BackendEntry {
    /// Which backend.
    pub kind: BackendKind,
    /// The cargo feature (of this crate and of `arpa-conformance`) that compiles it in.
    pub feature: &'static str,
    /// What it runs on, for error messages.
    pub description: &'static str,
    /// Whether [`BackendOptions::adapter`] applies to it.
    pub takes_adapter: bool,
    /// Creates a tracer.
    pub create: CreateTracer,
    /// Creates the backend's WGSL kernel runner, on which the conformance suite runs the
    /// core's WGSL twin; `None` for a backend that runs no WGSL.
    pub kernel_runner: Option<MakeKernelRunner>,
}

impl core::fmt::Debug for BackendEntry {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.debug_struct("BackendEntry")
            .field("kind", &self.kind)
            .field("feature", &self.feature)
            .field("takes_adapter", &self.takes_adapter)
            .field("kernel_runner", &self.kernel_runner.is_some())
            .finish()
    }
}

/// The backends compiled in, in report-column order.
pub const REGISTRY: &[BackendEntry] = &[
    #[cfg(feature = "cpu")]
    BackendEntry {
        kind: BackendKind::Cpu,
        feature: "cpu",
        description: "Embree 4",
        takes_adapter: false,
        create: |_| Ok(Box::new(arpa_cpu::CpuTracer::new()?)),
        kernel_runner: None,
    },
    #[cfg(feature = "wgpu")]
    BackendEntry {
        kind: BackendKind::Wgpu,
        feature: "wgpu",
        description: "wgpu ray queries: a GPU, or lavapipe",
        takes_adapter: true,
        create: |o| Ok(Box::new(arpa_wgpu::WgpuTracer::new(&wgpu_adapter(o))?)),
        kernel_runner: Some(kernel_runner::wgpu_kernel_runner),
    },
    #[cfg(feature = "vk")]
    BackendEntry {
        kind: BackendKind::Vk,
        feature: "vk",
        description: "Vulkan ray-tracing pipelines (ash): a GPU, or lavapipe",
        takes_adapter: true,
        create: |o| Ok(Box::new(arpa_vk::VkTracer::new(&vk_adapter(o))?)),
        kernel_runner: Some(kernel_runner::vk_kernel_runner),
    },
];

/// The Vulkan adapter [`BackendOptions::adapter`] asks for.
#[cfg(feature = "vk")]
fn vk_adapter(options: &BackendOptions) -> arpa_vk::AdapterChoice {
    match &options.adapter {
        Some(name) => arpa_vk::AdapterChoice::NameContains(name.clone()),
        None => arpa_vk::AdapterChoice::Auto,
    }
}

/// The wgpu adapter [`BackendOptions::adapter`] asks for.
#[cfg(feature = "wgpu")]
fn wgpu_adapter(options: &BackendOptions) -> arpa_wgpu::AdapterChoice {
    match &options.adapter {
        Some(name) => arpa_wgpu::AdapterChoice::NameContains(name.clone()),
        None => arpa_wgpu::AdapterChoice::Auto,
    }
}

/// The entry of `kind`, if it is compiled in.
pub fn entry(kind: BackendKind) -> Option<&'static BackendEntry> {
    REGISTRY.iter().find(|e| e.kind == kind)
}

/// The names of the backends compiled in, comma-separated (or how to get one).
pub fn compiled_list() -> String {
    if REGISTRY.is_empty() {
        "none (rebuild with `--features cpu`)".to_string()
    } else {
        REGISTRY.iter().map(|e| e.kind.name()).collect::<Vec<_>>().join(", ")
    }
}

/// Parses a backend name: only backends compiled into this build are accepted; the error
/// says whether the name is unknown or names a backend this build lacks.
pub fn parse(name: &str) -> Result<BackendKind, String> {
    match BackendKind::from_name(name) {
        Some(kind) if entry(kind).is_some() => Ok(kind),
        Some(kind) => Err(format!(
            "backend '{name}' is not compiled into this build (rebuild with `--features {kind}`); compiled backends: {}",
            compiled_list()
        )),
        None => Err(format!("unknown backend '{name}'; compiled backends: {}", compiled_list())),
    }
}

/// Why [`create`] could not make a tracer.
#[derive(Debug, thiserror::Error)]
pub enum BackendError {
    /// The backend is not compiled into this build.
    #[error("{0}")]
    NotCompiled(String),
    /// An option the backend does not take.
    #[error("--adapter applies to backends {takers} only (backend '{kind}' given)")]
    AdapterNotTaken {
        /// The backend asked for.
        kind: BackendKind,
        /// The backends that take an adapter, comma-separated.
        takers: String,
    },
    /// The backend's own start-up error (no device, no driver, no adapter by that name).
    #[error("cannot start the {kind} backend ({description})")]
    Start {
        /// The backend.
        kind: BackendKind,
        /// What it runs on.
        description: &'static str,
        /// The backend's error.
        #[source]
        source: BoxError,
    },
}

/// Creates a tracer of backend `kind`. The error names the backend and says what failed:
/// not compiled in, an option it does not take, or its own start-up error (the source).
pub fn create(kind: BackendKind, options: &BackendOptions) -> Result<Box<dyn DynTracer>, BackendError> {
    let Some(e) = entry(kind) else {
        return Err(BackendError::NotCompiled(parse(kind.name()).err().unwrap_or_default()));
    };
    if options.adapter.is_some() && !e.takes_adapter {
        let takers: Vec<&str> = REGISTRY.iter().filter(|e| e.takes_adapter).map(|e| e.kind.name()).collect();
        return Err(BackendError::AdapterNotTaken { kind, takers: takers.join(", ") });
    }
    (e.create)(options).map_err(|source| BackendError::Start { kind, description: e.description, source })
}

/// [`Tracer`] with its associated error type erased: the same stage and `read_*` calls,
/// each error boxed. Implemented for every `T: Tracer + Send`, so callers never name a
/// backend type. `Send` lets a caller drive the backend from a thread pool of its choosing.
pub trait DynTracer: Send {
    /// [`Tracer::capabilities`].
    fn capabilities(&self) -> Capabilities;
    /// [`Tracer::upload_scene`].
    fn upload_scene(&mut self, scene: &Scene, settings: &RenderSettings) -> Result<(), BoxError>;
    /// [`Tracer::camera_pass`].
    fn camera_pass(&mut self) -> Result<(), BoxError>;
    /// [`Tracer::photon_pass`].
    fn photon_pass(&mut self) -> Result<(), BoxError>;
    /// [`Tracer::build_acceleration_structure`].
    fn build_acceleration_structure(&mut self) -> Result<(), BoxError>;
    /// [`Tracer::gather`].
    fn gather(&mut self) -> Result<(), BoxError>;
    /// [`Tracer::accumulate`].
    fn accumulate(&mut self) -> Result<(), BoxError>;
    /// [`Tracer::iterate`] (the backend's own, which may fuse stages).
    fn iterate(&mut self) -> Result<(), BoxError>;
    /// [`Tracer::iterations`].
    fn iterations(&self) -> u32;
    /// [`Tracer::read_image`].
    fn read_image(&self) -> Result<Image, BoxError>;
    /// [`Tracer::read_query_points`].
    fn read_query_points(&self) -> Result<Vec<QueryRecord>, BoxError>;
    /// [`Tracer::read_footprints`].
    fn read_footprints(&self) -> Result<Vec<PackedFootprint>, BoxError>;
    /// [`Tracer::read_photons`].
    fn read_photons(&self) -> Result<Vec<PackedPhoton>, BoxError>;
    /// [`Tracer::read_stats`].
    fn read_stats(&self) -> Result<IterationStats, BoxError>;
    /// [`Tracer::read_accumulation`].
    fn read_accumulation(&self) -> Result<Accumulation, BoxError>;
    /// [`Tracer::restore_accumulation`].
    fn restore_accumulation(&mut self, state: &Accumulation) -> Result<(), BoxError>;
}

fn boxed<E: std::error::Error + Send + Sync + 'static>(e: E) -> BoxError {
    Box::new(e)
}

impl<T: Tracer + Send> DynTracer for T {
    fn capabilities(&self) -> Capabilities {
        Tracer::capabilities(self)
    }
    fn upload_scene(&mut self, scene: &Scene, settings: &RenderSettings) -> Result<(), BoxError> {
        Tracer::upload_scene(self, scene, settings).map_err(boxed)
    }
    fn camera_pass(&mut self) -> Result<(), BoxError> {
        Tracer::camera_pass(self).map_err(boxed)
    }
    fn photon_pass(&mut self) -> Result<(), BoxError> {
        Tracer::photon_pass(self).map_err(boxed)
    }
    fn build_acceleration_structure(&mut self) -> Result<(), BoxError> {
        Tracer::build_acceleration_structure(self).map_err(boxed)
    }
    fn gather(&mut self) -> Result<(), BoxError> {
        Tracer::gather(self).map_err(boxed)
    }
    fn accumulate(&mut self) -> Result<(), BoxError> {
        Tracer::accumulate(self).map_err(boxed)
    }
    fn iterate(&mut self) -> Result<(), BoxError> {
        Tracer::iterate(self).map_err(boxed)
    }
    fn iterations(&self) -> u32 {
        Tracer::iterations(self)
    }
    fn read_image(&self) -> Result<Image, BoxError> {
        Tracer::read_image(self).map_err(boxed)
    }
    fn read_query_points(&self) -> Result<Vec<QueryRecord>, BoxError> {
        Tracer::read_query_points(self).map_err(boxed)
    }
    fn read_footprints(&self) -> Result<Vec<PackedFootprint>, BoxError> {
        Tracer::read_footprints(self).map_err(boxed)
    }
    fn read_photons(&self) -> Result<Vec<PackedPhoton>, BoxError> {
        Tracer::read_photons(self).map_err(boxed)
    }
    fn read_stats(&self) -> Result<IterationStats, BoxError> {
        Tracer::read_stats(self).map_err(boxed)
    }
    fn read_accumulation(&self) -> Result<Accumulation, BoxError> {
        Tracer::read_accumulation(self).map_err(boxed)
    }
    fn restore_accumulation(&mut self, state: &Accumulation) -> Result<(), BoxError> {
        Tracer::restore_accumulation(self, state).map_err(boxed)
    }
}

/// A boxed backend error as a [`std::error::Error`]: displays as the backend's error and
/// reports its source, so error chains read as they do for the backend type itself.
#[derive(Debug)]
pub struct DynError(pub BoxError);

impl core::fmt::Display for DynError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        self.0.fmt(f)
    }
}

impl std::error::Error for DynError {
    fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
        self.0.source()
    }
}

/// A registry tracer is a [`Tracer`] again, so generic code (the render session) drives
/// it as it drives a concrete backend.
impl Tracer for Box<dyn DynTracer> {
    type Error = DynError;

    fn capabilities(&self) -> Capabilities {
        (**self).capabilities()
    }
    fn upload_scene(&mut self, scene: &Scene, settings: &RenderSettings) -> Result<(), DynError> {
        (**self).upload_scene(scene, settings).map_err(DynError)
    }
    fn camera_pass(&mut self) -> Result<(), DynError> {
        (**self).camera_pass().map_err(DynError)
    }
    fn photon_pass(&mut self) -> Result<(), DynError> {
        (**self).photon_pass().map_err(DynError)
    }
    fn build_acceleration_structure(&mut self) -> Result<(), DynError> {
        (**self).build_acceleration_structure().map_err(DynError)
    }
    fn gather(&mut self) -> Result<(), DynError> {
        (**self).gather().map_err(DynError)
    }
    fn accumulate(&mut self) -> Result<(), DynError> {
        (**self).accumulate().map_err(DynError)
    }
    fn iterate(&mut self) -> Result<(), DynError> {
        (**self).iterate().map_err(DynError)
    }
    fn iterations(&self) -> u32 {
        (**self).iterations()
    }
    fn read_image(&self) -> Result<Image, DynError> {
        (**self).read_image().map_err(DynError)
    }
    fn read_query_points(&self) -> Result<Vec<QueryRecord>, DynError> {
        (**self).read_query_points().map_err(DynError)
    }
    fn read_footprints(&self) -> Result<Vec<PackedFootprint>, DynError> {
        (**self).read_footprints().map_err(DynError)
    }
    fn read_photons(&self) -> Result<Vec<PackedPhoton>, DynError> {
        (**self).read_photons().map_err(DynError)
    }
    fn read_stats(&self) -> Result<IterationStats, DynError> {
        (**self).read_stats().map_err(DynError)
    }
    fn read_accumulation(&self) -> Result<Accumulation, DynError> {
        (**self).read_accumulation().map_err(DynError)
    }
    fn restore_accumulation(&mut self, state: &Accumulation) -> Result<(), DynError> {
        (**self).restore_accumulation(state).map_err(DynError)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_known_backend_parses_to_itself_or_says_it_is_not_compiled() {
        for kind in BackendKind::ALL {
            match parse(&kind.name().to_ascii_uppercase()) {
                Ok(k) => assert_eq!((k, entry(k).map(|e| e.kind)), (kind, Some(kind))),
                Err(e) => assert!(entry(kind).is_none() && e.contains("not compiled") && e.contains(kind.name()), "{e}"),
            }
        }
        let e = parse("quantum").unwrap_err();
        assert!(e.contains("unknown backend 'quantum'") && e.contains("compiled backends"), "{e}");
        assert!(REGISTRY.iter().all(|e| e.feature == e.kind.name()), "a backend's feature is its name");
    }

    #[test]
    fn adapter_only_where_a_backend_takes_one() {
        for e in REGISTRY.iter().filter(|e| !e.takes_adapter) {
            let err = create(e.kind, &BackendOptions { adapter: Some("x".into()) }).err().expect("refused");
            assert!(err.to_string().contains("--adapter applies to"), "{err}");
        }
        let missing = BackendKind::ALL.into_iter().find(|k| entry(*k).is_none());
        if let Some(kind) = missing {
            let err = create(kind, &BackendOptions::default()).err().expect("refused");
            assert!(err.to_string().contains("not compiled"), "{err}");
        }
    }
}
