//! The prepared scene as the device reads it ([`crate::gpu::shaders::SCENE`], bind group 0 of
//! the camera and photon passes): per-mesh materials with the roughness cut-off resolved,
//! per-triangle vertices and normals, and the emitters of next-event estimation, every
//! value the core's rounded once to `f32`; and the order of each mesh's triangles in its
//! bottom-level acceleration structure.

use alloc::vec::Vec;

use glam::{DVec3, Vec3};

use crate::emit::emission::Light;
use crate::gpu::codes::{NORMAL_MAP_BUMP, NORMAL_MAP_NONE, NORMAL_MAP_TANGENT, NORMAL_MAP_TANGENT_UV, SCATTER_DIFFUSE, SCATTER_MIRROR, SCATTER_REFRACTIVE, SCATTER_THIN, TRIANGLE_NORMALS, TRIANGLE_SHADED};
use crate::gpu::layout::{SceneEmitter, SceneInfo, SceneMesh, SceneTriangle};
use crate::gpu::texture::{TextureWords, TooManyTexels, NO_TEXTURE};
use crate::base::morton::morton_code;
use crate::render::prepared_scene::PreparedScene;
use crate::render::ray_cast::RayHit;
use crate::render::scene::{BlendWeight, Handedness, NormalPerturbation, Opacity, Scattering, TriangleMesh};
use crate::propagate::shading_normal::ShadedTriangle;

/// The order in which a mesh's triangles go into its bottom-level acceleration structure:
/// triangle indices sorted by the 30-bit Morton code ([`morton_code`]) of their `f32`
/// centroids in the box of all the mesh's centroids (world space, metres), ties by index.
/// A spatially coherent primitive order keeps the BVH of a builder that does not sort the
/// primitives itself (lavapipe's) fast to traverse; a builder that does sort builds the
/// same BVH either way. Centroids with a non-finite coordinate land in cell 0 of that axis;
/// an index beyond the vertices counts as the origin (meshes are validated before upload).
pub fn morton_triangle_order(mesh: &TriangleMesh) -> Vec<u32> {
    let centroid = |t: &[u32; 3]| {
        let [a, b, c] = t.map(|i| mesh.positions.get(i as usize).copied().unwrap_or(Vec3::ZERO));
        (a + b + c) / 3.0
    };
    let centroids: Vec<Vec3> = mesh.indices.iter().map(centroid).collect();
    let lo = centroids.iter().copied().fold(Vec3::INFINITY, Vec3::min);
    let hi = centroids.iter().copied().fold(Vec3::NEG_INFINITY, Vec3::max);
    let inv_extent = crate::base::morton::inverse_extent(lo.to_array(), hi.to_array());
    let lo = if lo.is_finite() { lo } else { Vec3::ZERO };
    let mut keyed: Vec<(u32, u32)> = centroids.iter().zip(0u32..).map(|(c, i)| (morton_code(c.to_array(), lo.to_array(), inv_extent), i)).collect();
    keyed.sort_unstable();
    keyed.into_iter().map(|(_, i)| i).collect()
}

/// Why a scene's tables cannot be built.
#[derive(Clone, Copy, Debug, PartialEq, Eq, thiserror::Error)]
pub enum SceneTablesError {
    /// The scene has more triangles than a `u32` counts.
    #[error("the scene has more than 2^32 - 1 triangles")]
    TooManyTriangles,
    /// The texture words outgrow `u32` indices.
    #[error(transparent)]
    TooManyTexels(#[from] TooManyTexels),
}

/// The tables of bind group 0 (bindings 1 to 5 of `scene.wgsl`).
#[derive(Clone, Debug, PartialEq)]
pub struct SceneTables {
    /// Counts and the bounding sphere (uniform).
    pub info: SceneInfo,
    /// One record per mesh, then one per blend mesh for its other material
    /// ([`SceneMesh::blend_record`]).
    pub meshes: Vec<SceneMesh>,
    /// One record per triangle, mesh after mesh in the meshes' triangle order.
    pub triangles: Vec<SceneTriangle>,
    /// Delta lights in the core's emitter order, then the area emitters with positive
    /// power in [`PreparedScene::area_emitter_cdf`]'s order.
    pub emitters: Vec<SceneEmitter>,
    /// Per emitter record, its index into [`PreparedScene::emitters`].
    pub emitter_order: Vec<usize>,
    /// The textures and the meshes' texture coordinates
    /// ([`crate::gpu::texture::TextureWords::words`]; never empty: the decode tables).
    pub texture_words: Vec<u32>,
}

/// `kind`, `color` and `ior` of a mesh record scattering as `s`.
fn scatter_fields(s: Scattering) -> (u32, Vec3, f32) {
    match s {
        Scattering::Diffuse(c) => (SCATTER_DIFFUSE, c, 1.0),
        Scattering::Mirror(c) => (SCATTER_MIRROR, c, 1.0),
        Scattering::Refractive(ior, c) => (SCATTER_REFRACTIVE, c, ior),
        Scattering::Thin(ior, c) => (SCATTER_THIN, c, ior),
    }
}

impl SceneTables {
    /// The tables of `scene` whose mesh `m`'s bottom-level structure holds, at primitive
    /// `i`, the mesh's triangle `triangle_orders[m][i]` ([`morton_triangle_order`]).
    pub fn new(scene: &PreparedScene, triangle_orders: &[Vec<u32>]) -> Result<Self, SceneTablesError> {
        let s = scene.scene();
        let textures = TextureWords::new(scene)?;
        let emitter_records = crate::gpu::texture::emitter_records(scene);
        let f3 = |v: DVec3| v.as_vec3().to_array();
        let mut meshes = Vec::with_capacity(s.meshes.len());
        let mut triangles = Vec::new();
        for (mi, m) in s.meshes.iter().enumerate() {
            let (kind, color, ior) = scatter_fields(s.materials[m.material as usize].scattering(s.roughness_cutoff));
            let first_triangle = u32::try_from(triangles.len()).map_err(|_| SceneTablesError::TooManyTriangles)?;
            let maps = s.textures.maps(m.material);
            let (opacity_texture, opacity) = match maps.opacity {
                None => (NO_TEXTURE, 1.0),
                Some(Opacity::Constant(o)) => (NO_TEXTURE, o),
                Some(Opacity::Texture(id)) => (id, 1.0),
            };
            meshes.push(SceneMesh {
                first_triangle,
                triangle_count: m.indices.len() as u32,
                kind,
                emissive: m.emission.is_some() as u32,
                color: color.to_array(),
                ior,
                emission: m.emission.unwrap_or(Vec3::ZERO).to_array(),
                has_normals: m.normals.is_some() as u32,
                color_texture: maps.color.unwrap_or(NO_TEXTURE),
                opacity_texture,
                opacity,
                uv_first: textures.uv_first[mi],
                emission_texture: s.textures.emission_of(mi).unwrap_or(NO_TEXTURE),
                normal_texture: maps.normal.map_or(NO_TEXTURE, |n| n.texture()),
                normal_kind: match maps.normal {
                    None => NORMAL_MAP_NONE,
                    Some(NormalPerturbation::NormalMap { handedness: Handedness::RightHanded, .. }) => NORMAL_MAP_TANGENT,
                    Some(NormalPerturbation::NormalMap { handedness: Handedness::FollowTextureCoordinates, .. }) => NORMAL_MAP_TANGENT_UV,
                    Some(NormalPerturbation::BumpMap { .. }) => NORMAL_MAP_BUMP,
                },
                normal_scale: maps.normal.map_or(1.0, |n| n.scale()),
                blend_record: NO_TEXTURE,
                blend_weight: 0.0,
                blend_weight_texture: NO_TEXTURE,
                ..SceneMesh::default()
            });
            let order = triangle_orders.get(mi).map_or(&[][..], |o| &o[..]);
            for (ti, idx) in m.indices.iter().enumerate() {
                let p = scene.triangle(mi as u32, ti as u32);
                let probe = scene.surface(&RayHit { t: 1.0, mesh: mi as u32, triangle: ti as u32, b1: 0.0, b2: 0.0 });
                let normal = probe.geometric_normal;
                let (n, normals_usable) = match &m.normals {
                    Some(ns) => {
                        let n = idx.map(|i| ns[i as usize]);
                        let usable = ShadedTriangle { p, n: n.map(|v| v.as_dvec3()) }.barycentric_gradients().is_ok();
                        (n.map(|v| v.to_array()), usable)
                    }
                    None => ([f3(normal); 3], false),
                };
                let flags = if scene.has_shading_normals(&probe) { TRIANGLE_SHADED } else { 0 } | if normals_usable { TRIANGLE_NORMALS } else { 0 };
                triangles.push(SceneTriangle {
                    p0: f3(p[0]),
                    p1: f3(p[1]),
                    p2: f3(p[2]),
                    flags,
                    normal: f3(normal),
                    blas_triangle: order.get(ti).copied().unwrap_or(ti as u32),
                    n0: n[0],
                    n1: n[1],
                    n2: n[2],
                    ..SceneTriangle::default()
                });
            }
        }
        let emitters = scene.emitters();
        let powers = scene.emitter_powers();
        let (area, cdf) = scene.area_emitter_cdf();
        let total = cdf.last().copied().unwrap_or(0.0);
        let mut order: Vec<usize> = (0..emitters.len()).filter(|&i| !matches!(emitters[i], Light::Triangle(_) | Light::Quad(_))).collect();
        let delta_count = order.len();
        // Without positive total power the core picks no area emitter: none is listed.
        let area_count = if total > 0.0 { area.len() } else { 0 };
        order.extend(&area[..area_count]);
        let packed = order
            .iter()
            .enumerate()
            .map(|(slot, &i)| {
                let (cdf, probability) = if slot >= delta_count { ((cdf[slot - delta_count] / total) as f32, (powers[i] / total) as f32) } else { (0.0, 0.0) };
                let e = SceneEmitter { kind: emitters[i].kind_code(), cdf, probability, emission_record: emitter_records[i], ..SceneEmitter::default() };
                match emitters[i] {
                    Light::Point(l) => SceneEmitter { p0: f3(l.position), color: f3(l.intensity), ..e },
                    Light::Spot(l) => SceneEmitter {
                        falloff: l.falloff.code(),
                        cutoff: l.cutoff as f32,
                        beam_width: l.beam_width as f32,
                        p0: f3(l.position),
                        p1: f3(l.direction.normalize_or(DVec3::Z)),
                        color: f3(l.intensity),
                        ..e
                    },
                    Light::Directional(l) => SceneEmitter { p0: f3(l.direction.normalize_or(DVec3::Z)), color: f3(l.irradiance), ..e },
                    Light::Triangle(l) => SceneEmitter { p0: f3(l.p[0]), p1: f3(l.p[1]), p2: f3(l.p[2]), color: f3(l.radiance), ..e },
                    Light::Quad(l) => SceneEmitter { p0: f3(l.origin), p1: f3(l.edge_u), p2: f3(l.edge_v), color: f3(l.radiance), ..e },
                    Light::Environment(l) => SceneEmitter { color: f3(l.radiance), ..e },
                }
            })
            .collect();
        // A blend's other material: one record after the meshes per blend mesh.
        for (mi, m) in s.meshes.iter().enumerate() {
            let Some(b) = s.textures.maps(m.material).blend else { continue };
            let (kind, color, ior) = scatter_fields(s.materials[b.other as usize].scattering(s.roughness_cutoff));
            let record = u32::try_from(meshes.len()).map_err(|_| SceneTablesError::TooManyTriangles)?;
            let (weight, texture) = match b.weight {
                BlendWeight::Constant(w) => (w, NO_TEXTURE),
                BlendWeight::Texture(id) => (0.0, id),
            };
            meshes.push(SceneMesh { kind, color: color.to_array(), ior, color_texture: s.textures.maps(b.other).color.unwrap_or(NO_TEXTURE), ..meshes[mi] });
            meshes[mi].blend_record = record;
            meshes[mi].blend_weight = weight;
            meshes[mi].blend_weight_texture = texture;
        }
        let (centre, radius) = scene.bounding_sphere();
        let info = SceneInfo {
            mesh_count: s.meshes.len() as u32,
            delta_count: delta_count as u32,
            area_count: area_count as u32,
            has_masks: scene.has_masks() as u32,
            sphere_centre: f3(centre),
            sphere_radius: radius as f32,
        };
        Ok(Self { info, meshes, triangles, emitters: packed, emitter_order: order, texture_words: textures.words })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn triangles_go_in_morton_order() {
        // Triangles along x (same shape), listed in a shuffled order.
        let xs = [3.0f32, 0.0, 2.0, 5.0, 1.0, 4.0];
        let mut mesh = TriangleMesh { uvs: None, name: "row".into(), positions: Vec::new(), normals: None, indices: Vec::new(), material: 0, emission: None };
        for (t, x) in xs.iter().enumerate() {
            mesh.positions.extend([Vec3::new(*x, 0.0, 0.0), Vec3::new(x + 0.5, 0.0, 0.0), Vec3::new(*x, 0.5, 0.0)]);
            let i = 3 * t as u32;
            mesh.indices.push([i, i + 1, i + 2]);
        }
        let order = morton_triangle_order(&mesh);
        assert_eq!(order, [1, 4, 2, 0, 5, 3]);
    }
}
