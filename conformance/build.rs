//! Adds an rpath to the Embree 4 library directory to the `conformance` binary and the
//! suite's tests, so they run without `LD_LIBRARY_PATH` (as the root package's build
//! script does). `arpa-cpu` exports the directory as `DEP_ARPA_EMBREE4_LIBDIR` through its
//! `links = "arpa_embree4"`; without the `cpu` feature it is absent and nothing happens.

fn main() {
    println!("cargo:rerun-if-changed=build.rs");
    println!("cargo:rerun-if-env-changed=DEP_ARPA_EMBREE4_LIBDIR");
    if let Some(dir) = std::env::var_os("DEP_ARPA_EMBREE4_LIBDIR").filter(|d| !d.is_empty()) {
        println!(
            "cargo:rustc-link-arg=-Wl,-rpath,{}",
            std::path::PathBuf::from(dir).display()
        );
    }
}
