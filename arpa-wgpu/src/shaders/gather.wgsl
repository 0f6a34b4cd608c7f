// Footprint and photon gather on ray queries: for each query point, a point query (a ray
// of negligible length started at the point) against the record boxes in the TLAS finds the
// candidates; each footprint is tested exactly in filter space and weighted by the kernel
// (footprint.wgsl's arpa_footprint_irradiance), each progressive photon by the sphere test
// and constant kernel of arpa_core::progressive_photon::PackedPhoton::irradiance. Needs
// kernel.wgsl and footprint.wgsl.
//
// Bindings: footprints and photons, each sorted by map; one AABB instance per non-empty
// (kind, map) whose custom data is kind << 23 | index of its first record (kind 0
// footprint, 1 photon; primitive i of that instance is record (custom & 0x7fffff) + i) and
// whose mask is 1 << map. The module must start with `enable wgpu_ray_query;` (placed by
// the host before the twin files).
//
// Entry points: `gather` (query points in, irradiance per map out: the stage on its own)
// and `gather_image` (the tracer's camera-pass query records in, the iteration's radiance
// per pixel out, as arpa-cpu's gather_one: radiance + weight * (E_caustic + E_global),
// non-finite components to 0; with photon batches E is summed over the batches'
// maps in batch_irradiance and the last batch writes the radiance).

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

// arpa_core::progressive_photon::PackedPhoton (48 bytes).
struct GatherPhoton {
    position: vec3<f32>,  // metres
    map: u32,
    normal: vec3<f32>,    // unit, towards the arrival side
    pad0: u32,
    flux: vec3<f32>,      // W, RGB
    pad1: u32,
}

// arpa_core::tracer::QueryRecord (64 bytes).
struct GatherQueryRecord {
    position: vec3<f32>,  // metres
    pixel: u32,
    normal: vec3<f32>,    // unit, towards the viewer
    valid: u32,
    weight: vec3<f32>,    // 1/sr
    pad0: u32,
    radiance: vec3<f32>,  // W/(m^2 sr)
    pad1: u32,
}

struct GatherImageParams {
    radii: vec2<f32>,     // progressive radius per map (metres)
    kernel: u32,          // ARPA_KERNEL_* id of the footprints
    pixels: u32,          // query records (one per pixel)
    batch: u32,           // GATHER_BATCH_FIRST | GATHER_BATCH_LAST (both: the whole iteration)
    pad0: u32,
    pad1: u32,
    pad2: u32,
}

// Photon batches (arpa-wgpu gather.rs GatherBatch): the first batch of an iteration starts
// the per-pixel irradiance sum and counts the valid records; later ones add to the sum; the
// last writes the image radiance + weight * (sum over the batches).
const GATHER_BATCH_FIRST: u32 = 1u;
const GATHER_BATCH_LAST: u32 = 2u;

@group(0) @binding(0) var<storage, read> footprints: array<ArpaPackedFootprint>;
@group(0) @binding(1) var<storage, read> queries: array<GatherQuery>;
@group(0) @binding(2) var<storage, read_write> results: array<GatherResult>;
@group(0) @binding(3) var boxes: acceleration_structure;
@group(0) @binding(4) var<storage, read> photons: array<GatherPhoton>;
@group(0) @binding(5) var<storage, read> records: array<GatherQueryRecord>;
@group(0) @binding(6) var<storage, read_write> image: array<vec4<f32>>;
@group(0) @binding(7) var<storage, read> image_params: GatherImageParams;
// [contributions low word, high word, valid query records, 0]
@group(0) @binding(8) var<storage, read_write> gathered_total: array<atomic<u32>, 4>;
// Per pixel: irradiance summed over the batches gathered so far (W/m^2, RGB; caustic +
// global), written by every batch but the last.
@group(0) @binding(9) var<storage, read_write> batch_irradiance: array<vec4<f32>>;

const GATHER_PHOTON_BIT: u32 = 0x800000u;
const GATHER_INDEX_MASK: u32 = 0x7fffffu;

// PackedPhoton::irradiance: flux / (pi r^2) inside the sphere |q - x|^2 < r^2 and on the lit
// side, else 0 (also 0 when the density or the result is not finite).
fn gather_photon_irradiance(ph: GatherPhoton, q: vec3<f32>, query_normal: vec3<f32>, radius: f32) -> vec3<f32> {
    let density = ARPA_FRAC_1_PI / (radius * radius);
    let d = q - ph.position;
    if arpa_is_finite(density) && dot(d, d) < radius * radius && dot(ph.normal, query_normal) > 0.0 {
        let e = ph.flux * density;
        if arpa_is_finite3(e) {
            return e;
        }
    }
    return vec3<f32>(0.0);
}

// Length of the point query's ray (metres): any box that contains the query point is a
// candidate whatever the length; the exact test decides.
const GATHER_RAY_LENGTH: f32 = 1e-6;

// Everything at point q with normal n: irradiance per map and contribution counts.
// `radii` is only read when photon instances exist.
fn gather_at(q: vec3<f32>, n: vec3<f32>, kernel: u32, radii: vec2<f32>) -> GatherResult {
    var sum = array<vec3<f32>, 2>(vec3<f32>(0.0), vec3<f32>(0.0));
    var count = array<u32, 2>(0u, 0u);
    var rq: ray_query;
    rayQueryInitialize(&rq, boxes, RayDesc(RAY_FLAG_NONE, 0xffu, 0.0, GATHER_RAY_LENGTH, q, vec3<f32>(0.0, 0.0, 1.0)));
    while rayQueryProceed(&rq) {
        let c = rayQueryGetCandidateIntersection(&rq);
        if c.kind != RAY_QUERY_INTERSECTION_AABB {
            continue;
        }
        let index = (c.instance_custom_data & GATHER_INDEX_MASK) + c.primitive_index;
        var e: vec3<f32>;
        var m: u32;
        if (c.instance_custom_data & GATHER_PHOTON_BIT) == 0u {
            let fp = footprints[index];
            m = min(fp.map, 1u);
            e = arpa_footprint_irradiance(fp, q, n, kernel);
        } else {
            let ph = photons[index];
            m = min(ph.map, 1u);
            e = gather_photon_irradiance(ph, q, n, radii[m]);
        }
        if any(e != vec3<f32>(0.0)) && arpa_is_finite3(e) {
            sum[m] += e;
            count[m] += 1u;
        }
    }
    return GatherResult(sum[0], count[0], sum[1], count[1]);
}

@compute @workgroup_size(64)
fn gather(@builtin(global_invocation_id) gid: vec3<u32>) {
    let i = gid.x;
    if i >= arrayLength(&queries) {
        return;
    }
    let q = queries[i];
    results[i] = gather_at(q.position, q.normal, q.kernel, vec2<f32>(0.0));
}

fn gather_finite_or_zero(v: vec3<f32>) -> vec3<f32> {
    return select(vec3<f32>(0.0), v, vec3<bool>(arpa_is_finite(v.x), arpa_is_finite(v.y), arpa_is_finite(v.z)));
}

// 2D dispatch of 64-wide workgroups, linearised.
@compute @workgroup_size(64)
fn gather_image(@builtin(global_invocation_id) gid: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>) {
    let i = gid.x + gid.y * groups.x * 64u;
    if i >= image_params.pixels {
        return;
    }
    let rec = records[i];
    let first = (image_params.batch & GATHER_BATCH_FIRST) != 0u;
    let last = (image_params.batch & GATHER_BATCH_LAST) != 0u;
    var radiance = rec.radiance;
    var e = vec3<f32>(0.0);
    var n = 0u;
    if rec.valid != 0u {
        let g = gather_at(rec.position, rec.normal, image_params.kernel, image_params.radii);
        // One batch: exactly the single-pass expression (no addition of a zero sum).
        e = g.caustic + g.global;
        if !first {
            e = batch_irradiance[i].xyz + e;
        }
        radiance = rec.radiance + rec.weight * e;
        n = g.caustic_count + g.global_count;
        if first {
            atomicAdd(&gathered_total[2], 1u);
        }
    }
    if last {
        image[i] = vec4<f32>(gather_finite_or_zero(radiance), 0.0);
    } else {
        batch_irradiance[i] = vec4<f32>(e, 0.0);
    }
    if n > 0u {
        // 64-bit total: low word, carry into the high word.
        let old = atomicAdd(&gathered_total[0], n);
        if old > 0xffffffffu - n {
            atomicAdd(&gathered_total[1], 1u);
        }
    }
}
