//! Footprint stores of several photons at once, one photon per SIMD lane.
//!
//! [`store_footprints_lanes`] runs the common path of
//! [`store_footprint_resolved`](crate::store::store_footprint_resolved) (smoothing,
//! γ = 1/4 dampening, the H-max test, degenerate removal, the box, culling and packing)
//! for `N` footprints side by side, written as straight-line arithmetic over `[f64; N]`
//! arrays so that the compiler can put each operation on vector lanes. Every lane computes
//! exactly the operations of the scalar path in the same order, and IEEE arithmetic is
//! lane-wise, so a lane's record and box are the scalar ones bit for bit. A lane that
//! leaves the common path (a rejection, an H-max clamp, a fallback of the dampening
//! formula, non-finite input) reports `None`, and the caller stores that photon with the
//! scalar function, which makes the decision.
//!
//! Worth it only where the stores of many photons are at hand together (a CPU photon pass
//! that queues its footprint stores), and with wide vectors (AVX2 or AVX-512 chosen at run
//! time by the caller with `#[target_feature]`: this function is `#[inline(always)]` so
//! that it is compiled for the caller's features).

use crate::aabb::Aabb;
use crate::classify::Smoothing;
use crate::footprint::{Footprint, PackedFootprint, MIN_RELATIVE_SEMI_AXIS};
use crate::heuristics::{CullMetric, ResolvedHeuristics};
use glam::DVec3;

/// `N` values, one per lane.
type L<const N: usize> = [f64; N];

/// The lanes of a 3-vector field.
#[derive(Clone, Copy)]
struct V<const N: usize> {
    x: L<N>,
    y: L<N>,
    z: L<N>,
}

#[inline(always)]
fn lanes<const N: usize>(f: impl FnMut(usize) -> f64) -> L<N> {
    core::array::from_fn(f)
}

impl<const N: usize> V<N> {
    #[inline(always)]
    fn gather(fps: &[Footprint; N], f: impl Fn(&Footprint) -> DVec3) -> Self {
        Self { x: lanes(|k| f(&fps[k]).x), y: lanes(|k| f(&fps[k]).y), z: lanes(|k| f(&fps[k]).z) }
    }

    #[inline(always)]
    fn at(&self, k: usize) -> DVec3 {
        DVec3::new(self.x[k], self.y[k], self.z[k])
    }

    /// `self * s` lane by lane (glam's `DVec3 * f64`).
    #[inline(always)]
    fn scale(&self, s: &L<N>) -> Self {
        Self { x: lanes(|k| self.x[k] * s[k]), y: lanes(|k| self.y[k] * s[k]), z: lanes(|k| self.z[k] * s[k]) }
    }

    /// glam's `dot`: `(x·x' + y·y') + z·z'`.
    #[inline(always)]
    fn dot(&self, o: &Self) -> L<N> {
        lanes(|k| (self.x[k] * o.x[k]) + (self.y[k] * o.y[k]) + (self.z[k] * o.z[k]))
    }

    /// glam's `cross`.
    #[inline(always)]
    fn cross(&self, o: &Self) -> Self {
        Self {
            x: lanes(|k| self.y[k] * o.z[k] - o.y[k] * self.z[k]),
            y: lanes(|k| self.z[k] * o.x[k] - o.z[k] * self.x[k]),
            z: lanes(|k| self.x[k] * o.y[k] - o.x[k] * self.y[k]),
        }
    }

    /// glam's `abs().max_element()`: `max(|x|, max(|y|, |z|))` with `a > b ? a : b`.
    #[inline(always)]
    fn abs_max_element(&self) -> L<N> {
        let max = |a: f64, b: f64| if a > b { a } else { b };
        lanes(|k| max(self.x[k].abs(), max(self.y[k].abs(), self.z[k].abs())))
    }
}

/// `√x` lane by lane, correctly rounded (IEEE `sqrt`, as `libm::sqrt`): on x86-64 with
/// SSE2's packed square root, two lanes per instruction (merged into wider ones where the
/// caller is compiled for them), since `libm::sqrt`'s scalar intrinsic does not vectorise.
#[inline(always)]
fn sqrt_lanes<const N: usize>(x: L<N>) -> L<N> {
    #[cfg(target_arch = "x86_64")]
    {
        use core::arch::x86_64::{_mm_loadu_pd, _mm_sqrt_pd, _mm_storeu_pd};
        let mut out = [0.0; N];
        let mut k = 0;
        while k + 2 <= N {
            // SAFETY: SSE2 is part of x86-64; `k + 2 <= N` keeps both accesses in bounds.
            unsafe { _mm_storeu_pd(out.as_mut_ptr().add(k), _mm_sqrt_pd(_mm_loadu_pd(x.as_ptr().add(k)))) };
            k += 2;
        }
        while k < N {
            out[k] = libm::sqrt(x[k]);
            k += 1;
        }
        out
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        x.map(libm::sqrt)
    }
}

/// `true` where `x` is finite (`x − x` is 0 only for finite `x`).
#[inline(always)]
#[allow(clippy::eq_op)]
fn finite(x: f64) -> bool {
    x - x == 0.0
}

/// Stores the `N` footprints `fps` (unsmoothed, as
/// [`Footprint::from_transferred`] builds them) under `smoothing` and `heuristics`, with
/// the progressive radii `radii` (metres, `[caustic, global]`) that the heuristics were
/// resolved for ([`ResolvedHeuristics::at_radii`]). Lane `k` is
/// `Some((record, box))` exactly where
/// [`store_footprint_resolved`](crate::store::store_footprint_resolved)`(fps[k], smoothing,
/// heuristics, radii[map])` stores a footprint, with the same record and box bit for bit;
/// `None` where that function must decide (it may still store a footprint there).
/// Every lane is `None` when the heuristics use something other than γ = 1/4 dampening
/// with the radii cached, or no dampening.
///
/// The lanes are handed to `out` in order, `out(k, lane k)`, as they are packed (an array
/// of results returned by value would be written piecewise and read back whole, which
/// stalls on store forwarding).
#[inline(always)]
pub fn store_footprints_lanes<const N: usize>(
    fps: &[Footprint; N],
    smoothing: &Smoothing,
    heuristics: &ResolvedHeuristics,
    radii: [f64; 2],
    mut out: impl FnMut(usize, Option<(PackedFootprint, Aabb)>),
) {
    let parts = heuristics.lane_parts(radii);
    let Some(parts) = parts else {
        for k in 0..N {
            out(k, None);
        }
        return;
    };
    let caustic: [bool; N] = core::array::from_fn(|k| fps[k].map.index() == 0);
    let pick = |k: usize, v: [f64; 2]| if caustic[k] { v[0] } else { v[1] };
    // Inputs, with every lane's inputs finite (a non-finite one goes to the scalar path).
    let center = V::gather(fps, |f| f.center);
    let normal = V::gather(fps, |f| f.normal);
    let flux = V::gather(fps, |f| f.flux);
    let smooth: L<N> = lanes(|k| pick(k, [smoothing.caustic, smoothing.global]));
    // Smoothing (`Footprint::scaled`).
    let du = V::gather(fps, |f| f.du).scale(&smooth);
    let dv = V::gather(fps, |f| f.dv).scale(&smooth);
    let mut ok: [bool; N] = core::array::from_fn(|k| {
        let s = (center.x[k] - center.x[k]) + (center.y[k] - center.y[k]) + (center.z[k] - center.z[k]);
        let n = (normal.x[k] - normal.x[k]) + (normal.y[k] - normal.y[k]) + (normal.z[k] - normal.z[k]);
        let f = (flux.x[k] - flux.x[k]) + (flux.y[k] - flux.y[k]) + (flux.z[k] - flux.z[k]);
        finite(s + n + f)
    });
    // `ResolvedHeuristics::store`: scale-free parts.
    let la2_0 = du.dot(&du);
    let lb2_0 = dv.dot(&dv);
    let major2_0: L<N> = lanes(|k| la2_0[k].max(lb2_0[k]));
    let cross_0 = du.cross(&dv);
    let e2_0: V<N> = V {
        x: lanes(|k| 0.25 * (du.x[k] * du.x[k] + dv.x[k] * dv.x[k])),
        y: lanes(|k| 0.25 * (du.y[k] * du.y[k] + dv.y[k] * dv.y[k])),
        z: lanes(|k| 0.25 * (du.z[k] * du.z[k] + dv.z[k] * dv.z[k])),
    };
    if let Some(f) = parts.degenerate {
        let c2 = cross_0.dot(&cross_0);
        for k in 0..N {
            ok[k] &= major2_0[k] > 0.0 && c2[k] >= f * f * major2_0[k] * major2_0[k];
        }
    }
    let major_0 = sqrt_lanes(major2_0);
    let minor_0 = sqrt_lanes::<N>(lanes(|k| la2_0[k].min(lb2_0[k])));
    let e_0: V<N> = V { x: sqrt_lanes(e2_0.x), y: sqrt_lanes(e2_0.y), z: sqrt_lanes(e2_0.z) };
    // Dampening (γ = 1/4, `dampen_ratio_with`'s first branch); the other branches and a
    // ratio that is not finite and positive go to the scalar path.
    let s: L<N> = match parts.reference_pow {
        None => [1.0; N],
        Some(pow) => lanes(|k| pick(k, pow) * crate::heuristics::pow_minus_3_8(major2_0[k])),
    };
    if parts.reference_pow.is_some() {
        for k in 0..N {
            ok[k] &= major2_0[k].is_normal() & (major2_0[k] < f64::INFINITY) & finite(s[k]) & (s[k] > 0.0);
        }
    }
    let s2: L<N> = lanes(|k| s[k] * s[k]);
    let la2: L<N> = lanes(|k| la2_0[k] * s2[k]);
    let lb2: L<N> = lanes(|k| lb2_0[k] * s2[k]);
    if let Some(h) = parts.h_max {
        for k in 0..N {
            ok[k] &= !(la2[k].max(lb2[k]) > h * h);
        }
    }
    let du = du.scale(&s);
    let dv = dv.scale(&s);
    let cross = du.cross(&dv);
    let den = cross.dot(&normal);
    // `degenerate_denominator`.
    const K2: f64 = 256.0 * f64::EPSILON * f64::EPSILON;
    for k in 0..N {
        ok[k] &= (den[k] * den[k] > K2 * la2[k] * lb2[k]) & finite(den[k]);
    }
    // `half_thickness(centre, s·major, s·minor, radius)`.
    let c_max = center.abs_max_element();
    let h: L<N> = lanes(|k| {
        let floor = 8.0 * f32::EPSILON as f64 * (c_max[k] + s[k] * major_0[k]);
        (0.5 * (s[k] * minor_0[k])).min(pick(k, radii)).max(floor)
    });
    // `finish`: the box of the elliptic slab, culling.
    let e: V<N> = V {
        x: lanes(|k| e_0.x[k] * s[k] + (normal.x[k] * h[k]).abs()),
        y: lanes(|k| e_0.y[k] * s[k] + (normal.y[k] * h[k]).abs()),
        z: lanes(|k| e_0.z[k] * s[k] + (normal.z[k] * h[k]).abs()),
    };
    if let Some((metric, threshold)) = parts.cull {
        let mine: L<N> = match metric {
            CullMetric::LargestExtent => {
                let max = |a: f64, b: f64| if a > b { a } else { b };
                lanes(|k| 2.0 * max(e.x[k], max(e.y[k], e.z[k])))
            }
            CullMetric::Diagonal => lanes(|k| 2.0 * libm::sqrt(e.dot(&e)[k])),
            CullMetric::SurfaceArea => lanes(|k| 8.0 * (e.x[k] * e.y[k] + e.y[k] * e.z[k] + e.z[k] * e.x[k])),
        };
        for k in 0..N {
            ok[k] &= mine[k] <= threshold;
        }
    }
    // `pack_parts`.
    let c2 = cross.dot(&cross);
    for k in 0..N {
        let scale = c_max[k].max(1e-30) * MIN_RELATIVE_SEMI_AXIS;
        ok[k] &= (c2[k] >= 4.0 * (la2[k] + lb2[k]) * scale * scale) & (h[k] > 0.0);
    }
    let inv: L<N> = lanes(|k| 2.0 / den[k]);
    let row_u = dv.cross(&normal).scale(&inv);
    let row_v = normal.cross(&du).scale(&inv);
    let dens: L<N> = lanes(|k| 2.0 * inv[k].abs());
    let density = flux.scale(&dens);
    let inv_h: L<N> = lanes(|k| 1.0 / h[k]);
    let row_n = normal.scale(&inv_h);
    for k in 0..N {
        let d32 = density.at(k).as_vec3();
        let f = flux.at(k);
        let underflow = |c: usize| f[c] != 0.0 && !(d32[c].abs() >= f32::MIN_POSITIVE);
        let (c, ru, rv, rn) = (center.at(k).as_vec3(), row_u.at(k).as_vec3(), row_v.at(k).as_vec3(), row_n.at(k).as_vec3());
        let zero = (c - c) + (ru - ru) + (rv - rv) + (rn - rn) + (d32 - d32);
        if !ok[k] || underflow(0) | underflow(1) | underflow(2) || zero.x + zero.y + zero.z != 0.0 {
            out(k, None);
            continue;
        }
        let ek = DVec3::new(e.x[k], e.y[k], e.z[k]);
        let packed = PackedFootprint {
            center: c.to_array(),
            map: fps[k].map as u32,
            row_u: ru.to_array(),
            flux_density_r: d32.x,
            row_v: rv.to_array(),
            flux_density_g: d32.y,
            row_n: rn.to_array(),
            flux_density_b: d32.z,
        };
        out(k, Some((packed, Aabb::from_centre_half_extent(center.at(k), ek))));
    }
}

/// What [`store_footprints_lanes`] needs of a [`ResolvedHeuristics`], uniform over a batch.
pub(crate) struct LaneParts {
    /// γ = 1/4 dampening: `ℓ_ref^(3/4)` per map; `None` without dampening.
    pub reference_pow: Option<[f64; 2]>,
    /// `h_max` (metres) where H-max is on (a clamp leaves the lane path).
    pub h_max: Option<f64>,
    /// Degenerate-removal fraction.
    pub degenerate: Option<f64>,
    /// Culling metric and threshold.
    pub cull: Option<(CullMetric, f64)>,
}

impl ResolvedHeuristics {
    /// The batch-uniform parts for the radii `radii`; `None` where the lane path does not
    /// apply (dampening with another exponent, or radii other than the cached ones).
    pub(crate) fn lane_parts(&self, radii: [f64; 2]) -> Option<LaneParts> {
        let reference_pow = match self.dampening {
            None => None,
            Some(d) => {
                if d.exponent != 0.25 {
                    return None;
                }
                let mut pow = [0.0; 2];
                for (m, p) in pow.iter_mut().enumerate() {
                    let reference = d.reference.length(radii[m]);
                    let (r, rp) = self.reference_pow[m]?;
                    if r != radii[m] || !(reference > 0.0 && reference.is_finite()) {
                        return None;
                    }
                    *p = rp;
                }
                Some(pow)
            }
        };
        let h_max = self.h_max.map(|(h, _)| h).filter(|&h| h > 0.0);
        Some(LaneParts { reference_pow, h_max, degenerate: self.degenerate, cull: self.cull })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::aabb::Aabb;
    use crate::footprint::PhotonMap;
    use crate::heuristics::{BoundingBoxCulling, DegenerateRemoval, HMax, HMaxMode, Heuristics, LengthSpec};
    use crate::rng::{Rng, StreamDomain};
    use crate::store::{store_footprint_resolved, StoredPhoton};
    use alloc::vec;
    use alloc::vec::Vec;

    /// A unit vector, uniformly random.
    fn unit(r: &mut Rng) -> DVec3 {
        loop {
            let v = DVec3::new(r.next_f64(), r.next_f64(), r.next_f64()) * 2.0 - 1.0;
            if v.length_squared() > 1e-3 && v.length_squared() <= 1.0 {
                return v.normalize();
            }
        }
    }

    /// Footprints of every kind the store meets: scales from 1e-9 to 10 m, centres near
    /// and far from the origin, near-parallel differentials (degenerate), one zero or
    /// huge differential (H-max clamps, culling), zero flux channels, a few non-finite
    /// inputs.
    fn pool(seed: u32, n: usize) -> Vec<Footprint> {
        let mut r = Rng::new(seed, 0, 0, StreamDomain::User);
        (0..n)
            .map(|i| {
                let normal = unit(&mut r);
                let t = normal.any_orthonormal_pair();
                let scale = libm::pow(10.0, r.next_f64() * 10.0 - 9.0);
                let (a, b) = (r.next_f64() * 2.0 - 1.0, r.next_f64() * 2.0 - 1.0);
                let mut du = (t.0 * (0.2 + r.next_f64()) + t.1 * a) * scale;
                let mut dv = (t.1 * (0.2 + r.next_f64()) + t.0 * b) * scale * libm::pow(10.0, r.next_f64() * 2.0 - 1.0);
                match i % 23 {
                    0 => dv = du * (1.0 + 1e-9),
                    1 => dv = DVec3::ZERO,
                    2 => du *= 1e6,
                    3 => du = DVec3::new(f64::NAN, 0.0, 0.0),
                    4 => dv = DVec3::splat(f64::INFINITY),
                    5 => du = du * 1e-300,
                    _ => {}
                }
                let center = unit(&mut r) * libm::pow(10.0, r.next_f64() * 6.0 - 3.0) * if i % 17 == 0 { 1e5 } else { 1.0 };
                let mut flux = DVec3::new(r.next_f64(), r.next_f64(), r.next_f64()) * 1e-5;
                if i % 11 == 0 {
                    flux.y = 0.0;
                }
                if i % 13 == 0 {
                    flux *= 1e-40;
                }
                let map = if i % 3 == 0 { PhotonMap::Caustic } else { PhotonMap::Global };
                Footprint { center, normal, du, dv, flux, map }
            })
            .collect()
    }

    fn configs() -> Vec<Heuristics> {
        let d = Heuristics::default();
        let mut out = vec![d];
        out.push(Heuristics { h_max: Some(HMax { length: LengthSpec::RelativeToDiagonal(0.001), mode: HMaxMode::PreserveAspect }), ..d });
        out.push(Heuristics { dampening: None, ..d });
        out.push(Heuristics { degenerate: None, culling: None, ..d });
        out.push(Heuristics { culling: Some(BoundingBoxCulling { fraction: 0.001, metric: CullMetric::Diagonal }), ..d });
        out.push(Heuristics { culling: Some(BoundingBoxCulling { fraction: 1e-5, metric: CullMetric::SurfaceArea }), degenerate: Some(DegenerateRemoval { fraction: 0.3 }), ..d });
        out.push(Heuristics { dampening: None, h_max: None, degenerate: None, culling: None });
        out
    }

    /// Every lane that answers gives the scalar store's footprint record and box bit for
    /// bit, and the lanes answer for nearly every footprint the scalar store keeps (so the
    /// comparison is not vacuous).
    #[test]
    fn lanes_match_the_scalar_store_bit_for_bit() {
        let scene = Aabb { min: DVec3::splat(-5.0), max: DVec3::splat(5.0) };
        let radii = [3e-3, 2e-2];
        let smoothing = Smoothing { caustic: 0.7, global: 1.3 };
        for (c, heuristics) in configs().into_iter().enumerate() {
            let resolved = heuristics.resolve(&scene).at_radii(radii);
            let fps = pool(c as u32 + 1, 4096);
            let (mut kept, mut answered) = (0, 0);
            for chunk in fps.chunks_exact(4) {
                let batch: &[Footprint; 4] = chunk.try_into().unwrap();
                let mut lanes = Vec::new();
                store_footprints_lanes(batch, &smoothing, &resolved, radii, |k, lane| lanes.push((k, lane)));
                assert_eq!(lanes.iter().map(|l| l.0).collect::<Vec<_>>(), [0, 1, 2, 3]);
                for (fp, (_, lane)) in batch.iter().zip(lanes) {
                    let scalar = store_footprint_resolved(*fp, &smoothing, &resolved, radii[fp.map.index()]);
                    if let StoredPhoton::Footprint { .. } = scalar {
                        kept += 1;
                    }
                    if let Some((packed, aabb)) = lane {
                        answered += 1;
                        let StoredPhoton::Footprint { packed: p, aabb: a } = scalar else {
                            panic!("config {c}: lanes stored {fp:?}, the scalar store did not: {scalar:?}")
                        };
                        assert_eq!(bytemuck::bytes_of(&packed), bytemuck::bytes_of(&p), "config {c}: {fp:?}");
                        for (x, y) in [(aabb.min, a.min), (aabb.max, a.max)] {
                            assert_eq!(x.to_array().map(f64::to_bits), y.to_array().map(f64::to_bits), "config {c}: {fp:?}");
                        }
                    }
                }
            }
            assert!(kept > 500, "config {c}: only {kept} footprints kept");
            // With dampening the lanes leave out only clamps and fallbacks; without it every
            // lane answers (`None` for all lanes only where the lane path does not apply).
            assert!(answered as f64 >= 0.5 * kept as f64, "config {c}: lanes answered {answered} of {kept}");
        }
    }

    /// The lane path steps aside (every lane `None`) where it does not apply: another
    /// dampening exponent, or radii other than those cached.
    #[test]
    fn lanes_step_aside_where_they_do_not_apply() {
        let scene = Aabb { min: DVec3::splat(-5.0), max: DVec3::splat(5.0) };
        let fps: [Footprint; 4] = pool(9, 16)[8..12].try_into().unwrap();
        let s = Smoothing::default();
        let answered = |h: &ResolvedHeuristics, radii: [f64; 2]| {
            let mut n = 0;
            store_footprints_lanes(&fps, &s, h, radii, |_, lane| n += lane.is_some() as usize);
            n
        };
        let h = Heuristics::default().resolve(&scene);
        assert_eq!(answered(&h, [1e-3, 1e-2]), 0, "radii not cached");
        let cached = h.at_radii([1e-3, 1e-2]);
        assert!(answered(&cached, [1e-3, 1e-2]) > 0, "cached radii");
        assert_eq!(answered(&cached, [1e-3, 2e-2]), 0, "other radii");
        let mut other = Heuristics::default();
        other.dampening.as_mut().unwrap().exponent = 0.5;
        let other = other.resolve(&scene).at_radii([1e-3, 1e-2]);
        assert_eq!(answered(&other, [1e-3, 1e-2]), 0, "exponent 0.5");
    }
}
