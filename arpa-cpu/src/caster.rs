//! [`EmbreeCaster`]: the core's [`RayCaster`] answered by an Embree triangle scene.

use core::sync::atomic::{AtomicU64, Ordering};

use arpa_core::glam::Vec3;
use arpa_core::render::prepared_scene::PreparedScene;
use arpa_core::render::ray_cast::{RayCaster, RayHit};

use crate::embree::{BuildQuality, Device, EmbreeScene, EmbreeSceneBuilder, Result};

/// Closest-hit and occlusion queries of the camera and photon paths against the scene's
/// triangles, on an Embree BVH.
///
/// Every mesh with at least one triangle becomes one Embree triangle geometry, added in
/// mesh order; [`RayHit::mesh`] is the index in [`arpa_core::render::scene::Scene::meshes`] (meshes
/// without triangles get no geometry and are mapped around) and [`RayHit::triangle`] the
/// triangle index within it. The BVH is built with [`BuildQuality::High`] and Embree's
/// robust (watertight) mode, so rays do not leak through shared edges of closed meshes.
///
/// The core's rays are open segments `t ∈ (t_min, t_max)` ([`RayCaster`]); Embree's are
/// closed (`tnear ≤ t ≤ tfar`), so a segment starts at `tnear = max(t_min,
/// f32::MIN_POSITIVE)`: a ray whose origin lies exactly on a triangle does not hit it at
/// `t = 0`, as with [`arpa_core::render::brute_force::BruteForceCaster`].
///
/// Rays leaving a surface start on it and skip the triangle they leave: that rule is the
/// core's ([`arpa_core::render::ray_cast::RayStart`]), on top of these queries, so none is needed
/// here.
///
/// Embree reports errors per query; a failed query (an invalid ray, which the core's paths
/// never produce, or an Embree error) counts as a miss and is tallied in
/// [`EmbreeCaster::errors`].
#[derive(Debug)]
pub struct EmbreeCaster {
    scene: EmbreeScene,
    /// Mesh index of each Embree geometry id.
    mesh_of_geometry: Vec<u32>,
    errors: AtomicU64,
}

impl EmbreeCaster {
    /// Builds the triangle BVH of `scene` on `device`.
    pub fn new(device: &Device, scene: &PreparedScene) -> Result<Self> {
        let mut builder = EmbreeSceneBuilder::new(device)?
            .build_quality(BuildQuality::High)
            .robust(true);
        let mut mesh_of_geometry = Vec::with_capacity(scene.scene().meshes.len());
        for (index, mesh) in scene.scene().meshes.iter().enumerate() {
            if mesh.indices.is_empty() || mesh.positions.is_empty() {
                continue;
            }
            let vertices: Vec<[f32; 3]> = mesh.positions.iter().map(|p| p.to_array()).collect();
            let geom = builder.add_triangle_mesh(&vertices, &mesh.indices)?;
            debug_assert_eq!(geom as usize, mesh_of_geometry.len());
            mesh_of_geometry.push(index as u32);
        }
        Ok(Self {
            scene: builder.commit()?,
            mesh_of_geometry,
            errors: AtomicU64::new(0),
        })
    }

    /// Queries that failed (and were answered as misses) since this caster was built.
    /// Always 0 unless something is wrong.
    pub fn errors(&self) -> u64 {
        self.errors.load(Ordering::Relaxed)
    }

    /// The Embree scene.
    pub fn scene(&self) -> &EmbreeScene {
        &self.scene
    }

    #[cold]
    fn failed(&self) {
        self.errors.fetch_add(1, Ordering::Relaxed);
    }
}

/// Start of every ray segment: the smallest positive normal `f32`, so that `t = 0` is
/// excluded as in the core's open interval (a normal number, so that denormals-are-zero
/// modes cannot turn it back into 0).
const T_NEAR: f32 = f32::MIN_POSITIVE;

impl RayCaster for EmbreeCaster {
    #[inline]
    fn intersect(&self, origin: Vec3, direction: Vec3, t_min: f32, t_max: f32) -> Option<RayHit> {
        let hit = match self.scene.intersect(origin.to_array(), direction.to_array(), t_min.max(T_NEAR), t_max) {
            Ok(Some(hit)) => hit,
            Ok(None) => return None,
            Err(_) => {
                self.failed();
                return None;
            }
        };
        match self.mesh_of_geometry.get(hit.geom_id as usize) {
            Some(&mesh) => Some(RayHit { t: hit.t, mesh, triangle: hit.prim_id, b1: hit.u, b2: hit.v }),
            None => {
                self.failed();
                None
            }
        }
    }

    fn occluded(&self, origin: Vec3, direction: Vec3, t_min: f32, t_max: f32) -> bool {
        match self
            .scene
            .occluded(origin.to_array(), direction.to_array(), t_min.max(T_NEAR), t_max)
        {
            Ok(o) => o,
            Err(_) => {
                self.failed();
                false
            }
        }
    }
}
