//! The photon buffers of one iteration: footprints with their acceleration-structure
//! boxes, progressive photons, and the counts of the photon pass.

use arpa_core::aabb::Aabb as CoreAabb;
use arpa_core::footprint::PackedFootprint;
use arpa_core::glam::{DMat3, DVec3, Vec3};
use arpa_core::progressive_photon::PackedPhoton;
use arpa_core::store::{ProgressiveReason, StoredPhoton};

use crate::scene::Aabb;

/// Relative padding of the boxes handed to Embree, on top of `f32` outward rounding.
///
/// The gather's exact tests run in `f32` ([`PackedFootprint::irradiance`],
/// [`PackedPhoton::irradiance`]) and may accept a point a few ulps outside the exact
/// (`f64`) shape; the padding keeps every such point inside the box, so the acceleration
/// structure finds exactly what a brute-force gather over the same records finds.
const RELATIVE_PAD: f64 = 1e-4;
/// Absolute padding in units of the box centre's magnitude (`f32` ulps of the position).
const POSITION_PAD: f64 = 8.0 * f32::EPSILON as f64;

/// `box` grown by the padding above and rounded outwards to `f32`.
pub(crate) fn padded_box(b: &CoreAabb) -> Aabb {
    let centre = b.centre();
    let half = 0.5 * (b.max - b.min);
    let pad = half * RELATIVE_PAD
        + DVec3::splat(POSITION_PAD * (centre.abs().max_element() + half.max_element()));
    let grown = CoreAabb {
        min: b.min - pad,
        max: b.max + pad,
    };
    let (lower, upper) = grown.to_f32_conservative();
    Aabb { lower, upper }
}

/// The box of everything [`PackedFootprint::contains`] accepts, padded.
///
/// The packed rows map `Δ = q − x_p` to `y = M Δ`; the footprint is the elliptic cylinder
/// `y.x² + y.y² ≤ 1, |y.z| ≤ 1`, i.e. `Δ = c_u y.x + c_v y.y + c_n y.z` with the columns
/// `c_u, c_v, c_n` of `M⁻¹` (the conjugate semi-diameters `D_u/2`, `D_v/2` and `h n`). Its
/// box has half-extents `e_k = √(c_u,k² + c_v,k²) + |c_n,k|`. Computed from the `f32` rows
/// themselves, so it bounds the region the gather's test really accepts. `None` if the rows
/// are singular (a valid packed footprint never is).
///
/// (The core's [`arpa_core::footprint::Footprint::aabb`] bounds the *ellipsoid*
/// `|y| ≤ 1`, which the cylinder overhangs near the ellipse's rim off its plane, so it is
/// not used here.)
pub(crate) fn footprint_box(fp: &PackedFootprint) -> Option<Aabb> {
    let row = |r: [f32; 3]| Vec3::from_array(r).as_dvec3();
    let m = DMat3::from_cols(row(fp.row_u), row(fp.row_v), row(fp.row_n)).transpose();
    let det = m.determinant();
    if !(det != 0.0 && det.is_finite()) {
        return None;
    }
    let inv = m.inverse();
    if !inv.is_finite() {
        return None;
    }
    let (cu, cv, cn) = (inv.x_axis, inv.y_axis, inv.z_axis);
    let half = (cu * cu + cv * cv).map(f64::sqrt) + cn.abs();
    let centre = row(fp.center);
    let b = CoreAabb::from_centre_half_extent(centre, half);
    (b.min.is_finite() && b.max.is_finite()).then(|| padded_box(&b))
}

/// The box of a progressive photon of radius `radius`: `position ± radius`, padded.
pub(crate) fn photon_box(photon: &PackedPhoton, radius: f32) -> Aabb {
    let centre = Vec3::from_array(photon.position).as_dvec3();
    padded_box(&CoreAabb::from_centre_half_extent(
        centre,
        DVec3::splat(radius as f64),
    ))
}

/// Counts of a photon pass.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub(crate) struct StoreCounts {
    pub footprints: [u64; 2],
    pub progressive: [u64; 2],
    pub degenerate: u64,
    pub culled: u64,
    pub unrepresentable: u64,
    pub differential_lost: u64,
}

/// Footprints (with boxes) and progressive photons, in photon-index order.
#[derive(Clone, Debug, Default)]
pub(crate) struct PhotonStore {
    pub footprints: Vec<PackedFootprint>,
    pub footprint_boxes: Vec<Aabb>,
    pub photons: Vec<PackedPhoton>,
    pub counts: StoreCounts,
}

impl PhotonStore {
    /// Empties the buffers (keeping their capacity) and zeroes the counts.
    pub fn clear(&mut self) {
        self.footprints.clear();
        self.footprint_boxes.clear();
        self.photons.clear();
        self.counts = StoreCounts::default();
    }

    /// Appends the photons of `parts` in order (the chunks of a photon pass).
    pub fn extend_from_parts(&mut self, parts: &[PhotonStore]) {
        self.footprints
            .reserve(parts.iter().map(|p| p.footprints.len()).sum());
        self.footprint_boxes
            .reserve(parts.iter().map(|p| p.footprint_boxes.len()).sum());
        self.photons
            .reserve(parts.iter().map(|p| p.photons.len()).sum());
        for p in parts {
            self.footprints.extend_from_slice(&p.footprints);
            self.footprint_boxes.extend_from_slice(&p.footprint_boxes);
            self.photons.extend_from_slice(&p.photons);
            let (a, b) = (&mut self.counts, &p.counts);
            for m in 0..2 {
                a.footprints[m] += b.footprints[m];
                a.progressive[m] += b.progressive[m];
            }
            a.degenerate += b.degenerate;
            a.culled += b.culled;
            a.unrepresentable += b.unrepresentable;
            a.differential_lost += b.differential_lost;
        }
    }

    /// Appends one stored photon.
    pub fn push(&mut self, stored: StoredPhoton) {
        let map = stored.map().index();
        match stored {
            StoredPhoton::Footprint { packed, aabb } => {
                self.footprints.push(packed);
                self.footprint_boxes
                    .push(footprint_box(&packed).unwrap_or_else(|| padded_box(&aabb)));
                self.counts.footprints[map] += 1;
            }
            StoredPhoton::Progressive { photon, reason } => {
                self.photons.push(photon);
                self.counts.progressive[map] += 1;
                match reason {
                    ProgressiveReason::Degenerate => self.counts.degenerate += 1,
                    ProgressiveReason::Culled => self.counts.culled += 1,
                    ProgressiveReason::Unrepresentable => self.counts.unrepresentable += 1,
                    ProgressiveReason::DifferentialLost => self.counts.differential_lost += 1,
                    ProgressiveReason::ProgressiveMethod => {}
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn padded_box_contains_the_exact_box_and_is_tight() {
        let b = CoreAabb {
            min: DVec3::new(0.1, -2.0, 1e-9),
            max: DVec3::new(0.3, -1.9, 2e-9),
        };
        let p = padded_box(&b);
        for k in 0..3 {
            assert!((p.lower[k] as f64) <= b.min[k] && (p.upper[k] as f64) >= b.max[k]);
            let size = b.max[k] - b.min[k];
            assert!(
                (p.upper[k] - p.lower[k]) as f64 <= size * 1.001 + 1e-5,
                "{p:?}"
            );
        }
    }

    /// Deterministic test RNG (SplitMix64) in [-1, 1).
    struct Rng(u64);
    impl Rng {
        fn f(&mut self) -> f64 {
            self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
            let mut z = self.0;
            z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
            z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
            ((z ^ (z >> 31)) >> 11) as f64 / (1u64 << 52) as f64 - 1.0
        }
        fn v(&mut self) -> DVec3 {
            DVec3::new(self.f(), self.f(), self.f())
        }
    }

    /// Every point the packed test accepts lies in the box, including the rim of the
    /// elliptic cylinder off the footprint's plane, where the ellipsoid's box (the core's
    /// `Footprint::aabb`) falls short; and the box is tight there.
    #[test]
    fn footprint_box_covers_the_packed_test() {
        use arpa_core::footprint::{Footprint, PhotonMap};
        let mut rng = Rng(3);
        let mut outside_core_box = 0;
        for _ in 0..200 {
            let n = rng.v().normalize_or(DVec3::Z);
            let project = |v: DVec3| v - n * n.dot(v);
            let fp = Footprint {
                center: rng.v() * 10.0,
                normal: n,
                du: project(rng.v()) * 0.1,
                dv: project(rng.v()) * 0.1,
                flux: DVec3::ONE,
                map: PhotonMap::Global,
            };
            let radius = 0.02;
            let Ok(packed) = fp.pack(radius) else {
                continue;
            };
            let b = footprint_box(&packed).expect("regular rows");
            let (a, bb, h) = (0.5 * fp.du, 0.5 * fp.dv, n * fp.half_thickness(radius));
            let mut reach = DVec3::ZERO;
            for k in 0..720 {
                let t = k as f64 * core::f64::consts::TAU / 720.0;
                for z in [-1.0, 1.0] {
                    // Just inside the rim, on the slab's faces.
                    let d = (a * t.cos() + bb * t.sin()) * 0.999_99 + h * z * 0.999_99;
                    let q = (fp.center + d).as_vec3();
                    if packed.contains(q) {
                        assert!(b.contains(q.to_array()), "{q:?} outside {b:?}");
                        outside_core_box += usize::from(!fp.aabb(radius).contains(q.as_dvec3()));
                    }
                    reach = reach.max(d.abs());
                }
            }
            for k in 0..3 {
                let half = 0.5 * (b.upper[k] - b.lower[k]) as f64;
                assert!(
                    half <= reach[k] * 1.001 + 1e-4,
                    "box not tight: {half} vs {}",
                    reach[k]
                );
            }
        }
        // Points the core's ellipsoid box misses (0 once the core bounds the cylinder).
        eprintln!("{outside_core_box} rim points outside Footprint::aabb");
    }

    #[test]
    fn photon_box_covers_the_f32_sphere_test() {
        let ph = PackedPhoton {
            position: [1000.5, -3.25, 0.125],
            ..Default::default()
        };
        let r = 0.01f32;
        let b = photon_box(&ph, r);
        // Points along the axes just inside the f32 sphere test are inside the box.
        for k in 0..3 {
            for s in [-1.0f32, 1.0] {
                let mut q = Vec3::from_array(ph.position);
                q[k] += s * r;
                // Step back ulp by ulp until the f32 test accepts it.
                while !ph.contains(q, r) {
                    q[k] = if s > 0.0 {
                        q[k].next_down()
                    } else {
                        q[k].next_up()
                    };
                }
                assert!(b.contains(q.to_array()), "{q:?} {b:?}");
            }
        }
    }
}
