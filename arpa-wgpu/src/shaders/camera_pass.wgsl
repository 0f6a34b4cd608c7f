// The camera pass: one invocation per pixel traces the camera path of
// arpa_core::camera_path::trace_camera_path in f32 and writes its QueryRecord.
// Needs, before it: `enable wgpu_ray_query;`, rng.wgsl, frame.wgsl, sampling.wgsl,
// lambertian.wgsl (arpa_core::shaders) and scene.wgsl (group 0). Group 1: the pass's
// parameters and the query records. Units: metres, world space; radiance W/(m^2 sr).

const ARPA_CAMERA_FRAC_1_PI: f32 = 0.31830988618379067;
// Ray extent of camera rays: the core casts them to infinity.
const ARPA_CAMERA_T_MAX: f32 = 3.4028235e38;

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

// arpa_core::tracer::QueryRecord (48 bytes).
struct ArpaQueryRecord {
    position: vec3<f32>,
    pixel: u32,
    normal: vec3<f32>,
    valid: u32,
    weight: vec3<f32>,
    pad0: u32,
    radiance: vec3<f32>,
    pad1: u32,
}

@group(1) @binding(0) var<uniform> arpa_camera: ArpaCameraParams;
@group(1) @binding(1) var<storage, read_write> arpa_camera_queries: array<ArpaQueryRecord>;

fn arpa_camera_finite(x: f32) -> bool {
    return (bitcast<u32>(x) & 0x7f800000u) != 0x7f800000u;
}

// The core's `(word as f64 / 2^32) as f32`: the draw rounded to the nearest f32 (ties to
// even), in integer arithmetic so that no conversion rounding mode is assumed.
fn arpa_camera_unit_f32(word: u32) -> f32 {
    if word < 0x01000000u {
        return f32(word) * 2.3283064365386963e-10;
    }
    let drop = 8u - countLeadingZeros(word);
    var m = word >> drop;
    let rem = word & ((1u << drop) - 1u);
    let half = 1u << (drop - 1u);
    if rem > half || (rem == half && (m & 1u) == 1u) {
        m += 1u;
    }
    return ldexp(f32(m), i32(drop) - 32);
}

// v / |v| as glam's Vec3::normalize_or (times the reciprocal length), or `fallback`.
fn arpa_camera_normalize_or(v: vec3<f32>, fallback: vec3<f32>) -> vec3<f32> {
    let rcp = 1.0 / length(v);
    if arpa_camera_finite(rcp) && rcp > 0.0 {
        return v * rcp;
    }
    return fallback;
}

// CameraFrame::direction through film position (x, y) in pixels.
fn arpa_camera_direction(x: f32, y: f32) -> vec3<f32> {
    let c = arpa_camera;
    let sx = (2.0 * x / f32(c.width) - 1.0) * c.tan_half_fov * c.aspect;
    let sy = (1.0 - 2.0 * y / f32(c.height)) * c.tan_half_fov;
    return arpa_camera_normalize_or(c.forward + c.right * sx + c.up * sy, c.forward);
}

// fresnel::dielectric_reflectance: reflected fraction for cos_i = d.n (either sign; < 0
// arriving from outside) and ior = inside over outside; 1 under total internal reflection.
fn arpa_camera_fresnel(cos_i: f32, ior: f32) -> f32 {
    if !(ior > 0.0) || !arpa_camera_finite(ior) || !arpa_camera_finite(cos_i) {
        return 1.0;
    }
    let eta = select(ior, 1.0 / ior, cos_i < 0.0);
    let ci = min(abs(cos_i), 1.0);
    let sin_t2 = eta * eta * (1.0 - ci * ci);
    if sin_t2 >= 1.0 {
        return 1.0;
    }
    let ct = sqrt(1.0 - sin_t2);
    let rs = (eta * ci - ct) / (eta * ci + ct);
    let rp = (ci - eta * ct) / (ci + eta * ct);
    return clamp(0.5 * (rs * rs + rp * rp), 0.0, 1.0);
}

// differential::refract_direction: the refracted unit direction, whether it was
// transmitted (else total internal reflection: the mirror direction) and eta = n_i / n_t.
struct ArpaCameraRefraction {
    dir: vec3<f32>,
    transmitted: bool,
    eta: f32,
}

fn arpa_camera_reflect(d: vec3<f32>, n: vec3<f32>) -> vec3<f32> {
    return d - 2.0 * dot(d, n) * n;
}

fn arpa_camera_refract(d: vec3<f32>, n_in: vec3<f32>, ior: f32) -> ArpaCameraRefraction {
    var n = n_in;
    var eta = 1.0 / ior;
    if dot(d, n_in) > 0.0 {
        n = -n_in;
        eta = ior;
    }
    if !(eta > 0.0) || !arpa_camera_finite(eta) {
        return ArpaCameraRefraction(d, true, 1.0);
    }
    let cos_i = dot(d, n);
    let k = 1.0 - eta * eta * (1.0 - cos_i * cos_i);
    if k < 0.0 {
        return ArpaCameraRefraction(arpa_camera_reflect(d, n), false, eta);
    }
    let mu = eta * cos_i + sqrt(k);
    return ArpaCameraRefraction(arpa_camera_normalize_or(eta * d - mu * n, d), true, eta);
}

// Whether the segment from `origin` to `to` is unoccluded (the core's shadow ray: up to
// 1 - 1e-4 of the distance).
fn arpa_camera_visible(origin: vec3<f32>, to: vec3<f32>) -> bool {
    let d = to - origin;
    let dist = length(d);
    return dist > 0.0 && !arpa_scene_occluded(origin, d / dist, dist * (1.0 - 1e-4));
}

// asin(x) for |x| <= 0.5 by its Taylor series to x^21 (truncation below 1.2e-9, under the
// f32 rounding), Horner in x^2: the coefficients are (2k)! / (4^k k!^2 (2k + 1)).
fn arpa_camera_asin_small(x: f32) -> f32 {
    let z = x * x;
    var p = 0.008390335809616815;
    p = p * z + 0.009761609529194078;
    p = p * z + 0.011551800896139705;
    p = p * z + 0.01396484375;
    p = p * z + 0.017352764423076924;
    p = p * z + 0.022372159090909092;
    p = p * z + 0.030381944444444444;
    p = p * z + 0.044642857142857144;
    p = p * z + 0.075;
    p = p * z + 0.16666666666666666;
    return x + x * z * p;
}

// acos(x) for x in [-1, 1] to a few f32 ulps (the device's built-in acos may be far less
// accurate: Vulkan allows thousands of ulps, and lavapipe's differs from the core's libm
// acos by ~1e-4 rad). Half-angle reduction outside |x| <= 0.5.
fn arpa_camera_acos(x: f32) -> f32 {
    if x > 0.5 {
        return 2.0 * arpa_camera_asin_small(sqrt(0.5 * (1.0 - x)));
    }
    if x < -0.5 {
        return 3.141592653589793 - 2.0 * arpa_camera_asin_small(sqrt(0.5 * (1.0 + x)));
    }
    return 1.5707963267948966 - arpa_camera_asin_small(x);
}

// spot falloff f(theta) (SpotLight::falloff_at).
fn arpa_camera_spot_falloff(e: ArpaSceneEmitter, theta: f32) -> f32 {
    if theta <= e.beam_width {
        return 1.0;
    }
    if theta >= e.cutoff {
        return 0.0;
    }
    let x = (e.cutoff - theta) / (e.cutoff - e.beam_width);
    if e.falloff == 1u {
        return x * x * (3.0 - 2.0 * x);
    }
    return x;
}

// camera_path::direct_irradiance (W/m^2, RGB) at the diffuse point s in the shading frame sh:
// every delta light exactly, then one area emitter picked by power with one sampled point.
fn arpa_camera_direct(s: ArpaSurface, sh: ArpaDiffuseShading, rng: ptr<function, ArpaRng>) -> vec3<f32> {
    let p = s.position;
    let shadow_origin = arpa_offset_origin(p, sh.geometric);
    var e = vec3<f32>(0.0);
    let info = arpa_scene_info;
    for (var i = 0u; i < info.delta_count; i++) {
        let l = arpa_scene_emitters[i];
        if l.kind == ARPA_EMITTER_DIRECTIONAL {
            let to_light = -l.p0;
            let cos = arpa_diffuse_cosine(sh, to_light);
            let far = p + to_light * (4.0 * info.sphere_radius + 1.0);
            if cos > 0.0 && arpa_camera_visible(shadow_origin, far) {
                e += l.color * cos;
            }
        } else {
            let d = l.p0 - p;
            let r2 = dot(d, d);
            let r = sqrt(r2);
            let cos = arpa_diffuse_cosine(sh, d / r);
            var falloff = 1.0;
            if l.kind == ARPA_EMITTER_SPOT {
                falloff = arpa_camera_spot_falloff(l, arpa_camera_acos(clamp(dot(-d / r, l.p1), -1.0, 1.0)));
            }
            if cos > 0.0 && falloff > 0.0 && arpa_camera_visible(shadow_origin, l.p0) {
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
    if l.kind == ARPA_EMITTER_TRIANGLE {
        let b = arpa_uniform_triangle(sample);
        n = cross(l.p1 - l.p0, l.p2 - l.p0);
        point = l.p0 * b.x + l.p1 * b.y + l.p2 * b.z;
        area = 0.5 * length(n);
    } else {
        n = cross(l.p1, l.p2);
        point = l.p0 + l.p1 * sample.x + l.p2 * sample.y;
        area = length(n);
    }
    let normal = arpa_camera_normalize_or(n, vec3<f32>(0.0, 1.0, 0.0));
    let d = point - p;
    let r2 = dot(d, d);
    let r = sqrt(r2);
    if r > 0.0 {
        let cos_q = arpa_diffuse_cosine(sh, d / r);
        let cos_l = -dot(normal, d) / r;
        if cos_q > 0.0 && cos_l > 0.0 && l.probability > 0.0 && arpa_camera_visible(shadow_origin, point) {
            e += l.color * (cos_q * cos_l * area / (r2 * l.probability));
        }
    }
    return e;
}

@compute @workgroup_size(64)
fn arpa_camera_main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let c = arpa_camera;
    let pixel = gid.x + gid.y * c.row_invocations;
    if gid.x >= c.row_invocations || pixel >= c.pixel_count {
        return;
    }
    var rng = arpa_rng_new(c.seed, c.iteration, pixel, ARPA_DOMAIN_CAMERA);
    let px = pixel % c.width;
    let py = pixel / c.width;
    let jx = arpa_camera_unit_f32(arpa_rng_next_u32(&rng));
    let jy = arpa_camera_unit_f32(arpa_rng_next_u32(&rng));
    var dir = arpa_camera_direction(f32(px) + jx, f32(py) + jy);
    var origin = c.position;
    var throughput = vec3<f32>(1.0);
    var radiance = vec3<f32>(0.0);
    var rec = ArpaQueryRecord(vec3<f32>(0.0), pixel, vec3<f32>(0.0), 0u, vec3<f32>(0.0), 0u, vec3<f32>(0.0), 0u);
    for (var depth = 0u; depth < c.max_depth; depth++) {
        let h = arpa_scene_intersect(origin, dir, ARPA_CAMERA_T_MAX);
        if h.hit == 0u {
            break;
        }
        let s = arpa_scene_surface(h);
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
            dir = arpa_camera_normalize_or(arpa_camera_reflect(dir, n), dir);
            origin = arpa_offset_origin(s.position, front);
        } else {
            let fresnel = arpa_camera_fresnel(dot(dir, n), s.ior);
            if arpa_rng_next_f32(&rng) < fresnel {
                dir = arpa_camera_normalize_or(arpa_camera_reflect(dir, n), dir);
                origin = arpa_offset_origin(s.position, front);
            } else {
                let t = arpa_camera_refract(dir, n, s.ior);
                if t.transmitted {
                    throughput *= s.color * (t.eta * t.eta);
                    origin = arpa_offset_origin(s.position, -front);
                } else {
                    origin = arpa_offset_origin(s.position, front);
                }
                dir = t.dir;
            }
        }
        if !(max(throughput.x, max(throughput.y, throughput.z)) > 0.0) {
            break;
        }
    }
    let finite = (bitcast<vec3<u32>>(radiance) & vec3<u32>(0x7f800000u)) != vec3<u32>(0x7f800000u);
    rec.radiance = select(vec3<f32>(0.0), radiance, finite);
    arpa_camera_queries[pixel] = rec;
}
