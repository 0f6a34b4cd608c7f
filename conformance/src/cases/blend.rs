//! A blend material (Mitsuba's `blendbsdf`) against closed-form light: the lit plane of
//! [`crate::scenes::lit_plane`] as a blend of a white diffuse surface and a mirror that sends
//! the light it catches away from the scene. With the mirror's weight `w` the plane's radiance
//! is `(1 − w) · I cos θ / (π d²)`: the per-hit choice must pick the mirror with probability
//! `w`, both by next-event estimation and by photons only. Checked for a constant weight
//! and a texture's (a 1 × 1 bitmap's single value), over the whole image.

use std::f64::consts::PI;

use arpa_core::glam::{DVec3, Vec3};
use arpa_core::render::scene::{Blend, BlendWeight, Material, MaterialMaps, Scene};
use arpa_core::render::texture::{Bitmap, Texels, Texture, TextureFilter, TextureWrap, UvTransform};

use crate::dyn_tracer::DynTracer;
use crate::scenes::{self, PLANE_INTENSITY, PLANE_LIGHT_HEIGHT};
use crate::suite::{CaseResult, Context};

/// Largest error of the image mean by next-event estimation (percent): at least 2.2
/// standard deviations of the per-query-point coin toss over ITERATIONS × SIZE²
/// draws (σ = 0.64 % for weight 0.25, 1.35 % for 0.6).
pub const TOL_PERCENT: f64 = 3.0;
/// Largest difference of the photons-only image mean from next-event estimation's (percent).
pub const TOL_PHOTONS_PERCENT: f64 = 2.5;
/// Image side (pixels).
const SIZE: u32 = 32;
/// Photons per iteration.
const PHOTONS: u32 = 40_000;
/// Iterations.
const ITERATIONS: u32 = 8;

/// `I cos θ / (π d²)` at floor point `p` (albedo 1).
fn radiance(p: DVec3) -> f64 {
    let light = DVec3::new(0.0, PLANE_LIGHT_HEIGHT, 0.0);
    let d = light - p;
    let dist = d.length();
    PLANE_INTENSITY * (d.y / dist) / (dist * dist) / PI
}

/// The lit plane as a blend of white diffuse and a mirror of weight `weight` (the texture, if
/// any, is texture 0).
fn blended_plane(weight: BlendWeight, texture: Option<Texture>) -> Scene {
    let mut scene = scenes::lit_plane_textured(SIZE, texture.into_iter().collect(), MaterialMaps { blend: Some(Blend { other: 1, weight }), ..MaterialMaps::default() });
    scene.materials.push(Material::Conductor { reflectance: Vec3::ONE, roughness: 0.0 });
    scene
}

/// The image mean's error (percent) against `(1 − w)` times the closed-form radiance
/// averaged over the pixel centres (a camera ray that picks the mirror leaves the scene).
fn check(t: &mut dyn DynTracer, scene: &Scene, direct: bool, w: f64) -> Result<f64, String> {
    let settings = super::common::plane_settings(PHOTONS, 9, direct);
    t.upload_scene(scene, &settings).ctx("upload_scene")?;
    let pixels = (SIZE * SIZE) as usize;
    for _ in 0..ITERATIONS {
        t.iterate().ctx("iterate")?;
    }
    let image = t.read_image().ctx("read_image")?;
    if image.pixels.len() != pixels || image.pixels.iter().any(|p| !p.is_finite()) {
        return Err("the image has the wrong size or a non-finite pixel".into());
    }
    let est = image.pixels.iter().map(|p| p.x as f64).sum::<f64>() / pixels as f64;
    let mut closed = 0.0;
    let side = SIZE as f64;
    // The camera sees the floor square |x|, |z| ≤ 1.5 (lit_plane: height 3, tan(fov/2) = ½);
    // integrate the closed form over the pixel centres.
    for j in 0..SIZE {
        for i in 0..SIZE {
            let x = ((i as f64 + 0.5) / side - 0.5) * 3.0;
            let z = ((j as f64 + 0.5) / side - 0.5) * 3.0;
            closed += (1.0 - w) * radiance(DVec3::new(x, 0.0, z));
        }
    }
    closed /= pixels as f64;
    Ok((est / closed - 1.0) * 100.0)
}

/// A blend of white diffuse and a mirror, mirror weight 0.25 (constant) and 0.6 (a 1 × 1
/// bitmap's single value), by next-event estimation and by photons only.
pub fn blend_plane(t: &mut dyn DynTracer) -> CaseResult {
    let bitmap = Texture::Bitmap(Bitmap {
        width: 1,
        height: 1,
        texels: Texels::Float(vec![[0.6; 3]]),
        filter: TextureFilter::Nearest,
        wrap: TextureWrap::Repeat,
        to_uv: UvTransform::IDENTITY,
    });
    let mut ok = true;
    let mut report = Vec::new();
    for (name, scene, w) in [
        ("constant weight 0.25", blended_plane(BlendWeight::Constant(0.25), None), 0.25),
        ("texture weight 0.6", blended_plane(BlendWeight::Texture(0), Some(bitmap)), 0.6),
    ] {
        let direct = check(t, &scene, true, w)?;
        let photons = check(t, &scene, false, w)?;
        // The camera's coin is the same in both renders (same seed, and a point light's
        // next-event estimate draws nothing): photons against next-event estimation isolates
        // the photons' record weight from the coin's noise.
        let relative = ((1.0 + photons / 100.0) / (1.0 + direct / 100.0) - 1.0) * 100.0;
        ok &= direct.abs() < TOL_PERCENT && relative.abs() < TOL_PHOTONS_PERCENT;
        report.push(format!("{name}: direct {direct:+.2}%, photons {photons:+.2}% ({relative:+.2}% against direct)"));
    }
    let msg = format!("{} (tol ±{TOL_PERCENT}% direct, ±{TOL_PHOTONS_PERCENT}% photons against direct, {ITERATIONS}×{PHOTONS} photons, {SIZE}² px)", report.join("; "));
    if ok { Ok(msg) } else { Err(msg) }
}
