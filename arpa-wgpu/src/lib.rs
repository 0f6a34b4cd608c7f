//! # arpa-wgpu
//!
//! The wgpu backend of ARPA, on Vulkan ray queries (`EXPERIMENTAL_RAY_QUERY`), with
//! lavapipe (Mesa's software Vulkan, ≥ 25) when no GPU is present.
//!
//! [`WgpuTracer`] implements [`arpa_core::tracer::Tracer`] with every stage on the device;
//! the modules it is built from:
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
//! * [`photon`]: the photon pass on the device (one invocation per photon, the twin of
//!   `arpa_core::photon_path::trace_photon`), appending raw footprints and progressive
//!   photons with unique keys, with counters and overflow counting;
//! * [`store`]: footprint store, acceleration-structure build and gather in one device
//!   submission (deterministic slots, inactive boxes for rejected footprints); the
//!   tracer's keyed store on the photon pass's buffers ([`store::MapStore`]: heuristics,
//!   fallback photons, sort keys, compaction);
//! * [`sort`]: the device sort by `(map, Morton code, photon key)` that makes the maps
//!   independent of the append order and spatially ordered for the AABB build;
//! * [`accel`]: the per-iteration AABB acceleration structure over the sorted records;
//! * [`camera`]: the camera pass (query points, emission seen, next-event estimation) on
//!   ray queries, checked per pixel against the core's `trace_camera_path`;
//! * [`gather`]: the gather stage on ray queries (footprint boxes in AABB acceleration
//!   structures, one per map; point queries; the twin's exact test and kernel), checked
//!   against the core's brute-force gather; the tracer's image gather over footprints and
//!   progressive photons ([`gather::ImageGather`]);
//! * [`accumulate`]: the running mean on the device;
//! * [`maps`]: store → sort → build → gather chained on device buffers;
//! * [`tracer`]: [`WgpuTracer`] and [`WgpuError`]; an iteration whose records exceed one
//!   storage binding is traced in photon batches, summed per pixel on the device.

pub mod accel;
pub mod accumulate;
pub mod camera;
pub mod device;
pub mod gather;
pub mod harness;
pub mod maps;
pub mod photon;
pub mod scene;
pub mod sort;
pub mod store;
pub mod tracer;

pub use device::{AdapterChoice, DeviceError, GpuContext};
pub use tracer::{WgpuError, WgpuTracer};
pub use harness::{HarnessError, run_kernel};
