// The gather: for each query point, every footprint and progressive photon whose
// acceleration-structure box contains it is a candidate; each footprint is tested exactly
// in filter space and weighted by the kernel (footprint.wgsl's arpa_footprint_irradiance),
// each progressive photon by the sphere test and constant kernel of
// arpa_core::progressive_photon::PackedPhoton::irradiance; irradiance is summed per map.
//
// Records: footprints (ArpaPackedFootprint) and photons (ArpaPackedPhoton), each sorted by
// map (store.wgsl). The acceleration structure holds one box instance per non-empty
// (kind, map) whose custom index is kind bit | index of its first record
// (arpa_core::gpu::codes::INSTANCE_PHOTON_BIT, INSTANCE_INDEX_MASK: primitive i of that
// instance is record (custom & mask) + i) and whose mask is 1 << map.
//
// Box traversal is the backend's: its glue declares binding 7 of group 0 (its acceleration
// structure over the record boxes) and defines
//   fn arpa_gather_at(q: vec3<f32>, n: vec3<f32>, kernel: u32, radii: vec2<f32>) -> ArpaGatherResult
//     every candidate box containing the query point q (metres; n: unit normal towards
//     the viewer) passed to arpa_gather_candidate in traversal order, then
//     arpa_gather_result (arpa-wgpu: a point query on ray queries).
//
// Per query record, arpa_gather_pixel (the backend's entry point calls it once per
// record; arpa-wgpu: compute, arpa-vk: ray generation): the camera pass's query records
// in, the iteration's radiance per pixel out, radiance + weight * (E_caustic + E_global) with non-finite components set to
// 0. Photon batches (arpa_core::gpu::batch): an iteration traced in several batches
// gathers each batch's maps in turn; E is summed over the batches in batch_irradiance and
// the last batch writes the radiance.

// Irradiance per map (W/m^2, RGB), the number of contributing records and the number of
// candidate records per map (arpa_core::gpu::layout::GatherResult, 48 bytes).
struct ArpaGatherResult {
    caustic: vec3<f32>,
    caustic_count: u32,
    global: vec3<f32>,
    global_count: u32,
    candidates: vec2<u32>,
    pad: vec2<u32>,
}

// The sums of one query while its candidates come in (zero-initialised).
struct ArpaGatherSum {
    sum: array<vec3<f32>, 2>,
    count: array<u32, 2>,
    candidates: array<u32, 2>,
}

// layout::GatherImageParams (32 bytes).
struct GatherImageParams {
    radii: vec2<f32>,     // progressive radius per map (metres)
    kernel: u32,          // ARPA_KERNEL_* id of the footprints
    pixels: u32,          // query records (one per pixel)
    batch: u32,           // GATHER_BATCH_FIRST | GATHER_BATCH_LAST (both: the whole iteration)
    pad0: u32,
    pad1: u32,
    pad2: u32,
}

// Photon batches (layout::GatherBatch): the first batch of an iteration starts the
// per-pixel irradiance sum and counts the valid records; later ones add to the sum; the
// last writes the image radiance + weight * (sum over the batches).
const GATHER_BATCH_FIRST: u32 = 1u;
const GATHER_BATCH_LAST: u32 = 2u;

// Instance custom index: photon-kind bit and first-record mask (codes::INSTANCE_*).
const ARPA_INSTANCE_PHOTON_BIT: u32 = 0x800000u;
const ARPA_INSTANCE_INDEX_MASK: u32 = 0x7fffffu;

@group(0) @binding(0) var<storage, read> footprints: array<ArpaPackedFootprint>;
@group(0) @binding(1) var<storage, read> photons: array<ArpaPackedPhoton>;
@group(0) @binding(2) var<storage, read> records: array<ArpaQueryRecord>;
@group(0) @binding(3) var<storage, read_write> image: array<vec4<f32>>;
@group(0) @binding(4) var<storage, read> image_params: GatherImageParams;
// layout::GatherCounts: contributions per map (low, high word) at 0..3, candidates per map
// (low, high word) at 4..7, valid query records at 8, query records with a contribution
// per map at 9..10, padding 11.
@group(0) @binding(5) var<storage, read_write> gathered_total: array<atomic<u32>, 12>;
// Per pixel: irradiance summed over the batches gathered so far (W/m^2, RGB; caustic +
// global), written by every batch but the last.
@group(0) @binding(6) var<storage, read_write> batch_irradiance: array<vec4<f32>>;

// PackedPhoton::irradiance: flux / (pi r^2) inside the sphere |q - x|^2 < r^2 and on the lit
// side, else 0 (also 0 when the density or the result is not finite).
fn gather_photon_irradiance(ph: ArpaPackedPhoton, q: vec3<f32>, query_normal: vec3<f32>, radius: f32) -> vec3<f32> {
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

// Adds the candidate record of an instance with custom index `custom`, primitive
// `primitive`, to the sums of the query at q with normal n: the record's irradiance
// (footprints with `kernel`, photons with the radius of their map from `radii`) when it is
// non-zero and finite. `radii` is only read for photon instances.
fn arpa_gather_candidate(acc: ptr<function, ArpaGatherSum>, custom: u32, primitive: u32, q: vec3<f32>, n: vec3<f32>,
                         kernel: u32, radii: vec2<f32>) {
    let index = (custom & ARPA_INSTANCE_INDEX_MASK) + primitive;
    var e: vec3<f32>;
    var m: u32;
    if (custom & ARPA_INSTANCE_PHOTON_BIT) == 0u {
        let fp = footprints[index];
        m = min(fp.map, 1u);
        e = arpa_footprint_irradiance(fp, q, n, kernel);
    } else {
        let ph = photons[index];
        m = min(ph.map, 1u);
        e = gather_photon_irradiance(ph, q, n, radii[m]);
    }
    (*acc).candidates[m] += 1u;
    if any(e != vec3<f32>(0.0)) && arpa_is_finite3(e) {
        (*acc).sum[m] += e;
        (*acc).count[m] += 1u;
    }
}

// The result of a query's sums.
fn arpa_gather_result(acc: ArpaGatherSum) -> ArpaGatherResult {
    return ArpaGatherResult(acc.sum[0], acc.count[0], acc.sum[1], acc.count[1], vec2<u32>(acc.candidates[0], acc.candidates[1]), vec2<u32>(0u));
}

fn gather_finite_or_zero(v: vec3<f32>) -> vec3<f32> {
    return select(vec3<f32>(0.0), v, vec3<bool>(arpa_is_finite(v.x), arpa_is_finite(v.y), arpa_is_finite(v.z)));
}

// Query record i (< pixels) of this batch: sum, image and counters.
fn arpa_gather_pixel(i: u32) {
    let rec = records[i];
    let first = (image_params.batch & GATHER_BATCH_FIRST) != 0u;
    let last = (image_params.batch & GATHER_BATCH_LAST) != 0u;
    var radiance = rec.radiance;
    var e = vec3<f32>(0.0);
    var counts = vec2<u32>(0u);
    var candidates = vec2<u32>(0u);
    if rec.valid != 0u {
        let g = arpa_gather_at(rec.position, rec.normal, image_params.kernel, image_params.radii);
        // One batch: exactly the single-pass expression (no addition of a zero sum).
        e = g.caustic + g.global;
        if !first {
            e = batch_irradiance[i].xyz + e;
        }
        radiance = rec.radiance + rec.weight * e;
        counts = vec2<u32>(g.caustic_count, g.global_count);
        candidates = g.candidates;
        if first {
            atomicAdd(&gathered_total[8], 1u);
        }
    }
    if last {
        image[i] = vec4<f32>(gather_finite_or_zero(radiance), 0.0);
    } else {
        batch_irradiance[i] = vec4<f32>(e, 0.0);
    }
    for (var m = 0u; m < 2u; m++) {
        gather_count(2u * m, counts[m]);
        gather_count(4u + 2u * m, candidates[m]);
        if counts[m] > 0u {
            atomicAdd(&gathered_total[9u + m], 1u);
        }
    }
}

// Adds n to the 64-bit total at gathered_total[at] (low word; carry into at + 1).
fn gather_count(at: u32, n: u32) {
    if n > 0u {
        let old = atomicAdd(&gathered_total[at], n);
        if old > 0xffffffffu - n {
            atomicAdd(&gathered_total[at + 1u], 1u);
        }
    }
}
