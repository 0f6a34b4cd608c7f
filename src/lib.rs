//! # arpa
//!
//! ARPA — photon mapping with photon differentials on ray-tracing hardware. This is the
//! facade crate: it re-exports the mathematical core ([`core`]) and holds the backend
//! registry ([`backends`]: one cargo feature per backend, `cpu` and `wgpu`), the render
//! loop ([`session`]), the scene-file loader ([`scene_file`]), the embedded default scene
//! ([`default_scene`]), image input/output ([`image_io`]) and the image metrics
//! ([`metrics`]).
//!
//! Cargo feature `cli` (on by default) adds the run-time-against-error harness (module
//! `bench`), the `arpa` command-line tool (module `cli`, the `arpa` binary) and the crates
//! only they need (clap, indicatif, serde, toml, plotters, ...). Without it this crate is
//! the library a renderer's tests build on: `arpa-conformance` depends on it with
//! `default-features = false`.
#![cfg_attr(feature = "cli", doc = "")]
#![cfg_attr(feature = "cli", doc = "In this build: [`bench`](mod@bench), [`cli`].")]
#![warn(missing_docs)]

pub use arpa_core as core;
#[cfg(feature = "cpu")]
pub use arpa_cpu as cpu;

pub mod backends;
#[cfg(feature = "cli")]
pub mod bench;
#[cfg(feature = "cli")]
pub mod cli;
pub mod default_scene;
pub mod image_io;
pub mod metrics;
#[cfg(feature = "cli")]
pub mod scale_map;
pub mod scene_file;
pub mod session;
pub mod state_file;
