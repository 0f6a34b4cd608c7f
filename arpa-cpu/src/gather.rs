//! The gather: for each query point, every footprint and progressive photon containing it,
//! summed with the core's estimator into the iteration's image.

use core::sync::atomic::{AtomicU64, Ordering};

use arpa_core::gather::scales::{ScaleSums, MOMENT_PLANES, SCALES};
use arpa_core::gather::estimate::{IrradianceEstimate, QueryPoint};
use arpa_core::glam::{DVec3, Vec3};
use arpa_core::gather::kernel::Kernel;
use arpa_core::base::prefetch::prefetch;
use arpa_core::render::tracer::QueryRecord;
use rayon::prelude::*;

use crate::accel::Accel;
use crate::photon_store::PhotonStore;

/// The records the gather reads besides the query points: the photon pass's store, the
/// box BVH built over it, and the settings of the estimate.
pub(crate) struct GatherInput<'a> {
    pub accel: &'a Accel,
    pub store: &'a PhotonStore,
    pub kernel: Kernel,
    /// Progressive radii `[caustic, global]` of the photons in `store`.
    pub radii: [f32; 2],
    /// Scales of the bandwidth ladder to evaluate: 1 (global bandwidth) or
    /// [`SCALES`] (per-pixel; [`arpa_core::gather::scales`]).
    pub scales: usize,
    /// Counts the point queries that failed (answered as "nothing found").
    pub errors: &'a AtomicU64,
}

/// The gather's counts over every valid query point, per map `[caustic, global]`.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub(crate) struct GatherCounts {
    /// Records whose box the BVH reported at the point (each then tested exactly).
    pub candidates: [u64; 2],
    /// Records that contributed.
    pub contributions: [u64; 2],
    /// Query points with at least one contribution.
    pub covered: [u64; 2],
}

/// Writes the radiance of each query record's pixel to `image` (one task per record, in
/// parallel) and returns the candidates and contributions found. With one scale `image`
/// holds one radiance per record; with [`SCALES`] it holds the planes of
/// [`arpa_core::gather::scales`], plane-major: the radiance at every scale, then the moment
/// planes of [`arpa_core::gather::scales::moments`].
///
/// `planes` is the per-pixel scratch of a per-pixel gather (its capacity is kept from one
/// iteration to the next, so the planes are not allocated again each time).
pub(crate) fn gather(queries: &[QueryRecord], input: &GatherInput<'_>, image: &mut Vec<Vec3>, planes: &mut Vec<[Vec3; SCALES + MOMENT_PLANES]>) -> GatherCounts {
    let counts: [AtomicU64; 6] = Default::default();
    let count = |e: &IrradianceEstimate| {
        for m in 0..2 {
            if e.candidates[m] > 0 {
                counts[m].fetch_add(e.candidates[m] as u64, Ordering::Relaxed);
            }
            if e.contributions[m] > 0 {
                counts[2 + m].fetch_add(e.contributions[m] as u64, Ordering::Relaxed);
                counts[4 + m].fetch_add(1, Ordering::Relaxed);
            }
        }
    };
    if input.scales <= 1 {
        queries
            .par_iter()
            .map_init(Vec::new, |scratch, rec| {
                let (l, e) = gather_one(rec, input, scratch, false);
                count(&e);
                l[0]
            })
            .collect_into_vec(image);
    } else {
        queries
            .par_iter()
            .map_init(Vec::new, |scratch, rec| {
                let (l, e) = gather_one(rec, input, scratch, true);
                count(&e);
                let m = arpa_core::gather::scales::moments(&l);
                core::array::from_fn(|p| if p < SCALES { l[p] } else { m[p - SCALES] })
            })
            .collect_into_vec(planes);
        let n = queries.len();
        image.clear();
        image.resize(planes.len() * (SCALES + MOMENT_PLANES), Vec3::ZERO);
        for (i, px) in planes.iter().enumerate() {
            for (p, v) in px.iter().enumerate() {
                image[p * n + i] = *v;
            }
        }
    }
    let [c0, c1, n0, n1, v0, v1] = counts.map(AtomicU64::into_inner);
    GatherCounts { candidates: [c0, c1], contributions: [n0, n1], covered: [v0, v1] }
}

/// Replaces non-finite components by 0.
fn finite_or_zero(v: DVec3) -> DVec3 {
    DVec3::select(v.is_finite_mask(), v, DVec3::ZERO)
}

/// Candidate key of the gather: footprints (`index`) before progressive photons
/// (`2³² + index`), the order [`arpa_core::gather::estimate::gather_brute_force`] sums in.
const PHOTON_KEY: u64 = 1 << 32;

/// The gather of one query record: its pixel's radiance (at every scale when `scaled`,
/// else at the stored scale in element 0), its estimate (with the candidates and
/// contributions per map).
///
/// Two phases. The Embree point query reports every box containing the query point (and
/// possibly a few more); its callback only notes the candidate's key in `keys` and
/// prefetches the record, so the records' cache misses overlap instead of stalling the
/// traversal one by one. Then the candidates are sorted and deduplicated by key and each
/// is added with the core's [`IrradianceEstimate::add_footprint`] /
/// [`IrradianceEstimate::add_photon`] (exact test and `f64` sum) in `(kind, index)` order,
/// so the sum is bit-identical to [`arpa_core::gather::estimate::gather_brute_force`] over the
/// same records, whatever order the BVH reported them in.
fn gather_one(rec: &QueryRecord, input: &GatherInput<'_>, keys: &mut Vec<u64>, scaled: bool) -> ([Vec3; SCALES], IrradianceEstimate) {
    let known = Vec3::from_array(rec.radiance).as_dvec3();
    if rec.valid == 0 {
        return ([finite_or_zero(known).as_vec3(); SCALES], IrradianceEstimate::default());
    }
    let mut estimate = IrradianceEstimate::default();
    let mut sums = ScaleSums::default();
    if let Accel::Boxes {
        scene,
        footprints,
        photons,
    } = input.accel
    {
        let store = input.store;
        let query = QueryPoint {
            position: Vec3::from_array(rec.position),
            normal: Vec3::from_array(rec.normal),
        };
        keys.clear();
        let found = scene.point_query(rec.position, 0.0, |c| {
            let i = c.prim_id as usize;
            if Some(c.geom_id) == *footprints {
                if let Some(fp) = store.footprints.get(i) {
                    prefetch(fp);
                    keys.push(i as u64);
                }
            } else if Some(c.geom_id) == *photons
                && let Some(ph) = store.photons.get(i)
            {
                prefetch(ph);
                keys.push(PHOTON_KEY | i as u64);
            }
        });
        if found.is_err() {
            input.errors.fetch_add(1, Ordering::Relaxed);
        }
        keys.sort_unstable();
        keys.dedup();
        for &key in keys.iter() {
            let i = (key & (PHOTON_KEY - 1)) as usize;
            match (key < PHOTON_KEY, scaled) {
                (true, false) => {
                    estimate.add_footprint(&store.footprints[i], &query, input.kernel);
                }
                (false, false) => {
                    estimate.add_photon(&store.photons[i], &query, input.radii);
                }
                (true, true) => sums.add(&estimate.add_footprint_scales(&store.footprints[i], &query, input.kernel)),
                (false, true) => sums.add(&estimate.add_photon_scales(&store.photons[i], &query, input.radii)),
            }
        }
    }
    let weight = Vec3::from_array(rec.weight).as_dvec3();
    let radiance = known + weight * estimate.irradiance();
    let mut out = [finite_or_zero(radiance).as_vec3(); SCALES];
    if scaled {
        // Scale 0 is the stored ellipse: the estimate's own sum (per map, then added), so
        // a per-pixel render's plane 0 is the global render's image bit for bit.
        for (o, e) in out.iter_mut().zip(&sums.per_scale).skip(1) {
            *o = finite_or_zero(known + weight * *e).as_vec3();
        }
    }
    (out, estimate)
}
