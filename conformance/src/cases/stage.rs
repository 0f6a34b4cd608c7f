//! Stage agreement: the backend's photon pass stores what `arpa-core`'s reference photon
//! path ([`trace_photon`] over the f64 [`BruteForceCaster`]) stores, photon for photon.

use arpa_core::store::footprint::PackedFootprint;
use arpa_core::glam::{DVec3, Vec3};
use arpa_core::render::photon_path::{PhotonPassSetup, trace_photon};
use arpa_core::render::prepared_scene::PreparedScene;
use arpa_core::store::progressive_photon::PackedPhoton;
use arpa_core::render::brute_force::BruteForceCaster;
use arpa_core::store::decision::StoredPhoton;
use arpa_core::render::tracer::{Method, RenderSettings};

use super::common::rel;
use crate::dyn_tracer::DynTracer;
use crate::scenes;
use crate::suite::{CaseResult, Context};

/// Position tolerance, relative to the scene's bounding-box diagonal.
pub const POSITION_TOL: f64 = 1e-4;
/// Tolerance of each filter-transform row and of the flux (density), relative.
pub const RECORD_REL_TOL: f64 = 1e-3;
/// Tolerance of a progressive photon's unit normal (absolute).
pub const NORMAL_TOL: f64 = 1e-4;

fn v(a: [f32; 3]) -> DVec3 {
    Vec3::from_array(a).as_dvec3()
}

/// Errors `[position (m), rows (rel), flux density (rel)]` of footprint `a` against `b`.
fn footprint_errors(a: &PackedFootprint, b: &PackedFootprint) -> [f64; 3] {
    let rows = [(a.row_u, b.row_u), (a.row_v, b.row_v), (a.row_n, b.row_n)]
        .iter()
        .map(|&(x, y)| rel(v(x), v(y)))
        .fold(0.0, f64::max);
    [
        (v(a.center) - v(b.center)).length(),
        rows,
        rel(a.flux_density().as_dvec3(), b.flux_density().as_dvec3()),
    ]
}

/// Errors `[position (m), normal, flux (rel)]` of photon `a` against `b`.
fn photon_errors(a: &PackedPhoton, b: &PackedPhoton) -> [f64; 3] {
    [
        (v(a.position) - v(b.position)).length(),
        (v(a.normal) - v(b.normal)).length(),
        rel(v(a.flux), v(b.flux)),
    ]
}

/// Matches `got` to `want` one to one, each pair of the same map and with every error
/// within its tolerance; returns the largest errors over the pairs. Tries the order the
/// records come in first, then any order (a GPU may append in any order).
fn match_records<T>(
    got: &[T],
    want: &[T],
    what: &str,
    pos: impl Fn(&T) -> DVec3,
    map: impl Fn(&T) -> u32,
    errors: impl Fn(&T, &T) -> [f64; 3],
    tol: [f64; 3],
) -> Result<[f64; 3], String> {
    if got.len() != want.len() {
        return Err(format!(
            "{} {what} stored, the core stores {}",
            got.len(),
            want.len()
        ));
    }
    let score = |e: [f64; 3]| (0..3).map(|k| e[k] / tol[k]).fold(0.0, f64::max);
    let fold = |m: [f64; 3], e: [f64; 3]| [m[0].max(e[0]), m[1].max(e[1]), m[2].max(e[2])];
    // Same order?
    let mut worst = [0.0; 3];
    let in_order = got.iter().zip(want).all(|(a, b)| {
        let e = errors(a, b);
        worst = fold(worst, e);
        map(a) == map(b) && score(e) <= 1.0
    });
    if in_order {
        return Ok(worst);
    }
    // Any order: candidates within the position tolerance in x, best score wins.
    let mut order: Vec<usize> = (0..want.len()).collect();
    order.sort_by(|&i, &j| pos(&want[i]).x.total_cmp(&pos(&want[j]).x));
    let xs: Vec<f64> = order.iter().map(|&i| pos(&want[i]).x).collect();
    let mut used = vec![false; want.len()];
    let mut worst = [0.0; 3];
    let mut unmatched = Vec::new();
    for (gi, a) in got.iter().enumerate() {
        let x = pos(a).x;
        let lo = xs.partition_point(|&w| w < x - tol[0]);
        let hi = xs.partition_point(|&w| w <= x + tol[0]);
        let best = (lo..hi)
            .map(|k| order[k])
            .filter(|&i| !used[i] && map(&want[i]) == map(a))
            .map(|i| (i, errors(a, &want[i])))
            .min_by(|x, y| score(x.1).total_cmp(&score(y.1)));
        match best {
            Some((i, e)) if score(e) <= 1.0 => {
                used[i] = true;
                worst = fold(worst, e);
            }
            _ => unmatched.push(gi),
        }
    }
    if unmatched.is_empty() {
        Ok(worst)
    } else {
        Err(format!(
            "{} of {} {what} match no record of the core within tolerance (first: #{} at {:?})",
            unmatched.len(),
            got.len(),
            unmatched[0],
            pos(&got[unmatched[0]])
        ))
    }
}

/// The reference: every photon of iteration 0 through [`trace_photon`] with the
/// brute-force caster, in photon-index order.
pub fn reference_photon_pass(
    scene: &arpa_core::render::scene::Scene,
    settings: &RenderSettings,
) -> Result<(Vec<PackedFootprint>, Vec<PackedPhoton>, u32), String> {
    let prepared =
        PreparedScene::new(scene.clone()).map_err(|e| format!("core rejects the scene: {e}"))?;
    let caster = BruteForceCaster::new(&prepared);
    let setup = PhotonPassSetup::new(&prepared, settings, 0);
    let (mut fps, mut phs) = (Vec::new(), Vec::new());
    for index in 0..setup.photon_count() {
        trace_photon(
            &prepared,
            &caster,
            settings,
            &setup,
            index,
            &mut |s| match s {
                StoredPhoton::Footprint { packed, .. } => fps.push(packed),
                StoredPhoton::Progressive { photon, .. } => phs.push(photon),
            },
        );
    }
    Ok((fps, phs, setup.photon_count()))
}

/// Photon pass of iteration 0 on the glass-and-mirror room (ARPA, 4000 global photons and a
/// caustic pass of 2000 aimed at the glass and the mirror, direct photons stored): counts
/// exact, records within [`POSITION_TOL`]·diagonal, [`RECORD_REL_TOL`], [`NORMAL_TOL`];
/// statistics consistent with the buffers.
pub fn photon_pass_agreement(t: &mut dyn DynTracer) -> CaseResult {
    let scene = scenes::glass_mirror_room(16);
    let settings = RenderSettings {
        method: Method::Arpa,
        photons_per_iteration: 4000,
        seed: 11,
        max_depth: 8,
        direct_lighting: false,
        // An explicit caustic pass: the automatic count skips it in this room (the glass
        // and the mirror fill much of the light's view).
        emission: arpa_core::render::tracer::EmissionStrategy { projection: true, caustic_photons: Some(2000) },
        ..RenderSettings::default()
    };
    t.upload_scene(&scene, &settings).ctx("upload_scene")?;
    t.photon_pass().ctx("photon_pass")?;
    let fps = t.read_footprints().ctx("read_footprints")?;
    let phs = t.read_photons().ctx("read_photons")?;
    let stats = t.read_stats().ctx("read_stats")?;
    let (want_fp, want_ph, emitted) = reference_photon_pass(&scene, &settings)?;
    // The scene must exercise both maps and the fallback, or the case proves little.
    let caustic = want_fp.iter().filter(|f| f.map == 0).count();
    if caustic == 0 || caustic == want_fp.len() || want_ph.is_empty() {
        return Err(format!(
            "degenerate scene: core stores {} footprints ({caustic} caustic), {} photons",
            want_fp.len(),
            want_ph.len()
        ));
    }
    if stats.photons_emitted != emitted as u64 {
        return Err(format!(
            "stats: {} photons emitted, the core emits {emitted}",
            stats.photons_emitted
        ));
    }
    let count = |m: [u64; 2]| m[0] + m[1];
    if count(stats.footprints) != fps.len() as u64 || count(stats.progressive) != phs.len() as u64 {
        return Err(format!(
            "stats count {:?} footprints, {:?} photons; buffers hold {}, {}",
            stats.footprints,
            stats.progressive,
            fps.len(),
            phs.len()
        ));
    }
    let diag = scene.bounds().diagonal();
    let e_fp = match_records(
        &fps,
        &want_fp,
        "footprints",
        |f| v(f.center),
        |f| f.map,
        footprint_errors,
        [POSITION_TOL * diag, RECORD_REL_TOL, RECORD_REL_TOL],
    )?;
    let e_ph = match_records(
        &phs,
        &want_ph,
        "photons",
        |p| v(p.position),
        |p| p.map,
        photon_errors,
        [POSITION_TOL * diag, NORMAL_TOL, RECORD_REL_TOL],
    )?;
    Ok(format!(
        "{} footprints ({caustic} caustic) + {} photons, counts exact; max Δ: footprint centre {:.1e} m, rows {:.1e}, flux density {:.1e}; photon position {:.1e} m, normal {:.1e}, flux {:.1e}",
        fps.len(),
        phs.len(),
        e_fp[0],
        e_fp[1],
        e_fp[2],
        e_ph[0],
        e_ph[1],
        e_ph[2]
    ))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn fp(x: f32, map: u32) -> PackedFootprint {
        PackedFootprint {
            center: [x, 0.5 * x, 1.0],
            map,
            row_u: [1.0, 0.0, 0.0],
            flux_density_r: 2.0,
            row_v: [0.0, 0.0, 1.0],
            flux_density_g: 2.0,
            row_n: [0.0, 10.0, 0.0],
            flux_density_b: 2.0,
        }
    }

    fn run(got: &[PackedFootprint], want: &[PackedFootprint]) -> Result<[f64; 3], String> {
        match_records(
            got,
            want,
            "footprints",
            |f| v(f.center),
            |f| f.map,
            footprint_errors,
            [1e-4, 1e-3, 1e-3],
        )
    }

    #[test]
    fn matching_is_order_independent_and_strict() {
        let want: Vec<_> = (0..50).map(|i| fp(i as f32 * 0.01, i % 2)).collect();
        // Reversed and perturbed within tolerance: matches.
        let mut got: Vec<_> = want.iter().rev().copied().collect();
        got[3].center[0] += 5e-5;
        got[7].flux_density_g *= 1.0005;
        let e = run(&got, &want).unwrap();
        assert!(e[0] > 4e-5 && e[2] > 1e-4, "{e:?}");
        // One record beyond the position tolerance.
        let mut bad = got.clone();
        bad[10].center[1] += 1e-3;
        assert!(run(&bad, &want).is_err());
        // Wrong map.
        let mut bad = got.clone();
        bad[0].map ^= 1;
        assert!(run(&bad, &want).is_err());
        // A record missing, or one twice.
        assert!(run(&got[1..], &want).is_err());
        let mut dup = got.clone();
        dup[1] = dup[0];
        assert!(run(&dup, &want).is_err());
    }
}
