//! The device photon pass (`arpa_wgpu::photon`) against the core's
//! `arpa_core::render::photon_path::trace_photon` with the core's brute-force caster, photon by
//! photon, on small scenes: a closed diffuse box with a glass sphere, a diffuse sphere and
//! a mirror sphere (all with vertex normals), a mirror panel, a mirror whose vertex normals
//! vanish (differentials lost there), an emissive quad and a point light; and a floor
//! under a flat glass slab lit by a spot, a directional and a triangle light.
//!
//! The device runs in `f32`, the core in `f64`; the hit points come from two different
//! ray casters (lavapipe's ray queries, the core's `f64` Möller–Trumbore). A photon's
//! path can therefore take another branch where a decision sits within that rounding of
//! its threshold (Fresnel choice, a ray grazing a triangle edge or a silhouette, the
//! heuristics' thresholds), after which the two paths are unrelated. So the test compares:
//! * the fraction of photons whose decisions agree (same stored records in the same order,
//!   same kind after the store, same maps) and whose records (position, normal, flux, map,
//!   `D_u`, `D_v`) lie within the `f32` bounds of [`TIGHT`]: at least 99 %;
//! * for every photon whose decisions agree, every record within [`COARSE`], the bound of
//!   `f32` rounding amplified along the path;
//! * the counters (photons, segments, records per map) within 1 % of the core's totals.
//!
//! Footprints leave the device before the heuristics (with the smoothing applied); the
//! test runs them through the core's `store_footprint` (smoothing 1) and compares
//! the result with what `trace_photon` stored, `D_u`, `D_v` recovered from the records'
//! filter-space rows and compared as the ellipse they span.

use crate::common::gpu;
use arpa_core::propagate::classify::Smoothing;
use arpa_core::emit::emission::{DirectionalLight, Light, PointLight, SpotFalloff, SpotLight, TriangleLight};
use arpa_core::store::footprint::{Footprint, PackedFootprint, PhotonMap};
use arpa_core::glam::{DMat3, DVec3, Vec3};
use arpa_core::store::heuristics::Heuristics;
use arpa_core::render::photon_path::{PhotonPassSetup, trace_photon};
use arpa_core::render::prepared_scene::PreparedScene;
use arpa_core::store::progressive_photon::PackedPhoton;
use arpa_core::render::brute_force::BruteForceCaster;
use arpa_core::base::rng::{Rng, StreamDomain};
use arpa_core::render::scene::{Camera, Material, Scene, TriangleMesh};
use arpa_core::render::shapes::{icosphere, parallelogram};
use arpa_core::{store::heuristics::ProgressiveReason, store::decision::{StoredPhoton, store_footprint}};
use arpa_core::render::tracer::{Method, RenderSettings};
use arpa_wgpu::GpuContext;
use arpa_wgpu::photon::{PhotonOutputs, PhotonPass};
use crate::support::{PhotonReadback, read_outputs};
use arpa_wgpu::scene::GpuScene;

fn camera() -> Camera {
    Camera { position: Vec3::new(0.0, 0.0, 3.0), target: Vec3::ZERO, up: Vec3::Y, vertical_fov: 0.8, width: 16, height: 16 }
}

/// A closed box `[-1, 1]³` (normals inwards), a smooth glass sphere, a smooth diffuse
/// sphere, a mirror panel, an emissive quad under the ceiling and a point light.
fn box_scene() -> Scene {
    let materials = vec![
        Material::Diffuse { albedo: Vec3::splat(0.75) },
        Material::Diffuse { albedo: Vec3::new(0.6, 0.1, 0.05) },
        Material::Dielectric { ior: 1.5, transmittance: Vec3::ONE, roughness: 0.0 },
        Material::Conductor { reflectance: Vec3::splat(0.9), roughness: 0.0 },
        Material::Diffuse { albedo: Vec3::new(0.3, 0.7, 0.4) },
    ];
    let (x, y, z) = (Vec3::X * 2.0, Vec3::Y * 2.0, Vec3::Z * 2.0);
    let o = Vec3::splat(-1.0);
    let mut meshes = vec![
        parallelogram("floor", o, z, x, 0),
        parallelogram("ceiling", Vec3::new(-1.0, 1.0, -1.0), x, z, 0),
        parallelogram("back", o, x, y, 0),
        parallelogram("front", Vec3::new(-1.0, -1.0, 1.0), y, x, 0),
        parallelogram("left", o, y, z, 1),
        parallelogram("right", Vec3::new(1.0, -1.0, -1.0), z, y, 0),
        icosphere("glass", Vec3::new(0.35, -0.55, 0.2), 0.4, 2, true, 2),
        icosphere("ball", Vec3::new(-0.5, -0.7, -0.3), 0.3, 1, true, 4),
        parallelogram("mirror", Vec3::new(-0.95, -0.2, -0.9), Vec3::new(0.6, 0.0, 0.3), Vec3::new(0.0, 0.9, 0.0), 3),
        icosphere("mirror ball", Vec3::new(0.6, 0.1, -0.6), 0.25, 1, true, 3),
    ];
    // A mirror whose vertex normals vanish: no shading-normal differential can be formed
    // there, so reflected photons lose their differential (progressive fallback).
    let mut lossy = parallelogram("lossy mirror", Vec3::new(0.95, -0.9, 0.2), Vec3::new(0.0, 0.0, 0.6), Vec3::new(0.0, 0.8, 0.0), 3);
    lossy.normals = Some(vec![Vec3::ZERO; 4]);
    meshes.push(lossy);
    let mut light: TriangleMesh = parallelogram("light", Vec3::new(-0.25, 0.98, -0.25), Vec3::new(0.5, 0.0, 0.0), Vec3::new(0.0, 0.0, 0.5), 0);
    light.emission = Some(Vec3::new(20.0, 18.0, 15.0));
    meshes.push(light);
    let lights = vec![Light::Point(PointLight { position: DVec3::new(0.3, 0.6, 0.5), intensity: DVec3::new(3.0, 3.0, 2.5) })];
    Scene { textures: Default::default(), meshes, materials, lights, camera: camera(), roughness_cutoff: 0.5, instancing: None }
}

/// A diffuse floor under a flat glass slab (no vertex normals), lit by a spot, a
/// directional and a triangle light.
fn slab_scene() -> Scene {
    let materials = vec![
        Material::Diffuse { albedo: Vec3::splat(0.8) },
        Material::Dielectric { ior: 1.45, transmittance: Vec3::new(0.95, 0.97, 1.0), roughness: 0.0 },
    ];
    let mut meshes = vec![parallelogram("floor", Vec3::new(-2.0, 0.0, 2.0), Vec3::new(4.0, 0.0, 0.0), Vec3::new(0.0, 0.0, -4.0), 0)];
    // The slab: a box [-0.8, 0.8] x [0.5, 0.7] x [-0.8, 0.8], outward normals.
    let (lo, hi) = (Vec3::new(-0.8, 0.5, -0.8), Vec3::new(0.8, 0.7, 0.8));
    let d = hi - lo;
    let (dx, dy, dz) = (Vec3::X * d.x, Vec3::Y * d.y, Vec3::Z * d.z);
    for (name, origin, u, v) in [
        ("slab bottom", lo, dx, dz),
        ("slab top", lo + dy, dz, dx),
        ("slab back", lo, dy, dx),
        ("slab front", lo + dz, dx, dy),
        ("slab left", lo, dz, dy),
        ("slab right", lo + dx, dy, dz),
    ] {
        meshes.push(parallelogram(name, origin, u, v, 1));
    }
    let lights = vec![
        Light::Spot(SpotLight {
            position: DVec3::new(0.2, 2.5, 0.1),
            direction: DVec3::new(-0.1, -1.0, 0.05),
            intensity: DVec3::splat(8.0),
            cutoff: 0.5,
            beam_width: 0.35,
            falloff: SpotFalloff::LinearAngle,
        }),
        Light::Directional(DirectionalLight { direction: DVec3::new(0.3, -1.0, 0.2), irradiance: DVec3::splat(1.5) }),
        Light::Triangle(TriangleLight {
            p: [DVec3::new(-1.0, 2.0, -1.0), DVec3::new(-1.0, 2.0, -0.5), DVec3::new(-0.5, 2.0, -1.0)],
            radiance: DVec3::splat(10.0),
        }),
    ];
    Scene { textures: Default::default(), meshes, materials, lights, camera: camera(), roughness_cutoff: 0.5, instancing: None }
}

fn settings(method: Method, photons: u32, direct_lighting: bool) -> RenderSettings {
    RenderSettings {
        method,
        photons_per_iteration: photons,
        seed: 7,
        max_depth: 8,
        direct_lighting,
        smoothing: Smoothing { caustic: 0.6, global: 0.9 },
        // A caustic pass (aimed, weighted, ending at its first diffuse hit) besides the
        // global one, so that the comparisons cover both.
        emission: arpa_core::render::tracer::EmissionStrategy { projection: true, caustic_photons: Some(photons / 2) },
        ..RenderSettings::default()
    }
}

/// Runs the device photon pass of `iteration` with the given capacities.
fn device_pass(ctx: &GpuContext, prepared: &PreparedScene, s: &RenderSettings, iteration: u32, caps: (u32, u32)) -> PhotonReadback {
    let scene = GpuScene::upload(ctx, prepared).expect("scene upload");
    let pass = PhotonPass::new(ctx, &scene, prepared, s).expect("photon pass");
    let out = PhotonOutputs::new(ctx, caps.0, caps.1).expect("outputs");
    let setup = PhotonPassSetup::new(prepared, s, iteration);
    let mut encoder = ctx.device.create_command_encoder(&Default::default());
    pass.encode(ctx, &mut encoder, &scene, &setup, &out).expect("encode");
    ctx.queue.submit([encoder.finish()]);
    read_outputs(ctx, &out)
}

/// `D_u`, `D_v` (metres), the unit normal and the flux (W) of a packed footprint, from
/// its filter-space rows: the inverse of `[row_u; row_v; row_n]` has columns
/// `D_u/2, D_v/2, n h`.
fn unpack(p: &PackedFootprint) -> Option<(DVec3, DVec3, DVec3, DVec3)> {
    let r = |a: [f32; 3]| Vec3::from_array(a).as_dvec3();
    let m = DMat3::from_cols(r(p.row_u), r(p.row_v), r(p.row_n)).transpose();
    let inv = m.inverse();
    if !inv.is_finite() {
        return None;
    }
    let (du, dv) = (2.0 * inv.x_axis, 2.0 * inv.y_axis);
    let area4 = du.cross(dv).length() / 4.0;
    let flux = DVec3::new(p.flux_density_r as f64, p.flux_density_g as f64, p.flux_density_b as f64) * area4;
    Some((du, dv, r(p.row_n).normalize(), flux))
}

/// The largest error of one record, relative to the bound it must stay within.
#[derive(Clone, Copy, Debug, Default)]
struct Errors {
    position: f64,
    normal: f64,
    flux: f64,
    differential: f64,
}

impl Errors {
    fn max(self, o: Errors) -> Errors {
        Errors { position: self.position.max(o.position), normal: self.normal.max(o.normal), flux: self.flux.max(o.flux), differential: self.differential.max(o.differential) }
    }
}

fn rel(a: DVec3, b: DVec3, scale: f64) -> f64 {
    (a - b).length() / scale.max(1e-30)
}

/// Errors between the device's record (through the core's store) and the core's.
fn record_errors(gpu: &StoredPhoton, cpu: &StoredPhoton) -> Errors {
    match (gpu, cpu) {
        (StoredPhoton::Footprint { packed: g, .. }, StoredPhoton::Footprint { packed: c, .. }) => {
            let pos = rel(Vec3::from_array(g.center).as_dvec3(), Vec3::from_array(c.center).as_dvec3(), 1.0);
            match (unpack(g), unpack(c)) {
                (Some((gu, gv, gn, gf)), Some((cu, cv, cn, cf))) => {
                    // Compared as ellipses (shape D_u D_uᵀ + D_v D_vᵀ): where H-max clamps the
                    // axes separately the store returns principal differentials, whose
                    // directions are ill-determined for a near-circle. Half the shape's
                    // relative error is the differentials' relative error.
                    let shape = |u: DVec3, v: DVec3| DMat3::from_cols(u * u.x + v * v.x, u * u.y + v * v.y, u * u.z + v * v.z);
                    let norm = |m: DMat3| m.col(0).length().max(m.col(1).length()).max(m.col(2).length());
                    let (sg, sc) = (shape(gu, gv), shape(cu, cv));
                    Errors {
                        position: pos,
                        normal: (gn - cn).length(),
                        flux: rel(gf, cf, cf.length()),
                        differential: 0.5 * norm(sg - sc) / norm(sc).max(1e-300),
                    }
                }
                _ => Errors { position: pos, normal: f64::INFINITY, flux: f64::INFINITY, differential: f64::INFINITY },
            }
        }
        (StoredPhoton::Progressive { photon: g, .. }, StoredPhoton::Progressive { photon: c, .. }) => {
            let v = |a: [f32; 3]| Vec3::from_array(a).as_dvec3();
            Errors {
                position: rel(v(g.position), v(c.position), 1.0),
                normal: (v(g.normal) - v(c.normal)).length(),
                flux: rel(v(g.flux), v(c.flux), v(c.flux).length()),
                differential: 0.0,
            }
        }
        _ => unreachable!("kinds compared before"),
    }
}

/// The device's records of one photon in depth order, each as the core's store makes it.
fn device_records(read: &PhotonReadback, prepared: &PreparedScene, s: &RenderSettings, setup: &PhotonPassSetup) -> Vec<Vec<(u32, StoredPhoton)>> {
    let n = setup.photon_count() as usize;
    let heuristics = s.heuristics.resolve(&prepared.bounds());
    let unit = Smoothing { caustic: 1.0, global: 1.0 };
    let mut per: Vec<Vec<(u32, StoredPhoton)>> = vec![Vec::new(); n];
    let d = |a: [f32; 3]| Vec3::from_array(a).as_dvec3();
    for f in &read.footprints {
        let raw = &f.footprint;
        let map = PhotonMap::from_index(raw.map);
        let fp = Footprint { center: d(raw.center), normal: d(raw.normal), du: d(raw.du), dv: d(raw.dv), flux: d(raw.flux), map };
        let stored = store_footprint(fp, &unit, &heuristics, setup.radii[map.index()]);
        per[(f.key / s.max_depth) as usize].push((f.key, stored));
    }
    for p in &read.photons {
        let photon: PackedPhoton = p.photon;
        per[(p.key / s.max_depth) as usize].push((p.key, StoredPhoton::Progressive { photon, reason: ProgressiveReason::ProgressiveMethod }));
    }
    for v in &mut per {
        v.sort_by_key(|(k, _)| *k);
    }
    per
}

fn same_kind(a: &StoredPhoton, b: &StoredPhoton) -> bool {
    matches!((a, b), (StoredPhoton::Footprint { .. }, StoredPhoton::Footprint { .. }) | (StoredPhoton::Progressive { .. }, StoredPhoton::Progressive { .. }))
        && a.map() == b.map()
}

/// Bounds (metres for positions in these 2–4 m scenes; relative for flux and for
/// `D_u`, `D_v`, against the larger of the two) for the records of photons whose decisions
/// agree. The device computes in `f32` along paths of up to 8 interactions, each step
/// accurate to a few `ε₃₂ = 1.2e-7` times its condition number (the twin files' stated
/// bounds), and draws its 2-D samples with 24 bits (within `2⁻²⁴` of the core's). Along a
/// path these differences are carried on and amplified by the path itself (a hit point
/// that moves by `δ` on a curved glass surface turns the refracted ray by `~δ/r`):
/// * `TIGHT`, the `f32` bounds with little amplification: a photon counts as agreeing when
///   its decisions agree and all its records are within them;
/// * `COARSE`, what any record of a photon with the same decisions must meet: amplified
///   rounding (of order 1e-3 m after six diffuse bounces and a pass through the glass
///   sphere) stays well inside it, while a wrong formula moves a record by a sizeable part
///   of the scene or changes its flux by a factor.
///
/// A spot light's flux carries its falloff, whose slope `1/(θ_c − θ_b)` turns the angle
/// difference of the device's direction (twin_emission's `2·DIR_TOL`) into a flux
/// difference; that term is added to both flux bounds for the photons of spot lights.
const TIGHT: Errors = Errors { position: 1e-4, normal: 1e-5, flux: 1e-3, differential: 1e-3 };
/// See [`TIGHT`].
const COARSE: Errors = Errors { position: 1e-2, normal: 1e-3, flux: 1e-2, differential: 1e-2 };

fn within(e: &Errors, bound: &Errors, flux_slack: f64) -> bool {
    e.position <= bound.position && e.normal <= bound.normal && e.flux <= bound.flux + flux_slack && e.differential <= bound.differential
}

/// The relative flux slack of photon `index` (see [`TIGHT`]): zero except for spot lights.
fn spot_flux_slack(s: &RenderSettings, setup: &PhotonPassSetup, index: u32) -> f64 {
    let Some((e, local)) = setup.locate(index) else { return 0.0 };
    let Some(light) = &setup.lights[e] else { return 0.0 };
    let Light::Spot(l) = light.light() else { return 0.0 };
    let mut rng = Rng::new(s.seed, setup.iteration, index, StreamDomain::Photon);
    let Ok(emitted) = light.emit(local, &mut rng) else { return 0.0 };
    let theta = l.direction.normalize().dot(emitted.ray.d).clamp(-1.0, 1.0).acos();
    let falloff = l.falloff_at(theta);
    let dtheta = 2.0 * 2e-5 + 4.0 * f32::EPSILON as f64 * theta;
    if falloff > 0.0 { dtheta / (l.cutoff - l.beam_width).max(1e-30) / falloff } else { 0.0 }
}

fn compare(name: &str, scene: Scene, s: RenderSettings) {
    let Some(ctx) = gpu() else { return };
    let prepared = PreparedScene::new(scene).expect("valid scene");
    let caster = BruteForceCaster::new(&prepared);
    let iteration = 3;
    let setup = PhotonPassSetup::new(&prepared, &s, iteration);
    let n = setup.photon_count();
    let read = device_pass(ctx, &prepared, &s, iteration, (4 * n, 4 * n));
    let c = read.counters;
    assert_eq!(c.emitted, n, "{name}: photons traced");
    assert_eq!((c.footprint_overflowed, c.photon_overflowed), (0, 0), "{name}: nothing may overflow");
    assert_eq!(c.footprint_appends, c.footprints_caustic + c.footprints_global, "{name}");
    assert_eq!(c.photon_appends, c.progressive_caustic + c.progressive_global, "{name}");
    assert_eq!(read.footprints.len() as u32, c.footprint_appends, "{name}");
    assert_eq!(read.photons.len() as u32, c.photon_appends, "{name}");
    if s.method == Method::Rtpm {
        assert_eq!(c.footprint_appends, 0, "{name}: RTPM stores no footprints");
    }
    let mut keys: Vec<u32> = read.footprints.iter().map(|f| f.key).chain(read.photons.iter().map(|p| p.key)).collect();
    keys.sort_unstable();
    assert!(keys.windows(2).all(|w| w[0] < w[1]), "{name}: keys must be unique");
    assert!(keys.iter().all(|&k| k < n * s.max_depth), "{name}: keys in range");

    let gpu_records = device_records(&read, &prepared, &s, &setup);
    let (mut same_decisions, mut agree, mut cpu_segments) = (0u32, 0u32, 0u64);
    let mut cpu_stored = [0u64; 2];
    // Core records by where the device leaves them: raw footprints (stored as footprints,
    // or rejected by the heuristics) and progressive photons (RTPM, lost differential).
    let (mut cpu_raw, mut cpu_progressive, mut cpu_lost) = ([0u64; 2], [0u64; 2], 0u64);
    let mut worst = Errors::default();
    let mut outside = Vec::new();
    for index in 0..n {
        let mut cpu = Vec::new();
        let stats = trace_photon(&prepared, &caster, &s, &setup, index, &mut |st| cpu.push(st));
        cpu_segments += stats.segments as u64;
        for st in &cpu {
            let m = st.map().index();
            cpu_stored[m] += 1;
            match st {
                StoredPhoton::Footprint { .. } => cpu_raw[m] += 1,
                StoredPhoton::Progressive { reason, .. } => match reason {
                    ProgressiveReason::Degenerate | ProgressiveReason::Culled | ProgressiveReason::Unrepresentable => cpu_raw[m] += 1,
                    ProgressiveReason::DifferentialLost => {
                        cpu_lost += 1;
                        cpu_progressive[m] += 1;
                    }
                    ProgressiveReason::ProgressiveMethod => cpu_progressive[m] += 1,
                },
            }
        }
        let gpu = &gpu_records[index as usize];
        let decisions = gpu.len() == cpu.len() && gpu.iter().zip(&cpu).all(|((_, g), c)| same_kind(g, c));
        if !decisions {
            continue;
        }
        same_decisions += 1;
        let slack = spot_flux_slack(&s, &setup, index);
        let mut tight = true;
        for ((key, g), c) in gpu.iter().zip(&cpu) {
            let e = record_errors(g, c);
            worst = worst.max(e);
            tight &= within(&e, &TIGHT, slack);
            if !within(&e, &COARSE, slack) {
                outside.push((index, key % s.max_depth, e));
            }
        }
        agree += tight as u32;
    }
    let fraction = agree as f64 / n as f64;
    let gpu_stored = [(c.footprints_caustic + c.progressive_caustic) as u64, (c.footprints_global + c.progressive_global) as u64];
    eprintln!(
        "{name}: {n} photons, decisions agree for {:.3} %, and records within the tight bounds for {:.3} %, worst errors {worst:?}; segments device {} core {cpu_segments}; stored [caustic, global] device {gpu_stored:?} core {cpu_stored:?}; footprints {} photons {} lost {}",
        100.0 * same_decisions as f64 / n as f64,
        100.0 * fraction,
        c.segments,
        c.footprint_appends,
        c.photon_appends,
        c.differential_lost
    );
    assert!(fraction >= 0.99, "{name}: decisions and records (within {TIGHT:?}) agree for only {:.3} % of the photons", 100.0 * fraction);
    assert!(outside.is_empty(), "{name}: {} records of photons with the same decisions outside {COARSE:?}, first (photon, depth, errors) {:?}", outside.len(), &outside[..outside.len().min(5)]);
    // Counts agree within the fraction of photons that may take other decisions.
    let within = |a: u64, b: u64| (a as f64 - b as f64).abs() <= 0.01 * b as f64;
    assert!(within(c.segments as u64, cpu_segments), "{name}: segments device {} core {cpu_segments}", c.segments);
    assert!(within(c.differential_lost as u64, cpu_lost), "{name}: differential lost: device {} core {cpu_lost}", c.differential_lost);
    let gpu_raw = [c.footprints_caustic as u64, c.footprints_global as u64];
    let gpu_progressive = [c.progressive_caustic as u64, c.progressive_global as u64];
    for m in 0..2 {
        assert!(within(gpu_stored[m], cpu_stored[m]), "{name}: stored in map {m}: device {} core {}", gpu_stored[m], cpu_stored[m]);
        assert!(within(gpu_raw[m], cpu_raw[m]), "{name}: raw footprints in map {m}: device {} core {}", gpu_raw[m], cpu_raw[m]);
        assert!(within(gpu_progressive[m], cpu_progressive[m]), "{name}: progressive in map {m}: device {} core {}", gpu_progressive[m], cpu_progressive[m]);
    }
}

#[test]
fn box_arpa_matches_the_core() {
    compare("box arpa", box_scene(), settings(Method::Arpa, 3000, true));
}

#[test]
fn box_arpa_without_direct_lighting_matches_the_core() {
    compare("box arpa no-direct", box_scene(), settings(Method::Arpa, 3000, false));
}

#[test]
fn box_rtpm_matches_the_core() {
    compare("box rtpm", box_scene(), settings(Method::Rtpm, 3000, true));
}

#[test]
fn slab_arpa_matches_the_core() {
    let mut s = settings(Method::Arpa, 3000, false);
    s.heuristics = Heuristics { dampening: None, h_max: None, degenerate: None, culling: None };
    compare("slab arpa no heuristics", slab_scene(), s);
}

/// A pass with room for fewer records than it stores: every append beyond the capacity is
/// counted as overflowed and dropped, the buffers hold exactly `capacity` records, each of
/// them one the uncapped pass wrote too (same key, same bits), and the other counters equal
/// the uncapped pass's. Footprints under ARPA, progressive photons under RTPM.
#[test]
fn overflow_is_counted_and_nothing_is_written_past_capacity() {
    let Some(ctx) = gpu() else { return };
    let prepared = PreparedScene::new(box_scene()).expect("valid scene");
    for method in [Method::Arpa, Method::Rtpm] {
        let s = settings(method, 1000, false);
        let full = device_pass(ctx, &prepared, &s, 0, (8000, 8000));
        let f = full.counters;
        assert_eq!((f.footprint_overflowed, f.photon_overflowed), (0, 0));
        let appends = f.footprint_appends + f.photon_appends;
        assert!(appends > 1000, "{method:?}: the pass must store: {f:?}");
        // A third of the footprints / half of the photons fit (and one record of the kind
        // the method does not store).
        let caps = ((f.footprint_appends / 3).max(1), (f.photon_appends / 2).max(1));
        let capped = device_pass(ctx, &prepared, &s, 0, caps);
        let c = capped.counters;
        assert_eq!(
            (c.footprint_appends, c.photon_appends, c.segments, c.emitted, c.footprints_caustic, c.footprints_global, c.progressive_caustic, c.progressive_global),
            (f.footprint_appends, f.photon_appends, f.segments, f.emitted, f.footprints_caustic, f.footprints_global, f.progressive_caustic, f.progressive_global),
            "{method:?}"
        );
        assert_eq!(c.footprint_overflowed, f.footprint_appends.saturating_sub(caps.0), "{method:?}");
        assert_eq!(c.photon_overflowed, f.photon_appends.saturating_sub(caps.1), "{method:?}");
        assert!(c.overflowed() > 0, "{method:?}");
        assert_eq!(capped.footprints.len() as u32, f.footprint_appends.min(caps.0), "{method:?}");
        assert_eq!(capped.photons.len() as u32, f.photon_appends.min(caps.1), "{method:?}");
        let by_key_f: std::collections::HashMap<u32, _> = full.footprints.iter().map(|r| (r.key, *r)).collect();
        let by_key_p: std::collections::HashMap<u32, _> = full.photons.iter().map(|r| (r.key, *r)).collect();
        assert!(capped.footprints.iter().all(|r| by_key_f.get(&r.key) == Some(r)), "{method:?}: capped footprints are records of the full pass");
        assert!(capped.photons.iter().all(|r| by_key_p.get(&r.key) == Some(r)), "{method:?}: capped photons are records of the full pass");
    }
}


/// Same scene, settings and iteration: the same records, bit for bit, once sorted by key
/// (the append order may differ); another iteration draws other photons.
#[test]
fn records_sorted_by_key_are_deterministic() {
    let Some(ctx) = gpu() else { return };
    let prepared = PreparedScene::new(box_scene()).expect("valid scene");
    let s = settings(Method::Arpa, 2000, true);
    let sorted = |r: PhotonReadback| {
        let mut f = r.footprints;
        let mut p = r.photons;
        f.sort_by_key(|x| x.key);
        p.sort_by_key(|x| x.key);
        (r.counters, f, p)
    };
    let a = sorted(device_pass(ctx, &prepared, &s, 5, (20_000, 20_000)));
    let b = sorted(device_pass(ctx, &prepared, &s, 5, (20_000, 20_000)));
    assert!(!a.1.is_empty() && !a.2.is_empty());
    assert_eq!(a, b);
    let c = sorted(device_pass(ctx, &prepared, &s, 6, (20_000, 20_000)));
    assert_ne!(a.1, c.1);
}

/// Photon batches (`PhotonPass::encode_batch`): tracing the iteration's photons in three
/// batches (boundaries off the 64-photon workgroups, across the two emitters) stores, bit
/// for bit, the records of one pass with the same keys, and the batches' counters sum to
/// the pass's; a batch outside the iteration is an error.
#[test]
fn batches_store_exactly_the_records_of_one_pass() {
    let Some(ctx) = gpu() else { return };
    let prepared = PreparedScene::new(box_scene()).expect("valid scene");
    for method in [Method::Arpa, Method::Rtpm] {
        let s = settings(method, 2000, false);
        let scene = GpuScene::upload(ctx, &prepared).expect("scene upload");
        let pass = PhotonPass::new(ctx, &scene, &prepared, &s).expect("photon pass");
        let setup = PhotonPassSetup::new(&prepared, &s, 4);
        assert!(setup.first_index.len() >= 2 && setup.first_index[1] > 700 && setup.first_index[1] < 2000, "{:?}", setup.first_index);
        let run = |range: std::ops::Range<u32>| {
            let out = PhotonOutputs::new(ctx, 20_000, 20_000).expect("outputs");
            let mut encoder = ctx.device.create_command_encoder(&Default::default());
            pass.encode_batch(ctx, &mut encoder, &scene, &setup, range, &out).expect("encode");
            ctx.queue.submit([encoder.finish()]);
            read_outputs(ctx, &out)
        };
        // The global pass's 2000 photons, then the caustic pass's.
        let total = setup.photon_count();
        assert!(total > 2000, "{:?}", setup.allocation);
        let whole = run(0..total);
        let parts: Vec<PhotonReadback> = [0..700, 700..1301, 1301..total].into_iter().map(run).collect();
        let (mut f, mut p) = (Vec::new(), Vec::new());
        let mut sum = [0u32; 9];
        for r in &parts {
            f.extend_from_slice(&r.footprints);
            p.extend_from_slice(&r.photons);
            let c = r.counters;
            let v = [c.emitted, c.segments, c.footprints_caustic, c.footprints_global, c.progressive_caustic, c.progressive_global, c.differential_lost, c.footprint_appends, c.photon_appends];
            for (a, b) in sum.iter_mut().zip(v) {
                *a += b;
            }
        }
        let c = whole.counters;
        assert_eq!(sum, [c.emitted, c.segments, c.footprints_caustic, c.footprints_global, c.progressive_caustic, c.progressive_global, c.differential_lost, c.footprint_appends, c.photon_appends]);
        assert_eq!(c.emitted, total);
        let (mut wf, mut wp) = (whole.footprints, whole.photons);
        for v in [&mut f, &mut wf] {
            v.sort_by_key(|x| x.key);
        }
        for v in [&mut p, &mut wp] {
            v.sort_by_key(|x| x.key);
        }
        let bits = |v: &[u8]| v.to_vec();
        assert!(!wp.is_empty() && (method == Method::Rtpm || !wf.is_empty()));
        assert!(bits(bytemuck::cast_slice(&f)) == bits(bytemuck::cast_slice(&wf)), "{}: footprints of the batches differ from one pass", method.name());
        assert!(bits(bytemuck::cast_slice(&p)) == bits(bytemuck::cast_slice(&wp)), "{}: photons of the batches differ from one pass", method.name());
        let out = PhotonOutputs::new(ctx, 16, 16).expect("outputs");
        let mut encoder = ctx.device.create_command_encoder(&Default::default());
        let e = pass.encode_batch(ctx, &mut encoder, &scene, &setup, total - 10..total + 10, &out).unwrap_err();
        assert!(e.to_string().contains(&format!("{}..{}", total - 10, total + 10)), "{e}");
    }
}

/// The photon pass's module (twin files, scene, pass) parses and validates with naga,
/// without a GPU.
#[test]
fn photon_pass_module_validates_with_naga() {
    let src = arpa_wgpu::shaders::photon_pass();
    let module = naga::front::wgsl::parse_str(&src).unwrap_or_else(|e| panic!("photon pass: {}", e.emit_to_string(&src)));
    naga::valid::Validator::new(naga::valid::ValidationFlags::all(), naga::valid::Capabilities::RAY_QUERY)
        .validate(&module)
        .unwrap_or_else(|e| panic!("photon pass: {}", e.emit_to_string(&src)));
}
