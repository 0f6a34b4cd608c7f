//! `conformance`: runs the suite on every backend compiled in, prints the case × backend
//! table and writes it as Markdown.
//!
//! ```text
//! conformance [--out FILE] [--case ID[,ID…]] [--list]
//! ```
//!
//! `--out` defaults to `$CARGO_TARGET_DIR/conformance.md` (or the workspace's
//! `target/conformance.md`). `ARPA_REQUIRE_BACKENDS=cpu,wgpu,vk` names backends that must be
//! compiled in and initialise; `ARPA_CONFORMANCE_CASES` (or `--case`) selects cases by id
//! substring. Exit status 1 on any unexpected failure, 2 on a usage error.
//!
//! Run it optimised: `cargo run -p arpa-conformance --profile test` (the reference cases
//! render whole images).

use std::path::PathBuf;
use std::process::ExitCode;

use arpa_conformance::{SuiteOptions, backends, cases, run_suite};

fn default_out() -> PathBuf {
    let target = std::env::var_os("CARGO_TARGET_DIR")
        .filter(|d| !d.is_empty())
        .map(PathBuf::from)
        .unwrap_or_else(|| PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/../target")));
    target.join("conformance.md")
}

fn main() -> ExitCode {
    let mut options = SuiteOptions::from_env();
    let mut out = default_out();
    let mut args = std::env::args().skip(1);
    while let Some(a) = args.next() {
        match a.as_str() {
            "--out" | "-o" => match args.next() {
                Some(p) => out = PathBuf::from(p),
                None => return usage("--out needs a path"),
            },
            "--case" => match args.next() {
                Some(c) => options.filter.extend(
                    c.split(',')
                        .map(str::trim)
                        .filter(|s| !s.is_empty())
                        .map(str::to_owned),
                ),
                None => return usage("--case needs an id"),
            },
            "--list" => {
                let compiled: Vec<&str> = backends::compiled().iter().map(|b| b.name).collect();
                println!("backends compiled in: {}", compiled.join(", "));
                for c in cases::all() {
                    println!("{:<30} {}", c.id, c.title);
                }
                return ExitCode::SUCCESS;
            }
            "-h" | "--help" => {
                println!(
                    "usage: conformance [--out FILE] [--case ID[,ID...]] [--list]\nenv: ARPA_REQUIRE_BACKENDS=cpu,wgpu,vk  ARPA_CONFORMANCE_CASES=id,..."
                );
                return ExitCode::SUCCESS;
            }
            other => return usage(&format!("unknown argument '{other}'")),
        }
    }
    let run = run_suite(&options);
    let md = run.to_markdown();
    println!("{md}");
    if let Some(dir) = out.parent().filter(|d| !d.as_os_str().is_empty())
        && let Err(e) = std::fs::create_dir_all(dir)
    {
        eprintln!("conformance: cannot create {}: {e}", dir.display());
        return ExitCode::FAILURE;
    }
    if let Err(e) = std::fs::write(&out, &md) {
        eprintln!("conformance: cannot write {}: {e}", out.display());
        return ExitCode::FAILURE;
    }
    eprintln!("conformance: report written to {}", out.display());
    if run.report.all_ok() {
        ExitCode::SUCCESS
    } else {
        ExitCode::FAILURE
    }
}

fn usage(msg: &str) -> ExitCode {
    eprintln!("conformance: {msg}\nusage: conformance [--out FILE] [--case ID[,ID...]] [--list]");
    ExitCode::from(2)
}
