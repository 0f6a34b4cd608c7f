// arpa-vk's ray casting for the scene of arpa-core's path/scene.wgsl on a ray-tracing
// pipeline: binding 0 of group 0 is the scene's top-level structure (one instance per mesh
// with triangles, custom index = mesh index, SBT record offset 0, over a bottom level of the
// mesh's triangles in SceneTables::triangle_orders order), and arpa_scene_intersect /
// arpa_scene_occluded are the functions scene.wgsl names, each one traceRay from the
// calling ray-generation shader. A pipeline that traces the scene takes this file's miss
// shader (vk_cast_miss) and closest-hit shader (vk_cast_closest_hit, a triangle hit group).
enable wgpu_ray_tracing_pipeline;
// primitive_index: naga declares the SPIR-V Geometry capability for it, even in closest-hit
// (the device enables geometryShader, see arpa_vk::device).
enable primitive_index;

@group(0) @binding(0) var arpa_scene_tlas: acceleration_structure;

// The payload (mesh = VK_CAST_MISS: miss). primitive: the BLAS primitive; triangle: the
// mesh's triangle as the core numbers it; b1, b2: barycentric weights of vertices 1 and 2 of
// that triangle; t: metres along the unit direction.
struct VkCastHit {
    t: f32,
    mesh: u32,
    primitive: u32,
    triangle: u32,
    b1: f32,
    b2: f32,
    pad0: u32,
    pad1: u32,
}

const VK_CAST_MISS: u32 = 0xffffffffu;

var<ray_payload> vk_cast_payload: VkCastHit;
var<incoming_ray_payload> vk_cast_incoming: VkCastHit;

fn vk_cast_miss_record() -> VkCastHit {
    return VkCastHit(0.0, VK_CAST_MISS, 0u, 0u, 0.0, 0.0, 0u, 0u);
}

// Closest hit along origin + t dir, t_min < t <= t_max (RayCaster::intersect); `triangle` is
// the mesh's triangle index as the core numbers it.
fn arpa_scene_intersect(origin: vec3<f32>, dir: vec3<f32>, t_min: f32, t_max: f32) -> ArpaSceneHit {
    vk_cast_payload = vk_cast_miss_record();
    traceRay(arpa_scene_tlas, RayDesc(RAY_FLAG_FORCE_OPAQUE, 0xffu, t_min, t_max, origin, dir), &vk_cast_payload);
    let h = vk_cast_payload;
    if h.mesh != VK_CAST_MISS && h.t > 0.0 {
        return arpa_scene_hit(h.mesh, h.primitive, h.t, vec2<f32>(h.b1, h.b2));
    }
    return arpa_scene_miss();
}

// Whether anything lies along origin + t dir, t_min < t <= t_max (RayCaster::occluded): the
// payload starts as a hit and only the miss shader clears it (no closest-hit runs).
fn arpa_scene_occluded(origin: vec3<f32>, dir: vec3<f32>, t_min: f32, t_max: f32) -> bool {
    vk_cast_payload = VkCastHit(0.0, 0u, 0u, 0u, 0.0, 0.0, 0u, 0u);
    traceRay(arpa_scene_tlas,
        RayDesc(RAY_FLAG_FORCE_OPAQUE | RAY_FLAG_TERMINATE_ON_FIRST_HIT | RAY_FLAG_SKIP_CLOSEST_HIT_SHADER, 0xffu, t_min, t_max, origin, dir),
        &vk_cast_payload);
    return vk_cast_payload.mesh != VK_CAST_MISS;
}

@miss
@incoming_payload(vk_cast_incoming)
fn vk_cast_miss() {
    vk_cast_incoming = vk_cast_miss_record();
}

// naga has no hit attributes (SPIR-V HitAttributeKHR), so the triangle's barycentrics are
// recomputed here from the scene table's vertices (Moller-Trumbore in f32) at the t the
// traversal found.
@closest_hit
@incoming_payload(vk_cast_incoming)
fn vk_cast_closest_hit(
    @builtin(instance_custom_data) mesh: u32,
    @builtin(primitive_index) primitive: u32,
    @builtin(ray_t_current_max) t: f32,
    @builtin(world_ray_origin) origin: vec3<f32>,
    @builtin(world_ray_direction) dir: vec3<f32>,
) {
    let hit = arpa_scene_hit(mesh, primitive, t, vec2<f32>(0.0));
    let tri = arpa_scene_triangles[arpa_scene_meshes[mesh].first_triangle + hit.triangle];
    let e1 = tri.p1 - tri.p0;
    let e2 = tri.p2 - tri.p0;
    let pv = cross(dir, e2);
    let inv = 1.0 / dot(e1, pv);
    let tv = origin - tri.p0;
    let b1 = dot(tv, pv) * inv;
    let b2 = dot(dir, cross(tv, e1)) * inv;
    vk_cast_incoming = VkCastHit(t, mesh, primitive, hit.triangle, b1, b2, 0u, 0u);
}
