// Running mean of the iteration images on the device: per pixel an f32 sum with Neumaier
// compensation (arpa_core::accumulate::image::RunningMean, in f32) and the count of rejected
// (non-finite) samples; the host divides by the iteration count when it reads the mean.
// A non-finite sample counts as an iteration that contributed 0, as in the core. Needs
// math.wgsl.

// arpa_core::gpu::layout::AccumPixel (32 bytes).
struct AccumPixel {
    sum: vec3<f32>,           // W/(m^2 sr) summed over iterations
    rejected: u32,            // non-finite samples
    compensation: vec3<f32>,  // Neumaier compensation of `sum`
    pad: u32,
}

@group(0) @binding(0) var<storage, read> acc_image: array<vec4<f32>>;
@group(0) @binding(1) var<storage, read_write> acc_pixels: array<AccumPixel>;
// The iteration's status word (schedule.wgsl): non-zero when its photon pass dropped
// records; the sums are then left as they are (the host traces the iteration again).
@group(0) @binding(2) var<storage, read> acc_status: array<u32, 4>;

@compute @workgroup_size(64)
fn accumulate(@builtin(global_invocation_id) gid: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>) {
    let i = gid.x + gid.y * groups.x * 64u;
    if i >= arrayLength(&acc_pixels) || acc_status[0] != 0u {
        return;
    }
    let x = acc_image[i].xyz;
    var p = acc_pixels[i];
    if !(arpa_finite(x.x) && arpa_finite(x.y) && arpa_finite(x.z)) {
        p.rejected += 1u;
        acc_pixels[i] = p;
        return;
    }
    for (var c = 0; c < 3; c++) {
        let s = p.sum[c];
        let t = s + x[c];
        if abs(s) >= abs(x[c]) {
            p.compensation[c] += (s - t) + x[c];
        } else {
            p.compensation[c] += (x[c] - t) + s;
        }
        p.sum[c] = t;
    }
    acc_pixels[i] = p;
}
