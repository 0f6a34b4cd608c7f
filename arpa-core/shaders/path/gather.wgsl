// The gather: for each query point, every footprint and progressive photon whose
// acceleration-structure box contains it is a candidate; each footprint is tested exactly
// in filter space and weighted by the kernel, each progressive photon by the sphere test and
// constant kernel, at every scale the parameters ask for (bandwidth.wgsl's
// arpa_footprint_irradiance_scales and arpa_photon_irradiance_scales, twins of
// PackedFootprint::irradiance_scales and PackedPhoton::irradiance_scales; scale 0 is the
// stored footprint and radius, PackedFootprint::irradiance and PackedPhoton::irradiance bit
// for bit); the stored scale is summed per map, the smaller scales with both maps together.
//
// Records: footprints (ArpaPackedFootprint) and photons (ArpaPackedPhoton), each sorted by
// map (store.wgsl). The acceleration structure holds box instances whose custom index is
// kind bit | index of their first record (arpa_core::gpu::codes::INSTANCE_PHOTON_BIT,
// INSTANCE_INDEX_MASK: primitive i of that instance is record (custom & mask) + i); the map
// is read from the record. The tracers build one instance per record kind over the store's
// whole capacity (first record 0, both maps, mask 0b11), whose slots past the records hold
// inactive boxes outside the scene that no query meets; tests also build one per
// (kind, map) with mask 1 << map.
//
// Box traversal is the backend's: its glue declares binding 7 of group 0 (its acceleration
// structure over the record boxes) and defines
//   fn arpa_gather_at(q: vec3<f32>, n: vec3<f32>, kernel: u32, radii: vec2<f32>, scales: u32) -> ArpaGatherResult
//     every candidate box containing the query point q (metres; n: unit normal towards
//     the viewer) passed to arpa_gather_candidate in traversal order (with scales, the
//     number of scales to evaluate, 1 ..= ARPA_SCALES), then arpa_gather_result
//     (arpa-wgpu: a point query on ray queries).
//
// Per query record, arpa_gather_pixel (the backend's entry point calls it once per
// record; arpa-wgpu: compute, arpa-vk: ray generation): the camera pass's query records
// in, the iteration's image out, plane-major (plane p of pixel i at p * pixels + i):
// plane k < scales is radiance + weight * E_k (E_0 = E_caustic + E_global, E_k the scale-k
// total) with non-finite components set to 0 (an invalid record: its radiance); with
// scales = ARPA_SCALES, planes ARPA_SCALES .. ARPA_PLANES - 1 are arpa_moments of those
// planes. Photon batches (arpa_core::gpu::batch): an iteration traced in several batches
// gathers each batch's maps in turn; each E_k is summed over the batches in
// batch_irradiance and the last batch writes the image.

// Irradiance per map (W/m^2, RGB), the number of contributing records and the number of
// candidate records per map at the stored scale, and the irradiance of both maps at scales
// 1 .. ARPA_SCALES - 1 (scaled[k - 1]: RGB, w = 0; zero where not evaluated)
// (arpa_core::gpu::layout::GatherResult, 112 bytes).
struct ArpaGatherResult {
    caustic: vec3<f32>,
    caustic_count: u32,
    global: vec3<f32>,
    global_count: u32,
    candidates: vec2<u32>,
    pad: vec2<u32>,
    scaled: array<vec4<f32>, 4>,
}

// The sums of one query while its candidates come in (zero-initialised): per map at the
// stored scale; scaled[k - 1] is scale k, both maps.
struct ArpaGatherSum {
    sum: array<vec3<f32>, 2>,
    count: array<u32, 2>,
    candidates: array<u32, 2>,
    scaled: array<vec3<f32>, 4>,
}

// layout::GatherImageParams (32 bytes).
struct GatherImageParams {
    radii: vec2<f32>,     // progressive radius per map (metres)
    kernel: u32,          // ARPA_KERNEL_* id of the footprints
    pixels: u32,          // query records (one per pixel)
    batch: u32,           // GATHER_BATCH_FIRST | GATHER_BATCH_LAST (both: the whole iteration)
    scales: u32,          // scales to evaluate: 1 (one plane) or ARPA_SCALES (ARPA_PLANES planes)
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
// Per scale and pixel (scale-major, scale k of pixel i at k * pixels + i): the irradiance
// summed over the batches gathered so far (W/m^2, RGB; caustic + global), written by every
// batch but the last.
@group(0) @binding(6) var<storage, read_write> batch_irradiance: array<vec4<f32>>;

// Adds the candidate record of an instance with custom index `custom`, primitive
// `primitive`, to the sums of the query at q with normal n: the record's irradiance at each
// of the first `scales` scales (footprints with `kernel`, photons with the radius of their
// map from `radii`), each when it is non-zero and finite. `radii` is only read for photon
// instances.
fn arpa_gather_candidate(acc: ptr<function, ArpaGatherSum>, custom: u32, primitive: u32, q: vec3<f32>, n: vec3<f32>,
                         kernel: u32, radii: vec2<f32>, scales: u32) {
    let index = (custom & ARPA_INSTANCE_INDEX_MASK) + primitive;
    var e: array<vec3<f32>, ARPA_SCALES>;
    var m: u32;
    if (custom & ARPA_INSTANCE_PHOTON_BIT) == 0u {
        let fp = footprints[index];
        m = min(fp.map, 1u);
        e = arpa_footprint_irradiance_scales(fp, q, n, kernel, scales);
    } else {
        let ph = photons[index];
        m = min(ph.map, 1u);
        e = arpa_photon_irradiance_scales(ph.position, ph.normal, ph.flux, q, n, radii[m], scales);
    }
    (*acc).candidates[m] += 1u;
    if any(e[0] != vec3<f32>(0.0)) && arpa_is_finite3(e[0]) {
        (*acc).sum[m] += e[0];
        (*acc).count[m] += 1u;
    }
    for (var k = 1u; k < min(scales, ARPA_SCALES); k++) {
        if any(e[k] != vec3<f32>(0.0)) && arpa_is_finite3(e[k]) {
            (*acc).scaled[k - 1u] += e[k];
        }
    }
}

// The result of a query's sums.
fn arpa_gather_result(acc: ArpaGatherSum) -> ArpaGatherResult {
    var scaled: array<vec4<f32>, 4>;
    for (var k = 0u; k < 4u; k++) {
        scaled[k] = vec4<f32>(acc.scaled[k], 0.0);
    }
    return ArpaGatherResult(acc.sum[0], acc.count[0], acc.sum[1], acc.count[1], vec2<u32>(acc.candidates[0], acc.candidates[1]), vec2<u32>(0u), scaled);
}

fn gather_finite_or_zero(v: vec3<f32>) -> vec3<f32> {
    return select(vec3<f32>(0.0), v, vec3<bool>(arpa_is_finite(v.x), arpa_is_finite(v.y), arpa_is_finite(v.z)));
}

// Query record i (< pixels) of this batch: sums, image planes and counters.
fn arpa_gather_pixel(i: u32) {
    let rec = records[i];
    let first = (image_params.batch & GATHER_BATCH_FIRST) != 0u;
    let last = (image_params.batch & GATHER_BATCH_LAST) != 0u;
    let scales = clamp(image_params.scales, 1u, ARPA_SCALES);
    let pixels = image_params.pixels;
    var radiance = rec.radiance;
    var e = vec3<f32>(0.0);
    // E_k of scales k >= 1 (entry 0 unused: the stored scale is e).
    var es: array<vec3<f32>, ARPA_SCALES>;
    var counts = vec2<u32>(0u);
    var candidates = vec2<u32>(0u);
    if rec.valid != 0u {
        let g = arpa_gather_at(rec.position, rec.normal, image_params.kernel, image_params.radii, scales);
        // One batch: exactly the single-pass expression (no addition of a zero sum).
        e = g.caustic + g.global;
        if !first {
            e = batch_irradiance[i].xyz + e;
        }
        radiance = rec.radiance + rec.weight * e;
        for (var k = 1u; k < scales; k++) {
            es[k] = g.scaled[k - 1u].xyz;
            if !first {
                es[k] = batch_irradiance[k * pixels + i].xyz + es[k];
            }
        }
        counts = vec2<u32>(g.caustic_count, g.global_count);
        candidates = g.candidates;
        if first {
            atomicAdd(&gathered_total[8], 1u);
        }
    }
    if last {
        var l: array<vec3<f32>, ARPA_SCALES>;
        l[0] = gather_finite_or_zero(radiance);
        image[i] = vec4<f32>(l[0], 0.0);
        for (var k = 1u; k < scales; k++) {
            var lk = rec.radiance;
            if rec.valid != 0u {
                lk = rec.radiance + rec.weight * es[k];
            }
            l[k] = gather_finite_or_zero(lk);
            image[k * pixels + i] = vec4<f32>(l[k], 0.0);
        }
        if scales == ARPA_SCALES {
            let moments = arpa_moments(l);
            for (var p = 0u; p < ARPA_MOMENT_PLANES; p++) {
                image[(ARPA_SCALES + p) * pixels + i] = vec4<f32>(moments[p], 0.0);
            }
        }
    } else {
        batch_irradiance[i] = vec4<f32>(e, 0.0);
        for (var k = 1u; k < scales; k++) {
            batch_irradiance[k * pixels + i] = vec4<f32>(es[k], 0.0);
        }
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
