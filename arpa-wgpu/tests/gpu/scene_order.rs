//! The BLAS triangle order of the scene upload (`morton_triangle_order`): a permutation of
//! each mesh's triangles whose centroid Morton codes ascend, and lookups by (mesh, triangle)
//! that still speak the core's numbering. A grid of triangles stored in a scrambled order
//! (so the Morton order is far from the file's) is hit through its centroids by vertical
//! rays: `arpa_scene_intersect`, `arpa_scene_surface`, `arpa_scene_triangle_vertices` and a
//! ray cast against the top-level structure alone (`support::cast_rays`, mapping the BLAS
//! primitive back through `GpuGeometry::triangle_orders`) must each name the triangle the
//! core's brute-force caster hits,
//! on every ray (a centroid lies far from every edge, so no tie is possible), with the
//! core's vertices exactly.

use crate::common::*;
use crate::scenes::mixed_scene;
use arpa_core::render::prepared_scene::PreparedScene;
use arpa_core::{render::brute_force::BruteForceCaster, render::ray_cast::RayCaster};
use arpa_core::render::scene::TriangleMesh;
use crate::support::run_scene_kernel;
use arpa_core::base::morton::morton_code;
use arpa_core::gpu::scene::morton_triangle_order;
use arpa_wgpu::scene::GpuScene;
use glam::Vec3;

const KERNEL: &str = r#"
@group(1) @binding(0) var<storage, read> input: array<u32>;
@group(1) @binding(1) var<storage, read_write> output: array<u32>;
fn in_v3(i: u32) -> vec3<f32> { return vec3<f32>(bitcast<f32>(input[i]), bitcast<f32>(input[i + 1u]), bitcast<f32>(input[i + 2u])); }

@compute @workgroup_size(64)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    if gid.x * 3u >= arrayLength(&input) { return; }
    let o = in_v3(gid.x * 3u);
    let h = arpa_scene_intersect(o, vec3<f32>(0.0, -1.0, 0.0), 0.0, 10.0);
    let ob = gid.x * 13u;
    output[ob] = h.hit;
    output[ob + 1u] = h.mesh;
    output[ob + 2u] = h.triangle;
    if h.hit == 0u { return; }
    let s = arpa_scene_surface(h);
    output[ob + 3u] = s.triangle;
    let p = arpa_scene_triangle_vertices(h.mesh, h.triangle);
    for (var k = 0u; k < 3u; k++) {
        output[ob + 4u + 3u * k] = bitcast<u32>(p[k].x);
        output[ob + 5u + 3u * k] = bitcast<u32>(p[k].y);
        output[ob + 6u + 3u * k] = bitcast<u32>(p[k].z);
    }
}
"#;

/// A horizontal `n` x `n` grid of quads (two triangles each) at height `y` in [-0.8, 0.8]²,
/// its triangles stored in a scrambled order (a multiplicative permutation of the indices).
fn scrambled_grid(n: u32, y: f32) -> TriangleMesh {
    let step = 1.6 / n as f32;
    let mut positions = Vec::new();
    for j in 0..=n {
        for i in 0..=n {
            positions.push(Vec3::new(-0.8 + step * i as f32, y, -0.8 + step * j as f32));
        }
    }
    let v = |i: u32, j: u32| j * (n + 1) + i;
    let mut tris = Vec::new();
    for j in 0..n {
        for i in 0..n {
            tris.push([v(i, j), v(i, j + 1), v(i + 1, j)]);
            tris.push([v(i + 1, j), v(i, j + 1), v(i + 1, j + 1)]);
        }
    }
    let count = tris.len() as u64;
    // 7919 is prime and does not divide 2n², so t -> 7919 t mod 2n² permutes.
    let indices = (0..count).map(|t| tris[((t * 7919) % count) as usize]).collect();
    TriangleMesh { uvs: None, name: "scrambled grid".into(), positions, normals: None, indices, material: 0, emission: None }
}

fn centroid(m: &TriangleMesh, t: usize) -> Vec3 {
    m.indices[t].iter().map(|&i| m.positions[i as usize]).sum::<Vec3>() / 3.0
}

#[test]
fn morton_order_is_a_sorted_permutation() {
    let grid = scrambled_grid(16, 0.5);
    let order = morton_triangle_order(&grid);
    let mut seen = order.clone();
    seen.sort_unstable();
    assert_eq!(seen, (0..grid.indices.len() as u32).collect::<Vec<_>>(), "not a permutation");
    assert_ne!(order, seen, "the scrambled grid must not already be in Morton order");
    // The box of the centroids; the grid is flat in y (that axis maps to cell 0).
    let cs: Vec<Vec3> = (0..grid.indices.len()).map(|t| centroid(&grid, t)).collect();
    let lo = cs.iter().copied().fold(Vec3::INFINITY, Vec3::min);
    let hi = cs.iter().copied().fold(Vec3::NEG_INFINITY, Vec3::max);
    let inv = [1.0 / (hi.x - lo.x), 0.0, 1.0 / (hi.z - lo.z)];
    let codes: Vec<u32> = order.iter().map(|&t| morton_code(cs[t as usize].to_array(), lo.to_array(), inv)).collect();
    assert!(codes.windows(2).all(|w| w[0] <= w[1]), "Morton codes do not ascend along the order");
    // The mixed scene's icospheres are permuted too, so the surface test exercises the map.
    let mixed = mixed_scene(4, 4);
    assert!(mixed.meshes.iter().any(|m| morton_triangle_order(m).iter().zip(0u32..).any(|(&a, b)| a != b)));
    let empty = TriangleMesh { uvs: None, indices: Vec::new(), ..grid };
    assert!(morton_triangle_order(&empty).is_empty());
}

#[test]
fn scrambled_triangles_keep_the_core_numbering() {
    let Some(ctx) = gpu() else { return };
    let n = 16;
    let mut scene = mixed_scene(4, 4);
    let (low, high) = (scrambled_grid(n, 0.5), scrambled_grid(n - 3, 0.2));
    scene.meshes = vec![low, high];
    let prepared = PreparedScene::new(scene).expect("valid test scene");
    let gpu_scene = GpuScene::upload(ctx, &prepared).expect("upload");
    let caster = BruteForceCaster::new(&prepared);
    let grid = &prepared.scene().meshes[0];
    let origins: Vec<Vec3> = (0..grid.indices.len()).map(|t| centroid(grid, t) + Vec3::new(0.0, 1.0, 0.0)).collect();
    let input: Vec<u32> = origins.iter().flat_map(|o| o.to_array().map(fb)).collect();
    let source = format!("{}\n{KERNEL}", arpa_wgpu::shaders::scene());
    let out = run_scene_kernel(ctx, &gpu_scene, "scene order", &source, "main", &input, origins.len() as u32, origins.len() * 13);
    let rays: Vec<(Vec3, Vec3, f32)> = origins.iter().map(|&o| (o, Vec3::new(0.0, -1.0, 0.0), 10.0)).collect();
    let cast = crate::support::cast_rays(ctx, gpu_scene.geometry(), &rays);
    for (t, (g, c)) in out.chunks(13).zip(&cast).enumerate() {
        let want = caster.intersect(rays[t].0, rays[t].1, 0.0, rays[t].2).expect("the core hits the grid");
        assert_eq!((want.mesh, want.triangle), (0, t as u32), "core");
        assert_eq!(&g[..4], &[1, 0, t as u32, t as u32], "device hit/mesh/triangle/surface triangle for triangle {t}");
        let tri = prepared.triangle(0, t as u32);
        for (k, p) in tri.iter().enumerate() {
            assert_eq!(v3(g, 4 + 3 * k), p.as_vec3().as_dvec3(), "vertex {k} of triangle {t}");
        }
        let c = c.expect("the ray cast hits the grid");
        assert_eq!((c.mesh, c.triangle), (0, t as u32), "ray cast for triangle {t}");
    }
}
