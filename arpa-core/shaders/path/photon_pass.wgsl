// Photon pass on the device: photon_trace is the WGSL twin of
// arpa_core::render::photon_path::trace_photon for one photon; the backend's entry point (one
// invocation per photon of a batch; arpa-wgpu: compute, arpa-vk: ray generation) calls it
// for global photon first_photon + local and adds the photon and its segments to
// photon_counters.emitted / .segments. Emission from the iteration's prepared lights
// (arpa_core::emit::emission::PackedLight, lattice shift drawn on the host as PhotonPassSetup does),
// transfer / reflection / refraction of the ray differential (differential.wgsl), Fresnel
// choice, Russian roulette, diffuse store with the adjoint shading-normal ratio and lobe
// re-emission (arpa_core::propagate::lambertian), re-emission with the virtual distance
// (reemission.wgsl), caustic/global classification (arpa_core::propagate::classify), max_depth,
// alpha masks passed as the core passes them (scene.wgsl), textured colours at every hit.
//
// Group 0: the scene (scene.wgsl, with the backend's arpa_scene_intersect).
//
// Outputs (group 1), appended with atomics, each record tagged with the unique key
// photon_index * max_depth + depth (depth = 0-based index of the ray segment that ended at
// the hit), so a later sort by key gives an order independent of the append order:
// * raw footprints (ArpaKeyedFootprint): photons stored as footprints (method arpa,
//   differential intact), with D_u, D_v projected into the tangent plane and already
//   scaled by the map's smoothing factor S_c / S_g; the store (store.wgsl) applies only the
//   heuristics (heuristics.wgsl arpa_store), and turns a rejected footprint into a
//   progressive photon at its centre (arpa_core::store's fallback).
// * progressive photons (ArpaKeyedPhoton): method rtpm, or a lost differential.
// An append beyond a buffer's capacity (its arrayLength) is dropped and counted; nothing is
// written out of bounds.
//
// Precision: f32 (the core: f64). Decisions taken by comparing a random draw with a
// probability (Fresnel choice, Russian roulette) compare the full 32-bit draw with the
// probability exactly as the core's next_f64() < p does (arpa_rng_next_below), so they differ from the core only
// where the f32 probability itself differs (Fresnel: a few eps32; Russian roulette: never,
// the albedo is f32 in both). Directions drawn from 2-D samples use the 24-bit draws of
// rng.wgsl (within 2^-24 of the core's).

// Method (PhotonParams::method; arpa_core::gpu::codes::METHOD_*).
const ARPA_PHOTON_METHOD_ARPA: u32 = 0u;
const ARPA_PHOTON_METHOD_RTPM: u32 = 1u;

// Per-batch parameters (arpa_core::gpu::layout::PhotonParams, uniform, 48 bytes).
struct PhotonParams {
    photon_count: u32,     // photons of this dispatch (the batch)
    iteration: u32,        // 0-based
    seed: u32,
    max_depth: u32,        // surface interactions per photon
    method: u32,           // ARPA_PHOTON_METHOD_*
    direct_lighting: u32,  // 1: first diffuse hits of direct paths are not stored
    emitter_count: u32,
    first_photon: u32,     // global index of the batch's first photon (0: the whole iteration)
    smoothing: vec2<f32>,  // S_c, S_g (dimensionless)
    pad1: vec2<f32>,
}

// Per source (an emitter's global or caustic pass, PhotonPassSetup): its global photon
// range, whether it emits, and whether it is a caustic-pass source (layout::EmitterRange,
// 16 bytes).
struct PhotonEmitterRange {
    first_index: u32,
    count: u32,
    valid: u32,
    caustic_only: u32,
}

// layout::PhotonCounters (48 bytes).
struct PhotonCounters {
    emitted: atomic<u32>,
    segments: atomic<u32>,
    footprints_caustic: atomic<u32>,
    footprints_global: atomic<u32>,
    progressive_caustic: atomic<u32>,
    progressive_global: atomic<u32>,
    differential_lost: atomic<u32>,
    footprint_appends: atomic<u32>,
    photon_appends: atomic<u32>,
    footprint_overflowed: atomic<u32>,
    photon_overflowed: atomic<u32>,
    pad: atomic<u32>,
}

@group(1) @binding(0) var<uniform> photon_params: PhotonParams;
@group(1) @binding(1) var<storage, read> photon_lights: array<ArpaLight>;
@group(1) @binding(2) var<storage, read> photon_ranges: array<PhotonEmitterRange>;
@group(1) @binding(3) var<storage, read_write> photon_footprints: array<ArpaKeyedFootprint>;
@group(1) @binding(4) var<storage, read_write> photon_photons: array<ArpaKeyedPhoton>;
@group(1) @binding(5) var<storage, read_write> photon_counters: PhotonCounters;
// Every source's projection cells (layout::EmitterTables::cells; ArpaLight::cell_first).
@group(1) @binding(6) var<storage, read> photon_cells: array<u32>;

fn photon_max3(v: vec3<f32>) -> f32 {
    return max(v.x, max(v.y, v.z));
}

// A ray without a usable differential (photon_path's lost_differential).
fn photon_lost(p: vec3<f32>, d: vec3<f32>) -> ArpaRayDiff {
    let z = vec3<f32>(0.0);
    return ArpaRayDiff(p, arpa_diff_normalize_or(d, vec3<f32>(0.0, 0.0, 1.0)), z, z, z, z);
}

// PreparedScene::shading_normal: the interpolated unit shading normal with its derivatives
// along dp_du, dp_dv (ShadedTriangle::normal_differential), oriented like the geometric
// normal and turned by the material's normal or bump map; flat (zero derivatives) for
// meshes without vertex normals.
struct PhotonNormal {
    nd: ArpaNormalDiff,
    ok: bool,
}

fn photon_shading_normal(s: ArpaSurface, dp_du: vec3<f32>, dp_dv: vec3<f32>) -> PhotonNormal {
    var out: PhotonNormal;
    let zero = vec3<f32>(0.0);
    out.nd = ArpaNormalDiff(s.geometric_normal, zero, zero);
    out.ok = true;
    if s.mesh_has_normals == 0u {
        // The face normal turned by a normal or bump map (arpa_scene_surface computed it).
        out.nd.n = s.specular_normal;
        return out;
    }
    out.ok = false;
    let p = arpa_scene_triangle_vertices(s.mesh, s.triangle);
    let ns = arpa_scene_triangle_normals(s.mesh, s.triangle);
    let c = cross(p[1] - p[0], p[2] - p[0]);
    let twice_area = arpa_diff_length(c);
    if !(twice_area > 0.0) || !arpa_finite3(vec3<f32>(twice_area)) {
        return out;
    }
    let ng = c / twice_area;
    let g0 = cross(ng, p[2] - p[1]) / twice_area;
    let g1 = cross(ng, p[0] - p[2]) / twice_area;
    let g2 = cross(ng, p[1] - p[0]) / twice_area;
    let b = s.barycentric;
    let m = ns[0] * b.x + ns[1] * b.y + ns[2] * b.z;
    let len = arpa_diff_length(m);
    if !(len > 0.0) || !arpa_finite3(vec3<f32>(len)) {
        return out;
    }
    let n = m / len;
    let dm_u = ns[0] * dot(g0, dp_du) + ns[1] * dot(g1, dp_du) + ns[2] * dot(g2, dp_du);
    let dm_v = ns[0] * dot(g0, dp_dv) + ns[1] * dot(g1, dp_dv) + ns[2] * dot(g2, dp_dv);
    var nd = ArpaNormalDiff(n, (dm_u - n * dot(n, dm_u)) / len, (dm_v - n * dot(n, dm_v)) / len);
    if !arpa_finite3(nd.dn_du) || !arpa_finite3(nd.dn_dv) {
        return out;
    }
    if dot(nd.n, s.geometric_normal) < 0.0 {
        nd = ArpaNormalDiff(-nd.n, -nd.dn_du, -nd.dn_dv);
    }
    // A normal or bump map turns the normal, not its derivatives (PreparedScene::shading_normal):
    // arpa_scene_surface turned the same interpolated normal (up to rounding) already.
    if arpa_scene_meshes[s.mesh].normal_kind != ARPA_NORMAL_MAP_NONE {
        nd.n = s.specular_normal;
    }
    out.nd = nd;
    out.ok = true;
    return out;
}

// Appends a progressive photon (store_progressive): the normal oriented against the
// direction of travel `incoming`, flipped when the photon came from below the shading plane.
fn photon_append_progressive(position: vec3<f32>, normal: vec3<f32>, incoming: vec3<f32>, flux: vec3<f32>,
                             map: u32, below: bool, key: u32) {
    var n = arpa_diff_normalize_or(normal, -arpa_diff_normalize_or(incoming, vec3<f32>(0.0, 0.0, 1.0)));
    if dot(incoming, n) > 0.0 {
        n = -n;
    }
    if below {
        n = -n;
    }
    if map == 0u {
        atomicAdd(&photon_counters.progressive_caustic, 1u);
    } else {
        atomicAdd(&photon_counters.progressive_global, 1u);
    }
    let slot = atomicAdd(&photon_counters.photon_appends, 1u);
    if slot >= arrayLength(&photon_photons) {
        atomicAdd(&photon_counters.photon_overflowed, 1u);
        return;
    }
    photon_photons[slot] = ArpaKeyedPhoton(position, map, n, 0u, flux, 0u, key, 0u, 0u, 0u);
}

// photon_path's store: a raw footprint (method arpa, differential intact; Footprint::from_hit
// with the smoothing of Smoothing::apply) or a progressive photon.
fn photon_store(at: ArpaRayDiff, normal: vec3<f32>, flux: vec3<f32>, map: u32, valid: bool, below: bool, key: u32) {
    if photon_params.method == ARPA_PHOTON_METHOD_RTPM {
        photon_append_progressive(at.p, normal, at.d, flux, map, below, key);
        return;
    }
    let n0 = arpa_diff_normalize_or(normal, vec3<f32>(0.0));
    if !valid || all(n0 == vec3<f32>(0.0)) {
        atomicAdd(&photon_counters.differential_lost, 1u);
        photon_append_progressive(at.p, normal, at.d, flux, map, below, key);
        return;
    }
    let du = at.dp_du - n0 * dot(n0, at.dp_du);
    let dv = at.dp_dv - n0 * dot(n0, at.dp_dv);
    var n = n0;
    if dot(at.d, n0) > 0.0 {
        n = -n0;
    }
    if below {
        n = -n;
    }
    let s = photon_params.smoothing[min(map, 1u)];
    if map == 0u {
        atomicAdd(&photon_counters.footprints_caustic, 1u);
    } else {
        atomicAdd(&photon_counters.footprints_global, 1u);
    }
    let slot = atomicAdd(&photon_counters.footprint_appends, 1u);
    if slot >= arrayLength(&photon_footprints) {
        atomicAdd(&photon_counters.footprint_overflowed, 1u);
        return;
    }
    photon_footprints[slot] = ArpaKeyedFootprint(at.p, map, n, 0u, du * s, 0u, dv * s, 0u, flux, 0u, key, 0u, 0u, 0u);
}

// Emitter of global photon `index` (PhotonPassSetup::locate): the last emitter whose first
// index is <= index, if the index lies within its count. Returns emitter_count when none.
fn photon_locate(index: u32) -> u32 {
    let n = photon_params.emitter_count;
    var lo = 0u;
    var hi = n;
    // partition_point(first_index <= index)
    while lo < hi {
        let mid = lo + (hi - lo) / 2u;
        if photon_ranges[mid].first_index <= index {
            lo = mid + 1u;
        } else {
            hi = mid;
        }
    }
    if lo == 0u {
        return n;
    }
    let e = lo - 1u;
    if index - photon_ranges[e].first_index < photon_ranges[e].count {
        return e;
    }
    return n;
}

// trace_photon for global photon `index`; returns the segments cast.
fn photon_trace(index: u32) -> u32 {
    var segments = 0u;
    let e = photon_locate(index);
    if e >= photon_params.emitter_count || photon_ranges[e].valid == 0u {
        return segments;
    }
    let local = index - photon_ranges[e].first_index;
    var rng = arpa_rng_new(photon_params.seed, photon_params.iteration, index, ARPA_DOMAIN_PHOTON);
    let light = photon_lights[e];
    var cell = 0u;
    if light.cell_count != 0u {
        cell = photon_cells[light.cell_first + arpa_emission_slot(light, local, rng)];
    }
    // An environment map draws its photons' directions (a constant one's are uniform).
    let mapped = light.kind == ARPA_LIGHT_ENVIRONMENT && light.emission_record != ARPA_NO_TEXTURE;
    var emitted: ArpaEmitted;
    if mapped {
        emitted = arpa_env_emit(light, local, &rng, light.emission_record);
    } else {
        emitted = arpa_emit_in(light, local, &rng, cell);
    }
    // A caustic-pass photon stores only caustic records and ends at its first diffuse hit;
    // every caustic record is weighted by the source's balance weight (PhotonWalk).
    let caustic_only = photon_ranges[e].caustic_only != 0u;
    let caustic_weight = light.caustic_weight;
    if emitted.status != ARPA_DIFF_OK {
        return segments;
    }
    let reemission_length = emitted.reemission_length;
    var ray = emitted.ray;
    // Only ARPA's footprints use the differentials: RTPM's photons carry none (photon_path).
    var valid = photon_params.method == ARPA_PHOTON_METHOD_ARPA;
    var flux = emitted.flux;
    // A textured emitter's photon carries the texture at its origin over the texture's mean
    // over the triangle (PhotonWalk::start, PreparedScene::emission_factor_at).
    if light.emission_record != ARPA_NO_TEXTURE && !mapped {
        let b = arpa_barycentric(light.p0, light.p1, light.p2, ray.p);
        flux *= arpa_emitter_texture_factor(light.emission_record, b.x, b.y);
    }
    var specular_events = 0u;
    var diffuse_events = 0u;
    var start = arpa_ray_start_at(ray.p);
    if emitted.has_surface_normal != 0u {
        start = arpa_ray_start_off_surface(ray.p, emitted.surface_normal);
    }
    let max_depth = photon_params.max_depth;
    for (var depth = 0u; depth < max_depth; depth++) {
        let d = ray.d;
        segments += 1u;
        var hit = arpa_start_intersect(start, d, ARPA_SCENE_T_MAX);
        // PhotonWalk::advance: a mask the photon passes through lets the same ray go on
        // from its surface (passes are not segments); a photon that stops on a partly open
        // mask of opacity o stores its records with weight 1/o.
        var record_weight = 1.0;
        if arpa_scene_info.has_masks != 0u {
            var passes = 0u;
            loop {
                if hit.hit == 0u {
                    break;
                }
                let opacity = arpa_scene_opacity(hit);
                if passes < ARPA_MAX_MASK_PASSES && !arpa_stops_with(opacity, &rng) {
                    passes += 1u;
                    hit = arpa_start_intersect(arpa_ray_start_leaving_hit(hit), d, ARPA_SCENE_T_MAX);
                    continue;
                }
                if opacity > 0.0 && opacity < 1.0 {
                    record_weight = 1.0 / opacity;
                }
                break;
            }
        }
        if hit.hit == 0u {
            break;
        }
        var s = arpa_scene_surface(hit);
        let blend_weight = arpa_scene_choose_blend(&s, &rng);
        let t = max(dot(s.position - ray.p, d), 0.0);
        var at: ArpaRayDiff;
        var moved_ok = false;
        if valid {
            let moved = arpa_diff_transfer(ray, t, s.geometric_normal);
            if moved.status == ARPA_DIFF_OK {
                at = moved.ray;
                moved_ok = true;
            }
        }
        if !moved_ok {
            valid = false;
            at = photon_lost(s.position, d);
        }
        var front = -s.geometric_normal;
        if dot(d, s.geometric_normal) < 0.0 {
            front = s.geometric_normal;
        }
        let key = index * max_depth + depth;
        if s.kind == ARPA_SCATTER_DIFFUSE {
            var map = 1u;
            if specular_events > 0u && diffuse_events == 0u {
                map = 0u;
            }
            if caustic_only && map != 0u {
                break;
            }
            diffuse_events += 1u;
            let first_interaction = diffuse_events == 1u && specular_events == 0u;
            // DiffuseShading::new(front, shading normal, -d) and its adjoint ratio.
            var shading: ArpaDiffuseShading;
            let shaded = s.has_shading_normals != 0u;
            if shaded {
                shading = arpa_diffuse_shading_new(front, s.shading_normal, -d);
                if shading.valid == 0u {
                    break;
                }
                flux *= arpa_diffuse_adjoint_ratio(shading, -d);
                if !(photon_max3(flux) > 0.0) {
                    break;
                }
            }
            if !(photon_params.direct_lighting != 0u && first_interaction) && !(map == 0u && caustic_weight == 0.0) {
                let below = shaded && arpa_diffuse_below_shading_plane(shading);
                var stored_flux = flux;
                if map == 0u {
                    stored_flux = flux * caustic_weight;
                }
                photon_store(at, s.geometric_normal, stored_flux * (record_weight * blend_weight), map, valid, below, key);
            }
            if caustic_only {
                break;
            }
            let survive = min(photon_max3(s.color), 1.0);
            if !arpa_rng_next_below(&rng, survive) {
                break;
            }
            flux *= s.color / survive;
            var dir: vec3<f32>;
            if shaded {
                let r = arpa_diffuse_sample_reemission(shading, arpa_rng_next_2d(&rng));
                if r.valid == 0u {
                    break;
                }
                dir = r.direction;
            } else {
                dir = arpa_diffuse_direction(front, arpa_rng_next_2d(&rng));
            }
            var reemitted_ok = false;
            if valid {
                let r = arpa_reemit(s.position, at.dp_du, at.dp_dv, dir, reemission_length);
                if r.status == ARPA_DIFF_OK {
                    ray = r.ray;
                    reemitted_ok = true;
                }
            }
            if !reemitted_ok {
                valid = false;
                ray = photon_lost(s.position, dir);
            }
            start = arpa_ray_start_leaving(s);
        } else if s.kind == ARPA_SCATTER_MIRROR {
            specular_events += 1u;
            flux *= s.color;
            let nd = photon_shading_normal(s, at.dp_du, at.dp_dv);
            let r = photon_reflect(at, valid, nd, s.geometric_normal);
            ray = r.ray;
            valid = r.valid;
            start = arpa_ray_start_leaving(s);
        } else {
            specular_events += 1u;
            let nd = photon_shading_normal(s, at.dp_du, at.dp_dv);
            var n = s.geometric_normal;
            if nd.ok {
                n = nd.nd.n;
            }
            let thin = s.kind == ARPA_SCATTER_THIN;
            var fresnel = arpa_dielectric_reflectance(dot(d, n), s.ior);
            if thin {
                fresnel = arpa_thin_sheet_reflectance(dot(d, n), s.ior);
            }
            if arpa_rng_next_below(&rng, fresnel) {
                let r = photon_reflect(at, valid, nd, s.geometric_normal);
                ray = r.ray;
                valid = r.valid;
                start = arpa_ray_start_leaving(s);
            } else if thin {
                // Through a thin sheet: straight on, the differential as it arrived.
                flux *= s.color;
                ray = at;
                start = arpa_ray_start_leaving(s);
            } else {
                flux *= s.color;
                let rd = arpa_refract_direction(d, n, s.ior);
                var refracted_ok = false;
                if valid && nd.ok {
                    let r = arpa_diff_refract(at, nd.nd, s.ior);
                    if r.status == ARPA_DIFF_OK && r.event == rd.event {
                        ray = r.ray;
                        refracted_ok = true;
                    }
                }
                if !refracted_ok {
                    valid = false;
                    ray = photon_lost(s.position, rd.dir);
                }
                start = arpa_ray_start_leaving(s);
            }
        }
        if !(photon_max3(flux) > 0.0) || !arpa_finite3(flux) {
            break;
        }
    }
    return segments;
}

// PathState::reflect: specular reflection of `at` about the shading normal `nd`, or about
// the normal `geometric` (when nd could not be formed) without differential.
struct PhotonReflected {
    ray: ArpaRayDiff,
    valid: bool,
}

fn photon_reflect(at: ArpaRayDiff, valid: bool, nd: PhotonNormal, geometric: vec3<f32>) -> PhotonReflected {
    if valid && nd.ok {
        let r = arpa_diff_reflect(at, nd.nd);
        if r.status == ARPA_DIFF_OK {
            return PhotonReflected(r.ray, true);
        }
    }
    var n = geometric;
    if nd.ok {
        n = nd.nd.n;
    }
    return PhotonReflected(photon_lost(at.p, arpa_reflect_direction(at.d, n)), false);
}
