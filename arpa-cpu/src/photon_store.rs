//! The photon buffers of one iteration: footprints with their acceleration-structure
//! boxes, progressive photons, and the counts of the photon pass.

use arpa_core::base::aabb::Aabb;
use arpa_core::store::footprint::PackedFootprint;
use arpa_core::glam::{DVec3, Vec3};
use arpa_core::store::progressive_photon::PackedPhoton;
use arpa_core::store::decision::StoredPhoton;
use arpa_core::render::tracer::IterationStats;

use crate::embree::EmbreeBox;

/// `box` grown by the core's padding ([`Aabb::padded_f32`]), as an Embree box.
#[inline]
pub(crate) fn padded_box(b: &Aabb) -> EmbreeBox {
    let (lower, upper) = b.padded_f32();
    EmbreeBox { lower, upper }
}

/// The box of a progressive photon of radius `radius`: `position ± radius`, padded.
pub(crate) fn photon_box(photon: &PackedPhoton, radius: f32) -> EmbreeBox {
    let centre = Vec3::from_array(photon.position).as_dvec3();
    padded_box(&Aabb::from_centre_half_extent(
        centre,
        DVec3::splat(radius as f64),
    ))
}

/// Footprints (with boxes) and progressive photons, in photon-index order.
///
/// `footprint_boxes[i]` bounds `footprints[i]` from the photon pass until the acceleration
/// structure is built; the build moves the boxes into Embree's scene (and frees them once
/// the BVH exists), so afterwards `footprint_boxes` is empty.
#[derive(Clone, Debug, Default)]
pub(crate) struct PhotonStore {
    pub footprints: Vec<PackedFootprint>,
    pub footprint_boxes: Vec<EmbreeBox>,
    pub photons: Vec<PackedPhoton>,
    /// Store counts of the pass (footprints and progressive photons per map, reasons).
    pub counts: IterationStats,
}

impl PhotonStore {
    /// Empties the buffers (keeping their capacity) and zeroes the counts.
    pub fn clear(&mut self) {
        self.clear_records();
        self.counts = IterationStats::default();
    }

    /// Empties the record buffers (keeping their capacity), not the counts.
    fn clear_records(&mut self) {
        self.footprints.clear();
        self.footprint_boxes.clear();
        self.photons.clear();
    }

    /// Makes room for at least `footprints` footprints (and boxes) and `photons` progressive
    /// photons in total.
    pub fn reserve_total(&mut self, footprints: usize, photons: usize) {
        let more = |len: usize, want: usize| want.saturating_sub(len);
        self.footprints
            .reserve(more(self.footprints.len(), footprints));
        self.footprint_boxes
            .reserve(more(self.footprint_boxes.len(), footprints));
        self.photons.reserve(more(self.photons.len(), photons));
    }

    /// Appends the photons of `part` in order (one chunk of a photon pass).
    pub fn append(&mut self, part: &PhotonStore) {
        self.extend_records(part);
        self.counts.accumulate(&part.counts);
    }

    /// Appends the records (and boxes) of `part` in order, not its counts.
    fn extend_records(&mut self, part: &PhotonStore) {
        self.footprints.extend_from_slice(&part.footprints);
        self.footprint_boxes
            .extend_from_slice(&part.footprint_boxes);
        self.photons.extend_from_slice(&part.photons);
    }

    /// Moves the records of `part` (not its counts) to the end of these buffers, in order,
    /// and empties `part` (keeping its capacity).
    pub fn take_records(&mut self, part: &mut PhotonStore) {
        self.extend_records(part);
        part.clear_records();
    }

    /// Appends one stored photon. A footprint's box is the core's box of its elliptic slab
    /// ([`StoredPhoton::Footprint::aabb`]), padded and rounded outwards to `f32`
    /// ([`padded_box`]).
    #[inline]
    pub fn push(&mut self, stored: StoredPhoton) {
        self.counts.record_stored(&stored);
        self.push_record(stored);
    }

    /// [`PhotonStore::push`] without counting: appends the record (and box) only.
    #[inline]
    pub fn push_record(&mut self, stored: StoredPhoton) {
        match stored {
            StoredPhoton::Footprint { packed, aabb } => {
                self.footprints.push(packed);
                self.footprint_boxes.push(padded_box(&aabb));
            }
            StoredPhoton::Progressive { photon, .. } => self.photons.push(photon),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

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

    /// The box a stored footprint gets (the core's `aabb` from the store path, padded)
    /// holds every point the packed `f32` test accepts, including the rim of the elliptic
    /// slab off the footprint's plane, for round and very elongated ellipses, near the
    /// origin and far from it; and it is tight there.
    #[test]
    fn core_box_covers_the_packed_test() {
        use arpa_core::propagate::classify::Smoothing;
        use arpa_core::store::footprint::{Footprint, PhotonMap};
        use arpa_core::store::heuristics::Heuristics;
        use arpa_core::store::decision::store_footprint;
        let heuristics = Heuristics::NONE.resolve(&Aabb {
            min: DVec3::splat(-1e3),
            max: DVec3::splat(1e3),
        });
        let mut rng = Rng(3);
        let mut stored = 0;
        for case in 0..600 {
            let n = rng.v().normalize_or(DVec3::Z);
            let project = |v: DVec3| v - n * n.dot(v);
            // Elongation up to 1:1000 in a third of the cases.
            let squash = if case % 3 == 2 {
                10f64.powf(-3.0 * (0.5 + 0.5 * rng.f()))
            } else {
                1.0
            };
            let offset = if case % 2 == 0 { 10.0 } else { 300.0 };
            let fp = Footprint {
                center: rng.v() * offset,
                normal: n,
                du: project(rng.v()) * 0.1,
                dv: project(rng.v()) * 0.1 * squash,
                flux: DVec3::ONE,
                map: PhotonMap::Global,
            };
            let radius = 0.02;
            let StoredPhoton::Footprint { packed, aabb } =
                store_footprint(fp, &Smoothing::default(), &heuristics, radius)
            else {
                continue;
            };
            stored += 1;
            let b = padded_box(&aabb);
            let (a, bb) = (0.5 * fp.du, 0.5 * fp.dv);
            let h = n * fp.half_thickness(radius);
            let mut reach = DVec3::ZERO;
            for k in 0..720 {
                let t = k as f64 * core::f64::consts::TAU / 720.0;
                for z in [-1.0, 1.0] {
                    // On the slab's faces at the rim, just outside it and just inside it:
                    // whatever the f32 test accepts must be in the box.
                    for s in [0.999_99, 1.000_01, 1.0] {
                        let d = (a * t.cos() + bb * t.sin()) * s + h * z * s;
                        let q = (fp.center + d).as_vec3();
                        if packed.contains(q) {
                            assert!(b.contains(q.to_array()), "case {case}: {q:?} outside {b:?}");
                        }
                    }
                    reach = reach.max((a * t.cos() + bb * t.sin() + h * z).abs());
                }
            }
            for k in 0..3 {
                let half = 0.5 * (b.upper[k] - b.lower[k]) as f64;
                let slack = 8.0 * f32::EPSILON as f64 * (fp.center.abs().max_element() + 0.2);
                assert!(
                    half <= reach[k] * 1.001 + 2.0 * slack + 1e-9,
                    "case {case}: box not tight: {half} vs {}",
                    reach[k]
                );
            }
        }
        assert!(stored > 300, "{stored} footprints stored");
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
