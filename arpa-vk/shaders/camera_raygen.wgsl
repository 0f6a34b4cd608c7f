// arpa-vk's entry point of arpa-core's path/camera_pass.wgsl: one ray-generation invocation
// per pixel, launched (width, height, 1), writes the pixel's query record; its rays go
// through scene_trace.wgsl's miss and closest-hit shaders.

@ray_generation
fn vk_camera_raygen(@builtin(ray_invocation_id) id: vec3<u32>, @builtin(num_ray_invocations) size: vec3<u32>) {
    let pixel = id.x + size.x * id.y;
    if pixel >= arpa_camera.pixel_count {
        return;
    }
    arpa_camera_queries[pixel] = arpa_camera_trace(pixel);
}
