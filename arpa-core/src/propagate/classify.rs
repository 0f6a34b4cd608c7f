//! Photon classification (caustic `L S⁺ D` versus global) and the per-map smoothing
//! factors `S_c`, `S_g` applied on absorption (ARPA §4.2, §4.4).

use crate::store::footprint::{Footprint, PhotonMap};

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
/// ([`crate::emit::emission`]). Carried to a surface, the footprints still tile it about once,
/// so with `S = 1` a point is covered by about one footprint per iteration: the
/// per-iteration estimate is close to a one-nearest-neighbour estimate, whose relative
/// standard deviation is of order one **whatever `N`** (more photons only make the
/// footprints smaller). `S` scales both differentials, so a point is covered by about `S²`
/// footprints and the per-iteration standard deviation falls roughly like `1/S`, while the
/// bias grows with the footprint area (`∝ S²/N` times the irradiance's curvature). The
/// progressive average over `K` iterations divides the variance by `K`; the bias stays
/// unless the footprints shrink with the iterations (dampening against the shrinking
/// progressive radius, [`crate::store::heuristics::Dampening`]).
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

/// Automatic smoothing: `S_c`, `S_g` chosen from a pilot iteration rendered at `S = 1`, so
/// that every point a map lights is covered by about [`AutoSmoothing::overlap`] of its
/// footprints per iteration.
///
/// # The target overlap
/// At a point covered by `k` footprints of a map, the per-iteration estimate has a relative
/// variance of about `v/k` (`v ≈ 0.85`: one footprint, see [`Smoothing`]) and a bias that
/// grows with the footprint area, `≈ β k` (`β`: the irradiance's relative curvature over
/// the area one photon covers). Averaged over `K` iterations the squared error is
/// `v/(kK) + β²k²`, smallest at `k* = (v / (2 β² K))^{1/3}`: more overlap for short renders
/// and smooth light, less for long renders and sharp caustics. `β` is not known before
/// rendering, so the default `k = 8` is `k*` for `K = 100` iterations (a 10 s render at
/// 50K photons per iteration on the shared scenes) and `β ≈ 0.3 %` per footprint;
/// per iteration it leaves a relative standard deviation of about `√(v/8) ≈ 0.33`.
///
/// # From the pilot to `S`
/// The pilot measures each map's overlap `c` at `S = 1` (contributions per covered query
/// point, [`crate::render::tracer::IterationStats::overlap`]). `S` scales both axes before the
/// heuristics; dampened adaptation with exponent `γ` ([`crate::store::heuristics::Dampening`])
/// then leaves the axes `∝ S^γ`, so the area and the overlap grow like `S^{2γ}` (`S²`
/// without dampening), and `S = (k/c)^{1/(2γ)}`, clamped to [`AutoSmoothing::min`],
/// [`AutoSmoothing::max`]. A map without contributions in the pilot keeps `S = 1`. Where
/// the H-max limit clamps footprints, `S` does not change their size.
///
/// # Progressive
/// `S` then stays fixed, and the footprints shrink with the iterations: dampening pulls
/// their axes towards twice the map's progressive radius `r_i`, so axes `∝ r_i^{1−γ}` and
/// the overlap per iteration `∝ (r_i/r_1)^{2(1−γ)}`; with PPM's `r_i² ∝ i^{α−1}` that is
/// `i^{−(1−α)(1−γ)}` (`α = 2/3`, `γ = 1/4`: `i^{−1/4}`), so the bias vanishes while the
/// accumulated contributions still grow without bound, and the estimate stays consistent.
/// Without dampening the overlap does not shrink: fix `S` then, or keep dampening on.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AutoSmoothing {
    /// Target footprints of a map per covered point per iteration (`k`) with a global
    /// bandwidth.
    pub overlap: f64,
    /// The same target for the stored (largest) scale of a per-pixel bandwidth render
    /// ([`crate::accumulate::bandwidth`]): 8, the global target, so the stored footprints are the global
    /// choice and the ladder's smaller scales refine it where the light has structure, with
    /// the gather's candidates those of a global render (a larger stored scale costs gather
    /// time in every pixel, also where the stored one is chosen).
    pub per_pixel_overlap: f64,
    /// Smallest `S` chosen.
    pub min: f64,
    /// Largest `S` chosen.
    pub max: f64,
}

impl Default for AutoSmoothing {
    fn default() -> Self {
        Self { overlap: 8.0, per_pixel_overlap: 8.0, min: 1.0 / 16.0, max: 16.0 }
    }
}

impl AutoSmoothing {
    /// These parameters with the target overlap of `bandwidth`: [`AutoSmoothing::overlap`]
    /// for a global one, [`AutoSmoothing::per_pixel_overlap`] for the stored scale of a
    /// per-pixel one.
    pub fn for_bandwidth(&self, bandwidth: crate::gather::scales::Bandwidth) -> Self {
        match bandwidth {
            crate::gather::scales::Bandwidth::Global => *self,
            crate::gather::scales::Bandwidth::PerPixel => Self { overlap: self.per_pixel_overlap, ..*self },
        }
    }

    /// `S_c`, `S_g` for a pilot that measured `overlap_at_one` (`[caustic, global]`, at
    /// `S = 1`) with `dampening` (the heuristics' dampened adaptation, if on).
    pub fn resolve(&self, overlap_at_one: [f64; 2], dampening: Option<&crate::store::heuristics::Dampening>) -> Smoothing {
        let growth = match dampening {
            Some(d) if d.exponent > 0.0 && d.exponent.is_finite() => 2.0 * d.exponent,
            _ => 2.0,
        };
        let s = |c: f64| {
            if c > 0.0 && c.is_finite() {
                libm::pow(self.overlap / c, 1.0 / growth).clamp(self.min, self.max)
            } else {
                1.0
            }
        };
        Smoothing { caustic: s(overlap_at_one[0]), global: s(overlap_at_one[1]) }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use SurfaceInteraction::*;

    #[test]
    fn auto_smoothing_inverts_the_overlap_growth() {
        use crate::store::heuristics::{DampenReference, Dampening};
        let auto = AutoSmoothing::default();
        let d = Dampening { exponent: 0.25, reference: DampenReference::ProgressiveDiameter };
        // Overlap 2 at S = 1 grows like S^0.5 with dampening: S = (8/2)^2 = 16.
        let s = auto.resolve([2.0, 0.5], Some(&d));
        assert!((s.caustic - 16.0).abs() < 1e-12, "{s:?}");
        // 0.5 would need S = 256: clamped.
        assert_eq!(s.global, auto.max);
        // Without dampening the overlap grows like S^2.
        let s = auto.resolve([32.0, 0.0], None);
        assert!((s.caustic - 0.5).abs() < 1e-12 && s.global == 1.0, "{s:?}");
        let s = auto.resolve([f64::NAN, 8.0], Some(&d));
        assert_eq!((s.caustic, s.global), (1.0, 1.0));
    }

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
