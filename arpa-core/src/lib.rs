//! # arpa-core
//!
//! The `no_std` mathematical core of ARPA: photon mapping with *photon differentials*
//! (De Barro, Bugeja & Spina), built on Igehy's ray differentials, Frisvad et al.'s
//! filter-space transform, Fabianowski's absorb-and-re-emit trick and Knaus & Zwicker's
//! progressive radius schedule.
//!
//! The modules follow the pipeline of one photon-mapping iteration:
//!
//! | stage | modules |
//! |---|---|
//! | random numbers | [`rng`], [`sampling`], [`frame`] |
//! | emit | [`emission`] |
//! | propagate | [`differential`], [`shading_normal`], [`fresnel`], [`lambertian`], [`reemission`], [`classify`] |
//! | store footprints | [`footprint`], [`heuristics`], [`progressive_photon`], [`store`], [`aabb`] |
//! | build AS | (backends; [`aabb`] gives the boxes) |
//! | gather | [`kernel`], [`estimate`] |
//! | accumulate | [`radius`], [`accumulate`] |
//!
//! With the `alloc` feature, the renderer-facing layer: the scene model ([`scene`],
//! [`shapes`], [`prepared_scene`]), the backend trait ([`tracer`]) and the reference
//! per-photon and per-pixel paths every backend must reproduce ([`photon_path`],
//! [`camera_path`], over a [`ray_cast::RayCaster`]).
//!
//! [`shaders`] holds the WGSL twin of the per-photon maths (rng, kernel, footprint,
//! radius, differentials) and the path-level WGSL of the GPU stages (camera pass, photon
//! pass, store, sort, gather, accumulate) as source strings, composed in dependency order
//! by [`shaders::compose`]. [`gpu`] is the host side both GPU backends share: the record
//! layouts those shaders read and write, their codes, Morton codes and the photon batch
//! policy. No backend depends on another backend; both depend on these two modules.
//!
//! ## Conventions
//! * World space is right-handed, units are *scene units* (the scene's length unit, called
//!   metres in doc comments for brevity). Directions are unit vectors.
//! * Propagation math is done in `f64` ([`glam::DVec3`]) so that extreme differential
//!   magnitudes (1e-30 … 1e30) neither overflow nor underflow; what is stored for the
//!   gather ([`footprint::PackedFootprint`], [`progressive_photon::PackedPhoton`]) is `f32`,
//!   laid out for GPU storage buffers.
//! * Colours are linear RGB triples. Flux is in watts (W), irradiance in W/m²,
//!   radiance in W/(m²·sr), intensity in W/sr.
//! * No function panics on any input: functions return finite values, or an explicit
//!   error/degenerate label.
//!
//! ## Features
//! * `std` (default): implies `alloc`; uses the standard library.
//! * `alloc`: heap-backed helpers such as [`accumulate::ImageAccumulator`].
//! * neither: pure `no_std`, maths through `libm`.
#![no_std]
#![warn(missing_docs)]
// `!(x > 0.0)` is used on purpose throughout: it is true for NaN, which must be rejected.
#![allow(clippy::neg_cmp_op_on_partial_ord)]

#[cfg(feature = "alloc")]
extern crate alloc;
#[cfg(feature = "std")]
extern crate std;

pub mod aabb;
pub mod accumulate;
#[cfg(feature = "alloc")]
pub mod camera_path;
pub mod classify;
pub mod differential;
pub mod emission;
pub mod estimate;
pub mod footprint;
pub mod frame;
pub mod gpu;
pub mod fresnel;
pub mod heuristics;
pub mod kernel;
pub mod lambertian;
#[cfg(feature = "alloc")]
pub mod prepared_scene;
#[cfg(feature = "alloc")]
pub mod photon_path;
pub mod prefetch;
pub mod progressive_photon;
pub mod radius;
#[cfg(feature = "alloc")]
pub mod ray_cast;
pub mod reemission;
pub mod rng;
pub mod sampling;
#[cfg(feature = "alloc")]
pub mod scene;
pub mod shading_normal;
pub mod shaders;
#[cfg(feature = "alloc")]
pub mod shapes;
pub mod store;
#[cfg(feature = "alloc")]
pub mod tracer;

pub use glam;
