//! # arpa-wgpu
//!
//! The wgpu backend of ARPA, on Vulkan ray queries (`EXPERIMENTAL_RAY_QUERY`), with
//! lavapipe (Mesa's software Vulkan, ≥ 25) when no GPU is present.
//!
//! This first slice holds the foundation the tracer is built on:
//! * [`device`]: adapter choice (a real GPU with ray queries, else lavapipe, or a name
//!   forced by the caller) and device creation, with an error naming the adapter when ray
//!   queries are missing;
//! * [`harness`]: a compute harness that runs WGSL functions (the core's WGSL twin,
//!   [`arpa_core::shaders`]) over input buffers and reads the results back; the
//!   conformance suite's WGSL-twin cases (`arpa-conformance`, feature `wgpu`) compare the
//!   twin with the Rust core through it;
//! * [`scene`]: scene upload (a triangle BLAS per mesh, one TLAS) and closest-hit ray
//!   casting on ray queries, checked against the core's brute-force caster; the prepared
//!   scene (materials, normals, emitters) as bind group 0 of every pass with its WGSL
//!   ([`scene::SCENE_WGSL`]), checked against `PreparedScene`;
//! * [`store`]: footprint store, acceleration-structure build and gather in one device
//!   submission (deterministic slots, inactive boxes for rejected footprints);
//! * [`gather`]: the gather stage on ray queries (footprint boxes in AABB acceleration
//!   structures, one per map; point queries; the twin's exact test and kernel), checked
//!   against the core's brute-force gather.
//!
//! The `Tracer` (scene upload, photon pass, footprint AS, gather) is not implemented yet.

pub mod device;
pub mod gather;
pub mod harness;
pub mod scene;
pub mod store;

pub use device::{AdapterChoice, DeviceError, GpuContext};
pub use harness::{HarnessError, run_kernel};
