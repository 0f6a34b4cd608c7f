//! The WGSL twin of the core's per-photon maths, as source strings a GPU renderer can
//! include without the rest of arpa (WebGPU/wgpu directly, Vulkan through naga).
//!
//! Each constant is one file of `arpa-core/shaders/`. WGSL has no modules: a renderer
//! concatenates the files it needs, each after the ones it depends on ([`dependencies`];
//! [`ALL`] is in such an order), and its own code after them. Every name is prefixed
//! `arpa_`/`Arpa`/`ARPA_`, so the files never collide with each other or with the
//! renderer. Status codes replace the Rust error enums (each file lists them).
//!
//! | file | Rust twin | what |
//! |---|---|---|
//! | [`MATH`] | `f64::is_finite`, `libm::acos`, glam's `normalize_or` | finiteness tests, an accurate `acos` and angle between directions, glam's `f32` normalisation |
//! | [`RNG`] | [`crate::rng`] | `pcg4d`, streams; bit-identical `u32` and `f32` draws; `next_f64() < p` exactly; `next_f64() as f32` |
//! | [`KERNEL`] | [`crate::kernel`] | constant, Epanechnikov and Silverman kernels (`f32`, as `Kernel::eval`) |
//! | [`FOOTPRINT`] | [`crate::footprint`] | `PackedFootprint` (same 64-byte layout), `Footprint::pack` (`M_p⁻¹` rows, slab, flux density), point-in-footprint test, irradiance |
//! | [`RADIUS`] | [`crate::radius`] | progressive radius, closed form and recurrence |
//! | [`DIFFERENTIAL`] | [`crate::differential`] | transfer, reflection, refraction with total internal reflection; `refract_direction` |
//! | [`FRESNEL`] | [`crate::fresnel`] | `dielectric_reflectance` |
//! | [`FRAME`] | [`crate::frame`] | orthonormal frames (Duff et al.; with a tangent hint) |
//! | [`SAMPLING`] | [`crate::sampling`] | sphere, cone, concentric disc, cosine hemisphere, triangle, Fibonacci lattice |
//! | [`EMISSION`] | [`crate::emission`] | `PreparedLight::emit` from a [`crate::emission::PackedLight`] (same 160-byte layout) |
//! | [`REEMISSION`] | [`crate::reemission`] | virtual distance, `reemit`, cosine-distributed diffuse direction |
//! | [`LAMBERTIAN`] | [`crate::lambertian`] | two-sided Lambertian shading frame: cosine, adjoint ratio, re-emission direction |
//! | [`HEURISTICS`] | [`crate::heuristics`] | `ResolvedHeuristics::store` from a [`crate::heuristics::PackedHeuristics`]: dampening, H-max, degenerate removal, box, culling, record |
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

/// `math.wgsl`: `arpa_finite`, `arpa_finite3` (`is_finite` by the exponent bits),
/// `arpa_acos` (radians, a few `f32` ulps, where a device's built-in `acos` may be off by
/// 1e-4 rad), `arpa_angle_between` (radians between two unit directions, a few ulps also
/// near 0 and π), `arpa_glam_normalize_or` (glam's `Vec3::normalize_or`). Self-contained.
pub const MATH: &str = include_str!("../shaders/math.wgsl");

/// `rng.wgsl`: `arpa_pcg4d`, `ArpaRng`, `arpa_rng_new`, `arpa_rng_next_u32`,
/// `arpa_rng_next_f32` (24-bit `[0, 1)`), `arpa_rng_next_2d`, `arpa_rng_next_below`
/// (the core's `next_f64() < p`, bit-exact for an `f32` `p`), `arpa_rng_next_f64_as_f32`
/// (the core's `next_f64() as f32`, bit-exact).
pub const RNG: &str = include_str!("../shaders/rng.wgsl");

/// `kernel.wgsl`: `arpa_kernel_eval(kernel_id, r²)`, per unit filter-space area.
pub const KERNEL: &str = include_str!("../shaders/kernel.wgsl");

/// `footprint.wgsl` (needs [`KERNEL`]): `ArpaPackedFootprint`, `arpa_footprint_pack`,
/// `arpa_footprint_filter_coords`, `arpa_footprint_contains`, `arpa_footprint_faces`,
/// `arpa_footprint_irradiance`, `arpa_half_thickness`. Metres, W, W/m².
pub const FOOTPRINT: &str = include_str!("../shaders/footprint.wgsl");

/// `radius.wgsl`: `arpa_radius(r₁, α, iteration)` and `arpa_radius_next`, metres.
pub const RADIUS: &str = include_str!("../shaders/radius.wgsl");

/// `differential.wgsl` (needs [`MATH`]): `ArpaRayDiff`, `ArpaNormalDiff`, `arpa_diff_transfer`,
/// `arpa_diff_reflect`, `arpa_diff_refract`, `arpa_reflect_direction`, `ArpaRefracted`,
/// `arpa_refract_direction` ([`crate::differential::refract_direction`]). World space,
/// metres, unit directions.
pub const DIFFERENTIAL: &str = include_str!("../shaders/differential.wgsl");

/// `fresnel.wgsl` (needs [`MATH`]): `arpa_dielectric_reflectance(cos_i, ior)`
/// ([`crate::fresnel::dielectric_reflectance`]; `cos_i` of the unit direction of travel
/// with the normal, either sign; `ior` inside over outside; a fraction in `[0, 1]`).
pub const FRESNEL: &str = include_str!("../shaders/fresnel.wgsl");

/// `frame.wgsl` (needs [`MATH`]): `ArpaFrame`, `arpa_frame_from_normal`, `arpa_frame_from_normal_and_hint`,
/// `arpa_frame_to_world`, `arpa_frame_to_local`.
pub const FRAME: &str = include_str!("../shaders/frame.wgsl");

/// `sampling.wgsl`: `arpa_uniform_sphere`, `arpa_uniform_cone` (takes `1 − cos θ_max`),
/// `arpa_uniform_disc`, `arpa_cosine_hemisphere`, `arpa_uniform_triangle`,
/// `arpa_fibonacci_lattice`.
pub const SAMPLING: &str = include_str!("../shaders/sampling.wgsl");

/// `emission.wgsl` (needs [`MATH`], [`RNG`], [`FRAME`], [`SAMPLING`], [`DIFFERENTIAL`]): `ArpaLight`
/// (= [`crate::emission::PackedLight`]), `ArpaEmitted`, `arpa_emit`, `arpa_spot_falloff`,
/// `arpa_spot_falloff_at` (angles in radians).
pub const EMISSION: &str = include_str!("../shaders/emission.wgsl");

/// `heuristics.wgsl` (needs [`FOOTPRINT`], [`KERNEL`]): `ArpaHeuristics`
/// (= [`crate::heuristics::PackedHeuristics`]), `ArpaStored`, `arpa_store`.
pub const HEURISTICS: &str = include_str!("../shaders/heuristics.wgsl");

/// `reemission.wgsl` (needs [`MATH`], [`DIFFERENTIAL`], [`FRAME`], [`SAMPLING`]): `ArpaReemitted`,
/// `arpa_virtual_distance`, `arpa_reemit`, `arpa_diffuse_direction`.
pub const REEMISSION: &str = include_str!("../shaders/reemission.wgsl");

/// `lambertian.wgsl` (needs [`MATH`], [`FRAME`], [`SAMPLING`]): `ArpaDiffuseShading`
/// (= [`crate::lambertian::DiffuseShading`], `valid = 0` for `None`),
/// `arpa_diffuse_shading_new`, `arpa_diffuse_below_shading_plane`, `arpa_diffuse_cosine`,
/// `arpa_diffuse_adjoint_ratio`, `ArpaReemissionDirection`, `arpa_diffuse_sample_reemission`,
/// `ARPA_MAX_ADJOINT_RATIO`. Unit vectors, world space.
pub const LAMBERTIAN: &str = include_str!("../shaders/lambertian.wgsl");

/// Every file as `(file name, source)`, in an order in which concatenation satisfies each
/// file's dependencies.
pub const ALL: [(&str, &str); 13] = [
    ("math.wgsl", MATH),
    ("rng.wgsl", RNG),
    ("kernel.wgsl", KERNEL),
    ("footprint.wgsl", FOOTPRINT),
    ("radius.wgsl", RADIUS),
    ("differential.wgsl", DIFFERENTIAL),
    ("fresnel.wgsl", FRESNEL),
    ("frame.wgsl", FRAME),
    ("sampling.wgsl", SAMPLING),
    ("emission.wgsl", EMISSION),
    ("heuristics.wgsl", HEURISTICS),
    ("reemission.wgsl", REEMISSION),
    ("lambertian.wgsl", LAMBERTIAN),
];

/// The files each file needs before it (by name), for renderers that include a subset.
pub fn dependencies(file: &str) -> &'static [&'static str] {
    match file {
        "footprint.wgsl" => &["kernel.wgsl"],
        "fresnel.wgsl" => &["math.wgsl"],
        "differential.wgsl" | "frame.wgsl" => &["math.wgsl"],
        "emission.wgsl" => &["math.wgsl", "rng.wgsl", "differential.wgsl", "frame.wgsl", "sampling.wgsl"],
        "heuristics.wgsl" => &["kernel.wgsl", "footprint.wgsl"],
        "reemission.wgsl" => &["math.wgsl", "differential.wgsl", "frame.wgsl", "sampling.wgsl"],
        "lambertian.wgsl" => &["math.wgsl", "frame.wgsl", "sampling.wgsl"],
        _ => &[],
    }
}
