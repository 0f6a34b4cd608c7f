//! [`EmbreeCaster`]: the core's [`RayCaster`] answered by an Embree triangle scene.

use core::sync::atomic::{AtomicU64, Ordering};

use arpa_core::glam::Vec3;
use arpa_core::render::prepared_scene::PreparedScene;
use arpa_core::glam::DAffine3;
use arpa_core::render::ray_cast::{RayCaster, RayHit, refine_hit};
use arpa_core::render::scene::Instancing;

use crate::embree::{BuildQuality, Device, EmbreeScene, EmbreeSceneBuilder, Hit, Result};

/// Closest-hit and occlusion queries of the camera and photon paths against the scene's
/// triangles, on an Embree BVH.
///
/// Every mesh with at least one triangle becomes one Embree triangle geometry, added in
/// mesh order, except the copies of shared geometry ([`Scene::instancing`](arpa_core::render::scene::Scene::instancing), prototypes
/// placed at least twice, [`Instancing::copies`]): each such prototype is one Embree scene
/// of its meshes in object space, and each copy of it one instance geometry placed by its
/// transform. [`RayHit::mesh`] is the index in [`Scene::meshes`](arpa_core::render::scene::Scene::meshes) (of the copy, for a hit
/// through an instance; meshes without triangles get no geometry and are mapped around)
/// and [`RayHit::triangle`] the triangle index within it. Every BVH is built with
/// [`BuildQuality::High`] and Embree's robust (watertight) mode, so rays do not leak
/// through shared edges of closed meshes.
///
/// Whichever way the triangle was found, the hit is finished by the core's
/// [`refine_hit`] on the mesh's world-space triangle: the barycentric weights, all that
/// shading reads of a hit besides the triangle, depend on the ray and the triangle alone,
/// so an instanced scene renders as its flattened copy does (`t` stays Embree's, within
/// rounding of the flattened one's).
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
    /// What each geometry id of the top-level scene places.
    placed: Vec<Placed>,
    /// World-space vertices of every triangle, mesh after mesh ([`refine_hit`]'s input).
    triangles: Vec<[Vec3; 3]>,
    /// Index in `triangles` of each mesh's first triangle.
    first_triangle: Vec<u32>,
    /// The instanced prototype scenes (Embree holds its own references; kept so that
    /// they visibly outlive the top-level scene, which is dropped first).
    _prototypes: Vec<EmbreeScene>,
    errors: AtomicU64,
}

/// A geometry of the top-level scene.
#[derive(Debug)]
enum Placed {
    /// A triangle geometry: this mesh.
    Mesh(u32),
    /// An instance: the mesh copied at each geometry id of the instanced scene.
    Copies(Vec<u32>),
}

impl EmbreeCaster {
    /// Builds the triangle BVH of `scene` on `device`, instancing the prototypes of
    /// [`Scene::instancing`](arpa_core::render::scene::Scene::instancing) placed at least twice.
    pub fn new(device: &Device, scene: &PreparedScene) -> Result<Self> {
        let meshes = &scene.scene().meshes;
        let copies = scene.scene().instancing.as_ref().map(|i| i.copies(meshes.len())).unwrap_or_default();
        let mut builder = new_builder(device)?;
        let mut placed = Vec::with_capacity(meshes.len());
        for (index, mesh) in meshes.iter().enumerate() {
            if mesh.indices.is_empty() || mesh.positions.is_empty() || copies.get(index).is_some_and(Option::is_some) {
                continue;
            }
            let geom = add_mesh(&mut builder, &mesh.positions, &mesh.indices)?;
            debug_assert_eq!(geom as usize, placed.len());
            placed.push(Placed::Mesh(index as u32));
        }
        let mut prototypes = Vec::new();
        if let Some(instancing) = &scene.scene().instancing {
            // Per prototype: its Embree scene and the prototype mesh of each geometry id.
            let mut built: Vec<Option<(usize, Vec<u32>)>> = vec![None; instancing.prototypes.len()];
            for instance in copied_instances(instancing, &copies) {
                let inst = &instancing.instances[instance];
                let p = inst.prototype as usize;
                if built[p].is_none() {
                    let mut child = new_builder(device)?;
                    let mut of_geometry = Vec::new();
                    for (k, pm) in instancing.prototypes[p].meshes.iter().enumerate() {
                        if !(pm.indices.is_empty() || pm.positions.is_empty()) {
                            add_mesh(&mut child, &pm.positions, &pm.indices)?;
                            of_geometry.push(k as u32);
                        }
                    }
                    prototypes.push(child.commit()?);
                    built[p] = Some((prototypes.len() - 1, of_geometry));
                }
                let Some((slot, of_geometry)) = &built[p] else { continue };
                let geom = builder.add_instance(&prototypes[*slot], rows(&inst.to_world))?;
                debug_assert_eq!(geom as usize, placed.len());
                placed.push(Placed::Copies(of_geometry.iter().map(|&k| inst.meshes[k as usize]).collect()));
            }
        }
        let mut triangles = Vec::with_capacity(meshes.iter().map(|m| m.indices.len()).sum());
        let mut first_triangle = Vec::with_capacity(meshes.len());
        for m in meshes {
            first_triangle.push(triangles.len() as u32);
            triangles.extend(m.indices.iter().map(|t| t.map(|i| m.positions[i as usize])));
        }
        Ok(Self {
            scene: builder.commit()?,
            placed,
            triangles,
            first_triangle,
            _prototypes: prototypes,
            errors: AtomicU64::new(0),
        })
    }

    /// Queries that failed (and were answered as misses) since this caster was built.
    /// Always 0 unless something is wrong.
    pub fn errors(&self) -> u64 {
        self.errors.load(Ordering::Relaxed)
    }

    /// The Embree scene (the top level: it holds the instances of an instanced scene).
    pub fn scene(&self) -> &EmbreeScene {
        &self.scene
    }

    /// Instance geometries in the top-level scene (0 when nothing is instanced).
    pub fn instance_count(&self) -> usize {
        self.placed.iter().filter(|p| matches!(p, Placed::Copies(_))).count()
    }

    /// The mesh that Embree's `(inst_id, geom_id)` names.
    #[inline]
    fn mesh_of(&self, hit: &Hit) -> Option<u32> {
        if hit.inst_id == u32::MAX {
            match self.placed.get(hit.geom_id as usize)? {
                Placed::Mesh(m) => Some(*m),
                Placed::Copies(_) => None,
            }
        } else {
            match self.placed.get(hit.inst_id as usize)? {
                Placed::Copies(ms) => ms.get(hit.geom_id as usize).copied(),
                Placed::Mesh(_) => None,
            }
        }
    }

    #[cold]
    fn failed(&self) {
        self.errors.fetch_add(1, Ordering::Relaxed);
    }
}

/// A builder for the scene's triangles: [`BuildQuality::High`], robust.
fn new_builder(device: &Device) -> Result<EmbreeSceneBuilder> {
    Ok(EmbreeSceneBuilder::new(device)?.build_quality(BuildQuality::High).robust(true))
}

/// Adds a triangle mesh of `f32` positions.
fn add_mesh(builder: &mut EmbreeSceneBuilder, positions: &[Vec3], indices: &[[u32; 3]]) -> Result<u32> {
    let vertices: Vec<[f32; 3]> = positions.iter().map(|p| p.to_array()).collect();
    builder.add_triangle_mesh(&vertices, indices)
}

/// The instances whose meshes [`Instancing::copies`] lists, in instance order.
fn copied_instances<'a>(instancing: &'a Instancing, copies: &'a [Option<(u32, u32)>]) -> impl Iterator<Item = usize> + 'a {
    let mut seen = vec![false; instancing.instances.len()];
    for &(i, _) in copies.iter().flatten() {
        seen[i as usize] = true;
    }
    (0..instancing.instances.len()).filter(move |&i| seen[i])
}

/// An affine map as the rows of its 3×4 matrix in `f32` (Embree's `FLOAT3X4_ROW_MAJOR`).
fn rows(m: &DAffine3) -> [[f32; 4]; 3] {
    let (a, t) = (m.matrix3, m.translation);
    [0, 1, 2].map(|r| [a.x_axis[r] as f32, a.y_axis[r] as f32, a.z_axis[r] as f32, t[r] as f32])
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
        let triangle = self.mesh_of(&hit).and_then(|mesh| {
            let first = *self.first_triangle.get(mesh as usize)?;
            Some((mesh, self.triangles.get(first as usize + hit.prim_id as usize)?))
        });
        match triangle {
            Some((mesh, p)) => Some(refine_hit(RayHit { t: hit.t, mesh, triangle: hit.prim_id, b1: hit.u, b2: hit.v }, *p, origin, direction)),
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

#[cfg(test)]
mod tests {
    use super::*;
    use arpa_core::base::rng::{Rng, StreamDomain};
    use arpa_core::emit::emission::{Light, PointLight};
    use arpa_core::glam::{DQuat, DVec3};
    use arpa_core::render::scene::{Camera, Material, Scene};
    use arpa_core::render::shapes::{cuboid, icosphere, parallelogram};

    /// A floor and three copies of a group (a smooth sphere and a box) just above it (no
    /// coincident faces, whose order of discovery no structure defines) under rotations,
    /// non-uniform scales and one mirroring, with its instancing recorded.
    fn instanced_scene() -> Scene {
        let group = vec![icosphere("ball", Vec3::new(0.0, 0.3, 0.0), 0.3, 2, true, 0), cuboid("box", Vec3::new(0.2, 0.0, -0.2), Vec3::new(0.5, 0.4, 0.1), 0)];
        let mut meshes = vec![parallelogram("floor", Vec3::new(-2.0, 0.0, 2.0), Vec3::new(4.0, 0.0, 0.0), Vec3::new(0.0, 0.0, -4.0), 0)];
        let mut instancing = Instancing::default();
        let p = instancing.add_prototype("group", &group);
        for (scale, angle, at) in [(DVec3::ONE, 0.3, DVec3::new(-1.0, 0.02, 0.0)), (DVec3::new(1.3, 0.7, 1.1), -1.1, DVec3::new(0.7, 0.01, 0.4)), (DVec3::new(-1.0, 1.0, 1.0), 2.0, DVec3::new(0.1, 0.03, -1.2))] {
            let m = DAffine3::from_scale_rotation_translation(scale, DQuat::from_rotation_y(angle), at);
            instancing.place(&mut meshes, &group, p, m);
        }
        Scene {
            meshes,
            materials: vec![Material::Diffuse { albedo: Vec3::splat(0.5) }],
            lights: vec![Light::Point(PointLight { position: DVec3::new(0.0, 2.0, 0.0), intensity: DVec3::ONE })],
            camera: Camera { position: Vec3::new(0.0, 1.0, 3.0), target: Vec3::ZERO, up: Vec3::Y, vertical_fov: 0.8, width: 8, height: 8 },
            roughness_cutoff: 0.5,
            textures: Default::default(),
            instancing: Some(instancing),
        }
    }

    /// Through Embree instances and through the flattened copies, every ray hits the same
    /// triangle with the same barycentric weights bit for bit ([`refine_hit`] on the same
    /// world triangle; `t`, which the traversal computes in the instance's frame, close), and
    /// the hits name the copies in the scene's
    /// meshes.
    #[test]
    fn instanced_hits_equal_flattened_hits() {
        let scene = instanced_scene();
        scene.validate().expect("valid");
        let mut flat = scene.clone();
        flat.instancing = None;
        let device = Device::new().expect("device");
        let instanced = EmbreeCaster::new(&device, &PreparedScene::new(scene).expect("prepared")).expect("caster");
        let flattened = EmbreeCaster::new(&device, &PreparedScene::new(flat).expect("prepared")).expect("caster");
        assert_eq!((instanced.instance_count(), flattened.instance_count()), (3, 0));
        let mut rng = Rng::new(5, 0, 0, StreamDomain::Camera);
        let mut per_mesh = [0u32; 7];
        for _ in 0..1_000_000 {
            let o = Vec3::new(rng.next_f32() * 4.0 - 2.0, rng.next_f32() * 1.5 + 0.01, rng.next_f32() * 4.0 - 2.0);
            let d = Vec3::new(rng.next_f32() - 0.5, rng.next_f32() - 0.5, rng.next_f32() - 0.5).normalize();
            let (a, b) = (instanced.intersect(o, d, 0.0, f32::INFINITY), flattened.intersect(o, d, 0.0, f32::INFINITY));
            assert_eq!(a.map(|h| (h.mesh, h.triangle, h.b1.to_bits(), h.b2.to_bits())), b.map(|h| (h.mesh, h.triangle, h.b1.to_bits(), h.b2.to_bits())), "ray {o} {d}");
            if let (Some(a), Some(b)) = (a, b) {
                assert!((a.t - b.t).abs() <= 1e-3 * (1.0 + b.t), "ray {o} {d}: t {} and {}", a.t, b.t);
            }
            assert_eq!(instanced.occluded(o, d, 0.0, 1.0), flattened.occluded(o, d, 0.0, 1.0), "ray {o} {d}");
            if let Some(h) = a {
                per_mesh[h.mesh as usize] += 1;
            }
        }
        assert!(per_mesh.iter().all(|&n| n > 100), "every mesh, copies included, is hit: {per_mesh:?}");
        assert_eq!((instanced.errors(), flattened.errors()), (0, 0));
    }
}
