// arpa-wgpu's entry point of arpa-core's path/camera_pass.wgsl: one compute invocation per
// pixel (64-wide workgroups, row_invocations per row of the grid) writes the pixel's query
// record.

@compute @workgroup_size(64)
fn arpa_camera_main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let c = arpa_camera;
    let pixel = gid.x + gid.y * c.row_invocations;
    if gid.x >= c.row_invocations || pixel >= c.pixel_count {
        return;
    }
    arpa_camera_queries[pixel] = arpa_camera_trace(pixel);
}
