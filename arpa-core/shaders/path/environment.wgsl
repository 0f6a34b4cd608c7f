// WGSL twin of arpa_core::render::environment for an environment map in the texture words
// (arpa_core::gpu::texture: the environment record at word r, its texels and sampling
// tables): the map's value in a direction, its sampling density, a direction drawn from
// it, and an environment photon drawn by it (PreparedLight::emit_environment_in with
// Environment::photon_direction). Needs math.wgsl, texture.wgsl (and the includer's
// arpa_texture_word), frame.wgsl, sampling.wgsl, differential.wgsl and emission.wgsl.
//
// Precision: f32 throughout; the tables are the core's f64 tables rounded to f32, so a
// draw near a table step may land in the neighbouring patch (the conformance suite
// compares images, not draws).

const ARPA_ENV_PI: f32 = 3.14159265358979;

// Rows of the map's patches: max(H - 1, 1).
fn arpa_env_patch_rows(r: u32) -> u32 {
    return max(arpa_texture_word(r + 1u), 2u) - 1u;
}

// A column-major 3x3 matrix at word `at`.
fn arpa_env_mat3(at: u32) -> mat3x3<f32> {
    return mat3x3<f32>(arpa_texture_vec3(at), arpa_texture_vec3(at + 3u), arpa_texture_vec3(at + 6u));
}

// The map's texel (i mod W, min(j, H - 1)), linear RGB.
fn arpa_env_texel(r: u32, i: u32, j: u32) -> vec3<f32> {
    let w = arpa_texture_word(r);
    let h = arpa_texture_word(r + 1u);
    return arpa_texture_vec3(arpa_texture_word(r + 2u) + 3u * (min(j, h - 1u) * w + i % w));
}

// MapTables::eval_uv: bilinear with Mitsuba's grid (columns at (i + 1/2)/W, periodic; rows
// at t = j/(H - 1)).
fn arpa_env_eval_uv(r: u32, uv: vec2<f32>) -> vec3<f32> {
    let w = arpa_texture_word(r);
    let h = arpa_texture_word(r + 1u);
    let x = uv.x * f32(w) - 0.5;
    let x0 = floor(x);
    let fx = x - x0;
    let i = u32(i32(x0) - i32(w) * i32(floor(x0 / f32(w))));
    var y = 0.0;
    if h > 1u {
        y = clamp(uv.y * f32(h - 1u), 0.0, f32(h - 1u));
    }
    let j = min(u32(floor(y)), max(h, 2u) - 2u);
    let fy = y - f32(j);
    let top = arpa_env_texel(r, i, j) * (1.0 - fx) + arpa_env_texel(r, i + 1u, j) * fx;
    let bottom = arpa_env_texel(r, i, j + 1u) * (1.0 - fx) + arpa_env_texel(r, i + 1u, j + 1u) * fx;
    return top * (1.0 - fy) + bottom * fy;
}

// MapTables::uv of the unit world direction d (towards the environment).
fn arpa_env_uv(r: u32, d: vec3<f32>) -> vec2<f32> {
    let v = arpa_glam_normalize_or(arpa_env_mat3(r + 15u) * d, vec3<f32>(0.0, 1.0, 0.0));
    var u = atan2(v.x, -v.z) / (2.0 * ARPA_ENV_PI);
    if u < 0.0 {
        u += 1.0;
    }
    return vec2<f32>(min(u, 1.0), acos(clamp(v.y, -1.0, 1.0)) / ARPA_ENV_PI);
}

// MapTables::direction of (u, t).
fn arpa_env_direction(r: u32, u: f32, t: f32) -> vec3<f32> {
    let st = sin(ARPA_ENV_PI * t);
    let ct = cos(ARPA_ENV_PI * t);
    let sp = sin(2.0 * ARPA_ENV_PI * u);
    let cp = cos(2.0 * ARPA_ENV_PI * u);
    return arpa_glam_normalize_or(arpa_env_mat3(r + 6u) * vec3<f32>(st * sp, ct, -st * cp), vec3<f32>(0.0, 1.0, 0.0));
}

// The map's value (no scale) arriving from unit world direction d.
fn arpa_env_value(r: u32, d: vec3<f32>) -> vec3<f32> {
    return arpa_env_eval_uv(r, arpa_env_uv(r, d));
}

// MapTables::pdf: the density (1/sr) of arpa_env_sample drawing d.
fn arpa_env_pdf(r: u32, d: vec3<f32>) -> f32 {
    let uv = arpa_env_uv(r, d);
    let w = arpa_texture_word(r);
    let rows = arpa_env_patch_rows(r);
    let x = floor(uv.x * f32(w) - 0.5);
    let i = u32(i32(x) - i32(w) * i32(floor(x / f32(w))));
    let j = min(u32(uv.y * f32(rows)), rows - 1u);
    let s = sin(ARPA_ENV_PI * uv.y);
    if !(s > 0.0) {
        return 0.0;
    }
    return arpa_texture_f32(arpa_texture_word(r + 5u) + j * w + i) / (2.0 * ARPA_ENV_PI * ARPA_ENV_PI * s);
}

// The first entry of the n-entry CDF at word `at` that exceeds x (the last for x >= all).
fn arpa_env_search(at: u32, n: u32, x: f32) -> u32 {
    var lo = 0u;
    var hi = n;
    while lo < hi {
        let mid = (lo + hi) / 2u;
        if arpa_texture_f32(at + mid) <= x {
            lo = mid + 1u;
        } else {
            hi = mid;
        }
    }
    return min(lo, n - 1u);
}

// MapTables::sample: a direction drawn from the unit-square sample s (xyz) and its density
// (w, 1/sr).
fn arpa_env_sample(r: u32, s: vec2<f32>) -> vec4<f32> {
    let w = arpa_texture_word(r);
    let rows = arpa_env_patch_rows(r);
    let row_cdf = arpa_texture_word(r + 3u);
    let j = arpa_env_search(row_cdf, rows, s.y);
    var lo = 0.0;
    if j > 0u {
        lo = arpa_texture_f32(row_cdf + j - 1u);
    }
    let fy = clamp((s.y - lo) / (arpa_texture_f32(row_cdf + j) - lo), 0.0, 1.0);
    let col_cdf = arpa_texture_word(r + 4u) + j * w;
    let i = arpa_env_search(col_cdf, w, s.x);
    var lo_x = 0.0;
    if i > 0u {
        lo_x = arpa_texture_f32(col_cdf + i - 1u);
    }
    let fx = clamp((s.x - lo_x) / (arpa_texture_f32(col_cdf + i) - lo_x), 0.0, 1.0);
    var u = (f32(i) + 0.5 + fx) / f32(w);
    if u >= 1.0 {
        u -= 1.0;
    }
    let d = arpa_env_direction(r, u, (f32(j) + fy) / f32(rows));
    return vec4<f32>(d, arpa_env_pdf(r, d));
}

// An environment photon drawn by the map (PreparedLight::emit_environment_in with
// Environment::photon_direction): its direction from the photon's first 2-D draw, its flux
// times m(w) / (4 pi p(w) mean) (the mean from the record).
fn arpa_env_emit(light: ArpaLight, index: u32, rng: ptr<function, ArpaRng>, r: u32) -> ArpaEmitted {
    var out: ArpaEmitted;
    out.reemission_length = light.len_reemission;
    out.has_surface_normal = 0u;
    out.surface_normal = vec3<f32>(0.0);
    let u = arpa_fibonacci_lattice(index, light.photon_count, light.lattice_shift);
    let sampled = arpa_env_sample(r, arpa_rng_next_2d(rng));
    let towards = sampled.xyz;
    let mean = arpa_texture_vec3(r + 24u);
    var factor = vec3<f32>(0.0);
    if sampled.w > 0.0 {
        factor = arpa_env_value(r, towards) / (4.0 * ARPA_ENV_PI * sampled.w * mean);
    }
    let finite = vec3<bool>(arpa_finite(factor.x), arpa_finite(factor.y), arpa_finite(factor.z));
    out.flux = light.flux * select(vec3<f32>(0.0), factor, finite);
    let res = arpa_environment_ray(light, u, -towards);
    out.ray = res.ray;
    out.status = res.status;
    return out;
}
