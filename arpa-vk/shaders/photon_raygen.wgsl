// arpa-vk's entry point of arpa-core's path/photon_pass.wgsl: one ray-generation invocation
// per photon of the batch, launched (x, y, 1) and linearised x fastest; its rays go through
// scene_trace.wgsl's miss and closest-hit shaders. Ray generation has no workgroup memory,
// so each photon adds itself and its segments to the counters.

@ray_generation
fn vk_photon_raygen(@builtin(ray_invocation_id) id: vec3<u32>, @builtin(num_ray_invocations) size: vec3<u32>) {
    // Local index within the batch; the photon's global index (its random stream, emitter
    // and record keys) is first_photon + local, as arpa-wgpu's compute entry point.
    let local = id.x + size.x * id.y;
    if local >= photon_params.photon_count {
        return;
    }
    let segments = photon_trace(photon_params.first_photon + local);
    atomicAdd(&photon_counters.emitted, 1u);
    atomicAdd(&photon_counters.segments, segments);
}
