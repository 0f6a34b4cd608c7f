//! Textures and alpha masks against closed-form light: the lit plane of
//! [`crate::scenes::lit_plane`] with a textured albedo, and with a half-open mask between
//! the light and the floor. The expected values are computed here from the query points'
//! positions (the texture pattern, the sRGB curve and the shadow of the mask in closed form),
//! not through the core's texture lookup.

use std::f64::consts::PI;

use arpa_core::glam::{DVec3, Vec2, Vec3};
use arpa_core::render::scene::{MaterialMaps, Opacity, Scene, SceneTextures};
use arpa_core::render::texture::{Bitmap, Texels, Texture, TextureFilter, TextureWrap, UvTransform};
use arpa_core::render::tracer::QueryRecord;

use crate::dyn_tracer::DynTracer;
use crate::scenes::{self, PLANE_INTENSITY, PLANE_LIGHT_HEIGHT};
use crate::suite::{CaseResult, Context};

/// Largest error of a region mean (percent).
pub const TOL_PERCENT: f64 = 2.5;
/// Image side (pixels).
const SIZE: u32 = 32;
/// Photons per iteration.
const PHOTONS: u32 = 50_000;
/// Iterations.
const ITERATIONS: u32 = 4;

/// `I cos θ / d²` from the plane scene's light at the point `p` of a surface facing up.
fn irradiance(p: DVec3) -> f64 {
    let light = DVec3::new(0.0, PLANE_LIGHT_HEIGHT, 0.0);
    let d = (light - p).length();
    PLANE_INTENSITY * ((light.y - p.y) / d) / (d * d)
}

/// The lit plane with texture coordinates `((x + 10)/20, (z + 10)/20)` on its 20 × 20
/// square, the material reading `texture` as its colour (factor 1).
fn textured_plane(texture: Texture) -> Scene {
    scenes::lit_plane_textured(SIZE, vec![texture], MaterialMaps { color: Some(0), ..MaterialMaps::default() })
}

/// Uploads `scene`, runs the iterations and returns the image and every iteration's query
/// records (checked: one per pixel).
fn render(t: &mut dyn DynTracer, scene: &Scene, direct: bool, iterations: u32) -> Result<(Vec<Vec3>, Vec<Vec<QueryRecord>>), String> {
    let settings = super::common::plane_settings(PHOTONS, 11, direct);
    t.upload_scene(scene, &settings).ctx("upload_scene")?;
    let pixels = (SIZE * SIZE) as usize;
    let mut all = Vec::new();
    for _ in 0..iterations {
        t.iterate().ctx("iterate")?;
        let mut records = t.read_query_points().ctx("read_query_points")?;
        if records.len() != pixels || records.iter().any(|r| r.pixel as usize >= pixels) {
            return Err(format!("{} query records for {pixels} pixels, or one outside the image", records.len()));
        }
        records.sort_by_key(|r| r.pixel);
        all.push(records);
    }
    let image = t.read_image().ctx("read_image")?;
    if image.pixels.len() != pixels || image.pixels.iter().any(|p| !p.is_finite()) {
        return Err("the image has the wrong size or a non-finite pixel".into());
    }
    Ok((image.pixels, all))
}

/// Compares the mean of the image's red channel over each group of pixels with the mean of
/// `expected`; a group is named by `group(pixel)` (`None`: in no group).
fn compare(image: &[Vec3], expected: &[f64], groups: &[&str], group: impl Fn(usize) -> Option<usize>) -> (Vec<f64>, String) {
    let mut errors = Vec::new();
    let mut text = Vec::new();
    for (g, name) in groups.iter().enumerate() {
        let members: Vec<usize> = (0..image.len()).filter(|&i| group(i) == Some(g)).collect();
        if members.is_empty() {
            errors.push(f64::INFINITY);
            text.push(format!("{name}: no pixels"));
            continue;
        }
        let est = members.iter().map(|&i| image[i].x as f64).sum::<f64>() / members.len() as f64;
        let ana = members.iter().map(|&i| expected[i]).sum::<f64>() / members.len() as f64;
        let e = (est / ana - 1.0) * 100.0;
        errors.push(e);
        text.push(format!("{name} {e:+.2}% ({} px)", members.len()));
    }
    (errors, text.join(", "))
}

/// The 8-bit sRGB curve, written out here (independent of the core's).
fn srgb(c: u8) -> f64 {
    let c = c as f64 / 255.0;
    if c <= 0.04045 { c / 12.92 } else { ((c + 0.055) / 1.055).powf(2.4) }
}

/// A textured plane under a point light, photons only: each pixel's radiance is the
/// texture's albedo at its query point times `I cos θ / (π d²)`. Checked for a checkerboard
/// (`to_uv` scaled by 20: squares of half a metre) and for a 2 × 2 sRGB bitmap (nearest,
/// repeat, `to_uv` scaled by 10: texels of one metre), each over the pixels of each albedo.
pub fn texture_plane(t: &mut dyn DynTracer) -> CaseResult {
    let scale20 = UvTransform { rows: [[20.0, 0.0, 0.0], [0.0, 20.0, 0.0]] };
    let (c0, c1) = (0.7f64, 0.25f64);
    let checker = Texture::Checkerboard { color0: Vec3::splat(c0 as f32), color1: Vec3::splat(c1 as f32), to_uv: scale20 };
    // u' = 20 (x + 10)/20 = x + 10: colour0 where the fractional parts of x + 10 and z + 10
    // lie on the same side of ½.
    let checker_albedo = |p: DVec3| {
        let frac = |a: f64| a - a.floor();
        if (frac(p.x + 10.0) > 0.5) == (frac(p.z + 10.0) > 0.5) { c0 } else { c1 }
    };
    let bytes = [[200u8; 3], [60; 3], [120; 3], [255; 3]];
    let bitmap = Texture::Bitmap(Bitmap {
        width: 2,
        height: 2,
        texels: Texels::Srgb8(bytes.to_vec()),
        filter: TextureFilter::Nearest,
        wrap: TextureWrap::Repeat,
        to_uv: UvTransform { rows: [[10.0, 0.0, 0.0], [0.0, 10.0, 0.0]] },
    });
    // u' = (x + 10)/2: texel column ⌊2u'⌋ mod 2 = ⌊x + 10⌋ mod 2, row ⌊z + 10⌋ mod 2.
    let bitmap_albedo = |p: DVec3| {
        let (i, j) = ((p.x + 10.0).floor() as i64 & 1, (p.z + 10.0).floor() as i64 & 1);
        srgb(bytes[(2 * j + i) as usize][0])
    };
    let mut report = Vec::new();
    let mut ok = true;
    for (name, texture, albedo, levels) in [
        ("checkerboard", checker, &checker_albedo as &dyn Fn(DVec3) -> f64, vec![c0, c1]),
        ("bitmap", bitmap, &bitmap_albedo as &dyn Fn(DVec3) -> f64, bytes.iter().map(|b| srgb(b[0])).collect()),
    ] {
        let (image, records) = render(t, &textured_plane(texture), false, ITERATIONS)?;
        let pixels = image.len();
        let mut expected = vec![0.0; pixels];
        // The albedo level every query point of the pixel sees (None: it changes).
        let mut level: Vec<Option<usize>> = vec![None; pixels];
        for (it, rs) in records.iter().enumerate() {
            for r in rs {
                if r.valid != 1 {
                    return Err(format!("{name}: pixel {} has no query point", r.pixel));
                }
                let p = Vec3::from_array(r.position).as_dvec3();
                let a = albedo(p);
                let i = r.pixel as usize;
                expected[i] += a / PI * irradiance(p) / ITERATIONS as f64;
                let l = levels.iter().position(|&x| (x - a).abs() < 1e-12);
                level[i] = if it == 0 || level[i] == l { l } else { None };
            }
        }
        let names: Vec<String> = levels.iter().map(|l| format!("albedo {l:.3}")).collect();
        let names: Vec<&str> = names.iter().map(String::as_str).collect();
        let (errors, text) = compare(&image, &expected, &names, |i| level[i]);
        ok &= errors.iter().all(|e| e.abs() < TOL_PERCENT);
        report.push(format!("{name}: {text}"));
    }
    let msg = format!("{} (tol ±{TOL_PERCENT}%, {ITERATIONS}×{PHOTONS} photons, {SIZE}² px)", report.join("; "));
    if ok { Ok(msg) } else { Err(msg) }
}

/// Height of the mask above the floor (metres).
const MASK_HEIGHT: f64 = 0.5;
/// The mask's square, `x` and `z` ranges at [`MASK_HEIGHT`].
const MASK_X: (f64, f64) = (0.25, 1.25);
const MASK_Z: (f64, f64) = (-0.5, 0.5);
/// Its opacity.
const MASK_OPACITY: f64 = 0.5;
/// Iterations of the mask case: every shadowed query point's light passes the mask or not
/// (a coin toss per shadow ray or photon), so it needs more samples than the texture case.
const MASK_ITERATIONS: u32 = 16;

/// Whether the segment from floor point `p` to the light crosses the mask square.
fn behind_mask(p: DVec3) -> bool {
    let light = DVec3::new(0.0, PLANE_LIGHT_HEIGHT, 0.0);
    let s = (MASK_HEIGHT - p.y) / (light.y - p.y);
    let q = p + (light - p) * s;
    (MASK_X.0..=MASK_X.1).contains(&q.x) && (MASK_Z.0..=MASK_Z.1).contains(&q.z)
}

/// Distance (metres, on the floor) from `p` to the edge of the mask's shadow.
fn shadow_edge_distance(p: DVec3) -> f64 {
    // The shadow is the square scaled by h/(h − m) = 2 about the light's foot.
    let k = PLANE_LIGHT_HEIGHT / (PLANE_LIGHT_HEIGHT - MASK_HEIGHT);
    let (x0, x1, z0, z1) = (MASK_X.0 * k, MASK_X.1 * k, MASK_Z.0 * k, MASK_Z.1 * k);
    let dx = (p.x - x0).abs().min((p.x - x1).abs());
    let dz = (p.z - z0).abs().min((p.z - z1).abs());
    let inside_x = (x0..=x1).contains(&p.x);
    let inside_z = (z0..=z1).contains(&p.z);
    match (inside_x, inside_z) {
        (true, true) => dx.min(dz),
        (true, false) => dz,
        (false, true) => dx,
        (false, false) => dx.hypot(dz),
    }
}

/// A square mask of opacity ½ (a black diffuse surface) half a metre above the lit plane,
/// between the light and part of the floor, with photons only and with direct lighting:
/// the floor in its shadow receives half the irradiance, and camera rays through it reach
/// the floor half the time (a pixel behind it then averages ½ of black and ½ of the
/// half-lit floor). The expected radiance of every query point is computed from its
/// position; the fraction of camera rays stopped by the mask is ½ within its binomial error.
pub fn mask_plane(t: &mut dyn DynTracer) -> CaseResult {
    let mut scene = scenes::lit_plane(SIZE);
    let (x0, x1, z0, z1) = (MASK_X.0 as f32, MASK_X.1 as f32, MASK_Z.0 as f32, MASK_Z.1 as f32);
    // Facing up (towards the light and the camera); material 1: black, half open.
    let mask = scenes::quad("mask", Vec3::new(x0, MASK_HEIGHT as f32, z0), Vec3::new(0.0, 0.0, z1 - z0), Vec3::new(x1 - x0, 0.0, 0.0), 1);
    scene.meshes.push(mask);
    scene.materials.push(scenes::diffuse(0.0));
    scene.textures = SceneTextures { textures: vec![], maps: vec![MaterialMaps::default(), MaterialMaps { opacity: Some(Opacity::Constant(MASK_OPACITY as f32)), ..MaterialMaps::default() }], emission: vec![], environment: None };
    let mut report = Vec::new();
    let mut ok = true;
    for (direct, iterations) in [(false, MASK_ITERATIONS), (true, 4 * MASK_ITERATIONS)] {
        let (image, records) = render(t, &scene, direct, iterations)?;
        let pixels = image.len();
        let mut expected = vec![0.0; pixels];
        let (mut seen_mask, mut behind) = (0u32, 0u32);
        // Per pixel, its floor point (camera ray to y = 0) of the first iteration.
        let mut floor: Vec<DVec3> = vec![DVec3::ZERO; pixels];
        let mut floor_records = vec![0u32; pixels];
        let camera = DVec3::new(0.0, 3.0, 0.0);
        for (it, rs) in records.iter().enumerate() {
            for r in rs {
                let p = Vec3::from_array(r.position).as_dvec3();
                let i = r.pixel as usize;
                let on_mask = r.valid == 1 && (p.y - MASK_HEIGHT).abs() < 1e-3;
                let f = camera + (p - camera) * (camera.y / (camera.y - p.y));
                if it == 0 {
                    floor[i] = f;
                }
                let under = (MASK_X.0 + 0.05..=MASK_X.1 - 0.05).contains(&(f.x * (3.0 - MASK_HEIGHT) / 3.0)) && (MASK_Z.0 + 0.05..=MASK_Z.1 - 0.05).contains(&(f.z * (3.0 - MASK_HEIGHT) / 3.0));
                if under {
                    behind += 1;
                    seen_mask += on_mask as u32;
                }
                if r.valid != 1 || on_mask {
                    continue;
                }
                let open = if behind_mask(p) { 1.0 - MASK_OPACITY } else { 1.0 };
                expected[i] += scenes::PLANE_ALBEDO / PI * irradiance(p) * open / iterations as f64;
                floor_records[i] += 1;
            }
        }
        let fraction = seen_mask as f64 / behind.max(1) as f64;
        let sigma = (0.25 / behind.max(1) as f64).sqrt();
        let fraction_ok = behind > 100 && (fraction - MASK_OPACITY).abs() < 4.0 * sigma;
        // Groups by the pixel's floor point: in the shadow, open, or near its edge (none).
        let group = |i: usize| {
            let p = floor[i];
            (shadow_edge_distance(p) > 0.2).then(|| if behind_mask(p) { 0 } else { 1 })
        };
        let (errors, text) = compare(&image, &expected, &["shadowed", "open"], group);
        // With direct lighting each shadowed query point's one shadow ray passes the mask or
        // not: its estimate is 0 or twice the mean, a relative spread of 1 per query point,
        // so the shadowed mean is allowed 4 of its standard errors where that exceeds the
        // tolerance. The photon estimate averages many photons per point.
        let n: u32 = (0..pixels).filter(|&i| group(i) == Some(0)).map(|i| floor_records[i]).sum();
        let q = 1.0 - MASK_OPACITY;
        let shadow_tol = if direct { TOL_PERCENT.max(400.0 * ((1.0 - q) / (q * n.max(1) as f64)).sqrt()) } else { TOL_PERCENT };
        ok &= fraction_ok && errors[0].abs() < shadow_tol && errors[1].abs() < TOL_PERCENT;
        report.push(format!(
            "direct {} ({iterations} iterations): {text} (shadowed tol ±{shadow_tol:.1}%); camera rays stopped by the mask {:.3} of {behind} (expected {MASK_OPACITY} ± {:.3})",
            if direct { "on" } else { "off" },
            fraction,
            4.0 * sigma
        ));
    }
    // The mask itself lit (albedo 0.8, nothing behind it), photons only: a camera ray that
    // stops on it (half of them) reads the full irradiance arriving there, as Mitsuba's mask
    // gives `o · f`; rays that pass see nothing.
    let (lit, detail) = lit_mask(t)?;
    ok &= lit;
    report.push(detail);
    let msg = format!("{} (tol ±{TOL_PERCENT}%)", report.join("; "));
    if ok { Ok(msg) } else { Err(msg) }
}

/// The mask of [`mask_plane`] alone, albedo 0.8, under the point light; photons only.
/// Returns whether the mean radiance over the pixels looking at its interior is within
/// [`TOL_PERCENT`] of `o · ρ/π · I cos θ / d²` at the query points, and the report.
fn lit_mask(t: &mut dyn DynTracer) -> Result<(bool, String), String> {
    let mut scene = scenes::lit_plane(SIZE);
    let (x0, x1, z0, z1) = (MASK_X.0 as f32, MASK_X.1 as f32, MASK_Z.0 as f32, MASK_Z.1 as f32);
    scene.meshes = vec![scenes::quad("mask", Vec3::new(x0, MASK_HEIGHT as f32, z0), Vec3::new(0.0, 0.0, z1 - z0), Vec3::new(x1 - x0, 0.0, 0.0), 0)];
    let albedo = 0.8;
    scene.materials = vec![scenes::diffuse(albedo as f32)];
    scene.textures = SceneTextures { textures: vec![], maps: vec![MaterialMaps { opacity: Some(Opacity::Constant(MASK_OPACITY as f32)), ..MaterialMaps::default() }], emission: vec![], environment: None };
    let (image, records) = render(t, &scene, false, MASK_ITERATIONS)?;
    let pixels = image.len();
    let mut expected = vec![0.0; pixels];
    let mut inside = vec![true; pixels];
    let (mut stopped, mut cast) = (0u32, 0u32);
    for rs in &records {
        for r in rs {
            let i = r.pixel as usize;
            // Where the pixel's ray meets the mask's plane, from the query point (on the
            // mask) or, for a ray that passed, not known: such a pixel keeps its first class.
            if r.valid == 1 {
                let p = Vec3::from_array(r.position).as_dvec3();
                inside[i] &= (MASK_X.0 + 0.1..=MASK_X.1 - 0.1).contains(&p.x) && (MASK_Z.0 + 0.1..=MASK_Z.1 - 0.1).contains(&p.z);
                expected[i] += albedo / PI * irradiance(p) / MASK_ITERATIONS as f64;
                stopped += 1;
            }
            cast += 1;
        }
    }
    // Pixels that never stopped on the mask are not known to look at it: left out.
    let seen: Vec<bool> = (0..pixels).map(|i| expected[i] > 0.0 && inside[i]).collect();
    let (errors, text) = compare(&image, &expected, &["lit mask"], |i| seen[i].then_some(0));
    Ok((errors[0].abs() < TOL_PERCENT, format!("mask lit alone, photons only: {text}; {stopped} of {cast} camera rays stopped on it")))
}

/// Radiance of the two halves of the textured emitter of [`emitter_texture`] (x < 0, x > 0).
const EMITTER_RADIANCE: [f64; 2] = [4.0, 1.0];
/// Height of the emitter above the floor (metres); it covers `x, z ∈ [-1, 1]`.
const EMITTER_HEIGHT: f64 = 1.0;

/// Irradiance at floor point `p` from the emitter of [`emitter_texture`]: the midpoint rule
/// over each half (`L h² / r⁴`: both cosines are `h / r`), 80 × 160 cells per half.
fn emitter_irradiance(p: DVec3) -> f64 {
    let (nx, nz) = (80, 160);
    let mut e = 0.0;
    for (half, l) in EMITTER_RADIANCE.iter().enumerate() {
        let x0 = half as f64 - 1.0;
        let (dx, dz) = (1.0 / nx as f64, 2.0 / nz as f64);
        for i in 0..nx {
            for k in 0..nz {
                let (x, z) = (x0 + (i as f64 + 0.5) * dx, -1.0 + (k as f64 + 0.5) * dz);
                let r2 = (x - p.x).powi(2) + (z - p.z).powi(2) + EMITTER_HEIGHT * EMITTER_HEIGHT;
                e += l * EMITTER_HEIGHT * EMITTER_HEIGHT / (r2 * r2) * dx * dz;
            }
        }
    }
    e
}

/// A textured area light: a 2 × 2 m square one metre above the floor, facing down, whose
/// radiance is a 2 × 1 float bitmap (nearest): 4 over `x < 0`, 1 over `x > 0`. A camera below
/// it looks down at the floor: each query point's radiance is `ρ/π E` with `E` the
/// irradiance integrated here from the two halves (photons only, then with next-event
/// estimation, which samples the emitter's triangles by power and reads the texture at the
/// sampled point); a camera looking up sees the two radiances themselves.
pub fn emitter_texture(t: &mut dyn DynTracer) -> CaseResult {
    let h = EMITTER_HEIGHT as f32;
    let floor = scenes::quad("floor", Vec3::new(-10.0, 0.0, -10.0), Vec3::new(0.0, 0.0, 20.0), Vec3::new(20.0, 0.0, 0.0), 0);
    // x × z = -y: emits downwards.
    let mut light = scenes::quad("emitter", Vec3::new(-1.0, h, -1.0), Vec3::new(2.0, 0.0, 0.0), Vec3::new(0.0, 0.0, 2.0), 1);
    light.uvs = Some(light.positions.iter().map(|p| Vec2::new((p.x + 1.0) / 2.0, (p.z + 1.0) / 2.0)).collect());
    light.emission = Some(Vec3::ONE);
    let texels = EMITTER_RADIANCE.map(|l| [l as f32; 3]).to_vec();
    let bitmap = Texture::Bitmap(Bitmap { width: 2, height: 1, texels: Texels::Float(texels), filter: TextureFilter::Nearest, wrap: TextureWrap::Clamp, to_uv: UvTransform::IDENTITY });
    let albedo = 0.8;
    let down = scenes::camera(Vec3::new(0.0, 0.8, 0.0), Vec3::ZERO, Vec3::new(0.0, 0.0, -1.0), 2.0 * 0.5f32.atan().to_degrees(), SIZE);
    let mut scene = Scene {
        meshes: vec![floor, light],
        materials: vec![scenes::diffuse(albedo as f32), scenes::diffuse(0.0)],
        lights: vec![],
        camera: down,
        roughness_cutoff: 0.5,
        instancing: None,
        textures: SceneTextures { textures: vec![bitmap], maps: vec![], emission: vec![None, Some(0)], environment: None },
    };
    let mut report = Vec::new();
    let mut ok = true;
    // Next-event estimation draws one point of the emitter per query point and iteration
    // (the bright half lights the dim half's floor too): four times the iterations.
    for (direct, iterations) in [(false, ITERATIONS), (true, 4 * ITERATIONS)] {
        let (image, records) = render(t, &scene, direct, iterations)?;
        let mut expected = vec![0.0; image.len()];
        let mut x = vec![0.0f64; image.len()];
        for rs in &records {
            for r in rs {
                if r.valid != 1 {
                    return Err(format!("pixel {} has no query point on the floor", r.pixel));
                }
                let p = Vec3::from_array(r.position).as_dvec3();
                let i = r.pixel as usize;
                expected[i] += albedo / PI * emitter_irradiance(p) / iterations as f64;
                x[i] = p.x;
            }
        }
        let (errors, text) = compare(&image, &expected, &["under the bright half", "under the dim half"], |i| {
            (x[i].abs() > 0.05).then_some(if x[i] < 0.0 { 0 } else { 1 })
        });
        ok &= errors.iter().all(|e| e.abs() < TOL_PERCENT);
        report.push(format!("direct {} ({iterations} iterations): {text}", if direct { "on" } else { "off" }));
    }
    // Looking up from below: the pixels over each half see its radiance.
    scene.camera = scenes::camera(Vec3::new(0.0, 0.5, 0.0), Vec3::new(0.0, 1.0, 0.0), Vec3::new(0.0, 0.0, -1.0), 2.0 * 0.5f32.atan().to_degrees(), SIZE);
    let (image, _) = render(t, &scene, false, 1)?;
    let (w, hgt) = (SIZE as usize, SIZE as usize);
    // The camera's right is -x (looking up with up = -z): the left columns see x > 0.
    let mean = |cols: std::ops::Range<usize>| {
        let v: Vec<f64> = (hgt / 4..3 * hgt / 4).flat_map(|r| cols.clone().map(move |c| r * w + c)).map(|i| image[i].x as f64).collect();
        v.iter().sum::<f64>() / v.len() as f64
    };
    let (left, right) = (mean(2..w / 2 - 2), mean(w / 2 + 2..w - 2));
    let seen = [right, left];
    let seen_ok = seen.iter().zip(EMITTER_RADIANCE).all(|(s, l)| (s / l - 1.0).abs() < 1e-4);
    ok &= seen_ok;
    report.push(format!("seen from below: {:.4} and {:.4} (expected {} and {})", seen[0], seen[1], EMITTER_RADIANCE[0], EMITTER_RADIANCE[1]));
    let msg = format!("{} (tol ±{TOL_PERCENT}%, {ITERATIONS}×{PHOTONS} photons, {SIZE}² px)", report.join("; "));
    if ok { Ok(msg) } else { Err(msg) }
}
