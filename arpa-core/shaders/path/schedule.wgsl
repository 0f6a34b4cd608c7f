// The keyed store's schedule on the device (arpa_core::gpu::shaders::SCHEDULE): sizes that
// the host used to read back and write again are written here from the device's own counts,
// so the store (and, over the capacities, the sort and the compaction) runs in the same
// submission as the photon pass and the host waits for no count before the accumulate.
//
// store_schedule (one invocation) reads the photon pass's counters (PhotonCounters of
// arpa_core::gpu::layout) and writes
// - StoreParams.raw_count and .photon_count (arpa_core::gpu::layout::StoreParams; the host
//   writes the rest of the parameters through the queue before the submission): the
//   appends the photon pass wrote, i.e. attempted minus dropped
//   (PhotonCounters::footprints_written, ::photons_written);
// - the indirect dispatch arguments of store_keyed (words 0..3) and photon_keys (3..6), one
//   invocation per record of the 64-wide kernels, as the host's linear dispatch lays them
//   out: one row of workgroups up to 65 535, else rows of 32 768 (store.wgsl's store_index
//   linearises gid.x + gid.y · groups.x · 64); at least one workgroup, since the kernels
//   return past their counts;
// - the iteration's status word: 1 when the photon pass dropped appends (a buffer was
//   full), else left as it is. The host clears it at the start of an iteration's photon
//   pass; the accumulation leaves the sums alone while it is set (accumulate.wgsl), and the
//   host, which reads it with the iteration's counters at the accumulate's wait, traces the
//   iteration again with larger buffers.
//
// store_check (one invocation, after the store's compaction) sets the status word too when
// the store dropped photon items for lack of room (StoreCounts::overflowed).
// Group 0: binding 0 the counters (read), 1 the store parameters, 2 the arguments, 3 the
// status word, 4 the store's counters (StoreCounts, read).

struct ArpaScheduleCounters {
    emitted: u32,
    segments: u32,
    footprints_caustic: u32,
    footprints_global: u32,
    progressive_caustic: u32,
    progressive_global: u32,
    differential_lost: u32,
    footprint_appends: u32,
    photon_appends: u32,
    footprint_overflowed: u32,
    photon_overflowed: u32,
    pad: u32,
}

// StoreParams of store.wgsl (112 bytes), with the heuristics as plain words: this kernel
// writes only the two counts.
struct ArpaScheduleStoreParams {
    heuristics: array<u32, 12>,
    radii: vec2<f32>,
    pad0: vec2<f32>,
    scene_lo: vec3<f32>,
    raw_count: u32,
    scene_inv: vec3<f32>,
    photon_count: u32,
    fp_sorted: u32,
    ph_sorted: u32,
    pad1: vec2<u32>,
}

@group(0) @binding(0) var<storage, read> schedule_counters: ArpaScheduleCounters;
@group(0) @binding(1) var<storage, read_write> schedule_params: ArpaScheduleStoreParams;
@group(0) @binding(2) var<storage, read_write> schedule_args: array<u32, 6>;
@group(0) @binding(3) var<storage, read_write> schedule_status: array<u32, 4>;
@group(0) @binding(4) var<storage, read> schedule_store_counts: array<u32, 12>;

// Workgroups (x, y, 1) of a linear dispatch of `invocations` invocations of a 64-wide kernel.
fn arpa_linear_groups(invocations: u32) -> vec3<u32> {
    let groups = max((invocations + 63u) / 64u, 1u);
    if groups <= 65535u {
        return vec3<u32>(groups, 1u, 1u);
    }
    return vec3<u32>(32768u, (groups + 32767u) / 32768u, 1u);
}

@compute @workgroup_size(1)
fn store_schedule() {
    let raw = schedule_counters.footprint_appends - schedule_counters.footprint_overflowed;
    let photons = schedule_counters.photon_appends - schedule_counters.photon_overflowed;
    schedule_params.raw_count = raw;
    schedule_params.photon_count = photons;
    let keyed = arpa_linear_groups(raw);
    let keys = arpa_linear_groups(photons);
    schedule_args[0] = keyed.x;
    schedule_args[1] = keyed.y;
    schedule_args[2] = keyed.z;
    schedule_args[3] = keys.x;
    schedule_args[4] = keys.y;
    schedule_args[5] = keys.z;
    if schedule_counters.footprint_overflowed + schedule_counters.photon_overflowed > 0u {
        schedule_status[0] = 1u;
    }
}

@compute @workgroup_size(1)
fn store_check() {
    // StoreCounts::overflowed (word 7).
    if schedule_store_counts[7] > 0u {
        schedule_status[0] = 1u;
    }
}
