//! Ray queries work end to end on the adapter the backend picks (lavapipe in CI): a
//! triangle BLAS (the photon pass's geometry) and an AABB BLAS (the gather's footprint
//! boxes) in one TLAS with instance masks, traced from a compute shader. Hits are checked
//! against geometry computed by hand: hit distances, primitive indices, barycentrics,
//! instance data, and the exact set of boxes that contain a query point (the gather's
//! point query: a ray of negligible length started at the point).


use arpa_wgpu::GpuContext;
use crate::common::*;
use wgpu::util::DeviceExt;

/// The test scene: a unit quad at z = 0 (two triangles) lifted to z = 0.5 by its
/// instance transform; boxes `[x0, x1] × [y0, y1] × [−0.25, 0.25]`.
const QUAD: [[f32; 3]; 4] = [[-1.0, -1.0, 0.0], [1.0, -1.0, 0.0], [1.0, 1.0, 0.0], [-1.0, 1.0, 0.0]];
const QUAD_INDICES: [u32; 6] = [0, 1, 2, 0, 2, 3];
const BOXES: [[f32; 4]; 4] = [[-1.0, 0.0, -1.0, 0.0], [-0.5, 0.5, -0.5, 0.5], [0.0, 1.0, 0.0, 1.0], [-0.25, 1.0, -0.8, -0.1]];
const LIFT: f32 = 0.5;

const SHADER: &str = r#"
enable wgpu_ray_query;
@group(0) @binding(0) var<storage, read> input: array<vec4<f32>>;
@group(0) @binding(1) var<storage, read_write> output: array<vec4<f32>>;
@group(0) @binding(2) var scene: acceleration_structure;

@compute @workgroup_size(64)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let i = gid.x;
    if i >= arrayLength(&input) { return; }
    let xy = input[i].xy;
    // Triangles: straight down from z = 2, mask 0x01.
    var rq: ray_query;
    rayQueryInitialize(&rq, scene, RayDesc(RAY_FLAG_FORCE_OPAQUE, 0x01u, 0.0, 100.0, vec3<f32>(xy, 2.0), vec3<f32>(0.0, 0.0, -1.0)));
    rayQueryProceed(&rq);
    let hit = rayQueryGetCommittedIntersection(&rq);
    var tri = vec4<f32>(-1.0);
    if hit.kind == RAY_QUERY_INTERSECTION_TRIANGLE {
        tri = vec4<f32>(hit.t, f32(hit.primitive_index), hit.barycentrics);
    }
    output[2u * i] = tri;
    // Boxes: a point query at (x, y, 0), mask 0x02; every candidate box is recorded.
    var pq: ray_query;
    rayQueryInitialize(&pq, scene, RayDesc(RAY_FLAG_NONE, 0x02u, 0.0, 1e-4, vec3<f32>(xy, 0.0), vec3<f32>(0.0, 0.0, 1.0)));
    var boxes = 0u;
    var custom = 0u;
    while rayQueryProceed(&pq) {
        let c = rayQueryGetCandidateIntersection(&pq);
        if c.kind == RAY_QUERY_INTERSECTION_AABB {
            boxes |= 1u << c.primitive_index;
            custom = c.instance_custom_data;
        }
    }
    output[2u * i + 1u] = vec4<f32>(f32(boxes), f32(custom), f32(hit.instance_custom_data), 0.0);
}
"#;

fn trace(ctx: &GpuContext, points: &[[f32; 2]]) -> Vec<[f32; 8]> {
    let device = &ctx.device;
    let usage = wgpu::BufferUsages::BLAS_INPUT;
    let vertices = device.create_buffer_init(&wgpu::util::BufferInitDescriptor { label: None, contents: bytemuck::cast_slice(&QUAD), usage });
    let indices = device.create_buffer_init(&wgpu::util::BufferInitDescriptor { label: None, contents: bytemuck::cast_slice(&QUAD_INDICES), usage });
    let aabbs: Vec<f32> = BOXES.iter().flat_map(|b| [b[0], b[2], -0.25, b[1], b[3], 0.25]).collect();
    let aabb_buf = device.create_buffer_init(&wgpu::util::BufferInitDescriptor { label: None, contents: bytemuck::cast_slice(&aabbs), usage });

    let tri_size = wgpu::BlasTriangleGeometrySizeDescriptor {
        vertex_format: wgpu::VertexFormat::Float32x3,
        vertex_count: QUAD.len() as u32,
        index_format: Some(wgpu::IndexFormat::Uint32),
        index_count: Some(QUAD_INDICES.len() as u32),
        flags: wgpu::AccelerationStructureGeometryFlags::OPAQUE,
    };
    let aabb_size = wgpu::BlasAABBGeometrySizeDescriptor { primitive_count: BOXES.len() as u32, flags: wgpu::AccelerationStructureGeometryFlags::empty() };
    let blas_desc = wgpu::CreateBlasDescriptor {
        label: None,
        flags: wgpu::AccelerationStructureFlags::PREFER_FAST_TRACE,
        update_mode: wgpu::AccelerationStructureUpdateMode::Build,
    };
    let tri_blas = device.create_blas(&blas_desc, wgpu::BlasGeometrySizeDescriptors::Triangles { descriptors: vec![tri_size.clone()] });
    let aabb_blas = device.create_blas(&blas_desc, wgpu::BlasGeometrySizeDescriptors::AABBs { descriptors: vec![aabb_size.clone()] });
    let mut tlas = device.create_tlas(&wgpu::CreateTlasDescriptor {
        label: None,
        max_instances: 2,
        flags: wgpu::AccelerationStructureFlags::PREFER_FAST_TRACE,
        update_mode: wgpu::AccelerationStructureUpdateMode::Build,
    });
    let lift = [1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0, LIFT];
    let identity = [1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0];
    tlas[0] = Some(wgpu::TlasInstance::new(&tri_blas, lift, 7, 0x01));
    tlas[1] = Some(wgpu::TlasInstance::new(&aabb_blas, identity, 9, 0x02));

    let input: Vec<[f32; 4]> = points.iter().map(|p| [p[0], p[1], 0.0, 0.0]).collect();
    let input_buf = device.create_buffer_init(&wgpu::util::BufferInitDescriptor { label: None, contents: bytemuck::cast_slice(&input), usage: wgpu::BufferUsages::STORAGE });
    let out_bytes = (points.len() * 32) as u64;
    let output = device.create_buffer(&wgpu::BufferDescriptor { label: None, size: out_bytes, usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC, mapped_at_creation: false });
    let staging = device.create_buffer(&wgpu::BufferDescriptor { label: None, size: out_bytes, usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST, mapped_at_creation: false });

    let scope = device.push_error_scope(wgpu::ErrorFilter::Validation);
    let module = device.create_shader_module(wgpu::ShaderModuleDescriptor { label: Some("ray query smoke"), source: wgpu::ShaderSource::Wgsl(SHADER.into()) });
    let pipeline = device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
        label: None,
        layout: None,
        module: &module,
        entry_point: Some("main"),
        compilation_options: Default::default(),
        cache: None,
    });
    let bind_group = device.create_bind_group(&wgpu::BindGroupDescriptor {
        label: None,
        layout: &pipeline.get_bind_group_layout(0),
        entries: &[
            wgpu::BindGroupEntry { binding: 0, resource: input_buf.as_entire_binding() },
            wgpu::BindGroupEntry { binding: 1, resource: output.as_entire_binding() },
            wgpu::BindGroupEntry { binding: 2, resource: tlas.as_binding() },
        ],
    });
    let mut encoder = device.create_command_encoder(&Default::default());
    encoder.build_acceleration_structures(
        [
            &wgpu::BlasBuildEntry {
                blas: &tri_blas,
                geometry: wgpu::BlasGeometries::TriangleGeometries(vec![wgpu::BlasTriangleGeometry {
                    size: &tri_size,
                    vertex_buffer: &vertices,
                    first_vertex: 0,
                    vertex_stride: 12,
                    index_buffer: Some(&indices),
                    first_index: Some(0),
                    transform_buffer: None,
                    transform_buffer_offset: None,
                }]),
            },
            &wgpu::BlasBuildEntry {
                blas: &aabb_blas,
                geometry: wgpu::BlasGeometries::AabbGeometries(vec![wgpu::BlasAabbGeometry {
                    size: &aabb_size,
                    stride: wgpu::AABB_GEOMETRY_MIN_STRIDE,
                    aabb_buffer: &aabb_buf,
                    primitive_offset: 0,
                }]),
            },
        ],
        [&tlas],
    );
    {
        let mut pass = encoder.begin_compute_pass(&Default::default());
        pass.set_pipeline(&pipeline);
        pass.set_bind_group(0, &bind_group, &[]);
        pass.dispatch_workgroups((points.len() as u32).div_ceil(64), 1, 1);
    }
    encoder.copy_buffer_to_buffer(&output, 0, &staging, 0, out_bytes);
    if let Some(e) = pollster::block_on(scope.pop()) {
        panic!("ray-query pipeline rejected by wgpu: {e}");
    }
    ctx.queue.submit([encoder.finish()]);
    staging.map_async(wgpu::MapMode::Read, .., |r| r.expect("map"));
    device.poll(wgpu::PollType::wait_indefinitely()).expect("poll");
    let view = staging.get_mapped_range(..).expect("mapped");
    bytemuck::cast_slice::<u8, [f32; 8]>(&view).to_vec()
}

#[test]
fn triangles_and_boxes_are_found() {
    let Some(ctx) = gpu() else { return };
    // A grid of points that avoids every edge by at least 0.01.
    let mut points = Vec::new();
    for i in 0..64 {
        for j in 0..64 {
            let p = [-1.49 + 2.98 * (i as f32 + 0.37) / 64.0, -1.49 + 2.98 * (j as f32 + 0.61) / 64.0];
            let near = |a: f32, e: f32| (a - e).abs() < 0.01;
            let edges = [-1.0, -0.8, -0.5, -0.25, -0.1, 0.0, 0.5, 1.0];
            if edges.iter().any(|&e| near(p[0], e) || near(p[1], e)) || near(p[0], p[1]) {
                continue;
            }
            points.push(p);
        }
    }
    let out = trace(ctx, &points);
    let (mut hits, mut box_hits) = (0, 0);
    for (p, o) in points.iter().zip(&out) {
        let (x, y) = (p[0], p[1]);
        let inside = x.abs() < 1.0 && y.abs() < 1.0;
        if inside {
            hits += 1;
            assert!((o[0] - (2.0 - LIFT)).abs() < 1e-5, "({x}, {y}): t = {}", o[0]);
            // Triangle 0 = (v0, v1, v2) below the diagonal y = x, triangle 1 = (v0, v2, v3) above.
            let prim = if y < x { 0 } else { 1 };
            assert_eq!(o[1], prim as f32, "({x}, {y}): primitive");
            let tri = [QUAD_INDICES[3 * prim], QUAD_INDICES[3 * prim + 1], QUAD_INDICES[3 * prim + 2]].map(|k| QUAD[k as usize]);
            let (u, v) = (o[2], o[3]);
            for c in 0..2 {
                let q = tri[0][c] * (1.0 - u - v) + tri[1][c] * u + tri[2][c] * v;
                assert!((q - p[c]).abs() < 1e-5, "({x}, {y}): barycentrics ({u}, {v}) give {q}");
            }
            assert_eq!(o[6], 7.0, "triangle instance data");
        } else {
            assert_eq!(o[0], -1.0, "({x}, {y}) should miss");
        }
        let expected: u32 = BOXES.iter().enumerate().filter(|(_, b)| x > b[0] && x < b[1] && y > b[2] && y < b[3]).map(|(k, _)| 1u32 << k).sum();
        assert_eq!(o[4] as u32, expected, "boxes containing ({x}, {y})");
        if expected != 0 {
            box_hits += 1;
            assert_eq!(o[5], 9.0, "box instance data");
        }
    }
    assert!(hits > 1000 && box_hits > 500, "{hits} triangle hits, {box_hits} points in boxes");
}
