//! Adds an rpath to the Embree 4 library directory to the `arpa` binary (and the root
//! package's tests), so `cargo run -- render` works without `LD_LIBRARY_PATH`.
//!
//! `arpa-cpu`'s build script finds `libembree4.so` and, through `links = "arpa_embree4"`
//! and `cargo:libdir=…`, exports the directory to dependents as `DEP_ARPA_EMBREE4_LIBDIR`.
//! Cargo does not propagate `rustc-link-arg` from a dependency, so the root package adds
//! the rpath itself. Without the `cpu` feature the variable is absent and nothing happens.

fn main() {
    println!("cargo:rerun-if-changed=build.rs");
    println!("cargo:rerun-if-env-changed=DEP_ARPA_EMBREE4_LIBDIR");
    if let Some(dir) = std::env::var_os("DEP_ARPA_EMBREE4_LIBDIR").filter(|d| !d.is_empty()) {
        let dir = std::path::PathBuf::from(dir);
        println!("cargo:rustc-link-arg=-Wl,-rpath,{}", dir.display());
    }
}
