//! Scenes and helpers shared by the CPU backend's integration tests.
#![allow(dead_code)]

use std::collections::HashMap;

use arpa_core::emission::{Light, PointLight};
use arpa_core::glam::{DVec3, Vec3};
use arpa_core::scene::{Camera, Material, Scene, TriangleMesh};
use arpa_core::tracer::{QueryRecord, Tracer};
use arpa_cpu::CpuTracer;

/// A diffuse triangle mesh using material `material`.
pub fn mesh(
    name: &str,
    positions: Vec<Vec3>,
    indices: Vec<[u32; 3]>,
    material: u32,
) -> TriangleMesh {
    TriangleMesh {
        name: name.into(),
        positions,
        normals: None,
        indices,
        material,
        emission: None,
    }
}

/// The parallelogram `origin + s·u + t·v`, `s, t ∈ [0, 1]`, as two triangles with normal
/// `u × v`.
pub fn quad(name: &str, origin: Vec3, u: Vec3, v: Vec3, material: u32) -> TriangleMesh {
    mesh(
        name,
        vec![origin, origin + u, origin + u + v, origin + v],
        vec![[0, 1, 2], [0, 2, 3]],
        material,
    )
}

/// An icosphere of radius `radius` around `centre`: the icosahedron subdivided
/// `subdivisions` times (20·4^k triangles), vertices on the sphere, normals outwards.
pub fn icosphere(centre: Vec3, radius: f32, subdivisions: u32, material: u32) -> TriangleMesh {
    let t = (1.0 + 5f64.sqrt()) / 2.0;
    let mut v: Vec<DVec3> = [
        (-1.0, t, 0.0),
        (1.0, t, 0.0),
        (-1.0, -t, 0.0),
        (1.0, -t, 0.0),
        (0.0, -1.0, t),
        (0.0, 1.0, t),
        (0.0, -1.0, -t),
        (0.0, 1.0, -t),
        (t, 0.0, -1.0),
        (t, 0.0, 1.0),
        (-t, 0.0, -1.0),
        (-t, 0.0, 1.0),
    ]
    .iter()
    .map(|&(x, y, z)| DVec3::new(x, y, z).normalize())
    .collect();
    let mut f: Vec<[u32; 3]> = vec![
        [0, 11, 5],
        [0, 5, 1],
        [0, 1, 7],
        [0, 7, 10],
        [0, 10, 11],
        [1, 5, 9],
        [5, 11, 4],
        [11, 10, 2],
        [10, 7, 6],
        [7, 1, 8],
        [3, 9, 4],
        [3, 4, 2],
        [3, 2, 6],
        [3, 6, 8],
        [3, 8, 9],
        [4, 9, 5],
        [2, 4, 11],
        [6, 2, 10],
        [8, 6, 7],
        [9, 8, 1],
    ];
    for _ in 0..subdivisions {
        let mut mid: HashMap<(u32, u32), u32> = HashMap::new();
        let mut midpoint = |a: u32, b: u32, v: &mut Vec<DVec3>| {
            let key = (a.min(b), a.max(b));
            *mid.entry(key).or_insert_with(|| {
                v.push((v[a as usize] + v[b as usize]).normalize());
                (v.len() - 1) as u32
            })
        };
        let mut next = Vec::with_capacity(f.len() * 4);
        for [a, b, c] in f {
            let ab = midpoint(a, b, &mut v);
            let bc = midpoint(b, c, &mut v);
            let ca = midpoint(c, a, &mut v);
            next.extend([[a, ab, ca], [b, bc, ab], [c, ca, bc], [ab, bc, ca]]);
        }
        f = next;
    }
    let positions = v
        .iter()
        .map(|p| centre + (*p * radius as f64).as_vec3())
        .collect();
    mesh("icosphere", positions, f, material)
}

/// Total area of a mesh (m²), in `f64`.
pub fn mesh_area(m: &TriangleMesh) -> f64 {
    m.indices
        .iter()
        .map(|t| {
            let p = t.map(|i| m.positions[i as usize].as_dvec3());
            0.5 * (p[1] - p[0]).cross(p[2] - p[0]).length()
        })
        .sum()
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
    Scene {
        meshes,
        materials,
        lights,
        camera,
        roughness_cutoff: 0.5,
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
