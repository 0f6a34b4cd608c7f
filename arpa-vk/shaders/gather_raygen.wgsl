// arpa-vk's box traversal and entry point for arpa-core's path/gather.wgsl on a ray-tracing
// pipeline: binding 7 of group 0 is the top level over the record boxes (AABB instances as
// gather.wgsl describes them), and arpa_gather_at is the function
// gather.wgsl names: a point query, one ray of negligible length started at the query
// point, through the AABB hit group of gather.rint (the exact test) and gather.rahit (the
// contribution, added to this payload; then ignoreIntersection, so every box containing
// the point is visited). Those two stages are GLSL (naga has no intersection stage and no
// ignore-intersection); they read the records and parameters from this module's bindings 0,
// 1 and 4, so arpa_gather_at's kernel, radii and scales arguments are already in
// image_params (the any-hit shader evaluates image_params.scales scales).
//
// The payload's layout is gather_payload.glsl's ArpaGatherPayload, member for member.
enable wgpu_ray_tracing_pipeline;

@group(0) @binding(7) var arpa_gather_boxes: acceleration_structure;

// Per-map sums and contribution counts of one point query at the stored scale, the query's
// unit normal (the any-hit shader's side test), the candidates per map, and the sums of both
// maps at scales 1 to 4 (xyz; w = 0).
struct VkGatherPayload {
    caustic: vec3<f32>,
    caustic_count: u32,
    global_sum: vec3<f32>,
    global_count: u32,
    normal: vec3<f32>,
    pad: u32,
    candidates: vec2<u32>,
    pad1: vec2<u32>,
    scale1: vec4<f32>,
    scale2: vec4<f32>,
    scale3: vec4<f32>,
    scale4: vec4<f32>,
}

var<ray_payload> vk_gather_payload: VkGatherPayload;
var<incoming_ray_payload> vk_gather_incoming: VkGatherPayload;

// Length of the point query's ray (metres): any box that contains the query point is a
// candidate whatever the length; the exact test decides (as arpa-wgpu's).
const ARPA_GATHER_RAY_LENGTH: f32 = 1e-6;

fn arpa_gather_at(q: vec3<f32>, n: vec3<f32>, kernel: u32, radii: vec2<f32>, scales: u32) -> ArpaGatherResult {
    let zero = vec4<f32>(0.0);
    vk_gather_payload = VkGatherPayload(vec3<f32>(0.0), 0u, vec3<f32>(0.0), 0u, n, 0u, vec2<u32>(0u), vec2<u32>(0u), zero, zero, zero, zero);
    // Not opaque (an opaque ray skips any-hit); every instance mask.
    traceRay(arpa_gather_boxes, RayDesc(RAY_FLAG_NONE, 0xffu, 0.0, ARPA_GATHER_RAY_LENGTH, q, vec3<f32>(0.0, 0.0, 1.0)), &vk_gather_payload);
    let p = vk_gather_payload;
    let scaled = array<vec4<f32>, 4>(p.scale1, p.scale2, p.scale3, p.scale4);
    return ArpaGatherResult(p.caustic, p.caustic_count, p.global_sum, p.global_count, p.candidates, vec2<u32>(0u), scaled);
}

// One invocation per query record, launched (x, y, 1) and linearised x fastest.
@ray_generation
fn vk_gather_raygen(@builtin(ray_invocation_id) id: vec3<u32>, @builtin(num_ray_invocations) size: vec3<u32>) {
    let i = id.x + size.x * id.y;
    if i >= image_params.pixels {
        return;
    }
    arpa_gather_pixel(i);
}

// A point query that meets no box keeps the zero sums.
@miss
@incoming_payload(vk_gather_incoming)
fn vk_gather_miss() {
}
