//! Mitsuba's built-in shapes as triangle meshes (object space, before `to_world`):
//! `rectangle` (`[-1, 1]²` at z = 0, normal +z), `cube` (`[-1, 1]³`, outward normals,
//! face-normal shading) and `sphere` (an icosphere subdivided 4 times, 5,120 triangles,
//! exact unit-sphere vertices with smooth outward normals).

use super::RawMesh;
use glam::DVec3;
use std::collections::HashMap;

/// Mitsuba's `rectangle`.
pub(crate) fn rectangle() -> RawMesh {
    let positions = vec![DVec3::new(-1.0, -1.0, 0.0), DVec3::new(1.0, -1.0, 0.0), DVec3::new(1.0, 1.0, 0.0), DVec3::new(-1.0, 1.0, 0.0)];
    RawMesh { positions, normals: Some(vec![DVec3::Z; 4]), indices: vec![[0, 1, 2], [0, 2, 3]] }
}

/// Mitsuba's `cube`.
pub(crate) fn cube() -> RawMesh {
    let (x, y, z) = (DVec3::X, DVec3::Y, DVec3::Z);
    let faces = [(x, y, z), (-x, z, y), (y, z, x), (-y, x, z), (z, x, y), (-z, y, x)];
    let mut m = RawMesh { positions: Vec::new(), normals: None, indices: Vec::new() };
    for (n, u, v) in faces {
        let b = m.positions.len() as u32;
        m.positions.extend([n - u - v, n + u - v, n + u + v, n - u + v]);
        m.indices.extend([[b, b + 1, b + 2], [b, b + 2, b + 3]]);
    }
    m
}

/// Subdivisions of the sphere's icosahedron.
pub const SPHERE_SUBDIVISIONS: u32 = 4;

/// A unit icosphere (`20·4^SPHERE_SUBDIVISIONS` triangles) with outward winding and normals.
pub(crate) fn sphere() -> RawMesh {
    let t = (1.0 + 5f64.sqrt()) / 2.0;
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
    for _ in 0..SPHERE_SUBDIVISIONS {
        let mut mid: HashMap<(u32, u32), u32> = HashMap::new();
        let mut next = Vec::with_capacity(indices.len() * 4);
        for [a, b, c] in indices {
            let mut m = |i: u32, j: u32| {
                *mid.entry((i.min(j), i.max(j))).or_insert_with(|| {
                    positions.push(((positions[i as usize] + positions[j as usize]) * 0.5).normalize());
                    positions.len() as u32 - 1
                })
            };
            let (ab, bc, ca) = (m(a, b), m(b, c), m(c, a));
            next.extend([[a, ab, ca], [b, bc, ab], [c, ca, bc], [ab, bc, ca]]);
        }
        indices = next;
    }
    // Make the winding outward whatever the table's convention.
    for t in indices.iter_mut() {
        let p = t.map(|i| positions[i as usize]);
        if (p[1] - p[0]).cross(p[2] - p[0]).dot(p[0] + p[1] + p[2]) < 0.0 {
            t.swap(1, 2);
        }
    }
    let normals = positions.clone();
    RawMesh { positions, normals: Some(normals), indices }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn outward(m: &RawMesh) -> bool {
        let c = m.positions.iter().copied().sum::<DVec3>() / m.positions.len() as f64;
        m.indices.iter().all(|t| {
            let p = t.map(|i| m.positions[i as usize]);
            (p[1] - p[0]).cross(p[2] - p[0]).dot((p[0] + p[1] + p[2]) / 3.0 - c) > 0.0
        })
    }

    #[test]
    fn shapes_are_closed_and_outward() {
        assert!(outward(&cube()) && cube().indices.len() == 12);
        let s = sphere();
        assert_eq!(s.indices.len(), 5120);
        assert!(outward(&s));
        let r = rectangle();
        let p = r.indices[0].map(|i| r.positions[i as usize]);
        assert!((p[1] - p[0]).cross(p[2] - p[0]).z > 0.0);
    }
}
