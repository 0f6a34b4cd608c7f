//! Small test scenes shared by the scene-data and camera-pass tests.
#![allow(dead_code)]

use arpa_core::emission::{DirectionalLight, Light, PointLight, SpotFalloff, SpotLight};
use arpa_core::scene::{Camera, Material, Scene, TriangleMesh};
use arpa_core::shapes::{icosphere, parallelogram};
use glam::{DVec3, Vec3};

/// A closed 2 m box (diffuse walls of three albedos) holding every kind of surface: a smooth
/// glass icosphere (vertex normals), a smooth diffuse icosphere (vertex normals against its inward winding), a
/// flat mirror panel, a smooth mirror icosphere, a rough conductor (diffuse by the
/// roughness cut-off), a rough dielectric (diffuse too), a flat icosphere whose vertex
/// normals equal its face normals on some triangles only (flat-shaded detection), an
/// emissive ceiling quad facing down, a point light, a spot light and a directional light
/// (shadowed by the box: it must contribute nothing on both sides).
pub fn mixed_scene(width: u32, height: u32) -> Scene {
    let s = 1.0;
    let mut light = parallelogram("light", Vec3::new(-0.3, 1.98, -0.3), Vec3::new(0.6, 0.0, 0.0), Vec3::new(0.0, 0.0, 0.6), 0);
    light.emission = Some(Vec3::new(6.0, 5.0, 4.0));
    let mut small_light = parallelogram("small light", Vec3::new(0.98, 1.2, -0.5), Vec3::new(0.0, 0.0, 0.3), Vec3::new(0.0, 0.3, 0.0), 0);
    small_light.emission = Some(Vec3::new(1.0, 2.0, 3.0));
    let meshes: Vec<TriangleMesh> = vec![
        parallelogram("floor", Vec3::new(-s, 0.0, -s), Vec3::new(0.0, 0.0, 2.0 * s), Vec3::new(2.0 * s, 0.0, 0.0), 0),
        parallelogram("ceiling", Vec3::new(-s, 2.0, -s), Vec3::new(2.0 * s, 0.0, 0.0), Vec3::new(0.0, 0.0, 2.0 * s), 0),
        parallelogram("back", Vec3::new(-s, 0.0, -s), Vec3::new(2.0 * s, 0.0, 0.0), Vec3::new(0.0, 2.0, 0.0), 1),
        parallelogram("front", Vec3::new(-s, 0.0, s), Vec3::new(0.0, 2.0, 0.0), Vec3::new(2.0 * s, 0.0, 0.0), 0),
        parallelogram("left", Vec3::new(-s, 0.0, -s), Vec3::new(0.0, 2.0, 0.0), Vec3::new(0.0, 0.0, 2.0 * s), 2),
        parallelogram("right", Vec3::new(s, 0.0, -s), Vec3::new(0.0, 0.0, 2.0 * s), Vec3::new(0.0, 2.0, 0.0), 0),
        icosphere("glass", Vec3::new(0.35, 0.45, 0.1), 0.3, 2, true, 3),
        inward_wound(icosphere("diffuse ball", Vec3::new(-0.45, 0.3, -0.3), 0.28, 1, true, 0)),
        parallelogram("mirror", Vec3::new(-0.9, 0.2, 0.5), Vec3::new(0.5, 0.0, -0.3), Vec3::new(0.05, 0.9, 0.0), 4),
        icosphere("mirror ball", Vec3::new(0.5, 1.3, -0.5), 0.2, 2, true, 4),
        parallelogram("rough metal", Vec3::new(0.2, 0.01, -0.8), Vec3::new(0.5, 0.0, 0.0), Vec3::new(0.0, 0.0, 0.4), 5),
        icosphere("frosted", Vec3::new(-0.5, 1.3, 0.4), 0.15, 1, false, 6),
        facetted_ball(),
        light,
        small_light,
    ];
    Scene {
        meshes,
        materials: vec![
            Material::Diffuse { albedo: Vec3::splat(0.7) },
            Material::Diffuse { albedo: Vec3::new(0.2, 0.5, 0.8) },
            Material::Diffuse { albedo: Vec3::new(0.8, 0.3, 0.1) },
            Material::Dielectric { ior: 1.5, transmittance: Vec3::new(0.95, 0.97, 1.0), roughness: 0.0 },
            Material::Conductor { reflectance: Vec3::new(0.9, 0.85, 0.8), roughness: 0.0 },
            Material::Conductor { reflectance: Vec3::new(0.5, 0.6, 0.7), roughness: 0.8 },
            Material::Dielectric { ior: 1.3, transmittance: Vec3::new(0.6, 0.7, 0.8), roughness: 0.9 },
        ],
        lights: vec![
            Light::Point(PointLight { position: DVec3::new(-0.2, 1.6, 0.3), intensity: DVec3::new(0.8, 0.7, 0.6) }),
            Light::Spot(SpotLight {
                position: DVec3::new(0.6, 1.8, 0.6),
                direction: DVec3::new(-0.4, -1.0, -0.3).normalize(),
                intensity: DVec3::new(2.0, 2.0, 1.5),
                cutoff: 0.6,
                beam_width: 0.3,
                falloff: SpotFalloff::SmoothstepAngle,
            }),
            Light::Directional(DirectionalLight { direction: DVec3::new(0.3, -1.0, 0.2).normalize(), irradiance: DVec3::splat(1.0) }),
        ],
        camera: Camera { position: Vec3::new(0.0, 1.0, 0.95), target: Vec3::new(0.0, 0.7, 0.0), up: Vec3::Y, vertical_fov: 1.4, width, height },
        roughness_cutoff: 0.5,
    }
}

/// `m` with its winding reversed: geometric normals inwards, vertex normals still outwards
/// (the shading normal must be flipped to the geometric side).
fn inward_wound(mut m: TriangleMesh) -> TriangleMesh {
    for t in &mut m.indices {
        t.swap(1, 2);
    }
    m
}

/// A diffuse icosphere with vertex normals = face normals on the upper half of its
/// triangles (unshared vertices) and tilted ones below.
fn facetted_ball() -> TriangleMesh {
    let base = icosphere("facetted", Vec3::new(0.6, 0.25, 0.6), 0.2, 1, false, 0);
    let mut positions = Vec::new();
    let mut normals = Vec::new();
    let mut indices = Vec::new();
    let centre = Vec3::new(0.6, 0.25, 0.6);
    for t in &base.indices {
        let p = t.map(|i| base.positions[i as usize]);
        let face = (p[1] - p[0]).cross(p[2] - p[0]).normalize();
        let k = positions.len() as u32;
        for q in p {
            positions.push(q);
            normals.push(if q.y > centre.y { face } else { (q - centre).normalize() });
        }
        indices.push([k, k + 1, k + 2]);
    }
    TriangleMesh { name: "facetted".into(), positions, normals: Some(normals), indices, material: 0, emission: None }
}
