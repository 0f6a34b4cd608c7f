// Test kernel: closest-hit ray casting on ray queries against the scene's top-level
// structure alone (one triangle BLAS per mesh, instance custom data = mesh index), the
// device side of arpa_core's RayCaster; reports the BLAS primitive (support.rs maps it back
// to the mesh's triangle).

struct CastRay {
    origin: vec3<f32>,   // metres
    t_max: f32,          // metres
    direction: vec3<f32>,// unit
    pad: u32,
}

// A hit (mesh = 0xffffffff: none). b1, b2: barycentric weights of vertices 1 and 2.
struct CastHit {
    t: f32,
    mesh: u32,
    triangle: u32,
    b1: f32,
    b2: f32,
    pad0: u32,
    pad1: u32,
    pad2: u32,
}

@group(0) @binding(0) var<storage, read> rays: array<CastRay>;
@group(0) @binding(1) var<storage, read_write> hits: array<CastHit>;
@group(0) @binding(2) var scene: acceleration_structure;

@compute @workgroup_size(64)
fn cast_rays(@builtin(global_invocation_id) gid: vec3<u32>) {
    let i = gid.x;
    if i >= arrayLength(&rays) {
        return;
    }
    let r = rays[i];
    var rq: ray_query;
    rayQueryInitialize(&rq, scene, RayDesc(RAY_FLAG_FORCE_OPAQUE, 0xffu, 0.0, r.t_max, r.origin, r.direction));
    while rayQueryProceed(&rq) {}
    let h = rayQueryGetCommittedIntersection(&rq);
    var out = CastHit(0.0, 0xffffffffu, 0u, 0.0, 0.0, 0u, 0u, 0u);
    if h.kind == RAY_QUERY_INTERSECTION_TRIANGLE && h.t > 0.0 {
        out = CastHit(h.t, h.instance_custom_data, h.primitive_index, h.barycentrics.x, h.barycentrics.y, 0u, 0u, 0u);
    }
    hits[i] = out;
}
