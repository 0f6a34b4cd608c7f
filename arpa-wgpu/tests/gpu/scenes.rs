//! Small test scenes shared by the scene-data and camera-pass tests.
#![allow(dead_code)]

use arpa_core::emit::emission::{DirectionalLight, Light, PointLight, QuadLight, SpotFalloff, SpotLight};
use arpa_core::render::scene::{Camera, Material, Scene, TriangleMesh};
use arpa_core::render::shapes::{icosphere, parallelogram};
use glam::{DVec3, Vec3};

/// A closed 2 m box (diffuse walls of three albedos) holding every kind of surface: a smooth
/// glass icosphere (vertex normals), a smooth diffuse icosphere (vertex normals against its inward winding), a
/// flat mirror panel, a smooth mirror icosphere, a rough conductor (diffuse by the
/// roughness cut-off), a rough dielectric (diffuse too), a flat icosphere whose vertex
/// normals equal its face normals on some triangles only (flat-shaded detection), a panel
/// on the back wall whose vertex normals lean ~80° sideways (the camera sees it from below
/// its shading plane: flipped query normals and shading frames), an
/// emissive ceiling quad facing down and a smaller emissive wall quad, a point light, a spot
/// light, a directional light (shadowed by the box: it must contribute nothing on both
/// sides) and an analytic quad light facing down.
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
        tilted_panel(),
        light,
        small_light,
    ];
    Scene { textures: Default::default(),
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
            Light::Quad(QuadLight {
                origin: DVec3::new(-0.6, 1.9, 0.2),
                edge_u: DVec3::new(0.4, 0.0, 0.0),
                edge_v: DVec3::new(0.0, 0.0, 0.3),
                radiance: DVec3::new(2.0, 1.5, 1.0),
            }),
        ],
        camera: Camera { position: Vec3::new(0.0, 1.0, 0.95), target: Vec3::new(0.0, 0.7, 0.0), up: Vec3::Y, vertical_fov: 1.4, width, height },
        roughness_cutoff: 0.5,
        instancing: None,
    }
}

/// A diffuse panel just in front of the back wall (geometric normal +z, towards the
/// camera) with vertex normals leaning 75°–85° towards −x.
fn tilted_panel() -> TriangleMesh {
    let mut m = parallelogram("tilted panel", Vec3::new(-0.9, 0.9, -0.99), Vec3::new(0.6, 0.0, 0.0), Vec3::new(0.0, 0.6, 0.0), 0);
    let lean = |deg: f32| Vec3::new(-deg.to_radians().sin(), 0.0, deg.to_radians().cos());
    m.normals = Some(vec![lean(75.0), lean(85.0), lean(80.0), lean(78.0)]);
    m
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
    TriangleMesh { uvs: None, name: "facetted".into(), positions, normals: Some(normals), indices, material: 0, emission: None }
}

pub use arpa_core::render::shapes::cuboid;

fn camera(position: Vec3, target: Vec3, fov_degrees: f32, width: u32, height: u32) -> Camera {
    Camera { position, target, up: Vec3::Y, vertical_fov: fov_degrees.to_radians(), width, height }
}

/// Like the conformance suite's glass slab: a diffuse floor seen only through a clear glass
/// slab (IOR 1.5, parallel faces) under a point light.
pub fn glass_slab(size: u32) -> Scene {
    let floor = parallelogram("floor", Vec3::new(-6.0, 0.0, -6.0), Vec3::new(0.0, 0.0, 12.0), Vec3::new(12.0, 0.0, 0.0), 0);
    let slab = cuboid("glass slab", Vec3::new(-4.0, 0.5, -4.0), Vec3::new(4.0, 1.5, 4.0), 1);
    Scene { textures: Default::default(),
        meshes: vec![floor, slab],
        materials: vec![Material::Diffuse { albedo: Vec3::splat(0.6) }, Material::Dielectric { ior: 1.5, transmittance: Vec3::ONE, roughness: 0.0 }],
        lights: vec![Light::Point(PointLight { position: DVec3::new(0.3, 3.0, 0.2), intensity: DVec3::splat(10.0) })],
        camera: camera(Vec3::new(0.0, 6.0, 2.5), Vec3::ZERO, 24.0, size, size),
        roughness_cutoff: 0.5,
        instancing: None,
    }
}

/// Like the conformance suite's mirror wall: a diffuse floor ending at a vertical mirror,
/// a point light in front of it; rays above and beside the mirror leave the scene.
pub fn mirror_wall(size: u32) -> Scene {
    let floor = parallelogram("floor", Vec3::new(-3.0, 0.0, -3.0), Vec3::new(0.0, 0.0, 6.0), Vec3::new(4.0, 0.0, 0.0), 0);
    let mirror = parallelogram("mirror", Vec3::new(1.0, 0.0, -0.5), Vec3::new(0.0, 1.2, 0.0), Vec3::new(0.0, 0.0, 1.0), 1);
    Scene { textures: Default::default(),
        meshes: vec![floor, mirror],
        materials: vec![Material::Diffuse { albedo: Vec3::splat(0.5) }, Material::Conductor { reflectance: Vec3::splat(0.9), roughness: 0.0 }],
        lights: vec![Light::Point(PointLight { position: DVec3::new(-0.3, 0.6, 0.0), intensity: DVec3::splat(2.0) })],
        camera: camera(Vec3::new(-2.0, 2.2, 0.0), Vec3::new(0.6, 0.2, 0.0), 50.0, size, size),
        roughness_cutoff: 0.5,
        instancing: None,
    }
}

/// Like the embedded default scene: a Cornell box (coloured side walls) lit only by an
/// emissive ceiling quad, with a smooth glass icosphere and a mirror block.
pub fn cornell(size: u32) -> Scene {
    let (x, y, z) = (Vec3::X, Vec3::Y, Vec3::Z);
    let quad = |name: &str, c: Vec3, u: Vec3, v: Vec3, m: u32| parallelogram(name, c - u - v, 2.0 * u, 2.0 * v, m);
    let mut light = quad("light", Vec3::new(0.0, 0.99, 0.0), x * 0.25, z * 0.25, 0);
    light.emission = Some(Vec3::splat(12.0));
    Scene { textures: Default::default(),
        meshes: vec![
            quad("floor", Vec3::new(0.0, -1.0, 0.0), x, -z, 0),
            quad("ceiling", Vec3::new(0.0, 1.0, 0.0), x, z, 0),
            quad("back wall", Vec3::new(0.0, 0.0, -1.0), x, y, 0),
            quad("left wall", Vec3::new(-1.0, 0.0, 0.0), y, z, 1),
            quad("right wall", Vec3::new(1.0, 0.0, 0.0), z, y, 2),
            icosphere("glass sphere", Vec3::new(0.4, -0.6, 0.2), 0.4, 3, true, 3),
            cuboid("mirror block", Vec3::new(-0.7, -1.0, -0.7), Vec3::new(-0.2, 0.2, -0.2), 4),
            light,
        ],
        materials: vec![
            Material::Diffuse { albedo: Vec3::splat(0.75) },
            Material::Diffuse { albedo: Vec3::new(0.6, 0.06, 0.05) },
            Material::Diffuse { albedo: Vec3::new(0.1, 0.6, 0.08) },
            Material::Dielectric { ior: 1.5, transmittance: Vec3::ONE, roughness: 0.0 },
            Material::Conductor { reflectance: Vec3::splat(0.95), roughness: 0.0 },
        ],
        lights: vec![],
        camera: camera(Vec3::new(0.0, 0.0, 3.4), Vec3::ZERO, 45.0, size, size),
        roughness_cutoff: 0.5,
        instancing: None,
    }
}

/// Like the shared water-caustic scene: a diffuse pool floor under a single wavy water
/// surface (a flat grid with tilted vertex normals, IOR 1.33, one interface: camera paths
/// end under water and carry the radiance-mode factor `(1/1.33)²`), walls, a point light
/// and an area light above.
pub fn water(size: u32) -> Scene {
    let n = 8;
    let (lo, side, height) = (-1.0f32, 2.0f32, 0.6f32);
    let mut positions = Vec::new();
    let mut normals = Vec::new();
    let mut indices = Vec::new();
    for j in 0..=n {
        for i in 0..=n {
            let (x, z) = (lo + side * i as f32 / n as f32, lo + side * j as f32 / n as f32);
            positions.push(Vec3::new(x, height, z));
            normals.push(Vec3::new(0.25 * (3.0 * x).sin(), 1.0, 0.2 * (4.0 * z + 1.0).cos()).normalize());
        }
    }
    for j in 0..n {
        for i in 0..n {
            let k = j * (n + 1) + i;
            // Winding with the geometric normal up (+y): the water is below.
            indices.push([k, k + n + 1, k + 1]);
            indices.push([k + 1, k + n + 1, k + n + 2]);
        }
    }
    let surface = TriangleMesh { uvs: None, name: "water".into(), positions, normals: Some(normals), indices, material: 1, emission: None };
    let mut light = parallelogram("light", Vec3::new(-0.4, 2.5, -0.4), Vec3::new(0.8, 0.0, 0.0), Vec3::new(0.0, 0.0, 0.8), 0);
    light.emission = Some(Vec3::splat(4.0));
    Scene { textures: Default::default(),
        meshes: vec![
            parallelogram("pool floor", Vec3::new(-1.0, 0.0, -1.0), Vec3::new(0.0, 0.0, 2.0), Vec3::new(2.0, 0.0, 0.0), 0),
            parallelogram("pool wall", Vec3::new(-1.0, 0.0, -1.0), Vec3::new(2.0, 0.0, 0.0), Vec3::new(0.0, 1.0, 0.0), 2),
            surface,
            light,
        ],
        materials: vec![
            Material::Diffuse { albedo: Vec3::splat(0.8) },
            Material::Dielectric { ior: 1.33, transmittance: Vec3::new(0.9, 0.95, 1.0), roughness: 0.0 },
            Material::Diffuse { albedo: Vec3::new(0.3, 0.6, 0.9) },
        ],
        lights: vec![Light::Point(PointLight { position: DVec3::new(0.4, 2.0, 0.3), intensity: DVec3::splat(3.0) })],
        camera: camera(Vec3::new(0.3, 2.2, 1.8), Vec3::new(0.0, 0.2, 0.0), 50.0, size, size),
        roughness_cutoff: 0.5,
        instancing: None,
    }
}
