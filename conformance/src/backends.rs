//! The backends compiled into the suite (the facade's registry, `arpa::backends`; one
//! cargo feature of this crate per backend forwards to the facade's), with the cases each
//! is expected to fail (every expectation carries its reason); and backends from outside
//! the registry ([`Backend::external`]): a renderer author's own tracer.

use arpa::backends::{BackendEntry, REGISTRY};
/// What [`Backend::external`] takes: how to create a backend's tracer, and its options.
pub use arpa::backends::{BackendOptions, CreateTracer};

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
    /// Name as in [`BackendKind::name`](arpa::core::render::tracer::BackendKind::name) and `ARPA_REQUIRE_BACKENDS` (the report's column);
    /// for an external backend, the name its author chose.
    pub name: &'static str,
    /// Cargo feature of `arpa-conformance` that compiles it in; empty for an external
    /// backend ([`Backend::external`]), which no feature of this crate controls.
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
    /// A backend from outside the facade's registry: the tracer of a renderer that is not
    /// part of arpa, made by `create`, under the report column `name`. It is expected to
    /// fail nothing ([`Backend::with_expected_failures`] declares what it is) and runs no
    /// WGSL (the core's WGSL-twin cases are then [`crate::Verdict::NotApplicable`]).
    ///
    /// `create` is a plain function or a closure that captures nothing, e.g.
    /// `|_| Ok(Box::new(MyTracer::new()?))`: any `T: Tracer + Send` boxes into a
    /// [`crate::DynTracer`]. It is called once per backend, and again after a case panics.
    /// Put `name` in [`crate::SuiteOptions::required`] so that a tracer that cannot start
    /// fails the run instead of being reported as unavailable.
    pub const fn external(name: &'static str, create: CreateTracer) -> Self {
        Backend {
            name,
            feature: "",
            create,
            expected_failures: &[],
            kernel_runner: None,
        }
    }

    /// The same backend, expected to fail `failures` (each with its reason, shown in the
    /// report). A listed case that passes is a failure, so the list cannot go stale.
    pub const fn with_expected_failures(self, failures: &'static [ExpectedFailure]) -> Self {
        Backend {
            expected_failures: failures,
            ..self
        }
    }

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
            expected_failures: &[],
            kernel_runner: e.kernel_runner,
        }
    }
}

/// The backends compiled in, in report-column order.
pub fn compiled() -> Vec<Backend> {
    REGISTRY.iter().map(Backend::from_entry).collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::BoxError;
    use crate::dyn_tracer::DynTracer;
    use arpa::backends::BackendOptions;

    fn no_tracer(_: &BackendOptions) -> Result<Box<dyn DynTracer>, BoxError> {
        Err("not here".into())
    }

    #[test]
    fn external_backends_expect_nothing_unless_told() {
        let b = Backend::external("mine", no_tracer);
        assert_eq!((b.name, b.feature), ("mine", ""));
        assert!(b.kernel_runner.is_none() && b.expected_failure("determinism").is_none());
        let b = b.with_expected_failures(&[ExpectedFailure {
            case: "determinism",
            reason: "atomics in the gather",
        }]);
        assert_eq!(
            b.expected_failure("determinism"),
            Some("atomics in the gather")
        );
        assert_eq!(b.expected_failure("bad-input"), None);
        assert!((b.create)(&BackendOptions::default()).is_err());
    }
}
