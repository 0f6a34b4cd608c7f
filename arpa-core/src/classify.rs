//! Photon classification (caustic `L S⁺ D` versus global) and the per-map smoothing
//! factors `S_c`, `S_g` applied on absorption (ARPA §4.2, §4.4).

use crate::footprint::{Footprint, PhotonMap};

/// What kind of surface interaction a photon just had.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SurfaceInteraction {
    /// Perfectly specular reflection or transmission (mirror, conductor, dielectric,
    /// or glossy below the roughness cut-off).
    Specular,
    /// Diffuse (or rough above the cut-off): the photon is stored here, then re-emitted.
    Diffuse,
}

/// Tracks a photon path from the light to classify each diffuse hit. RTPM's default
/// "LS+D" rule: a diffuse hit is caustic iff at least one specular event and no diffuse
/// event happened before it.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct PathClassifier {
    specular_events: u32,
    diffuse_events: u32,
}

impl PathClassifier {
    /// A path just leaving the light.
    pub const fn new() -> Self {
        Self { specular_events: 0, diffuse_events: 0 }
    }

    /// The map a diffuse hit *now* would be stored in.
    #[inline]
    pub const fn map_at_diffuse_hit(&self) -> PhotonMap {
        if self.specular_events > 0 && self.diffuse_events == 0 { PhotonMap::Caustic } else { PhotonMap::Global }
    }

    /// Records an interaction and, for a diffuse one, returns the map the photon is
    /// stored in *at* that hit (classification happens before the event is recorded).
    #[inline]
    pub fn record(&mut self, interaction: SurfaceInteraction) -> Option<PhotonMap> {
        match interaction {
            SurfaceInteraction::Specular => {
                self.specular_events = self.specular_events.saturating_add(1);
                None
            }
            SurfaceInteraction::Diffuse => {
                let map = self.map_at_diffuse_hit();
                self.diffuse_events = self.diffuse_events.saturating_add(1);
                Some(map)
            }
        }
    }

    /// Specular events so far.
    pub const fn specular_events(&self) -> u32 {
        self.specular_events
    }

    /// Diffuse events so far.
    pub const fn diffuse_events(&self) -> u32 {
        self.diffuse_events
    }
}

/// Smoothing factors `S_c` (caustic) and `S_g` (global): dimensionless scales of the
/// footprint differentials applied on absorption, before the heuristics.
///
/// # Noise and bias against `S`
/// Emission tiles each light's domain once: `N` photons, each footprint `1/N` of it
/// ([`crate::emission`]). Carried to a surface, the footprints still tile it about once,
/// so with `S = 1` a point is covered by about one footprint per iteration: the
/// per-iteration estimate is close to a one-nearest-neighbour estimate, whose relative
/// standard deviation is of order one **whatever `N`** (more photons only make the
/// footprints smaller). `S` scales both differentials, so a point is covered by about `S²`
/// footprints and the per-iteration standard deviation falls roughly like `1/S`, while the
/// bias grows with the footprint area (`∝ S²/N` times the irradiance's curvature). The
/// progressive average over `K` iterations divides the variance by `K`; the bias stays
/// unless the footprints shrink with the iterations (dampening against the shrinking
/// progressive radius, [`crate::heuristics::Dampening`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Smoothing {
    /// `S_c`.
    pub caustic: f64,
    /// `S_g`.
    pub global: f64,
}

impl Default for Smoothing {
    fn default() -> Self {
        Self { caustic: 1.0, global: 1.0 }
    }
}

impl Smoothing {
    /// The factor for `map`.
    #[inline]
    pub fn factor(&self, map: PhotonMap) -> f64 {
        match map {
            PhotonMap::Caustic => self.caustic,
            PhotonMap::Global => self.global,
        }
    }

    /// `fp` with `D_u`, `D_v` scaled by its map's factor; flux unchanged.
    #[inline]
    pub fn apply(&self, fp: Footprint) -> Footprint {
        fp.scaled(self.factor(fp.map))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use SurfaceInteraction::*;

    #[test]
    fn lsd_rule() {
        let mut p = PathClassifier::new();
        assert_eq!(p.record(Diffuse), Some(PhotonMap::Global)); // direct L D
        assert_eq!(p.record(Specular), None);
        assert_eq!(p.record(Diffuse), Some(PhotonMap::Global)); // L D S D
        let mut p = PathClassifier::new();
        p.record(Specular);
        p.record(Specular);
        assert_eq!(p.record(Diffuse), Some(PhotonMap::Caustic)); // L S S D
        assert_eq!(p.record(Diffuse), Some(PhotonMap::Global)); // L S S D D
    }
}
