// arpa-wgpu's ray casting for the scene of arpa-core's path/scene.wgsl, on ray queries
// (wgpu EXPERIMENTAL_RAY_QUERY): binding 0 of group 0 is the scene's top-level structure
// (one instance per mesh with triangles, custom index = mesh index, over a bottom level
// holding the mesh's triangles in SceneTables::triangle_orders order), and
// arpa_scene_intersect / arpa_scene_occluded are the functions scene.wgsl names.
enable wgpu_ray_query;

@group(0) @binding(0) var arpa_scene_tlas: acceleration_structure;

// Closest hit along origin + t dir, t_min < t <= t_max (RayCaster::intersect); `triangle` is
// the mesh's triangle index as the core numbers it. The barycentric weights are recomputed
// from the mesh's world-space triangle and the world ray (Moller-Trumbore in f32, as the vk
// backend's closest-hit shader does): the hardware's are taken in an instance's object
// space, so a copy placed by an instance transform would otherwise shade with other bits
// than its flattened twin. t stays the traversal's (nothing shades with it; the recast
// past a left triangle steps from it).
fn arpa_scene_intersect(origin: vec3<f32>, dir: vec3<f32>, t_min: f32, t_max: f32) -> ArpaSceneHit {
    var rq: ray_query;
    rayQueryInitialize(&rq, arpa_scene_tlas, RayDesc(RAY_FLAG_FORCE_OPAQUE, 0xffu, t_min, t_max, origin, dir));
    while rayQueryProceed(&rq) {}
    let h = rayQueryGetCommittedIntersection(&rq);
    if h.kind == RAY_QUERY_INTERSECTION_TRIANGLE && h.t > 0.0 {
        var hit = arpa_scene_hit(h.instance_custom_data, h.primitive_index, h.t, h.barycentrics);
        let tri = arpa_scene_triangles[arpa_scene_meshes[hit.mesh].first_triangle + hit.triangle];
        let e1 = tri.p1 - tri.p0;
        let e2 = tri.p2 - tri.p0;
        let pv = cross(dir, e2);
        let det = dot(e1, pv);
        if det != 0.0 {
            let inv = 1.0 / det;
            let tv = origin - tri.p0;
            let b1 = clamp(dot(tv, pv) * inv, 0.0, 1.0);
            hit.b1 = b1;
            hit.b2 = clamp(dot(dir, cross(tv, e1)) * inv, 0.0, 1.0 - b1);
        }
        return hit;
    }
    return arpa_scene_miss();
}

// Whether anything lies along origin + t dir, t_min < t <= t_max (RayCaster::occluded).
fn arpa_scene_occluded(origin: vec3<f32>, dir: vec3<f32>, t_min: f32, t_max: f32) -> bool {
    var rq: ray_query;
    rayQueryInitialize(&rq, arpa_scene_tlas,
        RayDesc(RAY_FLAG_FORCE_OPAQUE | RAY_FLAG_TERMINATE_ON_FIRST_HIT, 0xffu, t_min, t_max, origin, dir));
    while rayQueryProceed(&rq) {}
    let h = rayQueryGetCommittedIntersection(&rq);
    return h.kind == RAY_QUERY_INTERSECTION_TRIANGLE && h.t > 0.0;
}
