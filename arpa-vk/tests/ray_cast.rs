//! Acceleration structures and a ray-tracing pipeline on a real Vulkan driver (lavapipe in
//! CI) under the Khronos validation layer: closest-hit ray casting (raygen + closest-hit +
//! miss, WGSL compiled by naga) against the core's `BruteForceCaster` (Möller–Trumbore in
//! `f64`) on a closed box with an icosphere and a tilted panel inside, random rays from
//! inside the box. Also: AABB and top-level builds, and hit-group selection by the
//! instances' SBT record offsets (two hit groups in one pipeline).
//!
//! Bounds. The device intersects in `f32`:
//! - hit or miss must agree, except where `t_max` cuts a hit within rounding (`|t - t_max|
//!   <= 1e-5 t_max`);
//! - the mesh and triangle must agree, except for a tie: a ray within 1e-4 (barycentric) of
//!   a triangle edge, where rounding picks either neighbour; ties are counted and must stay
//!   below 0.5 % of the rays;
//! - t within 1e-5 relative (plus 1e-6 m): a few `f32` ulps of the hit distance, with margin
//!   for grazing hits where the `f32` intersection is ill-conditioned;
//! - barycentrics within 1e-4 (the closest-hit shader recomputes them in `f32`).
//!
//! Without a Vulkan loader, driver or validation layer the tests skip with a loud message,
//! except in CI (env `CI` set), where they fail.

use arpa_core::emit::emission::{Light, PointLight};
use arpa_core::gpu::scene::SceneTables;
use arpa_core::render::prepared_scene::PreparedScene;
use arpa_core::{render::brute_force::BruteForceCaster, render::ray_cast::RayCaster};
use arpa_core::base::rng::{Rng, StreamDomain};
use arpa_core::render::scene::{Camera, Material, Scene, TriangleMesh};
use arpa_core::render::shapes::{icosphere, parallelogram};
use arpa_vk::accel::IDENTITY_TRANSFORM;
use arpa_vk::shaders::{compile_wgsl, ray_cast_source};
use arpa_vk::vk;
use arpa_vk::{
    BindingKind, Buffer, HitGroup, MemoryLocation, Resource, RtPipeline, RtPipelineDesc, SceneAccel,
    ShaderEntry, TlasInstance, VkContext, VkError,
};
use glam::{DVec3, Vec3};

mod support;
use support::{assert_clean, context};

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
        camera: Camera {
            position: Vec3::new(0.0, 1.0, 0.9),
            target: Vec3::new(0.0, 1.0, 0.0),
            up: Vec3::Y,
            vertical_fov: 1.0,
            width: 8,
            height: 8,
        },
        roughness_cutoff: 0.5,
        instancing: None,
    }
}

/// `VkCastRay` of ray_cast.wgsl.
#[repr(C)]
#[derive(Clone, Copy, Debug, bytemuck::Pod, bytemuck::Zeroable)]
struct CastRay {
    origin: [f32; 3],
    t_min: f32,
    direction: [f32; 3],
    t_max: f32,
}

/// `VkCastHit` of ray_cast.wgsl.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, bytemuck::Pod, bytemuck::Zeroable)]
struct CastHit {
    t: f32,
    mesh: u32,
    primitive: u32,
    triangle: u32,
    b1: f32,
    b2: f32,
    pad: [u32; 2],
}

fn rays(seed: u32, n: usize) -> Vec<CastRay> {
    let mut rng = Rng::new(seed, 0, 0, StreamDomain::User);
    (0..n)
        .map(|_| {
            let o = Vec3::new(1.9 * rng.next_f32() - 0.95, 0.05 + 1.9 * rng.next_f32(), 1.9 * rng.next_f32() - 0.95);
            let d = arpa_core::base::sampling::uniform_sphere(rng.next_2d()).as_vec3().normalize();
            // Mostly unbounded, some short rays that stop before the walls.
            let t_max = if rng.next_u32().is_multiple_of(4) { 0.05 + rng.next_f32() } else { 100.0 };
            CastRay { origin: o.to_array(), t_min: 0.0, direction: d.to_array(), t_max }
        })
        .collect()
}

/// A host-visible storage buffer holding `bytes` (one zeroed record of `pad` bytes when empty).
fn storage(ctx: &VkContext, label: &str, bytes: &[u8], pad: usize, usage: vk::BufferUsageFlags) -> Buffer {
    let zeros = vec![0u8; pad];
    let bytes = if bytes.is_empty() { &zeros[..] } else { bytes };
    let mut b = ctx.create_buffer(label, bytes.len() as u64, usage, MemoryLocation::CpuToGpu).expect("buffer");
    b.write(0, bytes).expect("write");
    b
}

#[test]
fn closest_hits_match_brute_force() {
    let Some(ctx) = context("ray-cast") else { return };
    let start = std::time::Instant::now();
    let scene = scene();
    let prepared = PreparedScene::new(scene.clone()).expect("valid test scene");
    let reference = BruteForceCaster::new(&prepared);

    let accel = SceneAccel::build(&ctx, &prepared).expect("acceleration structures");
    assert_eq!(accel.instance_count(), scene.meshes.len() - 1);
    assert!(accel.blas(0).is_none() && accel.blas(7).is_some_and(|b| b.primitive_count() == scene.meshes[7].indices.len() as u32));
    let tables = SceneTables::new(&prepared, accel.triangle_orders()).expect("tables");

    let spirv = compile_wgsl("ray cast", &ray_cast_source()).expect("ray_cast.wgsl");
    let module = ctx.create_shader_module(&spirv).expect("shader module");
    let entry = |entry| ShaderEntry { module: &module, entry };
    use BindingKind::{AccelerationStructure as As, StorageBuffer as Sb, UniformBuffer as Ub};
    let pipeline = RtPipeline::new(
        &ctx,
        &RtPipelineDesc {
            label: "ray cast",
            raygen: entry("vk_cast_raygen"),
            miss: &[entry("vk_cast_miss")],
            hit_groups: &[HitGroup::Triangles { closest_hit: Some(entry("vk_cast_closest_hit")), any_hit: None }],
            sets: &[&[As, Ub, Sb, Sb, Sb], &[Sb, Sb]],
            push_constant_size: 0,
        },
    )
    .expect("pipeline");
    drop(module);
    eprintln!("arpa-vk ray-tracing properties: {:?}", ctx.ray_tracing());
    eprintln!("arpa-vk SBT layout: {:?}", pipeline.sbt_layout());

    let storage_usage = vk::BufferUsageFlags::STORAGE_BUFFER;
    let info = storage(&ctx, "scene info", bytemuck::bytes_of(&tables.info), 0, vk::BufferUsageFlags::UNIFORM_BUFFER);
    let meshes = storage(&ctx, "scene meshes", bytemuck::cast_slice(&tables.meshes), 64, storage_usage);
    let triangles = storage(&ctx, "scene triangles", bytemuck::cast_slice(&tables.triangles), 112, storage_usage);
    let emitters = storage(&ctx, "scene emitters", bytemuck::cast_slice(&tables.emitters), 128, storage_usage);

    let n = 20_000;
    let rs = rays(0x5eed_0001, n);
    let ray_buf = storage(&ctx, "rays", bytemuck::cast_slice(&rs), 0, storage_usage);
    let hit_buf = ctx.create_buffer("hits", (n * 32) as u64, storage_usage, MemoryLocation::GpuToCpu).expect("hits");
    let scene_set = [
        Resource::AccelerationStructure(accel.tlas()),
        Resource::UniformBuffer(&info),
        Resource::StorageBuffer(&meshes),
        Resource::StorageBuffer(&triangles),
        Resource::StorageBuffer(&emitters),
    ];
    let cast_set = [Resource::StorageBuffer(&ray_buf), Resource::StorageBuffer(&hit_buf)];
    let bindings = pipeline.bind(&[&scene_set, &cast_set]).expect("bind");
    // A 2-D launch (x fastest) covering every ray; the raygen skips the indices past the end.
    let width = 64u32;
    pipeline.trace_and_wait(&ctx, &bindings, &[], [width, (n as u32).div_ceil(width), 1]).expect("trace");
    let bytes = hit_buf.read(0, (n * 32) as u64).expect("read hits");
    let got: Vec<CastHit> = bytes.chunks_exact(32).map(bytemuck::pod_read_unaligned).collect();

    let (mut hits, mut misses, mut sphere, mut panel, mut ties, mut cut) = (0, 0, 0, 0, 0, 0);
    let (mut worst_t, mut worst_b) = (0.0f32, 0.0f32);
    for (r, g) in rs.iter().zip(&got) {
        let (o, d) = (Vec3::from_array(r.origin), Vec3::from_array(r.direction));
        let want = reference.intersect(o, d, r.t_min, r.t_max);
        let have = (g.mesh != u32::MAX).then_some(g);
        if let Some(h) = have {
            assert_eq!(accel.mesh_triangle(h.mesh, h.primitive), Some(h.triangle), "the shader's primitive -> triangle map");
        }
        match (want, have) {
            (None, None) => misses += 1,
            (Some(w), Some(h)) => {
                let rel_t = (h.t - w.t).abs() / w.t.max(1e-6);
                assert!((h.t - w.t).abs() <= 1e-5 * w.t + 1e-6, "t: device {} core {} for ray {r:?}", h.t, w.t);
                if (h.mesh, h.triangle) != (w.mesh, w.triangle) {
                    let edge = w.b1.min(w.b2).min(1.0 - w.b1 - w.b2);
                    assert!(edge < 1e-4, "ray {r:?}: device hit {h:?}, core {w:?}");
                    ties += 1;
                    continue;
                }
                hits += 1;
                sphere += (w.mesh == 7) as u32;
                panel += (w.mesh == 8) as u32;
                worst_t = worst_t.max(rel_t);
                let db = (h.b1 - w.b1).abs().max((h.b2 - w.b2).abs());
                worst_b = worst_b.max(db);
                assert!(db <= 1e-4, "barycentrics: device ({}, {}) core ({}, {}) for ray {r:?}", h.b1, h.b2, w.b1, w.b2);
            }
            (w, h) => {
                // One side only: allowed only where t_max cuts the hit within rounding.
                let t = w.map(|w| w.t).or(h.map(|h| h.t)).unwrap();
                assert!((t - r.t_max).abs() <= 1e-5 * r.t_max, "hit/miss disagree for ray {r:?}: core {w:?} device {h:?}");
                cut += 1;
            }
        }
    }
    eprintln!(
        "arpa-vk ray cast: {n} rays: {hits} hits agree, {misses} misses agree, {ties} edge ties, {cut} cut at t_max; sphere {sphere}, panel {panel}; worst relative t error {worst_t:.3e}, worst barycentric error {worst_b:.3e}; {:.2} s",
        start.elapsed().as_secs_f64()
    );
    assert!(ties * 200 <= n, "{ties} edge ties in {n} rays");
    assert!(hits > 12_500 && misses > 500 && sphere > 500 && panel > 100, "hits {hits}, misses {misses}, sphere {sphere}, panel {panel}");

    // Misuse is an error, not a panic.
    let e = pipeline.bind(&[&cast_set, &scene_set]).err().expect("wrong binding kinds");
    assert!(matches!(e, VkError::InvalidInput { .. }), "{e}");
    let e = pipeline.trace_and_wait(&ctx, &bindings, &[0; 4], [1, 1, 1]).unwrap_err();
    assert!(matches!(e, VkError::InvalidInput { .. }), "{e}");

    let log = ctx.validation_log();
    assert_clean(&log, "while building and tracing");
    drop((bindings, pipeline, accel, ray_buf, hit_buf, info, meshes, triangles, emitters));
    drop(ctx);
    assert_clean(&log, "while destroying");
}

#[test]
fn aabb_blas_and_top_levels_build_cleanly() {
    let Some(ctx) = context("ray-cast") else { return };
    // Boxes along x, one inactive (NaN), as the gather will build them.
    let mut boxes: Vec<[f32; 6]> = (0..100).map(|i| [i as f32, 0.0, 0.0, i as f32 + 0.5, 0.5, 0.5]).collect();
    boxes[7] = [f32::NAN; 6];
    let blas = ctx.build_aabb_blas("test boxes", &boxes).expect("AABB BLAS");
    assert_eq!((blas.primitive_count(), blas.level()), (100, vk::AccelerationStructureTypeKHR::BOTTOM_LEVEL));
    assert!(blas.size() > 0 && blas.device_address() != 0);
    let instances = [
        TlasInstance {
            blas: &blas,
            transform: IDENTITY_TRANSFORM,
            custom_index: 5,
            mask: 0x01,
            sbt_record_offset: 0,
            flags: vk::GeometryInstanceFlagsKHR::empty(),
        },
        TlasInstance {
            blas: &blas,
            transform: IDENTITY_TRANSFORM,
            custom_index: 6,
            mask: 0x02,
            sbt_record_offset: 1,
            flags: vk::GeometryInstanceFlagsKHR::empty(),
        },
    ];
    let tlas = ctx.build_tlas("test TLAS", &instances).expect("TLAS");
    assert_eq!((tlas.primitive_count(), tlas.level()), (2, vk::AccelerationStructureTypeKHR::TOP_LEVEL));
    let empty = ctx.build_tlas("test empty TLAS", &[]).expect("empty TLAS");
    assert_eq!(empty.primitive_count(), 0);
    // Errors, not panics.
    assert!(matches!(ctx.build_aabb_blas("none", &[]), Err(VkError::InvalidInput { .. })));
    let bad = [TlasInstance { blas: &tlas, ..instances[0] }];
    assert!(matches!(ctx.build_tlas("nested", &bad), Err(VkError::InvalidInput { .. })));
    let bad = [TlasInstance { custom_index: 1 << 24, ..instances[0] }];
    assert!(matches!(ctx.build_tlas("wide", &bad), Err(VkError::InvalidInput { .. })));
    let log = ctx.validation_log();
    drop((empty, tlas, blas));
    drop(ctx);
    assert_clean(&log, "building AABB and top-level structures");
}

/// A second closest-hit shader that marks its hits (`pad[0] = 1`), for hit-group selection.
static MARKED_HIT: arpa_core::gpu::shaders::WgslFile = arpa_core::gpu::shaders::WgslFile {
    name: "arpa-vk-tests/marked_hit.wgsl",
    source: "@closest_hit\n@incoming_payload(vk_cast_incoming)\nfn marked_closest_hit(\n    @builtin(instance_custom_data) mesh: u32,\n    @builtin(primitive_index) primitive: u32,\n    @builtin(ray_t_current_max) t: f32,\n) {\n    let hit = arpa_scene_hit(mesh, primitive, t, vec2<f32>(0.0));\n    vk_cast_incoming = VkCastHit(t, mesh, primitive, hit.triangle, 0.0, 0.0, 1u, 0u);\n}\n",
    deps: &[&arpa_vk::shaders::RAY_CAST],
};

#[test]
fn instance_sbt_offsets_select_hit_groups() {
    let Some(ctx) = context("ray-cast") else { return };
    let prepared = PreparedScene::new(scene()).expect("valid test scene");
    // Odd meshes use hit group 1 (the marking one), even meshes hit group 0.
    let accel = SceneAccel::build_with_sbt_offsets(&ctx, &prepared, |mesh| mesh as u32 % 2).expect("acceleration structures");
    let (tlas, orders) = (accel.tlas(), accel.triangle_orders());
    let tables = SceneTables::new(&prepared, orders).expect("tables");

    let spirv = compile_wgsl("marked", &arpa_core::gpu::shaders::compose(&[&MARKED_HIT])).expect("marked_hit.wgsl");
    let module = ctx.create_shader_module(&spirv).expect("shader module");
    let entry = |entry| ShaderEntry { module: &module, entry };
    use BindingKind::{AccelerationStructure as As, StorageBuffer as Sb, UniformBuffer as Ub};
    let pipeline = RtPipeline::new(
        &ctx,
        &RtPipelineDesc {
            label: "two hit groups",
            raygen: entry("vk_cast_raygen"),
            miss: &[entry("vk_cast_miss")],
            hit_groups: &[
                HitGroup::Triangles { closest_hit: Some(entry("vk_cast_closest_hit")), any_hit: None },
                HitGroup::Triangles { closest_hit: Some(entry("marked_closest_hit")), any_hit: None },
            ],
            sets: &[&[As, Ub, Sb, Sb, Sb], &[Sb, Sb]],
            push_constant_size: 0,
        },
    )
    .expect("pipeline");
    let layout = *pipeline.sbt_layout();
    eprintln!("arpa-vk SBT layout with two hit groups: {layout:?}");
    assert_eq!(layout.hit.size, 2 * layout.hit.stride);

    let storage_usage = vk::BufferUsageFlags::STORAGE_BUFFER;
    let info = storage(&ctx, "scene info", bytemuck::bytes_of(&tables.info), 0, vk::BufferUsageFlags::UNIFORM_BUFFER);
    let mesh_buf = storage(&ctx, "scene meshes", bytemuck::cast_slice(&tables.meshes), 64, storage_usage);
    let triangles = storage(&ctx, "scene triangles", bytemuck::cast_slice(&tables.triangles), 112, storage_usage);
    let emitters = storage(&ctx, "scene emitters", bytemuck::cast_slice(&tables.emitters), 128, storage_usage);
    let n = 2000;
    let rs = rays(0x5eed_0002, n);
    let ray_buf = storage(&ctx, "rays", bytemuck::cast_slice(&rs), 0, storage_usage);
    let hit_buf = ctx.create_buffer("hits", (n * 32) as u64, storage_usage, MemoryLocation::GpuToCpu).expect("hits");
    let scene_set = [
        Resource::AccelerationStructure(tlas),
        Resource::UniformBuffer(&info),
        Resource::StorageBuffer(&mesh_buf),
        Resource::StorageBuffer(&triangles),
        Resource::StorageBuffer(&emitters),
    ];
    let cast_set = [Resource::StorageBuffer(&ray_buf), Resource::StorageBuffer(&hit_buf)];
    let bindings = pipeline.bind(&[&scene_set, &cast_set]).expect("bind");
    pipeline.trace_and_wait(&ctx, &bindings, &[], [n as u32, 1, 1]).expect("trace");
    let bytes = hit_buf.read(0, (n * 32) as u64).expect("read hits");
    let got: Vec<CastHit> = bytes.chunks_exact(32).map(bytemuck::pod_read_unaligned).collect();
    let mut per_group = [0u32; 2];
    for h in got.iter().filter(|h| h.mesh != u32::MAX) {
        assert_eq!(h.pad[0], h.mesh % 2, "mesh {} ran hit group {}", h.mesh, h.pad[0]);
        per_group[h.pad[0] as usize] += 1;
    }
    eprintln!("arpa-vk hit groups: {} hits through group 0, {} through group 1", per_group[0], per_group[1]);
    assert!(per_group.iter().all(|&c| c > 100), "{per_group:?}");
    let log = ctx.validation_log();
    drop((bindings, pipeline, module, accel, ray_buf, hit_buf, info, mesh_buf, triangles, emitters));
    drop(ctx);
    assert_clean(&log, "tracing with two hit groups");
}

/// A scene whose instancing places one group three times: the copies share the group's
/// bottom levels (one per group mesh) under three instances each, the orders of a copy are
/// its prototype mesh's, and the build is clean under the validation layer.
#[test]
fn instanced_copies_share_bottom_levels() {
    use arpa_core::glam::{DAffine3, DQuat};
    use arpa_core::render::scene::Instancing;
    let Some(ctx) = context("instancing") else { return };
    let mut scene = scene();
    let group = [icosphere("ball", Vec3::ZERO, 0.2, 1, true, 0), parallelogram("tile", Vec3::ZERO, Vec3::X * 0.3, Vec3::Z * 0.3, 0)];
    let mut inst = Instancing::default();
    let p = inst.add_prototype("group", &group);
    let first = scene.meshes.len();
    for k in 0..3 {
        inst.place(&mut scene.meshes, &group, p, DAffine3::from_scale_rotation_translation(DVec3::splat(1.0 + 0.2 * k as f64), DQuat::from_rotation_y(k as f64), DVec3::new(k as f64 * 0.4 - 0.4, 0.5, 0.0)));
    }
    scene.instancing = Some(inst);
    let prepared = PreparedScene::new(scene.clone()).expect("valid instanced scene");
    let accel = SceneAccel::build(&ctx, &prepared).expect("acceleration structures");
    let with_triangles = scene.meshes.iter().filter(|m| !m.indices.is_empty()).count();
    assert_eq!(accel.instance_count(), with_triangles);
    assert_eq!(accel.blas_count(), with_triangles - 6 + 2, "six copies, two shared bottom levels");
    assert!(std::ptr::eq(accel.blas(first).unwrap(), accel.blas(first + 2).unwrap()));
    assert_eq!(accel.triangle_orders()[first], accel.triangle_orders()[first + 4]);
    let log = ctx.validation_log();
    drop(accel);
    drop(ctx);
    assert_clean(&log, "building instanced structures");
}
