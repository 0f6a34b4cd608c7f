//! The environment light against closed forms: a constant environment of radiance `L` over
//! an unoccluded diffuse plane of albedo `ρ` gives irradiance `πL` on the plane's upper side,
//! so radiance `ρL` there, and `L` where a camera ray leaves the scene. Under an environment
//! map the plane's irradiance is `∫ L(ω) cos θ dω` over the upper hemisphere, summed here on a
//! fine grid of directions from the map's radiance alone (not from its sampling tables, its
//! photons or next-event estimation, which the backends use).

use arpa_core::glam::Vec3;
use arpa_core::propagate::classify::Smoothing;
use arpa_core::render::tracer::{Method, RenderSettings};

use crate::dyn_tracer::DynTracer;
use crate::scenes::{self, ENVIRONMENT_RADIANCE, PLANE_ALBEDO};
use crate::suite::{CaseResult, Context};

/// Image side (pixels).
const SIZE: u32 = 48;
/// Photons per iteration.
const PHOTONS: u32 = 50_000;
/// Iterations.
const ITERATIONS: u32 = 4;
/// Largest error of the plane's mean radiance (percent), next-event estimation: exact for
/// the constant; for the map, the balance heuristic's draws have a relative spread of
/// about 50 % each, so about 1.3 % over the plane's pixels.
const DIRECT_TOL_PERCENT: f64 = 4.0;
/// Largest error of the plane's mean radiance (percent), photons only (away from the
/// plane's edges, where a density estimate loses what falls beyond the edge).
const PHOTONS_TOL_PERCENT: f64 = 3.0;

/// Renders the environment-lit plane ([`scenes::environment_plane`]) with direct lighting
/// on or off and compares: the environment's pixels (no query point) with `L` to `1e-5`,
/// and the mean of the plane's pixels whose query points lie within 0.6 m of its centre
/// (all iterations) with `ρL`.
fn environment_plane(t: &mut dyn DynTracer, direct_lighting: bool, mapped: bool) -> Result<String, String> {
    let scene = if mapped { scenes::environment_map_plane(SIZE) } else { scenes::environment_plane(SIZE) };
    let prepared = arpa_core::render::prepared_scene::PreparedScene::new(scene.clone()).map_err(|e| e.to_string())?;
    let env = prepared.environment().ok_or("no environment")?;
    // ∫ L(ω) cos θ dω over the upper hemisphere: midpoint rule in (φ, cos θ), 1024 × 512.
    let (nphi, nz) = (1024, 512);
    let mut irradiance = arpa_core::glam::DVec3::ZERO;
    for a in 0..nphi {
        let phi = (a as f64 + 0.5) / nphi as f64 * std::f64::consts::TAU;
        for b in 0..nz {
            let z = (b as f64 + 0.5) / nz as f64;
            let r = (1.0 - z * z).sqrt();
            let d = arpa_core::glam::DVec3::new(r * phi.cos(), z, r * phi.sin());
            irradiance += env.radiance(d) * z;
        }
    }
    let irradiance = irradiance * (std::f64::consts::TAU / nphi as f64 / nz as f64);
    let settings = RenderSettings {
        method: Method::Arpa,
        photons_per_iteration: PHOTONS,
        seed: 11,
        max_depth: 4,
        direct_lighting,
        // Each footprint tiles 1/N of the disc, so a query point meets about one: the
        // plane's mean would be as noisy as its query count. Wider footprints (S_g = 4,
        // about 5 cm here, a tenth of the margin to the plane's edge) average over 16.
        smoothing: Smoothing { global: 4.0, ..Smoothing::default() },
        ..RenderSettings::default()
    };
    t.upload_scene(&scene, &settings).ctx("upload_scene")?;
    let pixels = (SIZE * SIZE) as usize;
    // Per pixel: 0 environment, 1 plane inside the region, 2 plane elsewhere (or mixed).
    let mut class = vec![None::<u8>; pixels];
    for it in 0..ITERATIONS {
        t.iterate().ctx("iterate")?;
        let records = t.read_query_points().ctx("read_query_points")?;
        if records.len() != pixels {
            return Err(format!("{} query records for {pixels} pixels", records.len()));
        }
        for r in &records {
            let p = Vec3::from_array(r.position);
            let c = if r.valid != 1 { 0 } else if p.x.abs() < 0.6 && p.z.abs() < 0.6 { 1 } else { 2 };
            let slot = &mut class[r.pixel as usize];
            *slot = match (*slot, it) {
                (_, 0) => Some(c),
                (Some(old), _) if old == c => Some(c),
                _ => Some(2),
            };
        }
    }
    let image = t.read_image().ctx("read_image")?;
    if image.pixels.iter().any(|p| !p.is_finite()) {
        return Err("non-finite pixel".into());
    }
    if !mapped {
        super::analytic::check_grey(&image)?;
    }
    let (mut sky, mut worst_sky, mut plane, mut inside) = (0usize, 0.0f64, 0.0f64, 0usize);
    let luminance = |v: arpa_core::glam::DVec3| v.dot(arpa_core::glam::DVec3::new(0.2126, 0.7152, 0.0722));
    for (i, c) in class.iter().enumerate() {
        let v = luminance(image.pixels[i].as_dvec3());
        match c {
            Some(0) => {
                sky += 1;
                // The pixel's own direction varies with the jitter: only the constant's is exact.
                if !mapped {
                    worst_sky = worst_sky.max((v / ENVIRONMENT_RADIANCE - 1.0).abs());
                }
            }
            Some(1) => {
                plane += v;
                inside += 1;
            }
            _ => {}
        }
    }
    if sky < pixels / 10 || inside < pixels / 10 {
        return Err(format!("{sky} environment and {inside} plane pixels: the camera does not see both"));
    }
    // ρ/π · E (luminance).
    let expected = PLANE_ALBEDO / std::f64::consts::PI * luminance(irradiance);
    let error = (plane / inside as f64 / expected - 1.0) * 100.0;
    let tol = if direct_lighting { DIRECT_TOL_PERCENT } else { PHOTONS_TOL_PERCENT };
    let msg = format!(
        "{} {}: plane {error:+.2}% of ρE/π = {expected:.3} over {inside} px (tol ±{tol}%), environment within {worst_sky:.1e} of L over {sky} px",
        if mapped { "map" } else { "constant" },
        if direct_lighting { "next-event estimation" } else { "photons only" }
    );
    if error.abs() < tol && worst_sky < 1e-5 { Ok(msg) } else { Err(msg) }
}

/// The plane under a constant environment, next-event estimation (exact: the cosine draw
/// alone; the constant's photons are the twin-emission case's and the map case's, which
/// share the disc). With the default emission strategy: an environment is never
/// projected, so projection maps change nothing for it.
pub fn constant_environment(t: &mut dyn DynTracer) -> CaseResult {
    environment_plane(t, true, false)
}

/// The plane under an environment map, next-event estimation (the map's sampling under
/// the balance heuristic) and photons only (directions drawn by the map).
pub fn map_environment(t: &mut dyn DynTracer) -> CaseResult {
    let direct = environment_plane(t, true, true)?;
    let photons = environment_plane(t, false, true)?;
    Ok(format!("{direct}; {photons}"))
}
