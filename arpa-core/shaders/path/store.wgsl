// The keyed store on the device, on the photon pass's append buffers (footprints already
// smoothed and, below the shading plane, with the normal flipped): each raw footprint goes
// through the twin's heuristics and packing (heuristics.wgsl's arpa_store) into the slot of
// its own index or, when rejected, becomes a progressive photon in its own slot (the core's
// fallback, arpa_core::store); every stored item gets a sort key (map << 30 | Morton code of
// its box centre, unique photon key, slot) for sort.wgsl; after the sort, compact_* copy the
// records and their acceleration-structure boxes into sorted order (caustic first, then
// global), so the maps do not depend on the order the photon pass appended in.
//
// Entry points, in order (64-wide workgroups over a 2D grid, linearised): store_keyed
// (raw_count invocations) and photon_keys (photon_count), sized by the schedule kernel on
// the device; then, over the store's capacities (fp_sorted, ph_sorted: no size waits for a
// count), pad_items (the larger of the two; it reads the appended counts from the store's
// counters), the sort of fp_items and ph_items, and compact_footprints (fp_sorted),
// compact_photons (ph_sorted), which give every slot past the records an inactive box
// (arpa_inactive_point, aabb.wgsl), so that the acceleration structures can be built over
// the whole capacity. Group 0, bindings 0 to 12.

// arpa_core::gpu::layout::StoreParams (112 bytes).
struct StoreParams {
    heuristics: ArpaHeuristics,
    radii: vec2<f32>,      // progressive radius per map (metres)
    pad2: vec2<f32>,
    scene_lo: vec3<f32>,   // scene bounds' low corner (metres)
    raw_count: u32,        // raw footprints appended by the photon pass
    scene_inv: vec3<f32>,  // 1 / scene extent per axis (1/m; 0 on a flat axis)
    photon_count: u32,     // progressive photons appended by the photon pass
    fp_sorted: u32,        // footprint items sorted and compacted (the raw capacity)
    ph_sorted: u32,        // photon items sorted and compacted (the sorted-photon capacity)
    pad3: vec2<u32>,
}

// Counter words of `store_counts` (layout::StoreCounts).
const STORE_COUNT_FOOTPRINTS: u32 = 0u;   // + map
const STORE_COUNT_PHOTONS: u32 = 2u;      // + map
const STORE_COUNT_REASON: u32 = 3u;       // + ARPA_STORE_* status (1 degenerate, 2 culled, 3 unrepresentable)
const STORE_COUNT_OVERFLOWED: u32 = 7u;   // photon items beyond ph_sorted or ph_out's capacity
const STORE_COUNT_FP_ITEMS: u32 = 8u;     // footprint sort items appended
const STORE_COUNT_PH_ITEMS: u32 = 9u;     // photon sort items appended
const STORE_INVALID: u32 = 0xffffffffu;

@group(0) @binding(0) var<storage, read> raw_in: array<ArpaKeyedFootprint>;
@group(0) @binding(1) var<storage, read> photons_in: array<ArpaKeyedPhoton>;
@group(0) @binding(2) var<storage, read> kparams: StoreParams;
@group(0) @binding(3) var<storage, read_write> fp_slots: array<ArpaPackedFootprint>;
@group(0) @binding(4) var<storage, read_write> fp_box_slots: array<f32>;
@group(0) @binding(5) var<storage, read_write> ph_extra: array<ArpaKeyedPhoton>;
@group(0) @binding(6) var<storage, read_write> fp_items: array<ArpaSortItem>;
@group(0) @binding(7) var<storage, read_write> ph_items: array<ArpaSortItem>;
@group(0) @binding(8) var<storage, read_write> store_counts: array<atomic<u32>, 12>;
@group(0) @binding(9) var<storage, read_write> fp_out: array<ArpaPackedFootprint>;
@group(0) @binding(10) var<storage, read_write> fp_box_out: array<f32>;
@group(0) @binding(11) var<storage, read_write> ph_out: array<ArpaPackedPhoton>;
@group(0) @binding(12) var<storage, read_write> ph_box_out: array<f32>;

// Linear invocation index of a 2D dispatch of 64-wide workgroups.
fn store_index(gid: vec3<u32>, groups: vec3<u32>) -> u32 {
    return gid.x + gid.y * groups.x * 64u;
}

fn store_item(map: u32, p: vec3<f32>, key: u32, slot: u32) -> ArpaSortItem {
    return ArpaSortItem((map << 30u) | arpa_morton_code(p, kparams.scene_lo, kparams.scene_inv), key, slot);
}

const STORE_INVALID_ITEM: ArpaSortItem = ArpaSortItem(0xffffffffu, 0xffffffffu, 0xffffffffu);

// Stores raw footprint i (i < raw_count) into its slot and appends its sort item: to
// fp_items when stored, else (the fallback photon, slot photon_count + i) to ph_items.
@compute @workgroup_size(64)
fn store_keyed(@builtin(global_invocation_id) gid: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>) {
    let i = store_index(gid, groups);
    if i >= kparams.raw_count {
        return;
    }
    let f = raw_in[i];
    let map = min(f.map, 1u);
    let st = arpa_store(kparams.heuristics, f.center, f.normal, f.du, f.dv, f.flux, map, kparams.radii[map]);
    if st.status == ARPA_STORE_OK {
        fp_slots[i] = st.record;
        let b = 6u * i;
        fp_box_slots[b] = st.box_min.x; fp_box_slots[b + 1u] = st.box_min.y; fp_box_slots[b + 2u] = st.box_min.z;
        fp_box_slots[b + 3u] = st.box_max.x; fp_box_slots[b + 4u] = st.box_max.y; fp_box_slots[b + 5u] = st.box_max.z;
        let at = atomicAdd(&store_counts[STORE_COUNT_FP_ITEMS], 1u);
        fp_items[at] = store_item(map, 0.5 * (st.box_min + st.box_max), f.key, i);
        atomicAdd(&store_counts[STORE_COUNT_FOOTPRINTS + map], 1u);
    } else {
        // The core's fallback: a progressive photon at the (smoothed) footprint's centre
        // with its normal and flux.
        ph_extra[i] = ArpaKeyedPhoton(f.center, map, f.normal, 0u, f.flux, 0u, f.key, 0u, 0u, 0u);
        let slot = kparams.photon_count + i;
        let at = atomicAdd(&store_counts[STORE_COUNT_PH_ITEMS], 1u);
        if at < kparams.ph_sorted {
            ph_items[at] = store_item(map, f.center, f.key, slot);
        } else {
            atomicAdd(&store_counts[STORE_COUNT_OVERFLOWED], 1u);
        }
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
    if at < kparams.ph_sorted {
        ph_items[at] = store_item(map, p.position, p.key, j);
    } else {
        atomicAdd(&store_counts[STORE_COUNT_OVERFLOWED], 1u);
    }
    atomicAdd(&store_counts[STORE_COUNT_PHOTONS + map], 1u);
}

// Fills the items after the appended ones (counted in store_counts) up to the lengths the
// sort runs over with invalid items.
@compute @workgroup_size(64)
fn pad_items(@builtin(global_invocation_id) gid: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>) {
    let i = store_index(gid, groups);
    if i >= atomicLoad(&store_counts[STORE_COUNT_FP_ITEMS]) && i < kparams.fp_sorted {
        fp_items[i] = STORE_INVALID_ITEM;
    }
    if i >= atomicLoad(&store_counts[STORE_COUNT_PH_ITEMS]) && i < kparams.ph_sorted {
        ph_items[i] = STORE_INVALID_ITEM;
    }
}

// Writes box s of `boxes` (6 f32 per box) as [lower, upper].
fn store_write_box(s: u32, lower: vec3<f32>, upper: vec3<f32>, to_photons: bool) {
    let b = 6u * s;
    if to_photons {
        ph_box_out[b] = lower.x; ph_box_out[b + 1u] = lower.y; ph_box_out[b + 2u] = lower.z;
        ph_box_out[b + 3u] = upper.x; ph_box_out[b + 4u] = upper.y; ph_box_out[b + 5u] = upper.z;
    } else {
        fp_box_out[b] = lower.x; fp_box_out[b + 1u] = lower.y; fp_box_out[b + 2u] = lower.z;
        fp_box_out[b + 3u] = upper.x; fp_box_out[b + 4u] = upper.y; fp_box_out[b + 5u] = upper.z;
    }
}

// Copies sorted footprint s and its box; a slot past the footprints (a padding item) gets
// the inactive box.
@compute @workgroup_size(64)
fn compact_footprints(@builtin(global_invocation_id) gid: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>) {
    let s = store_index(gid, groups);
    if s >= kparams.fp_sorted || s >= arrayLength(&fp_out) {
        return;
    }
    let item = fp_items[s];
    if item.hi == STORE_INVALID {
        let p = arpa_inactive_point(kparams.scene_lo);
        store_write_box(s, p, p, false);
        return;
    }
    let i = item.value;
    fp_out[s] = fp_slots[i];
    for (var c = 0u; c < 6u; c++) {
        fp_box_out[6u * s + c] = fp_box_slots[6u * i + c];
    }
}

// Copies sorted photon s and writes its box: the sphere of the map's progressive radius
// around it, padded as every acceleration-structure box (aabb.wgsl), so that the box holds
// every point the gather's f32 sphere test accepts; a slot past the photons gets the
// inactive box.
@compute @workgroup_size(64)
fn compact_photons(@builtin(global_invocation_id) gid: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>) {
    let s = store_index(gid, groups);
    if s >= kparams.ph_sorted {
        return;
    }
    let item = ph_items[s];
    if item.hi == STORE_INVALID {
        if s < arrayLength(&ph_out) {
            let p = arpa_inactive_point(kparams.scene_lo);
            store_write_box(s, p, p, true);
        }
        return;
    }
    if s >= arrayLength(&ph_out) {
        atomicAdd(&store_counts[STORE_COUNT_OVERFLOWED], 1u);
        return;
    }
    var p: ArpaKeyedPhoton;
    if item.value < kparams.photon_count {
        p = photons_in[item.value];
    } else {
        p = ph_extra[item.value - kparams.photon_count];
    }
    ph_out[s] = ArpaPackedPhoton(p.position, p.map, p.normal, 0u, p.flux, 0u);
    let r = kparams.radii[min(p.map, 1u)];
    let bx = arpa_padded_box(p.position, vec3<f32>(r));
    store_write_box(s, bx.lower, bx.upper, true);
}
