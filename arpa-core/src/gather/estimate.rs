//! Radiance estimation at a diffuse query point (ARPA §4.3, digest §7.2):
//!
//! `L(q) = ρ/π · [ Σ_footprints Φ_p W_p(q) + Σ_progressive Φ_p 1[|q − x_p| < r_i] / (π r_i²) ]`
//!
//! for a Lambertian surface of albedo `ρ`. Each map's irradiance is kept separately.
//! Contributions from footprints and photons whose lit side faces away from the query's
//! normal are skipped (no light through thin two-sided walls).

use crate::store::footprint::{Footprint, PackedFootprint, PhotonMap};
use crate::gather::kernel::Kernel;
use crate::store::progressive_photon::{PackedPhoton, ProgressivePhoton};
use core::f64::consts::FRAC_1_PI;
use glam::{DVec3, Vec3};

/// A diffuse query point found by the camera pass.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct QueryPoint {
    /// Position (metres).
    pub position: Vec3,
    /// Unit geometric normal oriented towards the viewer (flipped where the viewer lies
    /// below the shading plane, see [`crate::render::tracer::QueryRecord::normal`]).
    pub normal: Vec3,
}

/// Irradiance gathered at one query point, per map (W/m², RGB), accumulated in `f64`.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct IrradianceEstimate {
    /// Indexed by [`PhotonMap::index`].
    pub per_map: [DVec3; 2],
    /// Number of footprints that contributed.
    pub footprints: u32,
    /// Number of progressive photons that contributed.
    pub photons: u32,
    /// Records tested against the query point (by `add_footprint` / `add_photon`: the
    /// candidates an acceleration structure reported), per map.
    pub candidates: [u32; 2],
    /// Records that contributed (non-zero, finite), per map.
    pub contributions: [u32; 2],
}

impl IrradianceEstimate {
    /// Adds an already evaluated contribution `e` (W/m²) of `map`; zero or non-finite
    /// contributions are skipped. Returns `true` when it counted.
    #[inline]
    pub fn add(&mut self, map: PhotonMap, e: Vec3) -> bool {
        if e == Vec3::ZERO || !e.is_finite() {
            return false;
        }
        self.per_map[map.index()] += e.as_dvec3();
        self.contributions[map.index()] += 1;
        true
    }

    /// Adds a footprint's contribution if it contains `q` (exact ellipse + slab test)
    /// and faces it. Returns `true` when it contributed.
    #[inline]
    pub fn add_footprint(&mut self, fp: &PackedFootprint, q: &QueryPoint, kernel: Kernel) -> bool {
        self.candidates[fp.photon_map().index()] += 1;
        let counted = self.add(fp.photon_map(), fp.irradiance(q.position, q.normal, kernel));
        self.footprints += counted as u32;
        counted
    }

    /// [`IrradianceEstimate::add_footprint`] that also returns the footprint's contribution
    /// at every scale of the bandwidth ladder ([`PackedFootprint::irradiance_scales`];
    /// element 0 is the one added here), evaluating the record once.
    #[inline]
    pub fn add_footprint_scales(&mut self, fp: &PackedFootprint, q: &QueryPoint, kernel: Kernel) -> [Vec3; crate::gather::scales::SCALES] {
        let map = fp.photon_map();
        self.candidates[map.index()] += 1;
        let e = fp.irradiance_scales(q.position, q.normal, kernel);
        self.footprints += self.add(map, e[0]) as u32;
        e
    }

    /// [`IrradianceEstimate::add_photon`] that also returns the photon's contribution at
    /// every scale ([`PackedPhoton::irradiance_scales`]; element 0 is the one added here).
    #[inline]
    pub fn add_photon_scales(&mut self, ph: &PackedPhoton, q: &QueryPoint, radii: [f32; 2]) -> [Vec3; crate::gather::scales::SCALES] {
        let map = ph.photon_map();
        self.candidates[map.index()] += 1;
        let e = ph.irradiance_scales(q.position, q.normal, radii[map.index()]);
        self.photons += self.add(map, e[0]) as u32;
        e
    }

    /// Adds a progressive photon's contribution for its map's radius `radii[map]`.
    #[inline]
    pub fn add_photon(&mut self, ph: &PackedPhoton, q: &QueryPoint, radii: [f32; 2]) -> bool {
        let map = ph.photon_map();
        self.candidates[map.index()] += 1;
        let counted = self.add(map, ph.irradiance(q.position, q.normal, radii[map.index()]));
        self.photons += counted as u32;
        counted
    }

    /// Total irradiance of both maps (W/m²).
    #[inline]
    pub fn irradiance(&self) -> DVec3 {
        self.per_map[0] + self.per_map[1]
    }

    /// Irradiance of one map (W/m²).
    #[inline]
    pub fn map(&self, map: PhotonMap) -> DVec3 {
        self.per_map[map.index()]
    }

    /// Outgoing radiance of a Lambertian surface of albedo `albedo`: `ρ/π · E`
    /// (W/(m²·sr)). Non-finite components become 0.
    #[inline]
    pub fn lambertian_radiance(&self, albedo: DVec3) -> DVec3 {
        let l = albedo * FRAC_1_PI * self.irradiance();
        DVec3::select(l.is_finite_mask(), l, DVec3::ZERO)
    }
}

/// Brute-force gather over all `footprints` and `photons` (the packed `f32` records a
/// gather reads) with the progressive radii `radii` (metres, `[caustic, global]`, as
/// [`crate::accumulate::radius::ProgressiveConfig::radii`] gives them; the records use them in `f32`):
/// the reference the backends' acceleration structures must reproduce.
pub fn gather_brute_force(q: &QueryPoint, footprints: &[PackedFootprint], photons: &[PackedPhoton], radii: [f64; 2], kernel: Kernel) -> IrradianceEstimate {
    let radii = radii.map(|r| r as f32);
    let mut e = IrradianceEstimate::default();
    for fp in footprints {
        e.add_footprint(fp, q, kernel);
    }
    for ph in photons {
        e.add_photon(ph, q, radii);
    }
    e
}

/// [`gather_brute_force`] at every scale of the bandwidth ladder ([`crate::gather::scales`]):
/// the per-scale irradiance of both maps, summed in the same record order (footprints,
/// then photons). Scale 0 is `gather_brute_force(..).irradiance()`'s sum of the same
/// contributions.
pub fn gather_brute_force_scales(q: &QueryPoint, footprints: &[PackedFootprint], photons: &[PackedPhoton], radii: [f64; 2], kernel: Kernel) -> crate::gather::scales::ScaleSums {
    let radii = radii.map(|r| r as f32);
    let mut sums = crate::gather::scales::ScaleSums::default();
    for fp in footprints {
        sums.add(&fp.irradiance_scales(q.position, q.normal, kernel));
    }
    for ph in photons {
        sums.add(&ph.irradiance_scales(q.position, q.normal, radii[ph.photon_map().index()]));
    }
    sums
}

/// The same estimate in `f64` over unpacked records: footprints as the heuristics leave
/// them ([`crate::store::heuristics::Heuristics::apply`]; their slab limited by their map's
/// radius) and progressive photons, at query point `q` (metres) with unit normal
/// `query_normal`, for progressive radii `radii` (metres, `[caustic, global]`). For
/// renderer authors checking their own pipeline against analytic irradiance without the
/// `f32` storage; per map, as [`IrradianceEstimate`].
///
/// # Example: a point light over a plane
/// Irradiance under a point light of intensity `I` at height `h` is `E(ρ) = I h /
/// (h² + ρ²)^{3/2}` at distance `ρ` from the foot point, so the mean over the disc
/// `ρ < a` is the flux through it over its area, `I 2π (1 − h/√(h² + a²)) / (π a²)`.
/// The photons' footprints reproduce it, iteration after iteration (each iteration's
/// lattice shifted by [`EmissionParams::for_iteration`](crate::emit::emission::EmissionParams::for_iteration)):
///
/// ```
/// use arpa_core::emit::emission::{EmissionParams, Light, PointLight};
/// use arpa_core::gather::estimate::estimate_f64;
/// use arpa_core::store::footprint::{Footprint, PhotonMap};
/// use arpa_core::glam::DVec3;
/// use arpa_core::gather::kernel::Kernel;
/// use arpa_core::base::rng::{Rng, StreamDomain};
///
/// let (h, intensity, a) = (1.0, 10.0, 0.1);
/// let light = Light::Point(PointLight { position: DVec3::new(0.0, 0.0, h), intensity: DVec3::splat(intensity) });
/// let (n, iterations, seed) = (4000, 8, 1);
/// // Query points on a polar grid of the disc, each standing for an equal area.
/// let points: Vec<DVec3> = (0..8)
///     .flat_map(|i| (0..16).map(move |j| {
///         let (rho, phi) = (a * ((i as f64 + 0.5) / 8.0).sqrt(), core::f64::consts::TAU * j as f64 / 16.0);
///         DVec3::new(rho * phi.cos(), rho * phi.sin(), 0.0)
///     }))
///     .collect();
/// let mut mean = 0.0;
/// for iteration in 0..iterations {
///     let light = light.prepare(&EmissionParams::new(n).for_iteration(seed, iteration, 0)).unwrap();
///     let mut footprints = Vec::new();
///     for i in 0..n {
///         let photon = light.emit(i, &mut Rng::new(seed, iteration, i, StreamDomain::Photon)).unwrap();
///         if photon.ray.d.z >= 0.0 {
///             continue; // leaves upwards: the plane is the only surface
///         }
///         let hit = photon.ray.transfer(-photon.ray.p.z / photon.ray.d.z, DVec3::Z).unwrap();
///         footprints.push(Footprint::from_hit(&hit, DVec3::Z, photon.flux, PhotonMap::Global).unwrap());
///     }
///     for &q in &points {
///         let e = estimate_f64(q, DVec3::Z, &footprints, &[], [1.0; 2], Kernel::Silverman);
///         mean += e.irradiance().x / (points.len() * iterations as usize) as f64;
///     }
/// }
/// let exact = intensity * 2.0 * (1.0 - h / (h * h + a * a).sqrt()) / (a * a);
/// assert!((mean / exact - 1.0).abs() < 0.03, "{mean} W/m² against {exact} W/m²");
/// ```
pub fn estimate_f64(q: DVec3, query_normal: DVec3, footprints: &[Footprint], photons: &[ProgressivePhoton], radii: [f64; 2], kernel: Kernel) -> IrradianceEstimate {
    let mut e = IrradianceEstimate::default();
    for fp in footprints {
        let c = fp.irradiance(q, query_normal, radii[fp.map.index()], kernel);
        e.candidates[fp.map.index()] += 1;
        if c != DVec3::ZERO {
            e.per_map[fp.map.index()] += c;
            e.contributions[fp.map.index()] += 1;
            e.footprints += 1;
        }
    }
    for ph in photons {
        let c = ph.irradiance(q, query_normal, radii[ph.map.index()]);
        e.candidates[ph.map.index()] += 1;
        if c != DVec3::ZERO {
            e.per_map[ph.map.index()] += c;
            e.contributions[ph.map.index()] += 1;
            e.photons += 1;
        }
    }
    e
}
