//! Instancing on the real Crytek Sponza (`../shared/scenes/crytek-sponza/scene.xml`: 44
//! shapegroups placed by 170 instances): the loader records the instancing, and the cpu
//! backend's instanced ray casts give the flattened ones' hits bit for bit.

mod common;

use std::time::Instant;

use arpa::core::glam::Vec3;
use arpa::core::render::prepared_scene::PreparedScene;
use arpa::core::render::ray_cast::{RayCaster, RayHit};
use arpa::core::render::scene::Scene;
use arpa::cpu::{Device, EmbreeCaster};
use arpa::scene_file::load_scene;
use common::shared_scenes;

fn sponza() -> Option<Scene> {
    let dir = shared_scenes()?;
    Some(load_scene(&dir.join("crytek-sponza/scene.xml"), &[]).expect("crytek-sponza loads").scene)
}

/// Rays from the scene's camera through a `n × n` grid of the image, and from the
/// camera towards the centroid of every 97th triangle (rays that graze the geometry).
fn rays(scene: &Scene, n: u32) -> Vec<(Vec3, Vec3)> {
    let frame = scene.camera.frame().unwrap();
    let eye = scene.camera.position;
    let mut out: Vec<(Vec3, Vec3)> = (0..n * n).map(|i| (eye, frame.direction((i % n) as f32 + 0.5, (i / n) as f32 + 0.5, n, n))).collect();
    for m in &scene.meshes {
        let centroid = |t: &[u32; 3]| t.iter().map(|&i| m.positions[i as usize]).sum::<Vec3>() / 3.0;
        out.extend(m.indices.iter().step_by(97).filter_map(|t| (centroid(t) - eye).try_normalize().map(|d| (eye, d))));
    }
    out
}

/// What shading reads of a hit: the triangle and the barycentric weights, as bits (`t`
/// is the structure's own, within rounding).
fn bits(h: Option<RayHit>) -> Option<(u32, u32, u32, u32)> {
    h.map(|h| (h.mesh, h.triangle, h.b1.to_bits(), h.b2.to_bits()))
}

/// The loader records Sponza's groups; the instanced caster uses Embree instances and
/// every camera ray, and every ray aimed at a vertex, hits the triangle the flattened
/// caster hits with the same barycentric weights bit for bit, or both miss.
#[test]
fn crytek_sponza_instanced_casts_equal_flattened_casts() {
    let Some(scene) = sponza() else { return };
    let inst = scene.instancing.as_ref().expect("shapegroups are recorded");
    assert_eq!((inst.prototypes.len(), inst.instances.len()), (44, 170));
    let mut flat = scene.clone();
    flat.instancing = None;
    let device = Device::new().unwrap();
    let instanced = EmbreeCaster::new(&device, &PreparedScene::new(scene.clone()).unwrap()).unwrap();
    let flattened = EmbreeCaster::new(&device, &PreparedScene::new(flat).unwrap()).unwrap();
    assert!(instanced.instance_count() > 0 && flattened.instance_count() == 0);
    let rays = rays(&scene, 256);
    let differ: Vec<_> = rays
        .iter()
        .filter_map(|(o, d)| {
            let (a, b) = (instanced.intersect(*o, *d, 0.0, f32::INFINITY), flattened.intersect(*o, *d, 0.0, f32::INFINITY));
            (bits(a) != bits(b)).then_some((a, b))
        })
        .collect();
    // Sponza has coincident triangles (duplicates, overlapping faces): which of a tie a
    // structure reports first is its own; every other ray must agree.
    let ties = |a: &Option<RayHit>, b: &Option<RayHit>| matches!((a, b), (Some(a), Some(b)) if (a.t - b.t).abs() <= 1e-5 * (1.0 + b.t));
    let untied: Vec<_> = differ.iter().filter(|(a, b)| !ties(a, b)).collect();
    let hits = rays.iter().filter(|(o, d)| flattened.intersect(*o, *d, 0.0, f32::INFINITY).is_some()).count();
    assert!(hits > rays.len() / 2, "{hits} of {} rays hit", rays.len());
    assert!(untied.is_empty(), "{} of {} rays hit differently, e.g. {:?}", untied.len(), rays.len(), untied.first());
    assert!(differ.len() * 1000 < rays.len(), "{} of {} rays meet a tie", differ.len(), rays.len());
    eprintln!("{} of {} rays agree bit for bit; {} meet coincident faces in another order", rays.len() - differ.len(), rays.len(), differ.len());
}

/// Resident memory (kB) of this process.
fn rss_kb() -> u64 {
    let s = std::fs::read_to_string("/proc/self/status").unwrap_or_default();
    s.lines().find_map(|l| l.strip_prefix("VmRSS:")).and_then(|v| v.split_whitespace().next()?.parse().ok()).unwrap_or(0)
}

/// Measurement, not a check (`cargo test --release --test instancing -- --ignored
/// --nocapture`; `ARPA_INSTANCING_MEASURE=flattened` or `instanced` measures one variant,
/// in a fresh process for a clean resident-memory figure): the cpu triangle BVH of
/// crytek-sponza, the resident memory its first build adds, its build time (best of 3)
/// and the time of the camera and vertex rays.
#[test]
#[ignore]
fn crytek_sponza_bvh_flattened_vs_instanced() {
    let only = std::env::var("ARPA_INSTANCING_MEASURE").ok();
    let device = Device::new().unwrap();
    for what in ["flattened", "instanced"] {
        if only.as_deref().is_some_and(|o| o != what) {
            continue;
        }
        let Some(mut s) = sponza() else { return };
        if what == "flattened" {
            s.instancing = None;
        }
        let rays = rays(&s, 512);
        let prepared = PreparedScene::new(s).unwrap();
        let before = rss_kb();
        let first = EmbreeCaster::new(&device, &prepared).unwrap();
        let grew = rss_kb().saturating_sub(before);
        let instances = first.instance_count();
        drop(first);
        let (mut build, mut cast) = (f64::INFINITY, f64::INFINITY);
        let mut hits = 0;
        for _ in 0..3 {
            let t = Instant::now();
            let caster = EmbreeCaster::new(&device, &prepared).unwrap();
            build = build.min(t.elapsed().as_secs_f64());
            let t = Instant::now();
            hits = rays.iter().filter(|(o, d)| caster.intersect(*o, *d, 0.0, f32::INFINITY).is_some()).count();
            cast = cast.min(t.elapsed().as_secs_f64());
        }
        println!("{what}: {instances} instances, first build +{:.1} MiB resident, build {:.1} ms, {} rays ({hits} hits) {:.1} ms (best of 3)", grew as f64 / 1024.0, build * 1e3, rays.len(), cast * 1e3);
    }
}

/// Measurement, not a check (`--ignored --nocapture`): crytek-sponza at 160×90, ARPA,
/// 4 iterations of 100k photons, seed 1, instanced and flattened on cpu: how many pixels
/// differ, the image means and the largest relative pixel difference.
#[test]
#[ignore]
fn crytek_sponza_image_flattened_vs_instanced() {
    use arpa::core::render::tracer::{RenderSettings, Tracer};
    let Some(mut scene) = sponza() else { return };
    (scene.camera.width, scene.camera.height) = (160, 90);
    let mut flat = scene.clone();
    flat.instancing = None;
    let settings = RenderSettings { photons_per_iteration: 100_000, seed: 1, ..RenderSettings::default() };
    let mut images = Vec::new();
    for s in [&scene, &flat] {
        let mut t = arpa::cpu::CpuTracer::new().unwrap();
        t.upload_scene(s, &settings).unwrap();
        for _ in 0..4 {
            t.iterate().unwrap();
        }
        images.push(t.read_image().unwrap());
    }
    let (a, b) = (&images[0].pixels, &images[1].pixels);
    let differ = a.iter().zip(b).filter(|(x, y)| x != y).count();
    let mean = |v: &[Vec3]| v.iter().map(|p| p.element_sum() as f64).sum::<f64>() / (3 * v.len()) as f64;
    let worst = a.iter().zip(b).map(|(x, y)| ((*x - *y).abs().max_element() / y.max_element().max(1e-3)) as f64).fold(0.0, f64::max);
    println!("sponza 160x90, 4 x 100k: {differ} of {} pixels differ; means {:.6} instanced, {:.6} flattened; largest relative difference {worst:.3e}", a.len(), mean(a), mean(b));
}
