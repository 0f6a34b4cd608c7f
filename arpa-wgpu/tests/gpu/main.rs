//! arpa-wgpu's integration tests, in one test binary (each binary links wgpu and naga;
//! one binary instead of ten saves most of the link time). The GPU tests run on the
//! adapter `common::gpu` picks (lavapipe in CI) and skip loudly without one outside CI.

mod common;
mod support;

mod aabb_twin;
mod camera_pass;

mod gather;
mod maps;
mod naga_validate;
mod photon_pass;
mod ray_cast;
mod ray_query;
mod scene_order;
mod scene_surface;
mod scenes;
mod sort;
mod store;
mod tracer;
