//! Procedural meshes shared by the default scene, the scene loader (Mitsuba's `sphere`),
//! tests, benchmarks and the conformance suite.

use crate::render::scene::{MaterialId, TriangleMesh};
use alloc::collections::BTreeMap;
use alloc::string::String;
use alloc::vec;
use alloc::vec::Vec;
use glam::{DVec3, Vec3};

/// Smooth vertex normals of a triangle mesh without stored ones, as Mitsuba 3 computes them
/// for its mesh plugins (`Mesh::recompute_vertex_normals`): at each vertex, the sum over
/// the triangles using it of the unit face normal `(p1 − p0) × (p2 − p0)` weighted by the
/// triangle's angle at that vertex, normalised. Zero-area triangles add nothing; a vertex
/// only they use gets `+x`, as in Mitsuba. Only vertices shared by index are smoothed
/// together, so a mesh that duplicates its vertices along a crease keeps the crease.
/// Indices must be below `positions.len()`.
pub fn angle_weighted_normals(positions: &[DVec3], indices: &[[u32; 3]]) -> Vec<DVec3> {
    // The angle between unit vectors, accurate near 0 and π (asin of half the chord).
    let unit_angle = |a: DVec3, b: DVec3| {
        if a.dot(b) < 0.0 {
            core::f64::consts::PI - 2.0 * libm::asin(((a + b).length() / 2.0).min(1.0))
        } else {
            2.0 * libm::asin(((a - b).length() / 2.0).min(1.0))
        }
    };
    let mut sum = vec![DVec3::ZERO; positions.len()];
    for t in indices {
        let p = t.map(|i| positions[i as usize]);
        let n = (p[1] - p[0]).cross(p[2] - p[0]);
        let len = n.length();
        if !(len > 0.0 && len.is_finite()) {
            continue;
        }
        let n = n / len;
        for j in 0..3 {
            let a = (p[(j + 1) % 3] - p[j]).normalize_or_zero();
            let b = (p[(j + 2) % 3] - p[j]).normalize_or_zero();
            let angle = unit_angle(a, b);
            if angle.is_finite() {
                sum[t[j] as usize] += n * angle;
            }
        }
    }
    sum.into_iter().map(|n| n.try_normalize().unwrap_or(DVec3::X)).collect()
}

/// A unit icosphere: the icosahedron subdivided `subdivisions` times
/// (`20·4^subdivisions` triangles), every vertex on the unit sphere, triangles wound
/// outwards (`(p1 − p0) × (p2 − p0)` points away from the centre). The positions double as
/// the outward unit normals.
pub fn unit_icosphere(subdivisions: u32) -> (Vec<DVec3>, Vec<[u32; 3]>) {
    let t = (1.0 + libm::sqrt(5.0)) / 2.0;
    let mut positions: Vec<DVec3> = [
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
    .map(|&(a, b, c)| DVec3::new(a, b, c).normalize())
    .collect();
    let mut indices: Vec<[u32; 3]> = vec![
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
        let mut midpoints: BTreeMap<(u32, u32), u32> = BTreeMap::new();
        let mut next = Vec::with_capacity(indices.len() * 4);
        for [a, b, c] in indices {
            let mut mid = |i: u32, j: u32| {
                *midpoints.entry((i.min(j), i.max(j))).or_insert_with(|| {
                    positions.push((positions[i as usize] + positions[j as usize]).normalize());
                    positions.len() as u32 - 1
                })
            };
            let (ab, bc, ca) = (mid(a, b), mid(b, c), mid(c, a));
            next.extend([[a, ab, ca], [b, bc, ab], [c, ca, bc], [ab, bc, ca]]);
        }
        indices = next;
    }
    for t in indices.iter_mut() {
        let p = t.map(|i| positions[i as usize]);
        if (p[1] - p[0]).cross(p[2] - p[0]).dot(p[0] + p[1] + p[2]) < 0.0 {
            t.swap(1, 2);
        }
    }
    (positions, indices)
}

/// The parallelogram `origin + s·u + t·v`, `s, t ∈ [0, 1]` (metres), as two triangles
/// with geometric normal `u × v` and flat shading.
pub fn parallelogram(name: &str, origin: Vec3, u: Vec3, v: Vec3, material: MaterialId) -> TriangleMesh {
    TriangleMesh { uvs: None,
        name: String::from(name),
        positions: vec![origin, origin + u, origin + u + v, origin + v],
        normals: None,
        indices: vec![[0, 1, 2], [0, 2, 3]],
        material,
        emission: None,
    }
}

/// The axis-aligned box `[lo, hi]` (metres) as one closed mesh of 12 triangles, flat
/// shaded, geometric normals outwards (the interior of a dielectric box is on the side
/// opposite the normals).
pub fn cuboid(name: &str, lo: Vec3, hi: Vec3, material: MaterialId) -> TriangleMesh {
    let d = hi - lo;
    let (dx, dy, dz) = (Vec3::X * d.x, Vec3::Y * d.y, Vec3::Z * d.z);
    let faces = [
        (lo, dx, dz),                          // -Y
        (Vec3::new(lo.x, hi.y, lo.z), dz, dx), // +Y
        (lo, dy, dx),                          // -Z
        (Vec3::new(lo.x, lo.y, hi.z), dx, dy), // +Z
        (lo, dz, dy),                          // -X
        (Vec3::new(hi.x, lo.y, lo.z), dy, dz), // +X
    ];
    let mut mesh = TriangleMesh { uvs: None, name: String::from(name), positions: Vec::new(), normals: None, indices: Vec::new(), material, emission: None };
    for (o, u, v) in faces {
        let k = mesh.positions.len() as u32;
        mesh.positions.extend([o, o + u, o + u + v, o + v]);
        mesh.indices.extend([[k, k + 1, k + 2], [k, k + 2, k + 3]]);
    }
    mesh
}

/// An icosphere mesh of `radius` (metres) around `centre` ([`unit_icosphere`]), with
/// smooth outward vertex normals when `smooth` and flat facets otherwise.
pub fn icosphere(name: &str, centre: Vec3, radius: f32, subdivisions: u32, smooth: bool, material: MaterialId) -> TriangleMesh {
    let (unit, indices) = unit_icosphere(subdivisions);
    TriangleMesh { uvs: None,
        name: String::from(name),
        positions: unit.iter().map(|p| centre + (*p * radius as f64).as_vec3()).collect(),
        normals: smooth.then(|| unit.iter().map(|p| p.as_vec3()).collect()),
        indices,
        material,
        emission: None,
    }
}

/// The GPU backends' benchmark scene (`cargo bench -p arpa --bench backends`): a closed
/// Cornell-like room (2 m cube, coloured side walls, 12 triangles), a smooth glass icosphere
/// (IOR 1.5, 1280 triangles), a mirror block and a downward quad light (15 W/(m²·sr)) under
/// the ceiling; the camera inside the room looks at the sphere, `width × height` pixels.
/// Metres, world space, y up.
pub fn glass_room(width: u32, height: u32) -> crate::render::scene::Scene {
    use crate::render::scene::{Camera, Material, Scene};
    let s = 1.0;
    let mut light = parallelogram("light", Vec3::new(-0.25, 1.98, -0.25), Vec3::new(0.5, 0.0, 0.0), Vec3::new(0.0, 0.0, 0.5), 0);
    light.emission = Some(Vec3::splat(15.0));
    let meshes = vec![
        parallelogram("floor", Vec3::new(-s, 0.0, -s), Vec3::new(0.0, 0.0, 2.0 * s), Vec3::new(2.0 * s, 0.0, 0.0), 0),
        parallelogram("ceiling", Vec3::new(-s, 2.0, -s), Vec3::new(2.0 * s, 0.0, 0.0), Vec3::new(0.0, 0.0, 2.0 * s), 0),
        parallelogram("back", Vec3::new(-s, 0.0, -s), Vec3::new(2.0 * s, 0.0, 0.0), Vec3::new(0.0, 2.0, 0.0), 0),
        parallelogram("front", Vec3::new(-s, 0.0, s), Vec3::new(0.0, 2.0, 0.0), Vec3::new(2.0 * s, 0.0, 0.0), 0),
        parallelogram("left", Vec3::new(-s, 0.0, -s), Vec3::new(0.0, 2.0, 0.0), Vec3::new(0.0, 0.0, 2.0 * s), 1),
        parallelogram("right", Vec3::new(s, 0.0, -s), Vec3::new(0.0, 0.0, 2.0 * s), Vec3::new(0.0, 2.0, 0.0), 2),
        icosphere("glass", Vec3::new(0.35, 0.45, 0.1), 0.35, 3, true, 3),
        light,
        cuboid("mirror block", Vec3::new(-0.7, 0.0, -0.7), Vec3::new(-0.2, 1.1, -0.3), 4),
    ];
    Scene { textures: Default::default(),
        meshes,
        materials: vec![
            Material::Diffuse { albedo: Vec3::splat(0.75) },
            Material::Diffuse { albedo: Vec3::new(0.6, 0.06, 0.05) },
            Material::Diffuse { albedo: Vec3::new(0.1, 0.6, 0.08) },
            Material::Dielectric { ior: 1.5, transmittance: Vec3::ONE, roughness: 0.0 },
            Material::Conductor { reflectance: Vec3::splat(0.95), roughness: 0.0 },
        ],
        lights: vec![],
        camera: Camera { position: Vec3::new(0.0, 1.0, 0.97), target: Vec3::new(0.0, 0.8, 0.0), up: Vec3::Y, vertical_fov: 1.3, width, height },
        roughness_cutoff: 0.5,
        instancing: None,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cuboid_is_closed_with_outward_normals() {
        let (lo, hi) = (Vec3::new(-1.0, 0.5, 2.0), Vec3::new(0.5, 1.0, 4.0));
        let m = cuboid("box", lo, hi, 3);
        assert_eq!((m.positions.len(), m.indices.len(), m.material), (24, 12, 3));
        let centre = (lo + hi) * 0.5;
        let mut area = 0.0;
        for t in &m.indices {
            let q = t.map(|i| m.positions[i as usize]);
            let n = (q[1] - q[0]).cross(q[2] - q[0]);
            assert!(n.dot(q[0] - centre) > 0.0, "inward triangle {t:?}");
            area += 0.5 * n.length();
        }
        let d = hi - lo;
        assert!((area - 2.0 * (d.x * d.y + d.y * d.z + d.z * d.x)).abs() < 1e-5);
    }

    #[test]
    fn icosphere_is_closed_outward_and_on_the_sphere() {
        for k in 0..4 {
            let (p, t) = unit_icosphere(k);
            assert_eq!(t.len(), 20 * 4usize.pow(k));
            // Euler: V − E + F = 2 with E = 3F/2.
            assert_eq!(p.len() + t.len() - 3 * t.len() / 2, 2);
            assert!(p.iter().all(|v| (v.length() - 1.0).abs() < 1e-12));
            for tri in &t {
                let q = tri.map(|i| p[i as usize]);
                assert!((q[1] - q[0]).cross(q[2] - q[0]).dot(q[0]) > 0.0);
            }
        }
    }

    /// Mitsuba 3's own test of its vertex normals (test_mesh.py, "the weighting scheme"):
    /// two triangles sharing vertex 0 with angles π/2 and acos(3/5) there.
    #[test]
    fn angle_weighted_normals_match_mitsubas_test() {
        let (a, b) = (1.0, 0.5);
        let positions = [DVec3::ZERO, DVec3::new(-a, 1.0, 0.0), DVec3::new(a, 1.0, 0.0), DVec3::new(-b, 0.0, 1.0), DVec3::new(b, 0.0, 1.0)];
        let n = angle_weighted_normals(&positions, &[[0, 1, 2], [0, 3, 4]]);
        let (n0, n1) = (DVec3::new(0.0, 0.0, -1.0), DVec3::new(0.0, 1.0, 0.0));
        let n2 = (n0 * core::f64::consts::FRAC_PI_2 + n1 * libm::acos(3.0 / 5.0)).normalize();
        for (got, want) in n.iter().zip([n2, n0, n0, n1, n1]) {
            assert!((*got - want).length() < 1e-12, "{got} vs {want}");
        }
        // A vertex of degenerate triangles only: +x.
        let flat = angle_weighted_normals(&[DVec3::ZERO, DVec3::X, DVec3::new(2.0, 0.0, 0.0)], &[[0, 1, 2]]);
        assert_eq!(flat, [DVec3::X; 3]);
    }
}
