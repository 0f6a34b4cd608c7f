// The camera pass: per pixel, arpa_camera_trace traces the camera path of
// arpa_core::render::camera_path::trace_camera_path in f32 and gives its QueryRecord, which the
// backend's entry point (one invocation per pixel; arpa-wgpu: compute, arpa-vk: ray
// generation) writes to arpa_camera_queries. Group 0: the
// scene (scene.wgsl, with the backend's arpa_scene_intersect / arpa_scene_occluded); group
// 1: the pass's parameters and the query records. Units: metres, world space; radiance
// W/(m^2 sr).

const ARPA_CAMERA_FRAC_1_PI: f32 = 0.31830988618379067;

// arpa_core::gpu::layout::CameraParams (uniform, 96 bytes).
struct ArpaCameraParams {
    // Eye position (metres).
    position: vec3<f32>,
    width: u32,
    // CameraFrame: unit forward, right, up; tan(fov/2); width over height.
    forward: vec3<f32>,
    height: u32,
    right: vec3<f32>,
    tan_half_fov: f32,
    up: vec3<f32>,
    aspect: f32,
    seed: u32,
    // 0-based iteration.
    iteration: u32,
    max_depth: u32,
    // 1: next-event estimation at the query point.
    direct_lighting: u32,
    // width * height.
    pixel_count: u32,
    // Invocations per row of the dispatch grid (workgroups in x times 64).
    row_invocations: u32,
    pad0: u32,
    pad1: u32,
}

@group(1) @binding(0) var<uniform> arpa_camera: ArpaCameraParams;
@group(1) @binding(1) var<storage, read_write> arpa_camera_queries: array<ArpaQueryRecord>;

// CameraFrame::direction through film position (x, y) in pixels.
fn arpa_camera_direction(x: f32, y: f32) -> vec3<f32> {
    let c = arpa_camera;
    let sx = (2.0 * x / f32(c.width) - 1.0) * c.tan_half_fov * c.aspect;
    let sy = (1.0 - 2.0 * y / f32(c.height)) * c.tan_half_fov;
    return arpa_glam_normalize_or(c.forward + c.right * sx + c.up * sy, c.forward);
}

// Whether the segment from `start` to `to` is unoccluded (the core's shadow ray: up to
// 1 - 1e-4 of the distance), masks passed with draws from the path's stream.
fn arpa_camera_visible(start: ArpaRayStart, to: vec3<f32>, rng: ptr<function, ArpaRng>) -> bool {
    let d = to - start.origin;
    let dist = length(d);
    return dist > 0.0 && !arpa_scene_occluded_masked(start, d / dist, dist * (1.0 - 1e-4), rng);
}

// Environment::radiance (W/(m^2 sr), RGB) arriving from unit world direction d: the
// environment emitter's, zero without one.
fn arpa_camera_environment_radiance(d: vec3<f32>) -> vec3<f32> {
    for (var i = 0u; i < arpa_scene_info.delta_count; i++) {
        let l = arpa_scene_emitters[i];
        if l.kind == ARPA_LIGHT_ENVIRONMENT {
            if l.emission_record != ARPA_NO_TEXTURE {
                return l.color * arpa_env_value(l.emission_record, d);
            }
            return l.color;
        }
    }
    return vec3<f32>(0.0);
}

// Environment::irradiance of the environment emitter l at the diffuse point p in the
// shading frame sh: a constant environment by its cosine-weighted draw about the shading
// normal alone (the second 2-D draw is drawn and not used), a map by that draw and one
// from the map under the balance heuristic.
fn arpa_camera_environment(l: ArpaSceneEmitter, p: vec3<f32>, shadow_origin: ArpaRayStart, sh: ArpaDiffuseShading, rng: ptr<function, ArpaRng>) -> vec3<f32> {
    let cosine = arpa_rng_next_2d(rng);
    let light = arpa_rng_next_2d(rng);
    let n = sh.shading;
    let f = arpa_frame_from_normal(n);
    let by_cosine = arpa_frame_normalize_or(arpa_frame_to_world(f, arpa_cosine_hemisphere(cosine)), n);
    let far = 4.0 * arpa_scene_info.sphere_radius + 1.0;
    let r = l.emission_record;
    if r == ARPA_NO_TEXTURE {
        let cos = arpa_diffuse_cosine(sh, by_cosine);
        let pdf = max(dot(by_cosine, n), 0.0) * ARPA_CAMERA_FRAC_1_PI;
        if cos > 0.0 && pdf > 0.0 && arpa_camera_visible(shadow_origin, p + by_cosine * far, rng) {
            return l.color * (cos / pdf);
        }
        return vec3<f32>(0.0);
    }
    let by_light = arpa_env_sample(r, light).xyz;
    var e = vec3<f32>(0.0);
    for (var k = 0u; k < 2u; k++) {
        let d = select(by_light, by_cosine, k == 0u);
        let cos = arpa_diffuse_cosine(sh, d);
        if cos > 0.0 {
            let pdf = max(dot(d, n), 0.0) * ARPA_CAMERA_FRAC_1_PI + arpa_env_pdf(r, d);
            if pdf > 0.0 && arpa_camera_visible(shadow_origin, p + d * far, rng) {
                e += l.color * arpa_env_value(r, d) * (cos / pdf);
            }
        }
    }
    return e;
}

// camera_path::direct_irradiance (W/m^2, RGB) at the diffuse point s in the shading frame sh:
// every delta light exactly, then one area emitter picked by power with one sampled point.
fn arpa_camera_direct(s: ArpaSurface, sh: ArpaDiffuseShading, rng: ptr<function, ArpaRng>) -> vec3<f32> {
    let p = s.position;
    let shadow_origin = arpa_ray_start_leaving(s);
    var e = vec3<f32>(0.0);
    let info = arpa_scene_info;
    for (var i = 0u; i < info.delta_count; i++) {
        let l = arpa_scene_emitters[i];
        if l.kind == ARPA_LIGHT_ENVIRONMENT {
            e += arpa_camera_environment(l, p, shadow_origin, sh, rng);
        } else if l.kind == ARPA_LIGHT_DIRECTIONAL {
            let to_light = -l.p0;
            let cos = arpa_diffuse_cosine(sh, to_light);
            let far = p + to_light * (4.0 * info.sphere_radius + 1.0);
            if cos > 0.0 && arpa_camera_visible(shadow_origin, far, rng) {
                e += l.color * cos;
            }
        } else {
            let d = l.p0 - p;
            let r2 = dot(d, d);
            let r = sqrt(r2);
            let cos = arpa_diffuse_cosine(sh, d / r);
            var falloff = 1.0;
            if l.kind == ARPA_LIGHT_SPOT {
                let theta = arpa_angle_between(-d / r, l.p1);
                falloff = arpa_spot_falloff_at(theta, l.beam_width, l.cutoff, l.falloff);
            }
            if cos > 0.0 && falloff > 0.0 && arpa_camera_visible(shadow_origin, l.p0, rng) {
                e += l.color * (falloff * cos / r2);
            }
        }
    }
    let u = arpa_rng_next_f32(rng);
    let sample = arpa_rng_next_2d(rng);
    if info.area_count == 0u {
        return e;
    }
    // PreparedScene::pick_area_emitter: the first entry whose cumulative power exceeds u.
    var lo = 0u;
    var hi = info.area_count;
    while lo < hi {
        let mid = (lo + hi) / 2u;
        if arpa_scene_emitters[info.delta_count + mid].cdf <= u {
            lo = mid + 1u;
        } else {
            hi = mid;
        }
    }
    let l = arpa_scene_emitters[info.delta_count + min(lo, info.area_count - 1u)];
    var point: vec3<f32>;
    var n: vec3<f32>;
    var area: f32;
    var radiance = l.color;
    if l.kind == ARPA_LIGHT_TRIANGLE {
        let b = arpa_uniform_triangle(sample);
        n = cross(l.p1 - l.p0, l.p2 - l.p0);
        point = l.p0 * b.x + l.p1 * b.y + l.p2 * b.z;
        area = 0.5 * length(n);
        // A textured emitter's radiance at the sampled point.
        if l.emission_record != ARPA_NO_TEXTURE {
            radiance *= arpa_emitter_texture_factor(l.emission_record, b.y, b.z);
        }
    } else {
        n = cross(l.p1, l.p2);
        point = l.p0 + l.p1 * sample.x + l.p2 * sample.y;
        area = length(n);
    }
    let normal = arpa_glam_normalize_or(n, vec3<f32>(0.0, 1.0, 0.0));
    let d = point - p;
    let r2 = dot(d, d);
    let r = sqrt(r2);
    if r > 0.0 {
        let cos_q = arpa_diffuse_cosine(sh, d / r);
        let cos_l = -dot(normal, d) / r;
        if cos_q > 0.0 && cos_l > 0.0 && l.probability > 0.0 && arpa_camera_visible(shadow_origin, point, rng) {
            e += radiance * (cos_q * cos_l * area / (r2 * l.probability));
        }
    }
    return e;
}

// The query record of pixel `pixel` (< pixel_count) of this iteration.
fn arpa_camera_trace(pixel: u32) -> ArpaQueryRecord {
    let c = arpa_camera;
    var rng = arpa_rng_new(c.seed, c.iteration, pixel, ARPA_DOMAIN_CAMERA);
    let px = pixel % c.width;
    let py = pixel / c.width;
    let jx = arpa_rng_next_f64_as_f32(&rng);
    let jy = arpa_rng_next_f64_as_f32(&rng);
    var dir = arpa_camera_direction(f32(px) + jx, f32(py) + jy);
    var start = arpa_ray_start_at(c.position);
    var throughput = vec3<f32>(1.0);
    var radiance = vec3<f32>(0.0);
    var rec = ArpaQueryRecord(vec3<f32>(0.0), pixel, vec3<f32>(0.0), 0u, vec3<f32>(0.0), 0u, vec3<f32>(0.0), 0u);
    for (var depth = 0u; depth < c.max_depth; depth++) {
        var passed = vec3<f32>(0.0);
        let h = arpa_scene_intersect_seen(start, dir, ARPA_SCENE_T_MAX, &rng, &passed);
        radiance += throughput * passed;
        if h.hit == 0u {
            radiance += throughput * arpa_camera_environment_radiance(dir);
            break;
        }
        var s = arpa_scene_surface(h);
        _ = arpa_scene_choose_blend(&s, &rng);
        let facing = dot(dir, s.geometric_normal) < 0.0;
        let front = select(-s.geometric_normal, s.geometric_normal, facing);
        if s.emissive != 0u && facing {
            radiance += throughput * s.emission;
        }
        if s.kind == ARPA_SCATTER_DIFFUSE {
            // Mitsuba's two-sided diffuse lobe in the shading frame: zero for a viewer in
            // the shading plane.
            let sh = arpa_diffuse_shading_new(front, s.shading_normal, -dir);
            var weight = vec3<f32>(0.0);
            if sh.valid != 0u {
                weight = throughput * s.color * ARPA_CAMERA_FRAC_1_PI;
                if c.direct_lighting != 0u {
                    radiance += weight * arpa_camera_direct(s, sh, &rng);
                }
            }
            rec.position = s.position;
            // Flipped where the viewer is below the shading plane (the gather's side test).
            let below = sh.valid != 0u && arpa_diffuse_below_shading_plane(sh);
            rec.normal = select(front, -front, below);
            rec.weight = weight;
            rec.valid = 1u;
            break;
        }
        let n = s.specular_normal;
        if s.kind == ARPA_SCATTER_MIRROR {
            throughput *= s.color;
            dir = arpa_glam_normalize_or(arpa_reflect_direction(dir, n), dir);
            start = arpa_ray_start_leaving(s);
        } else if s.kind == ARPA_SCATTER_THIN {
            // A thin sheet reflects with its total reflectance, else passes straight on.
            if arpa_rng_next_below(&rng, arpa_thin_sheet_reflectance(dot(dir, n), s.ior)) {
                dir = arpa_glam_normalize_or(arpa_reflect_direction(dir, n), dir);
            } else {
                throughput *= s.color;
            }
            start = arpa_ray_start_leaving(s);
        } else {
            let fresnel = arpa_dielectric_reflectance(dot(dir, n), s.ior);
            // The core's `rng.next_f64() < fresnel`, exactly (rng.wgsl).
            if arpa_rng_next_below(&rng, fresnel) {
                dir = arpa_glam_normalize_or(arpa_reflect_direction(dir, n), dir);
                start = arpa_ray_start_leaving(s);
            } else {
                let t = arpa_refract_direction(dir, n, s.ior);
                if t.event == ARPA_REFRACTION_TRANSMITTED {
                    throughput *= s.color * (t.eta * t.eta);
                    start = arpa_ray_start_leaving(s);
                } else {
                    start = arpa_ray_start_leaving(s);
                }
                dir = t.dir;
            }
        }
        if !(max(throughput.x, max(throughput.y, throughput.z)) > 0.0) {
            break;
        }
    }
    let finite = vec3<bool>(arpa_finite(radiance.x), arpa_finite(radiance.y), arpa_finite(radiance.z));
    rec.radiance = select(vec3<f32>(0.0), radiance, finite);
    return rec;
}
