//! # arpa
//!
//! ARPA — photon mapping with photon differentials on ray-tracing hardware. This is the
//! facade crate: it re-exports the mathematical core ([`core`]) and will hold scene
//! loading, the backends chosen with cargo features, and the `arpa` command-line tool.
#![warn(missing_docs)]

pub use arpa_core as core;
