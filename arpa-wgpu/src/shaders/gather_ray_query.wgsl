// arpa-wgpu's box traversal for arpa-core's path/gather.wgsl, on ray queries (wgpu
// EXPERIMENTAL_RAY_QUERY): binding 7 of group 0 is the top-level structure over the record
// boxes (crate::accel), and arpa_gather_at is the function gather.wgsl names: a point
// query, a ray of negligible length started at the query point, whose candidates are every
// box containing the point.
enable wgpu_ray_query;

@group(0) @binding(7) var arpa_gather_boxes: acceleration_structure;

// Length of the point query's ray (metres): any box that contains the query point is a
// candidate whatever the length; the exact test decides.
const ARPA_GATHER_RAY_LENGTH: f32 = 1e-6;

fn arpa_gather_at(q: vec3<f32>, n: vec3<f32>, kernel: u32, radii: vec2<f32>, scales: u32) -> ArpaGatherResult {
    var acc: ArpaGatherSum;
    var rq: ray_query;
    rayQueryInitialize(&rq, arpa_gather_boxes, RayDesc(RAY_FLAG_NONE, 0xffu, 0.0, ARPA_GATHER_RAY_LENGTH, q, vec3<f32>(0.0, 0.0, 1.0)));
    while rayQueryProceed(&rq) {
        let c = rayQueryGetCandidateIntersection(&rq);
        if c.kind == RAY_QUERY_INTERSECTION_AABB {
            arpa_gather_candidate(&acc, c.instance_custom_data, c.primitive_index, q, n, kernel, radii, scales);
        }
    }
    return arpa_gather_result(acc);
}

// The entry point: arpa_gather_pixel per query record, 64-wide workgroups over a 2D grid,
// linearised.
@compute @workgroup_size(64)
fn gather_image(@builtin(global_invocation_id) gid: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>) {
    let i = gid.x + gid.y * groups.x * 64u;
    if i >= image_params.pixels {
        return;
    }
    arpa_gather_pixel(i);
}
