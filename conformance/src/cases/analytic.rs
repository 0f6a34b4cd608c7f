//! Closed-form answers: a point light over a diffuse plane (one bounce) and inside a
//! closed diffuse sphere (every bounce).

use std::f64::consts::PI;

use arpa_core::glam::{DVec3, Vec3};
use arpa_core::tracer::{Method, QueryRecord, RenderSettings};

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

/// `ρ/π · I cos θ / d²` at query point `r` of the plane scene.
fn analytic(r: &QueryRecord) -> f64 {
    let light = DVec3::new(0.0, PLANE_LIGHT_HEIGHT, 0.0);
    let d = (light - Vec3::from_array(r.position).as_dvec3()).length();
    PLANE_ALBEDO / PI * PLANE_INTENSITY * (PLANE_LIGHT_HEIGHT / d) / (d * d)
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
        ..RenderSettings::default()
    };
    t.upload_scene(&scene, &settings).ctx("upload_scene")?;
    let pixels = (PLANE_SIZE * PLANE_SIZE) as usize;
    let mut expected = vec![0.0f64; pixels];
    let mut ring = vec![None; pixels];
    for it in 0..PLANE_ITERATIONS {
        t.iterate().ctx("iterate")?;
        let records = t.read_query_points().ctx("read_query_points")?;
        if records.len() != pixels {
            return Err(format!(
                "{} query records for {pixels} pixels",
                records.len()
            ));
        }
        for r in &records {
            if r.valid != 1 {
                return Err(format!(
                    "pixel {}: no query point, but every camera ray hits the plane",
                    r.pixel
                ));
            }
            let p = r.pixel as usize;
            if p >= pixels {
                return Err(format!("query record for pixel {p} outside the image"));
            }
            expected[p] += analytic(r) / PLANE_ITERATIONS as f64;
            if it == 0 {
                let rho = (r.position[0] as f64).hypot(r.position[2] as f64);
                ring[p] = Some((rho / 0.5) as usize).filter(|&k| k < 3);
            }
        }
    }
    let image = t.read_image().ctx("read_image")?;
    if image.pixels.len() != pixels {
        return Err(format!(
            "image has {} pixels, expected {pixels}",
            image.pixels.len()
        ));
    }
    if let Some(p) = image.pixels.iter().find(|p| {
        !p.is_finite()
            || (p.x - p.y).abs() > 1e-5 * p.x.abs()
            || (p.x - p.z).abs() > 1e-5 * p.x.abs()
    }) {
        return Err(format!("grey scene, coloured or non-finite pixel {p:?}"));
    }
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
    plane(t, Method::Arpa)
}

/// The plane case with RTPM progressive photons.
pub fn plane_rtpm(t: &mut dyn DynTracer) -> CaseResult {
    plane(t, Method::Rtpm)
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
        ..RenderSettings::default()
    };
    t.upload_scene(&scene, &settings).ctx("upload_scene")?;
    let mut expected = 0.0;
    for _ in 0..FURNACE_ITERATIONS {
        t.iterate().ctx("iterate")?;
        let records = t.read_query_points().ctx("read_query_points")?;
        let mut sum = 0.0;
        for r in &records {
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
    }
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
    furnace(t, Method::Arpa, true)
}

/// The furnace case with RTPM photons carrying all the light (direct lighting off).
pub fn furnace_rtpm_photons_only(t: &mut dyn DynTracer) -> CaseResult {
    furnace(t, Method::Rtpm, false)
}
