//! Closed-form answers: a point light over a diffuse plane (one bounce) and inside a
//! closed diffuse sphere (every bounce).

use std::f64::consts::PI;

use arpa_core::glam::{DVec3, Vec3};
use arpa_core::accumulate::radius::{ProgressiveConfig, RadiusSpec};
use arpa_core::render::tracer::{Method, QueryRecord, RenderSettings};

use crate::dyn_tracer::DynTracer;
use crate::scenes::{self, PLANE_ALBEDO, PLANE_INTENSITY, PLANE_LIGHT_HEIGHT};
use crate::suite::{CaseResult, Context};

/// Largest error of a region mean (percent).
pub const PLANE_TOL_PERCENT: f64 = 2.0;
/// Image side (pixels).
pub const PLANE_SIZE: u32 = 32;
/// Photons per iteration.
pub const PLANE_PHOTONS: u32 = 50_000;
/// Iterations.
pub const PLANE_ITERATIONS: u32 = 4;

/// A grey scene's image: every pixel finite with equal channels (to 1e-5 relative).
pub(crate) fn check_grey(image: &arpa_core::render::tracer::Image) -> Result<(), String> {
    match image.pixels.iter().find(|p| !p.is_finite() || (p.x - p.y).abs() > 1e-5 * p.x.abs() || (p.x - p.z).abs() > 1e-5 * p.x.abs()) {
        Some(p) => Err(format!("grey scene, coloured or non-finite pixel {p:?}")),
        None => Ok(()),
    }
}

/// `ρ/π · I cos θ / d²` at query point `r` of the plane scene.
fn analytic(r: &QueryRecord) -> f64 {
    let light = DVec3::new(0.0, PLANE_LIGHT_HEIGHT, 0.0);
    let d = (light - Vec3::from_array(r.position).as_dvec3()).length();
    PLANE_ALBEDO / PI * PLANE_INTENSITY * (PLANE_LIGHT_HEIGHT / d) / (d * d)
}

/// Runs `iterations` iterations of the uploaded scene and hands each iteration's query
/// records to `each` (0-based iteration), after checking there is one record per pixel
/// of a `pixels`-pixel image and that every record names a pixel inside it.
fn for_each_iteration(
    t: &mut dyn DynTracer,
    iterations: u32,
    pixels: usize,
    mut each: impl FnMut(u32, &[QueryRecord]) -> Result<(), String>,
) -> Result<(), String> {
    for it in 0..iterations {
        t.iterate().ctx("iterate")?;
        let records = t.read_query_points().ctx("read_query_points")?;
        if records.len() != pixels {
            return Err(format!(
                "{} query records for {pixels} pixels",
                records.len()
            ));
        }
        if let Some(r) = records.iter().find(|r| r.pixel as usize >= pixels) {
            return Err(format!("query record for pixel {} outside the image", r.pixel));
        }
        each(it, &records)?;
    }
    Ok(())
}

/// Point light at height 1 over a diffuse plane, direct lighting off (every bit of the
/// image comes from the photons): the mean radiance of each ring `r ∈ [0, 0.5)`,
/// `[0.5, 1)`, `[1, 1.5)` around the light's foot is within [`PLANE_TOL_PERCENT`] of the
/// mean of `ρ/π · I cos θ / d²` over the same query points (each iteration's own,
/// jittered ones).
fn plane(t: &mut dyn DynTracer, method: Method) -> CaseResult {
    let scene = scenes::lit_plane(PLANE_SIZE);
    let settings = RenderSettings {
        method,
        photons_per_iteration: PLANE_PHOTONS,
        seed: 7,
        max_depth: 4,
        direct_lighting: false,
        emission: super::common::emission(),
        ..RenderSettings::default()
    };
    t.upload_scene(&scene, &settings).ctx("upload_scene")?;
    let pixels = (PLANE_SIZE * PLANE_SIZE) as usize;
    let mut expected = vec![0.0f64; pixels];
    let mut ring = vec![None; pixels];
    for_each_iteration(t, PLANE_ITERATIONS, pixels, |it, records| {
        for r in records {
            if r.valid != 1 {
                return Err(format!(
                    "pixel {}: no query point, but every camera ray hits the plane",
                    r.pixel
                ));
            }
            let p = r.pixel as usize;
            expected[p] += analytic(r) / PLANE_ITERATIONS as f64;
            if it == 0 {
                let rho = (r.position[0] as f64).hypot(r.position[2] as f64);
                ring[p] = Some((rho / 0.5) as usize).filter(|&k| k < 3);
            }
        }
        Ok(())
    })?;
    let image = t.read_image().ctx("read_image")?;
    if image.pixels.len() != pixels {
        return Err(format!(
            "image has {} pixels, expected {pixels}",
            image.pixels.len()
        ));
    }
    check_grey(&image)?;
    let mut errors = Vec::new();
    for k in 0..3 {
        let members: Vec<usize> = (0..pixels).filter(|&i| ring[i] == Some(k)).collect();
        let est = members
            .iter()
            .map(|&i| image.pixels[i].x as f64)
            .sum::<f64>()
            / members.len() as f64;
        let ana = members.iter().map(|&i| expected[i]).sum::<f64>() / members.len() as f64;
        errors.push((est / ana - 1.0) * 100.0);
    }
    let list = errors
        .iter()
        .map(|e| format!("{e:+.2}%"))
        .collect::<Vec<_>>()
        .join(" / ");
    let msg = format!(
        "ring means r<0.5 / <1 / <1.5: {list} (tol ±{PLANE_TOL_PERCENT}%, {PLANE_ITERATIONS}×{PLANE_PHOTONS} photons, {PLANE_SIZE}² px)"
    );
    if errors.iter().all(|e| e.abs() < PLANE_TOL_PERCENT) {
        Ok(msg)
    } else {
        Err(msg)
    }
}

/// The plane case with ARPA footprints.
pub fn plane_arpa(t: &mut dyn DynTracer) -> CaseResult {
    super::common::with_and_without_projection(t, |t| plane(t, Method::Arpa))
}

/// The plane case with RTPM progressive photons.
pub fn plane_rtpm(t: &mut dyn DynTracer) -> CaseResult {
    super::common::with_and_without_projection(t, |t| plane(t, Method::Rtpm))
}

/// Largest error of the furnace's mean radiance (percent).
pub const FURNACE_TOL_PERCENT: f64 = 2.0;
/// Furnace image side (pixels).
pub const FURNACE_SIZE: u32 = 16;
/// Furnace photons per iteration.
pub const FURNACE_PHOTONS: u32 = 30_000;
/// Furnace iterations.
pub const FURNACE_ITERATIONS: u32 = 4;

/// The furnace ([`scenes::furnace`]): a point light at the centre `c` of a closed
/// icosphere of albedo `ρ`. At a query point `q` with normal `n` the direct irradiance is
/// `E_d = I n·(c − q)/|c − q|³`; all emitted power `Φ = 4πI` ends on the wall after
/// `1/(1 − ρ)` bounces on average, and inside a sphere every point sees each patch with the
/// same form factor `dA/(4πR²)`, so the indirect irradiance is uniform,
/// `E_i = ρΦ/((1 − ρ) A)` (A: the facetted wall's area). Expected radiance
/// `ρ/π (E_d + E_i)` averaged over the query points; the image mean must be within
/// [`FURNACE_TOL_PERCENT`].
fn furnace(t: &mut dyn DynTracer, method: Method, direct_lighting: bool) -> CaseResult {
    let scene = scenes::furnace(FURNACE_SIZE);
    let area = scene.meshes[0].area();
    let rho = scenes::FURNACE_ALBEDO;
    let indirect = rho * 4.0 * PI * scenes::FURNACE_INTENSITY / ((1.0 - rho) * area);
    // Deep enough that truncation removes < 1e-9 of the light at albedo 0.5.
    let settings = RenderSettings {
        method,
        photons_per_iteration: FURNACE_PHOTONS,
        seed: 7,
        max_depth: 32,
        direct_lighting,
        emission: super::common::emission(),
        ..RenderSettings::default()
    };
    t.upload_scene(&scene, &settings).ctx("upload_scene")?;
    let pixels = (scene.camera.width * scene.camera.height) as usize;
    let mut expected = 0.0;
    for_each_iteration(t, FURNACE_ITERATIONS, pixels, |_, records| {
        let mut sum = 0.0;
        for r in records {
            if r.valid != 1 {
                return Err(format!(
                    "pixel {}: no query point inside a closed sphere",
                    r.pixel
                ));
            }
            let q = Vec3::from_array(r.position).as_dvec3();
            let n = Vec3::from_array(r.normal).as_dvec3();
            let d = q.length();
            let direct = scenes::FURNACE_INTENSITY * n.dot(-q).max(0.0) / (d * d * d);
            sum += rho / PI * (direct + indirect);
        }
        expected += sum / records.len().max(1) as f64 / FURNACE_ITERATIONS as f64;
        Ok(())
    })?;
    let image = t.read_image().ctx("read_image")?;
    if image.pixels.iter().any(|p| !p.is_finite()) {
        return Err("non-finite pixel".into());
    }
    let mean =
        image.pixels.iter().map(|p| p.x as f64).sum::<f64>() / image.pixels.len().max(1) as f64;
    let error = (mean / expected - 1.0) * 100.0;
    let msg = format!(
        "mean {mean:.4} vs analytic {expected:.4}: {error:+.2}% (tol ±{FURNACE_TOL_PERCENT}%, {FURNACE_ITERATIONS}×{FURNACE_PHOTONS} photons, {FURNACE_SIZE}² px)"
    );
    if error.abs() < FURNACE_TOL_PERCENT {
        Ok(msg)
    } else {
        Err(msg)
    }
}

/// The furnace case with ARPA footprints and next-event estimation for the direct light.
pub fn furnace_arpa_direct(t: &mut dyn DynTracer) -> CaseResult {
    super::common::with_and_without_projection(t, |t| furnace(t, Method::Arpa, true))
}

/// The furnace case with RTPM photons carrying all the light (direct lighting off).
pub fn furnace_rtpm_photons_only(t: &mut dyn DynTracer) -> CaseResult {
    super::common::with_and_without_projection(t, |t| furnace(t, Method::Rtpm, false))
}

/// Largest error of a region mean in the slab and mirror cases (percent).
pub const SPECULAR_TOL_PERCENT: f64 = 2.0;
/// Image side of the slab and mirror cases (pixels).
pub const SPECULAR_SIZE: u32 = 32;
/// Photons per iteration of the slab and mirror cases.
pub const SPECULAR_PHOTONS: u32 = 100_000;
/// Initial caustic radius of the slab and mirror cases (m): 4× the default, so that a
/// few photons per iteration suffice (the irradiance varies on a scale of 1 m, so the
/// kernel's smoothing bias stays ~`r²` ≈ 0.2 %).
pub const SPECULAR_CAUSTIC_RADIUS: f64 = 0.04;
/// Iterations of the slab and mirror cases.
pub const SPECULAR_ITERATIONS: u32 = 4;

/// Renders `scene` photons-only for [`SPECULAR_ITERATIONS`] and compares region means of
/// the image with `Σ weight · E(q)` over each pixel's own query points (the camera
/// weights are checked exactly by the camera cases). `region(q)` assigns a pixel (by its
/// first query point) to one of `names.len()` regions or none.
fn region_means(
    t: &mut dyn DynTracer,
    method: Method,
    scene: &arpa_core::render::scene::Scene,
    max_depth: u32,
    irradiance: impl Fn(DVec3) -> f64,
    region: impl Fn(DVec3) -> Option<usize>,
    names: &[&str],
) -> Result<(Vec<f64>, String), String> {
    let settings = RenderSettings {
        method,
        photons_per_iteration: SPECULAR_PHOTONS,
        seed: 9,
        max_depth,
        direct_lighting: false,
        radii: ProgressiveConfig {
            caustic: RadiusSpec::Absolute(SPECULAR_CAUSTIC_RADIUS),
            ..ProgressiveConfig::default()
        },
        emission: super::common::emission(),
        ..RenderSettings::default()
    };
    t.upload_scene(scene, &settings).ctx("upload_scene")?;
    let pixels = (scene.camera.width * scene.camera.height) as usize;
    let mut expected = vec![0.0f64; pixels];
    let mut member: Vec<Option<Option<usize>>> = vec![None; pixels];
    for_each_iteration(t, SPECULAR_ITERATIONS, pixels, |_, records| {
        for r in records.iter().filter(|r| r.valid == 1) {
            let p = r.pixel as usize;
            let q = Vec3::from_array(r.position).as_dvec3();
            let w = Vec3::from_array(r.weight).as_dvec3();
            expected[p] += w.x * irradiance(q) / SPECULAR_ITERATIONS as f64;
            member[p].get_or_insert(region(q));
        }
        Ok(())
    })?;
    let image = t.read_image().ctx("read_image")?;
    if image.pixels.len() != pixels || image.pixels.iter().any(|p| !p.is_finite()) {
        return Err("image of the wrong size or with non-finite pixels".into());
    }
    let mut errors = Vec::new();
    let mut parts = Vec::new();
    for (k, name) in names.iter().enumerate() {
        let members: Vec<usize> = (0..pixels)
            .filter(|&i| member[i] == Some(Some(k)))
            .collect();
        if members.len() < 20 {
            return Err(format!(
                "region '{name}' has {} pixels (framing error)",
                members.len()
            ));
        }
        let est = members
            .iter()
            .map(|&i| image.pixels[i].x as f64)
            .sum::<f64>();
        let ana = members.iter().map(|&i| expected[i]).sum::<f64>();
        let e = (est / ana - 1.0) * 100.0;
        errors.push(e);
        parts.push(format!("{name} {e:+.2}% ({} px)", members.len()));
    }
    Ok((
        errors,
        format!(
            "{} (tol ±{SPECULAR_TOL_PERCENT}%, {SPECULAR_ITERATIONS}×{SPECULAR_PHOTONS} photons, {}² px)",
            parts.join(", "),
            scene.camera.width
        ),
    ))
}

fn verdict_of(errors: &[f64], msg: String) -> CaseResult {
    if errors.iter().all(|e| e.abs() < SPECULAR_TOL_PERCENT) {
        Ok(msg)
    } else {
        Err(msg)
    }
}

/// Irradiance (W/m²) on the floor of [`scenes::glass_slab`] at horizontal distance `rho`
/// from the light's foot, from the light through the two interfaces (no internal
/// reflection): the ray leaving at angle θ lands at `ρ(θ) = (h_above + h_below) tan θ +
/// t tan θ_t` (`sin θ = n sin θ_t`) carrying `I (1 − F(θ))² dΩ` (the same `F` at both
/// faces), so `E = I (1 − F)² sin θ / (ρ dρ/dθ)`; at `ρ → 0`, `I (1 − F)²/ρ'(0)²`.
pub fn slab_irradiance(rho: f64) -> f64 {
    slab_irradiance_through(rho, scenes::SLAB_THICKNESS)
}

/// [`slab_irradiance`] with the slab `thick` metres thick (its bottom still at
/// [`scenes::SLAB_BOTTOM`]).
pub fn slab_irradiance_through(rho: f64, thick: f64) -> f64 {
    use super::optics::{fresnel, slab_entry_angle, slab_offset_derivative};
    let n = scenes::SLAB_IOR;
    let above = scenes::SLAB_LIGHT.y - scenes::SLAB_BOTTOM - thick;
    let below = scenes::SLAB_BOTTOM;
    let th = slab_entry_angle(rho, above, below, thick, n, 1);
    let tf = 1.0 - fresnel(1.0, n, th);
    let deriv = slab_offset_derivative(th, above, below, thick, n, 1);
    if th < 1e-6 {
        scenes::SLAB_INTENSITY * tf * tf / (deriv * deriv)
    } else {
        scenes::SLAB_INTENSITY * tf * tf * th.sin() / (rho * deriv)
    }
}

/// Glass slab ([`scenes::glass_slab`]), photons only, at most 3 interactions (so only the
/// straight chain top–bottom–floor exists for photons and camera rays alike): the floor
/// seen through the slab has radiance `weight · E(ρ)` with [`slab_irradiance`]'s exact
/// two-interface transmittance. Ring means `ρ < 0.4`, `< 0.8`, `< 1.2` of the light's
/// foot within [`SPECULAR_TOL_PERCENT`]; ignoring Fresnel would be 8 % too bright.
fn glass_slab(t: &mut dyn DynTracer, method: Method) -> CaseResult {
    slab_regions(t, method, &scenes::glass_slab(SPECULAR_SIZE), scenes::SLAB_THICKNESS)
}

/// The region check of [`glass_slab`] on `scene`: the slab scene's layout with the slab
/// `thick` metres thick.
pub(crate) fn slab_regions(t: &mut dyn DynTracer, method: Method, scene: &arpa_core::render::scene::Scene, thick: f64) -> CaseResult {
    let foot = DVec3::new(scenes::SLAB_LIGHT.x, 0.0, scenes::SLAB_LIGHT.z);
    let rho = |q: DVec3| (q - foot).length();
    let (errors, msg) = region_means(
        t,
        method,
        scene,
        3,
        |q| slab_irradiance_through(rho(q), thick),
        |q| Some((rho(q) / 0.4) as usize).filter(|&k| k < 3),
        &["ρ<0.4", "ρ<0.8", "ρ<1.2"],
    )?;
    verdict_of(&errors, msg)
}

/// Margin around the mirror's edge, measured in the mirror plane (m), inside which a
/// pixel is in no region (footprints and pixels straddle the caustic's edge).
pub const MIRROR_EDGE_MARGIN: f64 = 0.08;

/// The point where the image-source ray to floor point `q` crosses the mirror plane.
fn mirror_crossing(q: DVec3) -> DVec3 {
    let image = DVec3::new(
        2.0 * scenes::MIRROR_X - scenes::MIRROR_LIGHT.x,
        scenes::MIRROR_LIGHT.y,
        scenes::MIRROR_LIGHT.z,
    );
    let s = (image.x - scenes::MIRROR_X) / (image.x - q.x);
    image + (q - image) * s
}

/// Irradiance (W/m²) on the floor of [`scenes::mirror_wall`] at `q`: the light's
/// `I cos θ/d²` plus, where the ray from the image source `L'` (the light mirrored in
/// `x = 1`) to `q` crosses the mirror's rectangle, the image source's `I R cos θ'/d'²`.
pub fn mirror_irradiance(q: DVec3) -> f64 {
    let l = scenes::MIRROR_LIGHT;
    let image = DVec3::new(2.0 * scenes::MIRROR_X - l.x, l.y, l.z);
    let point = |src: DVec3| {
        let d = src - q;
        scenes::MIRROR_INTENSITY * (d.y / d.length()) / d.length_squared()
    };
    let m = mirror_crossing(q);
    let through =
        (0.0..=scenes::MIRROR_HEIGHT).contains(&m.y) && m.z.abs() <= scenes::MIRROR_HALF_WIDTH;
    point(l)
        + if through {
            scenes::MIRROR_REFLECTANCE * point(image)
        } else {
            0.0
        }
}

/// Mirror ([`scenes::mirror_wall`]), photons only, at most 2 interactions (light →
/// mirror → floor; no floor → mirror → floor): the floor (seen directly and in the
/// mirror) has radiance `weight · E` with [`mirror_irradiance`]. Region means inside the
/// reflected caustic (crossing at least [`MIRROR_EDGE_MARGIN`] inside the mirror's edge)
/// and beside it (as far outside), each within [`SPECULAR_TOL_PERCENT`]: the caustic has
/// the image source's irradiance and lands where the geometry says.
fn mirror_caustic(t: &mut dyn DynTracer, method: Method) -> CaseResult {
    let scene = scenes::mirror_wall(SPECULAR_SIZE);
    let region = |q: DVec3| {
        let m = mirror_crossing(q);
        let inside_z = scenes::MIRROR_HALF_WIDTH - MIRROR_EDGE_MARGIN;
        let inside_y = MIRROR_EDGE_MARGIN..=scenes::MIRROR_HEIGHT - MIRROR_EDGE_MARGIN;
        if m.z.abs() < inside_z && inside_y.contains(&m.y) {
            Some(0)
        } else if m.z.abs() > scenes::MIRROR_HALF_WIDTH + MIRROR_EDGE_MARGIN {
            Some(1)
        } else {
            None
        }
    };
    let (errors, msg) = region_means(
        t,
        method,
        &scene,
        2,
        mirror_irradiance,
        region,
        &["in caustic", "beside it"],
    )?;
    verdict_of(&errors, msg)
}

/// The slab case with ARPA footprints.
pub fn glass_slab_arpa(t: &mut dyn DynTracer) -> CaseResult {
    super::common::with_and_without_projection(t, |t| glass_slab(t, Method::Arpa))
}

/// The slab case with RTPM progressive photons.
pub fn glass_slab_rtpm(t: &mut dyn DynTracer) -> CaseResult {
    super::common::with_and_without_projection(t, |t| glass_slab(t, Method::Rtpm))
}

/// The mirror case with ARPA footprints.
pub fn mirror_caustic_arpa(t: &mut dyn DynTracer) -> CaseResult {
    super::common::with_and_without_projection(t, |t| mirror_caustic(t, Method::Arpa))
}

/// The mirror case with RTPM progressive photons.
pub fn mirror_caustic_rtpm(t: &mut dyn DynTracer) -> CaseResult {
    super::common::with_and_without_projection(t, |t| mirror_caustic(t, Method::Rtpm))
}

/// Iterations of [`thin_sheet`].
const THIN_ITERATIONS: u32 = 8;

/// Height of the thin sheet in [`thin_sheet`] (m).
const THIN_SHEET_HEIGHT: f32 = 0.5;

/// A thin dielectric sheet (`Material::ThinDielectric`, index 1.5) at height 0.5 between
/// the plane scene's point light (height 1) and its plane, photons only. A photon passes
/// the sheet straight with probability `T(θ) = 1 − 2R/(1 + R)` (`R` the Fresnel reflectance
/// of one face, [`super::optics::fresnel`]), so the plane's irradiance is
/// `T(θ) I cos θ / d²`, θ the angle of the light at the query point. The camera looks
/// through the sheet too, so its records carry its own pass-or-reflect choice: each ring's
/// mean radiance must equal the mean over its pixels' query records of
/// `weight · T(θ) I cos θ / d²` within [`PLANE_TOL_PERCENT`].
fn thin_sheet(t: &mut dyn DynTracer, method: Method) -> CaseResult {
    let mut scene = scenes::lit_plane(PLANE_SIZE);
    scene.materials.push(arpa_core::render::scene::Material::ThinDielectric { ior: 1.5, transmittance: Vec3::ONE });
    scene.meshes.push(scenes::quad("sheet", Vec3::new(-10.0, THIN_SHEET_HEIGHT, -10.0), Vec3::new(20.0, 0.0, 0.0), Vec3::new(0.0, 0.0, 20.0), 1));
    let settings = RenderSettings {
        method,
        photons_per_iteration: 4 * PLANE_PHOTONS,
        seed: 7,
        // Sheet and plane: a photon ends where it is stored, before the light the plane
        // reflects comes back off the sheet's underside (a few per cent more, not in the
        // closed form).
        max_depth: 2,
        direct_lighting: false,
        emission: super::common::emission(),
        // The photons through the sheet are caustic ones, each tiling 1/N of the light's
        // sphere, and the sheet's random reflections leave holes in the tiling that the
        // plane case has none of: wider footprints (S_c = 4, one bandwidth for the image)
        // and 4 × the photons over 8 iterations keep the ring means' noise inside the
        // tolerance with projection off too.
        smoothing: arpa_core::propagate::classify::Smoothing { caustic: 4.0, ..Default::default() },
        bandwidth: arpa_core::gather::scales::Bandwidth::Global,
        ..RenderSettings::default()
    };
    t.upload_scene(&scene, &settings).ctx("upload_scene")?;
    let pixels = (PLANE_SIZE * PLANE_SIZE) as usize;
    let mut expected = vec![0.0f64; pixels];
    let mut ring = vec![None; pixels];
    let mut passed = 0usize;
    for_each_iteration(t, THIN_ITERATIONS, pixels, |it, records| {
        for r in records {
            let p = r.pixel as usize;
            if r.valid == 1 {
                passed += 1;
                let q = Vec3::from_array(r.position).as_dvec3();
                let to_light = DVec3::new(0.0, PLANE_LIGHT_HEIGHT, 0.0) - q;
                let d = to_light.length();
                let cos = PLANE_LIGHT_HEIGHT / d;
                let fr = super::optics::fresnel(1.0, 1.5, cos.acos());
                let transmitted = 1.0 - 2.0 * fr / (1.0 + fr);
                expected[p] += r.weight[0] as f64 * transmitted * PLANE_INTENSITY * cos / (d * d) / THIN_ITERATIONS as f64;
            }
            if it == 0 {
                let (x, z) = (r.pixel % PLANE_SIZE, r.pixel / PLANE_SIZE);
                let (u, v) = ((x as f64 + 0.5) / PLANE_SIZE as f64 - 0.5, (z as f64 + 0.5) / PLANE_SIZE as f64 - 0.5);
                // The camera sees [-1.5, 1.5]² of the plane: rings by the pixel centre's point.
                ring[p] = Some((3.0 * u.hypot(v) / 0.5) as usize).filter(|&k| k < 3);
            }
        }
        Ok(())
    })?;
    // Most camera rays pass the sheet (R' is about 8 % near normal incidence).
    if passed < pixels * THIN_ITERATIONS as usize * 3 / 4 {
        return Err(format!("only {passed} of {} camera rays passed the sheet", pixels * THIN_ITERATIONS as usize));
    }
    let image = t.read_image().ctx("read_image")?;
    check_grey(&image)?;
    let mut errors = Vec::new();
    for k in 0..3 {
        let members: Vec<usize> = (0..pixels).filter(|&i| ring[i] == Some(k)).collect();
        let est = members.iter().map(|&i| image.pixels[i].x as f64).sum::<f64>();
        let ana = members.iter().map(|&i| expected[i]).sum::<f64>();
        errors.push((est / ana - 1.0) * 100.0);
    }
    let list = errors.iter().map(|e| format!("{e:+.2}%")).collect::<Vec<_>>().join(" / ");
    let msg = format!("ring means r<0.5 / <1 / <1.5 through the sheet: {list} (tol ±{PLANE_TOL_PERCENT}%, {passed} of {} camera rays passed it)", pixels * THIN_ITERATIONS as usize);
    if errors.iter().all(|e| e.abs() < PLANE_TOL_PERCENT) { Ok(msg) } else { Err(msg) }
}

/// The thin-sheet case with ARPA footprints, projection maps on and off.
pub fn thin_sheet_arpa(t: &mut dyn DynTracer) -> CaseResult {
    super::common::with_and_without_projection(t, |t| thin_sheet(t, Method::Arpa))
}
