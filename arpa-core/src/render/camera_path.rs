//! The camera pass of one pixel, as every backend must compute it: a jittered pinhole ray
//! follows specular chains (mirrors, Fresnel-chosen reflection or refraction) to the first
//! diffuse vertex, the *query point*. Emission seen along the way is added (also that of
//! area lights on masks and invisible surfaces the ray passes), and with
//! direct lighting on, next-event estimation evaluates every delta light exactly and one
//! area emitter chosen by power, and the environment by two draws (one cosine-weighted, one
//! from its own sampling) under the balance heuristic. A ray that leaves the scene sees the
//! environment's radiance. Diffuse surfaces are two-sided Lambertian in the shading
//! frame of their interpolated vertex normals, as in Mitsuba 3 ([`crate::propagate::lambertian`]).
//!
//! Camera paths carry *radiance*: crossing an interface from index `n_i` into `n_t`
//! scales it by `(n_i/n_t)²` (pbrt's radiance-mode transmission), so a floor seen through
//! the water surface has the right brightness. Photons carry flux and need no such factor.

use crate::propagate::differential::{refract_direction, reflect_direction, RefractionEvent};
use crate::emit::emission::Light;
use crate::propagate::fresnel::dielectric_reflectance;
use crate::propagate::lambertian::DiffuseShading;
use crate::render::prepared_scene::{PreparedScene, SurfacePoint};
use crate::render::ray_cast::{RayCaster, RayStart};
use crate::base::rng::{Rng, StreamDomain};
use crate::base::sampling::uniform_triangle;
use crate::render::scene::Scattering;
use crate::render::tracer::{QueryRecord, RenderSettings};
use core::f64::consts::FRAC_1_PI;
use glam::DVec3;

/// Traces the camera path of `pixel` (row-major) in 0-based `iteration`.
pub fn trace_camera_path(scene: &PreparedScene, caster: &impl RayCaster, settings: &RenderSettings, iteration: u32, pixel: u32) -> QueryRecord {
    let cam = scene.scene().camera;
    let frame = scene.camera();
    let mut rng = Rng::new(settings.seed, iteration, pixel, StreamDomain::Camera);
    let (px, py) = (pixel % cam.width, pixel / cam.width);
    let jitter = rng.next_2d();
    let mut dir = frame.direction(px as f32 + jitter.x as f32, py as f32 + jitter.y as f32, cam.width, cam.height).as_dvec3();
    let mut start = RayStart::at(cam.position);
    let mut throughput = DVec3::ONE;
    let mut radiance = DVec3::ZERO;
    let mut record = QueryRecord { pixel, ..QueryRecord::default() };
    for _ in 0..settings.max_depth {
        let (hit, passed) = scene.intersect_seen(caster, start, dir.as_vec3(), f32::INFINITY, &mut rng);
        radiance += throughput * passed;
        let Some(hit) = hit else {
            if let Some(env) = scene.environment() {
                radiance += throughput * env.radiance(dir);
            }
            break;
        };
        scene.prefetch_hit(&hit);
        let mut s = scene.surface(&hit);
        let _ = scene.choose_blend(&mut s, &mut rng);
        let front = if dir.dot(s.geometric_normal) < 0.0 { s.geometric_normal } else { -s.geometric_normal };
        if let Some(e) = s.emission.filter(|_| dir.dot(s.geometric_normal) < 0.0) {
            radiance += throughput * e.as_dvec3();
        }
        match s.scattering {
            Scattering::Diffuse(albedo) => {
                // Mitsuba's two-sided diffuse lobe in the shading frame: zero for a viewer
                // in the shading plane.
                let shading = DiffuseShading::new(front, scene.shading_normal_at(&s), -dir);
                let weight = if shading.is_some() { throughput * albedo.as_dvec3() * FRAC_1_PI } else { DVec3::ZERO };
                if let (true, Some(shading)) = (settings.direct_lighting, shading) {
                    radiance += weight * direct_irradiance(scene, caster, &s, &shading, &mut rng);
                }
                record.position = s.position.as_vec3().to_array();
                // Orientation for the gather: flipped where the viewer is below the
                // shading plane (see photon_path's `orient_to_shading_side`).
                let oriented = if shading.is_some_and(|sh| sh.below_shading_plane()) { -front } else { front };
                record.normal = oriented.as_vec3().to_array();
                record.weight = weight.as_vec3().to_array();
                record.valid = 1;
                break;
            }
            Scattering::Mirror(reflectance) => {
                throughput *= reflectance.as_dvec3();
                let n = shading_normal(scene, &s);
                dir = reflect_direction(dir, n).normalize_or(dir);
                start = s.leaving();
            }
            // A thin sheet reflects with its total reflectance, else passes straight on
            // (the same medium on both sides: no radiance scaling).
            Scattering::Thin(ior, transmittance) => {
                let n = shading_normal(scene, &s);
                if rng.next_f64() < crate::render::scene::thin_sheet_reflectance(dir.dot(n), ior as f64) {
                    dir = reflect_direction(dir, n).normalize_or(dir);
                } else {
                    throughput *= transmittance.as_dvec3();
                }
                start = s.leaving();
            }
            Scattering::Refractive(ior, transmittance) => {
                let ior = ior as f64;
                let n = shading_normal(scene, &s);
                let fresnel = dielectric_reflectance(dir.dot(n), ior);
                if rng.next_f64() < fresnel {
                    dir = reflect_direction(dir, n).normalize_or(dir);
                    start = s.leaving();
                } else {
                    let (t, event, eta) = refract_direction(dir, n, ior);
                    if event == RefractionEvent::Transmitted {
                        throughput *= transmittance.as_dvec3() * (eta * eta);
                        start = s.leaving();
                    } else {
                        start = s.leaving();
                    }
                    dir = t;
                }
            }
        }
        if !(throughput.max_element() > 0.0) {
            break;
        }
    }
    let radiance = DVec3::select(radiance.is_finite_mask(), radiance, DVec3::ZERO);
    record.radiance = radiance.as_vec3().to_array();
    record
}

fn shading_normal(scene: &PreparedScene, s: &SurfacePoint) -> DVec3 {
    scene.shading_normal(s, DVec3::ZERO, DVec3::ZERO).map(|n| n.n).unwrap_or(s.geometric_normal)
}

/// Direct irradiance (W/m², RGB) at a diffuse point in the shading frame `shading` (seen
/// from the viewer: [`DiffuseShading::new`] with the direction to the viewer): every delta
/// light exactly, plus one area emitter picked by power with one uniformly sampled point
/// (unbiased; one-sided emitters), and the environment's irradiance by
/// [`crate::render::environment::Environment::irradiance`]. The cosine at the point is taken about the shading
/// normal, and lights below the shading plane or behind the face give nothing
/// ([`DiffuseShading::cosine`]), as in Mitsuba 3; with `shading.shading = shading.geometric`
/// this is the plain `E = ∫ L cos θ dω`.
pub fn direct_irradiance(scene: &PreparedScene, caster: &impl RayCaster, s: &SurfacePoint, shading: &DiffuseShading, rng: &mut Rng) -> DVec3 {
    let p = s.position;
    let from = s.leaving();
    let mut e = DVec3::ZERO;
    let visible = |to: DVec3, rng: &mut Rng| {
        let d = to - from.origin.as_dvec3();
        let dist = d.length();
        dist > 0.0 && !scene.occluded(caster, from, (d / dist).as_vec3(), (dist * (1.0 - 1e-4)) as f32, rng)
    };
    for light in scene.emitters() {
        match light {
            Light::Point(l) => {
                let d = l.position - p;
                let r2 = d.length_squared();
                let cos = shading.cosine(d / libm::sqrt(r2));
                if cos > 0.0 && visible(l.position, rng) {
                    e += l.intensity * (cos / r2);
                }
            }
            Light::Spot(l) => {
                let d = l.position - p;
                let r2 = d.length_squared();
                let r = libm::sqrt(r2);
                let cos = shading.cosine(d / r);
                let axis = l.direction.normalize_or(DVec3::Z);
                let theta = libm::acos((-d / r).dot(axis).clamp(-1.0, 1.0));
                let falloff = l.falloff_at(theta);
                if cos > 0.0 && falloff > 0.0 && visible(l.position, rng) {
                    e += l.intensity * (falloff * cos / r2);
                }
            }
            Light::Directional(l) => {
                let to_light = -l.direction.normalize_or(DVec3::Z);
                let cos = shading.cosine(to_light);
                let far = p + to_light * (4.0 * scene.bounding_sphere().1 + 1.0);
                if cos > 0.0 && visible(far, rng) {
                    e += l.irradiance * cos;
                }
            }
            Light::Environment(_) => {
                let (cosine, light) = (rng.next_2d(), rng.next_2d());
                if let Some(env) = scene.environment() {
                    let far = 4.0 * scene.bounding_sphere().1 + 1.0;
                    e += env.irradiance(shading.shading, cosine, light, |d| shading.cosine(d), |d| visible(p + d * far, rng));
                }
            }
            Light::Triangle(_) | Light::Quad(_) => {}
        }
    }
    let u = rng.next_f64();
    let sample = rng.next_2d();
    if let Some((i, prob)) = scene.pick_area_emitter(u) {
        let (point, normal, area, radiance) = match scene.emitters()[i] {
            Light::Triangle(l) => {
                let b = uniform_triangle(sample);
                let n = (l.p[1] - l.p[0]).cross(l.p[2] - l.p[0]);
                // A textured emitter's radiance at the sampled point (its power, hence
                // `prob`, holds the texture's mean over the triangle).
                let radiance = l.radiance * scene.emission_factor(i, b.y as f32, b.z as f32).as_dvec3();
                (l.p[0] * b.x + l.p[1] * b.y + l.p[2] * b.z, n.normalize_or(DVec3::Y), 0.5 * n.length(), radiance)
            }
            Light::Quad(l) => {
                let n = l.edge_u.cross(l.edge_v);
                (l.origin + l.edge_u * sample.x + l.edge_v * sample.y, n.normalize_or(DVec3::Y), n.length(), l.radiance)
            }
            _ => (DVec3::ZERO, DVec3::Y, 0.0, DVec3::ZERO),
        };
        let d = point - p;
        let r2 = d.length_squared();
        let r = libm::sqrt(r2);
        if r > 0.0 {
            let cos_q = shading.cosine(d / r);
            let cos_l = -normal.dot(d) / r;
            if cos_q > 0.0 && cos_l > 0.0 && prob > 0.0 && visible(point, rng) {
                e += radiance * (cos_q * cos_l * area / (r2 * prob));
            }
        }
    }
    e
}
