//! A point light, a small tilted plane mirror and a diffuse floor in an open scene
//! ([`scenes::open_mirror`]), rendered with projection off and on
//! ([`arpa_core::render::tracer::EmissionStrategy`]). The mirror subtends about 1 % of the light's
//! sphere of directions, so this is the scene projection exists for: without it 99 % of
//! the photons never meet the mirror. Whatever the strategy, the caustic must be the
//! image source's light through the mirror's square, carry the flux the mirror
//! intercepts, and the two images must agree within their noise.
//!
//! Direct lighting is on and paths have at most 2 interactions, so the image is the
//! camera pass's next-event estimate plus the caustic map's `L S D` photons and nothing
//! else (a photon that hits the floor first is not stored, and after the floor it can
//! reach at most the mirror). The query records carry the next-event part
//! (`QueryRecord::radiance`), so each pixel's caustic part is its image value minus that,
//! and it is compared with the image source's irradiance in closed form.

use std::f64::consts::PI;

use arpa_core::store::footprint::{PackedFootprint, PhotonMap};
use arpa_core::glam::{DVec3, Vec3};
use arpa_core::accumulate::radius::{ProgressiveConfig, RadiusSpec};
use arpa_core::render::scene::Scene;
use arpa_core::render::tracer::{EmissionStrategy, Method, RenderSettings};

use super::camera::SIGMAS;
use crate::dyn_tracer::DynTracer;
use crate::scenes::{self, MIRROR_REFLECTANCE, OPEN_FLOOR_ALBEDO, OPEN_INTENSITY, OPEN_LIGHT};
use crate::suite::{CaseResult, Context};

/// Image side (pixels): every pixel's query point is an estimate of its own, and the
/// patch means average them.
pub const OPEN_SIZE: u32 = 48;
/// Photons per iteration (about 2 300 of them reach the mirror without projection).
pub const OPEN_PHOTONS: u32 = 200_000;
/// Iterations per strategy: each is an independent estimate (its own lattice shift), and
/// their spread is the noise estimate.
pub const OPEN_ITERATIONS: u32 = 8;
/// Initial caustic radius (m), 4× the default, as in the other specular cases: the
/// footprints are dampened towards its diameter, so each query point is covered by more
/// of them and its estimate is less noisy. Their semi-axes must stay below
/// [`OPEN_EDGE_MARGIN`] (checked), and the smoothing bias they cause, bounded by the
/// caustic's curvature (`λ a²/4`, see [`open_mirror`]), stays far inside the tolerance.
pub const OPEN_CAUSTIC_RADIUS: f64 = 0.04;
/// Largest error of a patch mean of the caustic against the image source (percent).
pub const OPEN_TOL_PERCENT: f64 = 2.0;
/// Largest error of the caustic flux on the floor against `I R Ω` (percent): the
/// footprints carry each photon's flux exactly, so only the count of lattice photons
/// that hit the mirror varies.
pub const OPEN_FLUX_TOL_PERCENT: f64 = 1.0;
/// Query points closer than this to the caustic's edge on the floor (m), inside or out,
/// are in no region. Every caustic footprint's semi-major axis must be shorter (checked),
/// so a point this far inside is covered by every footprint that would cover it on an
/// unbounded caustic, and a point this far outside by none.
pub const OPEN_EDGE_MARGIN: f64 = 0.06;
/// Largest relative error of a query point's next-event radiance against `ρ/π · I cos θ/d²`
/// (`f32` positions and sums).
pub const OPEN_DIRECT_TOL: f64 = 1e-4;
/// The patch names: quadrants of the mirror (`s`, `t` along its edges `p₁ − p₀`, `p₃ − p₀`)
/// whose light lands at least [`OPEN_EDGE_MARGIN`] inside the caustic's edge.
const PATCHES: [&str; 4] = ["s<½ t<½", "s>½ t<½", "s<½ t>½", "s>½ t>½"];

/// The scene's light, mirror and caustic in `f64`, from the scene's own `f32` vertices.
struct Geometry {
    /// Mirror corners `p₀ … p₃` (the parallelogram's vertices).
    corners: [DVec3; 4],
    /// Unit normal of the mirror, towards the light.
    normal: DVec3,
    /// The light mirrored in the mirror's plane.
    image: DVec3,
    /// The caustic's corners on the floor `(x, z)`, counter-clockwise.
    polygon: [(f64, f64); 4],
}

impl Geometry {
    fn new(scene: &Scene) -> Result<Self, String> {
        let mesh = scene
            .meshes
            .get(1)
            .filter(|m| m.positions.len() == 4)
            .ok_or("the scene's mesh 1 is not the mirror quad")?;
        let corners: [DVec3; 4] = std::array::from_fn(|i| mesh.positions[i].as_dvec3());
        let normal = (corners[1] - corners[0])
            .cross(corners[3] - corners[0])
            .normalize();
        let height = (OPEN_LIGHT - corners[0]).dot(normal);
        if height <= 0.0 || height.is_nan() {
            return Err("the mirror faces away from the light".into());
        }
        let image = OPEN_LIGHT - normal * (2.0 * height);
        let mut polygon = corners.map(|c| {
            let f = image + (c - image) * (image.y / (image.y - c.y));
            (f.x, f.z)
        });
        let area2: f64 = (0..4)
            .map(|i| polygon[i].0 * polygon[(i + 1) % 4].1 - polygon[(i + 1) % 4].0 * polygon[i].1)
            .sum();
        if area2 < 0.0 {
            polygon.reverse();
        }
        Ok(Self {
            corners,
            normal,
            image,
            polygon,
        })
    }

    /// Mirror coordinates `(s, t)` of the point where the segment `from → q` crosses the
    /// mirror's plane (`[0, 1]²` is the mirror), or `None` if it does not cross it.
    fn crossing(&self, from: DVec3, q: DVec3) -> Option<(f64, f64)> {
        let p0 = self.corners[0];
        let (a, b) = (self.corners[1] - p0, self.corners[3] - p0);
        let s = (p0 - from).dot(self.normal) / (q - from).dot(self.normal);
        if !(s > 0.0 && s < 1.0) {
            return None;
        }
        let m = from + (q - from) * s - p0;
        let den = a.cross(b).dot(self.normal);
        Some((
            m.cross(b).dot(self.normal) / den,
            a.cross(m).dot(self.normal) / den,
        ))
    }

    /// Point-source irradiance `I cos θ / d²` on the floor (normal `+y`) at `q` from `src`.
    fn point(src: DVec3, q: DVec3) -> f64 {
        let d = src - q;
        OPEN_INTENSITY * (d.y / d.length()) / d.length_squared()
    }

    /// Caustic irradiance (W/m²) at floor point `q`: the image source's `I R cos θ'/r'²`
    /// where the segment from the image source to `q` crosses the mirror's square, else 0.
    fn caustic(&self, q: DVec3) -> f64 {
        match self.crossing(self.image, q) {
            Some((s, t)) if (0.0..=1.0).contains(&s) && (0.0..=1.0).contains(&t) => {
                MIRROR_REFLECTANCE * Self::point(self.image, q)
            }
            _ => 0.0,
        }
    }

    /// Direct irradiance (W/m²) at floor point `q`: `I cos θ/d²` unless the mirror
    /// shadows `q`.
    fn direct(&self, q: DVec3) -> f64 {
        match self.crossing(OPEN_LIGHT, q) {
            Some((s, t)) if (0.0..=1.0).contains(&s) && (0.0..=1.0).contains(&t) => 0.0,
            _ => Self::point(OPEN_LIGHT, q),
        }
    }

    /// Signed distance (m) of floor point `q` from the caustic's edge: the least distance
    /// to the lines of its four edges, positive inside. Inside it is the distance to the
    /// edge; outside, the distance is at least its magnitude.
    fn edge_distance(&self, q: DVec3) -> f64 {
        (0..4)
            .map(|i| {
                let (a, b) = (self.polygon[i], self.polygon[(i + 1) % 4]);
                let (ex, ez) = (b.0 - a.0, b.1 - a.1);
                (ex * (q.z - a.1) - ez * (q.x - a.0)) / ex.hypot(ez)
            })
            .fold(f64::INFINITY, f64::min)
    }

    /// How far (m) the caustic's corners lie inside the square of floor the camera sees
    /// (it looks straight down with a square image): the caustic, with every footprint
    /// blurred across its edge, must lie in the view for the image mean to hold all of
    /// its flux.
    fn view_margin(&self, scene: &Scene) -> f64 {
        let cam = &scene.camera;
        let half = cam.position.y as f64 * (0.5 * cam.vertical_fov as f64).tan();
        let (cx, cz) = (cam.position.x as f64, cam.position.z as f64);
        self.polygon
            .iter()
            .map(|&(x, z)| (half - (x - cx).abs()).min(half - (z - cz).abs()))
            .fold(f64::INFINITY, f64::min)
    }

    /// A bound on the caustic's relative curvature (1/m²): the largest eigenvalue of the
    /// floor Hessian of `cos θ'/r'²` over its value is at most `12/ĥ²`, `ĥ` the image
    /// source's height (the radial second derivative of `ĥ/(ĥ² + ρ²)^{3/2}`).
    fn curvature_bound(&self) -> f64 {
        12.0 / (self.image.y * self.image.y)
    }

    /// Solid angle (sr) of the mirror seen from the light: its two triangles by Van
    /// Oosterom and Strackee's formula.
    fn solid_angle(&self) -> f64 {
        let tri = |p: [DVec3; 3]| {
            let [a, b, c] = p.map(|v| v - OPEN_LIGHT);
            let (la, lb, lc) = (a.length(), b.length(), c.length());
            let num = a.dot(b.cross(c)).abs();
            let den = la * lb * lc + a.dot(b) * lc + a.dot(c) * lb + b.dot(c) * la;
            2.0 * num.atan2(den)
        };
        let [p0, p1, p2, p3] = self.corners;
        tri([p0, p1, p2]) + tri([p0, p2, p3])
    }
}

/// Flux (W, grey) of a footprint: its density `Φ · 4/|D_u × D_v|` times the ellipse's
/// `|D_u × D_v|/4`, which is `1/|row_u × row_v|`; and its semi-major axis on the floor (m),
/// `1/σ_min` of the filter rows restricted to the floor's `(x, z)`.
fn footprint_flux_and_axis(f: &PackedFootprint) -> (f64, f64) {
    let (u, v) = (
        Vec3::from_array(f.row_u).as_dvec3(),
        Vec3::from_array(f.row_v).as_dvec3(),
    );
    let flux = f.flux_density_r as f64 / u.cross(v).length();
    // MᵀM of M = [[u.x, u.z], [v.x, v.z]]: its smaller eigenvalue is σ_min².
    let (p, q, r) = (
        u.x * u.x + v.x * v.x,
        u.x * u.z + v.x * v.z,
        u.z * u.z + v.z * v.z,
    );
    let lo = 0.5 * (p + r) - (0.25 * (p - r) * (p - r) + q * q).sqrt();
    (flux, 1.0 / lo.max(0.0).sqrt())
}

/// The larger of `a` and `b`, or infinity if `b` is NaN (`f64::max` would drop it).
fn worse(a: f64, b: f64) -> f64 {
    if b.is_nan() { f64::INFINITY } else { a.max(b) }
}

/// Mean and standard error of the mean of independent estimates.
fn mean_se(x: &[f64]) -> (f64, f64) {
    let n = x.len() as f64;
    let m = x.iter().sum::<f64>() / n;
    let var = x.iter().map(|v| (v - m) * (v - m)).sum::<f64>() / (n - 1.0).max(1.0);
    (m, (var / n).sqrt())
}

/// What one strategy's render measured.
struct Run {
    /// Per patch: caustic image over image source, summed over all iterations.
    ratio: [f64; 4],
    /// Per patch: standard error of `ratio` from the iterations' spread.
    se: [f64; 4],
    /// Per patch: its query points (over all iterations).
    count: [usize; 4],
    /// Per iteration: mean over the whole image of the photons' part (every pixel's value
    /// minus its next-event part).
    image_means: Vec<f64>,
    /// Mean caustic radiance of the query points beside the caustic.
    beside: f64,
    /// Query points beside the caustic.
    beside_count: usize,
    /// Mean expected caustic radiance of the query points inside it.
    inside_expected: f64,
    /// Per iteration: caustic flux on the floor (W).
    flux: Vec<f64>,
    /// Largest semi-major axis of a caustic footprint (m).
    axis: f64,
    /// Largest relative error of a query point's next-event radiance.
    direct: f64,
    /// Global-map records (must be none).
    global: usize,
    /// Photons emitted in the last iteration, `[caustic pass, global pass]`.
    emitted: [u64; 2],
}

/// Renders the scene with `emission` for [`OPEN_ITERATIONS`] iterations and measures it.
fn render(
    t: &mut dyn DynTracer,
    scene: &Scene,
    geo: &Geometry,
    emission: EmissionStrategy,
) -> Result<Run, String> {
    let settings = RenderSettings {
        method: Method::Arpa,
        photons_per_iteration: OPEN_PHOTONS,
        seed: 23,
        max_depth: 2,
        direct_lighting: true,
        emission,
        radii: ProgressiveConfig {
            caustic: RadiusSpec::Absolute(OPEN_CAUSTIC_RADIUS),
            ..ProgressiveConfig::default()
        },
        ..RenderSettings::default()
    };
    t.upload_scene(scene, &settings).ctx("upload_scene")?;
    let pixels = (scene.camera.width * scene.camera.height) as usize;
    let rho_pi = OPEN_FLOOR_ALBEDO / PI;
    let mut prev = vec![0.0f64; pixels];
    let (mut num, mut den) = (
        [[0.0f64; 4]; OPEN_ITERATIONS as usize],
        [[0.0f64; 4]; OPEN_ITERATIONS as usize],
    );
    let mut run = Run {
        ratio: [0.0; 4],
        se: [0.0; 4],
        count: [0; 4],
        image_means: Vec::new(),
        beside: 0.0,
        beside_count: 0,
        inside_expected: 0.0,
        flux: Vec::new(),
        axis: 0.0,
        direct: 0.0,
        global: 0,
        emitted: [0; 2],
    };
    let mut inside_count = 0usize;
    for k in 0..OPEN_ITERATIONS as usize {
        t.iterate().ctx("iterate")?;
        let records = t.read_query_points().ctx("read_query_points")?;
        let image = t.read_image().ctx("read_image")?;
        if records.len() != pixels || image.pixels.len() != pixels {
            return Err(format!(
                "{} query records and {} pixels for a {pixels}-pixel image",
                records.len(),
                image.pixels.len()
            ));
        }
        super::analytic::check_grey(&image)?;
        // This iteration's own image from the running means.
        let now: Vec<f64> = image.pixels.iter().map(|p| p.x as f64).collect();
        let this: Vec<f64> = now
            .iter()
            .zip(&prev)
            .map(|(a, b)| (k + 1) as f64 * a - k as f64 * b)
            .collect();
        prev = now;
        let mut photon_part = 0.0;
        for r in &records {
            let p = r.pixel as usize;
            if p >= pixels {
                return Err(format!("query record for pixel {p} outside the image"));
            }
            let q = Vec3::from_array(r.position).as_dvec3();
            let n = Vec3::from_array(r.normal).as_dvec3();
            let w = r.weight[0] as f64;
            if r.valid != 1
                || q.y.abs() > 1e-6
                || (n - DVec3::Y).abs().max_element() > 1e-5
                || (w - rho_pi).abs() > 1e-5 * rho_pi
            {
                return Err(format!(
                    "pixel {p}: record {r:?}: every camera ray must reach the floor directly, weight ρ/π = {rho_pi:.6}"
                ));
            }
            let direct = w * geo.direct(q);
            let error = (r.radiance[0] as f64 - direct).abs() / direct.max(f64::MIN_POSITIVE);
            run.direct = worse(run.direct, error);
            let caustic = this[p] - r.radiance[0] as f64;
            photon_part += caustic;
            let d = geo.edge_distance(q);
            if d >= OPEN_EDGE_MARGIN {
                let Some((s, t)) = geo.crossing(geo.image, q) else {
                    return Err(format!("{q} inside the caustic but not behind the mirror"));
                };
                let j = (s >= 0.5) as usize + 2 * (t >= 0.5) as usize;
                num[k][j] += caustic;
                den[k][j] += w * geo.caustic(q);
                run.count[j] += 1;
                run.inside_expected += w * geo.caustic(q);
                inside_count += 1;
            } else if d <= -OPEN_EDGE_MARGIN {
                run.beside += caustic;
                run.beside_count += 1;
            }
        }
        run.image_means.push(photon_part / pixels as f64);
        let mut flux = 0.0;
        for f in t.read_footprints().ctx("read_footprints")? {
            if f.photon_map() != PhotonMap::Caustic {
                run.global += 1;
                continue;
            }
            let (phi, axis) = footprint_flux_and_axis(&f);
            flux += phi;
            run.axis = worse(run.axis, axis);
        }
        for ph in t.read_photons().ctx("read_photons")? {
            match PhotonMap::from_index(ph.map) {
                PhotonMap::Caustic => flux += ph.flux[0] as f64,
                PhotonMap::Global => run.global += 1,
            }
        }
        run.flux.push(flux);
        run.emitted = t.read_stats().ctx("read_stats")?.emitted;
    }
    let total = |a: &[[f64; 4]], j: usize| a.iter().map(|x| x[j]).sum::<f64>();
    run.ratio = std::array::from_fn(|j| total(&num, j) / total(&den, j));
    run.se = std::array::from_fn(|j| {
        let per_iteration: Vec<f64> = num.iter().zip(&den).map(|(n, d)| n[j] / d[j]).collect();
        mean_se(&per_iteration).1
    });
    run.beside /= run.beside_count.max(1) as f64;
    run.inside_expected /= inside_count.max(1) as f64;
    Ok(run)
}

/// Checks one strategy's run against the closed forms; the findings and whether all held.
fn judge(name: &str, run: &Run, expected_flux: f64) -> (String, bool) {
    let mut ok = true;
    let mut parts = Vec::new();
    for (j, name) in PATCHES.iter().enumerate() {
        let e = (run.ratio[j] - 1.0) * 100.0;
        let se = run.se[j] * 100.0;
        // The tolerance must be SIGMAS standard errors wide, or a pass would say nothing.
        ok &= run.count[j] >= 20 && e.abs() < OPEN_TOL_PERCENT && se * SIGMAS < OPEN_TOL_PERCENT;
        parts.push(format!("{name} {e:+.2}%±{se:.2} ({} pts)", run.count[j]));
    }
    let (flux, flux_se) = mean_se(&run.flux);
    let flux_err = (flux / expected_flux - 1.0) * 100.0;
    ok &= flux_err.abs() < OPEN_FLUX_TOL_PERCENT;
    let beside = run.beside / run.inside_expected * 100.0;
    ok &= run.beside_count >= 20 && beside.abs() < OPEN_TOL_PERCENT;
    ok &= run.axis < OPEN_EDGE_MARGIN && run.direct < OPEN_DIRECT_TOL && run.global == 0;
    let msg = format!(
        "{name}: patches {}; beside {beside:+.3}% of the inside mean ({} pts); caustic flux {flux:.5} W ±{:.5} vs I R Ω {expected_flux:.5} W ({flux_err:+.2}%, tol ±{OPEN_FLUX_TOL_PERCENT}%); \
         largest footprint semi-axis {:.3} m (margin {OPEN_EDGE_MARGIN}); direct worst {:.1e} (tol {OPEN_DIRECT_TOL:.0e}); global records {}; emitted caustic/global {}/{}",
        parts.join(", "),
        run.beside_count,
        flux_se,
        run.axis,
        run.direct,
        run.global,
        run.emitted[0],
        run.emitted[1],
    );
    (msg, ok)
}

/// The open-mirror case, rendered with projection off, then on. Each strategy: every
/// patch mean of the caustic (image minus next-event part) within [`OPEN_TOL_PERCENT`]
/// of the image source's irradiance, with a standard error small enough that the
/// tolerance spans [`SIGMAS`] of them (else the pass would say nothing); nothing beside
/// the caustic; the caustic flux on the floor within [`OPEN_FLUX_TOL_PERCENT`] of `I R Ω`
/// (Ω: the mirror's solid angle from the light), which fails if projection drops or
/// double-counts caustic photons or weights them by the wrong share of the light's power;
/// no global record; the next-event radiance exact. Then the strategies agree: the mean
/// of the image's photon part within [`SIGMAS`] standard errors of the difference, and
/// each patch mean within as many beyond the smoothing bias the footprints' sizes allow.
/// The standard errors come from the spread of the [`OPEN_ITERATIONS`] per-iteration
/// estimates (independent lattice shifts); the two strategies' noise is independent.
pub fn open_mirror(t: &mut dyn DynTracer) -> CaseResult {
    let scene = scenes::open_mirror(OPEN_SIZE);
    let geo = Geometry::new(&scene)?;
    let expected_flux = OPEN_INTENSITY * MIRROR_REFLECTANCE * geo.solid_angle();
    let off = render(t, &scene, &geo, EmissionStrategy::WHOLE_DOMAIN)?;
    let on = render(t, &scene, &geo, EmissionStrategy::default())?;
    let (off_msg, off_ok) = judge("projection off", &off, expected_flux);
    let (on_msg, on_ok) = judge("projection on", &on, expected_flux);
    // Footprints of semi-major axis `a` smooth the caustic with a relative bias of at most
    // `λ a²/4` (λ: the curvature bound; the kernel's `⟨r²⟩ ≤ a²/2`), and the strategies may
    // store footprints of different sizes: their patch means may differ by that much
    // besides noise.
    let allowance = geo.curvature_bound() / 4.0 * (off.axis * off.axis + on.axis * on.axis);
    let worst = (0..4)
        .map(|j| {
            let beyond = ((on.ratio[j] - off.ratio[j]).abs() - allowance).max(0.0);
            beyond / off.se[j].hypot(on.se[j]).max(1e-300)
        })
        .fold(0.0, worse);
    // The photons' part of the image (the next-event part is the same for both strategies,
    // which share the camera paths) has a mean with no smoothing bias: footprints move
    // flux, they do not make or lose it, as long as the caustic and its footprints lie in
    // the view (checked).
    let view = geo.view_margin(&scene);
    let ((m_off, se_off), (m_on, se_on)) = (mean_se(&off.image_means), mean_se(&on.image_means));
    let z_image = (m_on - m_off) / se_off.hypot(se_on).max(1e-300);
    let same = worst < SIGMAS && z_image.abs() < SIGMAS && view > off.axis.max(on.axis);
    let msg = format!(
        "{off_msg}; {on_msg}; on vs off: mean photon part of the image {m_on:.5} vs {m_off:.5} ({z_image:+.1}σ; caustic {view:.3} m inside the view), \
         largest patch difference beyond the smoothing allowance {:.2}% {worst:.1}σ (tol {SIGMAS}σ); \
         tol ±{OPEN_TOL_PERCENT}%, {OPEN_ITERATIONS}×{OPEN_PHOTONS} photons, {OPEN_SIZE}² px",
        allowance * 100.0
    );
    if off_ok && on_ok && same {
        Ok(msg)
    } else {
        Err(msg)
    }
}
