//! Mitsuba's built-in shapes as triangle meshes (object space, before `to_world`), with
//! Mitsuba's texture coordinates:
//! - `rectangle`: `[-1, 1]²` at z = 0, normal +z, `uv = ((x + 1)/2, (y + 1)/2)`;
//! - `cube`: `[-1, 1]³`, outward normals, face-normal shading, each face's `uv` as
//!   Mitsuba's cube maps it;
//! - `sphere`: an icosphere subdivided 4 times (5,120 triangles) with exact unit-sphere
//!   vertices and smooth outward normals, `u = atan2(y, x)/2π` in `[0, 1)`,
//!   `v = acos(z)/π` (vertices on the `u` seam and at the poles duplicated so no triangle
//!   interpolates across the seam);
//! - `cylinder`: the open unit cylinder (radius 1, `z` from 0 to 1, no caps) of
//!   [`CYLINDER_SEGMENTS`] flat sides, smooth outward normals, `u = φ/2π`, `v = z`;
//! - `disk`: the unit disk at z = 0 facing +z, a fan of [`DISK_SEGMENTS`] triangles,
//!   `u = r`, `v = φ/2π` (near the centre `v` is within half a segment of the exact angle:
//!   each fan triangle has its own centre vertex at its mean angle).
//!
//! `φ = atan2(y, x)` in `[0, 2π)`. Curved shapes are tessellated: the flat sides of the
//! cylinder and the disk's chords lie within `1 − cos(π/N)` (7.5e-5 of the radius at
//! N = 256) of the exact surface.

use super::mesh::RawMesh;
use glam::{DVec2, DVec3};
use std::f64::consts::TAU;

/// Sides of the tessellated `cylinder`.
pub const CYLINDER_SEGMENTS: u32 = 256;

/// Triangles of the tessellated `disk`.
pub const DISK_SEGMENTS: u32 = 256;

/// `atan2(y, x)` mapped to `[0, 1)` (Mitsuba's azimuthal texture coordinate).
fn azimuth(y: f64, x: f64) -> f64 {
    let a = y.atan2(x) / TAU;
    if a < 0.0 { a + 1.0 } else { a }
}

/// Mitsuba's `rectangle`.
pub(crate) fn rectangle() -> RawMesh {
    let positions = vec![DVec3::new(-1.0, -1.0, 0.0), DVec3::new(1.0, -1.0, 0.0), DVec3::new(1.0, 1.0, 0.0), DVec3::new(-1.0, 1.0, 0.0)];
    let uvs = positions.iter().map(|p| DVec2::new(0.5 * (p.x + 1.0), 0.5 * (p.y + 1.0))).collect();
    RawMesh { positions, normals: Some(vec![DVec3::Z; 4]), uvs: Some(uvs), indices: vec![[0, 1, 2], [0, 2, 3]], face_normals: false }
}

/// The `uv` Mitsuba's cube gives the point `p` of its face with outward normal `n`.
fn cube_uv(n: DVec3, p: DVec3) -> DVec2 {
    let h = |a: f64| 0.5 * (a + 1.0);
    let g = |a: f64| 0.5 * (1.0 - a);
    match (n.x as i32, n.y as i32, n.z as i32) {
        (0, -1, 0) => DVec2::new(h(p.z), h(p.x)),
        (0, 1, 0) => DVec2::new(g(p.x), g(p.z)),
        (1, 0, 0) => DVec2::new(h(p.y), g(p.z)),
        (-1, 0, 0) => DVec2::new(h(p.y), h(p.z)),
        (0, 0, 1) => DVec2::new(h(p.y), h(p.x)),
        _ => DVec2::new(g(p.y), h(p.x)),
    }
}

/// Mitsuba's `cube`.
pub(crate) fn cube() -> RawMesh {
    let (x, y, z) = (DVec3::X, DVec3::Y, DVec3::Z);
    let faces = [(x, y, z), (-x, z, y), (y, z, x), (-y, x, z), (z, x, y), (-z, y, x)];
    let mut m = RawMesh { positions: Vec::new(), normals: None, uvs: Some(Vec::new()), indices: Vec::new(), face_normals: false };
    for (n, u, v) in faces {
        let b = m.positions.len() as u32;
        let corners = [n - u - v, n + u - v, n + u + v, n - u + v];
        m.positions.extend(corners);
        if let Some(uvs) = m.uvs.as_mut() {
            uvs.extend(corners.map(|p| cube_uv(n, p)));
        }
        m.indices.extend([[b, b + 1, b + 2], [b, b + 2, b + 3]]);
    }
    m
}

/// Subdivisions of the sphere's icosahedron.
pub const SPHERE_SUBDIVISIONS: u32 = 4;

/// A unit icosphere (`20·4^SPHERE_SUBDIVISIONS` triangles) with outward winding and normals
/// ([`arpa_core::render::shapes::unit_icosphere`]) and Mitsuba's sphere `uv`.
pub(crate) fn sphere() -> RawMesh {
    let (mut positions, mut indices) = arpa_core::render::shapes::unit_icosphere(SPHERE_SUBDIVISIONS);
    let mut uvs: Vec<DVec2> = positions.iter().map(|p| DVec2::new(azimuth(p.y, p.x), p.z.clamp(-1.0, 1.0).acos() / std::f64::consts::PI)).collect();
    let pole = |p: DVec3| p.x.abs() < 1e-12 && p.y.abs() < 1e-12;
    for t in indices.iter_mut() {
        // A triangle across the seam u = 0 ≡ 1: its vertices with small u get copies at u + 1.
        let us = t.map(|i| uvs[i as usize].x);
        let poles = t.map(|i| pole(positions[i as usize]));
        let live: Vec<f64> = (0..3).filter(|&k| !poles[k]).map(|k| us[k]).collect();
        let across = live.iter().cloned().fold(f64::MIN, f64::max) - live.iter().cloned().fold(f64::MAX, f64::min) > 0.5;
        for k in 0..3 {
            if across && !poles[k] && us[k] < 0.5 {
                positions.push(positions[t[k] as usize]);
                uvs.push(DVec2::new(us[k] + 1.0, uvs[t[k] as usize].y));
                t[k] = positions.len() as u32 - 1;
            }
        }
        // A pole's u is undefined: each triangle gets its own copy at the mean u of the
        // other two vertices.
        for k in 0..3 {
            if poles[k] {
                let others: Vec<f64> = (0..3).filter(|&j| j != k).map(|j| uvs[t[j] as usize].x).collect();
                let u = others.iter().sum::<f64>() / others.len() as f64;
                positions.push(positions[t[k] as usize]);
                uvs.push(DVec2::new(u, uvs[t[k] as usize].y));
                t[k] = positions.len() as u32 - 1;
            }
        }
    }
    let normals = positions.clone();
    RawMesh { positions, normals: Some(normals), uvs: Some(uvs), indices, face_normals: false }
}

/// Mitsuba's `cylinder` in its local frame: radius 1 around +z from `z = 0` to `z = 1`,
/// open (no caps), outward winding and normals.
pub(crate) fn cylinder() -> RawMesh {
    let n = CYLINDER_SEGMENTS;
    let mut m = RawMesh { positions: Vec::new(), normals: Some(Vec::new()), uvs: Some(Vec::new()), indices: Vec::new(), face_normals: false };
    for i in 0..=n {
        let u = i as f64 / n as f64;
        let (s, c) = (TAU * u).sin_cos();
        for z in [0.0, 1.0] {
            m.positions.push(DVec3::new(c, s, z));
            m.normals.as_mut().unwrap().push(DVec3::new(c, s, 0.0));
            m.uvs.as_mut().unwrap().push(DVec2::new(u, z));
        }
    }
    for i in 0..n {
        let (a, b) = (2 * i, 2 * i + 2);
        m.indices.extend([[a, b, b + 1], [a, b + 1, a + 1]]);
    }
    m
}

/// Mitsuba's `disk` in its local frame: radius 1 at `z = 0`, facing +z.
pub(crate) fn disk() -> RawMesh {
    let n = DISK_SEGMENTS;
    let mut m = RawMesh { positions: Vec::new(), normals: Some(Vec::new()), uvs: Some(Vec::new()), indices: Vec::new(), face_normals: false };
    let rim = |i: u32| {
        let v = i as f64 / n as f64;
        let (s, c) = (TAU * v).sin_cos();
        (DVec3::new(c, s, 0.0), v)
    };
    for i in 0..n {
        let b = m.positions.len() as u32;
        let ((p0, v0), (p1, v1)) = (rim(i), rim(i + 1));
        // The centre's angle is undefined: each triangle has its own centre vertex.
        m.positions.extend([DVec3::ZERO, p0, p1]);
        m.normals.as_mut().unwrap().extend([DVec3::Z; 3]);
        m.uvs.as_mut().unwrap().extend([DVec2::new(0.0, 0.5 * (v0 + v1)), DVec2::new(1.0, v0), DVec2::new(1.0, v1)]);
        m.indices.push([b, b + 1, b + 2]);
    }
    m
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
        let d = disk();
        assert!(d.indices.iter().all(|t| { let p = t.map(|i| d.positions[i as usize]); (p[1] - p[0]).cross(p[2] - p[0]).z > 0.0 }));
        let c = cylinder();
        assert!(c.indices.iter().all(|t| {
            let p = t.map(|i| c.positions[i as usize]);
            let mid = (p[0] + p[1] + p[2]) / 3.0;
            (p[1] - p[0]).cross(p[2] - p[0]).dot(DVec3::new(mid.x, mid.y, 0.0)) > 0.0
        }));
    }

    /// Mitsuba's parametrisations at points whose uv is known (from Mitsuba 3.9's shapes),
    /// interpolated over the triangle containing them.
    #[test]
    fn texture_coordinates_are_mitsubas() {
        fn uv_at(m: &RawMesh, q: DVec3) -> DVec2 {
            let uvs = m.uvs.as_ref().unwrap();
            for t in &m.indices {
                let p = t.map(|i| m.positions[i as usize]);
                let n = (p[1] - p[0]).cross(p[2] - p[0]);
                let area = n.length();
                let b = [(p[2] - p[1]).cross(q - p[1]).dot(n) / (area * area), (p[0] - p[2]).cross(q - p[2]).dot(n) / (area * area), (p[1] - p[0]).cross(q - p[0]).dot(n) / (area * area)];
                let off_plane = (q - p[0]).dot(n / area).abs();
                if b.iter().all(|&x| x >= -1e-9) && off_plane < 1e-3 {
                    return uvs[t[0] as usize] * b[0] + uvs[t[1] as usize] * b[1] + uvs[t[2] as usize] * b[2];
                }
            }
            panic!("no triangle contains {q}");
        }
        let close = |a: DVec2, b: DVec2, tol: f64| (a - b).abs().max_element() < tol;
        assert!(close(uv_at(&rectangle(), DVec3::new(0.5, -0.5, 0.0)), DVec2::new(0.75, 0.25), 1e-12));
        // Sphere: +y is (0.25, 0.5), −x is (0.5, 0.5); a point just past the seam has u near 1.
        let s = sphere();
        assert!(close(uv_at(&s, DVec3::Y), DVec2::new(0.25, 0.5), 1e-9));
        assert!(close(uv_at(&s, -DVec3::X), DVec2::new(0.5, 0.5), 1e-9));
        let seam = DVec3::new(0.99, -0.01, 0.0).normalize();
        assert!(uv_at(&s, seam).x > 0.99, "{}", uv_at(&s, seam));
        // Every sphere triangle spans less than a quarter turn in u (no seam wrap).
        let uvs = s.uvs.as_ref().unwrap();
        assert!(s.indices.iter().all(|t| { let u = t.map(|i| uvs[i as usize].x); u.iter().cloned().fold(f64::MIN, f64::max) - u.iter().cloned().fold(f64::MAX, f64::min) < 0.25 }));
        // Cube faces (Mitsuba 3.9): +Z at (x, y) = (0.5, -0.5) is ((y+1)/2, (x+1)/2).
        let c = cube();
        assert!(close(uv_at(&c, DVec3::new(0.5, -0.5, 1.0)), DVec2::new(0.25, 0.75), 1e-12));
        assert!(close(uv_at(&c, DVec3::new(0.5, 1.0, -0.5)), DVec2::new(0.25, 0.75), 1e-12));
        // Cylinder: u = φ/2π, v = z (on its flat sides, at a vertex column).
        let cy = cylinder();
        let q = DVec3::new((TAU * 0.25).cos(), (TAU * 0.25).sin(), 0.3);
        assert!(close(uv_at(&cy, q), DVec2::new(0.25, 0.3), 1e-9));
        // Disk: u = r, v = φ/2π (v within half a segment: the centre vertex of each fan
        // triangle carries the triangle's mean angle).
        let d = disk();
        let q = DVec3::new(0.5 * (TAU * 0.25).cos(), 0.5 * (TAU * 0.25).sin(), 0.0);
        let uv = uv_at(&d, q);
        assert!((uv.x - 0.5).abs() < 1e-9 && (uv.y - 0.25).abs() <= 0.5 / DISK_SEGMENTS as f64 + 1e-12, "{uv}");
    }
}
