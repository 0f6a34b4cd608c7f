// arpa-vk's ray-casting test kernel (tests/ray_cast.rs): one closest-hit ray per input ray
// through scene_trace.wgsl's miss and closest-hit shaders, the device side of
// arpa_core::render::ray_cast::RayCaster::intersect. Group 0: the scene (scene_trace.wgsl's top
// level at binding 0, the core's SceneTables at bindings 1 to 4). Group 1: the rays and one
// result (VkCastHit) per ray. Launch: (rays, 1, 1), or 2-D with x fastest.

// A ray: origin + t direction for t in [t_min, t_max] (metres; unit direction).
struct VkCastRay {
    origin: vec3<f32>,
    t_min: f32,
    direction: vec3<f32>,
    t_max: f32,
}

@group(1) @binding(0) var<storage, read> vk_cast_rays: array<VkCastRay>;
@group(1) @binding(1) var<storage, read_write> vk_cast_hits: array<VkCastHit>;

@ray_generation
fn vk_cast_raygen(@builtin(ray_invocation_id) id: vec3<u32>, @builtin(num_ray_invocations) size: vec3<u32>) {
    let i = id.x + size.x * id.y;
    if i >= arrayLength(&vk_cast_rays) {
        return;
    }
    let r = vk_cast_rays[i];
    vk_cast_payload = vk_cast_miss_record();
    traceRay(arpa_scene_tlas, RayDesc(RAY_FLAG_FORCE_OPAQUE, 0xffu, r.t_min, r.t_max, r.origin, r.direction), &vk_cast_payload);
    vk_cast_hits[i] = vk_cast_payload;
}
