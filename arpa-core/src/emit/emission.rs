//! Photon emission with differentials (Frisvad et al. 2014's light-source framework as
//! adopted by ARPA §4.1) for point, spot, directional and area lights.
//!
//! **Tiling rule.** Differential lengths are chosen so that the `N` photons of one light
//! tile its emission domain once: each photon's footprint ellipse `(π/4)|D_u × D_v|`
//! covers `1/N` of it (times the emission scale `s`, normally 1; the per-map smoothing
//! `S_c`/`S_g` is applied later, on absorption). With a unit-square sample mapped by an
//! equal-area map and the `N` samples taken from a shifted Fibonacci lattice
//! ([`crate::base::sampling::fibonacci_lattice`]) the photons really do tile it.
//!
//! | light | `∂P/∂u, ∂P/∂v` | `∂D/∂u, ∂D/∂v` | flux per photon |
//! |---|---|---|---|
//! | point (intensity `I`, W/sr) | 0 | `ℓ_ω T₁, ℓ_ω T₂`, `ℓ_ω = 2s√(4π/(πN))` | `4π I/N` |
//! | spot (cone `θ_c`, `Ω = 2π(1−cos θ_c)`) | 0 | `ℓ_ω = 2s√(Ω/(πN))` | `I f(θ) Ω/N` |
//! | directional (irradiance `E`, W/m²) | `ℓ_x T₁, ℓ_x T₂` on the aperture disc of radius `R`, `ℓ_x = 2s√(πR²/(πN))` | 0 | `E πR²/N` |
//! | area (radiance `L`, area `A`) | `ℓ_x = 2s√(A/(πN))` in the light plane | `ℓ_ω = 2s√(2π/(πN))` (hemisphere) | `π L A/N` |
//! | environment (radiance `L m(ω)`) | as directional, on the disc across the sampled direction | 0 | `L m(ω) πR²/(N p(ω))` |
//!
//! Area lights carry both differentials at once (digest §3.1 option (c)): the footprint
//! equals the light's share near the light and grows with distance like a point light's.
//! `T₁, T₂` are orthonormal and perpendicular to `D` (directional derivatives) or to the
//! light's normal/direction (positional ones).
//!
//! **Re-emission length.** At a diffuse bounce the photon is re-emitted with directional
//! differentials of the light's *directional* emission length `ℓ_ω` (ARPA §4.1); lights
//! whose directional length is 0 (directional lights) use the hemisphere length
//! `2s√(2/N)`. See [`EmissionLengths::reemission`].
//!
//! **Environment light.** Each photon draws the direction `ω` it comes from (uniform over
//! the sphere for a constant environment, by the map's luminance for a map:
//! [`PreparedLight::emit_environment_in`]) and then starts like a directional light's photon
//! on the disc of radius `R` across `ω`: wherever they land the photons are `N/(πR²)` per
//! unit area across their direction, the directional light's tiling, whatever `ω` is.

use crate::propagate::differential::{DifferentialError, RayDifferential};
use crate::base::frame::Frame;
use crate::base::rng::Rng;
use crate::base::sampling::{cone_solid_angle_from_angle, cosine_hemisphere, uniform_cone, uniform_disc, uniform_sphere, uniform_triangle};
use core::f64::consts::{PI, TAU};
use glam::{DVec2, DVec3};

/// An isotropic point light.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PointLight {
    /// Position (metres).
    pub position: DVec3,
    /// Radiant intensity (W/sr, RGB).
    pub intensity: DVec3,
}

/// Angular falloff of a spot light inside its transition band.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum SpotFalloff {
    /// Linear in angle from 1 at `beam_width` to 0 at `cutoff` (Mitsuba 3).
    #[default]
    LinearAngle,
    /// Smoothstep in angle over the band (Falcor).
    SmoothstepAngle,
}

/// A spot light: intensity `I` inside `beam_width`, falling off to 0 at `cutoff`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SpotLight {
    /// Position (metres).
    pub position: DVec3,
    /// Unit axis direction.
    pub direction: DVec3,
    /// On-axis radiant intensity (W/sr, RGB).
    pub intensity: DVec3,
    /// Cut-off half-angle `θ_c` (radians, in `(0, π]`).
    pub cutoff: f64,
    /// Half-angle `θ_b ≤ θ_c` of full intensity (radians).
    pub beam_width: f64,
    /// Falloff curve inside the band.
    pub falloff: SpotFalloff,
}

/// A directional light illuminating the scene bounds.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DirectionalLight {
    /// Unit direction of travel of the light.
    pub direction: DVec3,
    /// Irradiance on a plane perpendicular to `direction` (W/m², RGB).
    pub irradiance: DVec3,
}

/// Light arriving from infinitely far away in every direction (Mitsuba's `constant` and
/// `envmap`): radiance `radiance · m(ω)` from direction `ω`, where `m` is 1 for a constant
/// environment and a map's value otherwise. The map itself, and the tables that sample
/// it, live with the scene ([`crate::render::environment`]); the light keeps what its
/// power needs.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct EnvironmentLight {
    /// Radiance (W/(m²·sr), RGB) of a constant environment; the scale of a map.
    pub radiance: DVec3,
    /// Mean of `m` over the sphere, `∫ m dω / 4π` (RGB; 1 for a constant environment).
    pub mean: DVec3,
}

/// A one-sided Lambertian triangle emitter; emits on the side of `(p1 − p0) × (p2 − p0)`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TriangleLight {
    /// Vertices (metres).
    pub p: [DVec3; 3],
    /// Emitted radiance (W/(m²·sr), RGB).
    pub radiance: DVec3,
}

/// A one-sided Lambertian parallelogram emitter `origin + a·edge_u + b·edge_v`,
/// `a, b ∈ [0, 1]`; emits on the side of `edge_u × edge_v`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct QuadLight {
    /// Corner (metres).
    pub origin: DVec3,
    /// First edge (metres).
    pub edge_u: DVec3,
    /// Second edge (metres).
    pub edge_v: DVec3,
    /// Emitted radiance (W/(m²·sr), RGB).
    pub radiance: DVec3,
}

/// Any light.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Light {
    /// Point light.
    Point(PointLight),
    /// Spot light.
    Spot(SpotLight),
    /// Directional light.
    Directional(DirectionalLight),
    /// Triangle area light.
    Triangle(TriangleLight),
    /// Parallelogram area light.
    Quad(QuadLight),
    /// Environment light (at most one per scene).
    Environment(EnvironmentLight),
}

/// Why a light cannot emit.
#[derive(Clone, Copy, Debug, PartialEq, Eq, thiserror::Error)]
pub enum LightError {
    /// A position, direction or colour is NaN or infinite.
    #[error("light has a non-finite parameter")]
    NonFinite,
    /// Negative intensity, radiance or irradiance.
    #[error("light has negative emission")]
    NegativeEmission,
    /// Emits no power at all.
    #[error("light emits zero power")]
    ZeroPower,
    /// Area light with zero area.
    #[error("area light has zero area")]
    ZeroArea,
    /// Direction of a spot or directional light is zero.
    #[error("light direction is zero")]
    ZeroDirection,
    /// Spot cut-off outside `(0, π]` or beam width outside `[0, cutoff]`.
    #[error("spot light angles out of range")]
    BadSpotAngles,
    /// A directional light needs non-empty scene bounds to size its aperture.
    #[error("directional light needs non-empty scene bounds")]
    NoSceneBounds,
    /// Zero photons requested.
    #[error("photon count is zero")]
    NoPhotons,
}

/// Parameters shared by all photons of one light in one iteration.
///
/// Make them with [`EmissionParams::new`] and, for a progressive render, give each
/// iteration its own lattice shift with [`EmissionParams::for_iteration`]: the `N` photons
/// of a light are the points of a Fibonacci lattice shifted by [`lattice_shift`](Self::lattice_shift),
/// and point and spot lights draw nothing else at emission, so **with the same shift every
/// iteration they emit the same photons every iteration and the render does not converge**
/// (area lights still vary through their direction draws). Only directional lights read
/// [`scene_sphere`](Self::scene_sphere) ([`EmissionParams::with_scene_sphere`]).
///
/// ```
/// use arpa_core::emit::emission::{EmissionParams, Light, PointLight};
/// use arpa_core::glam::DVec3;
/// use arpa_core::base::rng::{Rng, StreamDomain};
///
/// let light = Light::Point(PointLight { position: DVec3::new(0.0, 0.0, 1.0), intensity: DVec3::splat(10.0) });
/// let (seed, iteration, n) = (7, 0, 1000);
/// let params = EmissionParams::new(n).for_iteration(seed, iteration, 0);
/// let prepared = light.prepare(&params).unwrap();
/// let mut total = DVec3::ZERO;
/// for i in 0..n {
///     // A point light draws nothing from the stream; an area light draws its direction.
///     let mut rng = Rng::new(seed, iteration, i, StreamDomain::Photon);
///     total += prepared.emit(i, &mut rng).unwrap().flux;
/// }
/// // The photons carry the light's power, 4π I (W).
/// assert!((total - DVec3::splat(40.0 * core::f64::consts::PI)).abs().max_element() < 1e-9);
/// ```
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct EmissionParams {
    /// Photons this light emits this iteration, `N` (at least 1).
    pub photon_count: u32,
    /// Emission scale `s` of the differential lengths (1 = exact tiling; finite, > 0).
    pub scale: f64,
    /// Bounding sphere of the scene (centre, radius in metres): the aperture of
    /// directional lights, which need a finite centre and a finite radius > 0. Other
    /// lights ignore it.
    pub scene_sphere: (DVec3, f64),
    /// Cranley–Patterson shift of the Fibonacci lattice for this iteration (unit square,
    /// finite; [`EmissionParams::for_iteration`] draws it).
    pub lattice_shift: DVec2,
    /// The part of the emission domain the photons are sent into: the whole domain, or the
    /// cells of a projection map ([`crate::render::projection`]). The photons then carry the flux
    /// of that part only and their differentials tile it.
    pub cells: CellDomain,
    /// Where the round robin over the projection cells starts this iteration (a uniform
    /// `u32`, [`crate::base::sampling::round_robin`]; [`EmissionParams::for_iteration`] draws it).
    pub cell_offset: u32,
}

/// Which part of a light's emission domain its photons sample: cells of a `grid` × `grid`
/// grid over the unit square that the light's equal-area map takes to its domain
/// (directions of point, spot and area lights, the aperture disc of directional lights),
/// as listed by a projection map ([`crate::render::projection::DomainCells`]).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct CellDomain {
    /// Cells per side; 0 for the whole domain.
    pub grid: u32,
    /// Cells sampled (`1..=grid²`; 0 for the whole domain).
    pub count: u32,
}

impl CellDomain {
    /// The whole domain.
    pub const WHOLE: Self = Self { grid: 0, count: 0 };

    /// The fraction of the domain's measure sampled (1 for the whole domain).
    pub fn fraction(&self) -> f64 {
        if self.grid == 0 { 1.0 } else { self.count as f64 / (self.grid as f64 * self.grid as f64) }
    }

    /// Whether only some cells are sampled.
    pub fn is_projected(&self) -> bool {
        self.grid != 0
    }
}

impl EmissionParams {
    /// `photon_count` photons with the exact tiling (`scale` 1), no lattice shift and no
    /// scene sphere (enough for point, spot and area lights in one iteration).
    pub const fn new(photon_count: u32) -> Self {
        Self { photon_count, scale: 1.0, scene_sphere: (DVec3::ZERO, 0.0), lattice_shift: DVec2::ZERO, cells: CellDomain::WHOLE, cell_offset: 0 }
    }

    /// The same parameters with the lattice shift of iteration `iteration` (0-based) of a
    /// render with `seed`, for light `light` (its index among the scene's emitters): the
    /// first 2-D draw of the stream `(seed, iteration, light)` in
    /// [`StreamDomain::Iteration`](crate::base::rng::StreamDomain::Iteration). This is the
    /// convention of every backend's photon pass
    /// ([`crate::render::photon_path::PhotonPassSetup`], the WGSL twin), so a renderer that
    /// follows it emits the photons the backends emit. Iterations count from 0 here, as
    /// in the random streams; the radius schedule counts them from 1
    /// ([`crate::accumulate::radius::ProgressiveConfig::radii`] takes `iteration + 1`).
    pub fn for_iteration(self, seed: u32, iteration: u32, light: u32) -> Self {
        let mut rng = crate::base::rng::Rng::new(seed, iteration, light, crate::base::rng::StreamDomain::Iteration);
        let lattice_shift = rng.next_2d();
        Self { lattice_shift, cell_offset: rng.next_u32(), ..self }
    }

    /// The same parameters with the scene's bounding sphere (centre, radius in metres),
    /// the aperture of a directional light.
    pub const fn with_scene_sphere(self, centre: DVec3, radius: f64) -> Self {
        Self { scene_sphere: (centre, radius), ..self }
    }

    /// The same parameters with emission scale `scale` (the differential lengths are
    /// `scale` times those of the exact tiling).
    pub const fn with_scale(self, scale: f64) -> Self {
        Self { scale, ..self }
    }

    /// The same parameters sampling only `count` cells of a `grid` × `grid` projection grid
    /// ([`CellDomain`]); the cells themselves are handed to [`PreparedLight::emit_in`].
    pub const fn with_cells(self, grid: u32, count: u32) -> Self {
        Self { cells: CellDomain { grid, count }, ..self }
    }

    /// Checks the fields a light reads: photon count, scale and shift for every light;
    /// the scene sphere for directional lights ([`Light::validate`]).
    fn validate(&self, light: &Light) -> Result<(), EmissionError> {
        if self.photon_count == 0 {
            return Err(LightError::NoPhotons.into());
        }
        if !(self.scale > 0.0) || !self.scale.is_finite() {
            return Err(EmissionError::Params("scale must be finite and > 0"));
        }
        if !self.lattice_shift.is_finite() {
            return Err(EmissionError::Params("lattice_shift must be finite"));
        }
        let c = self.cells;
        if c.grid != 0 && !(c.grid <= crate::base::sampling::MAX_CELL_GRID && c.count >= 1 && c.count as u64 <= c.grid as u64 * c.grid as u64) {
            return Err(EmissionError::Params("cells: count must lie in 1..=grid² and grid in 0..=256"));
        }
        if matches!(light, Light::Directional(_) | Light::Environment(_)) && !self.scene_sphere.0.is_finite() {
            return Err(LightError::NoSceneBounds.into());
        }
        Ok(())
    }
}

/// Differential lengths of one light for `N` photons.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct EmissionLengths {
    /// `ℓ_x`: length of `∂P/∂u`, `∂P/∂v` (metres).
    pub positional: f64,
    /// `ℓ_ω`: length of `∂D/∂u`, `∂D/∂v` (radians).
    pub directional: f64,
    /// Directional length used at diffuse re-emission (radians).
    pub reemission: f64,
}

/// One emitted photon.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct EmittedPhoton {
    /// Origin, direction and differentials.
    pub ray: RayDifferential,
    /// Flux (W, RGB).
    pub flux: DVec3,
    /// Directional length for re-emission at diffuse bounces (radians).
    pub reemission_length: f64,
    /// Unit normal of the emitting surface for area lights (the side emitted into), so
    /// the first ray can leave the emitter without hitting it; `None` for delta lights.
    pub surface_normal: Option<DVec3>,
}

fn finite3(v: &[DVec3]) -> bool {
    v.iter().all(|x| x.is_finite())
}

fn check_emission(e: DVec3) -> Result<(), LightError> {
    if !e.is_finite() {
        Err(LightError::NonFinite)
    } else if e.min_element() < 0.0 {
        Err(LightError::NegativeEmission)
    } else if e.max_element() <= 0.0 {
        Err(LightError::ZeroPower)
    } else {
        Ok(())
    }
}

impl SpotLight {
    /// Falloff `f(θ) ∈ [0, 1]` at angle `theta` (radians) from the axis.
    pub fn falloff_at(&self, theta: f64) -> f64 {
        if theta <= self.beam_width {
            1.0
        } else if theta >= self.cutoff {
            0.0
        } else {
            let x = (self.cutoff - theta) / (self.cutoff - self.beam_width);
            match self.falloff {
                SpotFalloff::LinearAngle => x,
                SpotFalloff::SmoothstepAngle => x * x * (3.0 - 2.0 * x),
            }
        }
    }

    /// `∫ f(θ) dω` over the sphere (steradians). Written without `1 − cos` cancellation
    /// so that very narrow spots keep their power.
    pub fn falloff_solid_angle(&self) -> f64 {
        let (tb, tc) = (self.beam_width, self.cutoff);
        let full = cone_solid_angle_from_angle(tb);
        let band = match self.falloff {
            // ∫_{θb}^{θc} (θc − θ)/(θc − θb) sin θ dθ = cos θb − (sin θc − sin θb)/(θc − θb);
            // with h = (θc − θb)/2: 2 sin(θb + h/2) sin(h/2) + cos(θb + h)(1 − sin h / h).
            SpotFalloff::LinearAngle => {
                let h = 0.5 * (tc - tb);
                let one_minus_sinc = if h < 1e-3 {
                    let h2 = h * h;
                    h2 / 6.0 * (1.0 - h2 / 20.0 * (1.0 - h2 / 42.0))
                } else {
                    1.0 - libm::sin(h) / h
                };
                2.0 * libm::sin(tb + 0.5 * h) * libm::sin(0.5 * h) + libm::cos(tb + h) * one_minus_sinc
            }
            SpotFalloff::SmoothstepAngle => {
                // Composite Simpson, 256 intervals: exact to ~1e-12 for this smooth integrand.
                let n = 256;
                let h = (tc - tb) / n as f64;
                let f = |t: f64| self.falloff_at(t) * libm::sin(t);
                let mut s = f(tb) + f(tc);
                for i in 1..n {
                    s += f(tb + i as f64 * h) * if i % 2 == 1 { 4.0 } else { 2.0 };
                }
                s * h / 3.0
            }
        };
        full + TAU * band.max(0.0)
    }
}

impl SpotFalloff {
    /// GPU code of the curve: 0 linear in angle, 1 smoothstep ([`PackedLight::falloff`],
    /// `ARPA_FALLOFF_*` in `emission.wgsl`).
    pub fn code(self) -> u32 {
        match self {
            SpotFalloff::LinearAngle => 0,
            SpotFalloff::SmoothstepAngle => 1,
        }
    }
}

impl Light {
    /// GPU code of the light's kind: 0 point, 1 spot, 2 directional, 3 triangle, 4 quad, 5
    /// environment ([`PackedLight::kind`], `ARPA_LIGHT_*` in `emission.wgsl`).
    pub fn kind_code(&self) -> u32 {
        match self {
            Light::Point(_) => 0,
            Light::Spot(_) => 1,
            Light::Directional(_) => 2,
            Light::Triangle(_) => 3,
            Light::Quad(_) => 4,
            Light::Environment(_) => 5,
        }
    }

    /// Checks every parameter; `scene_sphere_radius` matters only for directional and
    /// environment lights.
    pub fn validate(&self, scene_sphere_radius: f64) -> Result<(), LightError> {
        match self {
            Light::Point(l) => {
                if !l.position.is_finite() {
                    return Err(LightError::NonFinite);
                }
                check_emission(l.intensity)
            }
            Light::Spot(l) => {
                if !finite3(&[l.position, l.direction]) || !l.cutoff.is_finite() || !l.beam_width.is_finite() {
                    return Err(LightError::NonFinite);
                }
                if !(l.direction.length() > 0.0) {
                    return Err(LightError::ZeroDirection);
                }
                if !(l.cutoff > 0.0 && l.cutoff <= PI && l.beam_width >= 0.0 && l.beam_width <= l.cutoff) {
                    return Err(LightError::BadSpotAngles);
                }
                check_emission(l.intensity)
            }
            Light::Directional(l) => {
                if !l.direction.is_finite() {
                    return Err(LightError::NonFinite);
                }
                if !(l.direction.length() > 0.0) {
                    return Err(LightError::ZeroDirection);
                }
                if !(scene_sphere_radius > 0.0) || !scene_sphere_radius.is_finite() {
                    return Err(LightError::NoSceneBounds);
                }
                check_emission(l.irradiance)
            }
            Light::Triangle(l) => {
                if !finite3(&l.p) {
                    return Err(LightError::NonFinite);
                }
                check_emission(l.radiance)?;
                if !(self.area() > 0.0) { Err(LightError::ZeroArea) } else { Ok(()) }
            }
            Light::Quad(l) => {
                if !finite3(&[l.origin, l.edge_u, l.edge_v]) {
                    return Err(LightError::NonFinite);
                }
                check_emission(l.radiance)?;
                if !(self.area() > 0.0) { Err(LightError::ZeroArea) } else { Ok(()) }
            }
            Light::Environment(l) => {
                if !(scene_sphere_radius > 0.0) || !scene_sphere_radius.is_finite() {
                    return Err(LightError::NoSceneBounds);
                }
                check_emission(l.mean)?;
                check_emission(l.radiance)?;
                // Each may be positive in a channel where the other is zero.
                check_emission(l.radiance * l.mean)
            }
        }
    }

    /// Emitting area of an area light (m²); 0 for delta lights.
    pub fn area(&self) -> f64 {
        match self {
            Light::Triangle(l) => 0.5 * (l.p[1] - l.p[0]).cross(l.p[2] - l.p[0]).length(),
            Light::Quad(l) => l.edge_u.cross(l.edge_v).length(),
            _ => 0.0,
        }
    }

    /// Total emitted power (W, RGB). A directional light's power is what crosses its
    /// aperture disc of radius `scene_sphere_radius`; an environment's what crosses that
    /// disc from every direction, `4π L mean · πR²`.
    pub fn power(&self, scene_sphere_radius: f64) -> DVec3 {
        match self {
            Light::Point(l) => l.intensity * (4.0 * PI),
            Light::Spot(l) => l.intensity * l.falloff_solid_angle(),
            Light::Directional(l) => l.irradiance * (PI * scene_sphere_radius * scene_sphere_radius),
            Light::Triangle(l) => l.radiance * (PI * self.area()),
            Light::Quad(l) => l.radiance * (PI * self.area()),
            Light::Environment(l) => l.radiance * l.mean * (4.0 * PI * PI * scene_sphere_radius * scene_sphere_radius),
        }
    }

    /// Differential lengths for `n` photons with emission scale `s` (see module docs).
    pub fn emission_lengths(&self, n: u32, s: f64, scene_sphere_radius: f64) -> EmissionLengths {
        self.emission_lengths_in(n, s, scene_sphere_radius, 1.0)
    }

    /// Differential lengths for `n` photons with emission scale `s` that sample the
    /// fraction `fraction` of the emission domain ([`CellDomain::fraction`]): they tile
    /// that part, so the domain's measure in the table of the module docs is multiplied by
    /// it (the directions of area lights: their hemisphere; their positions are sampled
    /// whole).
    pub fn emission_lengths_in(&self, n: u32, s: f64, scene_sphere_radius: f64, fraction: f64) -> EmissionLengths {
        let whole = n.max(1) as f64;
        // The photons per unit of the sampled part's measure are those of `n / fraction`
        // photons over the whole domain.
        let n = whole / fraction;
        let tile = |measure: f64| 2.0 * s * libm::sqrt(measure / (PI * n));
        let hemisphere = tile(TAU);
        match self {
            Light::Point(_) => {
                let w = tile(4.0 * PI);
                EmissionLengths { positional: 0.0, directional: w, reemission: w }
            }
            Light::Spot(l) => {
                let w = tile(cone_solid_angle_from_angle(l.cutoff));
                EmissionLengths { positional: 0.0, directional: w, reemission: w }
            }
            Light::Directional(_) | Light::Environment(_) => EmissionLengths {
                positional: tile(PI * scene_sphere_radius * scene_sphere_radius),
                directional: 0.0,
                reemission: hemisphere,
            },
            Light::Triangle(_) | Light::Quad(_) => {
                // Every photon samples the whole emitter: its positional share is 1/N.
                let positional = 2.0 * s * libm::sqrt(self.area() / (PI * whole));
                EmissionLengths { positional, directional: hemisphere, reemission: hemisphere }
            }
        }
    }

    /// Emits photon `index` of `params.photon_count`. The primary two dimensions (direction
    /// for point/spot, position for area/directional lights) come from the shifted
    /// Fibonacci lattice; only area lights draw from `rng` (their direction, two draws),
    /// so point, spot and directional lights leave it untouched. The backends pass the
    /// photon's own stream, `Rng::new(seed, iteration, global photon index,
    /// StreamDomain::Photon)`, which the photon's path then continues. Validates the light
    /// and `params` first; a photon pass should [`Light::prepare`] once per iteration and
    /// call [`PreparedLight::emit`].
    pub fn emit(&self, index: u32, params: &EmissionParams, rng: &mut Rng) -> Result<EmittedPhoton, EmissionError> {
        self.prepare(params)?.emit(index, rng)
    }

    /// The light's frame, the one [`Light::prepare`] keeps for emission and the projection
    /// maps ([`crate::render::projection`]) map cells with: `+z` for a point light (whose
    /// directions are drawn in world space), the spot's axis, the directional light's
    /// direction of travel, the emitting side's normal of an area light (tangent `t` along
    /// its first edge), `+z` for an environment (whose directions are drawn per photon).
    pub fn frame(&self) -> Frame {
        match self {
            Light::Point(_) | Light::Environment(_) => Frame::from_normal(DVec3::Z),
            Light::Spot(l) => Frame::from_normal(l.direction),
            Light::Directional(l) => Frame::from_normal(l.direction.normalize()),
            Light::Triangle(l) => Frame::from_normal_and_hint((l.p[1] - l.p[0]).cross(l.p[2] - l.p[0]), l.p[1] - l.p[0]),
            Light::Quad(l) => Frame::from_normal_and_hint(l.edge_u.cross(l.edge_v), l.edge_u),
        }
    }

    /// Validates the light and computes everything that does not depend on the photon:
    /// differential lengths, frames and flux per photon.
    pub fn prepare(&self, params: &EmissionParams) -> Result<PreparedLight, EmissionError> {
        let radius = params.scene_sphere.1;
        self.validate(radius)?;
        params.validate(self)?;
        let n = params.photon_count;
        let fraction = params.cells.fraction();
        let per_photon = fraction / n as f64;
        let flux = match self {
            Light::Point(l) => l.intensity * (4.0 * PI * per_photon),
            Light::Spot(l) => l.intensity * (cone_solid_angle_from_angle(l.cutoff) * per_photon),
            Light::Directional(l) => l.irradiance * (PI * radius * radius * per_photon),
            Light::Triangle(l) => l.radiance * (PI * self.area() * per_photon),
            Light::Quad(l) => l.radiance * (PI * self.area() * per_photon),
            Light::Environment(_) => self.power(radius) * per_photon,
        };
        let frame = self.frame();
        let cos_cutoff = if let Light::Spot(l) = self { libm::cos(l.cutoff) } else { -1.0 };
        Ok(PreparedLight { light: *self, params: *params, lengths: self.emission_lengths_in(n, params.scale, radius, fraction), flux, frame, cos_cutoff })
    }
}

/// A light prepared for one iteration ([`Light::prepare`]): validated, with its
/// differential lengths, frame (spot axis, directional beam, area-light plane) and flux per
/// photon computed once.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PreparedLight {
    light: Light,
    params: EmissionParams,
    lengths: EmissionLengths,
    flux: DVec3,
    frame: Frame,
    cos_cutoff: f64,
}

impl PreparedLight {
    /// The differential lengths of this iteration's photons.
    pub fn lengths(&self) -> EmissionLengths {
        self.lengths
    }

    /// The light.
    pub fn light(&self) -> &Light {
        &self.light
    }

    /// The part of the emission domain this light's photons sample.
    pub fn cells(&self) -> CellDomain {
        self.params.cells
    }

    /// Emits photon `index` (see [`Light::emit`]) over the whole domain; a light prepared
    /// with projection cells needs [`PreparedLight::emit_in`].
    #[inline]
    pub fn emit(&self, index: u32, rng: &mut Rng) -> Result<EmittedPhoton, EmissionError> {
        self.emit_in(index, rng, &[])
    }

    /// The slot in the light's cell list of photon `index`, whose stream is `rng` before
    /// emission (not advanced); 0 for the whole domain. Point, spot and directional lights
    /// share their photons round robin over the cells
    /// ([`crate::base::sampling::round_robin`]); area lights pick the cell of their direction
    /// with their first draw ([`crate::base::sampling::split_draw`]). The shaders look the cell
    /// up with it before they emit (`arpa_emission_slot`).
    pub fn emission_slot(&self, index: u32, rng: &Rng) -> u32 {
        let p = &self.params;
        match (p.cells.grid, &self.light) {
            (0, _) => 0,
            (_, Light::Triangle(_) | Light::Quad(_)) => crate::base::sampling::split_draw({ let mut r = *rng; r.next_u32() }, p.cells.count).0,
            _ => crate::base::sampling::round_robin(index, p.photon_count, p.cells.count, p.cell_offset).0,
        }
    }

    /// Emits photon `index` into the projection cells `cells` (the list of the light's
    /// [`CellDomain`], `count` entries, each below `grid²`; empty for the whole domain):
    /// the primary sample (the lattice point of point, spot and directional lights, the
    /// direction draw of area lights) lands in the cell of
    /// [`PreparedLight::emission_slot`]: for point, spot and directional lights the
    /// Fibonacci lattice of that cell's photons, for area lights the rest of the draw.
    #[inline]
    pub fn emit_in(&self, index: u32, rng: &mut Rng, cells: &[u32]) -> Result<EmittedPhoton, EmissionError> {
        if let Light::Environment(_) = self.light {
            return self.emit_environment_in(index, rng, |draw| (uniform_sphere(draw), DVec3::ONE));
        }
        let params = &self.params;
        let domain = params.cells;
        // Only the length here: a scan of the list would cost O(cells) per photon; the one
        // cell a photon takes is checked where it is taken ([`cell_at`]).
        if cells.len() != domain.count as usize {
            return Err(EmissionError::Params("cells: the list does not match the light's cell domain"));
        }
        let (centre, radius) = params.scene_sphere;
        let lengths = &self.lengths;
        let area = matches!(self.light, Light::Triangle(_) | Light::Quad(_));
        let mut cell_weight = 1.0;
        let u = if domain.grid != 0 && !area {
            let (slot, j, n) = crate::base::sampling::round_robin(index, params.photon_count, domain.count, params.cell_offset);
            cell_weight = crate::base::sampling::round_robin_weight(params.photon_count, domain.count, n);
            let local = crate::base::sampling::fibonacci_lattice(j, n, params.lattice_shift);
            crate::base::sampling::cell_point(local, cell_at(cells, slot, domain)?, domain.grid)
        } else {
            crate::base::sampling::fibonacci_lattice(index, params.photon_count, params.lattice_shift)
        };
        let (ray, flux, surface_normal) = match &self.light {
            Light::Point(l) => {
                let d = uniform_sphere(u);
                let f = Frame::from_normal(d);
                let w = lengths.directional;
                (RayDifferential::new(l.position, d, DVec3::ZERO, DVec3::ZERO, f.t * w, f.b * w)?, self.flux, None)
            }
            Light::Spot(l) => {
                let local = uniform_cone(u, self.cos_cutoff);
                let d = self.frame.to_world(local);
                let theta = libm::acos(local.z.clamp(-1.0, 1.0));
                let f = Frame::from_normal(d);
                let w = lengths.directional;
                (RayDifferential::new(l.position, d, DVec3::ZERO, DVec3::ZERO, f.t * w, f.b * w)?, self.flux * l.falloff_at(theta), None)
            }
            Light::Directional(_) => {
                let f = &self.frame;
                let disc = uniform_disc(u) * radius;
                let origin = centre - f.n * radius + f.t * disc.x + f.b * disc.y;
                let x = lengths.positional;
                (RayDifferential::new(origin, f.n, f.t * x, f.b * x, DVec3::ZERO, DVec3::ZERO)?, self.flux, None)
            }
            Light::Triangle(l) => {
                let b = uniform_triangle(u);
                self.area_photon(l.p[0] * b.x + l.p[1] * b.y + l.p[2] * b.z, rng, cells)?
            }
            Light::Quad(l) => self.area_photon(l.origin + l.edge_u * u.x + l.edge_v * u.y, rng, cells)?,
            Light::Environment(_) => unreachable!("environment photons leave above"),
        };
        Ok(EmittedPhoton { ray, flux: flux * cell_weight, reemission_length: lengths.reemission, surface_normal })
    }

    /// Photon `index` of an environment light whose direction comes from `sample`. It is
    /// handed the photon's first 2-D draw from `rng` and gives the unit direction `ω`
    /// (world) the light arrives from and the flux factor `m(ω) / (4π p(ω) mean)` (RGB;
    /// `p` the density of `ω` per steradian, so 1 for a constant environment sampled
    /// uniformly, which is what [`PreparedLight::emit`] does). The photon starts at the
    /// lattice point on the disc of radius `R` across `ω`, a distance `R` out from the
    /// scene's centre, with a directional light's positional differentials. An environment
    /// light has no projection cells (it samples its whole domain).
    pub fn emit_environment_in(&self, index: u32, rng: &mut Rng, sample: impl FnOnce(DVec2) -> (DVec3, DVec3)) -> Result<EmittedPhoton, EmissionError> {
        let params = &self.params;
        if !matches!(self.light, Light::Environment(_)) {
            return Err(EmissionError::Params("emit_environment_in: the light is not an environment"));
        }
        if params.cells.grid != 0 {
            return Err(EmissionError::Params("cells: an environment light samples its whole domain"));
        }
        let u = crate::base::sampling::fibonacci_lattice(index, params.photon_count, params.lattice_shift);
        let (from, factor) = sample(rng.next_2d());
        let f = Frame::from_normal(-from);
        let (centre, radius) = params.scene_sphere;
        let disc = uniform_disc(u) * radius;
        let origin = centre - f.n * radius + f.t * disc.x + f.b * disc.y;
        let x = self.lengths.positional;
        let ray = RayDifferential::new(origin, f.n, f.t * x, f.b * x, DVec3::ZERO, DVec3::ZERO)?;
        Ok(EmittedPhoton { ray, flux: self.flux * factor, reemission_length: self.lengths.reemission, surface_normal: None })
    }

    #[inline(always)]
    fn area_photon(&self, p: DVec3, rng: &mut Rng, cells: &[u32]) -> Result<(RayDifferential, DVec3, Option<DVec3>), EmissionError> {
        let light_frame = &self.frame;
        let domain = self.params.cells;
        let draw = if domain.grid != 0 {
            let (slot, fx) = crate::base::sampling::split_draw(rng.next_u32(), domain.count);
            let fy = rng.next_f64();
            crate::base::sampling::cell_point(DVec2::new(fx, fy), cell_at(cells, slot, domain)?, domain.grid)
        } else {
            rng.next_2d()
        };
        let local = cosine_hemisphere(draw);
        let d = crate::base::frame::unit_or(light_frame.to_world(local), light_frame.n);
        let dir_frame = directional_frame(light_frame, local, d);
        let (x, w) = (self.lengths.positional, self.lengths.directional);
        // `d` is unit already (and the directional frame's axis as it is); the directional
        // differentials are unit vectors times a finite length, so only the origin and the
        // positional ones need the finiteness check.
        let ray = RayDifferential::new_unit_with_finite_dd(p, d, light_frame.t * x, light_frame.b * x, dir_frame.t * w, dir_frame.b * w)?;
        Ok((ray, self.flux, Some(light_frame.n)))
    }
}

/// Entry `slot` of a light's cell list, which must name a cell of its grid.
#[inline(always)]
fn cell_at(cells: &[u32], slot: u32, domain: CellDomain) -> Result<u32, EmissionError> {
    match cells.get(slot as usize) {
        Some(&c) if (c as u64) < domain.grid as u64 * domain.grid as u64 => Ok(c),
        _ => Err(EmissionError::Params("cells: an entry lies outside the light's grid")),
    }
}

/// The frame around an area-light photon's direction `d` (world, unit; `local` in the
/// light's frame `light`) whose first tangent is the light's first tangent made
/// perpendicular to `d`: the directional frame aligned with the positional one, so that
/// the two spreads add up instead of shearing the footprint. This is
/// [`Frame::from_normal_and_hint`]`(d, light.t)` with the projection taken in the light's
/// frame: `d·t = x` and `|t − x d|² = 1 − x² = y² + z²` (no cancellation), one square root
/// and no normalisation of `d` again. Directions within 30° of `±t` (one Gram–Schmidt
/// pass is not enough there) take the general construction.
#[inline(always)]
fn directional_frame(light: &Frame, local: DVec3, d: DVec3) -> Frame {
    let len2 = local.y * local.y + local.z * local.z;
    if !(len2 >= 0.25) {
        return Frame::from_normal_and_hint(d, light.t);
    }
    let t = (light.t - d * local.x) * (1.0 / libm::sqrt(len2));
    Frame { t, b: d.cross(t), n: d }
}

/// Why [`Light::emit`] failed.
#[derive(Clone, Copy, Debug, PartialEq, Eq, thiserror::Error)]
pub enum EmissionError {
    /// The light is invalid.
    #[error(transparent)]
    Light(#[from] LightError),
    /// The initial differential is not finite.
    #[error(transparent)]
    Differential(#[from] DifferentialError),
    /// An [`EmissionParams`] field is out of range (the message names it).
    #[error("emission parameters: {0}")]
    Params(&'static str),
}

/// The 176-byte `f32` record of a [`PreparedLight`] for GPU storage buffers: the WGSL
/// twin's `ArpaLight` (`arpa-core/shaders/emit/emission.wgsl`, [`crate::gpu::shaders::EMISSION`]),
/// whose `arpa_emit` emits photon `index` from it as [`PreparedLight::emit`] does. Built by
/// [`PreparedLight::pack`]; positions in metres, angles in radians, flux in W per photon.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
pub struct PackedLight {
    /// 0 point, 1 spot, 2 directional, 3 triangle, 4 quad, 5 environment.
    pub kind: u32,
    /// Spot falloff: 0 linear in angle, 1 smoothstep.
    pub falloff: u32,
    /// Photons this iteration, `N`.
    pub photon_count: u32,
    /// Projection grid cells per side ([`CellDomain::grid`]); 0: the whole domain.
    pub cell_grid: u32,
    /// Point/spot position, triangle vertex 0 or quad origin (m).
    pub p0: [f32; 3],
    /// Scene bounding-sphere radius (m).
    pub scene_radius: f32,
    /// Triangle vertex 1 or quad `edge_u` (m).
    pub p1: [f32; 3],
    /// Spot cut-off half-angle (rad).
    pub cutoff: f32,
    /// Triangle vertex 2 or quad `edge_v` (m).
    pub p2: [f32; 3],
    /// Spot full-intensity half-angle (rad).
    pub beam_width: f32,
    /// Light frame tangent `t` (spot axis frame, directional beam frame, emitter plane).
    pub frame_t: [f32; 3],
    /// `ℓ_x` (m).
    pub len_positional: f32,
    /// Light frame bitangent `b`.
    pub frame_b: [f32; 3],
    /// `ℓ_ω` (rad).
    pub len_directional: f32,
    /// Light frame axis `n`.
    pub frame_n: [f32; 3],
    /// Directional length at diffuse re-emission (rad).
    pub len_reemission: f32,
    /// Flux per photon before the spot falloff (W, RGB).
    pub flux: [f32; 3],
    /// `1 − cos(cutoff) = 2 sin²(cutoff/2)` (computed in f64; f32 cannot form it for narrow cones).
    pub one_minus_cos_cutoff: f32,
    /// Scene bounding-sphere centre (m).
    pub scene_centre: [f32; 3],
    /// Weight of the caustic records of this light's photons (the two passes' balance
    /// heuristic, [`crate::render::projection`]; 0: they store none). Set by whoever lays out the
    /// photon pass's tables ([`crate::gpu::fill::emitter_tables`]); 1 from
    /// [`PreparedLight::pack`].
    pub caustic_weight: f32,
    /// Cranley–Patterson shift of the Fibonacci lattice this iteration.
    pub lattice_shift: [f32; 2],
    /// Index of the light's first projection cell in the caller's cell table (the photon
    /// pass's `photon_cells`, [`crate::gpu::fill::cell_table`]; set by
    /// [`crate::gpu::fill::emitter_tables`], 0 from [`PreparedLight::pack`]); the
    /// shader reads entry `cell_first + arpa_emission_slot(..)`.
    pub cell_first: u32,
    /// Projection cells sampled ([`CellDomain::count`]); 0: the whole domain.
    pub cell_count: u32,
    /// [`EmissionParams::cell_offset`] of this iteration.
    pub cell_offset: u32,
    /// A textured emitter triangle's record in the photon pass's texture words
    /// (`crate::gpu::texture::emitter_records`; set by `crate::gpu::fill::emitter_tables`),
    /// or `u32::MAX` (no texture; what [`PreparedLight::pack`] gives).
    pub emission_record: u32,
    /// Padding (0).
    pub pad3: [u32; 2],
}

// The WGSL struct `ArpaLight` has exactly this size (eight vec3 + scalar groups, a header
// and the lattice shift).
const _: () = assert!(core::mem::size_of::<PackedLight>() == 176);

impl PreparedLight {
    /// The GPU record of this light (see [`PackedLight`]); every value rounded once to `f32`.
    pub fn pack(&self) -> PackedLight {
        let f = |v: DVec3| v.as_vec3().to_array();
        let zero = [0.0f32; 3];
        let kind = self.light.kind_code();
        let (p0, p1, p2, cutoff, beam_width, falloff) = match &self.light {
            Light::Point(l) => (f(l.position), zero, zero, 0.0, 0.0, 0),
            Light::Spot(l) => (f(l.position), zero, zero, l.cutoff as f32, l.beam_width as f32, l.falloff.code()),
            Light::Directional(_) => (zero, zero, zero, 0.0, 0.0, 0),
            Light::Triangle(l) => (f(l.p[0]), f(l.p[1]), f(l.p[2]), 0.0, 0.0, 0),
            Light::Quad(l) => (f(l.origin), f(l.edge_u), f(l.edge_v), 0.0, 0.0, 0),
            Light::Environment(_) => (zero, zero, zero, 0.0, 0.0, 0),
        };
        let one_minus_cos_cutoff = if let Light::Spot(l) = &self.light { cone_solid_angle_from_angle(l.cutoff) / TAU } else { 2.0 };
        PackedLight {
            kind,
            falloff,
            photon_count: self.params.photon_count,
            cell_grid: self.params.cells.grid,
            p0,
            scene_radius: self.params.scene_sphere.1 as f32,
            p1,
            cutoff,
            p2,
            beam_width,
            frame_t: f(self.frame.t),
            len_positional: self.lengths.positional as f32,
            frame_b: f(self.frame.b),
            len_directional: self.lengths.directional as f32,
            frame_n: f(self.frame.n),
            len_reemission: self.lengths.reemission as f32,
            flux: f(self.flux),
            one_minus_cos_cutoff: one_minus_cos_cutoff as f32,
            scene_centre: f(self.params.scene_sphere.0),
            caustic_weight: 1.0,
            lattice_shift: self.params.lattice_shift.as_vec2().to_array(),
            cell_first: 0,
            cell_count: self.params.cells.count,
            cell_offset: self.params.cell_offset,
            emission_record: u32::MAX,
            pad3: [0; 2],
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::base::rng::{Rng, StreamDomain};

    /// The area-light photon's directional frame taken in the light's frame agrees with
    /// the general construction to rounding, is orthonormal, and is right-handed around
    /// the direction, for tilted lights and for directions near the light's tangent (where
    /// it falls back to the general construction).
    #[test]
    fn directional_frame_matches_the_general_construction() {
        let mut rng = Rng::new(5, 0, 0, StreamDomain::User);
        let normals = [DVec3::Z, DVec3::new(0.3, -0.8, 0.52), DVec3::new(-1.0, 1e-3, 0.0), DVec3::new(0.0, -1.0, 0.0)];
        let hints = [DVec3::X, DVec3::new(1.0, 0.2, -0.4), DVec3::Z, DVec3::new(0.7, 0.0, 0.7)];
        let mut general = 0;
        for (n, hint) in normals.into_iter().zip(hints) {
            let light = Frame::from_normal_and_hint(n, hint);
            for k in 0..20_000 {
                // Every 50th sample grazes along ±t.
                let local = if k % 50 == 0 {
                    let a = 1e-3 * rng.next_f64();
                    DVec3::new(if k % 100 == 0 { 1.0 } else { -1.0 } * (1.0 - a * a).sqrt(), 0.0, a)
                } else {
                    cosine_hemisphere(rng.next_2d())
                };
                if local.y * local.y + local.z * local.z < 0.25 {
                    general += 1;
                }
                let d = crate::base::frame::unit_or(light.to_world(local), light.n);
                let f = directional_frame(&light, local, d);
                let g = Frame::from_normal_and_hint(d, light.t);
                assert!((f.t - g.t).abs().max_element() <= 1e-14, "{local:?}: {:?} vs {:?}", f.t, g.t);
                assert!((f.b - g.b).abs().max_element() <= 1e-14, "{local:?}: {:?} vs {:?}", f.b, g.b);
                // Orthonormal and right-handed to rounding, as the general construction is.
                let err = |f: &Frame| [(f.t.length() - 1.0).abs(), f.t.dot(d).abs(), (f.t.cross(f.b) - d).length()];
                let (ef, eg) = (err(&f), err(&g));
                for k in 0..3 {
                    assert!(ef[k] <= 2e-15, "{local:?}: {ef:?} (general {eg:?})");
                }
            }
        }
        assert!(general > 100, "the fallback was exercised {general} times");
    }
}
