//! emission.wgsl (with frame.wgsl, sampling.wgsl) against arpa_core::emit::emission: random
//! lights of every kind, prepared on the host (`PreparedLight::pack`), over their whole
//! domain or random projection cells (`EmissionParams::with_cells`), photon `index` of N
//! emitted on the device (`arpa_emission_slot`, then `arpa_emit_in` with the cell of that
//! slot) and by `PreparedLight::emit_in`; the slots must agree exactly (integer
//! arithmetic on both sides); the Fibonacci lattice at large indices.
//!
//! Bounds (ε = f32::EPSILON): the twin is f32 with the core's formulas (cancellation-free
//! where the core's f64 could afford cancellation). Its sin/cos are the device's: lavapipe's
//! are accurate to a few ulps; the Vulkan spec allows 2⁻¹¹ absolute on [−π, π], so on other
//! devices `DIR_TOL` would have to be 2⁻¹¹. The samples differ by up to `DU` (f32 lattice,
//! 24-bit draws), which moves a direction by `DU` times the warp's Jacobian (`2π + 4/sin θ`
//! at the sphere's and cone's poles, `2π + 4/cos θ` at the hemisphere's rim). Checked: origin
//! within `64 ε` of the magnitude of the points it is built from; direction within
//! `DIR_TOL` (2e-5) plus that sample term; the differentials
//! within `DIR_TOL` of their length, times `1 + 1/sin(d, t)` for the area lights' direction
//! frame (built from the hint t); flux within 1e-5 relative plus the spot falloff's slope
//! times the angle error; re-emission length and surface normal exactly as packed. Photons
//! whose lattice point lies within 1e-5 of the unit square's edge are skipped (the wrap of
//! the shifted lattice is decided by rounding there). Environment lights (whole domain only)
//! draw their direction like a point light and hang the disc's frame on it, so their origin
//! and positional differentials also move with the direction error: `4 R` and `4 ℓ_x` times
//! it.

use std::cell::Cell;

use arpa_core::emit::emission::{
    DirectionalLight, EmissionParams, EnvironmentLight, Light, PackedLight, PointLight, QuadLight, SpotFalloff,
    SpotLight, TriangleLight,
};
use arpa_core::glam::{DVec2, DVec3};
use arpa_core::base::rng::{Rng, StreamDomain};
use arpa_core::base::sampling::{fibonacci_lattice, round_robin};
use proptest::prelude::*;

use super::{check, f, fb, proptest_batches, run, run_prop, v3};
use crate::kernel_runner::KernelRunner;
use crate::suite::CaseResult;

const EPS: f64 = f32::EPSILON as f64;
const DIR_TOL: f64 = 2e-5;
/// Largest difference between the twin's and the core's unit-square samples: the f32
/// lattice (a few ulps below 2) and the 24-bit random draws (2⁻²⁴).
const DU: f64 = 2.5e-7;
/// Random lights per batch, and batches.
const ITEMS: usize = 2048;
const BATCHES: u32 = 4;

fn dir() -> impl Strategy<Value = DVec3> {
    (0.0..std::f64::consts::PI, 0.0..std::f64::consts::TAU)
        .prop_map(|(t, p)| DVec3::new(t.sin() * p.cos(), t.sin() * p.sin(), t.cos()))
}

fn point(lo: f64, hi: f64) -> impl Strategy<Value = DVec3> {
    (dir(), lo..hi).prop_map(|(d, e)| (d * 10f64.powf(e)).as_vec3().as_dvec3())
}

fn colour() -> impl Strategy<Value = DVec3> {
    prop::array::uniform3(0.1f64..10.0).prop_map(DVec3::from_array)
}

fn light() -> impl Strategy<Value = Light> {
    prop_oneof![
        (point(-2.0, 2.0), colour()).prop_map(|(position, intensity)| Light::Point(PointLight {
            position,
            intensity
        })),
        (
            point(-2.0, 2.0),
            point(-3.0, 3.0),
            colour(),
            prop_oneof![(1e-3f64..0.1), (0.1f64..std::f64::consts::PI)],
            0.0f64..1.0,
            any::<bool>()
        )
            .prop_map(
                |(position, direction, intensity, cutoff, beam, smooth)| Light::Spot(SpotLight {
                    position,
                    direction,
                    intensity,
                    cutoff,
                    beam_width: cutoff * beam,
                    falloff: if smooth {
                        SpotFalloff::SmoothstepAngle
                    } else {
                        SpotFalloff::LinearAngle
                    },
                })
            ),
        (dir(), colour()).prop_map(|(direction, irradiance)| Light::Directional(
            DirectionalLight {
                direction,
                irradiance
            }
        )),
        (
            point(-2.0, 2.0),
            point(-2.0, 1.0),
            point(-2.0, 1.0),
            colour()
        )
            .prop_map(|(p0, a, b, radiance)| Light::Triangle(TriangleLight {
                p: [p0, p0 + a, p0 + b],
                radiance
            })),
        (
            point(-2.0, 2.0),
            point(-2.0, 1.0),
            point(-2.0, 1.0),
            colour()
        )
            .prop_map(|(origin, edge_u, edge_v, radiance)| Light::Quad(QuadLight {
                origin,
                edge_u,
                edge_v,
                radiance
            })),
        (colour(), colour()).prop_map(|(radiance, mean)| Light::Environment(EnvironmentLight {
            radiance,
            mean
        })),
    ]
}

#[derive(Clone, Debug)]
struct Case {
    light: Light,
    params: EmissionParams,
    index: u32,
    stream: (u32, u32),
    /// Projection cells (empty: the whole domain).
    cells: Vec<u32>,
}

/// A projection: none (half the cases), or some cells of a 4, 16 or 64 grid.
fn projection() -> impl Strategy<Value = (u32, Vec<u32>)> {
    prop_oneof![
        Just((0u32, Vec::new())),
        (prop_oneof![Just(4u32), Just(16u32), Just(64u32)], 0.0f64..1.0, any::<u32>()).prop_map(|(grid, keep, seed)| {
            let mut rng = Rng::new(seed, 0, 0, StreamDomain::User);
            let mut cells: Vec<u32> = (0..grid * grid).filter(|_| rng.next_f64() < keep.max(0.02)).collect();
            if cells.is_empty() {
                cells.push(seed % (grid * grid));
            }
            (grid, cells)
        }),
    ]
}

prop_compose! {
    fn case()(light in light(), n_exp in 0.0f64..6.5, scale in 0.5f64..2.0, centre in point(-1.0, 2.0), r_exp in -1.0f64..3.0,
              shift in (0.0f64..1.0, 0.0f64..1.0), frac in 0.0f64..1.0, stream in (any::<u32>(), any::<u32>()),
              (grid, cells) in projection(), cell_offset in any::<u32>()) -> Case {
        let photon_count = 10f64.powf(n_exp) as u32;
        // An environment samples its whole domain.
        let (grid, cells) = if matches!(light, Light::Environment(_)) { (0, Vec::new()) } else { (grid, cells) };
        // The shift as the device sees it (f32), so both sides start from the same lattice.
        let lattice_shift = DVec2::new(shift.0, shift.1).as_vec2().as_dvec2();
        let params = EmissionParams { photon_count, scale, scene_sphere: (centre, 10f64.powf(r_exp) as f32 as f64), lattice_shift, ..EmissionParams::new(1) }
            .with_cells(grid, cells.len() as u32);
        let params = EmissionParams { cell_offset, ..params };
        Case { light, params, index: ((photon_count as f64 * frac) as u32).min(photon_count - 1), stream, cells }
    }
}

const HELPERS: &str = "
fn in_light(b: u32) -> ArpaLight {
    var l: ArpaLight;
    l.kind = in_u(b); l.falloff = in_u(b + 1u); l.photon_count = in_u(b + 2u);
    l.p0 = in_v3(b + 4u); l.scene_radius = in_f(b + 7u);
    l.p1 = in_v3(b + 8u); l.cutoff = in_f(b + 11u);
    l.p2 = in_v3(b + 12u); l.beam_width = in_f(b + 15u);
    l.frame_t = in_v3(b + 16u); l.len_positional = in_f(b + 19u);
    l.frame_b = in_v3(b + 20u); l.len_directional = in_f(b + 23u);
    l.frame_n = in_v3(b + 24u); l.len_reemission = in_f(b + 27u);
    l.flux = in_v3(b + 28u); l.one_minus_cos_cutoff = in_f(b + 31u);
    l.scene_centre = in_v3(b + 32u);
    l.lattice_shift = vec2<f32>(in_f(b + 36u), in_f(b + 37u));
    l.cell_grid = in_u(b + 3u); l.caustic_weight = in_f(b + 35u);
    l.cell_first = in_u(b + 38u); l.cell_count = in_u(b + 39u); l.cell_offset = in_u(b + 40u);
    return l;
}";

const BODY: &str = "
    let light = in_light(ib);
    let index = in_u(ib + 44u);
    var rng = arpa_rng_new(in_u(ib + 45u), in_u(ib + 46u), index, ARPA_DOMAIN_PHOTON);
    let slot = arpa_emission_slot(light, index, rng);
    var e: ArpaEmitted;
    if light.cell_count == 0u {
        e = arpa_emit(light, index, &rng);
    } else {
        e = arpa_emit_in(light, index, &rng, in_u(ib + 47u));
    }
    out_u(ob + 27u, slot);
    out_v3(ob, e.ray.p); out_v3(ob + 3u, e.ray.d);
    out_v3(ob + 6u, e.ray.dp_du); out_v3(ob + 9u, e.ray.dp_dv);
    out_v3(ob + 12u, e.ray.dd_du); out_v3(ob + 15u, e.ray.dd_dv);
    out_v3(ob + 18u, e.flux); out_f(ob + 21u, e.reemission_length);
    out_v3(ob + 22u, e.surface_normal); out_u(ob + 25u, e.has_surface_normal); out_u(ob + 26u, e.status);";

fn scale_of(l: &Light, p: &EmissionParams) -> f64 {
    match l {
        Light::Point(l) => l.position.length(),
        Light::Spot(l) => l.position.length(),
        Light::Directional(_) | Light::Environment(_) => p.scene_sphere.0.length() + 2.0 * p.scene_sphere.1,
        Light::Triangle(l) => l.p.iter().map(|v| v.length()).sum(),
        Light::Quad(l) => l.origin.length() + l.edge_u.length() + l.edge_v.length(),
    }
}

/// Random lights within the bounds of the module docs, then the lattice at large indices.
pub fn matches_core(runner: &dyn KernelRunner) -> CaseResult {
    let stats = random_lights(runner)?;
    lattice_is_accurate_for_large_indices(runner)?;
    Ok(format!(
        "{stats}; Fibonacci lattice up to index 2^32 - 2 within bound"
    ))
}

fn random_lights(runner: &dyn KernelRunner) -> Result<String, String> {
    let total = Cell::new(0usize);
    let worst_all = Cell::new(0.0f64);
    let strategy = prop::collection::vec(case(), ITEMS);
    proptest_batches("twin-emission", BATCHES, &strategy, |cases| {
        let mut input = Vec::new();
        let mut kept = Vec::new();
        for c in &cases {
            let Ok(prepared) = c.light.prepare(&c.params) else {
                continue;
            };
            let packed: PackedLight = prepared.pack();
            input.extend_from_slice(bytemuck::cast_slice::<PackedLight, u32>(
                std::slice::from_ref(&packed),
            ));
            let rng = Rng::new(c.stream.0, c.stream.1, c.index, StreamDomain::Photon);
            let slot = prepared.emission_slot(c.index, &rng);
            let cell = c.cells.get(slot as usize).copied().unwrap_or(0);
            input.extend([c.index, c.stream.0, c.stream.1, cell]);
            kept.push((c.clone(), prepared));
        }
        prop_assert!(
            kept.len() > cases.len() * 9 / 10,
            "only {} of {} lights prepared",
            kept.len(),
            cases.len()
        );
        let out = run_prop(runner, "emission", HELPERS, BODY, &input, 48, 28)?;
        let (mut compared, mut worst_dir) = (0, 0.0f64);
        for ((c, prepared), g) in kept.iter().zip(&out) {
            let rng = Rng::new(c.stream.0, c.stream.1, c.index, StreamDomain::Photon);
            prop_assert_eq!(g[27], prepared.emission_slot(c.index, &rng), "slot of {:?}", c);
            let area = matches!(c.light, Light::Triangle(_) | Light::Quad(_));
            // The lattice point the photon's primary sample comes from: of the whole
            // light, or of its cell's round-robin share.
            let u = if c.cells.is_empty() || area {
                fibonacci_lattice(c.index, c.params.photon_count, c.params.lattice_shift)
            } else {
                let (_, j, n) = round_robin(c.index, c.params.photon_count, c.cells.len() as u32, c.params.cell_offset);
                fibonacci_lattice(j, n, c.params.lattice_shift)
            };
            if [u.x, u.y]
                .iter()
                .any(|&x| !(1e-5..=1.0 - 1e-5).contains(&x))
            {
                continue;
            }
            let mut rng = Rng::new(c.stream.0, c.stream.1, c.index, StreamDomain::Photon);
            let want = prepared.emit_in(c.index, &mut rng, &c.cells);
            let Ok(w) = want else {
                prop_assert!(
                    g[26] != 0,
                    "core failed ({:?}) but twin succeeded for {:?}",
                    want,
                    c
                );
                continue;
            };
            prop_assert_eq!(g[26], 0, "twin status for {:?}", c);
            compared += 1;
            let s = scale_of(&c.light, &c.params);
            let close =
                |what: &str, got: DVec3, want: DVec3, tol: f64| -> Result<(), TestCaseError> {
                    prop_assert!(
                        (got - want).length() <= tol,
                        "{}: twin {:?} core {:?} (|diff| {:e} > {:e}) for {:?}",
                        what,
                        got,
                        want,
                        (got - want).length(),
                        tol,
                        c
                    );
                    Ok(())
                };
            // Sensitivity of the direction to its unit-square sample (the twin's samples
            // differ from the core's by up to DU: f32 lattice, 24-bit draws), singular where
            // the warp is: at the poles of the sphere and cone, at the rim of the hemisphere.
            let packed = prepared.pack();
            let axis = DVec3::from_array(packed.frame_n.map(f64::from));
            let t_hint = DVec3::from_array(packed.frame_t.map(f64::from));
            let d = w.ray.d;
            let (jacobian, frame_k) = match c.light {
                Light::Point(_) | Light::Environment(_) => (
                    std::f64::consts::TAU + 4.0 / d.cross(DVec3::Z).length().max(1e-9),
                    1.0,
                ),
                Light::Spot(_) => (
                    std::f64::consts::TAU + 4.0 / d.cross(axis).length().max(1e-9),
                    1.0,
                ),
                Light::Directional(_) => (0.0, 1.0),
                _ => (
                    std::f64::consts::TAU + 4.0 / d.dot(axis).abs().max(1e-9),
                    1.0 + 1.0 / d.cross(t_hint).length().max(1e-12),
                ),
            };
            // Where the core's own frame construction branches (Duff's frame at d.z = 0,
            // the hint's parallel fallback), rounding picks the branch: skip.
            if (!area && d.z.abs() < 1e-5) || (area && d.cross(t_hint).length() < 1e-5) {
                continue;
            }
            let dir_tol = DIR_TOL + DU * jacobian;
            // An environment's disc turns with its direction.
            let env = matches!(c.light, Light::Environment(_));
            let turn = if env { 4.0 * dir_tol } else { 0.0 };
            close("origin", v3(g, 0), w.ray.p, 64.0 * EPS * s.max(1e-30) + turn * c.params.scene_sphere.1)?;
            let dd = (v3(g, 3) - w.ray.d).length();
            worst_dir = worst_dir.max(dd / dir_tol);
            close("direction", v3(g, 3), w.ray.d, dir_tol)?;
            let lengths = prepared.lengths();
            close(
                "dP/du",
                v3(g, 6),
                w.ray.dp_du,
                (16.0 * EPS + turn) * lengths.positional,
            )?;
            close(
                "dP/dv",
                v3(g, 9),
                w.ray.dp_dv,
                (16.0 * EPS + turn) * lengths.positional,
            )?;
            close(
                "dD/du",
                v3(g, 12),
                w.ray.dd_du,
                dir_tol * lengths.directional * frame_k,
            )?;
            close(
                "dD/dv",
                v3(g, 15),
                w.ray.dd_dv,
                dir_tol * lengths.directional * frame_k,
            )?;
            let mut flux_tol = 1e-5 * w.flux.length();
            if let Light::Spot(l) = c.light {
                let flux0 = DVec3::from_array(prepared.pack().flux.map(f64::from)).length();
                let theta = l.direction.normalize().dot(w.ray.d).clamp(-1.0, 1.0).acos();
                let dtheta = 2.0 * dir_tol + 4.0 * EPS * theta;
                flux_tol += flux0 * dtheta / (l.cutoff - l.beam_width).max(1e-30);
            }
            close("flux", v3(g, 18), w.flux, flux_tol)?;
            prop_assert_eq!(f(g[21]), w.reemission_length as f32);
            prop_assert_eq!(g[25] == 1, w.surface_normal.is_some());
            if let Some(n) = w.surface_normal {
                close("surface normal", v3(g, 22), n, 2.0 * EPS)?;
            }
        }
        prop_assert!(
            compared > kept.len() * 9 / 10,
            "compared {} of {}",
            compared,
            kept.len()
        );
        total.set(total.get() + compared);
        worst_all.set(worst_all.get().max(worst_dir));
        Ok(())
    })?;
    Ok(format!(
        "{} photons compared; worst direction error / bound {:.3}",
        total.get(),
        worst_all.get()
    ))
}

/// The 64-bit fixed-point Fibonacci lattice keeps its fractional bits for large indices,
/// where an f32 product `i φ` would have none. Bound: the twin's 24-bit truncation (6e-8),
/// the shift's f32 rounding, and the core's own rounding of the f64 product `i φ` (half an
/// ulp, up to 2.4e-7 at i ~ 2³²).
fn lattice_is_accurate_for_large_indices(runner: &dyn KernelRunner) -> Result<(), String> {
    let idx: Vec<u32> = vec![
        0,
        1,
        2,
        1000,
        1 << 20,
        (1 << 24) + 1,
        123_456_789,
        u32::MAX - 1,
    ];
    let n = u32::MAX;
    let input: Vec<u32> = idx
        .iter()
        .flat_map(|&i| [i, n, fb(0.25), fb(0.5)])
        .collect();
    let out = run(
        runner,
        "lattice",
        "let u = arpa_fibonacci_lattice(in_u(ib), in_u(ib + 1u), vec2<f32>(in_f(ib + 2u), in_f(ib + 3u))); out_f(ob, u.x); out_f(ob + 1u, u.y);",
        &input,
        4,
        2,
    )?;
    for (&i, g) in idx.iter().zip(&out) {
        let w = fibonacci_lattice(i, n, DVec2::new(0.25, 0.5));
        for (k, (got, want)) in [(f(g[0]) as f64, w.x), (f(g[1]) as f64, w.y)]
            .into_iter()
            .enumerate()
        {
            let d = (got - want).abs();
            let tol = 1.3e-7 + i as f64 * 0.62 * f64::EPSILON;
            check!(
                d.min(1.0 - d) < tol,
                "index {i} coordinate {k}: twin {got} core {want} (diff {d:e} > {tol:e})"
            );
        }
    }
    Ok(())
}
