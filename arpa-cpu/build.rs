//! Locates the Embree 4 shared library for linking.
//!
//! `embree4-sys` only emits `cargo:rustc-link-lib=embree4`; it adds no search path. This
//! script adds `-L <libdir>` (propagated by Cargo to everything that links arpa-cpu) and an
//! rpath for arpa-cpu's own tests/examples/benches, so `cargo test` works without
//! `LD_LIBRARY_PATH`.
//!
//! Search order:
//! 1. `$EMBREE_DIR/lib`, `$EMBREE_DIR/lib64`, `$EMBREE_DIR`,
//! 2. `<workspace root>/.deps/embree4/lib` (what `scripts/install-embree4.sh` lays out),
//! 3. `pkg-config --variable=libdir embree4`.
//!
//! The chosen directory is also exported as `DEP_ARPA_EMBREE4_LIBDIR` to the build scripts
//! of crates depending on arpa-cpu (through `links = "arpa_embree4"`).

use std::env;
use std::path::{Path, PathBuf};
use std::process::Command;

fn has_embree(dir: &Path) -> bool {
    dir.join("libembree4.so").exists()
}

fn main() {
    println!("cargo:rerun-if-changed=build.rs");
    println!("cargo:rerun-if-env-changed=EMBREE_DIR");
    println!("cargo:rerun-if-env-changed=PKG_CONFIG_PATH");

    let manifest_dir = PathBuf::from(env::var("CARGO_MANIFEST_DIR").expect("CARGO_MANIFEST_DIR"));
    let workspace_root = manifest_dir.parent().unwrap_or(&manifest_dir).to_path_buf();
    let default_prefix = workspace_root.join(".deps").join("embree4");
    // Re-run when the default prefix gets (re)installed.
    println!(
        "cargo:rerun-if-changed={}",
        default_prefix.join(".installed").display()
    );

    let mut tried: Vec<PathBuf> = Vec::new();
    let mut found: Option<PathBuf> = None;

    if let Some(dir) = env::var_os("EMBREE_DIR").filter(|d| !d.is_empty()) {
        let dir = PathBuf::from(dir);
        for cand in [dir.join("lib"), dir.join("lib64"), dir.clone()] {
            if found.is_none() && has_embree(&cand) {
                found = Some(cand.clone());
            }
            tried.push(cand);
        }
    }
    if found.is_none() {
        let cand = default_prefix.join("lib");
        if has_embree(&cand) {
            found = Some(cand.clone());
        }
        tried.push(cand);
    }
    if found.is_none()
        && let Ok(out) = Command::new("pkg-config")
            .args(["--variable=libdir", "embree4"])
            .output()
        && out.status.success()
    {
        let cand = PathBuf::from(String::from_utf8_lossy(&out.stdout).trim());
        if !cand.as_os_str().is_empty() {
            if has_embree(&cand) {
                found = Some(cand.clone());
            }
            tried.push(cand);
        }
    }

    let Some(libdir) = found else {
        let tried: Vec<String> = tried.iter().map(|p| p.display().to_string()).collect();
        // `cargo::error` fails the build with this message after the script returns.
        println!(
            "cargo::error=arpa-cpu: the Embree 4 shared library (libembree4.so) was not found \
             (looked in: {}).",
            tried.join(", ")
        );
        println!(
            "cargo::error=Run `scripts/install-embree4.sh` from the workspace root (installs \
             Embree 4.4 into {}), or set EMBREE_DIR to an existing Embree 4.4 install.",
            default_prefix.display()
        );
        return;
    };
    let libdir = libdir.canonicalize().unwrap_or(libdir);

    println!("cargo:rustc-link-search=native={}", libdir.display());
    // rustc-link-arg only applies to this package's own linked targets (tests, examples,
    // benches); dependents use DEP_ARPA_EMBREE4_LIBDIR or LD_LIBRARY_PATH.
    println!("cargo:rustc-link-arg=-Wl,-rpath,{}", libdir.display());
    println!("cargo:libdir={}", libdir.display());
}
