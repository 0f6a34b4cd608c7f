//! The one geometric query the reference paths need from a backend: closest hit and
//! occlusion of a ray against the scene's triangles. Backends answer it with their own
//! acceleration structure (Embree, hardware ray tracing); [`crate::render::brute_force::BruteForceCaster`] answers it
//! by testing every triangle in `f64`, as an independent reference for tests.

use glam::{DVec3, Vec3};

/// A ray–triangle hit.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RayHit {
    /// Distance along the (unit) ray direction (metres).
    pub t: f32,
    /// Mesh index in [`crate::render::scene::Scene::meshes`].
    pub mesh: u32,
    /// Triangle index within the mesh.
    pub triangle: u32,
    /// Barycentric weight of the triangle's second vertex (Embree's `u`).
    pub b1: f32,
    /// Barycentric weight of the third vertex (Embree's `v`).
    pub b2: f32,
}

/// Closest-hit and occlusion queries against the scene's triangles. Rays are
/// `origin + t·direction` with unit `direction` and `t ∈ (t_min, t_max)` (metres; a
/// backend whose interval is closed, such as Embree's, may include the ends).
///
/// The paths never call these directly: they cast through a [`RayStart`], which adds the
/// rule for rays that leave a surface (skip the triangle just left).
pub trait RayCaster: Sync {
    /// The closest hit with `t_min < t < t_max`, if any.
    fn intersect(&self, origin: Vec3, direction: Vec3, t_min: f32, t_max: f32) -> Option<RayHit>;
    /// Whether anything is hit with `t_min < t < t_max`.
    fn occluded(&self, origin: Vec3, direction: Vec3, t_min: f32, t_max: f32) -> bool {
        self.intersect(origin, direction, t_min, t_max).is_some()
    }
}

/// A triangle of the scene: mesh index in [`crate::render::scene::Scene::meshes`] and triangle
/// index within the mesh (as [`RayHit`] reports them).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct TriangleId {
    /// Mesh index.
    pub mesh: u32,
    /// Triangle index within the mesh.
    pub triangle: u32,
}

/// How many times [`RayStart::intersect`] casts again past the triangle it leaves before
/// it gives up (and reports a miss). One re-cast suffices unless the backend's
/// ray–triangle test reports that triangle twice at different distances.
pub const LEAVE_RECASTS: u32 = 2;

/// Where a ray starts, and what it must not hit there.
///
/// A ray that leaves a surface starts **on** it (the hit point rounded to `f32`, not
/// offset) and skips the triangle it leaves, at whatever distance the backend's test
/// puts it ([`RayStart::leaving`]). Every other triangle counts from `t_min`, one `f32`
/// ulp of the origin's largest coordinate. So glass of any thickness the `f32`
/// coordinates resolve, a thin sheet or a lens near its knife-edge rim, is entered and
/// left, where an offset along the normal would start the ray beyond its far side. The
/// only origin still offset is that of an area light's photons
/// ([`RayStart::off_surface`]: the emitter's triangle is not known to the emission).
///
/// The same rule is the device's `arpa_ray_start_*` / `arpa_start_intersect` /
/// `arpa_start_occluded` in `shaders/path/scene.wgsl`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RayStart {
    /// Origin (metres, world space).
    pub origin: Vec3,
    /// Hits at `t ≤ t_min` (metres) are not reported.
    pub t_min: f32,
    /// The triangle the ray leaves, skipped wherever it is hit.
    pub leaves: Option<TriangleId>,
}

impl RayStart {
    /// A ray from a point off every surface (the camera, a point or spot light, a
    /// directional light's disc): every hit with `t > 0`.
    pub fn at(origin: Vec3) -> Self {
        Self { origin, t_min: 0.0, leaves: None }
    }

    /// A ray leaving triangle `leaves` at the point `p` on it (metres; either side: the
    /// direction decides), as after a reflection, refraction or diffuse bounce.
    pub fn leaving(p: DVec3, leaves: TriangleId) -> Self {
        let origin = p.as_vec3();
        Self { origin, t_min: leave_t_min(origin), leaves: Some(leaves) }
    }

    /// A ray from `p` offset along `normal` (unit, towards the side the ray leaves to) by
    /// [`crate::render::ray_cast::offset_origin`]: for photons leaving an area light, whose
    /// triangle the emission does not know.
    pub fn off_surface(p: DVec3, normal: DVec3) -> Self {
        Self::at(crate::render::ray_cast::offset_origin(p, normal))
    }

    /// The closest hit along unit `direction` up to `t_max` (metres), the left triangle
    /// skipped: cast again just past it when it comes first (at most [`LEAVE_RECASTS`]
    /// times).
    #[inline]
    pub fn intersect<C: RayCaster + ?Sized>(&self, caster: &C, direction: Vec3, t_max: f32) -> Option<RayHit> {
        let mut hit = caster.intersect(self.origin, direction, self.t_min, t_max)?;
        let Some(left) = self.leaves else { return Some(hit) };
        for _ in 0..LEAVE_RECASTS {
            if hit.mesh != left.mesh || hit.triangle != left.triangle {
                return Some(hit);
            }
            hit = caster.intersect(self.origin, direction, next_up(hit.t.max(self.t_min)), t_max)?;
        }
        (hit.mesh != left.mesh || hit.triangle != left.triangle).then_some(hit)
    }

    /// Whether anything but the left triangle lies along unit `direction` before `t_max`
    /// (metres): the backend's any-hit query, confirmed by [`RayStart::intersect`] when a
    /// triangle is left (the any-hit answer may be that triangle).
    #[inline]
    pub fn occluded<C: RayCaster + ?Sized>(&self, caster: &C, direction: Vec3, t_max: f32) -> bool {
        caster.occluded(self.origin, direction, self.t_min, t_max) && (self.leaves.is_none() || self.intersect(caster, direction, t_max).is_some())
    }
}

/// `t_min` of a ray leaving a surface at `origin`: `2⁻²³ (1 + max |origin_i|)` metres,
/// about one `f32` ulp of its largest coordinate, the resolution of the origin itself.
/// It keeps the neighbours of the left triangle in its plane (a flat mesh's other
/// triangles) from being hit at `t ≈ 0` when rounding puts the origin just behind that
/// plane.
#[inline]
pub fn leave_t_min(origin: Vec3) -> f32 {
    const ULP: f32 = 1.0 / 8_388_608.0; // 2^-23
    ULP * (1.0 + origin.abs().max_element())
}

/// Offsets a ray origin off a surface along `normal` (oriented to the side the ray
/// leaves towards) by `1e-5 (1 + max |p_i|)` metres, to avoid self-intersection in `f32`.
/// Only photons leaving an area light start so ([`RayStart::off_surface`]);
/// rays leaving a surface they hit start on it and skip its triangle
/// ([`RayStart::leaving`]), which glass thinner than this offset needs.
#[inline]
pub fn offset_origin(p: DVec3, normal: DVec3) -> Vec3 {
    let scale = 1e-5 * (1.0 + p.abs().max_element());
    (p + normal * scale).as_vec3()
}

/// The next `f32` above a finite `t ≥ 0` (its bits plus one; the device's
/// `arpa_next_up`).
#[inline]
pub fn next_up(t: f32) -> f32 {
    f32::from_bits(t.max(0.0).to_bits() + 1)
}


/// `hit` with its barycentric weights recomputed on the world-space triangle `p` (metres,
/// its vertices in index order) it hit, from the ray `origin + t·direction`:
/// Möller–Trumbore in `f64` on the exact `f64` images of the `f32` inputs, the weights
/// rounded to `f32` once and clamped onto the triangle.
///
/// So the hit that shading sees (the point interpolated from the weights, the normals and
/// texture coordinates at it) is a function of the ray and the triangle alone, not of the
/// acceleration structure that found it: an instanced structure (the ray taken into the
/// instance's object space) and a flattened one give the same bits for the same triangle.
/// `hit.t` stays the backend's: nothing is shaded with it, and [`RayStart::intersect`]
/// casts again from just past it, which must be past where that backend's structure
/// reports the triangle. A triangle degenerate along the ray (zero determinant) keeps
/// `hit`'s weights.
#[inline]
pub fn refine_hit(hit: RayHit, p: [Vec3; 3], origin: Vec3, direction: Vec3) -> RayHit {
    let [p0, p1, p2] = p.map(|v| v.as_dvec3());
    let (o, d) = (origin.as_dvec3(), direction.as_dvec3());
    let (e1, e2) = (p1 - p0, p2 - p0);
    let pv = d.cross(e2);
    let det = e1.dot(pv);
    if !(det.abs() > 1e-300) {
        return hit;
    }
    let inv = 1.0 / det;
    let tv = o - p0;
    let (b1, b2) = (tv.dot(pv) * inv, d.dot(tv.cross(e1)) * inv);
    if !(b1.is_finite() && b2.is_finite()) {
        return hit;
    }
    let b1 = b1.clamp(0.0, 1.0);
    let b2 = b2.clamp(0.0, 1.0 - b1);
    RayHit { b1: b1 as f32, b2: b2 as f32, ..hit }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The refined weights are the exact ones rounded once, whatever the input's were, and
    /// stay on the triangle; `t` is left as the backend reported it.
    #[test]
    fn refine_hit_recomputes_the_weights() {
        let p = [Vec3::new(0.0, 0.0, 1.0), Vec3::new(1.0, 0.0, 1.0), Vec3::new(0.0, 1.0, 1.0)];
        let rough = RayHit { t: 0.9, mesh: 3, triangle: 7, b1: 0.2, b2: 0.2 };
        let h = refine_hit(rough, p, Vec3::new(0.25, 0.5, 0.0), Vec3::Z);
        assert_eq!((h.t, h.b1, h.b2, h.mesh, h.triangle), (0.9, 0.25, 0.5, 3, 7));
        // A ray just outside an edge (as a watertight test may report) is clamped onto it.
        let h = refine_hit(rough, p, Vec3::new(-1e-6, 0.5, 0.0), Vec3::Z);
        assert_eq!((h.b1, h.b2), (0.0, 0.5));
        // Parallel to the triangle: nothing to recompute.
        assert_eq!(refine_hit(rough, p, Vec3::ZERO, Vec3::X), rough);
    }
}
