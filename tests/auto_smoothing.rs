//! Automatic smoothing (`arpa::session::auto_smoothing`, `arpa_core::propagate::classify::AutoSmoothing`)
//! on the cpu backend, for a point light over a large diffuse floor (every footprint a
//! plain ellipse, no heuristic but dampening acting):
//! - the pilot's `S` gives the target overlap: at the chosen `S`, a lit query point is
//!   covered by the bandwidth's target (8 footprints, `AutoSmoothing::for_bandwidth`)
//!   within 25 % (the `S^{2γ}` growth the choice assumes);
//! - the overlap then shrinks with the iterations as documented, `∝ (r_i/r_1)^{2(1−γ)}`
//!   (dampening pulls the axes towards twice the progressive radius `r_i`), within 10 %;
//! - the choice is deterministic (the same pilot twice gives the same `S`).

use arpa::backends::{self, BackendOptions};
use arpa::session::auto_smoothing;
use arpa_core::propagate::classify::AutoSmoothing;
use arpa_core::emit::emission::{Light, PointLight};
use arpa_core::glam::{DVec3, Vec3};
use arpa_core::store::heuristics::{DampenReference, Dampening, Heuristics};
use arpa_core::render::scene::{Camera, Material, Scene};
use arpa_core::render::shapes::parallelogram;
use arpa_core::render::tracer::{BackendKind, Method, RenderSettings, Tracer};

fn scene() -> Scene {
    Scene { textures: Default::default(),
        meshes: vec![parallelogram("floor", Vec3::new(-20.0, 0.0, -20.0), Vec3::new(0.0, 0.0, 40.0), Vec3::new(40.0, 0.0, 0.0), 0)],
        materials: vec![Material::Diffuse { albedo: Vec3::splat(0.5) }],
        lights: vec![Light::Point(PointLight { position: DVec3::new(0.0, 1.0, 0.0), intensity: DVec3::splat(10.0) })],
        camera: Camera { position: Vec3::new(0.0, 3.0, 0.01), target: Vec3::ZERO, up: Vec3::Y, vertical_fov: 0.6, width: 48, height: 48 },
        roughness_cutoff: 0.5,
        instancing: None,
    }
}

fn settings() -> RenderSettings {
    RenderSettings {
        method: Method::Arpa,
        photons_per_iteration: 20_000,
        seed: 3,
        max_depth: 1,
        direct_lighting: false,
        // Dampening alone: no H-max, culling or degenerate removal to cut the growth.
        heuristics: Heuristics { dampening: Some(Dampening { exponent: 0.25, reference: DampenReference::ProgressiveDiameter }), ..Heuristics::NONE },
        ..RenderSettings::default()
    }
}

#[test]
fn the_pilot_reaches_the_target_overlap_and_it_shrinks_with_the_radius() {
    let scene = scene();
    let mut settings = settings();
    let mut tracer = backends::create(BackendKind::Cpu, &BackendOptions::default()).expect("cpu backend");
    let auto = AutoSmoothing::default();
    let target = auto.for_bandwidth(settings.bandwidth).overlap;
    let pilot = auto_smoothing(&mut tracer, &scene, &settings, &auto).expect("pilot");
    let again = auto_smoothing(&mut tracer, &scene, &settings, &auto).expect("pilot");
    assert_eq!(pilot.smoothing, again.smoothing, "the pilot is not deterministic");
    let s = pilot.smoothing.global;
    assert!(s > auto.min && s < auto.max, "S_g {s} clamped: the test scene should need neither bound (pilot overlap {:?})", pilot.overlap_at_one);

    settings.smoothing = pilot.smoothing;
    tracer.upload_scene(&scene, &settings).expect("upload");
    let mut first = None;
    for i in 1..=32u32 {
        tracer.iterate().expect("iterate");
        let stats = tracer.read_stats().expect("stats");
        let (overlap, radius) = (stats.overlap()[1], stats.radii[1]);
        match first {
            None => {
                assert!((overlap / target - 1.0).abs() < 0.25, "iteration 1: overlap {overlap} at S_g {s}, target {target} (pilot {:?} at S = 1)", pilot.overlap_at_one);
                first = Some((overlap, radius));
            }
            Some((o1, r1)) if i.is_power_of_two() => {
                let want = o1 * (radius / r1).powf(2.0 * (1.0 - 0.25));
                assert!((overlap / want - 1.0).abs() < 0.1, "iteration {i}: overlap {overlap}, (r_i/r_1)^1.5 predicts {want} (r {radius} vs {r1})");
            }
            _ => {}
        }
    }
}
