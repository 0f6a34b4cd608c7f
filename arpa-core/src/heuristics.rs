//! The four footprint heuristics of ARPA §4.5, each switchable and parameterised.
//!
//! ## Order of application
//! After the smoothing factor `S_c`/`S_g` has scaled the footprint ([`crate::classify`]):
//! 1. **dampened adaptation** (changes the size),
//! 2. **H-max limit** (changes the size; may create degeneracy, so it comes before 3),
//! 3. **degenerate removal** (rejects),
//! 4. the AABB is built ([`Footprint::aabb`]) and **bounding-box culling** tests it (rejects).
//!
//! Rejected footprints become progressive photons with the map's current radius
//! ([`crate::store`]). The paper gives neither the order nor the values; the choices
//! below are this crate's readings of the open points of the design digest (§9), and every
//! ambiguous quantity is a parameter.
//!
//! ## Readings chosen
//! * **Dampened adaptation** — ARPA: "raises the major positional differential ∂P to
//!   ∂P^{1/4}; the minor one is dampened by the same ratio". Taken literally the result
//!   depends on the unit of length, so the length is measured relative to a reference:
//!   `ℓ' = ℓ_ref (ℓ/ℓ_ref)^γ` with `ℓ = |D_major|`, `γ = 1/4`, and both differentials are
//!   scaled by `ℓ'/ℓ` (aspect ratio kept). Default reference: the progressive *diameter*
//!   `2 r_i` of the photon's map ([`DampenReference::ProgressiveDiameter`]), so adaptation
//!   is measured against the size a PPM photon would have. `Absolute(1.0)` gives the literal
//!   reading.
//! * **H-max limit** — "clamps the positional differentials to a set length h_max": each of
//!   `D_u`, `D_v` longer than `h_max` is shortened to `h_max`
//!   ([`HMaxMode::EachDifferential`], default); `PreserveAspect` scales both by
//!   `h_max/|D_major|` instead. Default `h_max` = 5% of the scene's bounding-box diagonal.
//! * **Degenerate removal** — "footprint height below a small threshold fraction f of
//!   their base": base `|D_major|`, parallelogram height `|D_u × D_v|/|D_major|`;
//!   degenerate iff `|D_u × D_v| < f |D_major|²` (equivalently
//!   `(|D_minor|/|D_major|) sin α < f`). Zero or non-finite differentials are degenerate.
//!   Default `f = 0.05`.
//! * **Bounding-box culling** — "bounding box larger than 5% of the total scene area":
//!   default metric: the footprint AABB's longest side exceeds 5% of the scene AABB's
//!   longest side ([`CullMetric::LargestExtent`]). Alternatives: diagonal against diagonal,
//!   or AABB surface area against the scene AABB's surface area.

use crate::aabb::Aabb;
use crate::footprint::{degenerate_denominator, half_thickness, pack_parts, Footprint, PackedFootprint};
use glam::DVec3;

/// A length given in scene units or relative to the scene's bounding-box diagonal.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum LengthSpec {
    /// Metres (scene units).
    Absolute(f64),
    /// Fraction of the scene AABB's diagonal.
    RelativeToDiagonal(f64),
}

impl LengthSpec {
    /// The length in metres for a scene with bounds `scene`.
    #[inline]
    pub fn resolve(self, scene: &Aabb) -> f64 {
        match self {
            LengthSpec::Absolute(l) => l,
            LengthSpec::RelativeToDiagonal(f) => f * scene.diagonal(),
        }
    }
}

/// Reference length of dampened adaptation.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum DampenReference {
    /// A fixed length in metres (`1.0` = the literal `∂P^{1/4}` reading).
    Absolute(f64),
    /// Twice the current progressive radius of the photon's map.
    ProgressiveDiameter,
}

/// Dampened adaptation parameters.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Dampening {
    /// Exponent `γ` (ARPA: 1/4).
    pub exponent: f64,
    /// Reference length `ℓ_ref`.
    pub reference: DampenReference,
}

/// How the H-max limit clamps.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum HMaxMode {
    /// Clamp the length of each differential separately.
    EachDifferential,
    /// Scale both by the same factor so that the major one has length `h_max`.
    PreserveAspect,
}

/// H-max limit parameters.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct HMax {
    /// `h_max`.
    pub length: LengthSpec,
    /// Clamping mode.
    pub mode: HMaxMode,
}

/// Degenerate-removal parameters.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DegenerateRemoval {
    /// Threshold fraction `f`: degenerate iff `|D_u × D_v| < f |D_major|²`.
    pub fraction: f64,
}

/// What bounding-box culling compares.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum CullMetric {
    /// Longest side of the footprint AABB against the scene AABB's longest side.
    LargestExtent,
    /// Diagonal against diagonal.
    Diagonal,
    /// Surface area against the scene AABB's surface area.
    SurfaceArea,
}

/// Bounding-box culling parameters.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BoundingBoxCulling {
    /// Culled iff `metric(footprint box) > fraction · metric(scene box)` (ARPA: 0.05).
    pub fraction: f64,
    /// Which measure of the boxes is compared.
    pub metric: CullMetric,
}

/// The heuristic configuration; `None` switches a heuristic off.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Heuristics {
    /// Dampened adaptation.
    pub dampening: Option<Dampening>,
    /// H-max limit.
    pub h_max: Option<HMax>,
    /// Degenerate removal.
    pub degenerate: Option<DegenerateRemoval>,
    /// Bounding-box culling.
    pub culling: Option<BoundingBoxCulling>,
}

impl Default for Heuristics {
    /// All four on, as in every ARPA experiment, with the readings of the module docs.
    fn default() -> Self {
        Self {
            dampening: Some(Dampening { exponent: 0.25, reference: DampenReference::ProgressiveDiameter }),
            h_max: Some(HMax { length: LengthSpec::RelativeToDiagonal(0.05), mode: HMaxMode::EachDifferential }),
            degenerate: Some(DegenerateRemoval { fraction: 0.05 }),
            culling: Some(BoundingBoxCulling { fraction: 0.05, metric: CullMetric::LargestExtent }),
        }
    }
}

/// Inputs the heuristics need besides the footprint.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct HeuristicContext {
    /// Current progressive radius of the footprint's map (metres).
    pub radius: f64,
    /// Bounds of the scene geometry.
    pub scene_bounds: Aabb,
}

/// Why a footprint was replaced by a progressive photon.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Rejection {
    /// Degenerate removal (or `D_u`, `D_v` parallel/zero/non-finite).
    Degenerate,
    /// Bounding-box culling.
    Culled,
}

impl Heuristics {
    /// All heuristics off.
    pub const NONE: Self = Self { dampening: None, h_max: None, degenerate: None, culling: None };

    /// Dampened adaptation alone (identity when off or not applicable).
    pub fn dampen(&self, fp: Footprint, ctx: &HeuristicContext) -> Footprint {
        let Some(d) = self.dampening else { return fp };
        let (major, _) = fp.major_minor();
        let reference = match d.reference {
            DampenReference::Absolute(l) => l,
            DampenReference::ProgressiveDiameter => 2.0 * ctx.radius,
        };
        if !(major > 0.0) || !major.is_finite() || !(reference > 0.0) || !reference.is_finite() {
            return fp;
        }
        // ℓ'/ℓ = (ℓ/ℓ_ref)^(γ-1), computed in log space to stay finite for extreme ratios.
        let ratio = libm::exp((d.exponent - 1.0) * libm::log(major / reference));
        if ratio.is_finite() && ratio > 0.0 { fp.scaled(ratio) } else { fp }
    }

    /// H-max limit alone.
    pub fn clamp_h_max(&self, mut fp: Footprint, ctx: &HeuristicContext) -> Footprint {
        let Some(h) = self.h_max else { return fp };
        let h_max = h.length.resolve(&ctx.scene_bounds);
        if !(h_max > 0.0) {
            return fp;
        }
        match h.mode {
            HMaxMode::EachDifferential => {
                let clamp = |v: glam::DVec3| {
                    let l = v.length();
                    if l > h_max { v * (h_max / l) } else { v }
                };
                fp.du = clamp(fp.du);
                fp.dv = clamp(fp.dv);
                fp
            }
            HMaxMode::PreserveAspect => {
                let (major, _) = fp.major_minor();
                if major > h_max { fp.scaled(h_max / major) } else { fp }
            }
        }
    }

    /// `true` if degenerate removal (when on) rejects `fp`.
    pub fn is_degenerate(&self, fp: &Footprint) -> bool {
        let Some(d) = self.degenerate else { return false };
        let (major, _) = fp.major_minor();
        let cross = fp.parallelogram_area();
        !(major > 0.0) || !(cross >= d.fraction * major * major)
    }

    /// `true` if bounding-box culling (when on) rejects a footprint with box `bounds`.
    pub fn is_culled(&self, bounds: &Aabb, ctx: &HeuristicContext) -> bool {
        let Some(c) = self.culling else { return false };
        let (mine, scene) = match c.metric {
            CullMetric::LargestExtent => (bounds.largest_extent(), ctx.scene_bounds.largest_extent()),
            CullMetric::Diagonal => (bounds.diagonal(), ctx.scene_bounds.diagonal()),
            CullMetric::SurfaceArea => (bounds.surface_area(), ctx.scene_bounds.surface_area()),
        };
        !(mine <= c.fraction * scene)
    }

    /// Applies the heuristics in the documented order. Returns the final footprint and
    /// its AABB, or the reason it must become a progressive photon. A footprint whose
    /// `M_p⁻¹` does not exist is rejected as degenerate even with degenerate removal off.
    pub fn apply(&self, fp: Footprint, ctx: &HeuristicContext) -> Result<(Footprint, Aabb), Rejection> {
        let fp = self.dampen(fp, ctx);
        let fp = self.clamp_h_max(fp, ctx);
        if self.is_degenerate(&fp) || fp.filter_transform().is_err() {
            return Err(Rejection::Degenerate);
        }
        let bounds = fp.aabb(ctx.radius);
        if self.is_culled(&bounds, ctx) {
            return Err(Rejection::Culled);
        }
        Ok((fp, bounds))
    }
}

/// [`Heuristics`] with every scene-dependent quantity resolved once per scene (h_max
/// in metres, culling thresholds), and a fused [`ResolvedHeuristics::store`] that runs the
/// whole chain with each length, cross product and square root computed once. This is
/// the per-photon hot path; it makes exactly the decisions of [`Heuristics::apply`]
/// followed by [`Footprint::pack`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ResolvedHeuristics {
    dampening: Option<Dampening>,
    h_max: Option<(f64, HMaxMode)>,
    degenerate: Option<f64>,
    cull: Option<(CullMetric, f64)>,
}

/// Why [`ResolvedHeuristics::store`] did not produce a footprint record.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum StoreRejection {
    /// Rejected by a heuristic.
    Heuristic(Rejection),
    /// The ellipse cannot be resolved in `f32` storage.
    Unrepresentable,
}

/// `ℓ'/ℓ = (ℓ/ℓ_ref)^(γ−1)` from `major2 = ℓ²` and `reference = ℓ_ref`.
#[inline]
fn dampen_ratio(major2: f64, reference: f64, exponent: f64) -> f64 {
    if exponent == 0.25 {
        // γ = 1/4 (ARPA): (ℓ_ref²/ℓ²)^(3/8) with one division and three square roots.
        let a = libm::sqrt(reference * reference / major2); // (ℓ_ref/ℓ)
        let b = libm::sqrt(a); // (ℓ_ref/ℓ)^(1/2)
        b * libm::sqrt(b) // (ℓ_ref/ℓ)^(3/4)
    } else {
        libm::exp(0.5 * (exponent - 1.0) * libm::log(major2 / (reference * reference)))
    }
}

impl Heuristics {
    /// Resolves the scene-dependent quantities for a scene with bounds `scene_bounds`.
    pub fn resolve(&self, scene_bounds: &Aabb) -> ResolvedHeuristics {
        ResolvedHeuristics {
            dampening: self.dampening,
            h_max: self.h_max.map(|h| (h.length.resolve(scene_bounds), h.mode)),
            degenerate: self.degenerate.map(|d| d.fraction),
            cull: self.culling.map(|c| {
                let scene = match c.metric {
                    CullMetric::LargestExtent => scene_bounds.largest_extent(),
                    CullMetric::Diagonal => scene_bounds.diagonal(),
                    CullMetric::SurfaceArea => scene_bounds.surface_area(),
                };
                (c.metric, c.fraction * scene)
            }),
        }
    }
}

impl ResolvedHeuristics {
    /// Runs dampening, H-max, degenerate removal, the AABB and culling (the documented
    /// order) and packs the footprint for progressive radius `radius` (metres). Returns
    /// the final footprint, its record and its box, or why it must become a progressive
    /// photon.
    #[inline]
    pub fn store(&self, mut fp: Footprint, radius: f64) -> Result<(Footprint, PackedFootprint, Aabb), StoreRejection> {
        let mut la2 = fp.du.length_squared();
        let mut lb2 = fp.dv.length_squared();
        if let Some(d) = self.dampening {
            let major2 = la2.max(lb2);
            let reference = match d.reference {
                DampenReference::Absolute(l) => l,
                DampenReference::ProgressiveDiameter => 2.0 * radius,
            };
            if major2 > 0.0 && major2.is_finite() && reference > 0.0 && reference.is_finite() {
                let ratio = dampen_ratio(major2, reference, d.exponent);
                if ratio.is_finite() && ratio > 0.0 {
                    fp.du *= ratio;
                    fp.dv *= ratio;
                    let r2 = ratio * ratio;
                    la2 *= r2;
                    lb2 *= r2;
                }
            }
        }
        if let Some((h, mode)) = self.h_max.filter(|(h, _)| *h > 0.0) {
            let h2 = h * h;
            match mode {
                HMaxMode::EachDifferential => {
                    if la2 > h2 {
                        fp.du *= h / libm::sqrt(la2);
                        la2 = fp.du.length_squared();
                    }
                    if lb2 > h2 {
                        fp.dv *= h / libm::sqrt(lb2);
                        lb2 = fp.dv.length_squared();
                    }
                }
                HMaxMode::PreserveAspect => {
                    let major2 = la2.max(lb2);
                    if major2 > h2 {
                        let s = h / libm::sqrt(major2);
                        fp.du *= s;
                        fp.dv *= s;
                        la2 = fp.du.length_squared();
                        lb2 = fp.dv.length_squared();
                    }
                }
            }
        }
        let cross = fp.du.cross(fp.dv);
        let major2 = la2.max(lb2);
        if let Some(f) = self.degenerate {
            // |D_u × D_v| < f |D_major|², in squares.
            if !(major2 > 0.0) || !(cross.length_squared() >= f * f * major2 * major2) {
                return Err(StoreRejection::Heuristic(Rejection::Degenerate));
            }
        }
        let den = cross.dot(fp.normal);
        if degenerate_denominator(den, la2, lb2) {
            return Err(StoreRejection::Heuristic(Rejection::Degenerate));
        }
        let h = half_thickness(fp.center, libm::sqrt(major2), libm::sqrt(la2.min(lb2)), radius);
        // The box of the elliptic slab (see `Footprint::aabb`).
        let e2 = 0.25 * (fp.du * fp.du + fp.dv * fp.dv);
        let e = DVec3::new(libm::sqrt(e2.x), libm::sqrt(e2.y), libm::sqrt(e2.z)) + (fp.normal * h).abs();
        let bounds = Aabb::from_centre_half_extent(fp.center, e);
        if let Some((metric, threshold)) = self.cull {
            let mine = match metric {
                CullMetric::LargestExtent => 2.0 * e.max_element(),
                CullMetric::Diagonal => 2.0 * e.length(),
                CullMetric::SurfaceArea => 8.0 * (e.x * e.y + e.y * e.z + e.z * e.x),
            };
            if !(mine <= threshold) {
                return Err(StoreRejection::Heuristic(Rejection::Culled));
            }
        }
        match pack_parts(&fp, la2, lb2, cross, den, h) {
            Ok(packed) => Ok((fp, packed, bounds)),
            Err(crate::footprint::FootprintError::Degenerate) => Err(StoreRejection::Heuristic(Rejection::Degenerate)),
            Err(_) => Err(StoreRejection::Unrepresentable),
        }
    }
}

/// The 48-byte GPU record of a [`ResolvedHeuristics`]: the WGSL twin's `ArpaHeuristics`
/// (`arpa-core/shaders/heuristics.wgsl`, [`crate::shaders::HEURISTICS`]), whose
/// `arpa_store` makes the decisions of [`ResolvedHeuristics::store`] in `f32`. Lengths in
/// metres (the surface-area threshold in m²).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
pub struct PackedHeuristics {
    /// Bit 0 dampening, bit 1 H-max, bit 2 degenerate removal, bit 3 culling (set = on).
    pub enabled: u32,
    /// Dampening reference: 0 absolute (`dampen_reference`), 1 progressive diameter `2 r_i`.
    pub dampen_reference_kind: u32,
    /// H-max mode: 0 each differential, 1 preserve aspect.
    pub h_max_mode: u32,
    /// Culling metric: 0 largest extent, 1 diagonal, 2 surface area.
    pub cull_metric: u32,
    /// Dampening exponent `γ`.
    pub dampen_exponent: f32,
    /// Absolute dampening reference length (m), when `dampen_reference_kind` is 0.
    pub dampen_reference: f32,
    /// `h_max` (m).
    pub h_max: f32,
    /// Degenerate-removal fraction `f`.
    pub degenerate_fraction: f32,
    /// Culling threshold: fraction times the scene box's metric (m, or m² for surface area).
    pub cull_threshold: f32,
    /// Padding (0).
    pub pad: [f32; 3],
}

impl ResolvedHeuristics {
    /// The GPU record (see [`PackedHeuristics`]); values rounded once to `f32`.
    pub fn pack(&self) -> PackedHeuristics {
        let mut p = PackedHeuristics::default();
        if let Some(d) = self.dampening {
            p.enabled |= 1;
            p.dampen_exponent = d.exponent as f32;
            match d.reference {
                DampenReference::Absolute(l) => p.dampen_reference = l as f32,
                DampenReference::ProgressiveDiameter => p.dampen_reference_kind = 1,
            }
        }
        if let Some((h, mode)) = self.h_max {
            p.enabled |= 2;
            p.h_max = h as f32;
            p.h_max_mode = match mode {
                HMaxMode::EachDifferential => 0,
                HMaxMode::PreserveAspect => 1,
            };
        }
        if let Some(f) = self.degenerate {
            p.enabled |= 4;
            p.degenerate_fraction = f as f32;
        }
        if let Some((metric, threshold)) = self.cull {
            p.enabled |= 8;
            p.cull_metric = match metric {
                CullMetric::LargestExtent => 0,
                CullMetric::Diagonal => 1,
                CullMetric::SurfaceArea => 2,
            };
            p.cull_threshold = threshold as f32;
        }
        p
    }
}

const _: () = assert!(core::mem::size_of::<PackedHeuristics>() == 48);
