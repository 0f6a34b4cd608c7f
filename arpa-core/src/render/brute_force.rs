//! An independent reference for the one geometric query of [`crate::render::ray_cast`]:
//! every triangle of a prepared scene tested in `f64`, for tests.

use crate::render::prepared_scene::PreparedScene;
use crate::render::ray_cast::{RayCaster, RayHit};
use alloc::vec::Vec;
use glam::{DVec3, Vec3};

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
    fn intersect(&self, origin: Vec3, direction: Vec3, t_min: f32, t_max: f32) -> Option<RayHit> {
        let (o, d) = (origin.as_dvec3(), direction.as_dvec3());
        let t_min = t_min as f64;
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
            if t > t_min && t < best_t {
                best_t = t;
                best = Some(RayHit { t: t as f32, mesh: *mesh, triangle: *triangle, b1: b1 as f32, b2: b2 as f32 });
            }
        }
        best
    }
}
