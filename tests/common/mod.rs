//! Helpers shared by the root package's integration tests.

use std::path::{Path, PathBuf};

/// `shared/scenes` beside the repository (as on CI), or `None` with a loud message. With
/// `CI` set, missing scenes are a failure.
pub fn shared_scenes() -> Option<PathBuf> {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared/scenes");
    if dir.join("README.md").is_file() {
        return Some(dir);
    }
    if std::env::var_os("CI").is_some() {
        panic!("CI is set but the shared scenes are missing at {}", dir.display());
    }
    eprintln!("\n=== SKIPPED: shared scenes not found at {} (set CI to make this a failure) ===\n", dir.display());
    None
}
