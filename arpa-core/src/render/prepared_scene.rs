//! A validated scene with what the paths need precomputed: the emitters and how the
//! photons of an iteration are shared among them, scene bounds, the camera frame, and
//! surface lookups (positions, geometric and shading normals with their derivatives).

use crate::base::aabb::Aabb;
use crate::propagate::differential::{DifferentialError, NormalDifferential};
use crate::emit::emission::Light;
use crate::render::environment::Environment;
use crate::render::projection::{DomainCells, LightProjection, Projector, Targets, AREA_GRID, DELTA_GRID, SPECULAR_AREA_GRID, SPECULAR_DELTA_GRID};
use crate::base::prefetch::prefetch;
use crate::base::rng::Rng;
use crate::render::ray_cast::{RayCaster, RayHit, RayStart, TriangleId};
use crate::render::scene::{BlendWeight, CameraFrame, EmitterTexture, NormalPerturbation, Opacity, Scattering, Scene, SceneError};
use crate::propagate::normal_map::{bump_mapped, normal_mapped, texture_derivatives};
use crate::base::frame::Frame;
use crate::propagate::shading_normal::ShadedTriangle;
use alloc::vec::Vec;
use glam::{DVec2, DVec3, Vec2, Vec3};

/// Luminance weights used to compare light powers.
const LUMINANCE: DVec3 = DVec3::new(0.2126, 0.7152, 0.0722);

/// A validated, render-ready scene.
#[derive(Clone, Debug)]
pub struct PreparedScene {
    scene: Scene,
    emitters: Vec<Light>,
    emitter_power: Vec<f64>,
    area_emitters: Vec<usize>,
    area_cdf: Vec<f64>,
    bounds: Aabb,
    sphere: (DVec3, f64),
    camera: CameraFrame,
    scattering: Vec<Scattering>,
    /// Per mesh, per triangle: what every hit reads ([`TriangleGeometry`]).
    triangles: Vec<Vec<TriangleGeometry>>,
    /// Per mesh with shading normals, per triangle: its vertex normals and barycentric
    /// gradients ([`ShadingRecord`]); `None` for meshes without normals.
    shading: Vec<Option<Vec<ShadingRecord>>>,
    /// Per emitter: the cells of its domain that see geometry and specular objects.
    projections: Vec<LightProjection>,
    /// Whether some mesh is a mirror or glass.
    has_specular: bool,
    /// Whether some material is a mask.
    has_masks: bool,
    /// Whether some material is a blend.
    has_blends: bool,
    /// Per mesh, its material's normal or bump map (empty without any).
    normal_maps: Vec<Option<NormalPerturbation>>,
    /// Per emitter, the texture of a textured emitter triangle.
    emitter_textures: Vec<Option<EmitterTexture>>,
    /// Whether a photon leaving a diffuse surface can hit another surface at all (some
    /// diffuse surface scatters and not all geometry lies in one plane).
    second_hit_possible: bool,
    /// The environment light, with its map's sampling tables.
    environment: Option<Environment>,
}

/// Most masks one ray passes through before the next surface stops it whatever it is (a
/// bound on the work of a ray through a stack of cut-outs).
pub const MAX_MASK_PASSES: u32 = 64;

/// Whether a ray stops on a surface of opacity `o`: with probability `o`, drawing one
/// number from `rng` where `0 < o < 1` (none where the surface is fully open or closed), so
/// the decision repeats with the stream.
#[inline]
pub fn stops_with(o: f32, rng: &mut Rng) -> bool {
    if o >= 1.0 {
        true
    } else if o <= 0.0 {
        false
    } else {
        rng.next_f64() < o as f64
    }
}

/// The barycentric weights `(b1, b2)` of vertices 1 and 2 of the point `p` of the plane of
/// triangle `t` (the point projected into it; `(0, 0)` for a degenerate triangle).
pub fn barycentric(t: [DVec3; 3], p: DVec3) -> [f64; 2] {
    let (e1, e2, d) = (t[1] - t[0], t[2] - t[0], p - t[0]);
    let (d11, d12, d22) = (e1.dot(e1), e1.dot(e2), e2.dot(e2));
    let (d1, d2) = (d.dot(e1), d.dot(e2));
    let det = d11 * d22 - d12 * d12;
    if !(det > 0.0) {
        return [0.0, 0.0];
    }
    [(d22 * d1 - d12 * d2) / det, (d11 * d2 - d12 * d1) / det]
}

/// One triangle's barycentric gradients, or why it has none.
type TriangleGradients = Result<[DVec3; 3], DifferentialError>;

/// What a hit on a triangle with vertex normals reads besides its [`TriangleGeometry`]:
/// the vertex normals and the barycentric gradients, in one 128-byte record (two adjacent
/// cache lines, which [`PreparedScene::surface`] prefetches as soon as the hit is known)
/// instead of an index lookup followed by three normal lookups, and a gradient lookup, in
/// four arrays.
#[derive(Clone, Copy, Debug, PartialEq)]
#[repr(C, align(128))]
struct ShadingRecord {
    /// Vertex normals (the mesh's `f32` values, in vertex order).
    n: [Vec3; 3],
    /// [`ShadedTriangle::barycentric_gradients`] of the triangle.
    gradients: TriangleGradients,
}

impl ShadingRecord {
    /// The vertex normals in `f64` (exact).
    #[inline(always)]
    fn normals(&self) -> [DVec3; 3] {
        self.n.map(|v| v.as_dvec3())
    }
}

/// A triangle's vertices (the mesh's `f32` values, so converting them to `f64` is exact)
/// and its unit geometric normal, computed once at [`PreparedScene::new`] instead of at
/// every hit; 64 bytes, one cache line per hit.
#[derive(Clone, Copy, Debug, PartialEq)]
#[repr(C, align(64))]
struct TriangleGeometry {
    /// Vertex positions (metres).
    p: [Vec3; 3],
    /// `(p1 − p0) × (p2 − p0)` in `f64`, normalised (`+y` for a degenerate triangle).
    normal: DVec3,
    /// Whether the triangle has vertex normals that differ from `normal` (by more than
    /// [`FLAT_NORMAL_TOLERANCE`]); only then do diffuse hits on it take the shading-normal
    /// paths (the others give the same result up to that tolerance, faster).
    shaded: bool,
}

/// Largest distance (radians, for unit vectors) of all three unit vertex normals of a
/// triangle from its face normal (all on the same side) for which the triangle is shaded
/// flat: the cosines then differ by less than this relative amount.
pub const FLAT_NORMAL_TOLERANCE: f64 = 1e-6;

impl TriangleGeometry {
    /// The vertices in `f64`.
    #[inline]
    fn vertices(&self) -> [DVec3; 3] {
        self.p.map(|v| v.as_dvec3())
    }
}

/// A point on a surface hit by a ray.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SurfacePoint {
    /// Position interpolated from the vertices (metres).
    pub position: DVec3,
    /// Unit geometric normal `(p1 − p0) × (p2 − p0)` normalised (not oriented).
    pub geometric_normal: DVec3,
    /// Barycentric weights of the three vertices.
    pub barycentric: DVec3,
    /// Texture coordinates: the mesh's interpolated, or `(b1, b2)` without them.
    pub uv: Vec2,
    /// How the surface scatters here (the material's colour times its texture at `uv`).
    pub scattering: Scattering,
    /// Emitted radiance on the geometric-normal side, if the mesh emits.
    pub emission: Option<Vec3>,
    /// Mesh index.
    pub mesh: u32,
    /// Triangle index.
    pub triangle: u32,
}

impl SurfacePoint {
    /// A ray leaving this point (either side: the direction decides), as after a
    /// reflection, refraction or diffuse bounce: [`RayStart::leaving`] at its position and
    /// triangle.
    pub fn leaving(&self) -> RayStart {
        RayStart::leaving(self.position, TriangleId { mesh: self.mesh, triangle: self.triangle })
    }
}

impl PreparedScene {
    /// Validates `scene` and precomputes its lookups.
    pub fn new(scene: Scene) -> Result<Self, SceneError> {
        scene.validate()?;
        let (emitters, emitter_textures) = scene.emitters_with_textures();
        let radius = scene.bounding_sphere().1;
        let emitter_power: Vec<f64> = emitters.iter().map(|l| l.power(radius).dot(LUMINANCE).max(0.0)).collect();
        let area_emitters: Vec<usize> = (0..emitters.len()).filter(|&i| matches!(emitters[i], Light::Triangle(_) | Light::Quad(_))).collect();
        let mut area_cdf = Vec::with_capacity(area_emitters.len());
        let mut acc = 0.0;
        for &i in &area_emitters {
            acc += emitter_power[i];
            area_cdf.push(acc);
        }
        let environment = match emitters.iter().position(|l| matches!(l, Light::Environment(_))) {
            Some(i) => {
                let Light::Environment(light) = emitters[i] else { unreachable!() };
                Some(Environment::new(i, light, scene.textures.environment.as_ref())?)
            }
            None => None,
        };
        let scattering: Vec<Scattering> = scene.materials.iter().map(|m| m.scattering(scene.roughness_cutoff)).collect();
        let vertices = |m: &crate::render::scene::TriangleMesh, idx: [u32; 3]| idx.map(|i| m.positions[i as usize].as_dvec3());
        let normal_maps: Vec<Option<NormalPerturbation>> =
            if scene.textures.maps.iter().any(|m| m.normal.is_some()) { scene.meshes.iter().map(|m| scene.textures.maps(m.material).normal).collect() } else { Vec::new() };
        let triangles: Vec<Vec<TriangleGeometry>> = scene
            .meshes
            .iter()
            .enumerate()
            .map(|(mesh, m)| {
                let mapped = normal_maps.get(mesh).is_some_and(Option::is_some);
                m.indices
                    .iter()
                    .map(|&idx| {
                        let p = vertices(m, idx);
                        let normal = (p[1] - p[0]).cross(p[2] - p[0]).normalize_or(DVec3::Y);
                        let shaded = m.normals.as_ref().is_some_and(|ns| {
                            let near = |side: f64| {
                                idx.iter().all(|&i| (ns[i as usize].as_dvec3().normalize_or_zero() - normal * side).length() <= FLAT_NORMAL_TOLERANCE)
                            };
                            !(near(1.0) || near(-1.0))
                        });
                        TriangleGeometry { p: idx.map(|i| m.positions[i as usize]), normal, shaded: shaded || mapped }
                    })
                    .collect()
            })
            .collect();
        let shading = scene
            .meshes
            .iter()
            .map(|m| {
                m.normals.as_ref().map(|normals| {
                    m.indices
                        .iter()
                        .map(|&idx| {
                            let n = idx.map(|i| normals[i as usize]);
                            let gradients = ShadedTriangle { p: vertices(m, idx), n: n.map(|v| v.as_dvec3()) }.barycentric_gradients();
                            ShadingRecord { n, gradients }
                        })
                        .collect()
                })
            })
            .collect();
        let is_specular = |m: &crate::render::scene::TriangleMesh| matches!(scattering.get(m.material as usize), Some(Scattering::Mirror(_) | Scattering::Refractive(..) | Scattering::Thin(..)));
        let all: Vec<[DVec3; 3]> = triangles.iter().flatten().map(TriangleGeometry::vertices).collect();
        let specular: Vec<[DVec3; 3]> = scene.meshes.iter().zip(&triangles).filter(|(m, _)| is_specular(m)).flat_map(|(_, t)| t.iter().map(TriangleGeometry::vertices)).collect();
        let all_groups: Vec<usize> = scene.meshes.iter().map(|m| m.indices.len()).collect();
        let specular_groups: Vec<usize> = scene.meshes.iter().filter(|m| is_specular(m)).map(|m| m.indices.len()).collect();
        let has_specular = !specular.is_empty();
        let coplanar_geometry = coplanar(&all);
        // Clusters within each mesh: a small mirror never shares a sphere with another object.
        let (all_targets, specular_targets) = (Targets::grouped(all, &all_groups), Targets::grouped(specular, &specular_groups));
        let sphere = scene.bounding_sphere();
        let mut geometry = Projector::new(sphere, &all_targets, DELTA_GRID, AREA_GRID);
        let mut specular = Projector::new(sphere, &specular_targets, SPECULAR_DELTA_GRID, SPECULAR_AREA_GRID);
        let projections = emitters
            .iter()
            .map(|l| LightProjection {
                geometry: geometry.project(l),
                // An environment has no caustic pass: its caustics come from the global one.
                specular: if has_specular && !matches!(l, Light::Environment(_)) { specular.project(l) } else { DomainCells::none() },
            })
            .collect();
        let scatters = scene.meshes.iter().any(|m| matches!(scattering.get(m.material as usize), Some(Scattering::Diffuse(a)) if a.max_element() > 0.0));
        let second_hit_possible = scatters && !coplanar_geometry;
        Ok(Self {
            projections,
            has_specular,
            has_masks: scene.textures.any_opacity(),
            has_blends: scene.textures.maps.iter().any(|m| m.blend.is_some()),
            normal_maps,
            second_hit_possible,
            triangles,
            shading,
            bounds: scene.bounds(),
            sphere: scene.bounding_sphere(),
            camera: scene.camera.frame()?,
            scene,
            emitters,
            emitter_textures,
            emitter_power,
            area_emitters,
            area_cdf,
            scattering,
            environment,
        })
    }

    /// The environment light, if the scene has one.
    pub fn environment(&self) -> Option<&Environment> {
        self.environment.as_ref()
    }

    /// The scene.
    pub fn scene(&self) -> &Scene {
        &self.scene
    }

    /// Every emitter (analytic lights, then emissive triangles).
    pub fn emitters(&self) -> &[Light] {
        &self.emitters
    }

    /// Bounds of the geometry.
    pub fn bounds(&self) -> Aabb {
        self.bounds
    }

    /// Bounding sphere `(centre, radius)`.
    pub fn bounding_sphere(&self) -> (DVec3, f64) {
        self.sphere
    }

    /// The camera basis.
    pub fn camera(&self) -> CameraFrame {
        self.camera
    }

    /// Each emitter's projections ([`crate::render::projection`]), in [`PreparedScene::emitters`]
    /// order.
    pub fn projections(&self) -> &[LightProjection] {
        &self.projections
    }

    /// Whether some mesh is a mirror or glass.
    pub fn has_specular(&self) -> bool {
        self.has_specular
    }

    /// Whether a photon path of at most `max_depth` interactions can have a second
    /// interaction after a diffuse one: `max_depth` ≥ 2, some diffuse surface with a
    /// non-zero albedo, and not all geometry in one plane (a photon leaving a plane never
    /// meets it again).
    pub fn can_bounce_twice(&self, max_depth: u32) -> bool {
        max_depth >= 2 && self.second_hit_possible
    }

    /// Photons each emitter gets out of `total`: proportional to its power (luminance),
    /// by largest remainders, at least one per emitter with power while `total` allows.
    /// The counts sum to `total`.
    pub fn photon_allocation(&self, total: u32) -> Vec<u32> {
        crate::render::projection::allocate(&self.emitter_power, total)
    }

    /// Vertices of a triangle in `f64`.
    pub fn triangle(&self, mesh: u32, triangle: u32) -> [DVec3; 3] {
        self.triangles[mesh as usize][triangle as usize].vertices()
    }

    /// Asks the CPU to start loading what [`PreparedScene::surface`] and the shading-normal
    /// lookups will read for `hit` (the triangle's geometry record and, on meshes with
    /// vertex normals, its shading record). A hint: no effect on results; an out-of-range
    /// hit is ignored.
    #[inline(always)]
    pub fn prefetch_hit(&self, hit: &RayHit) {
        let (mesh, triangle) = (hit.mesh as usize, hit.triangle as usize);
        if let Some(tri) = self.triangles.get(mesh).and_then(|t| t.get(triangle)) {
            prefetch(tri);
        }
        if let Some(record) = self.shading.get(mesh).and_then(|r| r.as_ref()).and_then(|r| r.get(triangle)) {
            prefetch(record);
        }
    }

    /// The surface point of a hit.
    #[inline]
    pub fn surface(&self, hit: &RayHit) -> SurfacePoint {
        let m = &self.scene.meshes[hit.mesh as usize];
        let tri = &self.triangles[hit.mesh as usize][hit.triangle as usize];
        let (position, b) = self.hit_point(hit);
        let uv = self.uv(hit);
        let scattering = self.scattering_at(m.material, uv);
        SurfacePoint {
            position,
            geometric_normal: tri.normal,
            barycentric: b,
            uv,
            scattering,
            emission: match (m.emission, self.scene.textures.emission_of(hit.mesh as usize)) {
                (Some(e), Some(id)) => Some(e * self.scene.textures.textures[id as usize].eval(uv).max(Vec3::ZERO)),
                (e, _) => e,
            },
            mesh: hit.mesh,
            triangle: hit.triangle,
        }
    }

    /// How material `material` scatters at texture coordinates `uv`: its scattering times its
    /// colour texture there.
    #[inline]
    fn scattering_at(&self, material: u32, uv: Vec2) -> Scattering {
        let scattering = self.scattering[material as usize];
        let Some(id) = self.scene.textures.maps(material).color else { return scattering };
        let t = self.scene.textures.textures[id as usize].eval(uv).max(Vec3::ZERO);
        match scattering {
            Scattering::Diffuse(a) => Scattering::Diffuse(a * t),
            Scattering::Mirror(r) => Scattering::Mirror(r * t),
            Scattering::Refractive(ior, tr) => Scattering::Refractive(ior, tr * t),
            Scattering::Thin(ior, tr) => Scattering::Thin(ior, tr * t),
        }
    }

    /// The per-hit choice of a blend material (Mitsuba's `blendbsdf`): where the material at
    /// `s` is a blend, `s` scatters as the blend's other material with probability its weight
    /// at `s` ([`stops_with`]: one draw where the weight is strictly between 0 and 1, none
    /// otherwise). Scenes without blends draw nothing.
    ///
    /// Returns the weight of a photon record stored at `s`: `1/P`, with `P` the probability
    /// that the choice is diffuse, where it is (the irradiance a record measures does not
    /// depend on the choice, which only decides how the photon goes on); 1 otherwise.
    #[inline]
    pub fn choose_blend(&self, s: &mut SurfacePoint, rng: &mut Rng) -> f64 {
        if !self.has_blends {
            return 1.0;
        }
        let material = self.scene.meshes[s.mesh as usize].material;
        let Some(b) = self.scene.textures.maps(material).blend else { return 1.0 };
        let w = match b.weight {
            BlendWeight::Constant(w) => w,
            BlendWeight::Texture(id) => {
                let w = self.scene.textures.textures[id as usize].eval_1(s.uv);
                if w.is_nan() { 0.0 } else { w.clamp(0.0, 1.0) }
            }
        };
        let first_diffuse = matches!(s.scattering, Scattering::Diffuse(_));
        let other_diffuse = matches!(self.scattering[b.other as usize], Scattering::Diffuse(_));
        if stops_with(w, rng) {
            s.scattering = self.scattering_at(b.other, s.uv);
        }
        let p_diffuse = match (first_diffuse, other_diffuse) {
            (true, true) => 1.0,
            (true, false) => 1.0 - w as f64,
            (false, true) => w as f64,
            (false, false) => 1.0,
        };
        if matches!(s.scattering, Scattering::Diffuse(_)) && p_diffuse > 0.0 { 1.0 / p_diffuse } else { 1.0 }
    }

    /// The position of a hit interpolated from its triangle's vertices (metres), and its
    /// barycentric weights.
    #[inline]
    fn hit_point(&self, hit: &RayHit) -> (DVec3, DVec3) {
        let p = self.triangles[hit.mesh as usize][hit.triangle as usize].vertices();
        let (b1, b2) = (hit.b1 as f64, hit.b2 as f64);
        let b = DVec3::new(1.0 - b1 - b2, b1, b2);
        (p[0] * b.x + p[1] * b.y + p[2] * b.z, b)
    }

    /// A ray going on past `hit` (through a mask): [`SurfacePoint::leaving`] without
    /// evaluating the surface's material.
    #[inline]
    pub fn leaving_hit(&self, hit: &RayHit) -> RayStart {
        RayStart::leaving(self.hit_point(hit).0, TriangleId { mesh: hit.mesh, triangle: hit.triangle })
    }

    /// The texture coordinates of a hit: the mesh's, interpolated in `f32` with the hit's
    /// barycentric weights, or `(b1, b2)` on a mesh without them (as Mitsuba).
    #[inline]
    pub fn uv(&self, hit: &RayHit) -> Vec2 {
        let m = &self.scene.meshes[hit.mesh as usize];
        match &m.uvs {
            Some(uvs) => {
                let t = m.indices[hit.triangle as usize];
                let [a, b, c] = t.map(|i| uvs[i as usize]);
                a * (1.0 - hit.b1 - hit.b2) + b * hit.b1 + c * hit.b2
            }
            None => Vec2::new(hit.b1, hit.b2),
        }
    }

    /// The [`EmitterTexture`] of emitter `i` (a triangle of a mesh with an emission
    /// texture), if any.
    #[inline]
    pub fn emitter_texture(&self, i: usize) -> Option<&EmitterTexture> {
        self.emitter_textures.get(i).and_then(Option::as_ref)
    }

    /// What the radiance of emitter `i` is multiplied by at barycentric weights `(b1, b2)`
    /// of its triangle ([`EmitterTexture::factor`]); 1 for an emitter without a texture.
    #[inline]
    pub fn emission_factor(&self, i: usize, b1: f32, b2: f32) -> Vec3 {
        self.emitter_texture(i).map_or(Vec3::ONE, |t| t.factor(&self.scene.textures.textures, b1, b2))
    }

    /// [`PreparedScene::emission_factor`] at the point `p` of emitter `i`'s triangle (its
    /// barycentric weights solved in `f64`).
    pub fn emission_factor_at(&self, i: usize, p: DVec3) -> Vec3 {
        let (Some(t), Some(Light::Triangle(l))) = (self.emitter_texture(i), self.emitters.get(i)) else { return Vec3::ONE };
        let [b1, b2] = barycentric(l.p, p);
        t.factor(&self.scene.textures.textures, b1 as f32, b2 as f32)
    }

    /// Whether some material is a mask (rays may pass through its surfaces).
    #[inline]
    pub fn has_masks(&self) -> bool {
        self.has_masks
    }

    /// Whether a ray stops at `hit`: always on an opaque material; on a mask as
    /// [`stops_with`] decides for its opacity there.
    #[inline]
    pub fn stops(&self, hit: &RayHit, rng: &mut Rng) -> bool {
        !self.has_masks || stops_with(self.opacity(hit), rng)
    }

    /// The closest hit that stops a ray from `start` along unit `direction` up to `t_max`
    /// (metres): masks are passed as [`PreparedScene::stops`] decides, each pass continuing
    /// from the mask's surface (at most [`MAX_MASK_PASSES`] passes; the next hit then stops
    /// it).
    pub fn intersect<C: RayCaster + ?Sized>(&self, caster: &C, start: RayStart, direction: Vec3, t_max: f32, rng: &mut Rng) -> Option<RayHit> {
        self.intersect_passing(caster, start, direction, t_max, rng, |_| {})
    }

    /// [`PreparedScene::intersect`] for a camera ray, with the radiance (W/(m²·sr)) of the
    /// area lights it passes on the way: a ray passing a mask or an invisible (`null`) surface
    /// that emits towards it sees that emission, as in Mitsuba 3 (the same random draws as
    /// [`PreparedScene::intersect`]).
    pub fn intersect_seen<C: RayCaster + ?Sized>(&self, caster: &C, start: RayStart, direction: Vec3, t_max: f32, rng: &mut Rng) -> (Option<RayHit>, DVec3) {
        let mut seen = DVec3::ZERO;
        let hit = self.intersect_passing(caster, start, direction, t_max, rng, |passed| {
            if self.scene.meshes[passed.mesh as usize].emission.is_some() {
                let s = self.surface(passed);
                if let Some(e) = s.emission.filter(|_| direction.as_dvec3().dot(s.geometric_normal) < 0.0) {
                    seen += e.as_dvec3();
                }
            }
        });
        (hit, seen)
    }

    /// The one mask loop of [`PreparedScene::intersect`] and
    /// [`PreparedScene::intersect_seen`]: `passed` is called with every hit the ray passes.
    fn intersect_passing<C: RayCaster + ?Sized>(&self, caster: &C, start: RayStart, direction: Vec3, t_max: f32, rng: &mut Rng, mut passed: impl FnMut(&RayHit)) -> Option<RayHit> {
        if !self.has_masks {
            return start.intersect(caster, direction, t_max);
        }
        let mut start = start;
        let mut left = t_max;
        for _ in 0..MAX_MASK_PASSES {
            let hit = start.intersect(caster, direction, left)?;
            if self.stops(&hit, rng) {
                return Some(hit);
            }
            passed(&hit);
            left -= hit.t;
            start = self.leaving_hit(&hit);
        }
        start.intersect(caster, direction, left)
    }

    /// Whether a ray from `start` along unit `direction` is stopped before `t_max`
    /// (metres), masks passed as in [`PreparedScene::intersect`]. Without masks this is
    /// [`RayStart::occluded`] and draws nothing.
    pub fn occluded<C: RayCaster + ?Sized>(&self, caster: &C, start: RayStart, direction: Vec3, t_max: f32, rng: &mut Rng) -> bool {
        if !self.has_masks {
            return start.occluded(caster, direction, t_max);
        }
        self.intersect(caster, start, direction, t_max, rng).is_some()
    }

    /// The probability that a ray stops at `hit` (its material's opacity there); 1 for
    /// opaque materials.
    #[inline]
    pub fn opacity(&self, hit: &RayHit) -> f32 {
        let m = &self.scene.meshes[hit.mesh as usize];
        match self.scene.textures.maps(m.material).opacity {
            None => 1.0,
            Some(Opacity::Constant(o)) => o,
            Some(Opacity::Texture(id)) => {
                let o = self.scene.textures.textures[id as usize].eval_1(self.uv(hit));
                if o.is_nan() { 1.0 } else { o.clamp(0.0, 1.0) }
            }
        }
    }

    /// The shading normal at `s` and its derivatives along the positional differentials
    /// `dp_du`, `dp_dv` (zero for meshes without vertex normals), oriented like the
    /// geometric normal.
    #[inline(always)]
    pub fn shading_normal(&self, s: &SurfacePoint, dp_du: DVec3, dp_dv: DVec3) -> Result<NormalDifferential, DifferentialError> {
        let Some(records) = &self.shading[s.mesh as usize] else {
            return Ok(NormalDifferential::flat(self.perturbed(s, s.geometric_normal)));
        };
        let record = &records[s.triangle as usize];
        let tri = ShadedTriangle { p: self.triangle(s.mesh, s.triangle), n: record.normals() };
        let mut nd = tri.normal_differential_with(record.gradients?, s.barycentric, dp_du, dp_dv)?;
        if nd.n.dot(s.geometric_normal) < 0.0 {
            nd = NormalDifferential { n: -nd.n, dn_du: -nd.dn_du, dn_dv: -nd.dn_dv };
        }
        // A normal or bump map turns the normal; its derivatives stay those of the
        // interpolated normal (crate::propagate::normal_map).
        nd.n = self.perturbed(s, nd.n);
        Ok(nd)
    }

    /// The unit shading normal `n` (oriented like the geometric normal) turned by the
    /// normal or bump map of the material at `s`, if it has one
    /// ([`crate::propagate::normal_map`]); `n` itself otherwise.
    #[inline(always)]
    pub fn perturbed(&self, s: &SurfacePoint, n: DVec3) -> DVec3 {
        match self.normal_maps.get(s.mesh as usize) {
            Some(Some(map)) => self.apply_normal_map(s, n, *map),
            _ => n,
        }
    }

    #[inline(never)]
    fn apply_normal_map(&self, s: &SurfacePoint, n: DVec3, map: NormalPerturbation) -> DVec3 {
        let (dp_du, dp_dv) = self.texture_derivatives(s.mesh, s.triangle).unwrap_or_else(|| {
            let f = Frame::from_normal(n);
            (f.t, f.b)
        });
        let texture = &self.scene.textures.textures[map.texture() as usize];
        match map {
            NormalPerturbation::NormalMap { scale, handedness, .. } => {
                normal_mapped(n, s.geometric_normal, dp_du, dp_dv, texture.eval(s.uv).as_dvec3(), scale as f64, handedness)
            }
            NormalPerturbation::BumpMap { scale, .. } => bump_mapped(n, s.geometric_normal, dp_du, dp_dv, (texture.eval_1_grad(s.uv) * scale).as_dvec2()),
        }
    }

    /// The texture-coordinate derivatives `(∂p/∂u, ∂p/∂v)` of a triangle (world space,
    /// metres per unit; [`texture_derivatives`]) from its vertices and its mesh's texture
    /// coordinates, or `(0, 0), (1, 0), (0, 1)` on a mesh without them; `None` where they
    /// are degenerate.
    pub fn texture_derivatives(&self, mesh: u32, triangle: u32) -> Option<(DVec3, DVec3)> {
        let m = &self.scene.meshes[mesh as usize];
        let uv = match &m.uvs {
            Some(uvs) => m.indices[triangle as usize].map(|i| uvs[i as usize].as_dvec2()),
            None => [DVec2::ZERO, DVec2::X, DVec2::Y],
        };
        texture_derivatives(self.triangle(mesh, triangle), uv)
    }

    /// Whether the triangle of `s` has vertex normals that differ from its face normal
    /// (beyond [`FLAT_NORMAL_TOLERANCE`]); else its shading normal is the geometric one.
    #[inline(always)]
    pub fn has_shading_normals(&self, s: &SurfacePoint) -> bool {
        self.triangles[s.mesh as usize][s.triangle as usize].shaded
    }

    /// The unit interpolated shading normal at `s` (world space, oriented like the
    /// geometric normal), without derivatives: the geometric normal for triangles without
    /// distinct vertex normals ([`PreparedScene::has_shading_normals`]) or where the
    /// interpolated normal vanishes.
    #[inline(always)]
    pub fn shading_normal_at(&self, s: &SurfacePoint) -> DVec3 {
        if !self.has_shading_normals(s) {
            return s.geometric_normal;
        }
        let Some(records) = &self.shading[s.mesh as usize] else { return self.perturbed(s, s.geometric_normal) };
        let b = s.barycentric;
        let v = records[s.triangle as usize].normals();
        let n = (v[0] * b.x + v[1] * b.y + v[2] * b.z).normalize_or_zero();
        let n = if n == DVec3::ZERO {
            s.geometric_normal
        } else if n.dot(s.geometric_normal) < 0.0 {
            -n
        } else {
            n
        };
        self.perturbed(s, n)
    }

    /// Power of every emitter as the photon allocation and the area-emitter pick weigh
    /// it (luminance of the emitted power, W; ≥ 0), in [`PreparedScene::emitters`] order.
    pub fn emitter_powers(&self) -> &[f64] {
        &self.emitter_power
    }

    /// The area emitters (triangles and quads) in the order
    /// [`PreparedScene::pick_area_emitter`] searches them: their indices into
    /// [`PreparedScene::emitters`] and the running sum of their powers (W; the last entry is
    /// the total). For backends that mirror the pick.
    pub fn area_emitter_cdf(&self) -> (&[usize], &[f64]) {
        (&self.area_emitters, &self.area_cdf)
    }

    /// Picks an area emitter for next-event estimation with probability proportional to
    /// its power from the uniform number `u`: `(emitter index, probability)`.
    pub fn pick_area_emitter(&self, u: f64) -> Option<(usize, f64)> {
        let total = *self.area_cdf.last()?;
        if !(total > 0.0) {
            return None;
        }
        let x = u * total;
        let k = self.area_cdf.partition_point(|&c| c <= x).min(self.area_cdf.len() - 1);
        let i = self.area_emitters[k];
        Some((i, self.emitter_power[i] / total))
    }
}

/// Whether every triangle's vertices lie in one plane (to a relative 1e-6 of the
/// geometry's size); degenerate triangles do not choose the plane.
fn coplanar(triangles: &[[DVec3; 3]]) -> bool {
    let Some(plane) = triangles.iter().find_map(|t| {
        let n = (t[1] - t[0]).cross(t[2] - t[0]);
        (n.length() > 0.0).then(|| (n.normalize(), t[0]))
    }) else {
        return true;
    };
    let b = crate::base::aabb::Aabb::from_points(triangles.iter().flatten().copied());
    let tol = 1e-6 * b.diagonal().max(f64::MIN_POSITIVE);
    triangles.iter().flatten().all(|p| (*p - plane.1).dot(plane.0).abs() <= tol)
}
