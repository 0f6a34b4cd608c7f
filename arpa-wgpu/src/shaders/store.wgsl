// Footprint store on the device: each raw footprint (one per photon hit) goes through the
// twin's heuristics and packing (heuristics.wgsl's arpa_store) and is written to the slot of
// its own index, so the result is deterministic (no atomic append). A rejected footprint
// leaves a zero record and a zero-size box at 1e30 m, which no query reaches (and whose zero
// record would contribute nothing). Not min.x = NaN, which Vulkan defines as an inactive
// AABB: with such boxes in the structure, lavapipe (Mesa 25.0.7) missed active boxes too
// (the gather returned zero where the brute-force gather found footprints).
// Needs kernel.wgsl, footprint.wgsl and heuristics.wgsl.

struct RawFootprint {
    center: vec3<f32>,  // metres
    map: u32,           // 0 caustic, 1 global
    normal: vec3<f32>,  // unit, towards the arriving photon
    pad0: u32,
    du: vec3<f32>,      // metres (tangent plane)
    pad1: u32,
    dv: vec3<f32>,
    pad2: u32,
    flux: vec3<f32>,    // W, RGB
    pad3: u32,
}

struct StoreParams {
    heuristics: ArpaHeuristics,
    radii: vec2<f32>,   // progressive radius per map (metres)
    pad: vec2<f32>,
}

@group(0) @binding(0) var<storage, read> raw: array<RawFootprint>;
@group(0) @binding(1) var<storage, read> params: StoreParams;
@group(0) @binding(2) var<storage, read_write> records: array<ArpaPackedFootprint>;
@group(0) @binding(3) var<storage, read_write> boxes: array<f32>;
@group(0) @binding(4) var<storage, read_write> status: array<u32>;

@compute @workgroup_size(64)
fn store_footprints(@builtin(global_invocation_id) gid: vec3<u32>) {
    let i = gid.x;
    if i >= arrayLength(&raw) {
        return;
    }
    let f = raw[i];
    let map = min(f.map, 1u);
    let s = arpa_store(params.heuristics, f.center, f.normal, f.du, f.dv, f.flux, map, params.radii[map]);
    status[i] = s.status;
    let b = 6u * i;
    if s.status == ARPA_STORE_OK {
        records[i] = s.record;
        boxes[b] = s.box_min.x; boxes[b + 1u] = s.box_min.y; boxes[b + 2u] = s.box_min.z;
        boxes[b + 3u] = s.box_max.x; boxes[b + 4u] = s.box_max.y; boxes[b + 5u] = s.box_max.z;
    } else {
        var zero: ArpaPackedFootprint;
        records[i] = zero;
        // NaN must not be a const-expression in WGSL: `i & 0u` keeps it a runtime value.
        let far = 1e30; // metres: beyond any scene
        boxes[b] = far; boxes[b + 1u] = far; boxes[b + 2u] = far;
        boxes[b + 3u] = far; boxes[b + 4u] = far; boxes[b + 5u] = far;
    }
}
