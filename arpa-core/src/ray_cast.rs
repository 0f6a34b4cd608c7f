//! The one geometric query the reference paths need from a backend: closest hit and
//! occlusion of a ray against the scene's triangles. Backends answer it with their own
//! acceleration structure (Embree, hardware ray tracing); [`BruteForceCaster`] answers it
//! by testing every triangle in `f64`, as an independent reference for tests.

use crate::prepared_scene::PreparedScene;
use alloc::vec::Vec;
use glam::{DVec3, Vec3};

/// A ray–triangle hit.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RayHit {
    /// Distance along the (unit) ray direction (metres).
    pub t: f32,
    /// Mesh index in [`crate::scene::Scene::meshes`].
    pub mesh: u32,
    /// Triangle index within the mesh.
    pub triangle: u32,
    /// Barycentric weight of the triangle's second vertex (Embree's `u`).
    pub b1: f32,
    /// Barycentric weight of the third vertex (Embree's `v`).
    pub b2: f32,
}

/// Closest-hit and occlusion queries against the scene's triangles. Rays are
/// `origin + t·direction` with unit `direction` and `t ∈ (0, t_max)`.
pub trait RayCaster: Sync {
    /// The closest hit, if any.
    fn intersect(&self, origin: Vec3, direction: Vec3, t_max: f32) -> Option<RayHit>;
    /// Whether anything is hit.
    fn occluded(&self, origin: Vec3, direction: Vec3, t_max: f32) -> bool {
        self.intersect(origin, direction, t_max).is_some()
    }
}

/// Tests every triangle (Möller–Trumbore in `f64`). For small test scenes only.
#[derive(Clone, Debug)]
pub struct BruteForceCaster {
    triangles: Vec<([DVec3; 3], u32, u32)>,
}

impl BruteForceCaster {
    /// Collects the triangles of `scene`.
    pub fn new(scene: &PreparedScene) -> Self {
        let mut triangles = Vec::new();
        for (mi, m) in scene.scene().meshes.iter().enumerate() {
            for ti in 0..m.indices.len() {
                triangles.push((scene.triangle(mi as u32, ti as u32), mi as u32, ti as u32));
            }
        }
        Self { triangles }
    }
}

impl RayCaster for BruteForceCaster {
    fn intersect(&self, origin: Vec3, direction: Vec3, t_max: f32) -> Option<RayHit> {
        let (o, d) = (origin.as_dvec3(), direction.as_dvec3());
        let mut best: Option<RayHit> = None;
        let mut best_t = t_max as f64;
        for (p, mesh, triangle) in &self.triangles {
            let e1 = p[1] - p[0];
            let e2 = p[2] - p[0];
            let pv = d.cross(e2);
            let det = e1.dot(pv);
            if det.abs() < 1e-300 {
                continue;
            }
            let inv = 1.0 / det;
            let tv = o - p[0];
            let b1 = tv.dot(pv) * inv;
            if !(0.0..=1.0).contains(&b1) {
                continue;
            }
            let qv = tv.cross(e1);
            let b2 = d.dot(qv) * inv;
            if b2 < 0.0 || b1 + b2 > 1.0 {
                continue;
            }
            let t = e2.dot(qv) * inv;
            if t > 0.0 && t < best_t {
                best_t = t;
                best = Some(RayHit { t: t as f32, mesh: *mesh, triangle: *triangle, b1: b1 as f32, b2: b2 as f32 });
            }
        }
        best
    }
}
