//! The backend-agnostic [`Tracer`] trait that the CPU, wgpu and Vulkan backends implement,
//! with the settings, records and statistics that cross it.
//!
//! Designed for a GPU: the backend owns the scene, photon, footprint and image buffers;
//! [`Tracer::iterate`] runs the stages without host round trips; the host reads back only
//! through the explicit `read_*` calls (the image, and the stage outputs the conformance
//! suite inspects). Stages, in order:
//!
//! ```text
//! upload_scene -> camera_pass -> photon_pass -> build_acceleration_structure -> gather -> accumulate
//! ```

use crate::classify::Smoothing;
use crate::footprint::PackedFootprint;
use crate::heuristics::{DampenReference, Heuristics};
use crate::kernel::Kernel;
use crate::progressive_photon::PackedPhoton;
use crate::radius::{ProgressiveConfig, RadiusSpec};
use crate::scene::Scene;
use crate::store::{ProgressiveReason, StoredPhoton};
use alloc::format;
use alloc::string::String;
use alloc::vec::Vec;
use glam::Vec3;

/// The density-estimation method.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum Method {
    /// Photon differentials with the PPM fallback of the heuristics (ARPA).
    #[default]
    Arpa,
    /// Progressive photon mapping with photons as spheres of the progressive radius
    /// (Kern et al.'s RTPM), the baseline. Its photons carry no ray differentials (the
    /// photon pass skips their propagation) and are stored at the surface point they hit.
    Rtpm,
}

impl Method {
    /// Lower-case name as used on the command line.
    pub const fn name(self) -> &'static str {
        match self {
            Method::Arpa => "arpa",
            Method::Rtpm => "rtpm",
        }
    }
}

/// Everything that controls a render besides the scene.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RenderSettings {
    /// Density-estimation method.
    pub method: Method,
    /// Photons emitted per iteration, shared by all lights in proportion to their power.
    pub photons_per_iteration: u32,
    /// Seed of every random stream.
    pub seed: u32,
    /// Maximum number of surface interactions of a photon path and of a camera path.
    pub max_depth: u32,
    /// Direct lighting by next-event estimation at the query points (then the photon
    /// maps hold no direct `L D` photons).
    pub direct_lighting: bool,
    /// Smoothing factors `S_c`, `S_g`.
    pub smoothing: Smoothing,
    /// Footprint heuristics.
    pub heuristics: Heuristics,
    /// Progressive radii of both maps.
    pub radii: ProgressiveConfig,
    /// Kernel of the footprints (progressive photons always use the constant kernel).
    pub kernel: Kernel,
}

impl Default for RenderSettings {
    fn default() -> Self {
        Self {
            method: Method::Arpa,
            photons_per_iteration: 250_000,
            seed: 0,
            max_depth: 10,
            direct_lighting: true,
            smoothing: Smoothing::default(),
            heuristics: Heuristics::default(),
            radii: ProgressiveConfig::default(),
            kernel: Kernel::default(),
        }
    }
}

/// Settings no render can use, with the reason (names the field and its value).
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[error("{0}")]
pub struct InvalidSettings(pub String);

impl RenderSettings {
    /// Rejects settings no render can use: zero photons or depth, non-positive or
    /// non-finite smoothing factors and radii, `alpha` outside `(0, 1]`, and heuristic
    /// parameters outside their ranges. Every backend calls it in `upload_scene`.
    pub fn validate(&self) -> Result<(), InvalidSettings> {
        let s = self;
        let bad = |why: String| Err(InvalidSettings(why));
        let positive = |x: f64| x > 0.0 && x.is_finite();
        if s.photons_per_iteration == 0 {
            return bad("photons_per_iteration must be at least 1".into());
        }
        if s.max_depth == 0 {
            return bad("max_depth must be at least 1".into());
        }
        for (name, f) in [
            ("smoothing.caustic", s.smoothing.caustic),
            ("smoothing.global", s.smoothing.global),
        ] {
            if !positive(f) {
                return bad(format!("{name} must be positive and finite (got {f})"));
            }
        }
        for (name, spec) in [
            ("radii.caustic", s.radii.caustic),
            ("radii.global", s.radii.global),
        ] {
            let (RadiusSpec::Absolute(v) | RadiusSpec::RelativeToDiagonal(v)) = spec;
            if !positive(v) {
                return bad(format!("{name} must be positive and finite (got {v})"));
            }
        }
        if !(s.radii.alpha > 0.0 && s.radii.alpha <= 1.0) {
            return bad(format!(
                "radii.alpha must lie in (0, 1] (got {})",
                s.radii.alpha
            ));
        }
        let h = &s.heuristics;
        if let Some(d) = h.dampening {
            if !(d.exponent > 0.0 && d.exponent <= 1.0) {
                return bad(format!(
                    "dampening exponent must lie in (0, 1] (got {})",
                    d.exponent
                ));
            }
            if let DampenReference::Absolute(l) = d.reference
                && !positive(l)
            {
                return bad(format!(
                    "dampening reference length must be positive and finite (got {l})"
                ));
            }
        }
        if let Some(m) = h.h_max {
            let (crate::heuristics::LengthSpec::Absolute(v)
            | crate::heuristics::LengthSpec::RelativeToDiagonal(v)) = m.length;
            if !positive(v) {
                return bad(format!(
                    "h_max length must be positive and finite (got {v})"
                ));
            }
        }
        if let Some(d) = h.degenerate
            && !(d.fraction >= 0.0 && d.fraction.is_finite())
        {
            return bad(format!(
                "degenerate-removal fraction must be finite and >= 0 (got {})",
                d.fraction
            ));
        }
        if let Some(c) = h.culling
            && !positive(c.fraction)
        {
            return bad(format!(
                "culling fraction must be positive and finite (got {})",
                c.fraction
            ));
        }
        Ok(())
    }
}

/// What a backend supports.
#[derive(Clone, Debug, PartialEq)]
pub struct Capabilities {
    /// Backend name (`cpu`, `wgpu`, `vk`).
    pub backend: &'static str,
    /// Device description (CPU model, adapter name).
    pub device: String,
    /// Methods it implements.
    pub methods: Vec<Method>,
    /// Largest photon count per iteration it accepts (`None`: limited by memory only).
    pub max_photons_per_iteration: Option<u32>,
    /// Whether images are bit-identical for the same seed regardless of thread count.
    pub deterministic: bool,
}

/// A diffuse query point found by the camera pass, with what the gather needs.
#[derive(Clone, Copy, Debug, Default, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
#[repr(C)]
pub struct QueryRecord {
    /// Position (metres).
    pub position: [f32; 3],
    /// Pixel index (row-major) the query belongs to.
    pub pixel: u32,
    /// Unit geometric normal oriented towards the viewer, flipped where the viewer lies
    /// below the shading plane of a mesh with vertex normals (the gather's side test,
    /// [`crate::lambertian`]).
    pub normal: [f32; 3],
    /// 1 if this is a valid query point, 0 if the camera path ended elsewhere.
    pub valid: u32,
    /// Camera-path throughput up to this vertex times the Lambertian `albedo/π`
    /// (1/sr): radiance = `weight · E`.
    pub weight: [f32; 3],
    /// Padding.
    pub _pad0: u32,
    /// Radiance already known for the pixel this iteration: emission seen along the
    /// camera path and, with direct lighting on, the direct illumination (W/(m²·sr)).
    pub radiance: [f32; 3],
    /// Padding.
    pub _pad1: u32,
}

/// Wall-clock time of each stage of the last iteration, in seconds.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct StageTimes {
    /// Camera pass.
    pub camera: f64,
    /// Photon pass.
    pub photon: f64,
    /// Acceleration-structure build.
    pub build: f64,
    /// Gather.
    pub gather: f64,
    /// Accumulation.
    pub accumulate: f64,
}

/// Statistics of the last iteration (counts are per iteration).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct IterationStats {
    /// Iterations completed so far (1-based index of the last one).
    pub iteration: u32,
    /// Photons emitted.
    pub photons_emitted: u64,
    /// Ray segments traced by the photon pass.
    pub photon_segments: u64,
    /// Footprints stored, `[caustic, global]`.
    pub footprints: [u64; 2],
    /// Progressive photons stored, `[caustic, global]`.
    pub progressive: [u64; 2],
    /// Footprints replaced as degenerate.
    pub degenerate: u64,
    /// Footprints replaced by bounding-box culling.
    pub culled: u64,
    /// Footprints replaced because `f32` cannot resolve them.
    pub unrepresentable: u64,
    /// Photons whose differential was lost on the way.
    pub differential_lost: u64,
    /// Photons or footprints dropped because a buffer was full.
    pub overflowed: u64,
    /// Valid query points.
    pub query_points: u64,
    /// Footprint and photon containments found by the gather.
    pub gathered: u64,
    /// Progressive radii used, `[caustic, global]` (metres).
    pub radii: [f64; 2],
    /// Stage timings.
    pub times: StageTimes,
}

impl StageTimes {
    /// Adds `other`'s times (non-finite ones are skipped).
    pub fn accumulate(&mut self, other: &StageTimes) {
        for (acc, v) in [
            (&mut self.camera, other.camera),
            (&mut self.photon, other.photon),
            (&mut self.build, other.build),
            (&mut self.gather, other.gather),
            (&mut self.accumulate, other.accumulate),
        ] {
            if v.is_finite() {
                *acc += v;
            }
        }
    }
}

impl IterationStats {
    /// Counts one stored photon: a footprint or a progressive photon of its map, and the
    /// reason a footprint was replaced.
    #[inline]
    pub fn record_stored(&mut self, stored: &StoredPhoton) {
        match stored {
            StoredPhoton::Footprint { packed, .. } => self.footprints[packed.photon_map().index()] += 1,
            StoredPhoton::Progressive { photon, reason } => {
                self.progressive[photon.photon_map().index()] += 1;
                match reason {
                    ProgressiveReason::Degenerate => self.degenerate += 1,
                    ProgressiveReason::Culled => self.culled += 1,
                    ProgressiveReason::Unrepresentable => self.unrepresentable += 1,
                    ProgressiveReason::DifferentialLost => self.differential_lost += 1,
                    ProgressiveReason::ProgressiveMethod => {}
                }
            }
        }
    }

    /// Adds the counts and stage times of `other` (to total several iterations, or to
    /// merge the partial counts of a parallel pass); `iteration` and `radii` become
    /// `other`'s.
    pub fn accumulate(&mut self, other: &IterationStats) {
        self.iteration = other.iteration;
        self.radii = other.radii;
        self.photons_emitted += other.photons_emitted;
        self.photon_segments += other.photon_segments;
        for m in 0..2 {
            self.footprints[m] += other.footprints[m];
            self.progressive[m] += other.progressive[m];
        }
        self.degenerate += other.degenerate;
        self.culled += other.culled;
        self.unrepresentable += other.unrepresentable;
        self.differential_lost += other.differential_lost;
        self.overflowed += other.overflowed;
        self.query_points += other.query_points;
        self.gathered += other.gathered;
        self.times.accumulate(&other.times);
    }
}

/// An image of linear radiance, row-major, top row first.
#[derive(Clone, Debug, PartialEq)]
pub struct Image {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// `width × height` pixels (W/(m²·sr), linear RGB), always finite.
    pub pixels: Vec<Vec3>,
}

/// A rendering backend. Errors are the backend's own `thiserror` enum; nothing panics
/// across the trait.
pub trait Tracer {
    /// The backend's error type.
    type Error: core::error::Error + Send + Sync + 'static;

    /// What this backend supports.
    fn capabilities(&self) -> Capabilities;

    /// Validates and uploads `scene`, resets the accumulation and applies `settings`.
    fn upload_scene(&mut self, scene: &Scene, settings: &RenderSettings) -> Result<(), Self::Error>;

    /// Follows a camera path per pixel through specular chains to the first diffuse
    /// query point.
    fn camera_pass(&mut self) -> Result<(), Self::Error>;

    /// Emits, propagates, classifies and stores this iteration's photons.
    fn photon_pass(&mut self) -> Result<(), Self::Error>;

    /// Builds the acceleration structure over the stored footprints and photons.
    fn build_acceleration_structure(&mut self) -> Result<(), Self::Error>;

    /// Finds every footprint and photon containing each query point and evaluates the
    /// iteration's image.
    fn gather(&mut self) -> Result<(), Self::Error>;

    /// Adds the iteration's image to the running estimate and advances the radii.
    fn accumulate(&mut self) -> Result<(), Self::Error>;

    /// One full iteration: all stages in order.
    fn iterate(&mut self) -> Result<(), Self::Error> {
        self.camera_pass()?;
        self.photon_pass()?;
        self.build_acceleration_structure()?;
        self.gather()?;
        self.accumulate()
    }

    /// Iterations accumulated so far.
    fn iterations(&self) -> u32;

    /// The running estimate (mean over iterations).
    fn read_image(&self) -> Result<Image, Self::Error>;

    /// The query points of the last camera pass, one per pixel.
    fn read_query_points(&self) -> Result<Vec<QueryRecord>, Self::Error>;

    /// The footprints stored by the last photon pass.
    fn read_footprints(&self) -> Result<Vec<PackedFootprint>, Self::Error>;

    /// The progressive photons stored by the last photon pass.
    fn read_photons(&self) -> Result<Vec<PackedPhoton>, Self::Error>;

    /// Statistics of the last iteration.
    fn read_stats(&self) -> Result<IterationStats, Self::Error>;
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn default_settings_are_valid() {
        assert_eq!(RenderSettings::default().validate(), Ok(()));
    }

    #[test]
    fn each_invalid_field_is_named() {
        type Spoil = fn(&mut RenderSettings);
        let cases: [(&str, Spoil); 6] = [
            ("photons_per_iteration", |s| s.photons_per_iteration = 0),
            ("max_depth", |s| s.max_depth = 0),
            ("smoothing.caustic", |s| s.smoothing.caustic = f64::NAN),
            ("radii.global", |s| s.radii.global = RadiusSpec::Absolute(-1.0)),
            ("radii.alpha", |s| s.radii.alpha = 1.5),
            ("radii.caustic", |s| s.radii.caustic = RadiusSpec::RelativeToDiagonal(f64::INFINITY)),
        ];
        for (field, spoil) in cases {
            let mut s = RenderSettings::default();
            spoil(&mut s);
            let e = s.validate().expect_err(field);
            assert!(e.0.contains(field), "{field}: {e}");
        }
    }
}
