//! The scene model every backend renders: triangle meshes with optional shading normals,
//! materials, lights and a pinhole camera, plus validation that turns bad input into a
//! clear error instead of a wrong image.
//!
//! Frames and units: world space is right-handed, lengths in scene units (metres in the
//! docs). Radiance is linear RGB in W/(m²·sr); light parameters follow
//! [`crate::emit::emission`].

use crate::base::aabb::Aabb;
use crate::emit::emission::{Light, LightError, TriangleLight};
use crate::render::environment::EnvironmentMap;
use crate::render::texture::{Texture, TextureId};
pub use crate::propagate::normal_map::Handedness;
use alloc::string::String;
use alloc::vec::Vec;
use glam::{DAffine3, DVec3, Vec2, Vec3};

/// Index into [`Scene::materials`].
pub type MaterialId = u32;

/// A surface material.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Material {
    /// Lambertian reflector of albedo `ρ ∈ [0, 1]³`.
    Diffuse {
        /// Albedo (linear RGB).
        albedo: Vec3,
    },
    /// Mirror or metal: specular reflection scaled by `reflectance`. With `roughness`
    /// at or above the scene's [`Scene::roughness_cutoff`] it is treated as diffuse with
    /// albedo `reflectance` (RTPM's rule).
    Conductor {
        /// Specular reflectance (linear RGB, ≤ 1).
        reflectance: Vec3,
        /// GGX-style roughness α (0 = perfect mirror).
        roughness: f32,
    },
    /// Smooth dielectric interface (glass, water) with exact Fresnel; the interior is on
    /// the side opposite the geometric normal. Rough ones at or above the cut-off are diffuse
    /// with albedo `transmittance`.
    Dielectric {
        /// Interior over exterior index of refraction.
        ior: f32,
        /// Multiplier of transmitted light (linear RGB, ≤ 1).
        transmittance: Vec3,
        /// Roughness α (0 = smooth).
        roughness: f32,
    },
    /// An infinitely thin dielectric sheet (Mitsuba's `thindielectric`: a window pane):
    /// reflects with the sheet's total reflectance `R' = 2R/(1 + R)` over its two faces and
    /// inter-reflections (`R` the interface's Fresnel reflectance), otherwise passes
    /// straight through, scaled by `transmittance`.
    ThinDielectric {
        /// Index of the sheet over that of its surroundings.
        ior: f32,
        /// Multiplier of transmitted light (linear RGB, ≤ 1).
        transmittance: Vec3,
    },
}

/// How a material scatters light, after the roughness rule.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Scattering {
    /// Lambertian with this albedo: photons are stored here, camera paths end here.
    Diffuse(Vec3),
    /// Perfect mirror with this reflectance.
    Mirror(Vec3),
    /// Smooth dielectric: relative IOR (inside/outside) and transmittance.
    Refractive(f32, Vec3),
    /// Thin dielectric sheet: relative IOR and transmittance ([`Material::ThinDielectric`]).
    Thin(f32, Vec3),
}

/// The reflectance `R' = 2R/(1 + R)` of a thin dielectric sheet of relative index `ior` for
/// light arriving at `cos_i` to its normal (either side): the interface's Fresnel `R` summed
/// over the sheet's two faces and its inter-reflections (Mitsuba's `thindielectric`).
#[inline]
pub fn thin_sheet_reflectance(cos_i: f64, ior: f64) -> f64 {
    let r = crate::propagate::fresnel::dielectric_reflectance(-cos_i.abs(), ior);
    if r < 1.0 { 2.0 * r / (1.0 + r) } else { 1.0 }
}

impl Material {
    /// The scattering behaviour under roughness cut-off `cutoff`.
    pub fn scattering(&self, cutoff: f32) -> Scattering {
        match *self {
            Material::Diffuse { albedo } => Scattering::Diffuse(albedo),
            Material::Conductor { reflectance, roughness } => {
                if roughness >= cutoff { Scattering::Diffuse(reflectance) } else { Scattering::Mirror(reflectance) }
            }
            Material::Dielectric { ior, transmittance, roughness } => {
                if roughness >= cutoff { Scattering::Diffuse(transmittance) } else { Scattering::Refractive(ior, transmittance) }
            }
            Material::ThinDielectric { ior, transmittance } => Scattering::Thin(ior, transmittance),
        }
    }
}

/// A triangle mesh in world space.
#[derive(Clone, Debug, PartialEq)]
pub struct TriangleMesh {
    /// Name used in error messages (file or element name).
    pub name: String,
    /// Vertex positions (metres, world space).
    pub positions: Vec<Vec3>,
    /// Optional per-vertex shading normals (interpolated; their derivatives focus caustics).
    pub normals: Option<Vec<Vec3>>,
    /// Optional per-vertex texture coordinates (Mitsuba's convention, [`crate::render::texture`]);
    /// without them a hit's texture coordinates are its barycentric weights `(b1, b2)`.
    pub uvs: Option<Vec<Vec2>>,
    /// Triangles as vertex indices; winding defines the geometric normal
    /// `(p1 − p0) × (p2 − p0)`.
    pub indices: Vec<[u32; 3]>,
    /// Material of every triangle.
    pub material: MaterialId,
    /// One-sided emitted radiance (W/(m²·sr)) on the geometric-normal side, making every
    /// triangle an area light.
    pub emission: Option<Vec3>,
}

/// A pinhole camera.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Camera {
    /// Eye position (metres).
    pub position: Vec3,
    /// Point looked at.
    pub target: Vec3,
    /// Approximate up direction.
    pub up: Vec3,
    /// Vertical field of view (radians, in `(0, π)`).
    pub vertical_fov: f32,
    /// Image width in pixels.
    pub width: u32,
    /// Image height in pixels.
    pub height: u32,
}

/// An orthonormal camera basis: `forward` into the image, `right` to the image's right,
/// `up` to its top.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CameraFrame {
    /// Unit viewing direction.
    pub forward: Vec3,
    /// Unit right vector.
    pub right: Vec3,
    /// Unit up vector.
    pub up: Vec3,
    /// `tan(fov/2)`.
    pub tan_half_fov: f32,
    /// Width over height.
    pub aspect: f32,
}

impl Camera {
    /// The camera basis, or an error for a degenerate camera.
    pub fn frame(&self) -> Result<CameraFrame, SceneError> {
        let bad = |why: &'static str| Err(SceneError::DegenerateCamera(why));
        if !(self.position.is_finite() && self.target.is_finite() && self.up.is_finite() && self.vertical_fov.is_finite()) {
            return bad("non-finite position, target, up or field of view");
        }
        if self.width == 0 || self.height == 0 {
            return bad("zero image size");
        }
        if !(self.vertical_fov > 0.0 && self.vertical_fov < core::f32::consts::PI) {
            return bad("vertical field of view outside (0, 180) degrees");
        }
        let forward = (self.target - self.position).normalize_or_zero();
        if forward == Vec3::ZERO {
            return bad("target equals position");
        }
        let right = forward.cross(self.up).normalize_or_zero();
        if right == Vec3::ZERO {
            return bad("up is parallel to the viewing direction");
        }
        let up = right.cross(forward);
        Ok(CameraFrame { forward, right, up, tan_half_fov: libm::tanf(0.5 * self.vertical_fov), aspect: self.width as f32 / self.height as f32 })
    }
}

impl CameraFrame {
    /// Unit direction through film position `(x, y)` in pixels (continuous; `(0, 0)` is the
    /// top-left corner) of a `width × height` image.
    pub fn direction(&self, x: f32, y: f32, width: u32, height: u32) -> Vec3 {
        let sx = (2.0 * x / width as f32 - 1.0) * self.tan_half_fov * self.aspect;
        let sy = (1.0 - 2.0 * y / height as f32) * self.tan_half_fov;
        (self.forward + self.right * sx + self.up * sy).normalize_or(self.forward)
    }
}

/// Why a scene cannot be rendered. Every variant names the offending item.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum SceneError {
    /// A vertex position or normal is NaN or infinite.
    #[error("mesh '{mesh}': vertex {vertex} has a non-finite {what}")]
    NonFiniteVertex {
        /// Mesh name.
        mesh: String,
        /// Vertex index.
        vertex: usize,
        /// "position", "normal" or "texture coordinate".
        what: &'static str,
    },
    /// A triangle refers to a vertex that does not exist.
    #[error("mesh '{mesh}': triangle {triangle} refers to vertex {index}, but the mesh has {count} vertices")]
    IndexOutOfRange {
        /// Mesh name.
        mesh: String,
        /// Triangle index.
        triangle: usize,
        /// Offending vertex index.
        index: u32,
        /// Number of vertices.
        count: usize,
    },
    /// Normals given but not one per vertex.
    #[error("mesh '{mesh}': {normals} normals for {positions} vertices")]
    NormalCount {
        /// Mesh name.
        mesh: String,
        /// Normals given.
        normals: usize,
        /// Vertices.
        positions: usize,
    },
    /// A mesh uses a material that does not exist.
    #[error("mesh '{mesh}': material {material} does not exist ({count} materials)")]
    MissingMaterial {
        /// Mesh name.
        mesh: String,
        /// Material index.
        material: MaterialId,
        /// Number of materials.
        count: usize,
    },
    /// A material parameter is out of range.
    #[error("material {index}: {why}")]
    BadMaterial {
        /// Material index.
        index: usize,
        /// What is wrong.
        why: &'static str,
    },
    /// An emissive mesh emits nothing it could: zero total area or bad radiance.
    #[error("mesh '{mesh}': emitter {why}")]
    BadEmitter {
        /// Mesh name.
        mesh: String,
        /// What is wrong.
        why: &'static str,
    },
    /// An analytic light is invalid.
    #[error("light {index}: {source}")]
    BadLight {
        /// Light index in [`Scene::lights`].
        index: usize,
        /// The problem.
        source: LightError,
    },
    /// Texture coordinates given but not one per vertex.
    #[error("mesh '{mesh}': {uvs} texture coordinates for {positions} vertices")]
    UvCount {
        /// Mesh name.
        mesh: String,
        /// Texture coordinates given.
        uvs: usize,
        /// Vertices.
        positions: usize,
    },
    /// A texture is malformed.
    #[error("texture {index}: {why}")]
    BadTexture {
        /// Index in [`SceneTextures::textures`].
        index: usize,
        /// What is wrong.
        why: &'static str,
    },
    /// The scene has no light at all.
    #[error("the scene has no light (no analytic light and no emissive mesh)")]
    NoLights,
    /// More than one environment light, or an environment map without one.
    #[error("environment: {0}")]
    Environment(&'static str),
    /// The environment map cannot be used.
    #[error(transparent)]
    EnvironmentMap(#[from] crate::render::environment::EnvironmentError),
    /// The scene has no geometry.
    #[error("the scene has no geometry")]
    Empty,
    /// The camera cannot form an image.
    #[error("degenerate camera: {0}")]
    DegenerateCamera(&'static str),
    /// [`Scene::roughness_cutoff`] is NaN, infinite or negative (a NaN cut-off would
    /// silently make every rough material specular).
    #[error("roughness cut-off {0} is not a finite non-negative GGX alpha")]
    BadRoughnessCutoff(f32),
    /// [`Scene::instancing`] does not describe the scene's meshes.
    #[error("instance {instance}: {why}")]
    BadInstance {
        /// Index in [`Instancing::instances`].
        instance: usize,
        /// What is wrong (names the mesh or prototype).
        why: String,
    },
}

/// A complete scene.
#[derive(Clone, Debug, PartialEq)]
pub struct Scene {
    /// Geometry.
    pub meshes: Vec<TriangleMesh>,
    /// Materials referenced by [`TriangleMesh::material`].
    pub materials: Vec<Material>,
    /// Analytic lights (point, spot, directional, triangle/quad emitters).
    pub lights: Vec<Light>,
    /// The camera.
    pub camera: Camera,
    /// GGX `alpha` at and above which glossy materials count as diffuse (RTPM's rule is
    /// linear roughness `sqrt(alpha)` above 0.5; the Mitsuba loader uses `alpha` 0.25).
    pub roughness_cutoff: f32,
    /// Textures and the materials that read them (none by default).
    pub textures: SceneTextures,
    /// Which meshes are placed copies of shared geometry, for backends whose acceleration
    /// structures can instance it (`None`: every mesh stands alone). [`Scene::meshes`]
    /// stays the whole truth for shading either way: it holds every copy in world space.
    pub instancing: Option<Instancing>,
}

/// Shared geometry placed several times in a scene (Mitsuba's `shapegroup` + `instance`,
/// a glTF mesh that several nodes use): the groups of meshes in their own space and where
/// each copy is. It only lets a backend build one acceleration structure per group and
/// place it by a transform instead of holding every copy; what a ray hits is reported,
/// and shaded, as the copy in [`Scene::meshes`] (world-space positions, normals
/// transformed by the inverse transpose, so shading normals and differentials see the
/// instance's transform).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Instancing {
    /// The shared groups, indexed by [`Instance::prototype`].
    pub prototypes: Vec<Prototype>,
    /// The placed copies.
    pub instances: Vec<Instance>,
}

/// A group of meshes in the group's own (object) space.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Prototype {
    /// Name used in error messages (the group's id or the glTF mesh).
    pub name: String,
    /// The group's meshes.
    pub meshes: Vec<PrototypeMesh>,
}

/// One mesh of a [`Prototype`]: positions in object space (metres before the instance's
/// transform) and triangles, numbered and wound as in every copy of it.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct PrototypeMesh {
    /// Vertex positions (object space).
    pub positions: Vec<Vec3>,
    /// Triangles as vertex indices, equal to those of each copy in [`Scene::meshes`].
    pub indices: Vec<[u32; 3]>,
}

/// One placed copy of a [`Prototype`].
#[derive(Clone, Debug, PartialEq)]
pub struct Instance {
    /// Index in [`Instancing::prototypes`].
    pub prototype: u32,
    /// Object space to world space (an invertible affine map; metres).
    pub to_world: DAffine3,
    /// Per mesh of the prototype, in its order: the index in [`Scene::meshes`] of its copy
    /// (the prototype mesh's positions under `to_world`, rounded to `f32`).
    pub meshes: Vec<u32>,
}

impl Instancing {
    /// Per mesh of a scene with `mesh_count` meshes: `(instance, prototype mesh)` of the
    /// copy it is, or `None` for a mesh that a backend keeps on its own. Only copies of
    /// prototypes placed at least twice are listed: a prototype placed once gains nothing
    /// from a second level of acceleration structure, it only costs traversal. Indices out
    /// of range are left out ([`Scene::validate`] rejects them).
    pub fn copies(&self, mesh_count: usize) -> Vec<Option<(u32, u32)>> {
        let mut uses = alloc::vec![0u32; self.prototypes.len()];
        for inst in &self.instances {
            if let Some(u) = uses.get_mut(inst.prototype as usize) {
                *u += 1;
            }
        }
        let mut out = alloc::vec![None; mesh_count];
        for (i, inst) in self.instances.iter().enumerate() {
            if uses.get(inst.prototype as usize).is_none_or(|&u| u < 2) {
                continue;
            }
            for (k, &m) in inst.meshes.iter().enumerate() {
                if let Some(slot) = out.get_mut(m as usize) {
                    *slot = Some((i as u32, k as u32));
                }
            }
        }
        out
    }

    /// This without the prototypes placed fewer than twice (and their instances), or
    /// `None` if no prototype is placed twice: for loaders that record every placement
    /// of a mesh, not only the shared ones.
    pub fn shared_only(mut self) -> Option<Self> {
        let mut uses = alloc::vec![0u32; self.prototypes.len()];
        for inst in &self.instances {
            if let Some(u) = uses.get_mut(inst.prototype as usize) {
                *u += 1;
            }
        }
        let mut new_index = alloc::vec![u32::MAX; self.prototypes.len()];
        let mut kept = 0u32;
        for (p, &u) in uses.iter().enumerate() {
            if u >= 2 {
                new_index[p] = kept;
                kept += 1;
            }
        }
        let mut p = 0;
        self.prototypes.retain(|_| {
            p += 1;
            uses[p - 1] >= 2
        });
        self.instances.retain_mut(|inst| match new_index.get(inst.prototype as usize) {
            Some(&n) if n != u32::MAX => {
                inst.prototype = n;
                true
            }
            _ => false,
        });
        (!self.instances.is_empty()).then_some(self)
    }

    /// Adds `group` (meshes in object space) as a prototype named `name`; returns its
    /// index for [`Instancing::place`].
    pub fn add_prototype(&mut self, name: &str, group: &[TriangleMesh]) -> u32 {
        let meshes = group.iter().map(|m| PrototypeMesh { positions: m.positions.clone(), indices: m.indices.clone() }).collect();
        self.prototypes.push(Prototype { name: name.into(), meshes });
        (self.prototypes.len() - 1) as u32
    }

    /// Appends to `meshes` a copy of each mesh of `group` (the meshes prototype
    /// `prototype` was made from, [`Instancing::add_prototype`]) placed by `to_world`, and
    /// records the copies as an instance: positions transformed in `f64` and rounded to
    /// `f32`, normals by the inverse transpose and renormalised, the rest as in `group`.
    pub fn place(&mut self, meshes: &mut Vec<TriangleMesh>, group: &[TriangleMesh], prototype: u32, to_world: DAffine3) {
        let normal_matrix = to_world.matrix3.inverse().transpose();
        let first = meshes.len() as u32;
        meshes.extend(group.iter().enumerate().map(|(k, m)| TriangleMesh {
            name: alloc::format!("{} (instance {}, mesh {k})", m.name, self.instances.len()),
            positions: m.positions.iter().map(|p| to_world.transform_point3(p.as_dvec3()).as_vec3()).collect(),
            normals: m.normals.as_ref().map(|ns| ns.iter().map(|n| (normal_matrix * n.as_dvec3()).normalize_or(DVec3::Y).as_vec3()).collect()),
            ..m.clone()
        }));
        self.instances.push(Instance { prototype, to_world, meshes: (first..first + group.len() as u32).collect() });
    }

    /// Checks that this describes `meshes`: every index in range, each mesh the copy of at
    /// most one prototype mesh, transforms finite and invertible, and every copy the
    /// prototype mesh's triangles with its positions under the transform (within
    /// `1e-5 (1 + |p|)` metres: the copies are rounded to `f32`).
    pub fn validate(&self, meshes: &[TriangleMesh]) -> Result<(), SceneError> {
        let mut claimed = alloc::vec![false; meshes.len()];
        for (instance, inst) in self.instances.iter().enumerate() {
            let bad = |why: String| Err(SceneError::BadInstance { instance, why });
            let Some(proto) = self.prototypes.get(inst.prototype as usize) else {
                return bad(alloc::format!("prototype {} does not exist ({} prototypes)", inst.prototype, self.prototypes.len()));
            };
            let det = inst.to_world.matrix3.determinant();
            if !(inst.to_world.is_finite() && det.is_finite() && det.abs() > 1e-300 && inst.to_world.inverse().is_finite()) {
                return bad(alloc::format!("its transform of prototype '{}' is not finite or not invertible", proto.name));
            }
            if inst.meshes.len() != proto.meshes.len() {
                return bad(alloc::format!("{} meshes for the {} of prototype '{}'", inst.meshes.len(), proto.meshes.len(), proto.name));
            }
            for (pm, &mi) in proto.meshes.iter().zip(&inst.meshes) {
                let Some(m) = meshes.get(mi as usize) else {
                    return bad(alloc::format!("mesh {mi} does not exist ({} meshes)", meshes.len()));
                };
                if core::mem::replace(&mut claimed[mi as usize], true) {
                    return bad(alloc::format!("mesh '{}' is already a copy of another instance", m.name));
                }
                if m.indices != pm.indices || m.positions.len() != pm.positions.len() {
                    return bad(alloc::format!("mesh '{}' does not have the triangles and vertex count of prototype '{}'", m.name, proto.name));
                }
                let placed = pm.positions.iter().zip(&m.positions).position(|(p, w)| {
                    let w = w.as_dvec3();
                    !((inst.to_world.transform_point3(p.as_dvec3()) - w).abs().max_element() <= 1e-5 * (1.0 + w.abs().max_element()))
                });
                if let Some(v) = placed {
                    return bad(alloc::format!("vertex {v} of mesh '{}' is not prototype '{}' under the instance's transform", m.name, proto.name));
                }
            }
        }
        Ok(())
    }
}

/// A material's opacity: the probability that a ray hitting it stops there (Mitsuba's
/// `mask`); a ray that does not stop passes through unchanged.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Opacity {
    /// The same everywhere, in `[0, 1]`.
    Constant(f32),
    /// A texture's single value ([`Texture::eval_1`]), clamped to `[0, 1]`.
    Texture(TextureId),
}

/// The textures a material reads.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct MaterialMaps {
    /// Multiplies the material's colour (diffuse albedo, conductor reflectance, dielectric
    /// transmittance) at every hit.
    pub color: Option<TextureId>,
    /// Makes the material a mask; `None` is opaque.
    pub opacity: Option<Opacity>,
    /// Perturbs the material's shading normals; `None` keeps them.
    pub normal: Option<NormalPerturbation>,
    /// Makes the material a blend (Mitsuba's `blendbsdf`): at each hit it scatters as
    /// [`Blend::other`] with probability [`Blend::weight`], else as itself.
    pub blend: Option<Blend>,
}

/// The second material of a blend and its weight ([`MaterialMaps::blend`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Blend {
    /// The material a hit scatters as with probability `weight`: its scattering and its
    /// colour texture (its own maps may not hold an opacity, a normal map or a blend).
    pub other: MaterialId,
    /// The probability of `other`.
    pub weight: BlendWeight,
}

/// A blend's weight.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum BlendWeight {
    /// The same everywhere, in `[0, 1]`.
    Constant(f32),
    /// A texture's single value ([`Texture::eval_1`]), clamped to `[0, 1]` (NaN: 0).
    Texture(TextureId),
}

/// A texture that perturbs a material's shading normals
/// ([`crate::propagate::normal_map`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum NormalPerturbation {
    /// A tangent-space normal map: the texture's RGB value `c` is the normal `2c − 1` in the
    /// frame of the shading normal and `∂p/∂u` (Mitsuba 3's `normalmap`, glTF's
    /// `normalTexture`).
    NormalMap {
        /// The map (read as stored; normal maps are loaded `raw`).
        texture: TextureId,
        /// Multiplies the map's x and y components (glTF's `scale`; 1 for Mitsuba).
        scale: f32,
        /// How the frame's second tangent is oriented.
        handedness: Handedness,
    },
    /// A height field: the texture's single value times `scale` displaces the surface
    /// along its shading normal (Mitsuba 3's `bumpmap`).
    BumpMap {
        /// The height texture (a bitmap; its gradient is [`Texture::eval_1_grad`]).
        texture: TextureId,
        /// Height per unit of the texture's value (metres, with `uv` in texture units).
        scale: f32,
    },
}

impl NormalPerturbation {
    /// The texture it reads.
    pub fn texture(&self) -> TextureId {
        match *self {
            NormalPerturbation::NormalMap { texture, .. } | NormalPerturbation::BumpMap { texture, .. } => texture,
        }
    }

    /// Its scale factor.
    pub fn scale(&self) -> f32 {
        match *self {
            NormalPerturbation::NormalMap { scale, .. } | NormalPerturbation::BumpMap { scale, .. } => scale,
        }
    }
}

/// A scene's textures and, per material, the textures it reads.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct SceneTextures {
    /// The textures, indexed by [`TextureId`].
    pub textures: Vec<Texture>,
    /// Per material (indexed like [`Scene::materials`]; a shorter list means no maps for
    /// the rest).
    pub maps: Vec<MaterialMaps>,
    /// Per mesh (indexed like [`Scene::meshes`]; a shorter list means none for the rest):
    /// the texture multiplying the mesh's emitted radiance ([`TriangleMesh::emission`]) at
    /// each point (Mitsuba's textured `area` emitter).
    pub emission: Vec<Option<TextureId>>,
    /// The map of the scene's environment light ([`Light::Environment`]), if it has one
    /// (Mitsuba's `envmap`); the light's `mean` must be [`EnvironmentMap::mean`] of it.
    pub environment: Option<EnvironmentMap>,
}

/// What an emitter triangle of a mesh with an emission texture reads: the radiance of its
/// [`TriangleLight`] is the mesh's radiance times the texture's mean over the triangle
/// (`mean`, per channel, [`EMISSION_QUADRATURE`] points), which sets its power; the
/// radiance at a point is the mesh's radiance times the texture there, i.e. the
/// triangle's radiance times [`EmitterTexture::factor`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct EmitterTexture {
    /// The texture.
    pub texture: TextureId,
    /// Texture coordinates of the triangle's three vertices (the mesh's, or Mitsuba's
    /// `(0, 0), (1, 0), (0, 1)` without them).
    pub uvs: [Vec2; 3],
    /// `1 / mean` per channel (0 where the mean is 0).
    pub inv_mean: Vec3,
}

/// Points per triangle of the emission texture's mean ([`EmitterTexture`]): the centroids
/// of the triangle cut into `8²` equal triangles.
pub const EMISSION_QUADRATURE: u32 = 8;

impl EmitterTexture {
    /// The texture coordinates at barycentric weights `(b1, b2)` of vertices 1 and 2.
    #[inline]
    pub fn uv(&self, b1: f32, b2: f32) -> Vec2 {
        self.uvs[0] * (1.0 - b1 - b2) + self.uvs[1] * b1 + self.uvs[2] * b2
    }

    /// The texture over its triangle mean at barycentric weights `(b1, b2)` (per channel,
    /// non-negative): what the triangle's radiance is multiplied by there.
    #[inline]
    pub fn factor(&self, textures: &[Texture], b1: f32, b2: f32) -> Vec3 {
        textures[self.texture as usize].eval(self.uv(b1, b2)).max(Vec3::ZERO) * self.inv_mean
    }
}

impl SceneTextures {
    /// The maps of material `m`.
    #[inline]
    pub fn maps(&self, m: MaterialId) -> MaterialMaps {
        self.maps.get(m as usize).copied().unwrap_or_default()
    }

    /// Whether some material reads a texture or has an opacity, or some mesh emits through
    /// a texture.
    pub fn any(&self) -> bool {
        self.maps.iter().any(|m| m.color.is_some() || m.opacity.is_some() || m.normal.is_some() || m.blend.is_some()) || self.emission.iter().any(Option::is_some)
    }

    /// The emission texture of mesh `m`.
    #[inline]
    pub fn emission_of(&self, m: usize) -> Option<TextureId> {
        self.emission.get(m).copied().flatten()
    }

    /// Whether some material is a mask.
    pub fn any_opacity(&self) -> bool {
        self.maps.iter().any(|m| m.opacity.is_some())
    }
}

fn finite_rgb_in(v: Vec3, lo: f32, hi: f32) -> bool {
    v.is_finite() && v.min_element() >= lo && v.max_element() <= hi
}

impl Scene {
    /// Checks the whole scene; the first problem found is returned.
    pub fn validate(&self) -> Result<(), SceneError> {
        if self.meshes.iter().all(|m| m.indices.is_empty()) {
            return Err(SceneError::Empty);
        }
        if !(self.roughness_cutoff.is_finite() && self.roughness_cutoff >= 0.0) {
            return Err(SceneError::BadRoughnessCutoff(self.roughness_cutoff));
        }
        for (index, m) in self.materials.iter().enumerate() {
            let why = match *m {
                Material::Diffuse { albedo } if !finite_rgb_in(albedo, 0.0, 1.0) => Some("diffuse albedo outside [0, 1]"),
                Material::Conductor { reflectance, roughness } if !(finite_rgb_in(reflectance, 0.0, 1.0) && roughness >= 0.0 && roughness.is_finite()) => {
                    Some("conductor reflectance outside [0, 1] or roughness negative or not finite")
                }
                Material::Dielectric { ior, transmittance, roughness } if !(ior > 0.0 && ior.is_finite() && finite_rgb_in(transmittance, 0.0, 1.0) && roughness >= 0.0 && roughness.is_finite()) => {
                    Some("dielectric IOR not finite and positive, transmittance outside [0, 1] or roughness negative or not finite")
                }
                Material::ThinDielectric { ior, transmittance } if !(ior > 0.0 && ior.is_finite() && finite_rgb_in(transmittance, 0.0, 1.0)) => {
                    Some("thin dielectric IOR not finite and positive or transmittance outside [0, 1]")
                }
                _ => None,
            };
            if let Some(why) = why {
                return Err(SceneError::BadMaterial { index, why });
            }
        }
        if let Some(index) = self.textures.textures.iter().position(|t| !t.is_valid()) {
            return Err(SceneError::BadTexture { index, why: "its size does not match its texels, or a value or its to_uv is not finite" });
        }
        let count = self.textures.textures.len();
        for (index, maps) in self.textures.maps.iter().enumerate() {
            let bad_id = |id: TextureId| id as usize >= count;
            let why = if index >= self.materials.len() {
                Some("maps given for a material that does not exist")
            } else if maps.color.is_some_and(bad_id) || matches!(maps.opacity, Some(Opacity::Texture(id)) if bad_id(id)) || maps.normal.is_some_and(|n| bad_id(n.texture())) {
                Some("refers to a texture that does not exist")
            } else if maps.normal.is_some_and(|n| !n.scale().is_finite()) {
                Some("a normal or bump map's scale is not finite")
            } else if let Some(b) = maps.blend {
                let other = self.textures.maps(b.other);
                if b.other as usize >= self.materials.len() || b.other as usize == index {
                    Some("a blend's other material does not exist or is the material itself")
                } else if matches!(b.weight, BlendWeight::Texture(id) if bad_id(id)) {
                    Some("refers to a texture that does not exist")
                } else if matches!(b.weight, BlendWeight::Constant(w) if !(0.0..=1.0).contains(&w)) {
                    Some("a blend's weight is outside [0, 1]")
                } else if other.opacity.is_some() || other.normal.is_some() || other.blend.is_some() {
                    Some("a blend's other material has an opacity, a normal map or a blend of its own")
                } else {
                    None
                }
            } else if matches!(maps.opacity, Some(Opacity::Constant(o)) if !(0.0..=1.0).contains(&o)) {
                Some("opacity outside [0, 1]")
            } else {
                None
            };
            if let Some(why) = why {
                return Err(SceneError::BadMaterial { index, why });
            }
        }
        for (index, t) in self.textures.emission.iter().enumerate() {
            if t.is_some() && index >= self.meshes.len() {
                return Err(SceneError::BadTexture { index: t.unwrap_or(0) as usize, why: "an emission texture is given for a mesh that does not exist" });
            }
            if t.is_some_and(|id| id as usize >= count) {
                return Err(SceneError::BadTexture { index: t.unwrap_or(0) as usize, why: "a mesh's emission refers to a texture that does not exist" });
            }
        }
        for m in &self.meshes {
            if let Some(uvs) = &m.uvs {
                if uvs.len() != m.positions.len() {
                    return Err(SceneError::UvCount { mesh: m.name.clone(), uvs: uvs.len(), positions: m.positions.len() });
                }
                if let Some(vertex) = uvs.iter().position(|p| !p.is_finite()) {
                    return Err(SceneError::NonFiniteVertex { mesh: m.name.clone(), vertex, what: "texture coordinate" });
                }
            }
            if let Some(vertex) = m.positions.iter().position(|p| !p.is_finite()) {
                return Err(SceneError::NonFiniteVertex { mesh: m.name.clone(), vertex, what: "position" });
            }
            if let Some(n) = &m.normals {
                if n.len() != m.positions.len() {
                    return Err(SceneError::NormalCount { mesh: m.name.clone(), normals: n.len(), positions: m.positions.len() });
                }
                if let Some(vertex) = n.iter().position(|p| !p.is_finite()) {
                    return Err(SceneError::NonFiniteVertex { mesh: m.name.clone(), vertex, what: "normal" });
                }
            }
            for (triangle, t) in m.indices.iter().enumerate() {
                if let Some(&index) = t.iter().find(|&&i| i as usize >= m.positions.len()) {
                    return Err(SceneError::IndexOutOfRange { mesh: m.name.clone(), triangle, index, count: m.positions.len() });
                }
            }
            if m.material as usize >= self.materials.len() {
                return Err(SceneError::MissingMaterial { mesh: m.name.clone(), material: m.material, count: self.materials.len() });
            }
            if let Some(e) = m.emission {
                if !(e.is_finite() && e.min_element() >= 0.0) {
                    return Err(SceneError::BadEmitter { mesh: m.name.clone(), why: "radiance is negative or not finite" });
                }
                if e.max_element() > 0.0 && !(m.area() > 0.0) {
                    return Err(SceneError::BadEmitter { mesh: m.name.clone(), why: "has zero area" });
                }
            }
        }
        let radius = self.bounding_sphere().1;
        for (index, l) in self.lights.iter().enumerate() {
            l.validate(radius).map_err(|source| SceneError::BadLight { index, source })?;
        }
        let environments = self.lights.iter().filter(|l| matches!(l, Light::Environment(_))).count();
        if environments > 1 {
            return Err(SceneError::Environment("a scene has at most one environment light"));
        }
        if let Some(map) = &self.textures.environment {
            if environments == 0 {
                return Err(SceneError::Environment("an environment map without an environment light"));
            }
            map.check()?;
        }
        if self.emitters().is_empty() {
            return Err(SceneError::NoLights);
        }
        self.camera.frame()?;
        if let Some(instancing) = &self.instancing {
            instancing.validate(&self.meshes)?;
        }
        Ok(())
    }

    /// Bounds of all mesh vertices.
    pub fn bounds(&self) -> Aabb {
        Aabb::from_points(self.meshes.iter().flat_map(|m| m.positions.iter().map(|p| p.as_dvec3())))
    }

    /// Centre and radius of the sphere around [`Scene::bounds`] (the aperture of
    /// directional lights). Radius at least 1e-6.
    pub fn bounding_sphere(&self) -> (DVec3, f64) {
        let b = self.bounds();
        if b.is_empty() {
            return (DVec3::ZERO, 1e-6);
        }
        (b.centre(), (0.5 * b.diagonal()).max(1e-6))
    }

    /// Every emitter: the analytic lights followed by one [`TriangleLight`] per emissive
    /// triangle with non-zero area and radiance.
    pub fn emitters(&self) -> Vec<Light> {
        self.emitters_with_textures().0
    }

    /// [`Scene::emitters`], and per emitter the [`EmitterTexture`] of a triangle of a mesh
    /// with an emission texture (its radiance then holds the texture's mean over the
    /// triangle; a triangle over which the mean is zero emits nothing).
    pub fn emitters_with_textures(&self) -> (Vec<Light>, Vec<Option<EmitterTexture>>) {
        let mut out: Vec<Light> = self.lights.clone();
        let mut textures = alloc::vec![None; out.len()];
        for (mi, m) in self.meshes.iter().enumerate() {
            let Some(e) = m.emission else { continue };
            if !(e.max_element() > 0.0) {
                continue;
            }
            let texture = self.textures.emission_of(mi).filter(|&id| (id as usize) < self.textures.textures.len());
            for t in &m.indices {
                let p = t.map(|i| m.positions.get(i as usize).copied().unwrap_or(Vec3::ZERO).as_dvec3());
                let (radiance, tex) = match texture {
                    None => (e, None),
                    Some(id) => {
                        let uvs = match &m.uvs {
                            Some(uv) => t.map(|i| uv.get(i as usize).copied().unwrap_or(Vec2::ZERO)),
                            None => [Vec2::ZERO, Vec2::X, Vec2::Y],
                        };
                        let mut tex = EmitterTexture { texture: id, uvs, inv_mean: Vec3::ONE };
                        let mean = emission_mean(&self.textures.textures[id as usize], &tex);
                        tex.inv_mean = Vec3::select(mean.cmpgt(Vec3::ZERO), mean.recip(), Vec3::ZERO);
                        (e * mean, Some(tex))
                    }
                };
                let l = Light::Triangle(TriangleLight { p, radiance: radiance.as_dvec3() });
                if l.area() > 0.0 && radiance.max_element() > 0.0 {
                    out.push(l);
                    textures.push(tex);
                }
            }
        }
        (out, textures)
    }
}

/// The mean of `texture` (non-negative, per channel) over the triangle of `tex` at the
/// [`EMISSION_QUADRATURE`]² sub-triangle centroids.
fn emission_mean(texture: &Texture, tex: &EmitterTexture) -> Vec3 {
    let n = EMISSION_QUADRATURE;
    let inv = 1.0 / n as f32;
    let mut sum = Vec3::ZERO;
    for i in 0..n {
        for j in 0..n - i {
            let (fi, fj) = (i as f32, j as f32);
            sum += texture.eval(tex.uv((fi + 1.0 / 3.0) * inv, (fj + 1.0 / 3.0) * inv)).max(Vec3::ZERO);
            if i + j + 1 < n {
                sum += texture.eval(tex.uv((fi + 2.0 / 3.0) * inv, (fj + 2.0 / 3.0) * inv)).max(Vec3::ZERO);
            }
        }
    }
    sum / (n * n) as f32
}

impl TriangleMesh {
    /// Total area of the triangles (m², computed in `f64`); indices out of range count as
    /// the origin, so this never panics on an unvalidated mesh.
    pub fn area(&self) -> f64 {
        self.indices
            .iter()
            .map(|t| {
                let p = t.map(|i| self.positions.get(i as usize).copied().unwrap_or(Vec3::ZERO).as_dvec3());
                0.5 * (p[1] - p[0]).cross(p[2] - p[0]).length()
            })
            .sum()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn roughness_cutoff_is_inclusive() {
        let metal = |roughness| Material::Conductor { reflectance: Vec3::splat(0.5), roughness };
        assert_eq!(metal(0.0).scattering(0.25), Scattering::Mirror(Vec3::splat(0.5)));
        assert_eq!(metal(0.2499).scattering(0.25), Scattering::Mirror(Vec3::splat(0.5)));
        assert_eq!(metal(0.25).scattering(0.25), Scattering::Diffuse(Vec3::splat(0.5)));
        let glass = |roughness| Material::Dielectric { ior: 1.5, transmittance: Vec3::ONE, roughness };
        assert_eq!(glass(0.1).scattering(0.25), Scattering::Refractive(1.5, Vec3::ONE));
        assert_eq!(glass(0.25).scattering(0.25), Scattering::Diffuse(Vec3::ONE));
    }

    /// A copy that is not its prototype under the transform, a mesh claimed twice, an
    /// index out of range or a singular transform is an error naming the instance.
    #[test]
    fn instancing_is_validated() {
        use crate::render::shapes::cuboid;
        let group = [cuboid("box", Vec3::ZERO, Vec3::ONE, 0)];
        let mut meshes = alloc::vec::Vec::new();
        let mut inst = Instancing::default();
        let p = inst.add_prototype("g", &group);
        inst.place(&mut meshes, &group, p, DAffine3::from_translation(DVec3::new(2.0, 0.0, 0.0)));
        inst.place(&mut meshes, &group, p, DAffine3::from_scale(DVec3::splat(0.5)));
        assert_eq!(inst.validate(&meshes), Ok(()));
        assert_eq!(inst.copies(3), alloc::vec![Some((0, 0)), Some((1, 0)), None]);
        let fails = |f: &dyn Fn(&mut Instancing, &mut Vec<TriangleMesh>), what: &str| {
            let (mut i, mut m) = (inst.clone(), meshes.clone());
            f(&mut i, &mut m);
            match i.validate(&m) {
                Err(SceneError::BadInstance { why, .. }) => assert!(why.contains(what), "{why}"),
                other => panic!("{what}: {other:?}"),
            }
        };
        fails(&|_, m| m[1].positions[3].x += 0.01, "vertex 3");
        fails(&|_, m| m[1].indices[0].swap(1, 2), "triangles");
        fails(&|i, _| i.instances[1].meshes[0] = 0, "already a copy");
        fails(&|i, _| i.instances[1].meshes[0] = 9, "does not exist");
        fails(&|i, _| i.instances[1].prototype = 4, "prototype 4");
        fails(&|i, _| i.instances[1].to_world = DAffine3::from_scale(DVec3::new(1.0, 0.0, 1.0)), "not invertible");
        // A prototype placed once is left to the backend as a mesh of its own.
        inst.instances.pop();
        assert_eq!(inst.copies(2), alloc::vec![None, None]);
    }
}
