//! The cases. Each asserts physics (a closed-form answer) or exact agreement with
//! `arpa-core`'s reference computation; none compares with an image the code produced
//! itself.

use crate::suite::{Case, CaseBody};

pub mod analytic;
pub mod common;
pub mod bandwidth;
pub mod blend;
pub mod bad_input;
pub mod camera;
pub mod determinism;
pub mod environment;
pub mod gather;
pub mod normal_maps;
pub mod open_mirror;
pub mod optics;
pub mod reference;
pub mod stage;
pub mod textures;
pub mod thin_glass;
pub mod twin;

/// Every case, in report-row order.
pub fn all() -> Vec<Case> {
    vec![
        Case {
            id: "stage-photon-pass",
            title: "photon pass = core trace_photon (glass slab + mirror)",
            needs: None,
            run: CaseBody::Tracer(stage::photon_pass_agreement),
        },
        Case {
            id: "gather-exact-arpa-biweight",
            title: "gather = gather_brute_force (arpa, biweight)",
            needs: None,
            run: CaseBody::Tracer(gather::arpa_biweight),
        },
        Case {
            id: "gather-exact-arpa-constant",
            title: "gather = gather_brute_force (arpa, constant kernel)",
            needs: None,
            run: CaseBody::Tracer(gather::arpa_constant),
        },
        Case {
            id: "gather-exact-rtpm",
            title: "gather = gather_brute_force (rtpm)",
            needs: None,
            run: CaseBody::Tracer(gather::rtpm),
        },
        Case {
            id: "analytic-plane-arpa",
            title: "point light over plane, photons only (arpa)",
            needs: None,
            run: CaseBody::Tracer(analytic::plane_arpa),
        },
        Case {
            id: "texture-plane",
            title: "textured plane (checkerboard, sRGB bitmap) under a point light, photons only",
            needs: None,
            run: CaseBody::Tracer(textures::texture_plane),
        },
        Case {
            id: "normal-map-plane",
            title: "normal maps (both tangent frames) and a bump map tilt a lit plane's shading normal: radiance by the tilted cosine",
            needs: None,
            run: CaseBody::Tracer(normal_maps::normal_map_plane),
        },
        Case {
            id: "blend-plane",
            title: "a blend of white diffuse and a mirror (constant and textured weight) lights a plane by (1 − w) of the closed form",
            needs: None,
            run: CaseBody::Tracer(blend::blend_plane),
        },
        Case {
            id: "emitter-texture",
            title: "a textured area light (two radiances) lights the floor by its texture; seen, it shows it",
            needs: None,
            run: CaseBody::Tracer(textures::emitter_texture),
        },
        Case {
            id: "environment-constant",
            title: "a constant environment L over a diffuse plane: radiance ρL on it (NEE), L around it",
            needs: None,
            run: CaseBody::Tracer(environment::constant_environment),
        },
        Case {
            id: "environment-map",
            title: "an environment map over a diffuse plane: radiance ρE/π on it with E summed from the map (NEE and photons only)",
            needs: None,
            run: CaseBody::Tracer(environment::map_environment),
        },
        Case {
            id: "mask-plane",
            title: "a half-open mask halves the light behind it and shows the floor half the time",
            needs: None,
            run: CaseBody::Tracer(textures::mask_plane),
        },
        Case {
            id: "bandwidth-flat-plane",
            title: "per-pixel bandwidth: an evenly lit plane keeps the largest scale, unbiased",
            needs: None,
            run: CaseBody::Tracer(bandwidth::flat_plane),
        },
        Case {
            id: "bandwidth-shadow-edge",
            title: "per-pixel bandwidth: smaller scales at a hard shadow edge, sharper than global",
            needs: None,
            run: CaseBody::Tracer(bandwidth::shadow_edge_case),
        },
        Case {
            id: "analytic-thin-dielectric-arpa",
            title: "point light, thin dielectric sheet, plane: the sheet passes T = 1 − 2R/(1 + R) straight (photons and camera rays)",
            needs: None,
            run: CaseBody::Tracer(analytic::thin_sheet_arpa),
        },
        Case {
            id: "analytic-plane-rtpm",
            title: "point light over plane, photons only (rtpm)",
            needs: None,
            run: CaseBody::Tracer(analytic::plane_rtpm),
        },
        Case {
            id: "camera-mirror",
            title: "camera pass: query points through a plane mirror = geometric optics",
            needs: None,
            run: CaseBody::Tracer(camera::mirror),
        },
        Case {
            id: "camera-glass-slab",
            title: "camera pass: query points through a glass slab = geometric optics + Fresnel",
            needs: None,
            run: CaseBody::Tracer(camera::glass_slab),
        },
        Case {
            id: "camera-thin-glass",
            title: "camera pass: query points through a 4 µm sheet and a wedge's knife edge = geometric optics + Fresnel",
            needs: None,
            run: CaseBody::Tracer(thin_glass::camera),
        },
        Case {
            id: "analytic-thin-sheet-arpa",
            title: "point light through a 4 µm glass sheet: two-interface Fresnel transmittance (arpa)",
            needs: None,
            run: CaseBody::Tracer(thin_glass::photons_sheet_arpa),
        },
        Case {
            id: "analytic-glass-slab-arpa",
            title: "point light through glass slab: two-interface Fresnel transmittance (arpa)",
            needs: None,
            run: CaseBody::Tracer(analytic::glass_slab_arpa),
        },
        Case {
            id: "analytic-glass-slab-rtpm",
            title: "point light through glass slab: two-interface Fresnel transmittance (rtpm)",
            needs: None,
            run: CaseBody::Tracer(analytic::glass_slab_rtpm),
        },
        Case {
            id: "analytic-mirror-caustic-arpa",
            title: "point light and plane mirror: image-source caustic (arpa)",
            needs: None,
            run: CaseBody::Tracer(analytic::mirror_caustic_arpa),
        },
        Case {
            id: "analytic-mirror-caustic-rtpm",
            title: "point light and plane mirror: image-source caustic (rtpm)",
            needs: None,
            run: CaseBody::Tracer(analytic::mirror_caustic_rtpm),
        },
        Case {
            id: "analytic-open-mirror",
            title: "point light, small tilted mirror, open floor: image-source caustic and its flux, projection off and on (arpa)",
            needs: None,
            run: CaseBody::Tracer(open_mirror::open_mirror),
        },
        Case {
            id: "analytic-furnace-arpa-direct",
            title: "point light in closed sphere, all bounces (arpa, next-event)",
            needs: None,
            run: CaseBody::Tracer(analytic::furnace_arpa_direct),
        },
        Case {
            id: "analytic-furnace-rtpm-photons",
            title: "point light in closed sphere, all bounces (rtpm, photons only)",
            needs: None,
            run: CaseBody::Tracer(analytic::furnace_rtpm_photons_only),
        },
        Case {
            id: "reference-cornell-caustic",
            title: "cornell-caustic vs Mitsuba path (ground truth)",
            needs: Some(reference::cornell_caustic_data),
            run: CaseBody::Tracer(reference::cornell_caustic),
        },
        Case {
            id: "reference-caustic-glass",
            title: "caustic-glass vs LuxCore PhotonGI (ground truth)",
            needs: Some(reference::caustic_glass_data),
            run: CaseBody::Tracer(reference::caustic_glass),
        },
        Case {
            id: "reference-water-caustic",
            title: "water-caustic vs LuxCore PhotonGI (ground truth)",
            needs: Some(reference::water_caustic_data),
            run: CaseBody::Tracer(reference::water_caustic),
        },
        Case {
            id: "reference-veach-bidir",
            title: "veach-bidir vs Mitsuba path (ground truth)",
            needs: Some(reference::veach_bidir_data),
            run: CaseBody::Tracer(reference::veach_bidir),
        },
        Case {
            id: "reference-sponza-standin",
            title: "sponza-standin vs Mitsuba path (ground truth)",
            needs: Some(reference::sponza_standin_data),
            run: CaseBody::Tracer(reference::sponza_standin),
        },
        Case {
            id: "determinism",
            title: "same seed twice: bit-identical image",
            needs: None,
            run: CaseBody::Tracer(determinism::same_seed_twice),
        },
        Case {
            id: "resume-merge",
            title: "checkpoint resumed, parts merged: bit-identical image",
            needs: None,
            run: CaseBody::Tracer(determinism::resume_and_merge),
        },
        Case {
            id: "instancing",
            title: "instanced scene = its flattened copy: bit-identical image",
            needs: None,
            run: CaseBody::Tracer(determinism::instanced_equals_flattened),
        },
        Case {
            id: "determinism-threads",
            title: "1 vs 2 host threads: bit-identical image",
            needs: None,
            run: CaseBody::Tracer(determinism::thread_count_invariant),
        },
        Case {
            id: "bad-input",
            title: "bad scenes rejected by upload_scene (no panic)",
            needs: None,
            run: CaseBody::Tracer(bad_input::rejected),
        },
        Case {
            id: "twin-rng",
            title: "WGSL twin rng.wgsl = arpa_core::base::rng (known answers and random streams, bit-exact)",
            needs: None,
            run: CaseBody::Kernels(twin::rng::matches_core),
        },
        Case {
            id: "twin-rng-draws",
            title: "WGSL twin rng.wgsl f64-mirroring draws = arpa_core::base::rng (next_below, next_f64 as f32; bit-exact)",
            needs: None,
            run: CaseBody::Kernels(twin::rng_draws::matches_core),
        },
        Case {
            id: "twin-math",
            title: "WGSL twin math.wgsl = is_finite, f64 acos and angle, glam normalize_or",
            needs: None,
            run: CaseBody::Kernels(twin::math::matches_core),
        },
        Case {
            id: "twin-fresnel",
            title: "WGSL twin fresnel.wgsl + refract_direction = arpa_core::propagate::fresnel, differential (reflectance, refraction)",
            needs: None,
            run: CaseBody::Kernels(twin::fresnel::matches_core),
        },
        Case {
            id: "twin-differential",
            title: "WGSL twin differential.wgsl = arpa_core::propagate::differential (transfer, reflect, refract, TIR)",
            needs: None,
            run: CaseBody::Kernels(twin::differential::matches_core),
        },
        Case {
            id: "twin-emission",
            title: "WGSL twin emission.wgsl = arpa_core::emit::emission (every light kind, Fibonacci lattice)",
            needs: None,
            run: CaseBody::Kernels(twin::emission::matches_core),
        },
        Case {
            id: "twin-spot-falloff",
            title: "WGSL twin spot falloff (emission.wgsl) = SpotLight::falloff_at",
            needs: None,
            run: CaseBody::Kernels(twin::spot_falloff::matches_core),
        },
        Case {
            id: "twin-texture",
            title: "WGSL twin texture.wgsl = arpa_core::render::texture (bitmaps: 8-bit sRGB, raw, float; filters, wraps, to_uv; checkerboards)",
            needs: None,
            run: CaseBody::Kernels(twin::texture::matches_core),
        },
        Case {
            id: "twin-reemission",
            title: "WGSL twin reemission.wgsl = arpa_core::propagate::reemission",
            needs: None,
            run: CaseBody::Kernels(twin::reemission::matches_core),
        },
        Case {
            id: "twin-lambertian",
            title: "WGSL twin lambertian.wgsl = arpa_core::propagate::lambertian (shading frame, adjoint ratio, re-emission)",
            needs: None,
            run: CaseBody::Kernels(twin::lambertian::matches_core),
        },
        Case {
            id: "twin-footprint",
            title: "WGSL twin footprint.wgsl + kernel.wgsl + bandwidth.wgsl = arpa_core::store::footprint, kernel, bandwidth (record, M_p^-1, gather test, scale ladder, moments)",
            needs: None,
            run: CaseBody::Kernels(twin::footprint::matches_core),
        },
        Case {
            id: "twin-heuristics",
            title: "WGSL twin heuristics.wgsl = ResolvedHeuristics::store",
            needs: None,
            run: CaseBody::Kernels(twin::heuristics::matches_core),
        },
        Case {
            id: "twin-radius",
            title: "WGSL twin radius.wgsl = arpa_core::accumulate::radius (progressive radius schedule)",
            needs: None,
            run: CaseBody::Kernels(twin::radius::matches_core),
        },
    ]
}
