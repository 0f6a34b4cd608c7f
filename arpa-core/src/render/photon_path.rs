//! The photon pass of one photon, as every backend must compute it: emit with
//! differentials, propagate through specular chains (reflection, refraction with
//! Fresnel-weighted choice and total internal reflection), store at diffuse hits
//! (footprint or progressive photon), absorb and re-emit with the virtual distance, and
//! end by Russian roulette or after `max_depth` interactions. On meshes with vertex
//! normals a diffuse hit weights the photon by the adjoint shading-normal ratio and
//! re-emits it within the shading lobe ([`crate::propagate::lambertian`]).
//!
//! This is the reference the conformance suite compares backends with, and the CPU
//! backend's implementation.

use crate::propagate::classify::{PathClassifier, SurfaceInteraction};
use crate::propagate::differential::{refract_direction, reflect_direction, DifferentialError, NormalDifferential, RayDifferential};
use crate::emit::emission::{EmissionParams, PreparedLight};
use crate::render::emission_plan::EmissionPlan;
use crate::store::footprint::{Footprint, PhotonMap};
use crate::propagate::fresnel::dielectric_reflectance;
use crate::store::heuristics::ResolvedHeuristics;
use crate::propagate::lambertian::DiffuseShading;
use crate::render::prepared_scene::{stops_with, PreparedScene, SurfacePoint, MAX_MASK_PASSES};
use crate::render::ray_cast::{RayCaster, RayHit, RayStart};
use crate::propagate::reemission::{diffuse_direction_unit, reemit_unit};
use crate::base::rng::{Rng, StreamDomain};
use crate::render::scene::Scattering;
use crate::{store::decision::{store_footprint, store_progressive, StoredPhoton}, store::heuristics::ProgressiveReason};
use crate::render::tracer::{Method, RenderSettings};
use alloc::vec::Vec;
use glam::{DVec3, Vec3};

/// Per-iteration inputs of the photon pass, shared by all photons.
///
/// The photons of an iteration come from *sources*: source `e < n` is the global pass of
/// emitter `e` (of `n`), source `n + e` its caustic pass ([`crate::render::projection`]); the
/// global photon indices run over the sources in that order. A caustic-pass photon
/// stores only caustic records and ends at its first diffuse hit; every caustic record
/// is weighted by its source's [`PhotonPassSetup::caustic_weight`].
#[derive(Clone, Debug)]
pub struct PhotonPassSetup {
    /// Photons per source this iteration ([`EmissionPlan`]).
    pub allocation: Vec<u32>,
    /// First global photon index of each source (prefix sums of `allocation`).
    pub first_index: Vec<u32>,
    /// Each source's emitter prepared for this iteration (lattice shift drawn per
    /// iteration, projection cells of its pass); `None` for a source that does not emit.
    pub lights: Vec<Option<PreparedLight>>,
    /// Weight of the caustic records of each source's photons (the balance heuristic of
    /// the two passes; 0: the source stores none).
    pub caustic_weight: Vec<f64>,
    /// Emitters of the scene (`n`; the sources are `2n`).
    pub emitters: usize,
    /// Where each source's projection cells ([`source_cells`]) start in the scene's cell
    /// table ([`crate::gpu::fill::cell_table`]: every source's cells in source order).
    pub cell_first: Vec<u32>,
    /// Photons of the `[caustic, global]` passes.
    pub pass_photons: [u32; 2],
    /// What the iteration's plan skipped.
    pub skipped: crate::render::tracer::Skipped,
    /// Progressive radii `[caustic, global]` of this iteration (metres).
    pub radii: [f64; 2],
    /// 0-based iteration number.
    pub iteration: u32,
    /// The settings' heuristics resolved for the scene.
    pub heuristics: ResolvedHeuristics,
}

impl PhotonPassSetup {
    /// The setup of iteration `iteration` (0-based) under `settings`.
    pub fn new(scene: &PreparedScene, settings: &RenderSettings, iteration: u32) -> Self {
        let plan = EmissionPlan::new(scene, settings);
        let n = scene.emitters().len();
        let mut allocation = Vec::with_capacity(2 * n);
        let mut caustic_weight = Vec::with_capacity(2 * n);
        allocation.extend(plan.lights.iter().map(|l| l.global));
        allocation.extend(plan.lights.iter().map(|l| l.caustic));
        caustic_weight.extend(plan.lights.iter().map(|l| l.global_caustic_weight));
        caustic_weight.extend(plan.lights.iter().map(|l| l.caustic_weight));
        let mut first_index = Vec::with_capacity(allocation.len());
        let mut acc = 0u32;
        for &k in &allocation {
            first_index.push(acc);
            acc = acc.saturating_add(k);
        }
        let (centre, radius) = scene.bounding_sphere();
        let lights = (0..2 * n)
            .map(|source| {
                let (e, caustic) = (source % n.max(1), source >= n);
                let count = allocation[source];
                if count == 0 && (caustic || plan.projected) {
                    return None;
                }
                // The lattice shift of the emitter's stream: both passes draw the same
                // shift (their lattices are over different cells or counts).
                let mut params = EmissionParams::new(count.max(1)).with_scene_sphere(centre, radius).for_iteration(settings.seed, iteration, e as u32);
                if plan.projected {
                    let d = source_cells(scene, source).domain();
                    params = params.with_cells(d.grid, d.count);
                }
                scene.emitters()[e].prepare(&params).ok()
            })
            .collect();
        let radii = settings.radii.radii(&scene.bounds(), iteration.saturating_add(1));
        let mut at = 0u32;
        let cell_first = (0..2 * n)
            .map(|source| {
                let first = at;
                at += source_cells(scene, source).cells.len() as u32;
                first
            })
            .collect();
        Self {
            cell_first,
            allocation,
            first_index,
            lights,
            caustic_weight,
            emitters: n,
            pass_photons: plan.pass_photons(),
            skipped: plan.skipped,
            radii,
            iteration,
            heuristics: settings.heuristics.resolve(&scene.bounds()).at_radii(radii),
        }
    }

    /// Whether `source` is a caustic-pass source.
    #[inline]
    pub fn is_caustic_source(&self, source: usize) -> bool {
        source >= self.emitters
    }

    /// The emitter of `source`.
    #[inline]
    pub fn emitter_of(&self, source: usize) -> usize {
        source % self.emitters.max(1)
    }

    /// The projection cells `source`'s light samples (empty for the whole domain).
    pub fn cells<'a>(&self, scene: &'a PreparedScene, source: usize) -> &'a [u32] {
        match self.lights.get(source).and_then(|l| l.as_ref()) {
            Some(l) if l.cells().is_projected() => &source_cells(scene, source).cells,
            _ => &[],
        }
    }

    /// Writes the plan's photons per pass and skips into `stats`.
    pub fn record_plan(&self, stats: &mut crate::render::tracer::IterationStats) {
        stats.emitted = self.pass_photons.map(u64::from);
        stats.skipped = self.skipped;
    }

    /// Total photons of the iteration.
    pub fn photon_count(&self) -> u32 {
        self.allocation.iter().sum()
    }

    /// Source and index within it of global photon `index`.
    #[inline]
    pub fn locate(&self, index: u32) -> Option<(usize, u32)> {
        let e = self.first_index.partition_point(|&f| f <= index).checked_sub(1)?;
        let local = index - self.first_index[e];
        (local < self.allocation[e]).then_some((e, local))
    }
}

/// The projection of source `source` of `scene` ([`PhotonPassSetup`]'s numbering: the
/// geometry cells of emitter `source` for `source < n`, the specular cells of emitter
/// `source − n` after them).
pub fn source_cells(scene: &PreparedScene, source: usize) -> &crate::render::projection::DomainCells {
    let projections = scene.projections();
    let n = projections.len();
    if source < n { &projections[source].geometry } else { &projections[source - n].specular }
}

/// Counts of one photon's path.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct PhotonPathStats {
    /// Ray segments cast.
    pub segments: u32,
    /// Photons stored.
    pub stored: u32,
}

/// The part of the photon that does not depend on its differential.
#[derive(Clone, Debug)]
struct PathState {
    ray: RayDifferential,
    differential_valid: bool,
    flux: DVec3,
    classifier: PathClassifier,
}

/// Traces global photon `index` of the iteration and hands every stored photon to
/// `sink`. Deterministic: the photon's random stream depends only on
/// `(seed, iteration, index)`.
///
/// A loop over [`PhotonWalk`]: one ray segment per step, cast through `caster`.
pub fn trace_photon(
    scene: &PreparedScene,
    caster: &impl RayCaster,
    settings: &RenderSettings,
    setup: &PhotonPassSetup,
    index: u32,
    sink: &mut impl FnMut(StoredPhoton),
) -> PhotonPathStats {
    let Some(mut walk) = PhotonWalk::start(scene, settings, setup, index) else { return PhotonPathStats::default() };
    while let Some((start, direction)) = walk.next_ray() {
        let hit = start.intersect(caster, direction, f32::INFINITY);
        if let Some(h) = &hit {
            scene.prefetch_hit(h);
        }
        walk.advance(scene, settings, setup, hit, sink);
    }
    walk.stats()
}

/// One photon's path, advanced one ray segment at a time: [`PhotonWalk::next_ray`] gives
/// the segment to cast (unbounded), [`PhotonWalk::advance`] takes its closest hit. This is
/// [`trace_photon`] with the ray casts left to the caller, for backends that keep several
/// photons in flight (the CPU backend interleaves two, so that the hit data of one loads
/// while the other is processed); a photon's stored records and counts are the same
/// whatever it is interleaved with.
#[derive(Clone, Debug)]
pub struct PhotonWalk {
    st: PathState,
    rng: Rng,
    /// Start of the next segment (on the surface it leaves, which it skips).
    start: RayStart,
    reemission_length: f64,
    max_depth: u32,
    stats: PhotonPathStats,
    done: bool,
    /// A caustic-pass photon: stores only caustic records, ends at its first diffuse hit.
    caustic_only: bool,
    /// Weight of the photon's caustic records (0: it stores none).
    caustic_weight: f64,
    /// Masks passed since the last surface that stopped the photon.
    mask_passes: u32,
    /// Weight of the records stored at the current hit (`1/o` on a mask of opacity `o`).
    record_weight: f64,
}

impl PhotonWalk {
    /// Emits global photon `index` of the iteration; `None` when it does not exist or its
    /// emitter cannot emit it (such a photon traces nothing and stores nothing).
    #[inline(always)]
    pub fn start(scene: &PreparedScene, settings: &RenderSettings, setup: &PhotonPassSetup, index: u32) -> Option<Self> {
        let (source, local) = setup.locate(index)?;
        let light = setup.lights[source].as_ref()?;
        let mut rng = Rng::new(settings.seed, setup.iteration, index, StreamDomain::Photon);
        let mut emitted = match scene.environment() {
            // The environment's directions by its map (uniform for a constant one).
            Some(env) if setup.emitter_of(source) == env.emitter => light.emit_environment_in(local, &mut rng, |s| env.photon_direction(s)).ok()?,
            _ => light.emit_in(local, &mut rng, setup.cells(scene, source)).ok()?,
        };
        // A textured emitter's photon carries the texture at its origin over the texture's
        // mean over the triangle (which set the emitter's power).
        if let Some(emitter) = source.checked_rem(setup.emitters)
            && scene.emitter_texture(emitter).is_some()
        {
            emitted.flux *= scene.emission_factor_at(emitter, emitted.ray.p).as_dvec3();
        }
        // Only ARPA's footprints use the differentials: RTPM's photons (progressive photons
        // only) carry none, so its pass skips the transfer, reflection, refraction and
        // re-emission of the derivatives (its hits are stored at the surface point).
        let differential_valid = settings.method == Method::Arpa;
        let st = PathState { ray: emitted.ray, differential_valid, flux: emitted.flux, classifier: PathClassifier::new() };
        // Area-light photons start on the emitter: leave it along its normal.
        let start = match emitted.surface_normal {
            Some(n) => RayStart::off_surface(st.ray.p, n),
            None => RayStart::at(st.ray.p.as_vec3()),
        };
        Some(Self {
            st,
            rng,
            start,
            reemission_length: emitted.reemission_length,
            max_depth: settings.max_depth,
            stats: PhotonPathStats::default(),
            done: false,
            caustic_only: setup.is_caustic_source(source),
            caustic_weight: setup.caustic_weight[source],
            mask_passes: 0,
            record_weight: 1.0,
        })
    }

    /// The next segment to cast, `(start, unit direction)` in world space (metres), from
    /// the start to infinity, cast with [`RayStart::intersect`]; `None` once the path has ended (absorbed, escaped, or
    /// `max_depth` segments cast).
    #[inline(always)]
    pub fn next_ray(&self) -> Option<(RayStart, Vec3)> {
        (!self.done && self.stats.segments < self.max_depth).then(|| (self.start, self.st.ray.d.as_vec3()))
    }

    /// Counts of the path so far.
    #[inline]
    pub fn stats(&self) -> PhotonPathStats {
        self.stats
    }

    /// Takes the closest hit of the segment [`PhotonWalk::next_ray`] gave (`None`: it
    /// escaped), stores at a diffuse hit through `sink`, and scatters or ends the path.
    /// The settings and setup must be those [`PhotonWalk::start`] was given.
    #[inline(always)]
    pub fn advance(
        &mut self,
        scene: &PreparedScene,
        settings: &RenderSettings,
        setup: &PhotonPassSetup,
        hit: Option<RayHit>,
        sink: &mut impl FnMut(StoredPhoton),
    ) {
        // A mask the photon passes through: the same ray goes on from its surface (the
        // differential is transferred at the next surface that stops it; passes are not
        // segments, as in Mitsuba's volpath).
        self.record_weight = 1.0;
        if let Some(h) = &hit
            && scene.has_masks()
        {
            let opacity = scene.opacity(h);
            if self.mask_passes < MAX_MASK_PASSES && !stops_with(opacity, &mut self.rng) {
                self.mask_passes += 1;
                self.start = scene.leaving_hit(h);
                return;
            }
            // A photon stops on a partly open mask with probability `o`, so the records of
            // the photons that stop there carry 1/o: their density is the full irradiance
            // arriving at the surface, which a camera ray that stops there (also with
            // probability o) reads; the photon goes on with its own flux.
            if opacity > 0.0 && opacity < 1.0 {
                self.record_weight = 1.0 / opacity as f64;
            }
        }
        self.mask_passes = 0;
        self.stats.segments += 1;
        let carries_on = match hit {
            Some(hit) => self.interact(scene, settings, setup, &hit, sink),
            None => false,
        };
        if !carries_on || !(self.st.flux.max_element() > 0.0) || !self.st.flux.is_finite() {
            self.done = true;
        }
    }

    /// The interaction at `hit`; `false` ends the path.
    #[inline(always)]
    fn interact(&mut self, scene: &PreparedScene, settings: &RenderSettings, setup: &PhotonPassSetup, hit: &RayHit, sink: &mut impl FnMut(StoredPhoton)) -> bool {
        let st = &mut self.st;
        let rng = &mut self.rng;
        let d = st.ray.d;
        let mut s = scene.surface(hit);
        let blend_weight = scene.choose_blend(&mut s, rng);
        // Side the photon arrives from.
        let front = if d.dot(s.geometric_normal) < 0.0 { s.geometric_normal } else { -s.geometric_normal };
        match s.scattering {
            Scattering::Diffuse(albedo) => {
                let map = st.classifier.record(SurfaceInteraction::Diffuse).unwrap_or(PhotonMap::Global);
                // A caustic-pass photon has nothing more to store after its first diffuse hit.
                if self.caustic_only && map != PhotonMap::Caustic {
                    return false;
                }
                let first_interaction = st.classifier.diffuse_events() == 1 && st.classifier.specular_events() == 0;
                // Shading normals (Mitsuba's two-sided diffuse in the shading frame): the
                // photon counts with the adjoint ratio a(ω_i) = |ω_i·n_s|/|ω_i·n_g| both in
                // the density estimate and in what it carries on (crate::propagate::lambertian).
                let shading = match scene.has_shading_normals(&s) {
                    false => None,
                    true => match DiffuseShading::new(front, scene.shading_normal_at(&s), -d) {
                        Some(sh) => Some(sh),
                        None => return false,
                    },
                };
                if let Some(sh) = &shading {
                    st.flux *= sh.adjoint_ratio(-d);
                    if !(st.flux.max_element() > 0.0) {
                        return false;
                    }
                }
                let albedo = albedo.as_dvec3();
                let survive = albedo.max_element().min(1.0);
                // The ray at the hit (`PathState::at_hit`, the differential transfer) is taken
                // only where it is used: a hit that is not stored (direct lighting counts this
                // first hit) draws its roulette first and skips the transfer if absorbed. The
                // transfer draws no random numbers, so the stream is the same either way.
                let stores = !(settings.direct_lighting && first_interaction || map == PhotonMap::Caustic && self.caustic_weight == 0.0);
                if !stores && !(rng.next_f64() < survive) {
                    return false;
                }
                let ray_at_hit = st.at_hit(&s);
                if stores {
                    // A photon from below the shading plane (on the side it landed on) is
                    // stored with its orientation flipped, so that only query points seen
                    // from below the shading plane too gather it (crate::propagate::lambertian).
                    let below = shading.as_ref().is_some_and(DiffuseShading::below_shading_plane);
                    let flux = if map == PhotonMap::Caustic { st.flux * self.caustic_weight } else { st.flux } * (self.record_weight * blend_weight);
                    sink(store(&ray_at_hit, &s.geometric_normal, flux, map, st.differential_valid, below, settings, setup));
                    self.stats.stored += 1;
                    if self.caustic_only || !(rng.next_f64() < survive) {
                        return false;
                    }
                }
                st.flux *= albedo / survive;
                let dir = match &shading {
                    None => diffuse_direction_unit(front, rng.next_2d()),
                    Some(sh) => match sh.sample_reemission(rng.next_2d()) {
                        Some(dir) => dir,
                        None => return false,
                    },
                };
                st.ray = match st.differential_valid.then(|| reemit_unit(s.position, ray_at_hit.dp_du, ray_at_hit.dp_dv, dir, self.reemission_length)) {
                    Some(Ok(r)) => r,
                    _ => {
                        st.differential_valid = false;
                        lost_differential(s.position, dir)
                    }
                };
                self.start = s.leaving();
            }
            // Mirrors and dielectrics share the transfer, the shading normal's derivative
            // and the reflection: one inlined copy of each in the compiled pass instead of
            // two, which keeps the CPU backend's photon loop smaller.
            Scattering::Mirror(_) | Scattering::Refractive(..) | Scattering::Thin(..) => {
                let ray_at_hit = st.at_hit(&s);
                st.classifier.record(SurfaceInteraction::Specular);
                let nd = scene.shading_normal(&s, ray_at_hit.dp_du, ray_at_hit.dp_dv);
                let n = nd.map(|n| n.n).unwrap_or(s.geometric_normal);
                // A mirror always reflects; a dielectric reflects with the Fresnel
                // probability and otherwise refracts.
                let refraction = if let Scattering::Refractive(ior, transmittance) | Scattering::Thin(ior, transmittance) = s.scattering {
                    let ior = ior as f64;
                    let reflectance = match s.scattering {
                        Scattering::Thin(..) => crate::render::scene::thin_sheet_reflectance(d.dot(n), ior),
                        _ => dielectric_reflectance(d.dot(n), ior),
                    };
                    (!(rng.next_f64() < reflectance)).then_some((ior, transmittance))
                } else {
                    if let Scattering::Mirror(reflectance) = s.scattering {
                        st.flux *= reflectance.as_dvec3();
                    }
                    None
                };
                match refraction {
                    None => {
                        st.reflect(&ray_at_hit, nd, n);
                        self.start = s.leaving();
                    }
                    // Through a thin sheet: straight on, the differential as it arrived.
                    Some((_, transmittance)) if matches!(s.scattering, Scattering::Thin(..)) => {
                        st.flux *= transmittance.as_dvec3();
                        st.ray = ray_at_hit;
                        self.start = s.leaving();
                    }
                    Some((ior, transmittance)) => {
                        st.flux *= transmittance.as_dvec3();
                        let (dir, event, _) = refract_direction(d, n, ior);
                        st.ray = match st.differential_valid.then(|| nd.and_then(|nd| ray_at_hit.refract(&nd, ior))) {
                            Some(Ok((r, e))) if e == event => r,
                            _ => {
                                st.differential_valid = false;
                                lost_differential(s.position, dir)
                            }
                        };
                        self.start = s.leaving();
                    }
                }
            }
        }
        true
    }
}

impl PathState {
    /// The photon's ray moved onto the surface point `s` it hit: its differential
    /// transferred there, or, where that fails, a ray without one (and the path carries no
    /// differential from here on).
    #[inline(always)]
    fn at_hit(&mut self, s: &SurfacePoint) -> RayDifferential {
        let d = self.ray.d;
        // Distance from the differential's origin to the hit, along the direction.
        let t = (s.position - self.ray.p).dot(d).max(0.0);
        let moved = if self.differential_valid { self.ray.transfer_finite_unit_normal(t, s.geometric_normal).ok() } else { None };
        match moved {
            Some(r) => r,
            None => {
                self.differential_valid = false;
                lost_differential(s.position, d)
            }
        }
    }

    /// Specular reflection at the hit `at` about the shading normal `nd` (or `n` when its
    /// derivative could not be formed); the differential is lost if it cannot follow.
    #[inline(always)]
    fn reflect(&mut self, at: &RayDifferential, nd: Result<NormalDifferential, DifferentialError>, n: DVec3) {
        self.ray = match self.differential_valid.then(|| nd.and_then(|nd| at.reflect(&nd))) {
            Some(Ok(r)) => r,
            _ => {
                self.differential_valid = false;
                lost_differential(at.p, reflect_direction(at.d, n))
            }
        };
    }
}

/// A ray without a usable differential (all derivatives zero). `d` is a ray direction,
/// unit up to rounding on every path, so it takes `unit_or`'s cheap renormalisation
/// (RTPM builds one or two of these per segment).
#[inline(always)]
fn lost_differential(p: DVec3, d: DVec3) -> RayDifferential {
    let d = crate::base::frame::unit_or(d, DVec3::Z);
    RayDifferential { p, d, dp_du: DVec3::ZERO, dp_dv: DVec3::ZERO, dd_du: DVec3::ZERO, dd_dv: DVec3::ZERO }
}

/// Stores the photon `ray` at a diffuse hit with geometric normal `normal`: a footprint,
/// or a progressive photon (RTPM, lost differential, or a footprint the heuristics
/// reject). `below_shading_plane` flips the stored orientation ([`orient_to_shading_side`]).
#[allow(clippy::too_many_arguments)]
#[inline(always)]
fn store(
    ray: &RayDifferential,
    normal: &DVec3,
    flux: DVec3,
    map: PhotonMap,
    differential_valid: bool,
    below_shading_plane: bool,
    settings: &RenderSettings,
    setup: &PhotonPassSetup,
) -> StoredPhoton {
    let reason = match (settings.method, differential_valid) {
        (Method::Rtpm, _) => Some(ProgressiveReason::ProgressiveMethod),
        (Method::Arpa, false) => Some(ProgressiveReason::DifferentialLost),
        (Method::Arpa, true) => None,
    };
    let stored = match reason {
        Some(reason) => store_progressive(ray.p, *normal, ray.d, flux, map, reason),
        // A valid differential here was just transferred onto this surface
        // (`PhotonWalk::interact`): in its plane, with a unit normal.
        None => store_footprint(Footprint::from_transferred(ray, *normal, flux, map), &settings.smoothing, &setup.heuristics, setup.radii[map.index()]),
    };
    if below_shading_plane { orient_to_shading_side(stored) } else { stored }
}

/// Flips the orientation of a stored photon (a footprint's `row_n`, a progressive photon's
/// normal; exact sign flips) from the geometric side it arrived on to the other one.
///
/// The gather counts a record at a query point only where the query normal faces the
/// record's orientation. Query points carry their geometric normal towards the viewer,
/// flipped where the viewer is below the shading plane
/// ([`crate::render::camera_path::trace_camera_path`]), and records their geometric normal
/// towards the arriving photon, flipped where the photon came from below the shading
/// plane. So a photon counts where viewer and photon lie on the same side of the shading
/// plane, which is where Mitsuba's two-sided diffuse lobe is non-zero. Without vertex
/// normals nothing is flipped (the shading plane is the face).
#[cold]
fn orient_to_shading_side(stored: StoredPhoton) -> StoredPhoton {
    match stored {
        StoredPhoton::Footprint { mut packed, aabb } => {
            packed.row_n = packed.row_n.map(|x| -x);
            StoredPhoton::Footprint { packed, aabb }
        }
        StoredPhoton::Progressive { mut photon, reason } => {
            photon.normal = photon.normal.map(|x| -x);
            StoredPhoton::Progressive { photon, reason }
        }
    }
}
