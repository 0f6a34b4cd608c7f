//! The embedded default scene: a Cornell box with a glass sphere and a mirror block, lit by
//! a small area light under the ceiling. `arpa render` renders it when no scene file is
//! given.
//!
//! ## Layout and units
//! Scene units (called metres): the box is the cube `[-1, 1]³`, **y up**, open towards `+z`
//! where the camera stands. Every wall's geometric normal points into the box.
//!
//! | item | where | material |
//! |---|---|---|
//! | floor `y = -1`, ceiling `y = 1`, back wall `z = -1` | full faces of the cube | white Lambertian, albedo 0.75 |
//! | left wall `x = -1` | | red Lambertian, albedo (0.6, 0.06, 0.05) |
//! | right wall `x = 1` | | green Lambertian, albedo (0.1, 0.6, 0.08) |
//! | glass sphere | centre [`SPHERE_CENTRE`], radius [`SPHERE_RADIUS`], standing on the floor, front right | smooth dielectric, IOR 1.5, UV sphere of 1984 triangles with per-vertex normals, outward winding |
//! | mirror block | `0.5 × 1.2 × 0.5` box on the floor, back left, turned 40° about y | perfect mirror (conductor, roughness 0, reflectance 0.95) |
//! | light | `0.5 × 0.5` quad at `y = 0.98`, centred at [`LIGHT_CENTRE`], facing down | emissive mesh, radiance [`LIGHT_RADIANCE`] |
//! | camera | `(0, 0, 3.4)` looking at the origin, 45° vertical field of view, 512 × 512 | |
//!
//! The light sits slightly behind the box centre and the sphere slightly in front of it,
//! so light refracted by the sphere focuses on the floor just in front of the sphere's
//! contact point, inside its shadow: a caustic the camera sees.

use arpa_core::emit::emission::Light;
use arpa_core::glam::Vec3;
use arpa_core::render::scene::{Camera, Material, MaterialId, Scene, TriangleMesh};

/// Centre of the glass sphere (metres).
pub const SPHERE_CENTRE: Vec3 = Vec3::new(0.4, -1.0 + SPHERE_RADIUS + 1e-3, 0.3);
/// Radius of the glass sphere (metres).
pub const SPHERE_RADIUS: f32 = 0.38;
/// Index of refraction of the glass sphere.
pub const SPHERE_IOR: f32 = 1.5;
/// Stacks (latitude bands) of the UV sphere.
pub const SPHERE_STACKS: u32 = 32;
/// Slices (longitude segments) of the UV sphere.
pub const SPHERE_SLICES: u32 = 32;
/// Centre of the light quad (metres), 2 cm under the ceiling.
pub const LIGHT_CENTRE: Vec3 = Vec3::new(0.0, 0.98, -0.25);
/// Half side of the square light (metres).
pub const LIGHT_HALF_SIZE: f32 = 0.25;
/// Radiance emitted by the light (W/(m²·sr), linear RGB; slightly warm white).
pub const LIGHT_RADIANCE: Vec3 = Vec3::new(24.0, 21.0, 17.0);
/// Camera position (metres).
pub const CAMERA_POSITION: Vec3 = Vec3::new(0.0, 0.0, 3.4);
/// Default image width and height (pixels).
pub const DEFAULT_RESOLUTION: (u32, u32) = (512, 512);

/// Name of the glass sphere mesh.
pub const SPHERE_NAME: &str = "glass sphere";
/// Name of the light mesh.
pub const LIGHT_NAME: &str = "ceiling light";
/// Name of the mirror block mesh.
pub const MIRROR_NAME: &str = "mirror block";

const WHITE: MaterialId = 0;
const RED: MaterialId = 1;
const GREEN: MaterialId = 2;
const GLASS: MaterialId = 3;
const MIRROR: MaterialId = 4;

/// The default scene (see the module docs for its layout).
pub fn default_scene() -> Scene {
    let materials = vec![
        Material::Diffuse { albedo: Vec3::splat(0.75) },
        Material::Diffuse { albedo: Vec3::new(0.6, 0.06, 0.05) },
        Material::Diffuse { albedo: Vec3::new(0.1, 0.6, 0.08) },
        Material::Dielectric { ior: SPHERE_IOR, transmittance: Vec3::ONE, roughness: 0.0 },
        Material::Conductor { reflectance: Vec3::splat(0.95), roughness: 0.0 },
    ];
    let (x, y, z) = (Vec3::X, Vec3::Y, Vec3::Z);
    let mut meshes = vec![
        // quad(centre, u, v): geometric normal along u × v, into the box.
        quad("floor", Vec3::new(0.0, -1.0, 0.0), x, -z, WHITE),
        quad("ceiling", Vec3::new(0.0, 1.0, 0.0), x, z, WHITE),
        quad("back wall", Vec3::new(0.0, 0.0, -1.0), x, y, WHITE),
        quad("left wall", Vec3::new(-1.0, 0.0, 0.0), y, z, RED),
        quad("right wall", Vec3::new(1.0, 0.0, 0.0), z, y, GREEN),
    ];
    meshes.push(uv_sphere(SPHERE_NAME, SPHERE_CENTRE, SPHERE_RADIUS, SPHERE_STACKS, SPHERE_SLICES, GLASS));
    meshes.push(block(MIRROR_NAME, Vec3::new(-0.45, -0.4, -0.45), Vec3::new(0.25, 0.6, 0.25), 40f32.to_radians(), MIRROR));
    // The light: x × z = -y, so it emits downwards.
    let mut light = quad(LIGHT_NAME, LIGHT_CENTRE, x * LIGHT_HALF_SIZE, z * LIGHT_HALF_SIZE, WHITE);
    light.emission = Some(LIGHT_RADIANCE);
    meshes.push(light);

    Scene { textures: Default::default(),
        meshes,
        materials,
        lights: Vec::<Light>::new(),
        camera: Camera {
            position: CAMERA_POSITION,
            target: Vec3::ZERO,
            up: Vec3::Y,
            vertical_fov: 45f32.to_radians(),
            width: DEFAULT_RESOLUTION.0,
            height: DEFAULT_RESOLUTION.1,
        },
        roughness_cutoff: 0.5,
        instancing: None,
    }
}

/// A parallelogram `centre ± u ± v` of two triangles whose geometric normal is along
/// `u × v`.
fn quad(name: &str, centre: Vec3, u: Vec3, v: Vec3, material: MaterialId) -> TriangleMesh {
    TriangleMesh { uvs: None,
        name: name.into(),
        positions: vec![centre - u - v, centre + u - v, centre + u + v, centre - u + v],
        normals: None,
        indices: vec![[0, 1, 2], [0, 2, 3]],
        material,
        emission: None,
    }
}

/// A closed box (without its bottom face, which rests on the floor) of half extents `half`
/// centred at `centre`, turned by `angle` radians about +y; normals point outwards.
fn block(name: &str, centre: Vec3, half: Vec3, angle: f32, material: MaterialId) -> TriangleMesh {
    let (s, c) = angle.sin_cos();
    let rot = |v: Vec3| Vec3::new(c * v.x + s * v.z, v.y, -s * v.x + c * v.z);
    let (x, y, z) = (Vec3::X * half.x, Vec3::Y * half.y, Vec3::Z * half.z);
    // (face centre offset, u, v) with u × v along the outward normal.
    let faces = [(x, y, z), (-x, z, y), (y, z, x), (z, x, y), (-z, y, x)];
    let mut positions = Vec::new();
    let mut indices = Vec::new();
    for (n, u, v) in faces {
        let base = positions.len() as u32;
        for p in [n - u - v, n + u - v, n + u + v, n - u + v] {
            positions.push(centre + rot(p));
        }
        indices.push([base, base + 1, base + 2]);
        indices.push([base, base + 2, base + 3]);
    }
    TriangleMesh { uvs: None, name: name.into(), positions, normals: None, indices, material, emission: None }
}

/// A UV sphere with `stacks` latitude bands and `slices` longitude segments
/// (`2·slices·(stacks − 1)` triangles), unit outward per-vertex normals and outward winding.
fn uv_sphere(name: &str, centre: Vec3, radius: f32, stacks: u32, slices: u32, material: MaterialId) -> TriangleMesh {
    let stacks = stacks.max(2);
    let slices = slices.max(3);
    let mut positions = Vec::new();
    let mut normals = Vec::new();
    // Vertex (i, j): polar angle θ = π i / stacks from +y, azimuth φ = 2π j / slices; the
    // seam column j = slices repeats j = 0 and the poles are repeated per column so each
    // vertex has one clean normal.
    for i in 0..=stacks {
        let theta = std::f32::consts::PI * i as f32 / stacks as f32;
        for j in 0..=slices {
            let phi = std::f32::consts::TAU * (j % slices) as f32 / slices as f32;
            let n = if i == 0 {
                Vec3::Y
            } else if i == stacks {
                -Vec3::Y
            } else {
                Vec3::new(theta.sin() * phi.cos(), theta.cos(), theta.sin() * phi.sin()).normalize()
            };
            positions.push(centre + n * radius);
            normals.push(n);
        }
    }
    let v = |i: u32, j: u32| i * (slices + 1) + j;
    let mut indices = Vec::new();
    for i in 0..stacks {
        for j in 0..slices {
            // Stepping in φ then in θ: (∂p/∂φ) × (∂p/∂θ) points outwards.
            if i != 0 {
                indices.push([v(i, j), v(i, j + 1), v(i + 1, j)]);
            }
            if i != stacks - 1 {
                indices.push([v(i, j + 1), v(i + 1, j + 1), v(i + 1, j)]);
            }
        }
    }
    TriangleMesh { uvs: None, name: name.into(), positions, normals: Some(normals), indices, material, emission: None }
}
