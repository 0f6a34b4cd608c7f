//! Radiance estimation at a diffuse query point (ARPA §4.3, digest §7.2):
//!
//! `L(q) = ρ/π · [ Σ_footprints Φ_p W_p(q) + Σ_progressive Φ_p 1[|q − x_p| < r_i] / (π r_i²) ]`
//!
//! for a Lambertian surface of albedo `ρ`. Each map's irradiance is kept separately.
//! Contributions from footprints and photons whose lit side faces away from the query's
//! normal are skipped (no light through thin two-sided walls).

use crate::footprint::{Footprint, PackedFootprint, PhotonMap};
use crate::kernel::Kernel;
use crate::progressive_photon::{PackedPhoton, ProgressivePhoton};
use core::f64::consts::FRAC_1_PI;
use glam::{DVec3, Vec3};

/// A diffuse query point found by the camera pass.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct QueryPoint {
    /// Position (metres).
    pub position: Vec3,
    /// Unit geometric normal oriented towards the viewer (flipped where the viewer lies
    /// below the shading plane, see [`crate::tracer::QueryRecord::normal`]).
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
        true
    }

    /// Adds a footprint's contribution if it contains `q` (exact ellipse + slab test)
    /// and faces it. Returns `true` when it contributed.
    #[inline]
    pub fn add_footprint(&mut self, fp: &PackedFootprint, q: &QueryPoint, kernel: Kernel) -> bool {
        let counted = self.add(fp.photon_map(), fp.irradiance(q.position, q.normal, kernel));
        self.footprints += counted as u32;
        counted
    }

    /// Adds a progressive photon's contribution for its map's radius `radii[map]`.
    #[inline]
    pub fn add_photon(&mut self, ph: &PackedPhoton, q: &QueryPoint, radii: [f32; 2]) -> bool {
        let map = ph.photon_map();
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
/// [`crate::radius::ProgressiveConfig::radii`] gives them; the records use them in `f32`):
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

/// The same estimate in `f64` over unpacked records: footprints as the heuristics leave
/// them ([`crate::heuristics::Heuristics::apply`]; their slab limited by their map's
/// radius) and progressive photons, at query point `q` (metres) with unit normal
/// `query_normal`, for progressive radii `radii` (metres, `[caustic, global]`). For
/// renderer authors checking their own pipeline against analytic irradiance without the
/// `f32` storage; per map, as [`IrradianceEstimate`].
pub fn estimate_f64(q: DVec3, query_normal: DVec3, footprints: &[Footprint], photons: &[ProgressivePhoton], radii: [f64; 2], kernel: Kernel) -> IrradianceEstimate {
    let mut e = IrradianceEstimate::default();
    for fp in footprints {
        let c = fp.irradiance(q, query_normal, radii[fp.map.index()], kernel);
        if c != DVec3::ZERO {
            e.per_map[fp.map.index()] += c;
            e.footprints += 1;
        }
    }
    for ph in photons {
        let c = ph.irradiance(q, query_normal, radii[ph.map.index()]);
        if c != DVec3::ZERO {
            e.per_map[ph.map.index()] += c;
            e.photons += 1;
        }
    }
    e
}
