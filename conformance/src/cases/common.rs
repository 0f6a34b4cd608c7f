//! What several cases share: a relative vector error, the projection on/off wrapper of
//! the analytic cases with the emission strategy it sets, and the lit-plane cases' settings.

/// `|a − b| / |b|` for vectors (`|a − b|` when `b = 0`).
pub(crate) fn rel(a: arpa_core::glam::DVec3, b: arpa_core::glam::DVec3) -> f64 {
    let d = (a - b).length();
    let n = b.length();
    if n > 0.0 { d / n } else { d }
}

thread_local! {
    /// The emission strategy the analytic cases render with ([`emission`]).
    static EMISSION: std::cell::Cell<arpa_core::render::tracer::EmissionStrategy> = std::cell::Cell::new(arpa_core::render::tracer::EmissionStrategy::default());
}

/// The emission strategy of the analytic case being run (projection on or off).
pub(crate) fn emission() -> arpa_core::render::tracer::EmissionStrategy {
    EMISSION.with(|e| e.get())
}

/// Runs an analytic case with projection on (the default: projection maps and a caustic
/// pass) and off (one pass over every light's whole domain); both must pass.
pub(crate) fn with_and_without_projection(t: &mut dyn crate::dyn_tracer::DynTracer, mut case: impl FnMut(&mut dyn crate::dyn_tracer::DynTracer) -> crate::suite::CaseResult) -> crate::suite::CaseResult {
    let mut run = |strategy: arpa_core::render::tracer::EmissionStrategy, t: &mut dyn crate::dyn_tracer::DynTracer| {
        EMISSION.with(|e| e.set(strategy));
        let r = case(t);
        EMISSION.with(|e| e.set(arpa_core::render::tracer::EmissionStrategy::default()));
        r
    };
    let on = run(arpa_core::render::tracer::EmissionStrategy::default(), t).map_err(|e| format!("projection on: {e}"))?;
    let off = run(arpa_core::render::tracer::EmissionStrategy::WHOLE_DOMAIN, t).map_err(|e| format!("projection off: {e}"))?;
    Ok(format!("projection on: {on}; off: {off}"))
}

/// The settings of the lit-plane cases (textures, normal maps, blends): ARPA, `photons`
/// per iteration, `seed`, four bounces, next-event estimation when `direct` (else photons
/// only) and the emission strategy of the case being run ([`emission`]).
pub(crate) fn plane_settings(photons: u32, seed: u32, direct: bool) -> arpa_core::render::tracer::RenderSettings {
    arpa_core::render::tracer::RenderSettings {
        method: arpa_core::render::tracer::Method::Arpa,
        photons_per_iteration: photons,
        seed,
        max_depth: 4,
        direct_lighting: direct,
        emission: emission(),
        ..arpa_core::render::tracer::RenderSettings::default()
    }
}
