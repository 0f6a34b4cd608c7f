// Footprint gather on ray queries: for each query point, a point query (a ray of
// negligible length started at the point) against the footprint boxes in the TLAS finds the
// candidate footprints; each is tested exactly in filter space and weighted by the kernel
// (footprint.wgsl's arpa_footprint_irradiance). Needs kernel.wgsl and footprint.wgsl.
//
// Bindings: footprints sorted by map; one AABB instance per non-empty map whose custom
// data is the index of the map's first footprint (primitive i of that instance is
// footprint custom + i) and whose mask is 1 << map. The module must start with
// `enable wgpu_ray_query;` (placed by the host before the twin files).

struct GatherQuery {
    position: vec3<f32>,  // metres
    kernel: u32,          // ARPA_KERNEL_* id
    normal: vec3<f32>,    // unit, towards the viewer
    pad: u32,
}

// Irradiance per map (W/m^2, RGB) and the number of contributing footprints.
struct GatherResult {
    caustic: vec3<f32>,
    caustic_count: u32,
    global: vec3<f32>,
    global_count: u32,
}

@group(0) @binding(0) var<storage, read> footprints: array<ArpaPackedFootprint>;
@group(0) @binding(1) var<storage, read> queries: array<GatherQuery>;
@group(0) @binding(2) var<storage, read_write> results: array<GatherResult>;
@group(0) @binding(3) var boxes: acceleration_structure;

// Length of the point query's ray (metres): any box that contains the query point is a
// candidate whatever the length; the exact test decides.
const GATHER_RAY_LENGTH: f32 = 1e-6;

@compute @workgroup_size(64)
fn gather(@builtin(global_invocation_id) gid: vec3<u32>) {
    let i = gid.x;
    if i >= arrayLength(&queries) {
        return;
    }
    let q = queries[i];
    var sum = array<vec3<f32>, 2>(vec3<f32>(0.0), vec3<f32>(0.0));
    var count = array<u32, 2>(0u, 0u);
    var rq: ray_query;
    rayQueryInitialize(&rq, boxes, RayDesc(RAY_FLAG_NONE, 0x3u, 0.0, GATHER_RAY_LENGTH, q.position, vec3<f32>(0.0, 0.0, 1.0)));
    while rayQueryProceed(&rq) {
        let c = rayQueryGetCandidateIntersection(&rq);
        if c.kind != RAY_QUERY_INTERSECTION_AABB {
            continue;
        }
        let fp = footprints[c.instance_custom_data + c.primitive_index];
        let e = arpa_footprint_irradiance(fp, q.position, q.normal, q.kernel);
        if any(e != vec3<f32>(0.0)) {
            let m = min(fp.map, 1u);
            sum[m] += e;
            count[m] += 1u;
        }
    }
    results[i] = GatherResult(sum[0], count[0], sum[1], count[1]);
}
