//! The whole suite under `cargo test -p arpa-conformance`: every case on every backend
//! compiled in (honouring `ARPA_REQUIRE_BACKENDS` and `ARPA_CONFORMANCE_CASES`); the
//! table is printed and written to `<target dir>/conformance.md`.

use arpa_conformance::{SuiteOptions, run_suite};

#[test]
fn conformance_suite() {
    let run = run_suite(&SuiteOptions::from_env());
    let md = run.to_markdown();
    println!("{md}");
    // Integration tests run from the package root; the target dir is CARGO_TARGET_DIR or
    // the workspace's `target/`.
    let target = std::env::var_os("CARGO_TARGET_DIR")
        .filter(|d| !d.is_empty())
        .map(std::path::PathBuf::from)
        .unwrap_or_else(|| {
            std::path::PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/../target"))
        });
    if std::fs::create_dir_all(&target).is_ok() {
        let _ = std::fs::write(target.join("conformance.md"), &md);
    }
    assert!(run.report.all_ok(), "unexpected failures:\n{md}");
}
