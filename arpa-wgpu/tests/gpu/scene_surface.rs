//! The scene on the device (`GpuScene::upload`, scene.wgsl) against `PreparedScene`: random
//! rays inside the mixed test scene (diffuse, mirror, glass, rough materials resolved by the
//! cut-off, smooth and flat vertex normals, emitters) through `arpa_scene_intersect`,
//! then `arpa_scene_surface`, the triangle lookups, `arpa_offset_origin` and a ray leaving
//! the hit straight on (`arpa_ray_start_leaving`, `arpa_start_intersect`) at the device's
//! hit, compared with `PreparedScene::surface`, `shading_normal_at`, `has_shading_normals`,
//! `shading_normal`, `offset_origin` and `RayStart::leaving(..).intersect` at the same hit.
//!
//! Bounds (ε = f32::EPSILON): vertices, vertex normals, geometric normals, materials and
//! flags exact (the host rounds the core's values once); position within 4ε·max|vertex|
//! (three products and two sums in f32, against f64); shading normals within 8ε (an f32
//! normalisation); the offset origin within 8ε·(1 + |p|). Hits agree with the core's
//! brute-force caster (mesh and triangle) for >= 99 % of the rays; those that differ must
//! lie within 1e-4 (barycentric) of a triangle edge. `arpa_scene_occluded` agrees with
//! the closest hit's existence on every ray. The leaving ray's `t_min` is the core's within
//! one ulp; it never reports the triangle it leaves, and its next triangle agrees with the
//! core's for >= 99 % of the rays (the others near an edge).

use crate::common::*;
use crate::scenes::mixed_scene;
use arpa_core::{render::ray_cast::offset_origin, render::prepared_scene::PreparedScene};
use arpa_core::{render::brute_force::BruteForceCaster, render::ray_cast::{RayCaster, RayHit, RayStart, TriangleId}};
use arpa_core::base::rng::{Rng, StreamDomain};
use arpa_core::render::scene::Scattering;
use crate::support::run_scene_kernel;
use arpa_wgpu::scene::GpuScene;
use glam::{DVec3, Vec3};

const EPS: f64 = f32::EPSILON as f64;
const OUT: usize = 64;

const KERNEL: &str = r#"
@group(1) @binding(0) var<storage, read> input: array<u32>;
@group(1) @binding(1) var<storage, read_write> output: array<u32>;
fn in_f(i: u32) -> f32 { return bitcast<f32>(input[i]); }
fn in_v3(i: u32) -> vec3<f32> { return vec3<f32>(in_f(i), in_f(i + 1u), in_f(i + 2u)); }
fn out_u(i: u32, x: u32) { output[i] = x; }
fn out_f(i: u32, x: f32) { output[i] = bitcast<u32>(x); }
fn out_v3(i: u32, v: vec3<f32>) { out_f(i, v.x); out_f(i + 1u, v.y); out_f(i + 2u, v.z); }

@compute @workgroup_size(64)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let ib = gid.x * 7u;
    if ib >= arrayLength(&input) { return; }
    let ob = gid.x * 64u;
    let o = in_v3(ib);
    let d = in_v3(ib + 3u);
    let t_max = in_f(ib + 6u);
    let h = arpa_scene_intersect(o, d, 0.0, t_max);
    out_u(ob, h.hit);
    out_u(ob + 1u, select(0u, 1u, arpa_scene_occluded(o, d, 0.0, t_max)));
    if h.hit == 0u { return; }
    out_f(ob + 2u, h.t); out_u(ob + 3u, h.mesh); out_u(ob + 4u, h.triangle); out_f(ob + 5u, h.b1); out_f(ob + 6u, h.b2);
    let s = arpa_scene_surface(h);
    out_v3(ob + 7u, s.position);
    out_v3(ob + 10u, s.geometric_normal);
    out_v3(ob + 13u, s.shading_normal);
    out_u(ob + 16u, s.has_shading_normals);
    out_u(ob + 17u, s.kind);
    out_v3(ob + 18u, s.color);
    out_f(ob + 21u, s.ior);
    out_v3(ob + 22u, s.emission);
    out_u(ob + 25u, s.emissive);
    out_u(ob + 26u, s.mesh);
    out_u(ob + 27u, s.triangle);
    out_v3(ob + 28u, s.barycentric);
    out_v3(ob + 31u, s.specular_normal);
    out_u(ob + 34u, s.mesh_has_normals);
    let p = arpa_scene_triangle_vertices(h.mesh, h.triangle);
    let n = arpa_scene_triangle_normals(h.mesh, h.triangle);
    for (var k = 0u; k < 3u; k++) {
        out_v3(ob + 35u + 3u * k, p[k]);
        out_v3(ob + 44u + 3u * k, n[k]);
    }
    let side = select(s.geometric_normal, -s.geometric_normal, dot(d, s.geometric_normal) > 0.0);
    out_v3(ob + 53u, arpa_offset_origin(s.position, side));
    let start = arpa_ray_start_leaving(s);
    let next = arpa_start_intersect(start, d, ARPA_SCENE_T_MAX);
    out_u(ob + 56u, next.hit); out_u(ob + 57u, next.mesh); out_u(ob + 58u, next.triangle); out_f(ob + 59u, next.t);
    out_f(ob + 60u, start.t_min);
    out_v3(ob + 61u, start.origin);
}
"#;

fn rays(seed: u32, n: usize) -> Vec<(Vec3, Vec3, f32)> {
    let mut rng = Rng::new(seed, 0, 0, StreamDomain::User);
    (0..n)
        .map(|_| {
            let o = Vec3::new(1.9 * rng.next_f32() - 0.95, 0.05 + 1.9 * rng.next_f32(), 1.9 * rng.next_f32() - 0.95);
            let d = arpa_core::base::sampling::uniform_sphere(rng.next_2d()).as_vec3().normalize();
            let t_max = if rng.next_u32().is_multiple_of(4) { 0.05 + rng.next_f32() } else { 100.0 };
            (o, d, t_max)
        })
        .collect()
}

fn dv(g: &[u32], i: usize) -> DVec3 {
    v3(g, i)
}

#[test]
fn surfaces_match_prepared_scene() {
    let Some(ctx) = gpu() else { return };
    let prepared = PreparedScene::new(mixed_scene(4, 4)).expect("valid test scene");
    let scene = GpuScene::upload(ctx, &prepared).expect("upload");
    let caster = BruteForceCaster::new(&prepared);
    let rs = rays(11, 6000);
    let mut input = Vec::new();
    for (o, d, t) in &rs {
        push3(&mut input, o.to_array());
        push3(&mut input, d.to_array());
        input.push(fb(*t));
    }
    let source = format!("{}\n{KERNEL}", arpa_wgpu::shaders::scene());
    let out = run_scene_kernel(ctx, &scene, "scene surface", &source, "main", &input, rs.len() as u32, rs.len() * OUT);
    let meshes = &prepared.scene().meshes;
    let (mut hits, mut agree, mut differ) = (0usize, 0usize, 0usize);
    let (mut next_agree, mut next_differ) = (0usize, 0usize);
    let mut kinds = [0usize; 3];
    let (mut shaded, mut flat_with_normals, mut emissive) = (0, 0, 0);
    for (&(o, d, t_max), g) in rs.iter().zip(out.chunks(OUT)) {
        assert_eq!(g[0], g[1], "occluded disagrees with the closest hit for ray {o:?} {d:?} {t_max}");
        let want = caster.intersect(o, d, 0.0, t_max);
        if g[0] == 0 {
            if let Some(w) = want {
                assert!(w.b1.min(w.b2).min(1.0 - w.b1 - w.b2) < 1e-4 || (w.t - t_max).abs() <= 1e-5 * t_max, "device missed {w:?} for ray {o:?} {d:?}");
                differ += 1;
            }
            continue;
        }
        hits += 1;
        let hit = RayHit { t: f(g[2]), mesh: g[3], triangle: g[4], b1: f(g[5]), b2: f(g[6]) };
        match want {
            Some(w) if (w.mesh, w.triangle) == (hit.mesh, hit.triangle) => agree += 1,
            w => {
                let near_edge = |h: &RayHit| h.b1.min(h.b2).min(1.0 - h.b1 - h.b2) < 1e-4;
                assert!(near_edge(&hit) || w.is_some_and(|w| near_edge(&w)) || (hit.t - t_max).abs() <= 1e-5 * t_max, "device hit {hit:?}, core {w:?}");
                differ += 1;
            }
        }
        let s = prepared.surface(&hit);
        let tri = prepared.triangle(hit.mesh, hit.triangle);
        let vmax = tri.iter().map(|p| p.abs().max_element()).fold(0.0, f64::max);
        assert!((dv(g, 7) - s.position).length() <= 4.0 * EPS * vmax, "position {:?} vs {:?}", dv(g, 7), s.position);
        assert_eq!(dv(g, 10), s.geometric_normal.as_vec3().as_dvec3());
        assert!((dv(g, 13) - prepared.shading_normal_at(&s)).length() <= 8.0 * EPS, "shading normal {:?} vs {:?} at {hit:?}", dv(g, 13), prepared.shading_normal_at(&s));
        assert_eq!(g[16] == 1, prepared.has_shading_normals(&s));
        let (kind, color, ior) = match s.scattering {
            Scattering::Diffuse(c) => (0, c, None),
            Scattering::Mirror(c) => (1, c, None),
            Scattering::Refractive(ior, c) => (2, c, Some(ior)),
            Scattering::Thin(ior, c) => (3, c, Some(ior)),
        };
        kinds[kind as usize] += 1;
        assert_eq!(g[17], kind, "kind at {hit:?}");
        assert_eq!(dv(g, 18), color.as_dvec3());
        if let Some(ior) = ior {
            assert_eq!(f(g[21]), ior);
        }
        assert_eq!(g[25] == 1, s.emission.is_some());
        if let Some(e) = s.emission {
            emissive += 1;
            assert_eq!(dv(g, 22), e.as_dvec3());
        }
        assert_eq!((g[26], g[27]), (hit.mesh, hit.triangle));
        assert!((dv(g, 28) - s.barycentric).length() <= 2.0 * EPS);
        let specular = prepared.shading_normal(&s, DVec3::ZERO, DVec3::ZERO).map(|n| n.n).unwrap_or(s.geometric_normal);
        assert!((dv(g, 31) - specular).length() <= 8.0 * EPS, "specular normal {:?} vs {:?} at {hit:?}", dv(g, 31), specular);
        let m = &meshes[hit.mesh as usize];
        assert_eq!(g[34] == 1, m.normals.is_some());
        shaded += prepared.has_shading_normals(&s) as u32;
        flat_with_normals += (m.normals.is_some() && !prepared.has_shading_normals(&s)) as u32;
        let idx = m.indices[hit.triangle as usize];
        for k in 0..3 {
            assert_eq!(dv(g, 35 + 3 * k), tri[k].as_vec3().as_dvec3());
            let n = match &m.normals {
                Some(ns) => ns[idx[k] as usize].as_dvec3(),
                None => s.geometric_normal.as_vec3().as_dvec3(),
            };
            assert_eq!(dv(g, 44 + 3 * k), n);
        }
        let side = if d.as_dvec3().dot(s.geometric_normal) > 0.0 { -s.geometric_normal } else { s.geometric_normal };
        let want_o = offset_origin(s.position, side).as_dvec3();
        assert!((dv(g, 53) - want_o).length() <= 8.0 * EPS * (1.0 + s.position.abs().max_element()), "offset origin {:?} vs {:?}", dv(g, 53), want_o);
        // The ray leaving the hit straight on: from the device's origin, the core's rule.
        let left = TriangleId { mesh: hit.mesh, triangle: hit.triangle };
        let core_start = RayStart { origin: Vec3::from_array([f(g[61]), f(g[62]), f(g[63])]), ..RayStart::leaving(s.position, left) };
        assert!((dv(g, 61) - s.position).length() <= 4.0 * EPS * vmax, "leaving origin {:?} vs {:?}", dv(g, 61), s.position);
        let want_t_min = arpa_core::render::ray_cast::leave_t_min(core_start.origin);
        assert!((f(g[60]) - want_t_min).abs() <= want_t_min * EPS as f32, "t_min {} vs {want_t_min}", f(g[60]));
        let next = (g[56] == 1).then(|| RayHit { t: f(g[59]), mesh: g[57], triangle: g[58], b1: 0.0, b2: 0.0 });
        assert!(next.is_none_or(|n| (n.mesh, n.triangle) != (left.mesh, left.triangle)), "the leaving ray hit the triangle it left: {hit:?}");
        let core_next = core_start.intersect(&caster, d, f32::INFINITY);
        match (next, core_next) {
            (None, None) => next_agree += 1,
            (Some(a), Some(b)) if (a.mesh, a.triangle) == (b.mesh, b.triangle) => next_agree += 1,
            _ => next_differ += 1,
        }
    }
    assert!(agree as f64 >= 0.99 * (agree + differ) as f64, "{agree} hits agree, {differ} differ");
    assert!(next_agree as f64 >= 0.99 * (next_agree + next_differ) as f64, "leaving rays: {next_agree} agree, {next_differ} differ");
    assert!(hits > 4000 && kinds.iter().all(|&k| k > 50) && shaded > 200 && flat_with_normals > 20 && emissive > 5,
        "hits {hits}, kinds {kinds:?}, shaded {shaded}, flat with normals {flat_with_normals}, emissive {emissive}");
}
