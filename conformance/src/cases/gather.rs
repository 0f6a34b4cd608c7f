//! Gather exactness: the backend's per-pixel radiance equals
//! [`gather_brute_force`] over the very records the backend stored and the query points
//! it found, within [`GATHER_REL_TOL`], at every scale of a per-pixel bandwidth render
//! ([`gather_brute_force_scales`]), and so do its moment planes
//! ([`arpa_core::gather::scales::moments`] of the expected radiances).
//!
//! The `Tracer` trait has no call to upload arbitrary footprints, so the footprints and
//! query points come from one iteration of the backend on a scene built to produce the
//! hard cases: its own `read_footprints`, `read_photons` and `read_query_points` are read
//! back after the iteration, and the expected pixel is rebuilt on the host as
//! `record.radiance + record.weight · E` with `E` the brute-force irradiance (radii from
//! `read_stats`). Query points exactly on an ellipse boundary cannot be placed through a
//! scene; the case counts how many pairs lie within 1e-3 of the boundary (in `r²`), inside
//! the footprint's box but outside the ellipse, and inside but back-facing (query points
//! on a shelf's underside against footprints on its lit top), and fails if the scene
//! produced none of any kind.

use arpa_core::gather::scales::{PLANES, SCALES};
use arpa_core::gather::estimate::{QueryPoint, gather_brute_force, gather_brute_force_scales};
use arpa_core::store::footprint::PackedFootprint;
use arpa_core::glam::{DMat3, DVec3, Vec3};
use arpa_core::gather::kernel::Kernel;
use arpa_core::render::tracer::{Method, RenderSettings};

use crate::dyn_tracer::DynTracer;
use crate::scenes;
use crate::suite::{CaseResult, Context};

/// Largest relative difference of a pixel component from the brute-force value.
pub const GATHER_REL_TOL: f64 = 1e-5;

/// Half-extents of the box around footprint `fp`'s elliptic slab (from the inverse of its
/// filter transform: `Δ = M y`, ellipse axes `M e_x`, `M e_y`, slab axis `M e_z`).
fn half_extent(fp: &PackedFootprint) -> Option<DVec3> {
    let rows = DMat3::from_cols(
        Vec3::from_array(fp.row_u).as_dvec3(),
        Vec3::from_array(fp.row_v).as_dvec3(),
        Vec3::from_array(fp.row_n).as_dvec3(),
    )
    .transpose();
    let det = rows.determinant();
    if det == 0.0 || !det.is_finite() {
        return None;
    }
    let m = rows.inverse();
    let (a, b, c) = (m.x_axis, m.y_axis, m.z_axis);
    Some(DVec3::new(
        (a.x * a.x + b.x * b.x).sqrt() + c.x.abs(),
        (a.y * a.y + b.y * b.y).sqrt() + c.y.abs(),
        (a.z * a.z + b.z * b.z).sqrt() + c.z.abs(),
    ))
}

#[derive(Default)]
struct Coverage {
    contributing: u64,
    near_boundary: u64,
    box_not_ellipse: u64,
    back_facing: u64,
    photon_near_sphere: u64,
}

/// Iterations compared (the image is their mean, so the accumulation is checked too).
pub const GATHER_ITERATIONS: u32 = 3;

fn check(
    t: &mut dyn DynTracer,
    method: Method,
    kernel: Kernel,
    direct_lighting: bool,
    photons: u32,
) -> CaseResult {
    let scene = scenes::shelf_room(32);
    let settings = RenderSettings {
        method,
        photons_per_iteration: photons,
        seed: 5,
        max_depth: 6,
        direct_lighting,
        kernel,
        ..RenderSettings::default()
    };
    t.upload_scene(&scene, &settings).ctx("upload_scene")?;
    let pixels = (scene.camera.width * scene.camera.height) as usize;
    // Sum over iterations of each pixel's expected value (f64) in every plane of a
    // per-pixel bandwidth render (plane 0 is the image of a global one).
    let mut expected_sum = vec![[DVec3::ZERO; PLANES]; pixels];
    let mut cov = Coverage::default();
    let (mut found, mut reported, mut records) = ([0u64; 2], [0u64; 2], [0usize; 2]);
    let (mut candidates, mut query_points) = ([0u64; 2], 0u64);
    for _ in 0..GATHER_ITERATIONS {
        t.iterate().ctx("iterate")?;
        let queries = t.read_query_points().ctx("read_query_points")?;
        let fps = t.read_footprints().ctx("read_footprints")?;
        let phs = t.read_photons().ctx("read_photons")?;
        let stats = t.read_stats().ctx("read_stats")?;
        let radii = stats.radii.map(|r| r as f32);
        for m in 0..2 {
            reported[m] += stats.contributions[m];
            candidates[m] += stats.candidates[m];
            if stats.candidates[m] < stats.contributions[m] {
                return Err(format!(
                    "map {m}: {} candidates reported but {} contributions",
                    stats.candidates[m], stats.contributions[m]
                ));
            }
        }
        query_points += stats.query_points;
        records[0] += fps.len();
        records[1] += phs.len();
        if queries.len() != pixels {
            return Err(format!(
                "{} query records for {pixels} pixels",
                queries.len()
            ));
        }
        let boxes: Vec<Option<(DVec3, DVec3)>> = fps
            .iter()
            .map(|f| half_extent(f).map(|h| (Vec3::from_array(f.center).as_dvec3(), h)))
            .collect();
        for rec in &queries {
            let Some(sum) = expected_sum.get_mut(rec.pixel as usize) else {
                return Err(format!(
                    "query record for pixel {} outside the image",
                    rec.pixel
                ));
            };
            let known = Vec3::from_array(rec.radiance).as_dvec3();
            let mut scaled = [known; SCALES];
            let expected = if rec.valid == 0 {
                known
            } else {
                let q = QueryPoint {
                    position: Vec3::from_array(rec.position),
                    normal: Vec3::from_array(rec.normal),
                };
                let e = gather_brute_force(&q, &fps, &phs, stats.radii, kernel);
                for (f, c) in found.iter_mut().zip(e.contributions) {
                    *f += u64::from(c);
                }
                cov.contributing += e.footprints as u64;
                for (fp, b) in fps.iter().zip(&boxes) {
                    let y = fp.filter_coords(q.position);
                    let r2 = y.x * y.x + y.y * y.y;
                    let in_slab = y.z.abs() <= 1.0;
                    cov.near_boundary += (in_slab && (r2 - 1.0).abs() <= 1e-3) as u64;
                    cov.back_facing += (in_slab && r2 < 1.0 && !fp.faces(q.normal)) as u64;
                    if let Some((c, h)) = b {
                        let d = (q.position.as_dvec3() - *c).abs();
                        cov.box_not_ellipse +=
                            (d.cmple(*h).all() && !(r2 <= 1.0 && in_slab)) as u64;
                    }
                }
                for ph in &phs {
                    let r = radii[ph.photon_map().index()];
                    let d = (q.position - Vec3::from_array(ph.position)).length();
                    cov.photon_near_sphere += ((d / r - 1.0).abs() <= 1e-3) as u64;
                }
                let weight = Vec3::from_array(rec.weight).as_dvec3();
                let per_scale = gather_brute_force_scales(&q, &fps, &phs, stats.radii, kernel);
                for (s, e) in scaled.iter_mut().zip(&per_scale.per_scale).skip(1) {
                    *s = known + weight * *e;
                }
                known + weight * e.irradiance()
            };
            scaled[0] = expected;
            // What the backend stores for the iteration: finite, in f32.
            let stored = scaled.map(|v| DVec3::select(v.is_finite_mask(), v, DVec3::ZERO).as_vec3());
            let moments = arpa_core::gather::scales::moments(&stored);
            for (p, s) in sum.iter_mut().enumerate() {
                *s += if p < SCALES { stored[p] } else { moments[p - SCALES] }.as_dvec3();
            }
        }
    }
    let image = t.read_image().ctx("read_image")?;
    let accumulation = t.read_accumulation().ctx("read_accumulation")?;
    if image.pixels.len() != pixels || accumulation.pixel_count() != pixels {
        return Err(format!(
            "image has {} pixels, the accumulation {}, expected {pixels}",
            image.pixels.len(),
            accumulation.pixel_count()
        ));
    }
    if image.pixels != accumulation.mean() {
        return Err("read_image differs from the accumulation's image".into());
    }
    let planes = accumulation.planes as usize;
    let (mut worst, mut nonzero) = (0.0f64, 0usize);
    for plane in 0..planes {
        let got_plane = accumulation.plane_mean(plane);
        for (i, (got, sum)) in got_plane.iter().zip(&expected_sum).enumerate() {
            let expected = sum[plane] / GATHER_ITERATIONS as f64;
            let got = got.as_dvec3();
            if plane == 0 {
                nonzero += (expected != DVec3::ZERO) as usize;
            }
            // Moment planes: squares and squared differences of f32 luminances, which
            // cancel; held to the pixel's squared radiance, not to their own size.
            let scale_of = |x: f64| if plane < SCALES { x.abs() } else { (sum[SCALES] / GATHER_ITERATIONS as f64).x.abs().max(x.abs()) };
            for k in 0..3 {
                let (g, x) = (got[k], expected[k]);
                let tol = if plane < SCALES { GATHER_REL_TOL } else { 10.0 * GATHER_REL_TOL };
                let err = if scale_of(x) == 0.0 {
                    if g == 0.0 { 0.0 } else { f64::INFINITY }
                } else {
                    (g - x).abs() / scale_of(x)
                };
                if err.is_nan() || err > tol {
                    return Err(format!(
                        "pixel {i} plane {plane} channel {k}: backend {g:e}, brute force {x:e} (rel {err:.1e} > {tol:e})"
                    ));
                }
                worst = worst.max(err);
            }
        }
    }
    let per_query = |c: [u64; 2]| {
        let n = query_points.max(1) as f64;
        format!("{:.2}/{:.2}", c[0] as f64 / n, c[1] as f64 / n)
    };
    let gathered = if reported == found {
        format!(
            "= brute force per map; per query point caustic/global: candidates {}, contributions {}",
            per_query(candidates),
            per_query(reported)
        )
    } else {
        format!("(backend reports {reported:?} per map, candidates {candidates:?})")
    };
    let arpa = method == Method::Arpa;
    let lacking: Vec<&str> = [
        (nonzero * 4 < pixels, "lit pixels"),
        (records[0] == 0 && arpa, "footprints"),
        (cov.near_boundary == 0 && arpa, "ellipse-boundary pairs"),
        (
            cov.box_not_ellipse == 0 && arpa,
            "box-but-not-ellipse pairs",
        ),
        (cov.back_facing == 0 && arpa, "back-facing pairs"),
        (records[1] == 0, "progressive photons"),
        (
            cov.photon_near_sphere == 0 && !arpa,
            "sphere-boundary pairs",
        ),
    ]
    .iter()
    .filter(|(missing, _)| *missing)
    .map(|(_, what)| *what)
    .collect();
    if !lacking.is_empty() {
        return Err(format!(
            "the scene did not exercise: {}",
            lacking.join(", ")
        ));
    }
    Ok(format!(
        "{pixels} px × {GATHER_ITERATIONS} it × {planes} planes, max rel {worst:.1e}; {} footprints, {} photons; {} contributions {gathered}; pairs: {} near ellipse boundary, {} in box outside ellipse, {} back-facing, {} near sphere boundary",
        records[0],
        records[1],
        found[0] + found[1],
        cov.near_boundary,
        cov.box_not_ellipse,
        cov.back_facing,
        cov.photon_near_sphere
    ))
}

/// ARPA with the default biweight kernel, photons only (direct lighting off).
pub fn arpa_biweight(t: &mut dyn DynTracer) -> CaseResult {
    check(t, Method::Arpa, Kernel::Silverman, false, 20_000)
}

/// ARPA with the constant kernel (a jump at the ellipse boundary: the strictest test of
/// the containment decision), photons only.
pub fn arpa_constant(t: &mut dyn DynTracer) -> CaseResult {
    check(t, Method::Arpa, Kernel::Constant, false, 20_000)
}

/// RTPM (progressive photons only) with next-event estimation, so `record.radiance` is
/// non-zero and enters the expected pixel.
pub fn rtpm(t: &mut dyn DynTracer) -> CaseResult {
    check(t, Method::Rtpm, Kernel::Silverman, true, 20_000)
}
