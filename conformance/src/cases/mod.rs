//! The cases. Each asserts physics (a closed-form answer) or exact agreement with
//! `arpa-core`'s reference computation; none compares with an image the code produced
//! itself.

use crate::suite::Case;

pub mod analytic;
pub mod bad_input;
pub mod determinism;
pub mod gather;
pub mod stage;

/// Every case, in report-row order.
pub fn all() -> Vec<Case> {
    vec![
        Case {
            id: "stage-photon-pass",
            title: "photon pass = core trace_photon (glass slab + mirror)",
            run: stage::photon_pass_agreement,
        },
        Case {
            id: "gather-exact-arpa-biweight",
            title: "gather = gather_brute_force (arpa, biweight)",
            run: gather::arpa_biweight,
        },
        Case {
            id: "gather-exact-arpa-constant",
            title: "gather = gather_brute_force (arpa, constant kernel)",
            run: gather::arpa_constant,
        },
        Case {
            id: "gather-exact-rtpm",
            title: "gather = gather_brute_force (rtpm)",
            run: gather::rtpm,
        },
        Case {
            id: "analytic-plane-arpa",
            title: "point light over plane, photons only (arpa)",
            run: analytic::plane_arpa,
        },
        Case {
            id: "analytic-plane-rtpm",
            title: "point light over plane, photons only (rtpm)",
            run: analytic::plane_rtpm,
        },
        Case {
            id: "analytic-furnace-arpa-direct",
            title: "point light in closed sphere, all bounces (arpa, next-event)",
            run: analytic::furnace_arpa_direct,
        },
        Case {
            id: "analytic-furnace-rtpm-photons",
            title: "point light in closed sphere, all bounces (rtpm, photons only)",
            run: analytic::furnace_rtpm_photons_only,
        },
        Case {
            id: "determinism",
            title: "same seed twice: bit-identical image",
            run: determinism::same_seed_twice,
        },
        Case {
            id: "bad-input",
            title: "bad scenes rejected by upload_scene (no panic)",
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
