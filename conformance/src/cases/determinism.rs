//! Determinism: the same scene, settings and seed give a bit-identical image.

use arpa_core::tracer::{Image, Method, RenderSettings};

use crate::dyn_tracer::DynTracer;
use crate::scenes;
use crate::suite::{CaseResult, Context};

fn render(t: &mut dyn DynTracer, settings: &RenderSettings) -> Result<Image, String> {
    t.upload_scene(&scenes::glass_mirror_room(24), settings)
        .ctx("upload_scene")?;
    for _ in 0..2 {
        t.iterate().ctx("iterate")?;
    }
    t.read_image().ctx("read_image")
}

/// Renders the glass-and-mirror room (ARPA, next-event estimation on, 2 iterations of
/// 3000 photons) twice from a fresh upload and compares every pixel's bits.
pub fn same_seed_twice(t: &mut dyn DynTracer) -> CaseResult {
    let settings = RenderSettings {
        method: Method::Arpa,
        photons_per_iteration: 3000,
        seed: 3,
        max_depth: 8,
        ..RenderSettings::default()
    };
    let a = render(t, &settings)?;
    let b = render(t, &settings)?;
    if (a.width, a.height) != (b.width, b.height) || a.pixels.len() != b.pixels.len() {
        return Err("image sizes differ".into());
    }
    let bits = |i: &Image| {
        i.pixels
            .iter()
            .flat_map(|p| p.to_array().map(f32::to_bits))
            .collect::<Vec<_>>()
    };
    let (ba, bb) = (bits(&a), bits(&b));
    let differing = ba
        .chunks(3)
        .zip(bb.chunks(3))
        .filter(|(x, y)| x != y)
        .count();
    let lit = a.pixels.iter().filter(|p| p.max_element() > 0.0).count();
    if lit * 2 < a.pixels.len() {
        return Err(format!(
            "degenerate: only {lit} of {} pixels lit",
            a.pixels.len()
        ));
    }
    if differing > 0 {
        return Err(format!(
            "{differing} of {} pixels differ between two runs with seed {}",
            a.pixels.len(),
            settings.seed
        ));
    }
    Ok(format!(
        "{} px ({lit} lit) bit-identical over 2 runs × 2 iterations",
        a.pixels.len()
    ))
}
