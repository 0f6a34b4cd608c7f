//! Camera pass: the query points the backend finds through specular chains agree with
//! exact geometric optics computed here ([`super::optics`]), not with `arpa-core`'s own
//! camera path.
//!
//! The jitter inside a pixel is the backend's, so a query point cannot be predicted
//! exactly; instead each query point is *traced back*: the unique camera ray that reaches
//! it through the chain (its mirror image, or the entry angle through the slab) must leave
//! the eye through the record's own pixel. At the suite's resolutions a pixel spans a few
//! millimetres on the floor, so a misplaced reflection or a refraction with a wrong index
//! lands pixels away; over all records the traced-back rays' sub-pixel positions must
//! average `(½, ½)` (uniform jitter, the box filter of the references). Normals and
//! weights (`throughput · albedo/π`) are exact; the
//! Fresnel-chosen split between reflection and refraction is checked statistically
//! against the exact reflectance.

use std::f64::consts::PI;

use arpa_core::glam::{DVec3, Vec3};
use arpa_core::render::tracer::{Method, QueryRecord, RenderSettings};

use super::optics::{Pinhole, fresnel, slab_entry_angle};
use crate::dyn_tracer::DynTracer;
use crate::scenes;
use crate::suite::{CaseResult, Context};

/// Image side of both camera cases (pixels).
pub const SIZE: u32 = 48;
/// How far a traced-back ray may leave its pixel (pixels): `f32` positions and the
/// backends' ray-origin offsets (~1e-5 m) move a query point by far less than this.
pub const PIXEL_TOL: f64 = 0.02;
/// Tolerance of a query point's height above the floor (m).
pub const HEIGHT_TOL: f64 = 1e-4;
/// Tolerance of the unit normal (absolute, per component).
pub const NORMAL_TOL: f64 = 1e-5;
/// Tolerance of the weight (relative; the `f32` record).
pub const WEIGHT_TOL: f64 = 1e-5;
/// Standard deviations allowed for the Fresnel statistics.
pub const SIGMAS: f64 = 4.0;

/// Sub-pixel positions of the traced-back rays: with the documented jittered pinhole
/// (box filter) they are uniform over the pixel, mean `(½, ½)`, variance `1/12` per axis.
#[derive(Default)]
struct Jitter {
    sum: [f64; 2],
    n: usize,
}

impl Jitter {
    fn add(&mut self, pin: &Pinhole, (x, y): (f64, f64), pixel: u32) {
        self.sum[0] += x - (pixel % pin.width) as f64;
        self.sum[1] += y - (pixel / pin.width) as f64;
        self.n += 1;
    }

    /// `(mean x, mean y, largest |z|)` of the sub-pixel offsets against `½`.
    fn z(&self) -> (f64, f64, f64) {
        let n = self.n.max(1) as f64;
        let sd = (1.0 / 12.0 / n).sqrt();
        let (mx, my) = (self.sum[0] / n, self.sum[1] / n);
        (mx, my, ((mx - 0.5) / sd).abs().max(((my - 0.5) / sd).abs()))
    }

    fn describe(&self) -> String {
        let (mx, my, z) = self.z();
        format!("mean sub-pixel position ({mx:.3}, {my:.3}) (uniform jitter: 0.5, {z:.1}σ)")
    }
}

/// A traced-back ray: how far outside the record's pixel it leaves the eye (px) and its
/// film position (px).
type TracedBack = (f64, (f64, f64));

fn v(a: [f32; 3]) -> DVec3 {
    Vec3::from_array(a).as_dvec3()
}

fn check_floor_record(r: &QueryRecord, weight: f64) -> Result<(), String> {
    let p = v(r.position);
    let n = v(r.normal);
    if p.y.abs() > HEIGHT_TOL {
        return Err(format!(
            "pixel {}: query point {p} is not on the floor y = 0",
            r.pixel
        ));
    }
    if (n - DVec3::Y).abs().max_element() > NORMAL_TOL {
        return Err(format!(
            "pixel {}: normal {n}, expected +y (towards the viewer)",
            r.pixel
        ));
    }
    let w = v(r.weight);
    if (w - DVec3::splat(weight)).abs().max_element() > WEIGHT_TOL * weight {
        return Err(format!(
            "pixel {}: weight {w}, expected {weight:.6} per channel",
            r.pixel
        ));
    }
    Ok(())
}

fn collect(t: &mut dyn DynTracer, iterations: u32) -> Result<Vec<Vec<QueryRecord>>, String> {
    let pixels = (SIZE * SIZE) as usize;
    (0..iterations)
        .map(|_| {
            t.iterate().ctx("iterate")?;
            let records = t.read_query_points().ctx("read_query_points")?;
            if records.len() != pixels {
                return Err(format!(
                    "{} query records for {pixels} pixels",
                    records.len()
                ));
            }
            if let Some(r) = records.iter().find(|r| r.pixel as usize >= pixels) {
                return Err(format!(
                    "query record for pixel {} outside the image",
                    r.pixel
                ));
            }
            Ok(records)
        })
        .collect()
}

/// What a camera ray of the mirror scene reaches.
#[derive(Clone, Copy, Debug, PartialEq)]
enum MirrorChain {
    /// The floor, directly.
    Direct,
    /// The floor, after the mirror.
    Mirrored,
    /// Nothing.
    Escapes,
}

fn mirror_hit(o: DVec3, d: DVec3) -> Option<(f64, DVec3)> {
    if d.x <= 0.0 {
        return None;
    }
    let t = (scenes::MIRROR_X - o.x) / d.x;
    let m = o + d * t;
    (t > 0.0
        && (0.0..=scenes::MIRROR_HEIGHT).contains(&m.y)
        && m.z.abs() <= scenes::MIRROR_HALF_WIDTH)
        .then_some((t, m))
}

fn floor_hit(o: DVec3, d: DVec3) -> Option<(f64, DVec3)> {
    if d.y >= 0.0 {
        return None;
    }
    let t = -o.y / d.y;
    let p = o + d * t;
    ((-3.0..=scenes::MIRROR_X).contains(&p.x) && p.z.abs() <= 3.0).then_some((t, p))
}

fn mirror_chain(eye: DVec3, d: DVec3) -> MirrorChain {
    let floor = floor_hit(eye, d);
    match mirror_hit(eye, d) {
        Some((tm, m)) if floor.is_none_or(|(tf, _)| tm < tf) => {
            if floor_hit(m, DVec3::new(-d.x, d.y, d.z)).is_some() {
                MirrorChain::Mirrored
            } else {
                MirrorChain::Escapes
            }
        }
        _ if floor.is_some() => MirrorChain::Direct,
        _ => MirrorChain::Escapes,
    }
}

/// The mirror scene ([`scenes::mirror_wall`]), 48², 2 iterations: every pixel whose
/// centre and corners all reach the same place (floor directly, floor through the mirror,
/// nothing) has a query point exactly when that place is the floor; every query point is
/// on the floor with normal +y and weight `ρ/π` (direct) or `0.9 ρ/π` (mirrored), and the
/// camera ray to it (to its image in `x = 1` when mirrored, crossing the mirror's
/// rectangle) leaves the eye through the record's pixel.
pub fn mirror(t: &mut dyn DynTracer) -> CaseResult {
    let scene = scenes::mirror_wall(SIZE);
    let pin = Pinhole::new(&scene.camera);
    let settings = RenderSettings {
        method: Method::Arpa,
        photons_per_iteration: 1000,
        seed: 11,
        max_depth: 8,
        direct_lighting: false,
        ..RenderSettings::default()
    };
    t.upload_scene(&scene, &settings).ctx("upload_scene")?;
    let rho_pi = scenes::MIRROR_FLOOR_ALBEDO / PI;
    let mut counts = [0usize; 3];
    let mut worst = 0.0f64;
    let mut jitter = Jitter::default();
    for records in collect(t, 2)? {
        for r in &records {
            let probes = pin.pixel_probes(r.pixel).map(|d| mirror_chain(pin.eye, d));
            let unambiguous = probes.iter().all(|c| *c == probes[0]);
            if r.valid != 1 {
                if unambiguous && probes[0] != MirrorChain::Escapes {
                    return Err(format!(
                        "pixel {}: no query point, but every ray of the pixel reaches the floor ({:?})",
                        r.pixel, probes[0]
                    ));
                }
                counts[2] += 1;
                continue;
            }
            if unambiguous && probes[0] == MirrorChain::Escapes {
                return Err(format!(
                    "pixel {}: query point {:?}, but every ray of the pixel leaves the scene",
                    r.pixel, r.position
                ));
            }
            let q = v(r.position);
            // The two chains that can end at q, each with its traced-back ray.
            let direct = {
                let d = (q - pin.eye).normalize();
                let blocked =
                    mirror_hit(pin.eye, d).is_some_and(|(tm, _)| tm < (q - pin.eye).length());
                (!blocked).then(|| pin.film(d).map(|f| (pin.outside_pixel(f, r.pixel), f)))
            };
            let mirrored = {
                let image = DVec3::new(2.0 * scenes::MIRROR_X - q.x, q.y, q.z);
                let d = (image - pin.eye).normalize();
                mirror_hit(pin.eye, d)
                    .map(|_| pin.film(d).map(|f| (pin.outside_pixel(f, r.pixel), f)))
            };
            // Chains whose traced-back ray leaves the eye through this pixel (both near
            // the mirror's foot, where a point and its image nearly coincide).
            let fits: Vec<(MirrorChain, TracedBack)> = [
                (MirrorChain::Direct, direct),
                (MirrorChain::Mirrored, mirrored),
            ]
            .into_iter()
            .filter_map(|(c, o)| o.flatten().map(|o| (c, o)))
            .filter(|&(_, (o, _))| o <= PIXEL_TOL)
            .collect();
            let weight_of = |c: MirrorChain| match c {
                MirrorChain::Mirrored => scenes::MIRROR_REFLECTANCE * rho_pi,
                _ => rho_pi,
            };
            let w = v(r.weight).x;
            let Some(&(chain, (off, film))) = fits
                .iter()
                .find(|(c, _)| (w - weight_of(*c)).abs() <= WEIGHT_TOL * weight_of(*c))
                .or(fits.first())
            else {
                return Err(format!(
                    "pixel {}: query point {q}: no camera ray through this pixel reaches it, directly or in the mirror",
                    r.pixel
                ));
            };
            if unambiguous && chain != probes[0] {
                return Err(format!(
                    "pixel {}: query point {q} reached {chain:?}, geometry says {:?}",
                    r.pixel, probes[0]
                ));
            }
            worst = worst.max(off);
            jitter.add(&pin, film, r.pixel);
            check_floor_record(r, weight_of(chain))?;
            counts[(chain == MirrorChain::Mirrored) as usize] += 1;
        }
    }
    // Both chains must actually occur (≈ 40 % direct, 25 % mirrored at this framing).
    if counts[0] < 200 || counts[1] < 200 {
        return Err(format!(
            "query points direct/mirrored/none {counts:?}: a chain is missing"
        ));
    }
    let msg = format!(
        "direct/mirrored/none {}/{}/{}; worst traced-back ray {worst:.1e} px outside its pixel (tol {PIXEL_TOL}); {}",
        counts[0],
        counts[1],
        counts[2],
        jitter.describe()
    );
    if jitter.z().2 > SIGMAS {
        return Err(msg);
    }
    Ok(msg)
}

/// Largest number of slab crossings a chain may have in [`glass_slab`] (1 + 2 per pair of
/// internal reflections; longer chains have probability below `F⁸ ≈ 1e-11`).
pub const MAX_CROSSINGS: u32 = 7;

/// The slab scene ([`scenes::glass_slab`]), 48², 6 iterations: every camera ray meets the
/// slab's top. It is reflected (and leaves the scene: no query point) with the Fresnel
/// probability `F(θ)`, else it refracts, crosses the slab `1 + 2k` times (`k` pairs of
/// internal reflections, each with probability `F²`) and reaches the floor. Every query
/// point is on the floor with normal +y and weight `ρ/π` (radiance scaling `(1/n)²` in,
/// `n²` out, Fresnel choices weighted 1); the entry angle that carries the eye's ray to the
/// point through `1 + 2k` crossings leaves the eye through the record's pixel for some
/// `k`. Counted over all records: the number with a query point matches
/// `Σ (1 − F)/(1 + F)` and the number with `k = 0` matches `Σ (1 − F)²` (F at each pixel's
/// centre ray) within [`SIGMAS`] binomial standard deviations.
pub fn glass_slab(t: &mut dyn DynTracer) -> CaseResult {
    slab_chains(t, &scenes::glass_slab(SIZE), scenes::SLAB_THICKNESS, MAX_CROSSINGS, 5)
}

/// The camera check of [`glass_slab`] on `scene` (the slab scene's layout with a slab
/// `thickness` thick), with chains of at most `max_crossings` slab crossings (odd): the
/// expected Fresnel counts are `Σ_k (1 − F)² F^{2k}` over the chains that fit.
pub(crate) fn slab_chains(t: &mut dyn DynTracer, scene: &arpa_core::render::scene::Scene, thickness: f64, max_crossings: u32, seed: u32) -> CaseResult {
    let pin = Pinhole::new(&scene.camera);
    let n = scenes::SLAB_IOR;
    let top = scenes::SLAB_BOTTOM + thickness;
    let air = pin.eye.y - top;
    let settings = RenderSettings {
        method: Method::Arpa,
        photons_per_iteration: 1000,
        seed,
        max_depth: 2 + max_crossings,
        direct_lighting: false,
        ..RenderSettings::default()
    };
    t.upload_scene(scene, &settings).ctx("upload_scene")?;
    let rho_pi = scenes::SLAB_FLOOR_ALBEDO / PI;
    let (mut valid, mut first) = (0usize, 0usize);
    let (mut e_valid, mut v_valid, mut e_first, mut v_first) = (0.0, 0.0, 0.0, 0.0);
    let mut worst = 0.0f64;
    let mut jitter = Jitter::default();
    let mut by_k = vec![0usize; max_crossings as usize / 2 + 1];
    for records in collect(t, 6)? {
        for r in &records {
            let centre = pin.pixel_probes(r.pixel)[0];
            // The centre ray must meet the top face (the scene is framed so).
            let to_top = (top - pin.eye.y) / centre.y;
            let entry = pin.eye + centre * to_top;
            if !(to_top > 0.0
                && entry.x.abs() < scenes::SLAB_HALF_SIDE
                && entry.z.abs() < scenes::SLAB_HALF_SIDE)
            {
                return Err(format!(
                    "pixel {}: framing error, centre ray misses the slab",
                    r.pixel
                ));
            }
            let f = fresnel(1.0, n, centre.y.abs().acos());
            let p_valid = (0..=max_crossings / 2).map(|k| (1.0 - f) * (1.0 - f) * f.powi(2 * k as i32)).sum::<f64>();
            let p_first = (1.0 - f) * (1.0 - f);
            e_valid += p_valid;
            v_valid += p_valid * (1.0 - p_valid);
            e_first += p_first;
            v_first += p_first * (1.0 - p_first);
            if r.valid != 1 {
                continue;
            }
            valid += 1;
            let q = v(r.position);
            let horizontal = DVec3::new(q.x - pin.eye.x, 0.0, q.z - pin.eye.z);
            let rho = horizontal.length();
            let azimuth = horizontal / rho.max(1e-300);
            let best = (0..=max_crossings / 2)
                .map(|k| {
                    let th = slab_entry_angle(
                        rho,
                        air,
                        scenes::SLAB_BOTTOM,
                        thickness,
                        n,
                        1 + 2 * k,
                    );
                    let d = azimuth * th.sin() - DVec3::Y * th.cos();
                    let film = pin.film(d);
                    let off = film.map_or(f64::INFINITY, |fp| pin.outside_pixel(fp, r.pixel));
                    (off, k, film.unwrap_or_default())
                })
                .min_by(|a, b| a.0.total_cmp(&b.0))
                .unwrap_or((f64::INFINITY, 0, (0.0, 0.0)));
            if best.0 > PIXEL_TOL {
                return Err(format!(
                    "pixel {}: query point {q}: no chain through the slab ends there from this pixel (closest {} crossings, {:.3} px outside)",
                    r.pixel,
                    1 + 2 * best.1,
                    best.0
                ));
            }
            worst = worst.max(best.0);
            jitter.add(&pin, best.2, r.pixel);
            by_k[best.1 as usize] += 1;
            first += (best.1 == 0) as usize;
            check_floor_record(r, rho_pi)?;
        }
    }
    let z_valid = (valid as f64 - e_valid) / v_valid.sqrt();
    let z_first = (first as f64 - e_first) / v_first.sqrt();
    let msg = format!(
        "query points {valid} (Fresnel expects {e_valid:.0}, {z_valid:+.1}σ), straight through {first} ({e_first:.0}, {z_first:+.1}σ), by internal-reflection pairs {by_k:?}; worst traced-back ray {worst:.1e} px outside its pixel (tol {PIXEL_TOL}); {}",
        jitter.describe()
    );
    if z_valid.abs() > SIGMAS || z_first.abs() > SIGMAS || jitter.z().2 > SIGMAS {
        return Err(msg);
    }
    Ok(msg)
}
