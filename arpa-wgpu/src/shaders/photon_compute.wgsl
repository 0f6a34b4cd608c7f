// arpa-wgpu's entry point of arpa-core's path/photon_pass.wgsl: one compute invocation per
// photon of the batch (64-wide workgroups over a 2D grid, linearised). Each workgroup sums
// its photons and segments in workgroup memory and adds them to the counters once.

var<workgroup> photon_wg_emitted: atomic<u32>;
var<workgroup> photon_wg_segments: atomic<u32>;

@compute @workgroup_size(64)
fn photon_pass(@builtin(global_invocation_id) gid: vec3<u32>, @builtin(local_invocation_index) lid: u32,
               @builtin(num_workgroups) groups: vec3<u32>) {
    // Local index within the batch; the photon's global index (its random stream, emitter
    // and record keys) is first_photon + local, so a batch traces exactly the photons a
    // single pass over the iteration would at those indices.
    let local = gid.x + gid.y * groups.x * 64u;
    if local < photon_params.photon_count {
        let segments = photon_trace(photon_params.first_photon + local);
        atomicAdd(&photon_wg_emitted, 1u);
        atomicAdd(&photon_wg_segments, segments);
    }
    workgroupBarrier();
    if lid == 0u {
        atomicAdd(&photon_counters.emitted, atomicLoad(&photon_wg_emitted));
        atomicAdd(&photon_counters.segments, atomicLoad(&photon_wg_segments));
    }
}
