//! Mitsuba's built-in shapes as triangle meshes (object space, before `to_world`):
//! `rectangle` (`[-1, 1]²` at z = 0, normal +z), `cube` (`[-1, 1]³`, outward normals,
//! face-normal shading) and `sphere` (an icosphere subdivided 4 times, 5,120 triangles,
//! exact unit-sphere vertices with smooth outward normals).

use super::mesh::RawMesh;
use glam::DVec3;

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

/// A unit icosphere (`20·4^SPHERE_SUBDIVISIONS` triangles) with outward winding and normals
/// ([`arpa_core::render::shapes::unit_icosphere`]).
pub(crate) fn sphere() -> RawMesh {
    let (positions, indices) = arpa_core::render::shapes::unit_icosphere(SPHERE_SUBDIVISIONS);
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
