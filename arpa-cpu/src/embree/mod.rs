//! A minimal, safe layer over Embree 4: triangle scenes for rays, box sets for point
//! queries.
//!
//! * [`Device`] wraps an `RTCDevice` (Embree instance + BVH-build thread pool).
//! * [`EmbreeSceneBuilder`] collects triangle meshes
//!   ([`EmbreeSceneBuilder::add_triangle_mesh`]) and box sets
//!   ([`EmbreeSceneBuilder::add_boxes`], Embree user geometry made of [`EmbreeBox`]es) and
//!   commits them into an [`EmbreeScene`].
//! * [`EmbreeScene`] is immutable and `Send + Sync`: [`EmbreeScene::intersect`] (closest
//!   hit, also [`EmbreeScene::intersect8`] / [`EmbreeScene::intersect16`] for packets),
//!   [`EmbreeScene::occluded`] (any hit) and [`EmbreeScene::point_query`] /
//!   [`EmbreeScene::boxes_containing`] (boxes around a point) can be called from many
//!   threads at once.
//!
//! All coordinates are `f32` in one world frame chosen by the caller (the same frame and
//! unit for vertices, boxes, ray origins and query points); ray parameters `t` are in units
//! of the ray direction's length. Errors come back as [`EmbreeError`]; nothing panics
//! across the API, and invalid inputs are rejected before they reach Embree (whose release
//! build does not validate them).
//!
//! # The 4.2-header / 4.4-library trap
//! The raw `embree4-sys` bindings are generated from the Embree 4.2 headers it bundles,
//! but the library linked is Embree **4.4**, whose `RTCHit`, `RTCRayHit`, ray packets and
//! `RTCPointQueryContext` are larger (an `instPrimID` field since 4.3). Passing the 4.2
//! structs to the 4.4 library makes it write past the caller's object. The private `ffi`
//! module mirrors the 4.4 layouts (checked at compile time) and declares the entry points
//! whose 4.2 signatures are unsound against 4.4; every call here goes through those
//! mirrors, and the canary tests (`tests.rs`) check that the library writes nothing past
//! them.
//!
//! # Linking
//! The crate links `libembree4.so` (Embree 4.4, installed by `scripts/install-embree4.sh`
//! into `<workspace>/.deps/embree4`, or found through `EMBREE_DIR`); `build.rs` sets the
//! search path and an rpath for this crate's own tests. [`Device::new`] refuses a library
//! that is not Embree 4.

mod builder;
mod device;
mod error;
mod ffi;
mod geometry;
mod scene;

#[cfg(test)]
mod tests;

pub use builder::{BuildQuality, EmbreeSceneBuilder};
pub use geometry::EmbreeBox;
pub use device::Device;
pub use error::{EmbreeError, Result};
pub use scene::{EmbreeScene, Hit, PacketRay, PointQueryCandidate};
