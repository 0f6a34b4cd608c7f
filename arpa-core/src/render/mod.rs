//! The renderer layer (`alloc`): what a renderer drives the per-photon stages with.
//!
//! | module | what |
//! |---|---|
//! | [`scene`], [`shapes`], [`texture`] | the scene model (meshes, materials, textures, lights, camera) and shape builders |
//! | [`prepared_scene`] | a scene prepared for tracing: triangle tables, emitters, shading, projection maps |
//! | [`environment`] | the environment light's radiance and direction sampling (constant or equirectangular map) |
//! | [`projection`] | projection maps: which parts of each light's domain reach which targets |
//! | [`emission_plan`] | one render's photon allocation and pass skips from the projection maps |
//! | [`tracer`] | the backend trait, render settings, stage clock, statistics |
//! | [`ray_cast`], [`brute_force`] | the one geometric query the paths need, its ray-start rule, and an `f64` reference caster |
//! | [`photon_path`], [`camera_path`] | the reference photon and camera paths every backend reproduces |

pub mod brute_force;
pub mod camera_path;
pub mod emission_plan;
pub mod environment;
pub mod photon_path;
pub mod prepared_scene;
pub mod projection;
pub mod ray_cast;
pub mod scene;
pub mod shapes;
pub mod texture;
pub mod tracer;
