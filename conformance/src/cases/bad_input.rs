//! Bad input: scenes no backend can render are refused by `upload_scene` with an error,
//! never a panic, and the tracer still accepts a good scene afterwards.

use std::panic::{AssertUnwindSafe, catch_unwind};

use arpa_core::glam::Vec3;
use arpa_core::render::scene::Scene;
use arpa_core::render::tracer::RenderSettings;

use crate::dyn_tracer::DynTracer;
use crate::scenes;
use crate::suite::{CaseResult, Context};

fn bad_scenes() -> Vec<(&'static str, Scene)> {
    let good = scenes::lit_plane(8);
    let mut nan = good.clone();
    nan.meshes[0].positions[2].y = f32::NAN;
    let mut zero_area_mesh = good.clone();
    zero_area_mesh.meshes.push(arpa_core::render::scene::TriangleMesh { uvs: None,
        name: "collinear lamp".into(),
        positions: vec![
            Vec3::new(0.0, 2.0, 0.0),
            Vec3::new(1.0, 2.0, 0.0),
            Vec3::new(2.0, 2.0, 0.0),
        ],
        normals: None,
        indices: vec![[0, 1, 2]],
        material: 0,
        emission: Some(Vec3::splat(10.0)),
    });
    let mut zero_area_light = good.clone();
    zero_area_light
        .lights
        .push(scenes::zero_area_triangle_light());
    let mut no_lights = good.clone();
    no_lights.lights.clear();
    vec![
        ("NaN vertex", nan),
        ("zero-area emissive mesh", zero_area_mesh),
        ("zero-area triangle light", zero_area_light),
        ("no lights", no_lights),
    ]
}

/// Each bad scene: `upload_scene` returns `Err` without panicking; then the good scene
/// uploads and one iteration runs.
pub fn rejected(t: &mut dyn DynTracer) -> CaseResult {
    let settings = RenderSettings {
        photons_per_iteration: 1000,
        ..RenderSettings::default()
    };
    let mut problems = Vec::new();
    let cases = bad_scenes();
    for (what, scene) in &cases {
        match catch_unwind(AssertUnwindSafe(|| t.upload_scene(scene, &settings))) {
            Ok(Err(_)) => {}
            Ok(Ok(())) => problems.push(format!("{what}: accepted")),
            Err(_) => problems.push(format!("{what}: panicked")),
        }
    }
    if !problems.is_empty() {
        return Err(problems.join("; "));
    }
    t.upload_scene(&scenes::lit_plane(8), &settings)
        .ctx("good scene after the bad ones: upload_scene")?;
    t.iterate().ctx("good scene after the bad ones: iterate")?;
    Ok(format!(
        "{}/{} rejected ({}); good scene renders afterwards",
        cases.len(),
        cases.len(),
        cases.iter().map(|c| c.0).collect::<Vec<_>>().join(", ")
    ))
}
