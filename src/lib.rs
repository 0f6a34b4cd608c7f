//! # arpa
//!
//! ARPA — photon mapping with photon differentials on ray-tracing hardware. This is the
//! facade crate: it re-exports the mathematical core ([`core`]) and holds the backend
//! registry ([`backends`]: one cargo feature per backend, `cpu` and `wgpu`), the render
//! loop ([`session`]), the scene-file loader ([`scene_file`]), the embedded default scene
//! ([`default_scene`]), image input/output ([`image_io`]), the image metrics ([`metrics`]),
//! the run-time-against-error harness ([`bench`](mod@bench)) and the `arpa` command-line tool ([`cli`]).
#![warn(missing_docs)]

pub use arpa_core as core;
#[cfg(feature = "cpu")]
pub use arpa_cpu as cpu;

pub mod backends;
pub mod bench;
pub mod cli;
pub mod default_scene;
pub mod image_io;
pub mod metrics;
pub mod scene_file;
pub mod session;
