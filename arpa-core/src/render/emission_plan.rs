//! The plan of a render's two photon passes, built on the projection maps
//! ([`crate::render::projection`]): photons per light and pass, the balance weights of
//! caustic records, and which pass is skipped and why.
//!
//! **Two passes.** With projection on ([`crate::render::tracer::EmissionStrategy`]) the global
//! pass sends its photons into the cells that see any geometry and stores every record
//! (caustic ones too, see below); the caustic pass sends its own photons into the cells
//! that see a specular object and stores only caustic records (`L S+ D`: its photons end
//! at their first diffuse hit). Caustic records then come from two strategies with
//! densities `N_g/f_g` and `N_c/f_c` per unit of the light's domain (`f` the kept
//! fractions); the balance heuristic weights a global-pass caustic record by
//! `w_g = (N_g/f_g) / (N_g/f_g + N_c/f_c)` and a caustic-pass one by `w_c = 1 − w_g`
//! (constants per light: both densities are uniform over the caustic cells, which the
//! global cells contain). Where `w_g` falls below [`MIN_GLOBAL_CAUSTIC_WEIGHT`] the global
//! pass stores no caustic record at all and the caustic pass takes weight 1: its footprints
//! are small and the global pass's would add little but gather work.

use crate::render::prepared_scene::PreparedScene;
use crate::render::projection::{allocate, DomainCells, LightProjection};
use crate::render::tracer::{PassSkip, RenderSettings, Skipped};
use alloc::vec::Vec;

/// Below this balance weight the global pass stores no caustic records.
pub const MIN_GLOBAL_CAUSTIC_WEIGHT: f64 = 0.2;
/// The caustic pass's automatic share of the global pass's photons is at most this.
pub const MAX_AUTO_CAUSTIC_SHARE: f64 = 0.5;
/// Above this share `q` of the power (towards geometry) that already heads for specular
/// objects, no automatic caustic pass runs ([`auto_caustic_photons`]).
pub const MAX_AUTO_SPECULAR_SHARE: f64 = 0.25;

/// Why the caustic pass cannot run for the scene, from its projections (`None`: it can).
fn caustic_skip(scene: &PreparedScene) -> Option<PassSkip> {
    if !scene.has_specular() {
        return Some(PassSkip::NoSpecularSurface);
    }
    if scene.projections().iter().all(|p| p.specular.is_empty()) {
        let environment_only = scene.emitters().iter().all(|l| matches!(l, crate::emit::emission::Light::Environment(_)));
        return Some(if environment_only { PassSkip::EnvironmentOnly } else { PassSkip::SpecularUnreached });
    }
    None
}

/// The photons of the caustic pass chosen from the projected power:
/// `N_g · min(1/2, √q) · (1 − q)` for the global pass's `N_g` photons and `q` the power
/// the lights send towards specular objects over the power they send towards any
/// geometry (luminance). `q` is the share of the global photons that head for a specular
/// object already; the caustic pass adds `min(1/2, √q)(1 − q) / q` times their density
/// (about `1/√q` for small `q`) for a share of about `√q` more photons (short ones: they
/// end at their first diffuse hit), never more than half the global photons, and none
/// where every photon heads for a specular object anyway (`q = 1`: aiming gains nothing
/// there). None either above `q` = [`MAX_AUTO_SPECULAR_SHARE`]: the caustic density would
/// grow at most `1 + share/q` ≈ 2.5-fold there for ≥ 37 % more photons, whose paths through
/// the specular objects are the long ones, a trade that does not pay at equal time. At
/// least one photon when
/// `0 < q ≤ 1/4`; the caller takes `N_g` itself when the global pass does not run.
pub fn auto_caustic_photons(scene: &PreparedScene, global_photons: u32) -> u32 {
    let caustic: f64 = projected_powers(scene, |p| &p.specular).sum();
    let global: f64 = projected_powers(scene, |p| &p.geometry).sum();
    if !(caustic > 0.0) || !(global > 0.0) {
        return 0;
    }
    let q = (caustic / global).min(1.0);
    if q > MAX_AUTO_SPECULAR_SHARE {
        return 0;
    }
    let share = libm::sqrt(q).min(MAX_AUTO_CAUSTIC_SHARE) * (1.0 - q);
    if !(share > 0.0) {
        return 0;
    }
    (libm::ceil(global_photons as f64 * share) as u32).max(1)
}

/// Each emitter's power (luminance, W) times the fraction of its domain that `cells`
/// picks of its projections (0 for a projection that keeps no cell).
fn projected_powers<'a>(scene: &'a PreparedScene, cells: impl Fn(&LightProjection) -> &DomainCells + 'a) -> impl Iterator<Item = f64> + 'a {
    scene.projections().iter().zip(scene.emitter_powers()).map(move |(p, power)| power * cells(p).fraction())
}

/// Why the global pass cannot store anything (`None`: it can).
fn global_skip(scene: &PreparedScene, settings: &RenderSettings) -> Option<PassSkip> {
    if scene.projections().iter().all(|p| p.geometry.is_empty()) {
        return Some(PassSkip::NoLightReachesGeometry);
    }
    if settings.direct_lighting && !scene.can_bounce_twice(settings.max_depth) {
        return Some(PassSkip::NothingToBounceTo);
    }
    None
}

/// What one light emits in each pass of an iteration.
#[derive(Clone, Debug, PartialEq)]
pub struct LightPlan {
    /// Photons of the global pass.
    pub global: u32,
    /// Photons of the caustic pass.
    pub caustic: u32,
    /// Weight of the caustic records the global pass stores (0: it stores none).
    pub global_caustic_weight: f64,
    /// Weight of the caustic pass's records (1 when the global pass stores none).
    pub caustic_weight: f64,
}

/// The photon budget of an iteration over the lights and the two passes, with what it
/// skipped.
#[derive(Clone, Debug, PartialEq)]
pub struct EmissionPlan {
    /// Per emitter (in [`PreparedScene::emitters`] order).
    pub lights: Vec<LightPlan>,
    /// Whether the lights sample their projection cells (projection on).
    pub projected: bool,
    /// What was skipped.
    pub skipped: Skipped,
}

impl EmissionPlan {
    /// The plan for `scene` under `settings` (the same every iteration).
    pub fn new(scene: &PreparedScene, settings: &RenderSettings) -> Self {
        let n = scene.emitters().len();
        let strategy = settings.emission;
        if !strategy.projection {
            let global = scene.photon_allocation(settings.photons_per_iteration);
            let lights = global.into_iter().map(|g| LightPlan { global: g, caustic: 0, global_caustic_weight: 1.0, caustic_weight: 0.0 }).collect();
            return Self { lights, projected: false, skipped: Skipped::default() };
        }
        let projections = scene.projections();
        let geometry_power: Vec<f64> = projected_powers(scene, |p| &p.geometry).collect();
        let specular_power: Vec<f64> = projected_powers(scene, |p| &p.specular).collect();
        let total_power: f64 = scene.emitter_powers().iter().sum();
        let unreached = total_power - geometry_power.iter().sum::<f64>();
        let mut skipped = Skipped {
            lights: projections.iter().filter(|p| p.geometry.is_empty()).count() as u32,
            power_fraction: if total_power > 0.0 { (unreached / total_power).max(0.0) } else { 0.0 },
            global_pass: global_skip(scene, settings),
            caustic_pass: caustic_skip(scene),
        };
        let global_total = if skipped.global_pass.is_some() { 0 } else { settings.photons_per_iteration };
        let global = allocate(&geometry_power, global_total);
        let caustic_total = match (skipped.caustic_pass, strategy.caustic_photons) {
            (Some(_), _) => 0,
            (None, Some(c)) => c,
            (None, None) if global_total == 0 => settings.photons_per_iteration,
            (None, None) => auto_caustic_photons(scene, global_total),
        };
        if skipped.caustic_pass.is_none() && caustic_total == 0 {
            skipped.caustic_pass = Some(if strategy.caustic_photons.is_some() { PassSkip::NoCausticPhotons } else { PassSkip::LittleToGain });
        }
        let caustic = allocate(&specular_power, caustic_total);
        let lights = (0..n)
            .map(|e| {
                let p = &projections[e];
                let (g, c) = (global[e], caustic[e]);
                let dg = if g > 0 { g as f64 / p.geometry.fraction() } else { 0.0 };
                let dc = if c > 0 { c as f64 / p.specular.fraction() } else { 0.0 };
                let (wg, wc) = if dc == 0.0 {
                    (1.0, 0.0)
                } else {
                    let wg = dg / (dg + dc);
                    if wg < MIN_GLOBAL_CAUSTIC_WEIGHT { (0.0, 1.0) } else { (wg, 1.0 - wg) }
                };
                LightPlan { global: g, caustic: c, global_caustic_weight: wg, caustic_weight: wc }
            })
            .collect();
        Self { lights, projected: true, skipped }
    }

    /// Photons of the `[caustic, global]` passes.
    pub fn pass_photons(&self) -> [u32; 2] {
        [self.lights.iter().map(|l| l.caustic).sum(), self.lights.iter().map(|l| l.global).sum()]
    }
}

