//! The cases. Each asserts physics (a closed-form answer) or exact agreement with
//! `arpa-core`'s reference computation; none compares with an image the code produced
//! itself.

use crate::suite::Case;

pub mod analytic;
pub mod bad_input;
pub mod camera;
pub mod determinism;
pub mod gather;
pub mod optics;
pub mod reference;
pub mod stage;

/// Every case, in report-row order.
pub fn all() -> Vec<Case> {
    vec![
        Case {
            id: "stage-photon-pass",
            title: "photon pass = core trace_photon (glass slab + mirror)",
            needs: None,
            run: stage::photon_pass_agreement,
        },
        Case {
            id: "gather-exact-arpa-biweight",
            title: "gather = gather_brute_force (arpa, biweight)",
            needs: None,
            run: gather::arpa_biweight,
        },
        Case {
            id: "gather-exact-arpa-constant",
            title: "gather = gather_brute_force (arpa, constant kernel)",
            needs: None,
            run: gather::arpa_constant,
        },
        Case {
            id: "gather-exact-rtpm",
            title: "gather = gather_brute_force (rtpm)",
            needs: None,
            run: gather::rtpm,
        },
        Case {
            id: "analytic-plane-arpa",
            title: "point light over plane, photons only (arpa)",
            needs: None,
            run: analytic::plane_arpa,
        },
        Case {
            id: "analytic-plane-rtpm",
            title: "point light over plane, photons only (rtpm)",
            needs: None,
            run: analytic::plane_rtpm,
        },
        Case {
            id: "camera-mirror",
            title: "camera pass: query points through a plane mirror = geometric optics",
            needs: None,
            run: camera::mirror,
        },
        Case {
            id: "camera-glass-slab",
            title: "camera pass: query points through a glass slab = geometric optics + Fresnel",
            needs: None,
            run: camera::glass_slab,
        },
        Case {
            id: "analytic-glass-slab-arpa",
            title: "point light through glass slab: two-interface Fresnel transmittance (arpa)",
            needs: None,
            run: analytic::glass_slab_arpa,
        },
        Case {
            id: "analytic-glass-slab-rtpm",
            title: "point light through glass slab: two-interface Fresnel transmittance (rtpm)",
            needs: None,
            run: analytic::glass_slab_rtpm,
        },
        Case {
            id: "analytic-mirror-caustic-arpa",
            title: "point light and plane mirror: image-source caustic (arpa)",
            needs: None,
            run: analytic::mirror_caustic_arpa,
        },
        Case {
            id: "analytic-mirror-caustic-rtpm",
            title: "point light and plane mirror: image-source caustic (rtpm)",
            needs: None,
            run: analytic::mirror_caustic_rtpm,
        },
        Case {
            id: "analytic-furnace-arpa-direct",
            title: "point light in closed sphere, all bounces (arpa, next-event)",
            needs: None,
            run: analytic::furnace_arpa_direct,
        },
        Case {
            id: "analytic-furnace-rtpm-photons",
            title: "point light in closed sphere, all bounces (rtpm, photons only)",
            needs: None,
            run: analytic::furnace_rtpm_photons_only,
        },
        Case {
            id: "reference-cornell-caustic",
            title: "cornell-caustic vs Mitsuba path (ground truth)",
            needs: Some(reference::cornell_caustic_data),
            run: reference::cornell_caustic,
        },
        Case {
            id: "reference-caustic-glass",
            title: "caustic-glass vs LuxCore PhotonGI (ground truth)",
            needs: Some(reference::caustic_glass_data),
            run: reference::caustic_glass,
        },
        Case {
            id: "reference-water-caustic",
            title: "water-caustic vs LuxCore PhotonGI (ground truth)",
            needs: Some(reference::water_caustic_data),
            run: reference::water_caustic,
        },
        Case {
            id: "reference-veach-bidir",
            title: "veach-bidir vs Mitsuba path (ground truth)",
            needs: Some(reference::veach_bidir_data),
            run: reference::veach_bidir,
        },
        Case {
            id: "reference-sponza-standin",
            title: "sponza-standin vs Mitsuba path (ground truth)",
            needs: Some(reference::sponza_standin_data),
            run: reference::sponza_standin,
        },
        Case {
            id: "determinism",
            title: "same seed twice: bit-identical image",
            needs: None,
            run: determinism::same_seed_twice,
        },
        Case {
            id: "determinism-threads",
            title: "1 vs 2 host threads: bit-identical image",
            needs: None,
            run: determinism::thread_count_invariant,
        },
        Case {
            id: "bad-input",
            title: "bad scenes rejected by upload_scene (no panic)",
            needs: None,
            run: bad_input::rejected,
        },
    ]
}

/// `|a − b| / |b|` for vectors (`|a − b|` when `b = 0`).
pub(crate) fn rel(a: arpa_core::glam::DVec3, b: arpa_core::glam::DVec3) -> f64 {
    let d = (a - b).length();
    let n = b.length();
    if n > 0.0 { d / n } else { d }
}
