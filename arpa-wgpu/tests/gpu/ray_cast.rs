//! Scene upload and closest-hit ray casting on ray queries (`GpuGeometry`) against the core's
//! `BruteForceCaster` (Möller–Trumbore in f64) on a closed box with an icosphere and a
//! tilted panel inside: random rays from inside the box, all kinds of hits.
//!
//! Bound: the device intersects in f32. Hit or miss, mesh and triangle must agree except
//! for rays within 1e-4 (barycentric) of a triangle edge, where rounding picks the triangle;
//! t within 1e-5 relative (plus 1e-6 m), barycentrics within 1e-4.

use crate::common::*;
use arpa_core::emit::emission::{Light, PointLight};
use arpa_core::render::prepared_scene::PreparedScene;
use arpa_core::{render::brute_force::BruteForceCaster, render::ray_cast::RayCaster};
use arpa_core::base::rng::{Rng, StreamDomain};
use arpa_core::render::scene::{Camera, Material, Scene, TriangleMesh};
use arpa_core::render::shapes::{icosphere, parallelogram};
use arpa_wgpu::scene::{GpuGeometry, SceneUploadError};
use glam::{DVec3, Vec3};
use proptest::prelude::*;

fn scene() -> Scene {
    let s = 1.0;
    // The empty mesh first: instance slots differ from mesh indices after it.
    let meshes = vec![
        TriangleMesh { uvs: None, name: "empty".into(), positions: vec![], normals: None, indices: vec![], material: 0, emission: None },
        parallelogram("floor", Vec3::new(-s, 0.0, -s), Vec3::new(2.0 * s, 0.0, 0.0), Vec3::new(0.0, 0.0, 2.0 * s), 0),
        parallelogram("ceiling", Vec3::new(-s, 2.0, -s), Vec3::new(0.0, 0.0, 2.0 * s), Vec3::new(2.0 * s, 0.0, 0.0), 0),
        parallelogram("back", Vec3::new(-s, 0.0, -s), Vec3::new(0.0, 2.0, 0.0), Vec3::new(2.0 * s, 0.0, 0.0), 0),
        parallelogram("front", Vec3::new(-s, 0.0, s), Vec3::new(2.0 * s, 0.0, 0.0), Vec3::new(0.0, 2.0, 0.0), 0),
        parallelogram("left", Vec3::new(-s, 0.0, -s), Vec3::new(0.0, 0.0, 2.0 * s), Vec3::new(0.0, 2.0, 0.0), 0),
        parallelogram("right", Vec3::new(s, 0.0, -s), Vec3::new(0.0, 2.0, 0.0), Vec3::new(0.0, 0.0, 2.0 * s), 0),
        icosphere("sphere", Vec3::new(0.3, 0.6, -0.2), 0.35, 3, true, 0),
        parallelogram("panel", Vec3::new(-0.8, 0.3, 0.1), Vec3::new(0.6, 0.4, 0.0), Vec3::new(0.1, 0.2, 0.5), 0),
    ];
    Scene { textures: Default::default(),
        meshes,
        materials: vec![Material::Diffuse { albedo: Vec3::splat(0.5) }],
        lights: vec![Light::Point(PointLight { position: DVec3::new(0.0, 1.5, 0.0), intensity: DVec3::ONE })],
        camera: Camera { position: Vec3::new(0.0, 1.0, 0.9), target: Vec3::new(0.0, 1.0, 0.0), up: Vec3::Y, vertical_fov: 1.0, width: 8, height: 8 },
        roughness_cutoff: 0.5,
        instancing: None,
    }
}

fn rays(seed: u32, n: usize) -> Vec<(Vec3, Vec3, f32)> {
    let mut rng = Rng::new(seed, 0, 0, StreamDomain::User);
    (0..n)
        .map(|_| {
            let o = Vec3::new(1.9 * rng.next_f32() - 0.95, 0.05 + 1.9 * rng.next_f32(), 1.9 * rng.next_f32() - 0.95);
            let d = arpa_core::base::sampling::uniform_sphere(rng.next_2d()).as_vec3().normalize();
            // Mostly unbounded, some short rays that stop before the walls.
            let t_max = if rng.next_u32().is_multiple_of(4) { 0.05 + rng.next_f32() } else { 100.0 };
            (o, d, t_max)
        })
        .collect()
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 3, max_shrink_iters: 8, ..ProptestConfig::default() })]

    #[test]
    fn closest_hits_match_brute_force(seed in any::<u32>()) {
        let Some(ctx) = gpu() else { return Ok(()) };
        let scene = scene();
        let prepared = PreparedScene::new(scene.clone()).expect("valid test scene");
        let reference = BruteForceCaster::new(&prepared);
        let gpu_scene = GpuGeometry::upload(ctx, &scene.meshes, None).map_err(|e| TestCaseError::fail(e.to_string()))?;
        prop_assert_eq!(gpu_scene.instance_count(), scene.meshes.len() - 1);
        let rs = rays(seed, 5000);
        let got = crate::support::cast_rays(ctx, &gpu_scene, &rs);
        let (mut hits, mut misses, mut sphere, mut panel) = (0, 0, 0, 0);
        for (&(o, d, t_max), g) in rs.iter().zip(&got) {
            let want = reference.intersect(o, d, 0.0, t_max);
            if let Some(w) = want {
                let edge = w.b1.min(w.b2).min(1.0 - w.b1 - w.b2);
                if edge < 1e-4 {
                    continue;
                }
            }
            match (want, g) {
                (None, None) => misses += 1,
                (Some(w), Some(h)) => {
                    hits += 1;
                    sphere += (w.mesh == 7) as u32;
                    panel += (w.mesh == 8) as u32;
                    prop_assert_eq!((h.mesh, h.triangle), (w.mesh, w.triangle), "ray {:?} {:?}", o, d);
                    prop_assert!((h.t - w.t).abs() <= 1e-5 * w.t + 1e-6, "t: device {} core {} for ray {:?} {:?}", h.t, w.t, o, d);
                    prop_assert!((h.b1 - w.b1).abs() <= 1e-4 && (h.b2 - w.b2).abs() <= 1e-4, "barycentrics: device ({}, {}) core ({}, {})", h.b1, h.b2, w.b1, w.b2);
                }
                (w, h) => {
                    // A miss on one side only: allowed only where t_max cuts the hit within rounding.
                    let t = w.map(|w| w.t).or(h.map(|h| h.t)).unwrap();
                    prop_assert!((t - t_max).abs() <= 1e-5 * t_max, "hit/miss disagree for ray {:?} {:?} t_max {}: core {:?} device {:?}", o, d, t_max, w, h);
                }
            }
        }
        prop_assert!(hits > 3000 && misses > 100 && sphere > 100 && panel > 20, "hits {}, misses {}, sphere {}, panel {}", hits, misses, sphere, panel);
    }
}

#[test]
fn bad_meshes_are_named() {
    let Some(ctx) = gpu() else { return };
    let mut s = scene();
    s.meshes[8].indices.push([0, 1, 9]);
    let e = GpuGeometry::upload(ctx, &s.meshes, None).err().expect("index out of range");
    assert!(matches!(e, SceneUploadError::IndexOutOfRange { .. }) && e.to_string().contains("panel") && e.to_string().contains('9'), "{e}");
    let mut s = scene();
    s.meshes[7].positions[3].y = f32::NAN;
    let e = GpuGeometry::upload(ctx, &s.meshes, None).err().expect("non-finite vertex");
    assert!(e.to_string().contains("sphere") && e.to_string().contains("vertex 3"), "{e}");
}
