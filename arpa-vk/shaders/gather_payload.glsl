// The gather ray's payload (location 0): the irradiance sums and contribution counts per map
// (arpa_core::gpu::layout::GatherResult's first 32 bytes), the query's unit normal, which
// the any-hit shader's side test needs (the query point is the ray's origin), and the
// candidate records per map (every box containing the point).
struct ArpaGatherPayload {
    vec3 caustic;
    uint caustic_count;
    vec3 global_sum;
    uint global_count;
    vec3 normal;
    uint pad;
    uvec2 candidates;
    uvec2 pad1;
};
