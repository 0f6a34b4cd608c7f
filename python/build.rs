//! Adds an rpath to the Embree 4 library directory to the extension module, so that
//! `import arpa` finds `libembree4.so` without `LD_LIBRARY_PATH` (as the facade's build.rs
//! does for the `arpa` binary). `arpa-cpu`'s build script exports the directory it linked
//! against as `DEP_ARPA_EMBREE4_LIBDIR`; a wheel repaired by maturin bundles the library
//! instead and rewrites the rpath.

fn main() {
    println!("cargo:rerun-if-changed=build.rs");
    println!("cargo:rerun-if-env-changed=DEP_ARPA_EMBREE4_LIBDIR");
    if let Some(dir) = std::env::var_os("DEP_ARPA_EMBREE4_LIBDIR").filter(|d| !d.is_empty()) {
        println!("cargo:rustc-link-arg=-Wl,-rpath,{}", std::path::PathBuf::from(dir).display());
    }
}
