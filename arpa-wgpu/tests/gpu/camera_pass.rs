//! The camera pass (`CameraPass`, camera_pass.wgsl) per pixel against the core's
//! `trace_camera_path` (with its brute-force caster, f64) on small scenes: the mixed scene
//! (diffuse, mirror, glass, rough materials, smooth and inverted vertex normals, area,
//! point, spot and directional lights) and conformance-like scenes (glass slab, mirror
//! wall, Cornell box with an area light, glass sphere and mirror block, a wavy water
//! surface over a pool floor).
//!
//! The device traces in f32, the core in f64. A pixel's path *agrees* when validity,
//! query position and query normal agree; its weight must then agree within f32 bounds
//! (it depends on no further decision), and its radiance too unless a next-event decision
//! (shadow ray grazing an edge, area-emitter pick at a CDF step) went the other way.
//! Paths diverge only where a decision sits within f32 rounding of its threshold (Fresnel
//! choice, a ray grazing an edge): at least 99 % of the pixels must agree in everything.
//! Bounds (ε = f32::EPSILON): position within 1e-4 m ·(1 + |p|) (f32 rounding through
//! up to `max_depth` refractions; divergent paths land centimetres apart); normal within
//! 1e-5; weight within 64ε relative (products of ≤ 10 f32 factors); radiance within
//! 1e-3 relative to its largest component plus 1e-6 W/(m² sr): cosines and 1/r² at f32
//! positions err by ~1e-6 relative per term, amplified by `1/cos` at grazing light
//! directions (a Cornell-wall point 5e-5 m below the light's plane: 1.1e-3 relative at
//! 1.7e-5 absolute). Each test prints the largest differences it saw.

use crate::common::*;
use crate::scenes;
use arpa_core::render::camera_path::trace_camera_path;
use arpa_core::render::prepared_scene::PreparedScene;
use arpa_core::render::brute_force::BruteForceCaster;
use arpa_core::render::scene::Scene;
use arpa_core::render::tracer::{QueryRecord, RenderSettings};
use arpa_wgpu::camera::{CameraPass, CameraPassError};
use arpa_wgpu::scene::GpuScene;
use arpa_wgpu::GpuContext;
use glam::Vec3;

const EPS: f32 = f32::EPSILON;

fn device_queries(ctx: &GpuContext, prepared: &PreparedScene, settings: &RenderSettings, iteration: u32) -> Vec<QueryRecord> {
    let scene = GpuScene::upload(ctx, prepared).expect("upload");
    let pass = CameraPass::new(ctx, &scene, prepared, settings).expect("camera pass");
    let queries = pass.create_query_buffer(wgpu::BufferUsages::COPY_SRC);
    let staging = ctx.device.create_buffer(&wgpu::BufferDescriptor {
        label: Some("camera test staging"),
        size: pass.query_buffer_bytes(),
        usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
        mapped_at_creation: false,
    });
    let scope = ctx.device.push_error_scope(wgpu::ErrorFilter::Validation);
    let mut encoder = ctx.device.create_command_encoder(&Default::default());
    pass.encode(&mut encoder, iteration, &queries);
    encoder.copy_buffer_to_buffer(&queries, 0, &staging, 0, pass.query_buffer_bytes());
    ctx.queue.submit([encoder.finish()]);
    assert!(pollster::block_on(scope.pop()).is_none(), "validation error");
    staging.map_async(wgpu::MapMode::Read, .., |r| r.expect("map"));
    ctx.device.poll(wgpu::PollType::wait_indefinitely()).expect("poll");
    let bytes = staging.get_mapped_range(..).expect("mapped").to_vec();
    bytemuck::pod_collect_to_vec::<u8, QueryRecord>(&bytes)
}

#[derive(Debug, Default)]
struct Tally {
    pixels: usize,
    valid: usize,
    agree: usize,
    path_differs: usize,
    radiance_differs: usize,
    lit: usize,
    /// Largest errors among agreeing pixels: position (m, over 1 + |p|), weight and
    /// radiance (relative to their largest component).
    max_position: f32,
    max_weight: f32,
    max_radiance: f32,
    /// Valid query points whose normal faces away from the camera (flipped below the
    /// shading plane, or seen through a specular chain).
    facing_away: usize,
    /// Valid query points whose weight is below 0.6 albedo/π per channel: seen through an
    /// interface into a denser medium (radiance-mode factor) or a coloured specular chain.
    attenuated: usize,
}

fn close3(a: [f32; 3], b: [f32; 3], tol: f32) -> bool {
    (Vec3::from(a) - Vec3::from(b)).length() <= tol
}

fn compare(name: &str, scene: Scene, settings: RenderSettings, iterations: &[u32]) -> Tally {
    let Some(ctx) = gpu() else { return Tally::default() };
    let prepared = PreparedScene::new(scene).expect("valid scene");
    let caster = BruteForceCaster::new(&prepared);
    let mut t = Tally::default();
    for &it in iterations {
        let got = device_queries(ctx, &prepared, &settings, it);
        let cam = prepared.scene().camera;
        assert_eq!(got.len(), (cam.width * cam.height) as usize);
        for (pixel, g) in got.iter().enumerate() {
            let w = trace_camera_path(&prepared, &caster, &settings, it, pixel as u32);
            t.pixels += 1;
            assert_eq!(g.pixel, pixel as u32);
            assert_eq!((g._pad0, g._pad1), (0, 0));
            assert!(g.radiance.iter().chain(&g.weight).chain(&g.position).chain(&g.normal).all(|x| x.is_finite()), "{name}: non-finite record {g:?}");
            let p = Vec3::from(w.position);
            let same_path = g.valid == w.valid
                && (w.valid == 0 || (close3(g.position, w.position, 1e-4 * (1.0 + p.abs().max_element())) && close3(g.normal, w.normal, 1e-5)));
            if !same_path {
                t.path_differs += 1;
                continue;
            }
            t.valid += w.valid as usize;
            if w.valid == 1 {
                let to_camera = cam.position - p;
                t.facing_away += (Vec3::from(w.normal).dot(to_camera) < 0.0) as usize;
                t.attenuated += (Vec3::from(w.weight).max_element() < 0.6 * 0.8 * std::f32::consts::FRAC_1_PI) as usize;
            }
            let rel = |a: [f32; 3], b: [f32; 3]| {
                let m = Vec3::from(b).abs().max_element();
                if m > 0.0 { (Vec3::from(a) - Vec3::from(b)).length() / m } else { (Vec3::from(a) - Vec3::from(b)).length() }
            };
            t.max_position = t.max_position.max((Vec3::from(g.position) - p).length() / (1.0 + p.abs().max_element()));
            let wmax = Vec3::from(w.weight).abs().max_element();
            assert!(close3(g.weight, w.weight, 64.0 * EPS * wmax), "{name} it {it} pixel {pixel}: weight {:?} vs core {:?}", g.weight, w.weight);
            let rmax = Vec3::from(w.radiance).abs().max_element();
            t.lit += (rmax > 0.0) as usize;
            if close3(g.radiance, w.radiance, 1e-3 * rmax + 1e-6) {
                t.agree += 1;
                t.max_weight = t.max_weight.max(rel(g.weight, w.weight));
                t.max_radiance = t.max_radiance.max(rel(g.radiance, w.radiance));
            } else {
                t.radiance_differs += 1;
                eprintln!("{name} it {it} pixel {pixel}: radiance {:?} vs core {:?}", g.radiance, w.radiance);
            }
        }
    }
    eprintln!("{name}: {t:?}");
    assert!(t.agree as f64 >= 0.99 * t.pixels as f64, "{name}: only {} of {} pixels agree ({t:?})", t.agree, t.pixels);
    t
}

fn settings(seed: u32, direct_lighting: bool) -> RenderSettings {
    RenderSettings { seed, direct_lighting, ..RenderSettings::default() }
}

#[test]
fn mixed_scene_matches_core() {
    let t = compare("mixed", scenes::mixed_scene(48, 36), settings(7, true), &[0, 5]);
    if t.pixels > 0 {
        assert!(t.valid > t.pixels / 2 && t.lit > t.pixels / 2 && t.facing_away > 20, "{t:?}");
    }
}

#[test]
fn mixed_scene_without_direct_lighting_matches_core() {
    compare("mixed, no NEE", scenes::mixed_scene(32, 24), settings(3, false), &[2]);
}

#[test]
fn conformance_like_scenes_match_core() {
    // Minimum shares of directly lit pixels: the slab's floor and the pool floor are lit
    // only through the glass or water (shadow rays stop at interfaces), the others directly.
    for (name, scene, lit_share) in [
        ("glass slab", scenes::glass_slab(32), 0),
        ("mirror wall", scenes::mirror_wall(32), 4),
        ("cornell", scenes::cornell(40), 4),
        ("water", scenes::water(32), 16),
    ] {
        let t = compare(name, scene, settings(11, true), &[0, 1]);
        if t.pixels > 0 {
            assert!(t.valid > t.pixels / 2 && (lit_share == 0 || t.lit > t.pixels / lit_share), "{name}: {t:?}");
            if name == "water" {
                assert!(t.attenuated > t.pixels / 4, "{name}: {t:?}");
            }
        }
    }
}

#[test]
fn same_seed_is_bit_identical_and_iterations_differ() {
    let Some(ctx) = gpu() else { return };
    let prepared = PreparedScene::new(scenes::cornell(24)).expect("valid scene");
    let a = device_queries(ctx, &prepared, &settings(5, true), 3);
    let b = device_queries(ctx, &prepared, &settings(5, true), 3);
    let c = device_queries(ctx, &prepared, &settings(5, true), 4);
    assert_eq!(bytemuck::cast_slice::<QueryRecord, u32>(&a), bytemuck::cast_slice::<QueryRecord, u32>(&b));
    assert_ne!(bytemuck::cast_slice::<QueryRecord, u32>(&a), bytemuck::cast_slice::<QueryRecord, u32>(&c));
    // Two iterations encoded into one command buffer keep their own iteration numbers.
    let scene = GpuScene::upload(ctx, &prepared).expect("upload");
    let pass = CameraPass::new(ctx, &scene, &prepared, &settings(5, true)).expect("camera pass");
    let bytes = pass.query_buffer_bytes();
    let (q3, q4) = (pass.create_query_buffer(wgpu::BufferUsages::COPY_SRC), pass.create_query_buffer(wgpu::BufferUsages::COPY_SRC));
    let staging = ctx.device.create_buffer(&wgpu::BufferDescriptor {
        label: None,
        size: 2 * bytes,
        usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
        mapped_at_creation: false,
    });
    let mut encoder = ctx.device.create_command_encoder(&Default::default());
    pass.encode(&mut encoder, 3, &q3);
    pass.encode(&mut encoder, 4, &q4);
    encoder.copy_buffer_to_buffer(&q3, 0, &staging, 0, bytes);
    encoder.copy_buffer_to_buffer(&q4, 0, &staging, bytes, bytes);
    ctx.queue.submit([encoder.finish()]);
    staging.map_async(wgpu::MapMode::Read, .., |r| r.expect("map"));
    ctx.device.poll(wgpu::PollType::wait_indefinitely()).expect("poll");
    let both = staging.get_mapped_range(..).expect("mapped").to_vec();
    assert_eq!(&both[..bytes as usize], bytemuck::cast_slice::<QueryRecord, u8>(&a));
    assert_eq!(&both[bytes as usize..], bytemuck::cast_slice::<QueryRecord, u8>(&c));
}

#[test]
fn oversized_images_are_refused_with_their_size() {
    let Some(ctx) = gpu() else { return };
    let mut scene = scenes::cornell(8);
    (scene.camera.width, scene.camera.height) = (100_000, 100_000);
    let prepared = PreparedScene::new(scene).expect("valid scene");
    let gpu_scene = GpuScene::upload(ctx, &prepared).expect("upload");
    let e = CameraPass::new(ctx, &gpu_scene, &prepared, &settings(0, true)).err().expect("10^10 pixels");
    assert!(matches!(e, CameraPassError::TooManyPixels { .. }) && e.to_string().contains("100000 x 100000"), "{e}");
}
