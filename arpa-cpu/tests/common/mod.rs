//! Scenes and helpers shared by the CPU backend's integration tests.
#![allow(dead_code)]


use arpa_core::emit::emission::{Light, PointLight};
use arpa_core::glam::{DVec3, Vec3};
use arpa_core::render::scene::{Camera, Material, Scene, TriangleMesh};
use arpa_core::render::tracer::{QueryRecord, Tracer};
use arpa_cpu::CpuTracer;

/// A diffuse triangle mesh using material `material`.
pub fn mesh(
    name: &str,
    positions: Vec<Vec3>,
    indices: Vec<[u32; 3]>,
    material: u32,
) -> TriangleMesh {
    TriangleMesh { uvs: None,
        name: name.into(),
        positions,
        normals: None,
        indices,
        material,
        emission: None,
    }
}

pub use arpa_core::render::shapes::parallelogram as quad;

/// An icosphere of radius `radius` around `centre` with flat facets
/// ([`arpa_core::render::shapes::icosphere`]).
pub fn icosphere(centre: Vec3, radius: f32, subdivisions: u32, material: u32) -> TriangleMesh {
    arpa_core::render::shapes::icosphere("icosphere", centre, radius, subdivisions, false, material)
}


pub fn point_light(position: DVec3, intensity: f64) -> Light {
    Light::Point(PointLight {
        position,
        intensity: DVec3::splat(intensity),
    })
}

pub fn camera(position: Vec3, target: Vec3, up: Vec3, vertical_fov: f32, size: u32) -> Camera {
    Camera {
        position,
        target,
        up,
        vertical_fov,
        width: size,
        height: size,
    }
}

pub fn diffuse(albedo: f32) -> Material {
    Material::Diffuse {
        albedo: Vec3::splat(albedo),
    }
}

pub fn scene(
    meshes: Vec<TriangleMesh>,
    materials: Vec<Material>,
    lights: Vec<Light>,
    camera: Camera,
) -> Scene {
    Scene { textures: Default::default(),
        meshes,
        materials,
        lights,
        camera,
        roughness_cutoff: 0.5,
        instancing: None,
    }
}

/// Runs `iterations` iterations and, after each, calls `per_iteration` with that
/// iteration's query records (to accumulate analytic expectations at the very points the
/// image was estimated at).
pub fn render(
    tracer: &mut CpuTracer,
    iterations: u32,
    mut per_iteration: impl FnMut(&[QueryRecord]),
) {
    for _ in 0..iterations {
        tracer.iterate().expect("iteration");
        per_iteration(&tracer.read_query_points().expect("query points"));
    }
}

/// Relative error in percent.
pub fn percent(estimate: f64, expected: f64) -> f64 {
    (estimate / expected - 1.0) * 100.0
}
