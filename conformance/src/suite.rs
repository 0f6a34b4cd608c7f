//! The runner: every case on every backend compiled in, expectations applied, the
//! backends required by `ARPA_REQUIRE_BACKENDS` enforced.

use std::panic::{AssertUnwindSafe, catch_unwind};
use std::time::Instant;

use crate::backends::Backend;
use arpa::backends::BackendOptions;
use arpa::core::render::tracer::BackendKind;
use crate::dyn_tracer::{BoxError, DynTracer};
use crate::kernel_runner::{KernelRunner, MakeKernelRunner};
use crate::report::{Report, Verdict};

/// What a case body returns: the measured metric when its assertion held, else what was
/// measured and what was expected.
pub type CaseResult = Result<String, String>;

/// A case's body, by the capability of the backend it needs.
#[derive(Clone, Copy)]
pub enum CaseBody {
    /// Drives the backend's tracer. It uploads its own scene (which resets the tracer) and
    /// must not assume anything about the tracer's state.
    Tracer(fn(&mut dyn DynTracer) -> CaseResult),
    /// Runs WGSL kernels on the backend's [`KernelRunner`]
    /// ([`Backend::kernel_runner`]); [`Verdict::NotApplicable`] on a backend without one.
    Kernels(fn(&dyn KernelRunner) -> CaseResult),
}

/// A backend-agnostic case: one body for every backend.
#[derive(Clone, Copy)]
pub struct Case {
    /// Stable identifier (what expectations and `--case` filters name).
    pub id: &'static str,
    /// Row label of the report.
    pub title: &'static str,
    /// The case.
    pub run: CaseBody,
    /// Checked before the case runs on any backend: `Err(what is missing)` when data the
    /// case reads (the shared scenes) is absent. The case is then skipped loudly, or fails
    /// when env `CI` is set ([`ci_is_set`]). `None`: the case needs nothing external.
    pub needs: Option<fn() -> Result<(), String>>,
}

impl core::fmt::Debug for Case {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.debug_struct("Case")
            .field("id", &self.id)
            .field("title", &self.title)
            .finish()
    }
}

/// Row of the report that says whether each backend is present and initialises.
pub const AVAILABILITY_ROW: &str = "backend compiled in and initialises";

/// Environment variable listing the backends that must be compiled in and initialise.
pub const REQUIRE_ENV: &str = "ARPA_REQUIRE_BACKENDS";

/// `true` when env `CI` is set to anything but empty, `0` or `false` (GitHub, GitLab and
/// most CI services set `CI=true`): missing shared data then fails instead of skipping.
pub fn ci_is_set() -> bool {
    std::env::var("CI").is_ok_and(|v| {
        let v = v.trim();
        !(v.is_empty() || v == "0" || v.eq_ignore_ascii_case("false"))
    })
}

/// Environment variable restricting the run to cases whose id contains one of its
/// comma-separated parts.
pub const CASES_ENV: &str = "ARPA_CONFORMANCE_CASES";

/// How to run the suite.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct SuiteOptions {
    /// Backends that must be compiled in and initialise (`ARPA_REQUIRE_BACKENDS`).
    pub required: Vec<String>,
    /// Run only cases whose id contains one of these (all when empty).
    pub filter: Vec<String>,
}

fn split_list(s: &str) -> Vec<String> {
    s.split(',')
        .map(str::trim)
        .filter(|s| !s.is_empty())
        .map(str::to_owned)
        .collect()
}

impl SuiteOptions {
    /// Options from `ARPA_REQUIRE_BACKENDS` and `ARPA_CONFORMANCE_CASES` (comma-separated
    /// lists; unset or empty: nothing required, every case).
    pub fn from_env() -> Self {
        let var = |k| std::env::var(k).map(|v| split_list(&v)).unwrap_or_default();
        Self {
            required: var(REQUIRE_ENV),
            filter: var(CASES_ENV),
        }
    }

    fn selects(&self, case: &Case) -> bool {
        self.filter.is_empty() || self.filter.iter().any(|f| case.id.contains(f.as_str()))
    }
}

/// A finished run: the table, the device of each backend that ran, and the wall time.
#[derive(Clone, Debug, PartialEq)]
pub struct SuiteRun {
    /// Case × backend verdicts.
    pub report: Report,
    /// `(backend, device description)` of every backend that initialised.
    pub devices: Vec<(String, String)>,
    /// Wall-clock time of the whole run (seconds).
    pub seconds: f64,
}

impl SuiteRun {
    /// Markdown document: a short header (devices, time, verdict) and the table.
    pub fn to_markdown(&self) -> String {
        let mut s = String::from("# arpa conformance\n\n");
        if self.devices.is_empty() {
            s.push_str("- no backend initialised (compiled in: enable the `cpu` feature, or `wgpu`/`vk` as they land)\n");
        }
        for (b, d) in &self.devices {
            s.push_str(&format!("- `{b}`: {d}\n"));
        }
        let skipped = self.report.skipped();
        let not_applicable = self.report.not_applicable();
        s.push_str(&format!(
            "- total {:.1} s; {}{}{}\n\n",
            self.seconds,
            if self.report.all_ok() {
                "all cases pass (or fail as expected, with a reason)"
            } else {
                "**unexpected failures**"
            },
            if skipped > 0 {
                format!("; **{skipped} skipped** (shared scenes absent)")
            } else {
                String::new()
            },
            if not_applicable > 0 {
                format!(
                    "; {not_applicable} not applicable (n/a: the backend lacks what the case needs; not a pass)"
                )
            } else {
                String::new()
            }
        ));
        s.push_str(&self.report.to_markdown());
        s
    }
}

fn panic_message(p: &(dyn std::any::Any + Send)) -> String {
    p.downcast_ref::<&str>()
        .map(|s| (*s).to_owned())
        .or_else(|| p.downcast_ref::<String>().cloned())
        .unwrap_or_else(|| "non-string panic payload".into())
}

/// Turns a case's outcome into a verdict under the backend's expectation.
pub fn verdict(outcome: CaseResult, expected_failure: Option<&str>) -> Verdict {
    match (outcome, expected_failure) {
        (_, Some(r)) if r.trim().is_empty() => Verdict::Fail {
            detail: "expected-failure entry without a reason (every expectation needs one)".into(),
        },
        (Err(measured), Some(reason)) => Verdict::ExpectedFail {
            reason: reason.to_owned(),
            measured,
        },
        (Ok(metric), Some(reason)) => Verdict::Fail {
            detail: format!(
                "passed ({metric}) although expected to fail ({reason}): remove the expectation"
            ),
        },
        (Ok(metric), None) => Verdict::Pass { metric },
        (Err(detail), None) => Verdict::Fail { detail },
    }
}

/// The verdict of a case whose data is missing: skipped, or failed when `ci`.
pub fn missing_data(missing: String, ci: bool) -> Verdict {
    if ci {
        Verdict::Fail {
            detail: format!("{missing}; CI is set, so missing data is a failure"),
        }
    } else {
        Verdict::Skipped { reason: missing }
    }
}

fn create(backend: &Backend) -> Result<Box<dyn DynTracer>, String> {
    match catch_unwind(|| (backend.create)(&BackendOptions::default())) {
        Ok(Ok(t)) => Ok(t),
        Ok(Err(e)) => Err(e.to_string()),
        Err(p) => Err(format!("panicked: {}", panic_message(&*p))),
    }
}

fn create_runner(make: MakeKernelRunner) -> Result<Box<dyn KernelRunner>, String> {
    match catch_unwind(make) {
        Ok(Ok(r)) => Ok(r),
        Ok(Err(e)) => Err(e.to_string()),
        Err(p) => Err(format!("panicked: {}", panic_message(&*p))),
    }
}

/// Runs `cases` on every backend of `backends` under `options`. Progress goes to stderr.
///
/// * A backend named in `options.required` that is not a known backend, or not in
///   `backends` (not compiled in), or that fails to initialise, fails the availability row.
///   A backend that is compiled in but not required and cannot initialise is recorded as
///   an expected failure with the error as reason, and its cases do not run.
/// * A panicking case fails (on that backend only); the backend is then re-created.
/// * [`CaseBody::Kernels`] cases run on the backend's kernel runner, created at the first
///   such case (even when the tracer cannot initialise); a backend without one records
///   them [`Verdict::NotApplicable`]. A runner that cannot initialise fails them when the
///   backend is required, else records an expected failure with the error as reason.
pub fn run_suite_with(backends: &[Backend], cases: &[Case], options: &SuiteOptions) -> SuiteRun {
    let start = Instant::now();
    let mut report = Report::default();
    let mut devices = Vec::new();
    for backend in backends {
        let required = options.required.iter().any(|r| r == backend.name);
        let mut tracer = match create(backend) {
            Ok(t) => {
                let device = t.capabilities().device;
                report.record(
                    AVAILABILITY_ROW,
                    backend.name,
                    Verdict::Pass {
                        metric: device.clone(),
                    },
                );
                devices.push((backend.name.to_owned(), device));
                Some(t)
            }
            Err(e) if required => {
                report.record(
                    AVAILABILITY_ROW,
                    backend.name,
                    Verdict::Fail {
                        detail: format!("required by {REQUIRE_ENV} but failed to initialise: {e}"),
                    },
                );
                None
            }
            Err(e) => {
                report.record(
                    AVAILABILITY_ROW,
                    backend.name,
                    Verdict::ExpectedFail {
                        reason: format!("not required by {REQUIRE_ENV}; failed to initialise: {e}"),
                        measured: String::new(),
                    },
                );
                None
            }
        };
        // The kernel runner, created at the first kernel case.
        let mut runner: Option<Result<Box<dyn KernelRunner>, String>> = None;
        for case in cases.iter().filter(|c| options.selects(c)) {
            match case.run {
                CaseBody::Tracer(_) if tracer.is_none() => continue,
                CaseBody::Kernels(_) if backend.kernel_runner.is_none() => {
                    report.record(
                        case.title,
                        backend.name,
                        Verdict::NotApplicable {
                            reason: format!(
                                "{} runs no WGSL (no kernel runner); the Rust core is the twin's reference",
                                backend.name
                            ),
                        },
                    );
                    continue;
                }
                _ => {}
            }
            if let Some(Err(missing)) = case.needs.map(|f| f()) {
                let v = missing_data(missing, ci_is_set());
                if let Verdict::Skipped { reason } = &v {
                    eprintln!(
                        "\n*** WARNING: conformance case '{}' SKIPPED on {}: {reason} ***\n",
                        case.id, backend.name
                    );
                }
                report.record(case.title, backend.name, v);
                continue;
            }
            let t0 = Instant::now();
            let outcome = match (case.run, backend.kernel_runner) {
                (CaseBody::Tracer(body), _) => {
                    let Some(t) = tracer.as_mut() else { continue };
                    match catch_unwind(AssertUnwindSafe(|| body(t.as_mut()))) {
                        Ok(r) => r,
                        Err(p) => {
                            let msg = format!("panicked: {}", panic_message(&*p));
                            // The tracer may be in any state after a panic: start afresh.
                            tracer = create(backend).ok();
                            Err(msg)
                        }
                    }
                }
                (CaseBody::Kernels(_), None) => continue, // recorded above
                (CaseBody::Kernels(body), Some(make)) => {
                    let r = runner.get_or_insert_with(|| {
                        let r = create_runner(make);
                        if let Ok(r) = &r {
                            devices.push((format!("{} kernel runner", backend.name), r.device()));
                        }
                        r
                    });
                    let r = match r {
                        Ok(r) => r,
                        Err(e) => {
                            let v = if required {
                                Verdict::Fail {
                                    detail: format!(
                                        "required by {REQUIRE_ENV} but its kernel runner failed to initialise: {e}"
                                    ),
                                }
                            } else {
                                Verdict::ExpectedFail {
                                    reason: format!(
                                        "not required by {REQUIRE_ENV}; kernel runner failed to initialise: {e}"
                                    ),
                                    measured: String::new(),
                                }
                            };
                            report.record(case.title, backend.name, v);
                            continue;
                        }
                    };
                    match catch_unwind(AssertUnwindSafe(|| body(r.as_ref()))) {
                        Ok(r) => r,
                        Err(p) => {
                            // The device may be in any state after a panic: start afresh.
                            runner = None;
                            Err(format!("panicked: {}", panic_message(&*p)))
                        }
                    }
                }
            };
            let secs = t0.elapsed().as_secs_f64();
            let outcome = outcome.map(|m| format!("{m}; {secs:.2} s"));
            let v = verdict(outcome, backend.expected_failure(case.id));
            eprintln!("[{}] {} ({secs:.2} s): {v:?}", backend.name, case.id);
            report.record(case.title, backend.name, v);
        }
    }
    for name in &options.required {
        if backends.iter().any(|b| b.name == name) {
            continue;
        }
        let detail = if BackendKind::from_name(name).is_some() {
            format!(
                "required by {REQUIRE_ENV} but not compiled in (enable feature `{name}` of arpa-conformance)"
            )
        } else {
            format!(
                "required by {REQUIRE_ENV} but no such backend (known: {})",
                BackendKind::ALL.map(BackendKind::name).join(", ")
            )
        };
        report.record(AVAILABILITY_ROW, name, Verdict::Fail { detail });
    }
    SuiteRun {
        report,
        devices,
        seconds: start.elapsed().as_secs_f64(),
    }
}


/// Adds context to a backend error: `"photon_pass: <error>"`.
pub(crate) trait Context<T> {
    fn ctx(self, what: &str) -> Result<T, String>;
}

impl<T> Context<T> for Result<T, BoxError> {
    fn ctx(self, what: &str) -> Result<T, String> {
        self.map_err(|e| format!("{what}: {e}"))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::backends::ExpectedFailure;

    fn no_device(_: &BackendOptions) -> Result<Box<dyn DynTracer>, BoxError> {
        Err("no adapter".into())
    }

    fn fake(name: &'static str, expected_failures: &'static [ExpectedFailure]) -> Backend {
        Backend {
            name,
            feature: name,
            create: no_device,
            expected_failures,
            kernel_runner: None,
        }
    }

    #[test]
    fn expectations_need_reasons_and_must_still_fail() {
        assert_eq!(
            verdict(Err("x".into()), Some("no f64 on this GPU")),
            Verdict::ExpectedFail {
                reason: "no f64 on this GPU".into(),
                measured: "x".into(),
            }
        );
        assert!(!verdict(Err("x".into()), Some("  ")).is_ok());
        assert!(!verdict(Ok("fine".into()), Some("why")).is_ok());
        assert!(verdict(Ok("fine".into()), None).is_ok());
        assert!(!verdict(Err("bad".into()), None).is_ok());
    }

    #[test]
    fn required_backends_must_exist_and_initialise() {
        let backends = [fake("wgpu", &[])];
        // Compiled in, not required, no device: expected failure, suite ok.
        let run = run_suite_with(&backends, &[], &SuiteOptions::default());
        assert!(run.report.all_ok(), "{}", run.report.to_markdown());
        assert!(run.report.to_markdown().contains("xfail (not required"));
        // Required but cannot initialise.
        let run = run_suite_with(
            &backends,
            &[],
            &SuiteOptions {
                required: vec!["wgpu".into()],
                filter: vec![],
            },
        );
        assert!(!run.report.all_ok());
        // Required, known, not compiled in.
        let run = run_suite_with(
            &[],
            &[],
            &SuiteOptions {
                required: vec!["vk".into()],
                filter: vec![],
            },
        );
        assert!(!run.report.all_ok());
        assert!(run.report.to_markdown().contains("not compiled in"));
        // Unknown name.
        let run = run_suite_with(
            &[],
            &[],
            &SuiteOptions {
                required: vec!["cuda".into()],
                filter: vec![],
            },
        );
        assert!(!run.report.all_ok());
        assert!(run.report.to_markdown().contains("no such backend"));
    }

    /// A runner that returns zeros (the kernel-case tests below never look at them).
    struct ZeroRunner;

    impl KernelRunner for ZeroRunner {
        fn device(&self) -> String {
            "zeros".into()
        }
        fn run(&self, job: &crate::KernelJob<'_>) -> Result<Vec<u32>, BoxError> {
            Ok(vec![0; job.output_words])
        }
    }

    fn zero_runner() -> Result<Box<dyn KernelRunner>, BoxError> {
        Ok(Box::new(ZeroRunner))
    }

    fn no_runner() -> Result<Box<dyn KernelRunner>, BoxError> {
        Err("no adapter for kernels".into())
    }

    fn kernel_case(run: fn(&dyn KernelRunner) -> CaseResult) -> Case {
        Case {
            id: "twin-x",
            title: "twin x",
            needs: None,
            run: CaseBody::Kernels(run),
        }
    }

    fn runs_one_kernel(r: &dyn KernelRunner) -> CaseResult {
        let out = r
            .run(&crate::KernelJob {
                label: "x",
                source: "",
                entry: "main",
                input: &[],
                invocations: 1,
                output_words: 3,
            })
            .map_err(|e| e.to_string())?;
        if out.len() == 3 {
            Ok("3 words".into())
        } else {
            Err(format!("{} words", out.len()))
        }
    }

    fn always_fails(_: &dyn KernelRunner) -> CaseResult {
        Err("twin differs".into())
    }

    #[test]
    fn kernel_cases_are_not_applicable_without_a_runner() {
        let backends = [fake("cpu", &[])];
        let run = run_suite_with(
            &backends,
            &[kernel_case(always_fails)],
            &SuiteOptions::default(),
        );
        let md = run.to_markdown();
        // Neither a failure (even though the body would fail) nor a pass, and said so.
        assert!(run.report.all_ok(), "{md}");
        assert_eq!(run.report.not_applicable(), 1, "{md}");
        assert_eq!(run.report.passed(), 0, "{md}");
        assert_eq!(run.report.skipped(), 0, "{md}");
        assert!(md.contains("| twin x | n/a (cpu runs no WGSL"), "{md}");
        assert!(md.contains("1 not applicable"), "{md}");
    }

    #[test]
    fn kernel_cases_run_on_the_runner_even_without_a_tracer() {
        let backend = Backend {
            kernel_runner: Some(zero_runner),
            ..fake("wgpu", &[])
        };
        let run = run_suite_with(
            &[backend],
            &[kernel_case(runs_one_kernel)],
            &SuiteOptions::default(),
        );
        assert!(run.report.all_ok(), "{}", run.report.to_markdown());
        assert_eq!(run.report.passed(), 1);
        assert!(
            run.devices
                .iter()
                .any(|(b, d)| b == "wgpu kernel runner" && d == "zeros")
        );
        // A failing body on a runner is a failure.
        let run = run_suite_with(
            &[backend],
            &[kernel_case(always_fails)],
            &SuiteOptions::default(),
        );
        assert!(!run.report.all_ok());
        assert!(run.report.to_markdown().contains("**FAIL** (twin differs)"));
    }

    #[test]
    fn a_runner_that_cannot_start_fails_only_when_required() {
        let backend = Backend {
            kernel_runner: Some(no_runner),
            ..fake("wgpu", &[])
        };
        let cases = [kernel_case(runs_one_kernel)];
        let run = run_suite_with(&[backend], &cases, &SuiteOptions::default());
        assert!(run.report.all_ok(), "{}", run.report.to_markdown());
        assert!(
            run.report
                .to_markdown()
                .contains("kernel runner failed to initialise: no adapter for kernels")
        );
        let required = SuiteOptions {
            required: vec!["wgpu".into()],
            filter: vec![],
        };
        let run = run_suite_with(&[backend], &cases, &required);
        assert!(!run.report.all_ok());
        assert!(
            run.report
                .to_markdown()
                .contains("required by ARPA_REQUIRE_BACKENDS but its kernel runner failed")
        );
    }

    #[test]
    fn missing_data_skips_outside_ci_and_fails_in_ci() {
        let v = missing_data("../shared absent".into(), false);
        assert!(v.is_ok() && matches!(v, Verdict::Skipped { .. }));
        let mut r = crate::Report::default();
        r.record("reference", "cpu", v);
        assert_eq!(r.skipped(), 1);
        assert!(r.to_markdown().contains("**SKIPPED** (../shared absent)"));
        assert!(!missing_data("../shared absent".into(), true).is_ok());
    }

    #[test]
    fn list_parsing() {
        assert_eq!(
            split_list(" cpu, wgpu ,,"),
            vec!["cpu".to_owned(), "wgpu".to_owned()]
        );
        assert!(split_list("").is_empty());
    }
}
