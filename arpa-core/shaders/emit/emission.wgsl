// WGSL twin of arpa_core::emit::emission's per-photon step (PreparedLight::emit): photon `index`
// of a light prepared on the host (arpa_core::emit::emission::PackedLight, same 176-byte layout)
// with its ray differential, flux and re-emission length. Needs math.wgsl, rng.wgsl,
// frame.wgsl, sampling.wgsl and differential.wgsl.
//
// Precision: f32 throughout (positions to a few eps32 of their magnitude, directions and
// differentials to a few eps32 relative); the spot falloff angle is math.wgsl's
// arpa_angle_between the sampled direction and the axis, accurate to a few ulps also in
// narrow cones (the device's atan2 may not be: lavapipe's errs by 3.3e-6 rad). The random
// 2-D draws are the core's truncated to 24 bits (rng.wgsl).

// Light kinds (PackedLight::kind).
const ARPA_LIGHT_POINT: u32 = 0u;
const ARPA_LIGHT_SPOT: u32 = 1u;
const ARPA_LIGHT_DIRECTIONAL: u32 = 2u;
const ARPA_LIGHT_TRIANGLE: u32 = 3u;
const ARPA_LIGHT_QUAD: u32 = 4u;
const ARPA_LIGHT_ENVIRONMENT: u32 = 5u;
// Spot falloff curves (PackedLight::falloff).
const ARPA_FALLOFF_LINEAR: u32 = 0u;
const ARPA_FALLOFF_SMOOTHSTEP: u32 = 1u;

// A light prepared for one iteration (arpa_core::emit::emission::PackedLight).
struct ArpaLight {
    kind: u32,
    falloff: u32,
    photon_count: u32,         // N photons this iteration
    cell_grid: u32,            // projection grid cells per side; 0: the whole domain
    p0: vec3<f32>,             // point/spot position, triangle p0, quad origin (m)
    scene_radius: f32,         // bounding-sphere radius (m)
    p1: vec3<f32>,             // triangle p1, quad edge_u (m)
    cutoff: f32,               // spot cut-off half-angle (rad)
    p2: vec3<f32>,             // triangle p2, quad edge_v (m)
    beam_width: f32,           // spot full-intensity half-angle (rad)
    frame_t: vec3<f32>,        // light frame (spot axis / beam / emitter plane)
    len_positional: f32,       // l_x (m)
    frame_b: vec3<f32>,
    len_directional: f32,      // l_omega (rad)
    frame_n: vec3<f32>,
    len_reemission: f32,       // directional length at diffuse re-emission (rad)
    flux: vec3<f32>,           // flux per photon (W, RGB)
    one_minus_cos_cutoff: f32, // 1 - cos(cutoff), from f64 on the host
    scene_centre: vec3<f32>,   // bounding-sphere centre (m)
    caustic_weight: f32,       // weight of the photons' caustic records (0: none stored)
    lattice_shift: vec2<f32>,  // Cranley-Patterson shift of this iteration
    cell_first: u32,           // first projection cell in the caller's cell table
    cell_count: u32,           // projection cells sampled; 0: the whole domain
    cell_offset: u32,          // start of the round robin over the cells this iteration
    // A textured emitter triangle's record in the scene's texture words (the photon pass,
    // texture.wgsl's arpa_emitter_texture_factor), or 0xffffffff.
    emission_record: u32,
    pad3b: u32,
    pad3c: u32,
}

// One emitted photon; `ray` and the rest are meaningful only when status == ARPA_DIFF_OK.
struct ArpaEmitted {
    ray: ArpaRayDiff,
    flux: vec3<f32>,              // W, RGB
    reemission_length: f32,       // rad
    surface_normal: vec3<f32>,    // area lights: unit normal of the emitting side
    has_surface_normal: u32,      // 1 for area lights, 0 for delta lights
    status: u32,                  // ARPA_DIFF_* of the initial differential
}

// Spot falloff f(theta) in [0, 1] at angle theta (rad) from the axis (SpotLight::falloff_at)
// of a spot with full-intensity half-angle beam_width, cut-off half-angle cutoff (rad) and
// curve falloff (ARPA_FALLOFF_*); for renderers that keep their spots in their own layout.
fn arpa_spot_falloff_at(theta: f32, beam_width: f32, cutoff: f32, falloff: u32) -> f32 {
    if theta <= beam_width {
        return 1.0;
    }
    if theta >= cutoff {
        return 0.0;
    }
    let x = (cutoff - theta) / (cutoff - beam_width);
    if falloff == ARPA_FALLOFF_SMOOTHSTEP {
        return x * x * (3.0 - 2.0 * x);
    }
    return x;
}

// Spot falloff of a prepared light (arpa_spot_falloff_at with its angles and curve).
fn arpa_spot_falloff(light: ArpaLight, theta: f32) -> f32 {
    return arpa_spot_falloff_at(theta, light.beam_width, light.cutoff, light.falloff);
}

// RayDifferential::new: normalises d; InvalidDirection for a zero or non-finite d.
fn arpa_ray_new(p: vec3<f32>, d: vec3<f32>, dp_du: vec3<f32>, dp_dv: vec3<f32>, dd_du: vec3<f32>, dd_dv: vec3<f32>) -> ArpaDiffResult {
    let dn = arpa_diff_normalize_or(d, vec3<f32>(0.0));
    let r = ArpaRayDiff(p, dn, dp_du, dp_dv, dd_du, dd_dv);
    if all(dn == vec3<f32>(0.0)) {
        return ArpaDiffResult(r, ARPA_DIFF_INVALID_DIRECTION, 0u);
    }
    return arpa_diff_checked(r, 0u);
}

// Photon `index` of `light` over its whole domain (PreparedLight::emit; cell_count 0).
// Area lights draw their direction from `rng` (one 2-D draw); the primary sample comes
// from the shifted Fibonacci lattice.
fn arpa_emit(light: ArpaLight, index: u32, rng: ptr<function, ArpaRng>) -> ArpaEmitted {
    return arpa_emit_in(light, index, rng, 0u);
}

// PreparedLight::emission_slot: the slot in the light's cell list of photon `index`
// whose stream, before emission, is `rng` (a copy: not advanced). The caller looks the
// cell up in its table (entry cell_first + slot) and hands it to arpa_emit_in.
fn arpa_emission_slot(light: ArpaLight, index: u32, rng_in: ArpaRng) -> u32 {
    if light.cell_count == 0u {
        return 0u;
    }
    if light.kind == ARPA_LIGHT_TRIANGLE || light.kind == ARPA_LIGHT_QUAD {
        var rng = rng_in;
        return arpa_split_draw_slot(arpa_rng_next_u32(&rng), light.cell_count);
    }
    return arpa_round_robin(index, light.photon_count, light.cell_count, light.cell_offset).x;
}

// An environment photon (PreparedLight::emit_environment_in) travelling along unit `d`
// from lattice point `u`: it starts on the disc of the scene's radius across `d`, a radius
// out from the centre, with a directional light's positional differentials.
fn arpa_environment_ray(light: ArpaLight, u: vec2<f32>, d: vec3<f32>) -> ArpaDiffResult {
    let f = arpa_frame_from_normal(d);
    let disc = arpa_uniform_disc(u) * light.scene_radius;
    let origin = light.scene_centre - f.n * light.scene_radius + f.t * disc.x + f.b * disc.y;
    let x = light.len_positional;
    return arpa_ray_new(origin, f.n, f.t * x, f.b * x, vec3<f32>(0.0), vec3<f32>(0.0));
}

// Photon `index` of `light` (PreparedLight::emit_in) in projection cell `cell` (the entry
// of arpa_emission_slot's slot; ignored when the light samples its whole domain).
fn arpa_emit_in(light: ArpaLight, index: u32, rng: ptr<function, ArpaRng>, cell: u32) -> ArpaEmitted {
    var out: ArpaEmitted;
    out.flux = light.flux;
    out.reemission_length = light.len_reemission;
    out.has_surface_normal = 0u;
    out.surface_normal = vec3<f32>(0.0);
    let projected = light.cell_count != 0u;
    let area = light.kind == ARPA_LIGHT_TRIANGLE || light.kind == ARPA_LIGHT_QUAD;
    var u: vec2<f32>;
    var cell_weight = 1.0;
    if projected && !area {
        let rr = arpa_round_robin(index, light.photon_count, light.cell_count, light.cell_offset);
        cell_weight = arpa_round_robin_weight(light.photon_count, light.cell_count, rr.z);
        u = arpa_cell_point(arpa_fibonacci_lattice(rr.y, rr.z, light.lattice_shift), cell, light.cell_grid);
    } else {
        u = arpa_fibonacci_lattice(index, light.photon_count, light.lattice_shift);
    }
    let w = light.len_directional;
    let x = light.len_positional;
    let zero = vec3<f32>(0.0);
    var res: ArpaDiffResult;
    switch light.kind {
        case 0u: { // point
            let d = arpa_uniform_sphere(u);
            let f = arpa_frame_from_normal(d);
            res = arpa_ray_new(light.p0, d, zero, zero, f.t * w, f.b * w);
        }
        case 1u: { // spot
            let local = arpa_uniform_cone(u, light.one_minus_cos_cutoff);
            let lf = ArpaFrame(light.frame_t, light.frame_b, light.frame_n);
            let d = arpa_frame_to_world(lf, local);
            let theta = arpa_angle_between(local, vec3<f32>(0.0, 0.0, 1.0));
            let f = arpa_frame_from_normal(d);
            res = arpa_ray_new(light.p0, d, zero, zero, f.t * w, f.b * w);
            out.flux = light.flux * arpa_spot_falloff(light, theta);
        }
        case 5u: { // environment: a constant one's directions are uniform (one 2-D draw)
            res = arpa_environment_ray(light, u, -arpa_uniform_sphere(arpa_rng_next_2d(rng)));
        }
        case 2u: { // directional
            let disc = arpa_uniform_disc(u) * light.scene_radius;
            let origin = light.scene_centre - light.frame_n * light.scene_radius + light.frame_t * disc.x + light.frame_b * disc.y;
            res = arpa_ray_new(origin, light.frame_n, light.frame_t * x, light.frame_b * x, zero, zero);
        }
        default: { // triangle, quad
            var p: vec3<f32>;
            if light.kind == ARPA_LIGHT_TRIANGLE {
                let b = arpa_uniform_triangle(u);
                p = light.p0 * b.x + light.p1 * b.y + light.p2 * b.z;
            } else {
                p = light.p0 + light.p1 * u.x + light.p2 * u.y;
            }
            let lf = ArpaFrame(light.frame_t, light.frame_b, light.frame_n);
            var draw: vec2<f32>;
            if projected {
                let word = arpa_rng_next_u32(rng);
                let fx = arpa_split_draw_fraction(word, light.cell_count);
                let fy = arpa_rng_next_f32(rng);
                draw = arpa_cell_point(vec2<f32>(fx, fy), cell, light.cell_grid);
            } else {
                draw = arpa_rng_next_2d(rng);
            }
            let d = arpa_frame_normalize_or(arpa_frame_to_world(lf, arpa_cosine_hemisphere(draw)), light.frame_n);
            let df = arpa_frame_from_normal_and_hint(d, light.frame_t);
            res = arpa_ray_new(p, d, light.frame_t * x, light.frame_b * x, df.t * w, df.b * w);
            out.surface_normal = light.frame_n;
            out.has_surface_normal = 1u;
        }
    }
    out.flux *= cell_weight;
    out.ray = res.ray;
    out.status = res.status;
    return out;
}
