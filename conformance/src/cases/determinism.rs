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

/// ARPA with next-event estimation, seed 3, `photons` per iteration.
fn settings(photons: u32) -> RenderSettings {
    RenderSettings {
        method: Method::Arpa,
        photons_per_iteration: photons,
        seed: 3,
        max_depth: 8,
        ..RenderSettings::default()
    }
}

/// Compares two images bit for bit; `Ok(lit pixels)` when identical and mostly lit.
fn identical(a: &Image, b: &Image, what: &str) -> Result<usize, String> {
    if (a.width, a.height) != (b.width, b.height) || a.pixels.len() != b.pixels.len() {
        return Err("image sizes differ".into());
    }
    let differing = a
        .pixels
        .iter()
        .zip(&b.pixels)
        .filter(|(x, y)| x.to_array().map(f32::to_bits) != y.to_array().map(f32::to_bits))
        .count();
    let lit = a.pixels.iter().filter(|p| p.max_element() > 0.0).count();
    if lit * 2 < a.pixels.len() {
        return Err(format!("degenerate: only {lit} of {} pixels lit", a.pixels.len()));
    }
    if differing > 0 {
        return Err(format!("{differing} of {} pixels differ between {what}", a.pixels.len()));
    }
    Ok(lit)
}

/// Renders the glass-and-mirror room (ARPA, next-event estimation on, 2 iterations of
/// 3000 photons) twice from a fresh upload and compares every pixel's bits.
pub fn same_seed_twice(t: &mut dyn DynTracer) -> CaseResult {
    let settings = settings(3000);
    let a = render(t, &settings)?;
    let b = render(t, &settings)?;
    let lit = identical(&a, &b, &format!("two runs with seed {}", settings.seed))?;
    Ok(format!("{} px ({lit} lit) bit-identical over 2 runs × 2 iterations", a.pixels.len()))
}

/// Renders the same scene as [`same_seed_twice`] with the backend driven from a host
/// thread pool of one thread and from one of two threads (rayon, which the CPU backend
/// parallelises over; a GPU backend's host side must be just as indifferent) and compares
/// every pixel's bits. 20 000 photons per iteration, so that the photons span several
/// work chunks of a parallel photon pass.
pub fn thread_count_invariant(t: &mut dyn DynTracer) -> CaseResult {
    let settings = settings(20_000);
    let mut images = Vec::new();
    for threads in [1, 2] {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .map_err(|e| format!("thread pool of {threads}: {e}"))?;
        images.push(pool.install(|| render(&mut *t, &settings))?);
    }
    let lit = identical(&images[0], &images[1], "1 and 2 host threads")?;
    Ok(format!("{} px ({lit} lit) bit-identical with 1 and 2 host threads", images[0].pixels.len()))
}
