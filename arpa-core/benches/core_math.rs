//! Criterion benchmarks of arpa-core's per-photon hot paths.
//!
//! ```text
//! CARGO_TARGET_DIR=/work/target-bench cargo bench -p arpa-core --bench core_math
//! ```
//!
//! Every benchmark iterates over a pool of ~1024 *different* precomputed inputs (random
//! rays hitting planes at various angles, footprints of varied shape, query points half
//! inside / half outside), with inputs and outputs passed through `black_box`, so neither
//! constant folding nor a trained branch predictor can flatter the numbers. Criterion
//! reports the time of one pass over the pool (and the element throughput); after it has
//! run, a plain summary prints the time **per element** (`name: X.X ns/op`), both from
//! criterion's estimate and from an own `Instant` loop of at least 10^7 operations
//! (best of three rounds).
//!
//! * `cargo test --benches` (criterion's test mode, no `--bench` argument) runs every pass
//!   once and skips the timing loop, so CI stays fast.
//! * A positional filter (`cargo bench ... -- gather`) is applied to the summary too (as a
//!   substring of `group/name`).
//! * `ARPA_BENCH_SUMMARY_ONLY=1` skips criterion and runs only the timing loop.
//! * `ARPA_BENCH_OPS=N` times rounds of at least `N` operations instead of 10^7 (small `N`
//!   makes `valgrind --tool=callgrind` runs feasible; the ns/op are then less stable).

use std::f64::consts::{PI, TAU};
use std::hint::black_box;
use std::path::PathBuf;
use std::time::{Duration, Instant};

use arpa_core::base::aabb::Aabb;
use arpa_core::propagate::classify::Smoothing;
use arpa_core::propagate::differential::{NormalDifferential, RayDifferential, RefractionEvent};
use arpa_core::emit::emission::{EmissionParams, Light, PointLight, QuadLight};
use arpa_core::store::footprint::{Footprint, PackedFootprint, PhotonMap};
use arpa_core::base::frame::Frame;
use arpa_core::store::heuristics::{HeuristicContext, Heuristics};
use arpa_core::gather::kernel::Kernel;
use arpa_core::propagate::reemission::reemit;
use arpa_core::base::rng::{Rng, StreamDomain};
use arpa_core::base::sampling::{cosine_hemisphere, uniform_sphere};
use arpa_core::store::heuristics::ResolvedHeuristics;
use arpa_core::{store::heuristics::ProgressiveReason, store::decision::{StoredPhoton, store_footprint}};
use criterion::{Criterion, Throughput};
use glam::{DVec2, DVec3, Vec3};

/// Number of distinct inputs per pool.
const POOL: usize = 1024;
/// Operations timed per round by the summary loop (`ARPA_BENCH_OPS` overrides it).
const SUMMARY_OPS: usize = 10_000_000;
/// Rounds of the summary loop (the best is reported).
const SUMMARY_ROUNDS: usize = 3;
/// Photons per light per iteration assumed when sizing differentials.
const PHOTONS: u32 = 1 << 20;
/// Progressive radii of the caustic and global maps (metres).
const RADII: [f64; 2] = [0.01, 0.03];

// ---------------------------------------------------------------------------------------
// Input pools
// ---------------------------------------------------------------------------------------

/// A ray about to hit a surface: transfer distance, geometric and shading normals, ior.
#[derive(Clone, Copy)]
struct PropInput {
    ray: RayDifferential,
    t: f64,
    /// Geometric normal passed to `transfer` (random orientation).
    n_geo: DVec3,
    /// Curved shading normal (non-zero derivatives, random orientation).
    shading: NormalDifferential,
    ior: f64,
}

/// A ray already transferred onto the surface (input of reflect / refract alone).
#[derive(Clone, Copy)]
struct HitInput {
    ray: RayDifferential,
    shading: NormalDifferential,
    ior: f64,
}

/// A diffuse hit to store.
#[derive(Clone, Copy)]
struct StoreInput {
    ray: RayDifferential,
    n_geo: DVec3,
    flux: DVec3,
    map: PhotonMap,
}

/// A footprint that survived the heuristics, with its map's radius (input of `pack`).
#[derive(Clone, Copy)]
struct PackInput {
    fp: Footprint,
    radius: f64,
}

/// A gather query against one packed footprint.
#[derive(Clone, Copy)]
struct Query {
    fp: PackedFootprint,
    q: Vec3,
    n: Vec3,
}

/// One photon to emit.
#[derive(Clone, Copy)]
struct EmitInput {
    index: u32,
    rng: Rng,
}

/// One diffuse re-emission.
#[derive(Clone, Copy)]
struct ReemitInput {
    hit: DVec3,
    dp_du: DVec3,
    dp_dv: DVec3,
    direction: DVec3,
    length: f64,
}

/// Everything the benchmarks read.
struct Pools {
    prop: Vec<PropInput>,
    hits: Vec<HitInput>,
    stores: Vec<StoreInput>,
    /// Unsmoothed footprints from `Footprint::from_hit` (input of `Heuristics::apply`).
    footprints: Vec<Footprint>,
    packs: Vec<PackInput>,
    queries: Vec<Query>,
    emits: Vec<EmitInput>,
    reemits: Vec<ReemitInput>,
    rngs: Vec<Rng>,
    smoothing: Smoothing,
    heuristics: Heuristics,
    resolved: ResolvedHeuristics,
    resolved_none: ResolvedHeuristics,
    ctx: [HeuristicContext; 2],
    point_light: Light,
    quad_light: Light,
    emission: EmissionParams,
    stats: Vec<String>,
}

struct Gen(Rng);

impl Gen {
    fn f(&mut self) -> f64 {
        self.0.next_f64()
    }
    fn range(&mut self, lo: f64, hi: f64) -> f64 {
        lo + (hi - lo) * self.f()
    }
    fn log_range(&mut self, lo: f64, hi: f64) -> f64 {
        (lo.ln() + (hi.ln() - lo.ln()) * self.f()).exp()
    }
    fn chance(&mut self, p: f64) -> bool {
        self.f() < p
    }
    fn sign(&mut self) -> f64 {
        if self.chance(0.5) { 1.0 } else { -1.0 }
    }
    fn unit(&mut self) -> DVec3 {
        uniform_sphere(self.0.next_2d())
    }
    fn point(&mut self, half: f64) -> DVec3 {
        DVec3::new(self.range(-half, half), self.range(-half, half), self.range(-half, half))
    }
    /// Unit vector orthogonal to unit `n` at angle `a` in `n`'s frame.
    fn tangent_at(n: DVec3, a: f64) -> DVec3 {
        let f = Frame::from_normal(n);
        f.t * a.cos() + f.b * a.sin()
    }
    fn tangent(&mut self, n: DVec3) -> DVec3 {
        let a = self.range(0.0, TAU);
        Self::tangent_at(n, a)
    }
}

/// A photon differential arriving at a random plane at a random incidence angle.
fn make_prop(g: &mut Gen) -> PropInput {
    let n = g.unit();
    let hit = g.point(4.0);
    // Incidence cosines from near-grazing (0.03) to normal.
    let cos = g.range(0.03, 1.0);
    let sin = (1.0 - cos * cos).sqrt();
    let d = -n * cos + g.tangent(n) * sin;
    let t = g.log_range(0.2, 6.0);
    // Directional differentials: widths of about 1e-3..2e-2 rad, varied aspect, and
    // angles between them from nearly parallel (5%) to well spread.
    let a0 = g.range(0.0, TAU);
    let sep = if g.chance(0.05) { g.range(0.005, 0.05) } else { PI * g.range(0.15, 0.85) };
    let (e1, e2) = (Gen::tangent_at(d, a0), Gen::tangent_at(d, a0 + sep));
    let w1 = g.log_range(1e-3, 2e-2);
    let w2 = w1 * g.log_range(0.3, 3.0);
    let (dd_du, dd_dv) = (e1 * w1, e2 * w2);
    // Half point-light-like (no positional spread), half area-light / re-emitted photons
    // (virtual point emitter `v` behind the origin).
    let v = if g.chance(0.5) { 0.0 } else { g.log_range(0.05, 2.0) };
    let ray = RayDifferential::new(hit - d * t, d, dd_du * v, dd_dv * v, dd_du, dd_dv).expect("valid ray").reprojected();
    let n_geo = n * g.sign();
    // Curved shading normal near the geometric one, with non-zero derivatives.
    let ns = (n + 0.1 * g.unit()).normalize() * g.sign();
    let dn_du = g.tangent(ns) * g.log_range(1e-3, 1.0);
    let dn_dv = g.tangent(ns) * g.log_range(1e-3, 1.0);
    let shading = NormalDifferential { n: ns, dn_du, dn_dv };
    let ior = [1.33, 1.5, 1.7, 2.42][(g.0.next_u32() % 4) as usize];
    PropInput { ray, t, n_geo, shading, ior }
}

fn build_pools() -> Pools {
    let mut g = Gen(Rng::new(0xA59A_2024, 0, 0, StreamDomain::User));
    let mut stats = Vec::new();

    // Propagation.
    let prop: Vec<PropInput> = (0..POOL).map(|_| make_prop(&mut g)).collect();
    let hits: Vec<HitInput> = prop
        .iter()
        .filter_map(|p| p.ray.transfer(p.t, p.n_geo).ok().map(|ray| HitInput { ray, shading: p.shading, ior: p.ior }))
        .collect();
    assert!(hits.len() == POOL, "every generated ray must transfer");
    let tir = hits
        .iter()
        .filter(|h| matches!(h.ray.refract(&h.shading, h.ior), Ok((_, RefractionEvent::TotalInternalReflection))))
        .count();
    let refract_err = hits.iter().filter(|h| h.ray.refract(&h.shading, h.ior).is_err()).count();
    stats.push(format!("refract pool: {tir}/{POOL} total internal reflection, {refract_err} errors"));

    // Storing.
    let scene = Aabb { min: DVec3::splat(-5.0), max: DVec3::splat(5.0) };
    let ctx = RADII.map(|radius| HeuristicContext { radius, scene_bounds: scene });
    let smoothing = Smoothing::default();
    let heuristics = Heuristics::default();
    let stores: Vec<StoreInput> = prop
        .iter()
        .zip(&hits)
        .map(|(p, h)| {
            let flux = DVec3::new(g.range(0.2, 1.0), g.range(0.2, 1.0), g.range(0.2, 1.0)) * (4.0 / PHOTONS as f64);
            let map = if g.chance(0.3) { PhotonMap::Caustic } else { PhotonMap::Global };
            StoreInput { ray: h.ray, n_geo: p.n_geo, flux, map }
        })
        .collect();
    let footprints: Vec<Footprint> =
        stores.iter().map(|s| Footprint::from_hit(&s.ray, s.n_geo, s.flux, s.map).expect("valid normal")).collect();
    let (mut n_fp, mut n_deg, mut n_cull, mut n_unrep, mut n_other) = (0, 0, 0, 0, 0);
    for fp in &footprints {
        match store_footprint(*fp, &smoothing, &heuristics.resolve(&ctx[fp.map.index()].scene_bounds), ctx[fp.map.index()].radius) {
            StoredPhoton::Footprint { .. } => n_fp += 1,
            StoredPhoton::Progressive { reason: ProgressiveReason::Degenerate, .. } => n_deg += 1,
            StoredPhoton::Progressive { reason: ProgressiveReason::Culled, .. } => n_cull += 1,
            StoredPhoton::Progressive { reason: ProgressiveReason::Unrepresentable, .. } => n_unrep += 1,
            StoredPhoton::Progressive { .. } => n_other += 1,
        }
    }
    stats.push(format!(
        "store pool: {n_fp} footprints, {n_deg} degenerate, {n_cull} culled, {n_unrep} unrepresentable, {n_other} other (of {POOL})"
    ));
    let packs: Vec<PackInput> = footprints
        .iter()
        .filter_map(|fp| {
            let radius = RADII[fp.map.index()];
            heuristics.apply(smoothing.apply(*fp), &ctx[fp.map.index()]).ok().map(|(fp, _)| PackInput { fp, radius })
        })
        .collect();
    let packable: Vec<(PackInput, PackedFootprint)> =
        packs.iter().filter_map(|p| p.fp.pack(p.radius).ok().map(|packed| (*p, packed))).collect();
    assert!(!packable.is_empty(), "no generated footprint survived the heuristics and packing");

    // Gather: each query picks a random footprint; half the points lie inside it.
    let mut intended_inside = 0;
    let mut agree = 0;
    let mut facing = 0;
    let queries: Vec<Query> = (0..POOL)
        .map(|_| {
            let (p, packed) = packable[(g.0.next_u32() as usize) % packable.len()];
            let (a, b) = (0.5 * p.fp.du, 0.5 * p.fp.dv);
            let h = p.fp.half_thickness(p.radius);
            let theta = g.range(0.0, TAU);
            let inside = g.chance(0.5);
            let (r, z) = if inside {
                (0.97 * g.f().sqrt(), g.range(-0.95, 0.95) * h)
            } else if g.chance(0.7) {
                (g.range(1.03, 2.0), g.range(-0.95, 0.95) * h)
            } else {
                (0.97 * g.f().sqrt(), g.sign() * g.range(1.05, 3.0) * h)
            };
            let q = p.fp.center + a * (r * theta.cos()) + b * (r * theta.sin()) + p.fp.normal * z;
            let n = (p.fp.normal * if g.chance(0.9) { 1.0 } else { -1.0 } + 0.2 * g.unit()).normalize();
            let query = Query { fp: packed, q: q.as_vec3(), n: n.as_vec3() };
            intended_inside += inside as usize;
            agree += (query.fp.contains(query.q) == inside) as usize;
            facing += query.fp.faces(query.n) as usize;
            query
        })
        .collect();
    stats.push(format!(
        "gather pool: {intended_inside}/{POOL} queries inside, contains() agrees on {agree}, {facing} facing; {} distinct footprints",
        packable.len()
    ));
    assert!(agree >= POOL * 95 / 100, "query generation disagrees with contains(): {agree}/{POOL}");

    // Emission and re-emission.
    let emits: Vec<EmitInput> = (0..POOL)
        .map(|_| {
            let index = g.0.next_u32() % PHOTONS;
            EmitInput { index, rng: Rng::new(7, 3, index, StreamDomain::Photon) }
        })
        .collect();
    let point_light = Light::Point(PointLight { position: DVec3::new(0.3, 4.5, -0.2), intensity: DVec3::new(10.0, 9.0, 8.0) });
    let quad_light = Light::Quad(QuadLight {
        origin: DVec3::new(-0.5, 4.9, -0.5),
        edge_u: DVec3::new(1.0, 0.0, 0.0),
        edge_v: DVec3::new(0.0, 0.0, 1.0),
        radiance: DVec3::splat(12.0),
    });
    let emission = EmissionParams {
        photon_count: PHOTONS,
        scale: 1.0,
        scene_sphere: (DVec3::ZERO, 5.0 * 3f64.sqrt()),
        lattice_shift: DVec2::new(0.37, 0.81),
        ..EmissionParams::new(PHOTONS)
    };
    for e in &emits {
        for light in [&point_light, &quad_light] {
            let mut rng = e.rng;
            light.emit(e.index, &emission, &mut rng).expect("emission succeeds");
        }
    }
    let reemission_length = 2.0 * (TAU / (PI * PHOTONS as f64)).sqrt();
    let reemits: Vec<ReemitInput> = stores
        .iter()
        .map(|s| {
            let n = if s.ray.d.dot(s.n_geo) > 0.0 { -s.n_geo } else { s.n_geo };
            let direction = Frame::from_normal(n).to_world(cosine_hemisphere(g.0.next_2d())).normalize();
            ReemitInput { hit: s.ray.p, dp_du: s.ray.dp_du, dp_dv: s.ray.dp_dv, direction, length: reemission_length }
        })
        .collect();
    let reemit_ok = reemits.iter().filter(|r| reemit(r.hit, r.dp_du, r.dp_dv, r.direction, r.length).is_ok()).count();
    stats.push(format!("reemit pool: {reemit_ok}/{POOL} succeed"));

    let rngs = (0..POOL as u32).map(|i| Rng::new(11, 5, i.wrapping_mul(2_654_435_761), StreamDomain::Photon)).collect();

    Pools {
        prop,
        hits,
        stores,
        footprints,
        packs,
        queries,
        emits,
        reemits,
        rngs,
        smoothing,
        resolved: heuristics.resolve(&scene),
        resolved_none: Heuristics::NONE.resolve(&scene),
        heuristics,
        ctx,
        point_light,
        quad_light,
        emission,
        stats,
    }
}

// ---------------------------------------------------------------------------------------
// Passes: one pass runs the operation once per pool element and returns the element count.
// Criterion and the summary loop run exactly the same passes.
// ---------------------------------------------------------------------------------------

type Pass = fn(&mut Pools) -> usize;

fn transfer(p: &mut Pools) -> usize {
    for x in black_box(&p.prop).iter() {
        let x = black_box(x);
        black_box(x.ray.transfer(x.t, x.n_geo)).ok();
    }
    p.prop.len()
}

fn reflect(p: &mut Pools) -> usize {
    for x in black_box(&p.hits).iter() {
        let x = black_box(x);
        black_box(x.ray.reflect(&x.shading)).ok();
    }
    p.hits.len()
}

fn refract(p: &mut Pools) -> usize {
    for x in black_box(&p.hits).iter() {
        let x = black_box(x);
        black_box(x.ray.refract(&x.shading, x.ior)).ok();
    }
    p.hits.len()
}

fn transfer_reflect(p: &mut Pools) -> usize {
    for x in black_box(&p.prop).iter() {
        let x = black_box(x);
        black_box(x.ray.transfer(x.t, x.n_geo).and_then(|h| h.reflect(&x.shading))).ok();
    }
    p.prop.len()
}

fn transfer_refract(p: &mut Pools) -> usize {
    for x in black_box(&p.prop).iter() {
        let x = black_box(x);
        black_box(x.ray.transfer(x.t, x.n_geo).and_then(|h| h.refract(&x.shading, x.ior))).ok();
    }
    p.prop.len()
}

/// The per-photon store as the photon pass runs it: heuristics resolved for the scene
/// once per iteration, then `from_hit` + smoothing + heuristics + AABB + packing per photon.
fn footprint_heuristics(p: &mut Pools) -> usize {
    let (s, h, ctx) = black_box((&p.smoothing, &p.resolved, &p.ctx));
    for x in black_box(&p.stores).iter() {
        let x = black_box(x);
        if let Ok(fp) = Footprint::from_hit(&x.ray, x.n_geo, x.flux, x.map) {
            black_box(store_footprint(fp, s, h, ctx[fp.map.index()].radius));
        }
    }
    p.stores.len()
}

/// `Footprint::from_hit` alone (orientation and projection of the differentials).
fn footprint_from_hit(p: &mut Pools) -> usize {
    for x in black_box(&p.stores).iter() {
        let x = black_box(x);
        black_box(Footprint::from_hit(&x.ray, x.n_geo, x.flux, x.map)).ok();
    }
    p.stores.len()
}

/// The store path with every heuristic switched off (box and packing only).
fn footprint_no_heuristics(p: &mut Pools) -> usize {
    let (s, h, ctx) = black_box((&p.smoothing, &p.resolved_none, &p.ctx));
    for x in black_box(&p.stores).iter() {
        let x = black_box(x);
        if let Ok(fp) = Footprint::from_hit(&x.ray, x.n_geo, x.flux, x.map) {
            black_box(store_footprint(fp, s, h, ctx[fp.map.index()].radius));
        }
    }
    p.stores.len()
}

/// `store_footprint` with the heuristics resolved for the scene on every call: the cost of
/// not resolving them once per pass.
fn footprint_heuristics_unresolved(p: &mut Pools) -> usize {
    let (s, h, ctx) = black_box((&p.smoothing, &p.heuristics, &p.ctx));
    for x in black_box(&p.stores).iter() {
        let x = black_box(x);
        if let Ok(fp) = Footprint::from_hit(&x.ray, x.n_geo, x.flux, x.map) {
            black_box(store_footprint(fp, s, &h.resolve(&ctx[fp.map.index()].scene_bounds), ctx[fp.map.index()].radius));
        }
    }
    p.stores.len()
}

fn heuristics_apply(p: &mut Pools) -> usize {
    let (h, ctx) = black_box((&p.heuristics, &p.ctx));
    for fp in black_box(&p.footprints).iter() {
        let fp = black_box(fp);
        black_box(h.apply(*fp, &ctx[fp.map.index()])).ok();
    }
    p.footprints.len()
}

fn footprint_pack(p: &mut Pools) -> usize {
    for x in black_box(&p.packs).iter() {
        let x = black_box(x);
        black_box(x.fp.pack(x.radius)).ok();
    }
    p.packs.len()
}

fn contains(p: &mut Pools) -> usize {
    for x in black_box(&p.queries).iter() {
        let x = black_box(x);
        black_box(x.fp.contains(x.q));
    }
    p.queries.len()
}

fn irradiance(p: &mut Pools) -> usize {
    let kernel = black_box(Kernel::Silverman);
    for x in black_box(&p.queries).iter() {
        let x = black_box(x);
        black_box(x.fp.irradiance(x.q, x.n, kernel));
    }
    p.queries.len()
}

/// Emission as the photon pass runs it: the light prepared once per iteration
/// (`Light::prepare`), then `PreparedLight::emit` per photon.
fn emit_with(p: &Pools, light: &Light) -> usize {
    let prepared = black_box(light.prepare(black_box(&p.emission)).expect("valid light"));
    for x in black_box(&p.emits).iter() {
        let x = black_box(x);
        let mut rng = x.rng;
        black_box(prepared.emit(x.index, &mut rng)).ok();
    }
    p.emits.len()
}

/// `Light::emit`, which validates and prepares the light on every call.
fn emit_point_unprepared(p: &mut Pools) -> usize {
    let (params, light) = black_box((&p.emission, &p.point_light));
    for x in black_box(&p.emits).iter() {
        let x = black_box(x);
        let mut rng = x.rng;
        black_box(light.emit(x.index, params, &mut rng)).ok();
    }
    p.emits.len()
}

fn emit_point(p: &mut Pools) -> usize {
    emit_with(p, black_box(&p.point_light))
}

fn emit_quad(p: &mut Pools) -> usize {
    emit_with(p, black_box(&p.quad_light))
}

fn reemission(p: &mut Pools) -> usize {
    for x in black_box(&p.reemits).iter() {
        let x = black_box(x);
        black_box(reemit(x.hit, x.dp_du, x.dp_dv, x.direction, x.length)).ok();
    }
    p.reemits.len()
}

fn rng_next_u32(p: &mut Pools) -> usize {
    for r in black_box(&mut p.rngs).iter_mut() {
        black_box(r.next_u32());
    }
    p.rngs.len()
}

/// `(group, name, pass)`; criterion id = `group/name`.
const BENCHES: &[(&str, &str, Pass)] = &[
    ("propagate", "transfer", transfer),
    ("propagate", "reflect", reflect),
    ("propagate", "refract", refract),
    ("propagate", "transfer + reflect", transfer_reflect),
    ("propagate", "transfer + refract", transfer_refract),
    ("store", "footprint + heuristics", footprint_heuristics),
    ("store", "footprint + heuristics (resolving per call)", footprint_heuristics_unresolved),
    ("store", "footprint, heuristics off", footprint_no_heuristics),
    ("store", "Footprint::from_hit", footprint_from_hit),
    ("store", "Heuristics::apply", heuristics_apply),
    ("store", "Footprint::pack", footprint_pack),
    ("gather", "point-in-footprint", contains),
    ("gather", "irradiance Silverman", irradiance),
    ("emit", "Light::emit point", emit_point),
    ("emit", "Light::emit point (preparing per call)", emit_point_unprepared),
    ("emit", "Light::emit quad", emit_quad),
    ("emit", "reemission::reemit", reemission),
    ("emit", "Rng::next_u32", rng_next_u32),
];

/// Per-element targets (ns) checked in the summary.
const TARGETS: &[(&str, f64)] = &[("footprint + heuristics", 50.0), ("point-in-footprint", 5.0)];

// ---------------------------------------------------------------------------------------
// Driver
// ---------------------------------------------------------------------------------------

struct Args {
    /// Real benchmarking (`cargo bench`), as opposed to criterion's test/list modes.
    timing: bool,
    filter: Option<String>,
}

fn parse_args() -> Args {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let has = |f: &str| args.iter().any(|a| a == f);
    let timing = has("--bench") && !has("--test") && !has("--list") && !args.iter().any(|a| a.starts_with("--profile-time"));
    // Criterion options that take a separate value; the first other non-flag argument is
    // the filter.
    const WITH_VALUE: &[&str] = &[
        "--color", "-c", "--save-baseline", "-s", "--baseline", "-b", "--baseline-lenient", "--load-baseline",
        "--sample-size", "--warm-up-time", "--measurement-time", "--nresamples", "--noise-threshold",
        "--confidence-level", "--significance-level", "--profile-time", "--plotting-backend", "--output-format",
        "--format",
    ];
    let mut filter = None;
    let mut skip_next = false;
    for a in &args {
        if skip_next {
            skip_next = false;
        } else if WITH_VALUE.contains(&a.as_str()) {
            skip_next = true;
        } else if !a.starts_with('-') && filter.is_none() {
            filter = Some(a.clone());
        }
    }
    Args { timing, filter }
}

/// Where criterion writes its results; set explicitly so the summary can read them back.
fn criterion_home() -> PathBuf {
    if let Some(home) = std::env::var_os("CRITERION_HOME") {
        return home.into();
    }
    if let Some(target) = std::env::var_os("CARGO_TARGET_DIR") {
        return PathBuf::from(target).join("criterion");
    }
    // <target>/<profile>/deps/core_math-<hash>
    std::env::current_exe()
        .ok()
        .and_then(|exe| exe.ancestors().nth(3).map(|t| t.join("criterion")))
        .unwrap_or_else(|| PathBuf::from("target/criterion"))
}

/// Criterion's directory-name sanitising (`report::make_filename_safe`, non-Windows).
fn filename_safe(s: &str) -> String {
    s.chars().map(|c| if "?\"/\\*<>:|^".contains(c) { '_' } else { c }).collect()
}

/// Criterion's typical estimate (slope if present, else mean) of one pass, in ns.
fn criterion_estimate(home: &std::path::Path, group: &str, name: &str) -> Option<f64> {
    let path = home.join(filename_safe(group)).join(filename_safe(name)).join("new").join("estimates.json");
    let text = std::fs::read_to_string(path).ok()?;
    let point_after = |key: &str| -> Option<f64> {
        let start = text.find(&format!("\"{key}\":"))? + key.len() + 3;
        let rest = &text[start..];
        if rest.trim_start().starts_with("null") {
            return None;
        }
        let p = rest.find("\"point_estimate\":")? + "\"point_estimate\":".len();
        let num: String = rest[p..].chars().take_while(|c| !matches!(c, ',' | '}')).collect();
        num.trim().parse().ok()
    };
    point_after("slope").or_else(|| point_after("mean"))
}

/// On-CPU time of this thread in ns (Linux `schedstat`), so that time spent preempted by
/// other processes on a loaded machine can be told apart; `None` elsewhere.
fn thread_cpu_ns() -> Option<u64> {
    let s = std::fs::read_to_string("/proc/thread-self/schedstat").ok()?;
    s.split_whitespace().next()?.parse().ok()
}

/// Operations per timed round: `SUMMARY_OPS` or `ARPA_BENCH_OPS`.
fn summary_ops() -> usize {
    std::env::var("ARPA_BENCH_OPS").ok().and_then(|s| s.parse::<usize>().ok()).unwrap_or(SUMMARY_OPS).max(1)
}

/// Best-of-rounds ns per element of `pass`, over at least [`summary_ops`] elements per round:
/// `(wall clock, on-CPU time)`.
fn time_pass(pools: &mut Pools, pass: Pass) -> (f64, Option<f64>) {
    let per_pass = pass(pools).max(1);
    let passes = summary_ops().div_ceil(per_pass);
    let ops = (passes * per_pass) as f64;
    let mut best_wall = f64::INFINITY;
    let mut best_cpu: Option<f64> = None;
    for _ in 0..SUMMARY_ROUNDS {
        let cpu0 = thread_cpu_ns();
        let start = Instant::now();
        for _ in 0..passes {
            pass(pools);
        }
        let wall = start.elapsed().as_secs_f64() * 1e9 / ops;
        let cpu1 = thread_cpu_ns();
        best_wall = best_wall.min(wall);
        if let (Some(a), Some(b)) = (cpu0, cpu1) {
            let cpu = b.saturating_sub(a) as f64 / ops;
            best_cpu = Some(best_cpu.map_or(cpu, |c| c.min(cpu)));
        }
    }
    (best_wall, best_cpu)
}

fn main() {
    let args = parse_args();
    let mut pools = build_pools();
    let selected = |group: &str, name: &str| args.filter.as_ref().is_none_or(|f| format!("{group}/{name}").contains(f.as_str()));
    let home = criterion_home();

    if std::env::var_os("ARPA_BENCH_SUMMARY_ONLY").is_none() {
        let mut c = Criterion::default()
            .warm_up_time(Duration::from_millis(500))
            .measurement_time(Duration::from_secs(2))
            .output_directory(&home)
            .configure_from_args();
        let mut groups: Vec<&str> = BENCHES.iter().map(|b| b.0).collect();
        groups.dedup();
        for group in groups {
            let mut g = c.benchmark_group(group);
            g.measurement_time(Duration::from_secs(2)).warm_up_time(Duration::from_millis(500));
            for &(_, name, pass) in BENCHES.iter().filter(|b| b.0 == group) {
                let n = pass(&mut pools);
                g.throughput(Throughput::Elements(n as u64));
                g.bench_function(name, |b| b.iter(|| pass(&mut pools)));
            }
            g.finish();
        }
        c.final_summary();
    }

    if !args.timing {
        // Criterion's test mode (`cargo test --benches`): it already ran every pass once.
        return;
    }

    println!();
    println!("==== arpa-core core_math: time per element (pools of {POOL} varied inputs) ====");
    for s in &pools.stats {
        println!("  [{s}]");
    }
    println!("X.X ns/op = own Instant loop, best of {SUMMARY_ROUNDS} rounds of >= {} ops (wall clock)", summary_ops());
    println!("cpu = on-CPU time of the same rounds (excludes time preempted by other processes)");
    println!("criterion = its estimate of one pass / elements per pass");
    let mut results = Vec::new();
    for &(group, name, pass) in BENCHES {
        if !selected(group, name) {
            continue;
        }
        let n = pass(&mut pools);
        let (own, cpu) = time_pass(&mut pools, pass);
        let crit = criterion_estimate(&home, group, name).map(|t| t / n as f64);
        let fmt = |x: Option<f64>| x.map_or_else(|| "n/a".to_string(), |c| format!("{c:.1}"));
        println!("{name}: {own:.1} ns/op   (cpu {}, criterion {}; {group}, {n} elements/pass)", fmt(cpu), fmt(crit));
        results.push((name, own, cpu, crit));
    }
    for &(name, target) in TARGETS {
        if let Some(&(_, own, cpu, crit)) = results.iter().find(|r| r.0 == name) {
            let best = [Some(own), cpu, crit].into_iter().flatten().fold(f64::INFINITY, f64::min);
            let verdict = if best <= target { "MET" } else { "MISSED" };
            let fmt = |x: Option<f64>| x.map_or_else(|| "n/a".to_string(), |c| format!("{c:.1}"));
            println!("target {name} <= {target} ns: {verdict} (own loop {own:.1}, cpu {}, criterion {})", fmt(cpu), fmt(crit));
        }
    }
}
