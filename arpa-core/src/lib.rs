//! # arpa-core
//!
//! The `no_std` mathematical core of ARPA: photon mapping with *photon differentials*
//! (De Barro, Bugeja & Spina), built on Igehy's ray differentials, Frisvad et al.'s
//! filter-space transform, Fabianowski's absorb-and-re-emit trick and Knaus & Zwicker's
//! progressive radius schedule.
//!
//! The crate is in four layers, each a set of folders, and every import points down
//! (`tests/layering.rs` at the workspace root checks it, and that no module imports
//! another in a circle):
//!
//! | layer | folders | needs |
//! |---|---|---|
//! | base | [`base`]: counter-based random numbers, sampling, frames, boxes, Morton codes | `no_std` |
//! | per-photon stages | [`emit`], [`propagate`], [`store`], [`gather`], [`accumulate`] | `no_std` (a few items `alloc`) |
//! | renderer layer | [`render`]: scene model, preparation, projection maps, the `Tracer` trait, reference paths, ray casting | `alloc` |
//! | GPU layer | [`gpu`]: device record layouts, codes, sort and batch policy, the WGSL sources | `no_std` (scene tables and composition `alloc`) |
//!
//! The per-photon stages follow one photon-mapping iteration:
//!
//! | stage | modules |
//! |---|---|
//! | emit | [`emit::emission`] |
//! | propagate | [`propagate::differential`], [`propagate::shading_normal`], [`propagate::fresnel`], [`propagate::lambertian`], [`propagate::reemission`], [`propagate::classify`] |
//! | store footprints | [`store::footprint`], [`store::heuristics`], [`store::progressive_photon`], [`store::decision`] |
//! | build AS | (backends; [`base::aabb`] gives the boxes, [`base::morton`] the order) |
//! | gather | [`gather::kernel`], [`gather::estimate`], [`gather::scales`] (the scale ladder) |
//! | accumulate | [`accumulate::radius`], [`accumulate::image`], [`accumulate::bandwidth`] (per-pixel scale selection) |
//!
//! With the `alloc` feature, the renderer-facing layer [`render`]: the scene model
//! ([`render::scene`], [`render::shapes`], [`render::prepared_scene`], with the projection
//! maps of [`render::projection`]), the backend trait ([`render::tracer`]) and the
//! reference per-photon and per-pixel paths every backend must reproduce
//! ([`render::photon_path`] under a [`render::emission_plan`], [`render::camera_path`],
//! over a [`render::ray_cast::RayCaster`]).
//!
//! [`gpu::shaders`] holds the WGSL twin of the per-photon maths (its files in
//! `arpa-core/shaders/` follow the same folders) and the path-level WGSL of the GPU stages
//! (camera pass, photon pass, store, sort, gather, accumulate) as source strings, composed
//! in dependency order by [`gpu::shaders::compose`]. The rest of [`gpu`] is the host side
//! both GPU backends share: the record layouts those shaders read and write, their codes
//! and the photon batch policy. No backend depends on another backend; both depend on
//! this layer.
//!
//! ## Conventions
//! * World space is right-handed, units are *scene units* (the scene's length unit, called
//!   metres in doc comments for brevity). Directions are unit vectors.
//! * Propagation math is done in `f64` ([`glam::DVec3`]) so that extreme differential
//!   magnitudes (1e-30 … 1e30) neither overflow nor underflow; what is stored for the
//!   gather ([`store::footprint::PackedFootprint`], [`store::progressive_photon::PackedPhoton`]) is `f32`,
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
//! * `alloc`: adds the renderer-facing layer that needs a heap: [`render`] (scene model,
//!   preparation, projection maps, the backend trait, the reference paths, ray casting),
//!   the image accumulator ([`accumulate::image::ImageAccumulator`]) and the per-pixel
//!   selection ([`accumulate::bandwidth::select`]), [`gpu::shaders::compose`] and the GPU
//!   layer's scene tables ([`gpu::scene`], [`gpu::fill`]). Items that need it are marked
//!   in the docs.
//! * `std` (default): implies `alloc`; adds what needs the standard library (stage
//!   timing in [`render::tracer::StageClock::run`]).
//!
//! ## A first photon
//! One photon of a point light one metre above the floor `z = 0`, its footprint where it
//! lands, and the irradiance the footprint gives at its centre (every stage has a longer
//! example in its module):
//!
//! ```
//! use arpa_core::propagate::differential::NormalDifferential;
//! use arpa_core::emit::emission::{EmissionParams, Light, PointLight};
//! use arpa_core::store::footprint::{Footprint, PhotonMap};
//! use arpa_core::glam::DVec3;
//! use arpa_core::gather::kernel::Kernel;
//! use arpa_core::base::rng::{Rng, StreamDomain};
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

pub mod base;

pub mod emit;
pub mod propagate;
pub mod store;
pub mod gather;
pub mod accumulate;

#[cfg(feature = "alloc")]
#[cfg_attr(docsrs, doc(cfg(feature = "alloc")))]
pub mod render;

pub mod gpu;

pub use glam;
pub use libm;
