//! Glass thinner than a ray-origin offset: a 4 µm sheet ([`scenes::thin_sheet`]) and the
//! knife edge of a wedge ([`scenes::knife_edge`], the rim of a lens seen closely), where
//! the glass is thinner than `1e-5 m` for its first 0.2 mm. A ray that refracts into such
//! glass must meet its far face; one started beyond it (an origin offset along the
//! normal by more than the thickness) goes on in the refracted direction and lands
//! centimetres away. The checks are exact geometric optics written here in `f64`
//! ([`super::optics`]), independent of `arpa-core`'s paths.

use std::f64::consts::PI;

use arpa_core::glam::{DVec3, Vec3};
use arpa_core::render::scene::Scene;
use arpa_core::render::tracer::{Method, QueryRecord, RenderSettings};

use super::analytic::{SPECULAR_SIZE, slab_regions};
use super::camera::{SIGMAS, SIZE, slab_chains};
use super::optics::{Pinhole, fresnel};
use crate::dyn_tracer::DynTracer;
use crate::scenes;
use crate::suite::{CaseResult, Context};

/// Camera rays through the thin sheet, then through the knife edge: both must pass.
pub fn camera(t: &mut dyn DynTracer) -> CaseResult {
    let sheet = slab_chains(t, &scenes::thin_sheet(SIZE), scenes::thin_sheet_thickness(), 1, 7).map_err(|e| format!("thin sheet: {e}"))?;
    let edge = knife_edge(t).map_err(|e| format!("knife edge: {e}"))?;
    Ok(format!("thin sheet: {sheet}; knife edge: {edge}"))
}

/// Photons (ARPA footprints) through the thin sheet onto the floor: ring means against
/// the exact two-interface irradiance, as the thick slab's case.
pub fn photons_sheet_arpa(t: &mut dyn DynTracer) -> CaseResult {
    super::common::with_and_without_projection(t, |t| slab_regions(t, Method::Arpa, &scenes::thin_sheet(SPECULAR_SIZE), scenes::thin_sheet_thickness()))
}

/// How far a traced-back ray may leave its pixel in the zoomed knife-edge view (px): a
/// pixel spans 25 µrad there, so the `f32` camera frame and hit points move a query point
/// by a few thousandths of a pixel.
pub const EDGE_PIXEL_TOL: f64 = 0.05;
/// Glass thinner than this (m), 16 `f32` ulps of the coordinates, is not claimed: rays
/// entering the wedge there are left out of the checks.
pub const UNRESOLVED_THICKNESS: f64 = 2e-6;
/// The ray-origin offset the paths once used at the wedge (`1e-5 (1 + 0.5)` m): records
/// that entered thinner glass than this are counted separately and must occur.
pub const OLD_OFFSET: f64 = 1.5e-5;

/// What a camera ray of the knife-edge scene does.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Chain {
    /// Reaches the floor beside the wedge.
    Direct,
    /// Enters the wedge's top face where it is this thick (m), leaves through the bottom
    /// and reaches the floor; with the Fresnel reflectances of the two faces.
    Through { thickness: f64, f_in: f64, f_out: f64 },
    /// Anything else (a side face, total internal reflection, off the floor).
    Other,
}

/// The wedge's faces as its `f32` vertices place them: bottom plane height, top plane's
/// unit normal (outwards), length and half width (m).
struct Wedge {
    bottom: f64,
    top_normal: DVec3,
    slope: f64,
    length: f64,
    half_width: f64,
}

impl Wedge {
    fn new() -> Self {
        let bottom = scenes::WEDGE_BOTTOM as f32 as f64;
        let length = scenes::WEDGE_LENGTH as f32 as f64;
        let top = (scenes::WEDGE_BOTTOM + scenes::WEDGE_SLOPE * scenes::WEDGE_LENGTH) as f32 as f64;
        let slope = (top - bottom) / length;
        Self { bottom, top_normal: DVec3::new(-slope, 1.0, 0.0).normalize(), slope, length, half_width: scenes::WEDGE_HALF_WIDTH }
    }

    /// Follows the ray `eye + t d` to the floor: `(chain, floor point)`.
    fn trace(&self, eye: DVec3, d: DVec3) -> (Chain, DVec3) {
        let n = scenes::SLAB_IOR;
        let edge = DVec3::new(0.0, self.bottom, 0.0);
        let to_floor = |o: DVec3, d: DVec3| if d.y < 0.0 { o + d * (-o.y / d.y) } else { DVec3::NAN };
        // The top face's plane (through the knife edge).
        let denom = d.dot(self.top_normal);
        let t_top = if denom < 0.0 { (edge - eye).dot(self.top_normal) / denom } else { f64::INFINITY };
        let e = eye + d * t_top;
        if !(t_top > 0.0 && t_top.is_finite() && e.x > 0.0 && e.x <= self.length && e.z.abs() <= self.half_width) {
            // Beside the wedge: down to the bottom plane, which it must cross before the edge.
            let t_b = (self.bottom - eye.y) / d.y;
            let b = eye + d * t_b;
            return if t_b > 0.0 && b.x <= 0.0 { (Chain::Direct, to_floor(eye, d)) } else { (Chain::Other, DVec3::NAN) };
        }
        let thickness = self.slope * e.x;
        let Some((inside, f_in)) = refract(d, self.top_normal, 1.0, n) else { return (Chain::Other, DVec3::NAN) };
        if inside.y >= 0.0 {
            return (Chain::Other, DVec3::NAN);
        }
        let b = e + inside * ((self.bottom - e.y) / inside.y);
        if !(b.x > 0.0 && b.x <= self.length && b.z.abs() <= self.half_width) {
            return (Chain::Other, DVec3::NAN);
        }
        let Some((out, f_out)) = refract(inside, DVec3::NEG_Y, n, 1.0) else { return (Chain::Other, DVec3::NAN) };
        (Chain::Through { thickness, f_in, f_out }, to_floor(b, out))
    }
}

/// Snell refraction of unit `d` through a surface of unit outward normal `n` from index
/// `n1` (the side `d` comes from) into `n2`: the refracted unit direction and the Fresnel
/// reflectance, or `None` at total internal reflection.
fn refract(d: DVec3, n: DVec3, n1: f64, n2: f64) -> Option<(DVec3, f64)> {
    // Normal against the incident ray.
    let n = if d.dot(n) < 0.0 { n } else { -n };
    let cos_i = -d.dot(n);
    let eta = n1 / n2;
    let sin2_t = eta * eta * (1.0 - cos_i * cos_i);
    if sin2_t >= 1.0 {
        return None;
    }
    let cos_t = (1.0 - sin2_t).sqrt();
    Some(((d * eta + n * (eta * cos_i - cos_t)).normalize(), fresnel(n1, n2, cos_i.clamp(-1.0, 1.0).acos())))
}

/// The film position `(x, y)` (px) near `start` whose ray reaches floor point `q` through
/// the wedge (Newton's method on the exact chain, central differences), with how far
/// outside `pixel` it lies (px); `None` if no such chain converges.
fn through_wedge(w: &Wedge, pin: &Pinhole, q: DVec3, pixel: u32, start: (f64, f64)) -> Option<(f64, (f64, f64))> {
    let land = |f: (f64, f64)| match w.trace(pin.eye, pin.direction(f.0, f.1)) {
        (Chain::Through { .. }, p) => Some(p),
        _ => None,
    };
    let mut f = start;
    let h = 1e-3;
    for _ in 0..20 {
        let p = land(f)?;
        let r = (p.x - q.x, p.z - q.z);
        if r.0.hypot(r.1) < 1e-10 {
            return Some((pin.outside_pixel(f, pixel), f));
        }
        let (px1, px0) = (land((f.0 + h, f.1))?, land((f.0 - h, f.1))?);
        let (py1, py0) = (land((f.0, f.1 + h))?, land((f.0, f.1 - h))?);
        let j = [[(px1.x - px0.x) / (2.0 * h), (py1.x - py0.x) / (2.0 * h)], [(px1.z - px0.z) / (2.0 * h), (py1.z - py0.z) / (2.0 * h)]];
        let det = j[0][0] * j[1][1] - j[0][1] * j[1][0];
        if det.abs() < 1e-300 {
            return None;
        }
        let dx = (j[1][1] * r.0 - j[0][1] * r.1) / det;
        let dy = (-j[1][0] * r.0 + j[0][0] * r.1) / det;
        f = (f.0 - dx, f.1 - dy);
    }
    None
}

fn floor_record_error(r: &QueryRecord, weight: f64) -> Option<String> {
    let p = Vec3::from_array(r.position).as_dvec3();
    let n = Vec3::from_array(r.normal).as_dvec3();
    let w = Vec3::from_array(r.weight).as_dvec3();
    if p.y.abs() > 1e-6 || (n - DVec3::Y).abs().max_element() > 1e-5 || (w - DVec3::splat(weight)).abs().max_element() > 1e-5 * weight {
        return Some(format!("pixel {}: record at {p} normal {n} weight {w}: expected the floor, +y, {weight:.6}", r.pixel));
    }
    None
}

/// The knife-edge scene ([`scenes::knife_edge`]), 48², 4 iterations, chains of at most 3
/// interactions (top, bottom, floor: internal reflections end the path). Every query
/// point is on the floor with weight `ρ/π` (the radiance scalings `(1/n)²` in and `n²`
/// out cancel) and is reached from the eye, through the record's own pixel, either
/// directly beside the wedge or through its top and bottom faces by exact refraction
/// (solved back from the query point). Pixels whose centre and corners all go the same
/// way: beside the wedge, every one has a query point; through it, the share with one is
/// `(1 − F_in)(1 − F_out)` within [`SIGMAS`] binomial deviations. At least 100 of the
/// query points came through glass thinner than [`OLD_OFFSET`].
fn knife_edge(t: &mut dyn DynTracer) -> CaseResult {
    let scene: Scene = scenes::knife_edge(SIZE);
    let pin = Pinhole::new(&scene.camera);
    let wedge = Wedge::new();
    let iterations = 4;
    let settings = RenderSettings {
        method: Method::Arpa,
        photons_per_iteration: 1000,
        seed: 13,
        max_depth: 3,
        direct_lighting: false,
        ..RenderSettings::default()
    };
    t.upload_scene(&scene, &settings).ctx("upload_scene")?;
    let rho_pi = scenes::SLAB_FLOOR_ALBEDO / PI;
    let pixels = (SIZE * SIZE) as usize;
    let (mut direct, mut through, mut thin, mut none, mut skipped) = (0usize, 0usize, 0usize, 0usize, 0usize);
    let (mut through_pixels, mut through_valid, mut e_valid, mut v_valid) = (0usize, 0usize, 0.0, 0.0);
    let mut worst = 0.0f64;
    for _ in 0..iterations {
        t.iterate().ctx("iterate")?;
        let records = t.read_query_points().ctx("read_query_points")?;
        if records.len() != pixels {
            return Err(format!("{} query records for {pixels} pixels", records.len()));
        }
        for r in &records {
            if r.pixel as usize >= pixels {
                return Err(format!("query record for pixel {} outside the image", r.pixel));
            }
            let probes = pin.pixel_probes(r.pixel).map(|d| wedge.trace(pin.eye, d).0);
            let kind = |c: &Chain| match c {
                Chain::Direct => 0,
                Chain::Through { thickness, .. } if *thickness >= UNRESOLVED_THICKNESS => 1,
                Chain::Through { .. } => 2,
                Chain::Other => 3,
            };
            let class = kind(&probes[0]);
            let unambiguous = probes.iter().all(|c| kind(c) == class) && class < 2;
            if unambiguous && class == 1 {
                let Chain::Through { f_in, f_out, .. } = probes[0] else { unreachable!() };
                let p = (1.0 - f_in) * (1.0 - f_out);
                through_pixels += 1;
                through_valid += (r.valid == 1) as usize;
                e_valid += p;
                v_valid += p * (1.0 - p);
            }
            if !unambiguous {
                // A pixel straddling the knife edge or the wedge's end, or entering where
                // the glass is thinner than claimed: its rays may go either way.
                skipped += 1;
                continue;
            }
            if r.valid != 1 {
                if class == 0 {
                    return Err(format!("pixel {}: no query point, but every ray of the pixel reaches the floor beside the wedge", r.pixel));
                }
                none += 1;
                continue;
            }
            if let Some(e) = floor_record_error(r, rho_pi) {
                return Err(e);
            }
            let q = Vec3::from_array(r.position).as_dvec3();
            // The direct chain: the straight ray to q must pass beside the wedge.
            let d = (q - pin.eye).normalize();
            let direct_fit = match wedge.trace(pin.eye, d) {
                (Chain::Direct, _) => pin.film(d).map(|f| (pin.outside_pixel(f, r.pixel), f)),
                _ => None,
            }
            .filter(|&(off, _)| off <= EDGE_PIXEL_TOL);
            let centre = {
                let c = pin.pixel_probes(r.pixel)[0];
                pin.film(c).unwrap_or((0.0, 0.0))
            };
            let through_fit = through_wedge(&wedge, &pin, q, r.pixel, centre).filter(|&(off, _)| off <= EDGE_PIXEL_TOL);
            match (class, direct_fit, through_fit) {
                (0, Some((off, _)), _) => {
                    worst = worst.max(off);
                    direct += 1;
                }
                (1, _, Some((off, f))) => {
                    worst = worst.max(off);
                    through += 1;
                    if let (Chain::Through { thickness, .. }, _) = wedge.trace(pin.eye, pin.direction(f.0, f.1))
                        && thickness < OLD_OFFSET
                    {
                        thin += 1;
                    }
                }
                _ => {
                    return Err(format!(
                        "pixel {}: query point {q}: no ray through this pixel reaches it {}",
                        r.pixel,
                        if class == 0 { "beside the wedge" } else { "through the wedge" }
                    ));
                }
            }
        }
    }
    let z = (through_valid as f64 - e_valid) / v_valid.max(1e-300).sqrt();
    let msg = format!(
        "query points beside {direct}, through {through} ({thin} through glass thinner than {OLD_OFFSET:.1e} m), none {none}, pixels straddling or unresolved {skipped}; \
         through-wedge pixels {through_pixels}: {through_valid} with a query point, Fresnel expects {e_valid:.0} ({z:+.1}σ); worst traced-back ray {worst:.1e} px outside its pixel (tol {EDGE_PIXEL_TOL})"
    );
    if direct < 100 || through < 300 || thin < 100 || z.abs() > SIGMAS {
        return Err(msg);
    }
    Ok(msg)
}

