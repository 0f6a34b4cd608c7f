//! # arpa
//!
//! ARPA — photon mapping with photon differentials on ray-tracing hardware. This is the
//! facade crate: it re-exports the mathematical core ([`core`]) and holds the embedded
//! default scene ([`default_scene`]), image input/output ([`image_io`]) and the `arpa`
//! command-line tool ([`cli`]). Backends are chosen with cargo features (`cpu`).
#![warn(missing_docs)]

pub use arpa_core as core;
#[cfg(feature = "cpu")]
pub use arpa_cpu as cpu;

pub mod cli;
pub mod default_scene;
pub mod image_io;
pub mod metrics;
pub mod scene_file;
