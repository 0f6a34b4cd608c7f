//! Storing a photon at a diffuse hit: smoothing, heuristics and packing, with the
//! fallback to a progressive photon. This is the one function every backend's photon pass
//! calls, so all backends make the same decisions.

use crate::base::aabb::Aabb;
use crate::propagate::classify::Smoothing;
use crate::store::footprint::{Footprint, PackedFootprint, PhotonMap};
use crate::store::heuristics::{ProgressiveReason, ResolvedHeuristics};
use crate::store::progressive_photon::{PackedPhoton, ProgressivePhoton};
use glam::DVec3;

/// What a diffuse hit stores.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum StoredPhoton {
    /// An elliptical footprint with its acceleration-structure box.
    Footprint {
        /// The gather record.
        packed: PackedFootprint,
        /// Its AABB (metres).
        aabb: Aabb,
    },
    /// A progressive photon with the map's current radius.
    Progressive {
        /// The gather record.
        photon: PackedPhoton,
        /// Why it is not a footprint.
        reason: ProgressiveReason,
    },
}

impl StoredPhoton {
    /// The map the photon went to.
    pub fn map(&self) -> PhotonMap {
        match self {
            StoredPhoton::Footprint { packed, .. } => packed.photon_map(),
            StoredPhoton::Progressive { photon, .. } => photon.photon_map(),
        }
    }
}

/// Progressive photon at the footprint's centre with the same flux, normal and map.
fn fallback(fp: &Footprint, reason: ProgressiveReason) -> StoredPhoton {
    let photon = ProgressivePhoton::from_footprint(fp).pack();
    StoredPhoton::Progressive { photon, reason }
}

/// Stores footprint `fp` (unsmoothed, as built by [`Footprint::from_hit`]): applies the
/// map's smoothing factor, then the heuristics resolved for the scene (`heuristics`,
/// [`crate::store::heuristics::Heuristics::resolve`]) with the map's progressive `radius`
/// (metres: the dampening reference and the slab limit), then packs it. Anything rejected
/// becomes a progressive photon carrying the same flux, so energy is never lost or created.
///
/// ```
/// use arpa_core::base::aabb::Aabb;
/// use arpa_core::propagate::classify::Smoothing;
/// use arpa_core::store::footprint::{Footprint, PhotonMap};
/// use arpa_core::glam::DVec3;
/// use arpa_core::store::heuristics::Heuristics;
/// use arpa_core::{store::decision::{store_footprint, StoredPhoton}, store::heuristics::ProgressiveReason};
///
/// let scene = Aabb { min: DVec3::splat(-1.0), max: DVec3::splat(1.0) };
/// // Resolved once per scene and iteration, then used for every photon.
/// let heuristics = Heuristics::default().resolve(&scene).at_radii([0.01, 0.02]);
/// let smoothing = Smoothing::default();
/// let fp = |du: DVec3, dv: DVec3| Footprint { center: DVec3::ZERO, normal: DVec3::Z, du, dv, flux: DVec3::ONE, map: PhotonMap::Global };
/// // A round footprint is stored as one.
/// let round = store_footprint(fp(DVec3::X * 0.02, DVec3::Y * 0.02), &smoothing, &heuristics, 0.02);
/// assert!(matches!(round, StoredPhoton::Footprint { .. }));
/// // A sliver (height below 5 % of its base) becomes a progressive photon with the same flux.
/// match store_footprint(fp(DVec3::X * 0.02, DVec3::Y * 0.0005), &smoothing, &heuristics, 0.02) {
///     StoredPhoton::Progressive { photon, reason } => {
///         assert_eq!(reason, ProgressiveReason::Degenerate);
///         assert_eq!(photon.flux, [1.0; 3]);
///     }
///     other => panic!("{other:?}"),
/// }
/// ```
///
/// This is the one function every photon pass stores with (the WGSL twin's `store.wgsl`
/// makes the same decisions). [`ResolvedHeuristics::store`] is its heuristics step (the
/// final footprint, record and box, or the [`ProgressiveReason`]), and
/// [`crate::store::heuristics::Heuristics::apply`] the same chain step by step, the reference
/// the fused step is tested against.
#[inline(always)]
pub fn store_footprint(fp: Footprint, smoothing: &Smoothing, heuristics: &ResolvedHeuristics, radius: f64) -> StoredPhoton {
    let fp = smoothing.apply(fp);
    match heuristics.store(fp, radius) {
        Ok((_, packed, aabb)) => StoredPhoton::Footprint { packed, aabb },
        Err(reason) => fallback(&fp, reason),
    }
}

/// Stores a photon as a progressive photon (differential lost, or the RTPM method).
/// `normal` is oriented towards `incoming` (the photon's direction of travel) internally.
pub fn store_progressive(position: DVec3, normal: DVec3, incoming: DVec3, flux: DVec3, map: PhotonMap, reason: ProgressiveReason) -> StoredPhoton {
    let n = crate::base::frame::unit_or_zero(normal);
    let n = if n == DVec3::ZERO { -crate::base::frame::unit_or(incoming, DVec3::Z) } else { n };
    let n = if incoming.dot(n) > 0.0 { -n } else { n };
    StoredPhoton::Progressive { photon: ProgressivePhoton { position, normal: n, flux, map }.pack(), reason }
}
