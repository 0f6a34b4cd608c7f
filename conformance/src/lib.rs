//! # arpa-conformance
//!
//! The one conformance suite of arpa: backend-agnostic cases that run against every
//! backend compiled in and report a case × backend table.
//!
//! * [`DynTracer`]: the object-safe face of any [`arpa_core::render::tracer::Tracer`]; every case
//!   is one function of `&mut dyn DynTracer`, written once for all backends.
//! * [`backends`]: the registry. Each backend is a cargo feature of this crate (`cpu`, on
//!   by default; `wgpu`, `vk` as they land) with the cases it is expected to fail, each
//!   with a reason ([`Verdict::ExpectedFail`]).
//! * [`cases`]: the cases (stage agreement with `arpa-core`, gather exactness, camera pass
//!   through a mirror and a glass slab against exact optics, analytic scenes (plane,
//!   furnace, glass slab, mirror caustic, a small mirror in an open scene with projection
//!   off and on), independent references (each scene of `../shared/scenes` against its
//!   Mitsuba 3 / LuxCore ground truth), determinism, bad input, and the core's WGSL twin
//!   against the Rust core ([`cases::twin`])).
//! * [`KernelRunner`]: the capability the WGSL-twin cases need, offered per backend by the
//!   registry; a backend without one (cpu) reports them [`Verdict::NotApplicable`].
//! * [`suite`]: the runner. `ARPA_REQUIRE_BACKENDS=cpu,wgpu,vk` makes a listed backend that
//!   is unknown, not compiled in or unable to initialise a failure.
//!
//! Run it with `cargo run -p arpa-conformance --profile test [-- --out FILE]` (opt-level 2;
//! writes `target/conformance.md` by default) or `cargo test -p arpa-conformance` (asserts
//! that nothing failed unexpectedly, and writes the same file).
//! Add `--features wgpu` for the wgpu backend (its WGSL-twin cases run on lavapipe without a
//! GPU; `--test twin` runs only them, with their sabotage check).
//!
//! ## Reference cases: reduced and full set, missing data
//!
//! The reference cases ([`cases::reference`]) run a **reduced set** by default and in CI
//! (¼ of the reference resolution, 8 × 100k photons, the reference box-averaged 4 × 4;
//! seconds on 2 cores). Set `ARPA_CONFORMANCE_FULL=1` for the **full set** (reference
//! resolution, 64 × 250k photons, tighter limits; minutes). They read `../shared/scenes`
//! beside the repository (or `ARPA_SHARED_SCENES`); if it is absent they are skipped with
//! a loud warning ([`Verdict::Skipped`]), or fail when env `CI` is set
//! ([`suite::ci_is_set`]).
//! `ARPA_CONFORMANCE_IMAGES=DIR` writes the renders and references for inspection.
//!
//! ## Your own tracer
//!
//! A renderer that implements [`arpa_core::render::tracer::Tracer`] but is not one of arpa's
//! backends runs the same suite: wrap its constructor in [`Backend::external`] and hand it
//! to [`run_suite_with`] with the cases of [`cases::all`]. Without its default features
//! this crate builds no backend of its own and none of the `arpa` command line's crates
//! (the facade's `cli` feature stays off), so it is a light dev-dependency:
//!
//! ```toml
//! [dev-dependencies]
//! arpa-conformance = { path = "../arpa/conformance", default-features = false }
//!
//! # The suite prints its own table and sets the exit status: no libtest harness.
//! [[test]]
//! name = "conformance"
//! harness = false
//! ```
//!
//! and `tests/conformance.rs`:
//!
//! ```no_run
//! use std::process::ExitCode;
//!
//! use arpa_conformance::{Backend, ExpectedFailure, SuiteOptions, cases, run_suite_with};
//! # mod my_renderer {
//! #     pub struct MyTracer;
//! #     impl MyTracer {
//! #         pub fn new() -> Result<Box<dyn arpa_conformance::DynTracer>, arpa_conformance::BoxError> {
//! #             Err("a stand-in".into())
//! #         }
//! #     }
//! # }
//! use my_renderer::MyTracer; // your `Tracer + Send`
//!
//! fn main() -> ExitCode {
//!     let mine = Backend::external("mine", |_options| Ok(Box::new(MyTracer::new()?)))
//!         // Optional: cases it cannot pass yet, each with its reason.
//!         .with_expected_failures(&[ExpectedFailure {
//!             case: "determinism-threads",
//!             reason: "the gather sums with float atomics",
//!         }]);
//!     // `ARPA_CONFORMANCE_CASES=id,...` still selects cases; requiring "mine" makes a
//!     // tracer that cannot start a failure rather than "unavailable".
//!     let mut options = SuiteOptions::from_env();
//!     options.required.push("mine".into());
//!     let run = run_suite_with(&[mine], &cases::all(), &options);
//!     println!("{}", run.to_markdown());
//!     if run.report.all_ok() { ExitCode::SUCCESS } else { ExitCode::FAILURE }
//! }
//! ```
//!
//! Run it with `cargo test --test conformance` (under an optimising test profile: the
//! reference cases render whole images). A case that fails is a `**FAIL**` cell and exit
//! status 1; [`Report::get`] reads single cells where a `#[test]` wants to assert on them.
//! The reference cases find `shared/scenes` beside this crate's repository, or at
//! `ARPA_SHARED_SCENES`; the WGSL-twin cases are not applicable (they need a
//! [`KernelRunner`], which only arpa's own GPU backends offer).
#![warn(missing_docs)]

pub mod backends;
pub mod cases;
pub mod dyn_tracer;
pub mod kernel_runner;
pub mod report;
pub mod scenes;
pub mod suite;

pub use backends::{Backend, BackendOptions, CreateTracer, ExpectedFailure};
pub use dyn_tracer::{BoxError, DynTracer};
pub use kernel_runner::{KernelJob, KernelRunner};
pub use report::{Report, Verdict};
pub use suite::{Case, CaseBody, CaseResult, SuiteOptions, SuiteRun, run_suite_with};

/// Runs every case on every backend compiled in, under `options`.
pub fn run_suite(options: &SuiteOptions) -> SuiteRun {
    run_suite_with(&backends::compiled(), &cases::all(), options)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn markdown_table() {
        let mut r = Report::default();
        r.record(
            "gather exactness",
            "cpu",
            Verdict::Pass {
                metric: "max rel 3e-7".into(),
            },
        );
        r.record(
            "determinism",
            "wgpu",
            Verdict::ExpectedFail {
                reason: "no adapter".into(),
                measured: String::new(),
            },
        );
        assert!(r.all_ok());
        let md = r.to_markdown();
        assert_eq!(md.lines().count(), 4);
        assert!(md.contains("| gather exactness | pass (max rel 3e-7) | – |"));
        assert!(matches!(
            r.get("gather exactness", "cpu"),
            Some(Verdict::Pass { .. })
        ));
        assert_eq!(r.get("gather exactness", "wgpu"), None);
        assert_eq!(r.get("no such case", "cpu"), None);
        r.record(
            "determinism",
            "cpu",
            Verdict::Fail {
                detail: "images differ".into(),
            },
        );
        assert!(!r.all_ok());
        assert!(r.to_markdown().contains("**FAIL**"));
    }
}
