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
//! | gather | [`kernel`], [`estimate`], [`bandwidth`] (the scale ladder) |
//! | accumulate | [`radius`], [`accumulate`], [`bandwidth`] (per-pixel scale selection) |
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
//! * neither (`default-features = false`): pure `no_std` without a heap, maths through
//!   [`libm`] (re-exported, as is [`glam`]): everything a renderer needs per photon and
//!   per query point, from emission to the estimate.
//! * `alloc`: adds the renderer-facing layer that needs a heap: the scene model
//!   ([`scene`], [`shapes`], [`prepared_scene`]), the backend trait ([`tracer`]), the
//!   reference paths ([`photon_path`], [`camera_path`], [`ray_cast`]), the image
//!   accumulator ([`accumulate::ImageAccumulator`]), [`shaders::compose`] and the GPU
//!   layer's scene tables ([`gpu::scene`]). Items that need it are marked in the docs.
//! * `std` (default): implies `alloc`; adds what needs the standard library (stage
//!   timing in [`tracer::StageClock::run`]).
//!
//! ## A first photon
//! One photon of a point light one metre above the floor `z = 0`, its footprint where it
//! lands, and the irradiance the footprint gives at its centre (every stage has a longer
//! example in its module):
//!
//! ```
//! use arpa_core::differential::NormalDifferential;
//! use arpa_core::emission::{EmissionParams, Light, PointLight};
//! use arpa_core::footprint::{Footprint, PhotonMap};
//! use arpa_core::glam::DVec3;
//! use arpa_core::kernel::Kernel;
//! use arpa_core::rng::{Rng, StreamDomain};
//!
//! let light = Light::Point(PointLight { position: DVec3::new(0.0, 0.0, 1.0), intensity: DVec3::ONE });
//! let n = 10_000;
//! let prepared = light.prepare(&EmissionParams::new(n).for_iteration(1, 0, 0)).unwrap();
//! // Photon 0 heads somewhere on the sphere of directions; take the first one going down.
//! let (index, photon) = (0..n)
//!     .map(|i| (i, prepared.emit(i, &mut Rng::new(1, 0, i, StreamDomain::Photon)).unwrap()))
//!     .find(|(_, p)| p.ray.d.z < -0.5)
//!     .unwrap();
//! // Propagate to the floor: distance along the ray, then the differentials' transfer.
//! let t = -photon.ray.p.z / photon.ray.d.z;
//! let hit = photon.ray.transfer(t, DVec3::Z).unwrap();
//! let fp = Footprint::from_hit(&hit, DVec3::Z, photon.flux, PhotonMap::Global).unwrap();
//! // Inside its own ellipse, on the lit side, the footprint contributes Φ·W(x_p) > 0.
//! let e = fp.irradiance(fp.center, DVec3::Z, 0.01, Kernel::Silverman);
//! assert!(e.x > 0.0 && e.is_finite());
//! # let _ = (index, NormalDifferential::flat(DVec3::Z));
//! ```
#![no_std]
#![deny(missing_docs)]
#![cfg_attr(docsrs, feature(doc_cfg))]
// The docs link to the `alloc` and `std` items wherever they are the next step; in a build
// without them those items do not exist and the links render as plain text (the default
// `std` build checks every link).
#![cfg_attr(not(feature = "std"), allow(rustdoc::broken_intra_doc_links))]
// `!(x > 0.0)` is used on purpose throughout: it is true for NaN, which must be rejected.
#![allow(clippy::neg_cmp_op_on_partial_ord)]

#[cfg(feature = "alloc")]
extern crate alloc;
#[cfg(feature = "std")]
extern crate std;

pub mod aabb;
pub mod accumulate;
pub mod bandwidth;
#[cfg(feature = "alloc")]
#[cfg_attr(docsrs, doc(cfg(feature = "alloc")))]
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
#[cfg_attr(docsrs, doc(cfg(feature = "alloc")))]
pub mod prepared_scene;
#[cfg(feature = "alloc")]
#[cfg_attr(docsrs, doc(cfg(feature = "alloc")))]
pub mod photon_path;
pub mod prefetch;
#[cfg(feature = "alloc")]
#[cfg_attr(docsrs, doc(cfg(feature = "alloc")))]
pub mod projection;
pub mod progressive_photon;
pub mod radius;
#[cfg(feature = "alloc")]
#[cfg_attr(docsrs, doc(cfg(feature = "alloc")))]
pub mod ray_cast;
pub mod reemission;
pub mod rng;
pub mod sampling;
#[cfg(feature = "alloc")]
#[cfg_attr(docsrs, doc(cfg(feature = "alloc")))]
pub mod scene;
pub mod shading_normal;
pub mod shaders;
#[cfg(feature = "alloc")]
#[cfg_attr(docsrs, doc(cfg(feature = "alloc")))]
pub mod shapes;
pub mod store;
#[cfg(feature = "alloc")]
#[cfg_attr(docsrs, doc(cfg(feature = "alloc")))]
pub mod tracer;

pub use glam;
pub use libm;
