//! Determinism: the same scene, settings and seed give a bit-identical image, and so does
//! the same scene with its instancing recorded or stripped.

use arpa_core::accumulate::image::Accumulation;
use arpa_core::render::tracer::{Image, Method, RenderSettings};

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

/// Checkpoint, resume and merge: the glass-and-mirror room rendered for 4 iterations in one
/// go; again for 2 iterations, its accumulation read back and continued on a fresh upload
/// for 2 more; and as two parts (iterations 0..2 and 2..4 from empty accumulations)
/// merged on the host. All three images must be bit-identical (the same random streams and
/// radii for each iteration index, sums kept exactly), and an accumulation of another
/// image size must be refused.
pub fn resume_and_merge(t: &mut dyn DynTracer) -> CaseResult {
    let settings = settings(3000);
    let scene = scenes::glass_mirror_room(24);
    let run = |t: &mut dyn DynTracer, from: Option<&Accumulation>, iterations: u32| -> Result<Accumulation, String> {
        t.upload_scene(&scene, &settings).ctx("upload_scene")?;
        if let Some(a) = from {
            t.restore_accumulation(a).ctx("restore_accumulation")?;
        }
        for _ in 0..iterations {
            t.iterate().ctx("iterate")?;
        }
        t.read_accumulation().ctx("read_accumulation")
    };
    let full = run(t, None, 4)?;
    let whole = t.read_image().ctx("read_image")?;
    if (full.first_iteration, full.iterations, t.iterations()) != (0, 4, 4) {
        return Err(format!("accumulation covers {}..{} after 4 iterations", full.first_iteration, full.end()));
    }
    let as_image = |a: &Accumulation| Image { width: a.width, height: a.height, pixels: a.mean() };
    identical(&whole, &as_image(&full), "read_image and the mean of read_accumulation")?;

    let half = run(t, None, 2)?;
    let resumed = run(t, Some(&half), 2)?;
    if (resumed.first_iteration, resumed.iterations, t.iterations()) != (0, 4, 4) {
        return Err(format!("after resuming 2 iterations and rendering 2 more: {}..{}, iterations() = {}", resumed.first_iteration, resumed.end(), t.iterations()));
    }
    identical(&whole, &t.read_image().ctx("read_image")?, "an uninterrupted run and a resumed one")?;

    let first = run(t, Some(&Accumulation::empty(scene.camera.width, scene.camera.height, 0)), 2)?;
    let second = run(t, Some(&Accumulation::empty(scene.camera.width, scene.camera.height, 2)), 2)?;
    let merged = Accumulation::merge(&[second, first]).map_err(|e| format!("merge: {e}"))?;
    if (merged.first_iteration, merged.iterations) != (0, 4) {
        return Err(format!("merged parts cover {}..{}", merged.first_iteration, merged.end()));
    }
    let lit = identical(&whole, &as_image(&merged), "an uninterrupted run and two merged parts")?;

    t.upload_scene(&scene, &settings).ctx("upload_scene")?;
    if t.restore_accumulation(&Accumulation::empty(scene.camera.width + 1, scene.camera.height, 0)).is_ok() {
        return Err("an accumulation of another image size was accepted".into());
    }
    Ok(format!("{} px ({lit} lit) bit-identical: 4 iterations, 2 + resumed 2, parts 0..2 + 2..4 merged", whole.pixels.len()))
}

/// Instancing: the instanced room ([`scenes::instanced_room`]: three copies of a glass
/// ball, a box and a mirror, rotated, scaled and one mirrored) rendered with its
/// instancing recorded (a backend that can instances the group in its acceleration
/// structure) and with it stripped (every copy a mesh of its own), ARPA with next-event
/// estimation, 2 iterations of 5000 photons: the two images must be bit-identical.
pub fn instanced_equals_flattened(t: &mut dyn DynTracer) -> CaseResult {
    let settings = RenderSettings { photons_per_iteration: 5000, ..settings(5000) };
    let instanced = scenes::instanced_room(32);
    let mut flattened = instanced.clone();
    flattened.instancing = None;
    let mut images = Vec::new();
    for scene in [&instanced, &flattened] {
        t.upload_scene(scene, &settings).ctx("upload_scene")?;
        for _ in 0..2 {
            t.iterate().ctx("iterate")?;
        }
        images.push(t.read_image().ctx("read_image")?);
    }
    let lit = identical(&images[0], &images[1], "the instanced and the flattened scene")?;
    Ok(format!("{} px ({lit} lit) bit-identical, instanced and flattened", images[0].pixels.len()))
}
