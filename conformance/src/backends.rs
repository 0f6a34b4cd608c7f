//! The backends compiled into the suite (the facade's registry, `arpa::backends`; one
//! cargo feature of this crate per backend forwards to the facade's), with the cases each
//! is expected to fail (every expectation carries its reason).

use arpa::backends::{BackendEntry, CreateTracer, REGISTRY};
use arpa::core::tracer::BackendKind;

use crate::kernel_runner::MakeKernelRunner;

/// A case this backend is known to fail, and why.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ExpectedFailure {
    /// [`crate::suite::Case::id`] of the case.
    pub case: &'static str,
    /// Why the backend cannot pass it (shown in the report; must not be empty).
    pub reason: &'static str,
}

/// A backend the suite runs on.
#[derive(Clone, Copy)]
pub struct Backend {
    /// Name as in [`BackendKind::name`] and `ARPA_REQUIRE_BACKENDS`.
    pub name: &'static str,
    /// Cargo feature of `arpa-conformance` that compiles it in.
    pub feature: &'static str,
    /// Creates a fresh tracer (device, context); an error means the backend cannot run
    /// here (no adapter, no driver).
    pub create: CreateTracer,
    /// Cases it is expected to fail.
    pub expected_failures: &'static [ExpectedFailure],
    /// Creates the backend's WGSL kernel runner (what the cases of the core's WGSL twin
    /// run on); `None` for a backend that runs no WGSL (the twin cases are then not
    /// applicable to it). An error means the runner cannot run here.
    pub kernel_runner: Option<MakeKernelRunner>,
}

impl core::fmt::Debug for Backend {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.debug_struct("Backend")
            .field("name", &self.name)
            .field("feature", &self.feature)
            .field("expected_failures", &self.expected_failures)
            .field("kernel_runner", &self.kernel_runner.is_some())
            .finish()
    }
}

impl Backend {
    /// The reason this backend is expected to fail `case`, if it is.
    pub fn expected_failure(&self, case: &str) -> Option<&'static str> {
        self.expected_failures
            .iter()
            .find(|e| e.case == case)
            .map(|e| e.reason)
    }
}

impl Backend {
    /// The suite's view of a registry entry.
    pub fn from_entry(e: &BackendEntry) -> Self {
        Backend {
            name: e.kind.name(),
            feature: e.feature,
            create: e.create,
            expected_failures: expected_failures(e.kind),
            kernel_runner: e.kernel_runner,
        }
    }
}

/// The cases `kind` is expected to fail (none today).
fn expected_failures(kind: BackendKind) -> &'static [ExpectedFailure] {
    match kind {
        BackendKind::Cpu | BackendKind::Wgpu | BackendKind::Vk => &[],
    }
}

/// The backends compiled in, in report-column order.
pub fn compiled() -> Vec<Backend> {
    REGISTRY.iter().map(Backend::from_entry).collect()
}
