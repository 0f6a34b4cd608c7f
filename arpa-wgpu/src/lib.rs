//! # arpa-wgpu
//!
//! The wgpu backend of ARPA, on Vulkan ray queries (`EXPERIMENTAL_RAY_QUERY`), with
//! lavapipe (Mesa's software Vulkan, ≥ 25) when no GPU is present.
//!
//! [`WgpuTracer`] implements [`arpa_core::render::tracer::Tracer`] with every stage on the device.
//! What is not wgpu-specific lives in the core's GPU layer, shared with the other GPU
//! backend: the record layouts, codes, Morton codes, sort schedule and photon-batch policy
//! ([`arpa_core::gpu`]) and the path-level WGSL ([`arpa_core::gpu::shaders`]). This crate holds
//! the wgpu API calls and the ray-query glue:
//! * [`device`]: adapter choice (a real GPU with ray queries, else lavapipe, or a name
//!   forced by the caller) and device creation, with an error naming the adapter when ray
//!   queries are missing;
//! * [`shaders`]: the WGSL modules, the core's files composed with this backend's
//!   ray-query glue (scene ray casting, gather box traversal);
//! * [`harness`]: a compute harness that runs WGSL functions over input buffers and reads
//!   the results back (the conformance suite's WGSL-twin cases run the core's twin through
//!   it);
//! * [`scene`]: scene upload, a triangle BLAS per mesh and one TLAS, and the core's scene
//!   tables ([`arpa_core::gpu::scene::SceneTables`]) as bind group 0 of the camera and
//!   photon passes;
//! * [`camera`]: the camera pass, one query record per pixel;
//! * [`photon`]: the photon pass, one invocation per photon of a batch, appending keyed
//!   footprints and progressive photons, with counters and overflow counting;
//! * [`store`]: the keyed store on the photon pass's buffers (heuristics, fallback photons,
//!   sort keys, compaction into sorted maps with their boxes);
//! * [`sort`]: the device sort by `(map, Morton code, photon key)` that makes the maps
//!   independent of the append order and spatially ordered for the AABB build;
//! * [`accel`]: the AABB acceleration structure over a batch's sorted records;
//! * [`gather`]: the image gather over a batch's maps on ray queries;
//! * [`accumulate`]: the running mean on the device;
//! * [`maps`]: the photon batches of an iteration on the device (store → sort → keep, build,
//!   gather);
//! * [`tracer`]: [`WgpuTracer`] and [`WgpuError`].

pub mod accel;
pub mod accumulate;
pub mod camera;
pub mod device;
pub mod error;
pub mod gather;
pub mod harness;
pub mod maps;
pub mod photon;
pub mod scene;
pub mod shaders;
pub mod sort;
pub mod store;
pub mod timing;
pub mod tracer;

pub use device::{AdapterChoice, DeviceError, GpuContext};
pub use harness::{HarnessError, run_kernel};
pub use error::WgpuError;
pub use tracer::WgpuTracer;
