//! The core's WGSL: the twin of the per-photon maths, and the path-level kernels (camera
//! pass, photon pass, store, sort, gather, accumulation) both GPU backends run, as files a
//! GPU renderer includes without the rest of arpa (WebGPU/wgpu directly, Vulkan through
//! naga).
//!
//! The files sit in the folders of the core's layers they twin (`base/`, `emit/`,
//! `propagate/`, `store/`, `gather/`, `accumulate/`; `store/aabb.wgsl` is only the stored
//! record's padded box of [`crate::base::aabb`]), the path-level kernels in `path/`.
//!
//! Each constant is one file of `arpa-core/shaders/` as a [`WgslFile`]: its source and the
//! files it needs. WGSL has no modules; [`compose`] concatenates any set of files with
//! everything they need, each file after its dependencies, in one deterministic order, and
//! hoists `enable` directives to the top. That table is the one place the include order is
//! declared: every module of a backend (and the conformance suite's twin kernels) comes
//! from `compose`. A backend adds its own files the same way (a [`WgslFile`] whose `deps`
//! name core files), e.g. the glue that implements the ray casting the path-level files
//! call ([`SCENE`], [`GATHER`] name the functions).
//!
//! Why concatenation and not a shader composer: `naga_oil` (0.23, on naga 30 like wgpu 30)
//! would need `#import` directives that make the files non-WGSL, std and regex (so the
//! order could not live in this `no_std` crate), and hands back re-emitted naga IR with
//! mangled names; `wesl` re-prints the source through its own parser and its current
//! release needs a newer Rust than the workspace. The files need no namespacing (every
//! name is prefixed `arpa_`/`Arpa`/`ARPA_`, or by its path-level file: `photon_`, `store_`,
//! `gather_`, `sort_`, `radix_`), so a dependency table gives the backends the exact source text with
//! nothing in between. Status codes replace the Rust error enums (each file lists them).
//!
//! | file | Rust twin | what |
//! |---|---|---|
//! | [`MATH`] | `f64::is_finite`, `libm::acos`, glam's `normalize_or` | finiteness tests, an accurate `acos` and angle between directions, glam's `f32` normalisation |
//! | [`RNG`] | [`crate::base::rng`] | `pcg4d`, streams; bit-identical `u32` and `f32` draws; `next_f64() < p` exactly; `next_f64() as f32` |
//! | [`KERNEL`] | [`crate::gather::kernel`] | constant, Epanechnikov and Silverman kernels (`f32`, as `Kernel::eval`) |
//! | [`FOOTPRINT`] | [`crate::store::footprint`] | `PackedFootprint` (same 64-byte layout), `Footprint::pack` (`M_p⁻¹` rows, slab, flux density), point-in-footprint test, irradiance |
//! | [`RADIUS`] | [`crate::accumulate::radius`] | progressive radius, closed form and recurrence |
//! | [`DIFFERENTIAL`] | [`crate::propagate::differential`] | transfer, reflection, refraction with total internal reflection; `refract_direction` |
//! | [`FRESNEL`] | [`crate::propagate::fresnel`] | `dielectric_reflectance` |
//! | [`FRAME`] | [`crate::base::frame`] | orthonormal frames (Duff et al.; with a tangent hint) |
//! | [`SAMPLING`] | [`crate::base::sampling`] | sphere, cone, concentric disc, cosine hemisphere, triangle, Fibonacci lattice |
//! | [`EMISSION`] | [`crate::emit::emission`] | `PreparedLight::emit` from a [`crate::emit::emission::PackedLight`] (same 160-byte layout) |
//! | [`REEMISSION`] | [`crate::propagate::reemission`] | virtual distance, `reemit`, cosine-distributed diffuse direction |
//! | [`LAMBERTIAN`] | [`crate::propagate::lambertian`] | two-sided Lambertian shading frame: cosine, adjoint ratio, re-emission direction |
//! | [`NORMAL_MAP`] | [`crate::propagate::normal_map`] | normal-mapped and bump-mapped shading normals, a triangle's texture-coordinate derivatives |
//! | [`HEURISTICS`] | [`crate::store::heuristics`] | `ResolvedHeuristics::store` from a [`crate::store::heuristics::PackedHeuristics`]: dampening, H-max, degenerate removal, box, culling, record |
//! | [`AABB`] | [`crate::base::aabb::Aabb::padded_f32`] | the padded acceleration-structure box of a record |
//! | [`MORTON`] | [`crate::base::morton::morton_code`] | 30-bit Morton code (bit-exact) |
//! | [`BANDWIDTH`] | [`crate::gather::scales`], `PackedFootprint::irradiance_scales`, `PackedPhoton::irradiance_scales` | the scale ladder: footprint and progressive-photon irradiance at every scale, luminance moments |
//!
//! The path-level files ([`PATH`]) are the GPU form of the pipeline, on the records of
//! [`crate::gpu::layout`]:
//!
//! | file | Rust reference | what |
//! |---|---|---|
//! | [`RECORDS`] | [`crate::gpu::layout`] | the records the kernels exchange (keyed footprints and photons, packed photons, query records, sort items) |
//! | [`TEXTURE`] | [`crate::render::texture`] | bitmap and checkerboard lookups on the word table of [`crate::gpu::texture`] |
//! | [`ENVIRONMENT`] | [`crate::render::environment`] | an environment map's value, density and sampling, and its photons, on the word table of [`crate::gpu::texture`] |
//! | [`SCENE`] | [`crate::render::prepared_scene::PreparedScene`] | the scene tables of [`crate::gpu::scene::SceneTables`] (group 0), surface points with textured colours, alpha masks; ray casting by the backend |
//! | [`CAMERA_PASS`] | [`crate::render::camera_path::trace_camera_path`] | one query record per pixel |
//! | [`PHOTON_PASS`] | [`crate::render::photon_path::trace_photon`] | one invocation per photon of a batch, keyed footprints and photons appended |
//! | [`STORE`] | [`crate::store`] | heuristics, fallback photons, sort keys, compaction into sorted maps with padded boxes |
//! | [`SORT`] | — | bitonic sort of sort items (the radix sort's reference in tests and benches; [`crate::gpu::sort`]) |
//! | [`RADIX`] | — | stable LSD radix sort of the store's sort items, the store's sort on both GPU backends ([`crate::gpu::sort`]) |
//! | [`GATHER`] | [`crate::gather::estimate::gather_brute_force`], [`crate::gather::estimate::gather_brute_force_scales`] | per-pixel radiance (every plane of [`crate::gather::scales`]) over the maps, summed over photon batches; box traversal by the backend |
//! | [`ACCUMULATE`] | [`crate::accumulate::image::RunningMean`] | the running mean of the iteration images |
//!
//! ## Precision
//! WGSL has `f32` only; the core propagates in `f64`. The integer code ([`RNG`]) is exact.
//! The `f32` code follows the core's formulas with the rounding of `f32`
//! (`ε₃₂ = 2⁻²³ ≈ 1.2e-7`), so a result agrees with the core to a relative error of a few
//! `ε₃₂` times the condition number of the step, stated in each file: `1/|sin θ|` for
//! `M_p⁻¹` (θ between `D_u` and `D_v`), `1/|D·N|` for the transfer, `1/k` for refraction
//! near the critical angle, errors measured against the magnitude of the summed terms. The
//! range is that of `f32`: the footprint code pre-scales its vectors so any normal-`f32`
//! magnitude works; the differential code handles magnitudes up to ~1e18 (the core: 1e30).
//! Labels decided at a threshold (degenerate footprint, grazing, total internal reflection)
//! can differ from the core's within the `f32` rounding of the tested quantity; the
//! footprint's degenerate test uses `16 ε₃₂` where the core uses `16 ε₆₄`.
//! The conformance suite's twin cases (`arpa-conformance`, `cases::twin`) run every
//! function on each backend's WGSL kernel runner (a GPU, or lavapipe) against the Rust
//! functions over random and stress inputs.

/// `base/math.wgsl`: `arpa_finite`, `arpa_finite3` (`is_finite` by the exponent bits),
/// `arpa_acos` (radians, a few `f32` ulps, where a device's built-in `acos` may be off by
/// 1e-4 rad), `arpa_angle_between` (radians between two unit directions, a few ulps also
/// near 0 and π), `arpa_glam_normalize_or` (glam's `Vec3::normalize_or`). Self-contained.
pub const MATH: WgslFile = WgslFile { name: "base/math.wgsl", source: include_str!("../../shaders/base/math.wgsl"), deps: &[] };

/// `base/rng.wgsl`: `arpa_pcg4d`, `ArpaRng`, `arpa_rng_new`, `arpa_rng_next_u32`,
/// `arpa_rng_next_f32` (24-bit `[0, 1)`), `arpa_rng_next_2d`, `arpa_rng_next_below`
/// (the core's `next_f64() < p`, bit-exact for an `f32` `p`), `arpa_rng_next_f64_as_f32`
/// (the core's `next_f64() as f32`, bit-exact).
pub const RNG: WgslFile = WgslFile { name: "base/rng.wgsl", source: include_str!("../../shaders/base/rng.wgsl"), deps: &[] };

/// `gather/kernel.wgsl`: `arpa_kernel_eval(kernel_id, r²)`, per unit filter-space area.
pub const KERNEL: WgslFile = WgslFile { name: "gather/kernel.wgsl", source: include_str!("../../shaders/gather/kernel.wgsl"), deps: &[] };

/// `store/footprint.wgsl`: `ArpaPackedFootprint`, `arpa_footprint_pack`,
/// `arpa_footprint_filter_coords`, `arpa_footprint_contains`, `arpa_footprint_faces`,
/// `arpa_footprint_irradiance`, `arpa_half_thickness`, `arpa_major_axis2`,
/// `arpa_footprint_axes` (principal axis lengths). Metres, W, W/m².
pub const FOOTPRINT: WgslFile = WgslFile { name: "store/footprint.wgsl", source: include_str!("../../shaders/store/footprint.wgsl"), deps: &[&KERNEL] };

/// `accumulate/radius.wgsl`: `arpa_radius(r₁, α, iteration)` and `arpa_radius_next`, metres.
pub const RADIUS: WgslFile = WgslFile { name: "accumulate/radius.wgsl", source: include_str!("../../shaders/accumulate/radius.wgsl"), deps: &[] };

/// `propagate/differential.wgsl`: `ArpaRayDiff`, `ArpaNormalDiff`, `arpa_diff_transfer`,
/// `arpa_diff_reflect`, `arpa_diff_refract`, `arpa_reflect_direction`, `ArpaRefracted`,
/// `arpa_refract_direction` ([`crate::propagate::differential::refract_direction`]). World space,
/// metres, unit directions.
pub const DIFFERENTIAL: WgslFile = WgslFile { name: "propagate/differential.wgsl", source: include_str!("../../shaders/propagate/differential.wgsl"), deps: &[&MATH] };

/// `propagate/fresnel.wgsl`: `arpa_dielectric_reflectance(cos_i, ior)`
/// ([`crate::propagate::fresnel::dielectric_reflectance`]; `cos_i` of the unit direction of travel
/// with the normal, either sign; `ior` inside over outside; a fraction in `[0, 1]`).
pub const FRESNEL: WgslFile = WgslFile { name: "propagate/fresnel.wgsl", source: include_str!("../../shaders/propagate/fresnel.wgsl"), deps: &[&MATH] };

/// `base/frame.wgsl`: `ArpaFrame`, `arpa_frame_from_normal`, `arpa_frame_from_normal_and_hint`,
/// `arpa_frame_to_world`, `arpa_frame_to_local`.
pub const FRAME: WgslFile = WgslFile { name: "base/frame.wgsl", source: include_str!("../../shaders/base/frame.wgsl"), deps: &[&MATH] };

/// `base/sampling.wgsl`: `arpa_uniform_sphere`, `arpa_uniform_cone` (takes `1 − cos θ_max`),
/// `arpa_uniform_disc`, `arpa_cosine_hemisphere`, `arpa_uniform_triangle`,
/// `arpa_fibonacci_lattice`.
pub const SAMPLING: WgslFile = WgslFile { name: "base/sampling.wgsl", source: include_str!("../../shaders/base/sampling.wgsl"), deps: &[] };

/// `emit/emission.wgsl`: `ArpaLight`
/// (= [`crate::emit::emission::PackedLight`]), `ArpaEmitted`, `arpa_emit`, `arpa_spot_falloff`,
/// `arpa_spot_falloff_at` (angles in radians).
pub const EMISSION: WgslFile = WgslFile { name: "emit/emission.wgsl", source: include_str!("../../shaders/emit/emission.wgsl"), deps: &[&MATH, &RNG, &DIFFERENTIAL, &FRAME, &SAMPLING] };

/// `store/heuristics.wgsl`: `ArpaHeuristics`
/// (= [`crate::store::heuristics::PackedHeuristics`]), `ArpaStored`, `arpa_store`.
pub const HEURISTICS: WgslFile = WgslFile { name: "store/heuristics.wgsl", source: include_str!("../../shaders/store/heuristics.wgsl"), deps: &[&KERNEL, &FOOTPRINT] };

/// `propagate/reemission.wgsl`: `ArpaReemitted`,
/// `arpa_virtual_distance`, `arpa_reemit`, `arpa_diffuse_direction`.
pub const REEMISSION: WgslFile = WgslFile { name: "propagate/reemission.wgsl", source: include_str!("../../shaders/propagate/reemission.wgsl"), deps: &[&MATH, &DIFFERENTIAL, &FRAME, &SAMPLING] };

/// `propagate/lambertian.wgsl`: `ArpaDiffuseShading`
/// (= [`crate::propagate::lambertian::DiffuseShading`], `valid = 0` for `None`),
/// `arpa_diffuse_shading_new`, `arpa_diffuse_below_shading_plane`, `arpa_diffuse_cosine`,
/// `arpa_diffuse_adjoint_ratio`, `ArpaReemissionDirection`, `arpa_diffuse_sample_reemission`,
/// `ARPA_MAX_ADJOINT_RATIO`. Unit vectors, world space.
pub const LAMBERTIAN: WgslFile = WgslFile { name: "propagate/lambertian.wgsl", source: include_str!("../../shaders/propagate/lambertian.wgsl"), deps: &[&MATH, &FRAME, &SAMPLING] };

/// [`crate::propagate::normal_map`]: `arpa_normal_mapped`, `arpa_bump_mapped`,
/// `arpa_texture_derivatives`.
pub const NORMAL_MAP: WgslFile = WgslFile { name: "propagate/normal_map.wgsl", source: include_str!("../../shaders/propagate/normal_map.wgsl"), deps: &[&MATH, &FRAME] };

/// `store/aabb.wgsl`: `ArpaBox`, `arpa_padded_box(centre, half)`: the twin of
/// [`crate::base::aabb::Aabb::padded_f32`] (metres; the file states the `f32` precision).
pub const AABB: WgslFile = WgslFile { name: "store/aabb.wgsl", source: include_str!("../../shaders/store/aabb.wgsl"), deps: &[&FOOTPRINT] };

/// `base/morton.wgsl`: `arpa_morton_code(p, lo, inv_extent)`, the twin of
/// [`crate::base::morton::morton_code`] (bit-exact).
pub const MORTON: WgslFile = WgslFile { name: "base/morton.wgsl", source: include_str!("../../shaders/base/morton.wgsl"), deps: &[] };

/// `gather/bandwidth.wgsl`: `ARPA_SCALES`, `ARPA_MOMENT_PLANES`, `ARPA_PLANES`
/// ([`crate::gather::scales::SCALES`], …), `arpa_inv_scale2`, `arpa_footprint_irradiance_scales`
/// ([`crate::store::footprint::PackedFootprint::irradiance_scales`]),
/// `arpa_photon_irradiance_scales`
/// ([`crate::store::progressive_photon::PackedPhoton::irradiance_scales`], on the photon's fields),
/// `arpa_luminance`, `arpa_moments` ([`crate::gather::scales::moments`]). W/m², metres.
pub const BANDWIDTH: WgslFile = WgslFile { name: "gather/bandwidth.wgsl", source: include_str!("../../shaders/gather/bandwidth.wgsl"), deps: &[&KERNEL, &FOOTPRINT] };

/// `path/records.wgsl`: `ArpaKeyedFootprint`, `ArpaKeyedPhoton`, `ArpaPackedPhoton`,
/// `ArpaQueryRecord`, `ArpaSortItem`: the records of [`crate::gpu::layout`] the path-level
/// kernels exchange.
pub const RECORDS: WgslFile = WgslFile { name: "path/records.wgsl", source: include_str!("../../shaders/path/records.wgsl"), deps: &[] };

/// `path/texture.wgsl`: `arpa_texture_eval`, `arpa_texture_eval_1` (the twin of
/// [`crate::render::texture::Texture::eval`] and `eval_1`) on the word table of
/// [`crate::gpu::texture`], read through `arpa_texture_word(i)`, which the including file
/// defines ([`SCENE`]: binding 5 of group 0).
pub const TEXTURE: WgslFile = WgslFile { name: "path/texture.wgsl", source: include_str!("../../shaders/path/texture.wgsl"), deps: &[&MATH] };

/// `path/environment.wgsl`: an environment map's value in a direction, its sampling
/// density, a direction drawn by it and a photon drawn by it (`arpa_env_*`), on the texture
/// words (the includer provides `arpa_texture_word`).
pub const ENVIRONMENT: WgslFile = WgslFile {
    name: "path/environment.wgsl",
    source: include_str!("../../shaders/path/environment.wgsl"),
    deps: &[&MATH, &RNG, &TEXTURE, &FRAME, &SAMPLING, &DIFFERENTIAL, &EMISSION],
};

/// `path/scene.wgsl`: bind group 0 of the camera and photon passes (bindings 1 to 5: the
/// tables of [`crate::gpu::scene::SceneTables`]), `ArpaSceneHit`, `arpa_scene_hit`,
/// `arpa_scene_miss`, `ArpaSurface`, `arpa_scene_surface`, `arpa_scene_triangle_vertices`,
/// `arpa_scene_triangle_normals`, `arpa_offset_origin`, `ARPA_SCENE_T_MAX`, and the ray
/// starts of [`crate::render::ray_cast::RayStart`] (`ArpaRayStart`, `arpa_ray_start_*`,
/// `arpa_start_intersect`, `arpa_start_occluded`), texture lookups at hits and the alpha
/// masks of [`crate::render::prepared_scene::PreparedScene::intersect`]
/// (`arpa_scene_intersect_masked`, `arpa_scene_occluded_masked`). The backend's glue adds binding 0 (its
/// acceleration structure over the triangles) and defines `arpa_scene_intersect` and
/// `arpa_scene_occluded` with a `t_min` (the file states their contract).
pub const SCENE: WgslFile = WgslFile { name: "path/scene.wgsl", source: include_str!("../../shaders/path/scene.wgsl"), deps: &[&MATH, &RNG, &FRESNEL, &RECORDS, &TEXTURE, &FRAME, &NORMAL_MAP] };

/// `path/camera_pass.wgsl`: per pixel `arpa_camera_trace` (group 1:
/// [`crate::gpu::layout::CameraParams`] and the query records); the backend's entry point
/// writes one record per pixel.
pub const CAMERA_PASS: WgslFile = WgslFile {
    name: "path/camera_pass.wgsl",
    source: include_str!("../../shaders/path/camera_pass.wgsl"),
    deps: &[&MATH, &RNG, &DIFFERENTIAL, &FRESNEL, &FRAME, &SAMPLING, &EMISSION, &LAMBERTIAN, &RECORDS, &SCENE, &ENVIRONMENT],
};

/// `path/photon_pass.wgsl`: per photon `photon_trace` (group 1:
/// [`crate::gpu::layout::PhotonParams`], the packed lights, the
/// [`crate::gpu::layout::EmitterRange`]s, the keyed footprint and photon append buffers and
/// [`crate::gpu::layout::PhotonCounters`]); the backend's entry point runs one photon per
/// invocation and counts emitted photons and segments.
pub const PHOTON_PASS: WgslFile = WgslFile {
    name: "path/photon_pass.wgsl",
    source: include_str!("../../shaders/path/photon_pass.wgsl"),
    deps: &[&MATH, &RNG, &DIFFERENTIAL, &FRESNEL, &FRAME, &SAMPLING, &EMISSION, &REEMISSION, &LAMBERTIAN, &RECORDS, &SCENE, &ENVIRONMENT],
};

/// `path/store.wgsl`: entry points `store_keyed`, `photon_keys`, `pad_items`,
/// `compact_footprints`, `compact_photons` (group 0, bindings 0 to 12;
/// [`crate::gpu::layout::StoreParams`], [`crate::gpu::layout::StoreCounts`]).
pub const STORE: WgslFile =
    WgslFile { name: "path/store.wgsl", source: include_str!("../../shaders/path/store.wgsl"), deps: &[&KERNEL, &FOOTPRINT, &HEURISTICS, &MORTON, &AABB, &RECORDS] };

/// `path/sort.wgsl`: entry points `sort_local`, `sort_merge`, `sort_global` (the bitonic
/// sort of [`crate::gpu::sort`]).
pub const SORT: WgslFile = WgslFile { name: "path/sort.wgsl", source: include_str!("../../shaders/path/sort.wgsl"), deps: &[&RECORDS] };

/// `path/radix.wgsl`: entry points `radix_count`, `radix_scan`, `radix_scatter` (one pass of
/// the LSD radix sort of [`crate::gpu::sort`]; group 0: source items, destination items,
/// counters, the [`crate::gpu::sort::RadixPass`] uniform).
pub const RADIX: WgslFile = WgslFile { name: "path/radix.wgsl", source: include_str!("../../shaders/path/radix.wgsl"), deps: &[&RECORDS] };

/// `path/gather.wgsl`: per record `arpa_gather_pixel` (group 0, bindings 0 to 6;
/// [`crate::gpu::layout::GatherImageParams`]; the backend's entry point calls it per record;
/// it writes every plane of [`crate::gather::scales`] the parameters ask for), per candidate
/// `arpa_gather_candidate` (every scale asked for), `ArpaGatherResult`. The backend's glue adds binding 7 (its
/// acceleration structure over the record boxes) and defines `arpa_gather_at` (the file
/// states its contract).
pub const GATHER: WgslFile = WgslFile { name: "path/gather.wgsl", source: include_str!("../../shaders/path/gather.wgsl"), deps: &[&KERNEL, &FOOTPRINT, &BANDWIDTH, &RECORDS] };

/// `path/schedule.wgsl`: entry points `store_schedule` and `store_check` (one invocation
/// each; group 0: the photon pass's [`crate::gpu::layout::PhotonCounters`], the store's
/// [`crate::gpu::layout::StoreParams`], six words of indirect dispatch arguments, the
/// iteration's status word, the store's [`crate::gpu::layout::StoreCounts`]): the store's
/// record counts and dispatch sizes from the device's counters, so that no readback sits
/// between the photon pass and the store, and the status word that tells the accumulation
/// the iteration dropped records.
pub const SCHEDULE: WgslFile = WgslFile { name: "path/schedule.wgsl", source: include_str!("../../shaders/path/schedule.wgsl"), deps: &[] };

/// `path/accumulate.wgsl`: entry point `accumulate` ([`crate::gpu::layout::AccumPixel`];
/// binding 2: the iteration's status word, which leaves the sums alone when set).
pub const ACCUMULATE: WgslFile = WgslFile { name: "path/accumulate.wgsl", source: include_str!("../../shaders/path/accumulate.wgsl"), deps: &[&MATH] };

/// The twin files: every one is a function-level twin of the core, checked against it by
/// the conformance suite's twin cases (which run them composed together).
pub const TWIN: [&WgslFile; 17] =
    [&MATH, &RNG, &KERNEL, &FOOTPRINT, &RADIUS, &DIFFERENTIAL, &FRESNEL, &FRAME, &SAMPLING, &EMISSION, &HEURISTICS, &REEMISSION, &LAMBERTIAN, &AABB, &MORTON, &BANDWIDTH, &NORMAL_MAP];

/// The path-level files.
pub const PATH: [&WgslFile; 12] = [&RECORDS, &TEXTURE, &ENVIRONMENT, &SCENE, &CAMERA_PASS, &PHOTON_PASS, &STORE, &SCHEDULE, &SORT, &RADIX, &GATHER, &ACCUMULATE];

/// One WGSL file with the files it needs (WGSL has no imports: [`compose`] includes them).
#[derive(Clone, Copy, Debug)]
pub struct WgslFile {
    /// Path below the directory of the crate's shaders (`arpa-core/shaders/` for the
    /// core's; a backend names its own files so that they do not collide, e.g.
    /// `arpa-wgpu/…`). Unique: [`compose`] includes a file once per name.
    pub name: &'static str,
    /// The WGSL source.
    pub source: &'static str,
    /// The files whose declarations this one uses.
    pub deps: &'static [&'static WgslFile],
}

/// One WGSL module of `files` and everything they need: each file once, after its
/// dependencies (depth first, in the order `files` and each file's `deps` list them), with
/// the `enable` directives of all of them first (WGSL wants directives before any
/// declaration). Each file starts with a `// arpa: <name>` line, so that a compiler's line
/// numbers can be traced back.
#[cfg(feature = "alloc")]
#[cfg_attr(docsrs, doc(cfg(feature = "alloc")))]
pub fn compose(files: &[&'static WgslFile]) -> alloc::string::String {
    compose_with(files, "")
}

/// [`compose`] with a source of one's own after the files: a renderer's kernel that calls
/// the twin's functions, made at run time (its `enable` directives are hoisted with the
/// files'; it follows a `// arpa: user` line).
#[cfg(feature = "alloc")]
#[cfg_attr(docsrs, doc(cfg(feature = "alloc")))]
pub fn compose_with(files: &[&'static WgslFile], user: &str) -> alloc::string::String {
    use alloc::string::String;
    use alloc::vec::Vec;
    fn visit(file: &'static WgslFile, order: &mut Vec<&'static WgslFile>) {
        if order.iter().any(|f| f.name == file.name) {
            return;
        }
        for dep in file.deps {
            visit(dep, order);
        }
        order.push(file);
    }
    let mut order = Vec::new();
    for file in files {
        visit(file, &mut order);
    }
    let is_directive = |line: &str| {
        let t = line.trim();
        t.starts_with("enable ") && t.ends_with(';')
    };
    let mut directives: Vec<&str> = Vec::new();
    for source in order.iter().map(|f| f.source).chain([user]) {
        for line in source.lines().filter(|l| is_directive(l)) {
            if !directives.contains(&line.trim()) {
                directives.push(line.trim());
            }
        }
    }
    let mut out = String::new();
    for d in &directives {
        out.push_str(d);
        out.push('\n');
    }
    for file in &order {
        out.push_str("// arpa: ");
        out.push_str(file.name);
        out.push('\n');
        for line in file.source.lines().filter(|l| !is_directive(l)) {
            out.push_str(line);
            out.push('\n');
        }
    }
    if !user.is_empty() {
        out.push_str("// arpa: user\n");
        for line in user.lines().filter(|l| !is_directive(l)) {
            out.push_str(line);
            out.push('\n');
        }
    }
    out
}

#[cfg(all(test, feature = "alloc"))]
mod tests {
    use super::*;
    use alloc::vec::Vec;

    fn all() -> Vec<&'static WgslFile> {
        TWIN.iter().chain(PATH.iter()).copied().collect()
    }

    #[test]
    fn names_are_unique_and_name_their_files() {
        let files = all();
        for (i, f) in files.iter().enumerate() {
            assert!(files[i + 1..].iter().all(|g| g.name != f.name), "{} listed twice", f.name);
            assert!(f.name.ends_with(".wgsl") && !f.source.is_empty(), "{}", f.name);
        }
    }

    #[test]
    fn every_dependency_is_listed() {
        let files = all();
        for f in &files {
            for d in f.deps {
                assert!(files.iter().any(|g| g.name == d.name), "{} needs {}, which is in neither TWIN nor PATH", f.name, d.name);
            }
        }
    }

    #[test]
    fn compose_puts_each_file_once_after_its_dependencies() {
        let src = compose(&[&STORE, &GATHER, &FOOTPRINT]);
        let at = |f: &WgslFile| {
            let marker = alloc::format!("// arpa: {}\n", f.name);
            assert_eq!(src.matches(marker.as_str()).count(), 1, "{}", f.name);
            src.find(marker.as_str()).unwrap()
        };
        for f in [&STORE, &GATHER, &KERNEL, &FOOTPRINT, &HEURISTICS, &MORTON, &AABB, &RECORDS] {
            for d in f.deps {
                assert!(at(d) < at(f), "{} before its dependency {}", f.name, d.name);
            }
        }
        assert!(!src.contains("path/scene.wgsl"), "only what the files need");
        assert_eq!(compose(&[&KERNEL]), alloc::format!("// arpa: gather/kernel.wgsl\n{}", KERNEL.source));
    }

    #[test]
    fn enable_directives_come_first_once() {
        static GLUE: WgslFile = WgslFile { name: "test/glue.wgsl", source: "enable wgpu_ray_query;\nfn glue() {}\n", deps: &[&SCENE] };
        static OTHER: WgslFile = WgslFile { name: "test/other.wgsl", source: "  enable wgpu_ray_query;\nfn other() {}\n", deps: &[&GLUE] };
        let src = compose(&[&OTHER, &GLUE]);
        assert!(src.starts_with("enable wgpu_ray_query;\n// arpa: base/math.wgsl\n"), "{}", &src[..80]);
        assert_eq!(src.matches("enable ").count(), 1);
        assert!(src.find("fn glue").unwrap() < src.find("fn other").unwrap());
    }
}
