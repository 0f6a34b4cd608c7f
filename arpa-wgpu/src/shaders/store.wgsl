// Footprint store on the device: each raw footprint (one per photon hit) goes through the
// twin's heuristics and packing (heuristics.wgsl's arpa_store) and is written to the slot of
// its own index, so the result is deterministic (no atomic append). A rejected footprint
// leaves a zero record and a zero-size box at 1e30 m, which no query reaches (and whose zero
// record would contribute nothing). Not min.x = NaN, which Vulkan defines as an inactive
// AABB: with such boxes in the structure, lavapipe (Mesa 25.0.7) missed active boxes too
// (the gather returned zero where the brute-force gather found footprints).
//
// The tracer's keyed store (store_keyed, photon_keys, compact_*; bindings 5 and up) works on
// the photon pass's atomic-append buffers (footprints already smoothed and, below the
// shading plane, with the normal flipped): each raw footprint is stored through the
// heuristics into its own slot or, when rejected, becomes a progressive photon in its own
// slot (the core's fallback); every stored item gets a sort key (map << 30 | Morton code
// of its box centre, unique photon key, slot) for sort.wgsl; after the sort, compact_*
// copy the records and boxes into sorted order (caustic first, then global).
// Needs kernel.wgsl, footprint.wgsl, heuristics.wgsl, morton.wgsl and sort.wgsl's SortItem
// (declared here as StoreSortItem: same layout).

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

// arpa-wgpu photon.rs KeyedFootprint (96 bytes).
struct KeyedFootprint {
    fp: RawFootprint,
    key: u32,           // unique photon key (photon index * max_depth + depth)
    pad0: u32,
    pad1: u32,
    pad2: u32,
}

// arpa_core::progressive_photon::PackedPhoton + key (photon.rs KeyedPhoton, 64 bytes).
struct KeyedPhoton {
    position: vec3<f32>, // metres
    map: u32,
    normal: vec3<f32>,   // unit, towards the arrival side (already flipped where needed)
    pad0: u32,
    flux: vec3<f32>,     // W, RGB
    pad1: u32,
    key: u32,
    pad2: u32,
    pad3: u32,
    pad4: u32,
}

struct StoreParams {
    heuristics: ArpaHeuristics,
    radii: vec2<f32>,      // progressive radius per map (metres)
    pad2: vec2<f32>,
    scene_lo: vec3<f32>,   // scene bounds' low corner (metres)
    raw_count: u32,        // raw footprints appended by the photon pass
    scene_inv: vec3<f32>,  // 1 / scene extent per axis (1/m; 0 on a flat axis)
    photon_count: u32,     // progressive photons appended by the photon pass
    fp_sorted: u32,        // sorted length of the footprint items (power of two)
    ph_sorted: u32,        // sorted length of the photon items
    fp_count: u32,         // footprint items appended by store_keyed
    ph_count: u32,         // photon items appended by store_keyed and photon_keys
}

struct StoreSortItem {
    hi: u32,
    lo: u32,
    value: u32,
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

// ---- keyed store (the tracer) ----

// Counter words of `store_counts`.
const STORE_COUNT_FOOTPRINTS: u32 = 0u;   // + map
const STORE_COUNT_PHOTONS: u32 = 2u;      // + map
const STORE_COUNT_REASON: u32 = 3u;       // + ARPA_STORE_* status (1 degenerate, 2 culled, 3 unrepresentable)
const STORE_COUNT_OVERFLOWED: u32 = 7u;   // sorted photons beyond ph_out's capacity
const STORE_COUNT_FP_ITEMS: u32 = 8u;     // footprint sort items appended
const STORE_COUNT_PH_ITEMS: u32 = 9u;     // photon sort items appended
const STORE_INVALID: u32 = 0xffffffffu;

@group(0) @binding(5) var<storage, read> raw_in: array<KeyedFootprint>;
@group(0) @binding(6) var<storage, read> photons_in: array<KeyedPhoton>;
@group(0) @binding(7) var<storage, read> kparams: StoreParams;
@group(0) @binding(8) var<storage, read_write> fp_slots: array<ArpaPackedFootprint>;
@group(0) @binding(9) var<storage, read_write> fp_box_slots: array<f32>;
@group(0) @binding(10) var<storage, read_write> ph_extra: array<KeyedPhoton>;
@group(0) @binding(11) var<storage, read_write> fp_items: array<StoreSortItem>;
@group(0) @binding(12) var<storage, read_write> ph_items: array<StoreSortItem>;
@group(0) @binding(13) var<storage, read_write> store_counts: array<atomic<u32>, 12>;
@group(0) @binding(14) var<storage, read_write> fp_out: array<ArpaPackedFootprint>;
@group(0) @binding(15) var<storage, read_write> fp_box_out: array<f32>;
// PackedPhoton (48 bytes): the sorted output.
struct StorePhotonOut {
    position: vec3<f32>,
    map: u32,
    normal: vec3<f32>,
    pad0: u32,
    flux: vec3<f32>,
    pad1: u32,
}
@group(0) @binding(16) var<storage, read_write> ph_out: array<StorePhotonOut>;
@group(0) @binding(17) var<storage, read_write> ph_box_out: array<f32>;

// Linear invocation index of a 2D dispatch of 64-wide workgroups.
fn store_index(gid: vec3<u32>, groups: vec3<u32>) -> u32 {
    return gid.x + gid.y * groups.x * 64u;
}

fn store_item(map: u32, p: vec3<f32>, key: u32, slot: u32) -> StoreSortItem {
    return StoreSortItem((map << 30u) | morton_code(p, kparams.scene_lo, kparams.scene_inv), key, slot);
}

const STORE_INVALID_ITEM: StoreSortItem = StoreSortItem(0xffffffffu, 0xffffffffu, 0xffffffffu);

// Stores raw footprint i (i < raw_count) into its slot and appends its sort item: to
// fp_items when stored, else (the fallback photon, slot photon_count + i) to ph_items.
@compute @workgroup_size(64)
fn store_keyed(@builtin(global_invocation_id) gid: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>) {
    let i = store_index(gid, groups);
    if i >= kparams.raw_count {
        return;
    }
    let keyed = raw_in[i];
    let f = keyed.fp;
    let map = min(f.map, 1u);
    let st = arpa_store(kparams.heuristics, f.center, f.normal, f.du, f.dv, f.flux, map, kparams.radii[map]);
    if st.status == ARPA_STORE_OK {
        fp_slots[i] = st.record;
        let b = 6u * i;
        fp_box_slots[b] = st.box_min.x; fp_box_slots[b + 1u] = st.box_min.y; fp_box_slots[b + 2u] = st.box_min.z;
        fp_box_slots[b + 3u] = st.box_max.x; fp_box_slots[b + 4u] = st.box_max.y; fp_box_slots[b + 5u] = st.box_max.z;
        let at = atomicAdd(&store_counts[STORE_COUNT_FP_ITEMS], 1u);
        fp_items[at] = store_item(map, 0.5 * (st.box_min + st.box_max), keyed.key, i);
        atomicAdd(&store_counts[STORE_COUNT_FOOTPRINTS + map], 1u);
    } else {
        // The core's fallback: a progressive photon at the (smoothed) footprint's centre
        // with its normal and flux.
        ph_extra[i] = KeyedPhoton(f.center, map, f.normal, 0u, f.flux, 0u, keyed.key, 0u, 0u, 0u);
        let slot = kparams.photon_count + i;
        let at = atomicAdd(&store_counts[STORE_COUNT_PH_ITEMS], 1u);
        ph_items[at] = store_item(map, f.center, keyed.key, slot);
        atomicAdd(&store_counts[STORE_COUNT_PHOTONS + map], 1u);
        atomicAdd(&store_counts[STORE_COUNT_REASON + min(st.status, 3u)], 1u);
    }
}

// Appends the sort item of the photon pass's photon j (j < photon_count).
@compute @workgroup_size(64)
fn photon_keys(@builtin(global_invocation_id) gid: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>) {
    let j = store_index(gid, groups);
    if j >= kparams.photon_count {
        return;
    }
    let p = photons_in[j];
    let map = min(p.map, 1u);
    let at = atomicAdd(&store_counts[STORE_COUNT_PH_ITEMS], 1u);
    ph_items[at] = store_item(map, p.position, p.key, j);
    atomicAdd(&store_counts[STORE_COUNT_PHOTONS + map], 1u);
}

// Fills the items after the appended ones up to the sorted lengths with invalid items.
@compute @workgroup_size(64)
fn pad_items(@builtin(global_invocation_id) gid: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>) {
    let i = store_index(gid, groups);
    if i >= kparams.fp_count && i < kparams.fp_sorted {
        fp_items[i] = STORE_INVALID_ITEM;
    }
    if i >= kparams.ph_count && i < kparams.ph_sorted {
        ph_items[i] = STORE_INVALID_ITEM;
    }
}

@compute @workgroup_size(64)
fn compact_footprints(@builtin(global_invocation_id) gid: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>) {
    let s = store_index(gid, groups);
    if s >= kparams.fp_sorted {
        return;
    }
    let item = fp_items[s];
    if item.hi == STORE_INVALID {
        return;
    }
    let i = item.value;
    fp_out[s] = fp_slots[i];
    for (var c = 0u; c < 6u; c++) {
        fp_box_out[6u * s + c] = fp_box_slots[6u * i + c];
    }
}

// Relative padding, position padding (f32 ulps of the box's largest coordinate) and floor
// of a photon's box: arpa-cpu's padded_box (photon_store.rs), so that the box holds every
// point the f32 sphere test accepts.
const STORE_PHOTON_RELATIVE_PAD: f32 = 1e-4;
const STORE_PHOTON_POSITION_PAD: f32 = 9.0 * 1.1920929e-7;

@compute @workgroup_size(64)
fn compact_photons(@builtin(global_invocation_id) gid: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>) {
    let s = store_index(gid, groups);
    if s >= kparams.ph_sorted {
        return;
    }
    let item = ph_items[s];
    if item.hi == STORE_INVALID {
        return;
    }
    if s >= arrayLength(&ph_out) {
        atomicAdd(&store_counts[STORE_COUNT_OVERFLOWED], 1u);
        return;
    }
    var p: KeyedPhoton;
    if item.value < kparams.photon_count {
        p = photons_in[item.value];
    } else {
        p = ph_extra[item.value - kparams.photon_count];
    }
    ph_out[s] = StorePhotonOut(p.position, p.map, p.normal, 0u, p.flux, 0u);
    let r = kparams.radii[min(p.map, 1u)];
    let scale = arpa_max_abs(p.position) + r;
    let pad = r * STORE_PHOTON_RELATIVE_PAD + STORE_PHOTON_POSITION_PAD * scale + ARPA_F32_MIN_POSITIVE;
    let lo = p.position - vec3<f32>(r + pad);
    let hi = p.position + vec3<f32>(r + pad);
    let b = 6u * s;
    ph_box_out[b] = lo.x; ph_box_out[b + 1u] = lo.y; ph_box_out[b + 2u] = lo.z;
    ph_box_out[b + 3u] = hi.x; ph_box_out[b + 4u] = hi.y; ph_box_out[b + 5u] = hi.z;
}
