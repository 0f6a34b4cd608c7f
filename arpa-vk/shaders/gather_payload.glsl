// The gather ray's payload (location 0): the irradiance sums and contribution counts per map
// at the stored scale (arpa_core::gpu::layout::GatherResult's first 32 bytes), the query's
// unit normal, which the any-hit shader's side test needs (the query point is the ray's
// origin), the candidate records per map (every box containing the point), and the
// irradiance of both maps at scales 1 to 4 of the bandwidth ladder (scaleK.xyz, W/m^2 RGB;
// w stays 0; GatherResult::scaled). Separate members rather than an array, so that naga's
// layout of gather_raygen.wgsl's VkGatherPayload is trivially the same, member for member.
struct ArpaGatherPayload {
    vec3 caustic;
    uint caustic_count;
    vec3 global_sum;
    uint global_count;
    vec3 normal;
    uint pad;
    uvec2 candidates;
    uvec2 pad1;
    vec4 scale1;
    vec4 scale2;
    vec4 scale3;
    vec4 scale4;
};
