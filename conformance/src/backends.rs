//! The backends compiled into the suite, one per cargo feature of this crate, with the
//! cases each is expected to fail (every expectation carries its reason).

use crate::dyn_tracer::{BoxError, DynTracer};
use crate::kernel_runner::MakeKernelRunner;

/// Every backend name the project knows, compiled in or not. `ARPA_REQUIRE_BACKENDS`
/// may only name these.
pub const KNOWN_BACKENDS: &[&str] = &["cpu", "wgpu", "vk"];

/// A case this backend is known to fail, and why.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ExpectedFailure {
    /// [`crate::suite::Case::id`] of the case.
    pub case: &'static str,
    /// Why the backend cannot pass it (shown in the report; must not be empty).
    pub reason: &'static str,
}

/// A backend compiled in.
#[derive(Clone, Copy)]
pub struct Backend {
    /// Name as in [`KNOWN_BACKENDS`] and `ARPA_REQUIRE_BACKENDS`.
    pub name: &'static str,
    /// Cargo feature of `arpa-conformance` that compiles it in.
    pub feature: &'static str,
    /// Creates a fresh tracer (device, context); an error means the backend cannot run
    /// here (no adapter, no driver).
    pub create: fn() -> Result<Box<dyn DynTracer>, BoxError>,
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

#[cfg(feature = "cpu")]
fn create_cpu() -> Result<Box<dyn DynTracer>, BoxError> {
    Ok(Box::new(arpa_cpu::CpuTracer::new()?))
}

#[cfg(feature = "wgpu")]
fn create_wgpu() -> Result<Box<dyn DynTracer>, BoxError> {
    Ok(Box::new(arpa_wgpu::WgpuTracer::new(&arpa_wgpu::AdapterChoice::Auto)?))
}

/// The backends compiled in, in report-column order.
#[allow(clippy::vec_init_then_push)] // one `push` per feature
pub fn compiled() -> Vec<Backend> {
    #[allow(unused_mut)]
    let mut v = Vec::new();
    #[cfg(feature = "cpu")]
    v.push(Backend {
        name: "cpu",
        feature: "cpu",
        create: create_cpu,
        expected_failures: &[],
        kernel_runner: None,
    });
    #[cfg(feature = "wgpu")]
    v.push(Backend {
        name: "wgpu",
        feature: "wgpu",
        create: create_wgpu,
        expected_failures: &[],
        kernel_runner: Some(crate::kernel_runner::wgpu_kernel_runner),
    });
    v
}
