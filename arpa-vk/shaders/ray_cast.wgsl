// arpa-vk's closest-hit ray casting on a ray-tracing pipeline: the device side of
// arpa_core::ray_cast::RayCaster::intersect. Composed after the core's path/scene.wgsl
// (bind group 0: binding 0 is the scene's top-level structure, one instance per mesh with
// triangles, custom index = mesh index; bindings 1 to 4 the core's SceneTables).
// Group 1: the rays and one result per ray. Launch: (rays, 1, 1), or 2-D with x fastest.
enable wgpu_ray_tracing_pipeline;
// primitive_index: naga declares the SPIR-V Geometry capability for it, even in closest-hit
// (the device enables geometryShader, see arpa_vk::device).
enable primitive_index;

// A ray: origin + t direction for t in [t_min, t_max] (metres; unit direction).
struct VkCastRay {
    origin: vec3<f32>,
    t_min: f32,
    direction: vec3<f32>,
    t_max: f32,
}

// A result (mesh = 0xffffffff: miss). primitive: the BLAS primitive; triangle: the mesh's
// triangle as the core numbers it; b1, b2: barycentric weights of vertices 1 and 2 of that
// triangle.
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

@group(0) @binding(0) var arpa_scene_tlas: acceleration_structure;
@group(1) @binding(0) var<storage, read> vk_cast_rays: array<VkCastRay>;
@group(1) @binding(1) var<storage, read_write> vk_cast_hits: array<VkCastHit>;

var<ray_payload> vk_cast_payload: VkCastHit;
var<incoming_ray_payload> vk_cast_incoming: VkCastHit;

fn vk_cast_miss_record() -> VkCastHit {
    return VkCastHit(0.0, 0xffffffffu, 0u, 0u, 0.0, 0.0, 0u, 0u);
}

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
