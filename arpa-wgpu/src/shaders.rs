//! The WGSL modules of the backend: the core's path-level files ([`arpa_core::gpu::shaders`])
//! with this backend's ray-query glue, each composed by [`arpa_core::gpu::shaders::compose`].
//!
//! The glue implements what the core's files leave to the backend: [`SCENE_RAY_QUERY`]
//! casts rays against the scene (`arpa_scene_intersect`, `arpa_scene_occluded`: camera and
//! photon passes), [`GATHER_RAY_QUERY`] traverses the record boxes (`arpa_gather_at`:
//! gather). Both need wgpu's `EXPERIMENTAL_RAY_QUERY` (`enable wgpu_ray_query;`, which
//! `compose` puts first).

use arpa_core::gpu::shaders::{self as core, WgslFile, compose};

/// `arpa_scene_intersect` and `arpa_scene_occluded` on ray queries, with the scene's
/// top-level structure as binding 0 of group 0 ([`crate::scene::GpuScene`]).
pub const SCENE_RAY_QUERY: WgslFile =
    WgslFile { name: "arpa-wgpu/scene_ray_query.wgsl", source: include_str!("shaders/scene_ray_query.wgsl"), deps: &[&core::SCENE] };

/// `arpa_gather_at` on ray queries and the gather's compute entry point `gather_image`, with the maps' top-level structure as binding 7 of
/// group 0 ([`crate::accel`]).
pub const GATHER_RAY_QUERY: WgslFile =
    WgslFile { name: "arpa-wgpu/gather_ray_query.wgsl", source: include_str!("shaders/gather_ray_query.wgsl"), deps: &[&core::GATHER] };

/// The camera pass's compute entry point `arpa_camera_main` (one invocation per pixel).
pub const CAMERA_COMPUTE: WgslFile =
    WgslFile { name: "arpa-wgpu/camera_compute.wgsl", source: include_str!("shaders/camera_compute.wgsl"), deps: &[&core::CAMERA_PASS] };

/// The photon pass's compute entry point `photon_pass` (one invocation per photon of a
/// batch, counters summed per workgroup).
pub const PHOTON_COMPUTE: WgslFile =
    WgslFile { name: "arpa-wgpu/photon_compute.wgsl", source: include_str!("shaders/photon_compute.wgsl"), deps: &[&core::PHOTON_PASS] };

/// The scene (group 0) with ray casting: what a kernel that reads the scene starts with
/// (the scene's bind group is [`crate::scene::GpuScene::bind_group`]).
pub fn scene() -> String {
    compose(&[&SCENE_RAY_QUERY])
}

/// The camera pass (entry point `arpa_camera_main`).
pub fn camera_pass() -> String {
    compose(&[&CAMERA_COMPUTE, &SCENE_RAY_QUERY])
}

/// The photon pass (entry point `photon_pass`).
pub fn photon_pass() -> String {
    compose(&[&PHOTON_COMPUTE, &SCENE_RAY_QUERY])
}

/// The keyed store (entry points `store_keyed`, `photon_keys`, `pad_items`,
/// `compact_footprints`, `compact_photons`).
pub fn store() -> String {
    compose(&[&core::STORE])
}

/// The store's schedule from the device's counters (entry point `store_schedule`).
pub fn schedule() -> String {
    compose(&[&core::SCHEDULE])
}

/// The sort (entry points `sort_local`, `sort_merge`, `sort_global`).
pub fn sort() -> String {
    compose(&[&core::SORT])
}

/// The radix sort's pass (entry points `radix_count`, `radix_scan`, `radix_scatter`).
pub fn radix() -> String {
    compose(&[&core::RADIX])
}

/// The image gather (entry point `gather_image`).
pub fn gather() -> String {
    compose(&[&GATHER_RAY_QUERY])
}

/// The running mean (entry point `accumulate`).
pub fn accumulate() -> String {
    compose(&[&core::ACCUMULATE])
}
