// The scene on the device (bind group 0 of the camera and photon passes): per-mesh
// materials with the scene's roughness cut-off resolved on the host, per-triangle geometry,
// the emitters for next-event estimation, and the textures with the meshes' texture
// coordinates (texture.wgsl's word table), as arpa_core::gpu::scene::SceneTables uploads
// them; mirrors arpa_core::render::prepared_scene::PreparedScene. Needs math.wgsl,
// rng.wgsl, records.wgsl and texture.wgsl.
// Units: metres, world space; radiance W/(m^2 sr), intensity W/sr, irradiance W/m^2
// (linear RGB).
//
// Ray casting is the backend's: its glue declares binding 0 of group 0 (its acceleration
// structure over the triangles: one bottom level per mesh holding the mesh's triangles in
// the order of SceneTables::triangle_orders, instance custom index = mesh index) and
// defines
//   fn arpa_scene_intersect(origin: vec3<f32>, dir: vec3<f32>, t_min: f32, t_max: f32) -> ArpaSceneHit
//     closest hit along origin + t dir, t_min < t <= t_max (RayCaster::intersect), built
//     with arpa_scene_hit / arpa_scene_miss from what the hit reports;
//   fn arpa_scene_occluded(origin: vec3<f32>, dir: vec3<f32>, t_min: f32, t_max: f32) -> bool
//     whether anything lies along origin + t dir, t_min < t <= t_max (RayCaster::occluded);
// both with opaque triangles, unit dir and t_max up to ARPA_SCENE_T_MAX (arpa-wgpu:
// ray queries; arpa-vk: ray-tracing pipelines). The passes cast through an ArpaRayStart
// (arpa_start_intersect / arpa_start_occluded below), never directly.
//
// Alpha masks (PreparedScene::intersect): a ray passes through a mask of opacity o with
// probability 1 - o, drawing from the path's own stream exactly where the core draws, and
// is cast again from the mask's surface (arpa_scene_intersect_masked). The backends' casts
// stay opaque closest-hit queries: the mask decision is the core's, in this file, so every
// backend passes the same masks for the same seed.

// Scattering kinds (arpa_core::render::scene::Scattering; arpa_core::gpu::codes::SCATTER_*).
const ARPA_SCATTER_DIFFUSE: u32 = 0u;
const ARPA_SCATTER_MIRROR: u32 = 1u;
const ARPA_SCATTER_REFRACTIVE: u32 = 2u;
const ARPA_SCATTER_THIN: u32 = 3u;

// scene::thin_sheet_reflectance: a thin sheet's total reflectance 2R/(1 + R) for light at
// cos_i to its normal (either side).
fn arpa_thin_sheet_reflectance(cos_i: f32, ior: f32) -> f32 {
    let r = arpa_dielectric_reflectance(-abs(cos_i), ior);
    if r < 1.0 {
        return 2.0 * r / (1.0 + r);
    }
    return 1.0;
}

// Ray extent standing for the core's unbounded rays (t_max = infinity): the largest
// finite f32 (metres).
const ARPA_SCENE_T_MAX: f32 = 3.40282347e38;

// Per-triangle flags (arpa_core::gpu::codes::TRIANGLE_*).
// The triangle has vertex normals that differ from its face normal
// (PreparedScene::has_shading_normals).
const ARPA_TRIANGLE_SHADED: u32 = 1u;
// The mesh has vertex normals and the triangle a non-zero area, so
// PreparedScene::shading_normal interpolates them (specular bounces).
const ARPA_TRIANGLE_NORMALS: u32 = 2u;

// Normal and bump maps (arpa_core::gpu::codes::NORMAL_MAP_*).
const ARPA_NORMAL_MAP_NONE: u32 = 0u;
const ARPA_NORMAL_MAP_TANGENT: u32 = 1u;
const ARPA_NORMAL_MAP_TANGENT_UV: u32 = 2u;
const ARPA_NORMAL_MAP_BUMP: u32 = 3u;

// arpa_core::gpu::layout::SceneInfo (uniform, 32 bytes).
struct ArpaSceneInfo {
    mesh_count: u32,
    // Emitters: first the delta lights (point, spot, directional) in the core's emitter
    // order, then the area emitters (triangles, quads) in PreparedScene's area order.
    delta_count: u32,
    area_count: u32,
    // 1 if some material is a mask (PreparedScene::has_masks).
    has_masks: u32,
    // Bounding sphere (PreparedScene::bounding_sphere).
    sphere_centre: vec3<f32>,
    sphere_radius: f32,
}

// layout::SceneMesh (96 bytes).
struct ArpaSceneMesh {
    first_triangle: u32,
    triangle_count: u32,
    // ARPA_SCATTER_*.
    kind: u32,
    // 1 if the mesh emits `emission` on its geometric-normal side.
    emissive: u32,
    // Albedo (diffuse), reflectance (mirror) or transmittance (refractive).
    color: vec3<f32>,
    // Interior over exterior index of refraction (refractive only).
    ior: f32,
    emission: vec3<f32>,
    // 1 if the mesh has vertex normals.
    has_normals: u32,
    // The texture multiplying `color`, or ARPA_NO_TEXTURE.
    color_texture: u32,
    // The texture whose single value is the opacity, or ARPA_NO_TEXTURE.
    opacity_texture: u32,
    // The constant opacity where opacity_texture is none (1: opaque).
    opacity: f32,
    // Word of the first triangle's texture coordinates (u0 v0 u1 v1 u2 v2 per triangle) in
    // the texture words, or ARPA_NO_TEXTURE (the hit's (b1, b2) are used).
    uv_first: u32,
    // The texture multiplying `emission`, or ARPA_NO_TEXTURE.
    emission_texture: u32,
    // The normal or bump map, or ARPA_NO_TEXTURE.
    normal_texture: u32,
    // ARPA_NORMAL_MAP_*.
    normal_kind: u32,
    // The map's scale (NormalPerturbation::scale).
    normal_scale: f32,
    // A blend's record of the other material (kind, color, ior, color_texture), after the
    // scene's meshes; ARPA_NO_TEXTURE: not a blend.
    blend_record: u32,
    // The blend's constant weight, where blend_weight_texture is none.
    blend_weight: f32,
    // The texture whose single value is the blend's weight, or ARPA_NO_TEXTURE.
    blend_weight_texture: u32,
    pad_a: u32,
}

// layout::SceneTriangle (112 bytes).
struct ArpaSceneTriangle {
    p0: vec3<f32>,
    // ARPA_TRIANGLE_* bits.
    flags: u32,
    p1: vec3<f32>,
    // Not about this triangle: the mesh's triangle index of BLAS primitive i, where i is
    // this record's index within its mesh (the BLAS holds the triangles in the Morton order
    // of their centroids, arpa_core::gpu::scene::morton_triangle_order).
    blas_triangle: u32,
    p2: vec3<f32>,
    pad2: u32,
    // Unit geometric normal (p1 - p0) x (p2 - p0) / |...| computed in f64 (+y if degenerate).
    normal: vec3<f32>,
    pad3: u32,
    // Vertex normals as the mesh stores them (not normalised); the geometric normal for
    // meshes without normals.
    n0: vec3<f32>,
    pad4: u32,
    n1: vec3<f32>,
    pad5: u32,
    n2: vec3<f32>,
    pad6: u32,
}

// layout::SceneEmitter (80 bytes).
struct ArpaSceneEmitter {
    // ARPA_LIGHT_* (the light kinds of emission.wgsl, arpa_core::emit::emission::PackedLight::kind).
    kind: u32,
    // Spot falloff: 0 linear in angle, 1 smoothstep (ARPA_FALLOFF_* of emission.wgsl).
    falloff: u32,
    // Spot cut-off and full-intensity half-angles (rad).
    cutoff: f32,
    beam_width: f32,
    // Point/spot position, directional unit direction of travel, triangle vertex 0, quad origin.
    p0: vec3<f32>,
    // Area emitters: cumulative power up to and including this one over the total (the
    // core's area CDF divided by its last entry).
    cdf: f32,
    // Spot unit axis, triangle vertex 1, quad edge_u.
    p1: vec3<f32>,
    // Area emitters: probability of being picked (power / total).
    probability: f32,
    // Triangle vertex 2, quad edge_v.
    p2: vec3<f32>,
    // A textured emitter triangle's record in the texture words (texture.wgsl's
    // arpa_emitter_texture_factor), or ARPA_NO_TEXTURE; `color` then holds the radiance
    // times the texture's mean over the triangle.
    emission_record: u32,
    // Intensity (point, spot), irradiance (directional), radiance (area).
    color: vec3<f32>,
    pad1: f32,
}

@group(0) @binding(1) var<uniform> arpa_scene_info: ArpaSceneInfo;
@group(0) @binding(2) var<storage, read> arpa_scene_meshes: array<ArpaSceneMesh>;
@group(0) @binding(3) var<storage, read> arpa_scene_triangles: array<ArpaSceneTriangle>;
@group(0) @binding(4) var<storage, read> arpa_scene_emitters: array<ArpaSceneEmitter>;
@group(0) @binding(5) var<storage, read> arpa_scene_texture_words: array<u32>;

// texture.wgsl's word table.
fn arpa_texture_word(i: u32) -> u32 {
    return arpa_scene_texture_words[i];
}

// A closest hit (RayHit): t (metres along the unit direction), mesh, triangle within the
// mesh, barycentric weights b1, b2 of vertices 1 and 2; hit = 0: no hit.
struct ArpaSceneHit {
    t: f32,
    mesh: u32,
    triangle: u32,
    b1: f32,
    b2: f32,
    hit: u32,
}

// The hit of BLAS primitive `primitive` of mesh `mesh`'s bottom level at distance t
// (metres) with barycentric weights b of vertices 1 and 2: `triangle` becomes the mesh's
// triangle index as the core numbers it.
fn arpa_scene_hit(mesh: u32, primitive: u32, t: f32, b: vec2<f32>) -> ArpaSceneHit {
    let triangle = arpa_scene_triangles[arpa_scene_meshes[mesh].first_triangle + primitive].blas_triangle;
    return ArpaSceneHit(t, mesh, triangle, b.x, b.y, 1u);
}

// No hit.
fn arpa_scene_miss() -> ArpaSceneHit {
    return ArpaSceneHit(0.0, 0xffffffffu, 0u, 0.0, 0.0, 0u);
}

// A surface point (SurfacePoint plus its normals).
struct ArpaSurface {
    // Interpolated position (metres).
    position: vec3<f32>,
    // ARPA_SCATTER_*.
    kind: u32,
    // Unit geometric normal (not oriented).
    geometric_normal: vec3<f32>,
    // PreparedScene::has_shading_normals (0/1).
    has_shading_normals: u32,
    // PreparedScene::shading_normal_at: unit interpolated vertex normal oriented like the
    // geometric one, or the geometric normal.
    shading_normal: vec3<f32>,
    // Interior over exterior index of refraction (refractive only).
    ior: f32,
    // Albedo (diffuse), reflectance (mirror) or transmittance (refractive).
    color: vec3<f32>,
    // 1 if the mesh emits `emission` on the geometric-normal side.
    emissive: u32,
    emission: vec3<f32>,
    mesh: u32,
    // Barycentric weights of the three vertices.
    barycentric: vec3<f32>,
    triangle: u32,
    // PreparedScene::shading_normal(s, 0, 0).n, or the geometric normal where the core
    // falls back to it: the unit interpolated vertex normal whenever the mesh has vertex
    // normals (also on flat-shaded triangles), oriented like the geometric one. The normal
    // of specular bounces.
    specular_normal: vec3<f32>,
    // 1 if the mesh has vertex normals.
    mesh_has_normals: u32,
    // Texture coordinates (PreparedScene::uv).
    uv: vec2<f32>,
}

// Index of a mesh's triangle in arpa_scene_triangles.
fn arpa_scene_triangle_index(mesh: u32, triangle: u32) -> u32 {
    return arpa_scene_meshes[mesh].first_triangle + triangle;
}

// The vertices of a triangle (metres).
fn arpa_scene_triangle_vertices(mesh: u32, triangle: u32) -> array<vec3<f32>, 3> {
    let t = arpa_scene_triangles[arpa_scene_triangle_index(mesh, triangle)];
    return array<vec3<f32>, 3>(t.p0, t.p1, t.p2);
}

// The vertex normals of a triangle as the mesh stores them (not normalised); the unit
// geometric normal three times for meshes without vertex normals.
fn arpa_scene_triangle_normals(mesh: u32, triangle: u32) -> array<vec3<f32>, 3> {
    let t = arpa_scene_triangles[arpa_scene_triangle_index(mesh, triangle)];
    return array<vec3<f32>, 3>(t.n0, t.n1, t.n2);
}

// sum b_i n_i normalised and oriented like `geometric`; `geometric` where it vanishes.
fn arpa_scene_interpolated_normal(t: ArpaSceneTriangle, b: vec3<f32>) -> vec3<f32> {
    let m = t.n0 * b.x + t.n1 * b.y + t.n2 * b.z;
    let a = abs(m);
    let s = max(a.x, max(a.y, a.z));
    if !(s > 0.0) || !arpa_finite3(m) {
        return t.normal;
    }
    let w = m / s;
    let n = w / length(w);
    return select(n, -n, dot(n, t.normal) < 0.0);
}

// PreparedScene::uv: the mesh's texture coordinates interpolated with the hit's
// barycentric weights, or (b1, b2) on a mesh without them.
fn arpa_scene_uv(h: ArpaSceneHit) -> vec2<f32> {
    let first = arpa_scene_meshes[h.mesh].uv_first;
    if first == ARPA_NO_TEXTURE {
        return vec2<f32>(h.b1, h.b2);
    }
    let w = first + 6u * h.triangle;
    let a = vec2<f32>(arpa_texture_f32(w), arpa_texture_f32(w + 1u));
    let b = vec2<f32>(arpa_texture_f32(w + 2u), arpa_texture_f32(w + 3u));
    let c = vec2<f32>(arpa_texture_f32(w + 4u), arpa_texture_f32(w + 5u));
    return a * (1.0 - h.b1 - h.b2) + b * h.b1 + c * h.b2;
}

// prepared_scene::barycentric: the barycentric weights (b1, b2) of vertices 1 and 2 of the
// point p of the plane of triangle (p0, p1, p2); (0, 0) for a degenerate triangle.
fn arpa_barycentric(p0: vec3<f32>, p1: vec3<f32>, p2: vec3<f32>, p: vec3<f32>) -> vec2<f32> {
    let e1 = p1 - p0;
    let e2 = p2 - p0;
    let d = p - p0;
    let d11 = dot(e1, e1);
    let d12 = dot(e1, e2);
    let d22 = dot(e2, e2);
    let d1 = dot(d, e1);
    let d2 = dot(d, e2);
    let det = d11 * d22 - d12 * d12;
    if !(det > 0.0) {
        return vec2<f32>(0.0);
    }
    return vec2<f32>(d22 * d1 - d12 * d2, d11 * d2 - d12 * d1) / det;
}

// PreparedScene::opacity: the probability that a ray stops at the hit (1: opaque; a
// texture's NaN counts as 1).
fn arpa_scene_opacity(h: ArpaSceneHit) -> f32 {
    let m = arpa_scene_meshes[h.mesh];
    if m.opacity_texture == ARPA_NO_TEXTURE {
        return m.opacity;
    }
    let o = arpa_texture_eval_1(m.opacity_texture, arpa_scene_uv(h));
    if (bitcast<u32>(o) & 0x7fffffffu) > 0x7f800000u {
        return 1.0;
    }
    return clamp(o, 0.0, 1.0);
}

// prepared_scene::stops_with: whether a ray stops on a surface of opacity o, drawing one
// number where 0 < o < 1.
fn arpa_stops_with(o: f32, rng: ptr<function, ArpaRng>) -> bool {
    if o >= 1.0 {
        return true;
    }
    if o <= 0.0 {
        return false;
    }
    return arpa_rng_next_below(rng, o);
}

// The surface point of a hit (PreparedScene::surface, shading_normal_at,
// has_shading_normals, shading_normal without derivatives). h.hit must be 1.
fn arpa_scene_surface(h: ArpaSceneHit) -> ArpaSurface {
    let m = arpa_scene_meshes[h.mesh];
    let t = arpa_scene_triangles[m.first_triangle + h.triangle];
    let b = vec3<f32>(1.0 - h.b1 - h.b2, h.b1, h.b2);
    var s: ArpaSurface;
    s.position = t.p0 * b.x + t.p1 * b.y + t.p2 * b.z;
    s.kind = m.kind;
    s.geometric_normal = t.normal;
    s.has_shading_normals = select(0u, 1u, (t.flags & ARPA_TRIANGLE_SHADED) != 0u);
    s.shading_normal = t.normal;
    if s.has_shading_normals != 0u {
        s.shading_normal = arpa_scene_interpolated_normal(t, b);
    }
    s.specular_normal = t.normal;
    if (t.flags & ARPA_TRIANGLE_NORMALS) != 0u {
        s.specular_normal = arpa_scene_interpolated_normal(t, b);
    }
    s.ior = m.ior;
    s.uv = arpa_scene_uv(h);
    s.color = m.color;
    if m.color_texture != ARPA_NO_TEXTURE {
        s.color *= max(arpa_texture_eval(m.color_texture, s.uv), vec3<f32>(0.0));
    }
    s.emissive = m.emissive;
    s.emission = m.emission;
    if m.emissive != 0u && m.emission_texture != ARPA_NO_TEXTURE {
        s.emission *= max(arpa_texture_eval(m.emission_texture, s.uv), vec3<f32>(0.0));
    }
    s.mesh = h.mesh;
    s.triangle = h.triangle;
    s.barycentric = b;
    s.mesh_has_normals = m.has_normals;
    if m.normal_kind != ARPA_NORMAL_MAP_NONE {
        // Both normals turned by the map (PreparedScene::perturbed); a mesh without vertex
        // normals starts from the face normal.
        if m.has_normals == 0u {
            s.shading_normal = t.normal;
        }
        let both = arpa_scene_perturbed_pair(h.mesh, h.triangle, s.shading_normal, s.specular_normal, t.normal, s.uv);
        s.shading_normal = both[0];
        s.specular_normal = both[1];
    }
    return s;
}

// PreparedScene::choose_blend: where the mesh's material is a blend, the surface scatters as
// the blend's other material with probability its weight at the surface (arpa_stops_with:
// one draw for a weight strictly between 0 and 1). Returns the weight of a photon record
// stored there: 1/P(the choice is diffuse) where it is, else 1.
fn arpa_scene_choose_blend(s: ptr<function, ArpaSurface>, rng: ptr<function, ArpaRng>) -> f32 {
    let m = arpa_scene_meshes[(*s).mesh];
    if m.blend_record == ARPA_NO_TEXTURE {
        return 1.0;
    }
    var w = m.blend_weight;
    if m.blend_weight_texture != ARPA_NO_TEXTURE {
        w = arpa_texture_eval_1(m.blend_weight_texture, (*s).uv);
        if (bitcast<u32>(w) & 0x7fffffffu) > 0x7f800000u {
            w = 0.0;
        }
        w = clamp(w, 0.0, 1.0);
    }
    let o = arpa_scene_meshes[m.blend_record];
    let first_diffuse = (*s).kind == ARPA_SCATTER_DIFFUSE;
    let other_diffuse = o.kind == ARPA_SCATTER_DIFFUSE;
    if arpa_stops_with(w, rng) {
        (*s).kind = o.kind;
        (*s).ior = o.ior;
        (*s).color = o.color;
        if o.color_texture != ARPA_NO_TEXTURE {
            (*s).color *= max(arpa_texture_eval(o.color_texture, (*s).uv), vec3<f32>(0.0));
        }
    }
    var p_diffuse = 1.0;
    if first_diffuse && !other_diffuse {
        p_diffuse = 1.0 - w;
    } else if other_diffuse && !first_diffuse {
        p_diffuse = w;
    }
    if (*s).kind == ARPA_SCATTER_DIFFUSE && p_diffuse > 0.0 {
        return 1.0 / p_diffuse;
    }
    return 1.0;
}

// PreparedScene::texture_derivatives: (dp/du, dp/dv) of a mesh's triangle from its
// vertices and texture coordinates ((0, 0), (1, 0), (0, 1) without them).
fn arpa_scene_texture_derivatives(mesh: u32, triangle: u32) -> ArpaTextureDerivatives {
    let t = arpa_scene_triangles[arpa_scene_triangle_index(mesh, triangle)];
    let first = arpa_scene_meshes[mesh].uv_first;
    if first == ARPA_NO_TEXTURE {
        return arpa_texture_derivatives(t.p0, t.p1, t.p2, vec2<f32>(0.0), vec2<f32>(1.0, 0.0), vec2<f32>(0.0, 1.0));
    }
    let w = first + 6u * triangle;
    let uv0 = vec2<f32>(arpa_texture_f32(w), arpa_texture_f32(w + 1u));
    let uv1 = vec2<f32>(arpa_texture_f32(w + 2u), arpa_texture_f32(w + 3u));
    let uv2 = vec2<f32>(arpa_texture_f32(w + 4u), arpa_texture_f32(w + 5u));
    return arpa_texture_derivatives(t.p0, t.p1, t.p2, uv0, uv1, uv2);
}

// PreparedScene::perturbed of two unit shading normals at once (the diffuse one a and the
// specular one b, oriented like the unit geometric normal g): each turned by the normal or
// bump map of the mesh's material at uv, or kept without one. The texture is read once (one
// copy of the lookup where the shader compiler inlines it).
fn arpa_scene_perturbed_pair(mesh: u32, triangle: u32, a: vec3<f32>, b: vec3<f32>, g: vec3<f32>, uv: vec2<f32>) -> array<vec3<f32>, 2> {
    let m = arpa_scene_meshes[mesh];
    if m.normal_kind == ARPA_NORMAL_MAP_NONE {
        return array<vec3<f32>, 2>(a, b);
    }
    var d = arpa_scene_texture_derivatives(mesh, triangle);
    let bump = m.normal_kind == ARPA_NORMAL_MAP_BUMP;
    let lookup = arpa_texture_eval_and_grad(m.normal_texture, uv);
    var out: array<vec3<f32>, 2>;
    for (var i = 0u; i < 2u; i++) {
        let n = select(b, a, i == 0u);
        var du = d.dp_du;
        var dv = d.dp_dv;
        if !d.ok {
            let f = arpa_frame_from_normal(n);
            du = f.t;
            dv = f.b;
        }
        if bump {
            out[i] = arpa_bump_mapped(n, g, du, dv, lookup.grad * m.normal_scale);
        } else {
            out[i] = arpa_normal_mapped(n, g, du, dv, lookup.value, m.normal_scale, m.normal_kind == ARPA_NORMAL_MAP_TANGENT_UV);
        }
    }
    return out;
}

// A ray origin offset off the surface point p along the unit normal n (oriented to the side
// the ray leaves towards), prepared_scene::offset_origin: only for photons leaving an area
// light (arpa_ray_start_off_surface).
fn arpa_offset_origin(p: vec3<f32>, n: vec3<f32>) -> vec3<f32> {
    let a = abs(p);
    let scale = 1e-5 * (1.0 + max(a.x, max(a.y, a.z)));
    return p + n * scale;
}

// Where a ray starts and what it must not hit there (ray_cast::RayStart): a ray leaving a
// surface starts on it, not offset, and skips the triangle it leaves (mesh, triangle;
// mesh = ARPA_NO_TRIANGLE: none), so glass thinner than any offset is entered and left.
struct ArpaRayStart {
    origin: vec3<f32>,
    // Hits at t <= t_min (metres) are not reported.
    t_min: f32,
    mesh: u32,
    triangle: u32,
}

const ARPA_NO_TRIANGLE: u32 = 0xffffffffu;
// ray_cast::LEAVE_RECASTS.
const ARPA_LEAVE_RECASTS: u32 = 2u;

// RayStart::at: from a point off every surface.
fn arpa_ray_start_at(origin: vec3<f32>) -> ArpaRayStart {
    return ArpaRayStart(origin, 0.0, ARPA_NO_TRIANGLE, 0u);
}

// ray_cast::leave_t_min: 2^-23 (1 + max |origin_i|).
fn arpa_leave_t_min(origin: vec3<f32>) -> f32 {
    let a = abs(origin);
    return 1.1920929e-7 * (1.0 + max(a.x, max(a.y, a.z)));
}

// RayStart::leaving: a ray leaving the surface point s (either side).
fn arpa_ray_start_leaving(s: ArpaSurface) -> ArpaRayStart {
    return ArpaRayStart(s.position, arpa_leave_t_min(s.position), s.mesh, s.triangle);
}

// PreparedScene::leaving_hit: a ray going on past the hit h (through a mask).
fn arpa_ray_start_leaving_hit(h: ArpaSceneHit) -> ArpaRayStart {
    let t = arpa_scene_triangles[arpa_scene_meshes[h.mesh].first_triangle + h.triangle];
    let p = t.p0 * (1.0 - h.b1 - h.b2) + t.p1 * h.b1 + t.p2 * h.b2;
    return ArpaRayStart(p, arpa_leave_t_min(p), h.mesh, h.triangle);
}

// RayStart::off_surface: photons leaving an area light along its normal n.
fn arpa_ray_start_off_surface(p: vec3<f32>, n: vec3<f32>) -> ArpaRayStart {
    return arpa_ray_start_at(arpa_offset_origin(p, n));
}

// ray_cast::next_up: the next f32 above t >= 0.
fn arpa_next_up(t: f32) -> f32 {
    return bitcast<f32>(bitcast<u32>(max(t, 0.0)) + 1u);
}

fn arpa_start_is_left(start: ArpaRayStart, h: ArpaSceneHit) -> bool {
    return h.hit != 0u && h.mesh == start.mesh && h.triangle == start.triangle;
}

// RayStart::intersect: the closest hit along unit dir up to t_max, the left triangle
// skipped (cast again just past it, at most ARPA_LEAVE_RECASTS times, then a miss).
fn arpa_start_intersect(start: ArpaRayStart, dir: vec3<f32>, t_max: f32) -> ArpaSceneHit {
    var h = arpa_scene_intersect(start.origin, dir, start.t_min, t_max);
    for (var i = 0u; i < ARPA_LEAVE_RECASTS && arpa_start_is_left(start, h); i++) {
        h = arpa_scene_intersect(start.origin, dir, arpa_next_up(max(h.t, start.t_min)), t_max);
    }
    if arpa_start_is_left(start, h) {
        return arpa_scene_miss();
    }
    return h;
}

// RayStart::occluded: anything but the left triangle before t_max.
fn arpa_start_occluded(start: ArpaRayStart, dir: vec3<f32>, t_max: f32) -> bool {
    if !arpa_scene_occluded(start.origin, dir, start.t_min, t_max) {
        return false;
    }
    return start.mesh == ARPA_NO_TRIANGLE || arpa_start_intersect(start, dir, t_max).hit != 0u;
}

// prepared_scene::MAX_MASK_PASSES.
const ARPA_MAX_MASK_PASSES: u32 = 64u;

// PreparedScene::intersect: the closest hit that stops the ray, masks passed as
// arpa_stops_with decides (at most ARPA_MAX_MASK_PASSES, then the next hit stops it). The
// hit's t is measured from the last surface passed.
fn arpa_scene_intersect_masked(start: ArpaRayStart, dir: vec3<f32>, t_max: f32, rng: ptr<function, ArpaRng>) -> ArpaSceneHit {
    var unseen = vec3<f32>(0.0);
    return arpa_scene_intersect_seen(start, dir, t_max, rng, &unseen);
}

// PreparedScene::intersect_seen: arpa_scene_intersect_masked for a camera ray, adding to
// *seen the radiance of the area lights it passes that emit towards it (the one mask loop;
// arpa_scene_intersect_masked discards what it sees).
fn arpa_scene_intersect_seen(start: ArpaRayStart, dir: vec3<f32>, t_max: f32, rng: ptr<function, ArpaRng>, seen: ptr<function, vec3<f32>>) -> ArpaSceneHit {
    if arpa_scene_info.has_masks == 0u {
        return arpa_start_intersect(start, dir, t_max);
    }
    var at = start;
    var left = t_max;
    for (var i = 0u; i < ARPA_MAX_MASK_PASSES; i++) {
        let h = arpa_start_intersect(at, dir, left);
        if h.hit == 0u || arpa_stops_with(arpa_scene_opacity(h), rng) {
            return h;
        }
        let m = arpa_scene_meshes[h.mesh];
        if m.emissive != 0u && dot(dir, arpa_scene_triangles[m.first_triangle + h.triangle].normal) < 0.0 {
            var e = m.emission;
            if m.emission_texture != ARPA_NO_TEXTURE {
                e *= max(arpa_texture_eval(m.emission_texture, arpa_scene_uv(h)), vec3<f32>(0.0));
            }
            *seen += e;
        }
        left -= h.t;
        at = arpa_ray_start_leaving_hit(h);
    }
    return arpa_start_intersect(at, dir, left);
}

// PreparedScene::occluded: whether the ray is stopped before t_max, masks passed as in
// arpa_scene_intersect_masked (without masks: arpa_start_occluded, drawing nothing).
fn arpa_scene_occluded_masked(start: ArpaRayStart, dir: vec3<f32>, t_max: f32, rng: ptr<function, ArpaRng>) -> bool {
    if arpa_scene_info.has_masks == 0u {
        return arpa_start_occluded(start, dir, t_max);
    }
    return arpa_scene_intersect_masked(start, dir, t_max, rng).hit != 0u;
}
