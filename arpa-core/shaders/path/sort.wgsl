// Bitonic sort of (hi, lo, value) items in ascending lexicographic order, on the device.
// The order is total (value breaks ties), so the result does not depend on the order the
// items were written in (atomic appends). The item count is a power of two >= 512
// (SORT_BLOCK); the host pads with SORT_INVALID items, which sort last.
//
// Stages with a compare distance j < SORT_BLOCK run within one workgroup in shared memory
// (sort_local: every stage of blocks of SORT_BLOCK items; sort_merge: the j < SORT_BLOCK
// tail of one merge step k); stages with j >= SORT_BLOCK run one dispatch each
// (sort_global). Each invocation compares one pair. Items: ArpaSortItem (records.wgsl);
// the host schedule of the steps is arpa_core::gpu::sort::sort_steps.

// One step: merge size k and compare distance j (both powers of two); the first 16 bytes of
// arpa_core::gpu::sort::SortStep.
struct SortStep {
    k: u32,
    j: u32,
    pad0: u32,
    pad1: u32,
}

const SORT_BLOCK: u32 = 512u;           // arpa_core::gpu::sort::SORT_BLOCK
const SORT_INVALID: u32 = 0xffffffffu;  // arpa_core::gpu::sort::SORT_INVALID

@group(0) @binding(0) var<storage, read_write> sort_items: array<ArpaSortItem>;
@group(0) @binding(1) var<uniform> sort_step: SortStep;

var<workgroup> sort_shared: array<ArpaSortItem, 512>;

// a > b in (hi, lo, value) order.
fn sort_greater(a: ArpaSortItem, b: ArpaSortItem) -> bool {
    if a.hi != b.hi {
        return a.hi > b.hi;
    }
    if a.lo != b.lo {
        return a.lo > b.lo;
    }
    return a.value > b.value;
}

// Index of the first item of the pair that invocation t compares at distance j.
fn sort_pair_first(t: u32, j: u32) -> u32 {
    return (t / j) * (2u * j) + (t % j);
}

// Compare-exchange of shared items i and i + j; `global_i` decides the direction.
fn sort_shared_step(t: u32, base: u32, k: u32, j: u32) {
    let i = sort_pair_first(t, j);
    let l = i + j;
    let a = sort_shared[i];
    let b = sort_shared[l];
    let ascending = ((base + i) & k) == 0u;
    if sort_greater(a, b) == ascending {
        sort_shared[i] = b;
        sort_shared[l] = a;
    }
}

@compute @workgroup_size(256)
fn sort_local(@builtin(local_invocation_id) lid: vec3<u32>, @builtin(workgroup_id) wid: vec3<u32>) {
    let t = lid.x;
    let base = wid.x * SORT_BLOCK;
    sort_shared[t] = sort_items[base + t];
    sort_shared[t + 256u] = sort_items[base + t + 256u];
    workgroupBarrier();
    for (var k = 2u; k <= SORT_BLOCK; k = k * 2u) {
        for (var j = k / 2u; j > 0u; j = j / 2u) {
            sort_shared_step(t, base, k, j);
            workgroupBarrier();
        }
    }
    sort_items[base + t] = sort_shared[t];
    sort_items[base + t + 256u] = sort_shared[t + 256u];
}

@compute @workgroup_size(256)
fn sort_merge(@builtin(local_invocation_id) lid: vec3<u32>, @builtin(workgroup_id) wid: vec3<u32>) {
    let t = lid.x;
    let base = wid.x * SORT_BLOCK;
    let k = sort_step.k;
    sort_shared[t] = sort_items[base + t];
    sort_shared[t + 256u] = sort_items[base + t + 256u];
    workgroupBarrier();
    for (var j = SORT_BLOCK / 2u; j > 0u; j = j / 2u) {
        sort_shared_step(t, base, k, j);
        workgroupBarrier();
    }
    sort_items[base + t] = sort_shared[t];
    sort_items[base + t + 256u] = sort_shared[t + 256u];
}

@compute @workgroup_size(256)
fn sort_global(@builtin(global_invocation_id) gid: vec3<u32>) {
    let j = sort_step.j;
    let i = sort_pair_first(gid.x, j);
    let l = i + j;
    let a = sort_items[i];
    let b = sort_items[l];
    let ascending = (i & sort_step.k) == 0u;
    if sort_greater(a, b) == ascending {
        sort_items[i] = b;
        sort_items[l] = a;
    }
}
