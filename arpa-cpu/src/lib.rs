//! `arpa-cpu`: ARPA's CPU backend, [`CpuTracer`], on Embree 4 and rayon, over a minimal,
//! safe Embree layer.
//!
//! [`CpuTracer`] implements [`arpa_core::render::tracer::Tracer`]: the whole photon-mapping
//! iteration on Embree (rays through [`EmbreeCaster`], footprint and photon boxes through
//! point queries) and rayon, deterministic for any thread count. The modules follow the
//! pipeline:
//!
//! | module | stage |
//! |---|---|
//! | `tracer` | [`CpuTracer`] and [`CpuError`]: the uploaded state, the stage bookkeeping (the core's `StageClock`), `upload_scene` and `accumulate` |
//! | `caster` | [`EmbreeCaster`]: the core's `RayCaster` on the scene's triangle BVH (shared groups as Embree instances; built at upload; used by the camera and photon passes) |
//! | `camera` | camera pass: one camera path per pixel to its query point |
//! | `photons` | photon pass: photons in chunks of [`PHOTON_CHUNK`], two in flight per thread, merged in photon order |
//! | `photon_store` | the photon pass's buffers: footprints with their boxes, progressive photons, counts |
//! | `accel` | acceleration-structure build: the Embree box BVH over footprints and photons |
//! | `gather` | gather: point queries, then the core's estimator in `(kind, index)` order |
//!
//! The Embree layer (`embree`, re-exported here) is independent of the pipeline:
//!
//! * [`Device`] wraps an `RTCDevice` (Embree instance + BVH-build thread pool).
//! * [`EmbreeSceneBuilder`] collects triangle meshes
//!   ([`EmbreeSceneBuilder::add_triangle_mesh`]) and box sets
//!   ([`EmbreeSceneBuilder::add_boxes`] of [`EmbreeBox`]es, Embree user geometry) and
//!   commits them into an [`EmbreeScene`].
//! * [`EmbreeScene`] is immutable and `Send + Sync`: [`EmbreeScene::intersect`] (closest
//!   hit), [`EmbreeScene::occluded`] (any hit) and [`EmbreeScene::point_query`] /
//!   [`EmbreeScene::boxes_containing`] (boxes around a point) can be called from many
//!   threads at once.
//!
//! All coordinates are `f32` in one world frame chosen by the caller (the same frame and
//! unit for vertices, boxes, ray origins and query points); ray parameters `t` are in units
//! of the ray direction's length. Errors come back as [`EmbreeError`]; nothing panics
//! across the API, and invalid inputs are rejected before they reach Embree (whose release
//! build does not validate them).
//!
//! # Linking
//! The crate links `libembree4.so` (Embree **4.4**, installed by
//! `scripts/install-embree4.sh` into `<workspace>/.deps/embree4`, or found through
//! `EMBREE_DIR`); `build.rs` sets the search path and an rpath for this crate's own tests.
//! The raw `embree4-sys` bindings are generated from Embree 4.2 headers; the structs whose
//! layout changed by 4.4 are mirrored in the private `embree::ffi` module (see the
//! `embree` module's docs).

#![warn(missing_docs)]

mod accel;
mod camera;
mod caster;
mod embree;
mod error;
mod gather;
mod photon_store;
mod photons;
mod tracer;

pub use caster::EmbreeCaster;
pub use embree::{
    BuildQuality, Device, EmbreeBox, EmbreeError, EmbreeScene, EmbreeSceneBuilder, Hit,
    PacketRay, PointQueryCandidate, Result,
};
pub use photons::PHOTON_CHUNK;
pub use error::CpuError;
pub use tracer::CpuTracer;
