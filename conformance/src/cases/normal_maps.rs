//! Normal and bump maps against closed-form light: the lit plane of
//! [`crate::scenes::lit_plane`] (facing `+y`, texture coordinates `u = (x + 10)/20`,
//! `v = (z + 10)/20`, so `∂p/∂u = 20 x̂` and `∂p/∂v = 20 ẑ`) with a material whose shading
//! normal a texture turns. The expected radiance at each query point is
//! `ρ/π · I (l·n')⁺ / d²` with the turned normal `n'` written out here from the map's
//! definition (tangent frame `s = x̂`, `t = n × s = −ẑ`, or `+ẑ` where the frame follows
//! `∂p/∂v`; a linear height ramp's slope), not through the core's perturbation code.
//! Each map is checked by next-event estimation (exact per query point) and by photons
//! only (the adjoint ratio `|ω·n'|/|ω·n_g|` of the stored photons), each over the two
//! halves `z < 0` and `z > 0` of the image (a map that tilts the wrong way mirrors the
//! light, which a whole-image mean would not see).

use std::f64::consts::PI;

use arpa_core::glam::{DVec3, Vec3};
use arpa_core::render::scene::{Handedness, MaterialMaps, NormalPerturbation, Scene};
use arpa_core::render::texture::{Bitmap, Texels, Texture, TextureFilter, TextureWrap, UvTransform};

use crate::dyn_tracer::DynTracer;
use crate::scenes::{self, PLANE_INTENSITY, PLANE_LIGHT_HEIGHT};
use crate::suite::{CaseResult, Context};

/// Largest error of a half's mean, photons only (percent).
pub const TOL_PHOTONS_PERCENT: f64 = 2.5;
/// Largest error of a half's mean, next-event estimation (percent; the expected value is
/// computed at the same query points, so only `f32` rounding separates them).
pub const TOL_DIRECT_PERCENT: f64 = 0.05;
/// Image side (pixels).
const SIZE: u32 = 32;
/// Photons per iteration.
const PHOTONS: u32 = 40_000;
/// Iterations with photons only.
const ITERATIONS: u32 = 2;
/// Tilt of the normal map's normal (radians).
const TILT: f64 = 0.35;
/// Texels of the bump map's height ramp along `u`, and the ramp's step per texel.
const RAMP_TEXELS: u32 = 16;
const RAMP_STEP: f64 = 0.25;
/// The bump map's scale.
const BUMP_SCALE: f64 = 1.5;

/// The lit plane with texture coordinates and albedo 1, its material turned by `normal`
/// reading `texture`.
fn mapped_plane(texture: Texture, normal: NormalPerturbation) -> Scene {
    scenes::lit_plane_textured(SIZE, vec![texture], MaterialMaps { normal: Some(normal), ..MaterialMaps::default() })
}

/// `ρ/π · I (l·n)⁺ / d²` at floor point `p` for the unit shading normal `n` (`ρ = 1`).
fn radiance(p: DVec3, n: DVec3) -> f64 {
    let light = DVec3::new(0.0, PLANE_LIGHT_HEIGHT, 0.0);
    let d = light - p;
    let dist = d.length();
    PLANE_INTENSITY * (d / dist).dot(n).max(0.0) / (dist * dist) / PI
}

/// Renders `scene` (`direct`: next-event estimation, one iteration; else photons only) and
/// compares the red channel's mean over each half of the image with the expected radiance at
/// the query points; returns the two errors (percent) and their text.
fn check(t: &mut dyn DynTracer, scene: &Scene, direct: bool, normal: DVec3) -> Result<([f64; 2], String), String> {
    let iterations = if direct { 1 } else { ITERATIONS };
    let settings = super::common::plane_settings(PHOTONS, 5, direct);
    t.upload_scene(scene, &settings).ctx("upload_scene")?;
    let pixels = (SIZE * SIZE) as usize;
    let mut expected = vec![0.0; pixels];
    let mut half: Vec<Option<usize>> = vec![None; pixels];
    for it in 0..iterations {
        t.iterate().ctx("iterate")?;
        let records = t.read_query_points().ctx("read_query_points")?;
        if records.len() != pixels {
            return Err(format!("{} query records for {pixels} pixels", records.len()));
        }
        for r in &records {
            let i = r.pixel as usize;
            if r.valid != 1 || i >= pixels {
                return Err(format!("pixel {} has no query point", r.pixel));
            }
            let p = Vec3::from_array(r.position).as_dvec3();
            expected[i] += radiance(p, normal) / iterations as f64;
            // Pixels whose query points straddle z = 0 (or lie on it) belong to neither half.
            let h = if p.z < -1e-3 { Some(0) } else if p.z > 1e-3 { Some(1) } else { None };
            half[i] = if it == 0 || half[i] == h { h } else { None };
        }
    }
    let image = t.read_image().ctx("read_image")?;
    if image.pixels.len() != pixels || image.pixels.iter().any(|p| !p.is_finite()) {
        return Err("the image has the wrong size or a non-finite pixel".into());
    }
    let mut errors = [0.0; 2];
    let mut text = Vec::new();
    for (g, name) in ["z < 0", "z > 0"].iter().enumerate() {
        let members: Vec<usize> = (0..pixels).filter(|&i| half[i] == Some(g)).collect();
        if members.is_empty() {
            return Err(format!("no pixels in the half {name}"));
        }
        let est = members.iter().map(|&i| image.pixels[i].x as f64).sum::<f64>() / members.len() as f64;
        let ana = members.iter().map(|&i| expected[i]).sum::<f64>() / members.len() as f64;
        errors[g] = (est / ana - 1.0) * 100.0;
        text.push(format!("{name} {:+.2}%", errors[g]));
    }
    Ok((errors, text.join(" ")))
}

/// A constant tangent-space normal map tilting the normal by TILT towards the frame's
/// second tangent (`−ẑ` with Mitsuba's frame, `+ẑ` with the frame following `∂p/∂v`), and a
/// bump map whose height rises linearly along `u` (the normal tilts towards `−x̂` by the
/// ramp's slope); each by next-event estimation and by photons only.
pub fn normal_map_plane(t: &mut dyn DynTracer) -> CaseResult {
    let (s, c) = (TILT.sin(), TILT.cos());
    let tilted = Texture::Bitmap(Bitmap {
        width: 1,
        height: 1,
        texels: Texels::Float(vec![[0.5, (0.5 + 0.5 * s) as f32, (0.5 + 0.5 * c) as f32]]),
        filter: TextureFilter::Bilinear,
        wrap: TextureWrap::Repeat,
        to_uv: UvTransform::IDENTITY,
    });
    let ramp = Texture::Bitmap(Bitmap {
        width: RAMP_TEXELS,
        height: 1,
        texels: Texels::Float((0..RAMP_TEXELS).map(|i| [(RAMP_STEP * i as f64) as f32; 3]).collect()),
        filter: TextureFilter::Bilinear,
        wrap: TextureWrap::Clamp,
        to_uv: UvTransform::IDENTITY,
    });
    // dh/du = W · step (bilinear of a linear ramp) times the scale; with dp/du = 20 x̂ the
    // bumped surface rises by that over 20 m of x.
    let slope = BUMP_SCALE * RAMP_TEXELS as f64 * RAMP_STEP / 20.0;
    let cases = [
        (
            "normal map (t = n × s)",
            tilted.clone(),
            NormalPerturbation::NormalMap { texture: 0, scale: 1.0, handedness: Handedness::RightHanded },
            DVec3::new(0.0, c, -s),
        ),
        (
            "normal map (t along ∂p/∂v)",
            tilted,
            NormalPerturbation::NormalMap { texture: 0, scale: 1.0, handedness: Handedness::FollowTextureCoordinates },
            DVec3::new(0.0, c, s),
        ),
        ("bump map", ramp, NormalPerturbation::BumpMap { texture: 0, scale: BUMP_SCALE as f32 }, DVec3::new(-slope, 1.0, 0.0).normalize()),
    ];
    let mut ok = true;
    let mut report = Vec::new();
    for (name, texture, map, normal) in cases {
        let scene = mapped_plane(texture, map);
        let (direct, direct_text) = check(t, &scene, true, normal)?;
        let (photons, photon_text) = check(t, &scene, false, normal)?;
        ok &= direct.iter().all(|e| e.abs() < TOL_DIRECT_PERCENT) && photons.iter().all(|e| e.abs() < TOL_PHOTONS_PERCENT);
        report.push(format!("{name}: direct {direct_text}, photons {photon_text}"));
    }
    let msg = format!(
        "{} (tol ±{TOL_DIRECT_PERCENT}% direct, ±{TOL_PHOTONS_PERCENT}% photons over {ITERATIONS}×{PHOTONS}; tilt {TILT} rad, bump slope {slope:.3})",
        report.join("; ")
    );
    if ok { Ok(msg) } else { Err(msg) }
}
