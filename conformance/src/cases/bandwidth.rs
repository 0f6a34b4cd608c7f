//! Per-pixel bandwidth ([`arpa_core::accumulate::bandwidth`]) against closed-form light: an evenly lit
//! plane, where every scale is unbiased and the selection must keep the largest, and a
//! hard shadow edge, where the larger scales blur the step and the selection must go
//! smaller near the edge only, and come out sharper than the global bandwidth.

use std::f64::consts::{FRAC_1_SQRT_2, PI};

use arpa_core::gather::scales::Bandwidth;
use arpa_core::glam::Vec3;
use arpa_core::render::tracer::{Method, QueryRecord, RenderSettings};

use crate::dyn_tracer::DynTracer;
use crate::scenes::{self, BANDWIDTH_ALBEDO, BANDWIDTH_IRRADIANCE};
use crate::suite::{CaseResult, Context};

/// Image side (pixels).
pub const SIZE: u32 = 48;
/// Photons per iteration.
pub const PHOTONS: u32 = 40_000;
/// Iterations.
pub const ITERATIONS: u32 = 16;
/// Smoothing factor `S_g` of the stored footprints: large (and without dampening and
/// culling, which would shrink or reject them), so that the stored scale covers a point
/// with dozens of footprints (little noise) and blurs the edge over several pixels.
pub const SMOOTHING: f64 = 6.0;
/// Largest error of the lit region's mean radiance (percent).
pub const TOL_PERCENT: f64 = 3.0;

/// `ρ/π · E/√2`: the lit floor's radiance (W/(m²·sr)).
pub fn lit_radiance() -> f64 {
    BANDWIDTH_ALBEDO / PI * BANDWIDTH_IRRADIANCE * FRAC_1_SQRT_2
}

/// What one render of a bandwidth scene gives: per pixel the floor's `x` (metres, from the
/// last camera pass), the radiance (grey channel) and the chosen scale index.
struct Render {
    x: Vec<f32>,
    radiance: Vec<f64>,
    scale: Vec<f32>,
}

fn render(t: &mut dyn DynTracer, occluded: bool, bandwidth: Bandwidth) -> Result<Render, String> {
    let scene = scenes::bandwidth_plane(SIZE, occluded);
    let settings = RenderSettings {
        method: Method::Arpa,
        photons_per_iteration: PHOTONS,
        seed: 11,
        max_depth: 3,
        direct_lighting: false,
        bandwidth,
        emission: super::common::emission(),
        smoothing: arpa_core::propagate::classify::Smoothing { caustic: SMOOTHING, global: SMOOTHING },
        heuristics: arpa_core::store::heuristics::Heuristics { dampening: None, culling: None, ..Default::default() },
        ..RenderSettings::default()
    };
    t.upload_scene(&scene, &settings).ctx("upload_scene")?;
    for _ in 0..ITERATIONS {
        t.iterate().ctx("iterate")?;
    }
    let records: Vec<QueryRecord> = t.read_query_points().ctx("read_query_points")?;
    let image = t.read_image().ctx("read_image")?;
    super::analytic::check_grey(&image)?;
    let acc = t.read_accumulation().ctx("read_accumulation")?;
    let selection = acc.selection();
    let px = (SIZE * SIZE) as usize;
    if records.len() != px || image.pixels.len() != px || selection.scale.len() != px {
        return Err(format!("{} records, {} pixels, {} scales for {px} pixels", records.len(), image.pixels.len(), selection.scale.len()));
    }
    if let Some(r) = records.iter().find(|r| r.valid == 0) {
        return Err(format!("pixel {} sees no floor", r.pixel));
    }
    let mut x = vec![0.0; px];
    for r in &records {
        x[r.pixel as usize] = r.position[0];
    }
    if image.pixels != selection.image {
        return Err("read_image differs from the accumulation's selection".into());
    }
    Ok(Render { x, radiance: image.pixels.iter().map(|p: &Vec3| f64::from(p.x)).collect(), scale: selection.scale })
}

/// Mean of `v` over the pixels where `keep(x)`, and their number.
fn mean_where(r: &Render, v: impl Fn(usize) -> f64, keep: impl Fn(f32) -> bool) -> (f64, usize) {
    let idx: Vec<usize> = (0..r.x.len()).filter(|&i| keep(r.x[i])).collect();
    (idx.iter().map(|&i| v(i)).sum::<f64>() / idx.len().max(1) as f64, idx.len())
}

/// The evenly lit plane: the mean radiance is within [`TOL_PERCENT`] of `ρ/π · E/√2`, the
/// mean scale index is at most 0.25 and at least 90 % of the pixels keep scale 0 (index
/// below 0.5).
fn flat(t: &mut dyn DynTracer) -> CaseResult {
    let r = render(t, false, Bandwidth::PerPixel)?;
    let exact = lit_radiance();
    let (mean, _) = mean_where(&r, |i| r.radiance[i], |_| true);
    let err = 100.0 * (mean / exact - 1.0);
    let (scale, _) = mean_where(&r, |i| f64::from(r.scale[i]), |_| true);
    let largest = r.scale.iter().filter(|&&c| c < 0.5).count() as f64 / r.scale.len() as f64;
    let msg = format!("mean {mean:.5} against {exact:.5} ({err:+.2} %), mean scale index {scale:.3}, {:.1} % of pixels at scale 0", 100.0 * largest);
    if err.abs() > TOL_PERCENT || scale > 0.25 || largest < 0.9 {
        return Err(msg);
    }
    Ok(msg)
}

/// Half-width of the band around the edge in which the scales must shrink (metres: about
/// three footprints of the stored scale at these settings).
pub const NEAR: f32 = 0.06;
/// Distance from the edge beyond which the lit floor counts as flat (metres).
pub const FAR: f32 = 0.2;

/// The hard shadow edge: within [`NEAR`] of it the mean scale index is at least 1 (the
/// larger scales are left), on the lit floor beyond [`FAR`] at most 0.75 and at least one
/// scale below the edge's; the squared error
/// against the exact step over the band `|x| < 2 NEAR` is below 0.8 times the global
/// bandwidth's at the same iterations and seed; and the lit floor beyond [`FAR`] is within
/// [`TOL_PERCENT`] of `ρ/π · E/√2`.
fn shadow_edge(t: &mut dyn DynTracer) -> CaseResult {
    let pp = render(t, true, Bandwidth::PerPixel)?;
    let global = render(t, true, Bandwidth::Global)?;
    let exact = lit_radiance();
    let step = |x: f32| if x > 0.0 { exact } else { 0.0 };
    let (near, n_near) = mean_where(&pp, |i| f64::from(pp.scale[i]), |x| x.abs() < NEAR);
    let (far, n_far) = mean_where(&pp, |i| f64::from(pp.scale[i]), |x| x > FAR);
    let band_error = |r: &Render| mean_where(r, |i| (r.radiance[i] - step(r.x[i])).powi(2), |x| x.abs() < 2.0 * NEAR).0 / (exact * exact);
    let (e_pp, e_global) = (band_error(&pp), band_error(&global));
    let (lit, _) = mean_where(&pp, |i| pp.radiance[i], |x| x > FAR);
    let err = 100.0 * (lit / exact - 1.0);
    let msg = format!(
        "scale index near the edge {near:.2} ({n_near} px), far on the lit side {far:.2} ({n_far} px); band relative MSE per-pixel {e_pp:.4e} against global {e_global:.4e} ({:.2}x); lit floor {err:+.2} %",
        e_pp / e_global
    );
    let failed = n_near == 0 || n_far == 0 || near < 1.0 || far > 0.75 || near < far + 1.0 || e_pp >= 0.8 * e_global || !e_pp.is_finite() || err.abs() > TOL_PERCENT;
    if failed {
        return Err(msg);
    }
    Ok(msg)
}

/// The evenly lit plane (mean within [`TOL_PERCENT`], mean scale index at most 0.25, at
/// least 90 % of the pixels at scale 0) with projection on and off.
pub fn flat_plane(t: &mut dyn DynTracer) -> CaseResult {
    super::common::with_and_without_projection(t, flat)
}

/// The hard shadow edge (smaller scales within [`NEAR`] of the edge, larger beyond
/// [`FAR`], band error below 0.8 times the global bandwidth's) with projection on and off.
pub fn shadow_edge_case(t: &mut dyn DynTracer) -> CaseResult {
    super::common::with_and_without_projection(t, shadow_edge)
}
