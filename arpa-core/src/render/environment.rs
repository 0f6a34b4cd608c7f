//! The environment light's radiance, and the sampling of its directions: a constant
//! radiance (Mitsuba's `constant`) or an equirectangular map (Mitsuba's `envmap`).
//!
//! **Map convention (Mitsuba 3's `envmap`).** A world direction `ω` towards the environment
//! is taken to the map's frame, `v = to_world⁻¹ ω` (normalised), and then to
//! `u = atan2(v.x, −v.z) / 2π` (wrapped into `[0, 1)`), `t = acos(v.y) / π`: `+y` is up,
//! the first row of the image is the zenith. Between texels the map is bilinear with
//! Mitsuba's grid: columns at `u = (i + ½)/W`, periodic; rows at `t = j/(H − 1)`, the first
//! and last rows exactly at the poles (a one-row map is constant in `t`).
//!
//! **Sampling.** Directions are drawn piecewise constant over the map's bilinear patches
//! (column pair `i, i+1`, row pair `j, j+1`): a patch's weight is the largest luminance of
//! its four texels times `sin θ` at its centre, so that every direction with radiance has a
//! positive density. Within a patch `(u, t)` is uniform, and the density per steradian is
//! `p(u, t) / (2π² sin θ)`. A constant environment is sampled uniformly, `1/4π`.

use crate::base::frame::Frame;
use crate::base::sampling::{cosine_hemisphere, uniform_sphere};
use crate::emit::emission::EnvironmentLight;
use crate::render::texture::{Bitmap, LUMINANCE};
use alloc::vec::Vec;
use core::f64::consts::PI;
use glam::{DMat3, DVec2, DVec3, Vec3};

/// An equirectangular environment map: the bitmap (linear RGB, its own filter, wrap and
/// `to_uv` are ignored: the map has the grid of the module docs) and its orientation.
#[derive(Clone, Debug, PartialEq)]
pub struct EnvironmentMap {
    /// Texels, first row at the zenith (`+y` of the map's frame).
    pub bitmap: Bitmap,
    /// World from the map's frame (Mitsuba's `to_world`; only its linear part is read, and
    /// it must be invertible).
    pub to_world: DMat3,
}

/// The environment of a prepared scene: its light, its map if it has one, and the map's
/// sampling tables.
#[derive(Clone, Debug, PartialEq)]
pub struct Environment {
    /// Index of the light among the scene's emitters.
    pub emitter: usize,
    /// The light (radiance, or the map's scale; the map's mean).
    pub light: EnvironmentLight,
    map: Option<MapTables>,
}

/// A map with its sampling tables.
#[derive(Clone, Debug, PartialEq)]
struct MapTables {
    width: u32,
    height: u32,
    /// Linear RGB texels, row-major.
    texels: Vec<Vec3>,
    to_world: DMat3,
    from_world: DMat3,
    /// Patch rows `max(H − 1, 1)`: cumulative weight of the rows, normalised (last entry 1).
    rows: Vec<f64>,
    /// Per patch row, cumulative weight of its `W` patches, normalised.
    columns: Vec<f64>,
    /// Per patch, its weight over the total times the patch count (the density in `(u, t)`).
    density: Vec<f64>,
}

/// Why an environment map cannot be used.
#[derive(Clone, Copy, Debug, PartialEq, Eq, thiserror::Error)]
pub enum EnvironmentError {
    /// The bitmap's sizes or texels are invalid.
    #[error("environment map: invalid bitmap (sizes or non-finite texels)")]
    Bitmap,
    /// A texel is negative.
    #[error("environment map: negative radiance")]
    Negative,
    /// Every texel is black.
    #[error("environment map: every texel is black")]
    Black,
    /// `to_world` is singular or not finite.
    #[error("environment map: to_world is not invertible")]
    Transform,
}

impl EnvironmentMap {
    /// The mean of the map over the sphere, `∫ m dω / 4π` (RGB): the bilinear patches
    /// integrated with 4 × 4 Gauss–Legendre points each in `(u, t)`, weighted by `sin θ`.
    pub fn mean(&self) -> Result<DVec3, EnvironmentError> {
        Ok(MapTables::new(self)?.mean())
    }
}

/// Gauss–Legendre nodes and weights on `[0, 1]`, 4 points.
const GAUSS4: [(f64, f64); 4] = [
    (0.069_431_844_202_973_71, 0.173_927_422_568_726_93),
    (0.330_009_478_207_571_87, 0.326_072_577_431_273_07),
    (0.669_990_521_792_428_1, 0.326_072_577_431_273_07),
    (0.930_568_155_797_026_3, 0.173_927_422_568_726_93),
];

impl EnvironmentMap {
    /// Whether the map can be sampled, without building its tables: a valid bitmap, an
    /// invertible transform, no negative texel and some light. Every patch weight is the
    /// largest luminance of its four texels times a positive `sin`, and every texel is in a
    /// patch, so the tables' total is positive exactly when some texel's luminance is.
    pub fn check(&self) -> Result<(), EnvironmentError> {
        let b = &self.bitmap;
        if !b.is_valid() {
            return Err(EnvironmentError::Bitmap);
        }
        let m = self.to_world;
        let det = m.determinant();
        if !(det.abs() > 1e-12) || !det.is_finite() || !m.is_finite() {
            return Err(EnvironmentError::Transform);
        }
        let mut lit = false;
        for i in 0..b.texels.len() {
            let t = b.texels.linear(i);
            if t.min_element() < 0.0 {
                return Err(EnvironmentError::Negative);
            }
            lit |= t.dot(LUMINANCE) > 0.0;
        }
        if !lit {
            return Err(EnvironmentError::Black);
        }
        Ok(())
    }
}

impl MapTables {
    fn new(map: &EnvironmentMap) -> Result<Self, EnvironmentError> {
        map.check()?;
        let (b, m) = (&map.bitmap, map.to_world);
        let (w, h) = (b.width, b.height);
        let texels: Vec<Vec3> = (0..b.texels.len()).map(|i| b.texels.linear(i)).collect();
        let prows = (h - 1).max(1);
        let lum = |i: u32, j: u32| texels[(j.min(h - 1) * w + i % w) as usize].dot(LUMINANCE) as f64;
        let mut density = Vec::with_capacity((w * prows) as usize);
        let mut columns = Vec::with_capacity((w * prows) as usize);
        let mut rows = Vec::with_capacity(prows as usize);
        let mut total = 0.0;
        for j in 0..prows {
            let sin = libm::sin(PI * (j as f64 + 0.5) / prows as f64);
            let mut acc = 0.0;
            for i in 0..w {
                let l = lum(i, j).max(lum(i + 1, j)).max(lum(i, j + 1)).max(lum(i + 1, j + 1));
                let weight = l * sin;
                density.push(weight);
                acc += weight;
                columns.push(acc);
            }
            let first = (j * w) as usize;
            for c in &mut columns[first..] {
                *c = if acc > 0.0 { *c / acc } else { 0.0 };
            }
            total += acc;
            rows.push(total);
        }
        if !(total > 0.0) {
            return Err(EnvironmentError::Black);
        }
        for r in &mut rows {
            *r /= total;
        }
        let patches = (w * prows) as f64;
        for d in &mut density {
            *d *= patches / total;
        }
        Ok(Self { width: w, height: h, texels, to_world: m, from_world: m.inverse(), rows, columns, density })
    }

    /// Bilinear value at `(u, t)` (module docs' grid).
    fn eval_uv(&self, u: f64, t: f64) -> DVec3 {
        let (w, h) = (self.width, self.height);
        let x = u * w as f64 - 0.5;
        let x0 = libm::floor(x);
        let fx = x - x0;
        let i = (x0 as i64).rem_euclid(w as i64) as u32;
        let y = if h > 1 { (t * (h - 1) as f64).clamp(0.0, (h - 1) as f64) } else { 0.0 };
        let j = (libm::floor(y) as u32).min(h.saturating_sub(2));
        let fy = y - j as f64;
        let at = |i: u32, j: u32| self.texels[(j.min(h - 1) * w + i % w) as usize].as_dvec3();
        let top = at(i, j) * (1.0 - fx) + at(i + 1, j) * fx;
        let bottom = at(i, j + 1) * (1.0 - fx) + at(i + 1, j + 1) * fx;
        top * (1.0 - fy) + bottom * fy
    }

    /// `(u, t)` of the world direction `d` (towards the environment).
    fn uv(&self, d: DVec3) -> DVec2 {
        let v = (self.from_world * d).normalize_or(DVec3::Y);
        let mut u = libm::atan2(v.x, -v.z) / (2.0 * PI);
        if u < 0.0 {
            u += 1.0;
        }
        DVec2::new(u.min(1.0), libm::acos(v.y.clamp(-1.0, 1.0)) / PI)
    }

    /// World direction of `(u, t)`.
    fn direction(&self, u: f64, t: f64) -> DVec3 {
        let (st, ct) = (libm::sin(PI * t), libm::cos(PI * t));
        let (sp, cp) = (libm::sin(2.0 * PI * u), libm::cos(2.0 * PI * u));
        (self.to_world * DVec3::new(st * sp, ct, -st * cp)).normalize_or(DVec3::Y)
    }

    /// The patch containing `(u, t)`.
    fn patch(&self, uv: DVec2) -> (u32, u32) {
        let (w, prows) = (self.width, (self.height - 1).max(1));
        let i = (libm::floor(uv.x * w as f64 - 0.5) as i64).rem_euclid(w as i64) as u32;
        let j = ((uv.y * prows as f64) as u32).min(prows - 1);
        (i, j)
    }

    fn pdf(&self, d: DVec3) -> f64 {
        let uv = self.uv(d);
        let (i, j) = self.patch(uv);
        let sin = libm::sin(PI * uv.y);
        if !(sin > 0.0) {
            return 0.0;
        }
        self.density[(j * self.width + i) as usize] / (2.0 * PI * PI * sin)
    }

    fn sample(&self, s: DVec2) -> (DVec3, f64) {
        let w = self.width;
        let prows = (self.height - 1).max(1);
        let j = search(&self.rows, s.y);
        let lo = if j == 0 { 0.0 } else { self.rows[j - 1] };
        let fy = ((s.y - lo) / (self.rows[j] - lo)).clamp(0.0, 1.0);
        let row = &self.columns[j * w as usize..(j + 1) * w as usize];
        let i = search(row, s.x);
        let lo = if i == 0 { 0.0 } else { row[i - 1] };
        let fx = ((s.x - lo) / (row[i] - lo)).clamp(0.0, 1.0);
        let mut u = (i as f64 + 0.5 + fx) / w as f64;
        if u >= 1.0 {
            u -= 1.0;
        }
        let t = (j as f64 + fy) / prows as f64;
        let d = self.direction(u, t);
        (d, self.pdf(d))
    }

    fn mean(&self) -> DVec3 {
        let (w, prows) = (self.width, (self.height - 1).max(1));
        let mut sum = DVec3::ZERO;
        for j in 0..prows {
            for i in 0..w {
                for (gy, wy) in GAUSS4 {
                    let t = (j as f64 + gy) / prows as f64;
                    let sin = libm::sin(PI * t);
                    for (gx, wx) in GAUSS4 {
                        let u = (i as f64 + 0.5 + gx) / w as f64;
                        sum += self.eval_uv(u, t) * (wx * wy * sin);
                    }
                }
            }
        }
        // ∫ m dω = ∫∫ m sin θ 2π² du dt; each patch spans 1/(W rows) of the (u, t) square.
        sum * (2.0 * PI * PI / (w as f64 * prows as f64) / (4.0 * PI))
    }
}

/// A map's texels and sampling tables as they are (what [`crate::gpu::texture`] lays out
/// for the device): `rows` holds the normalised cumulative weights of the `max(H − 1, 1)`
/// patch rows, `columns` per patch row those of its `W` patches, `density` per patch its
/// density in `(u, t)` (module docs).
#[derive(Clone, Copy, Debug)]
pub struct MapView<'a> {
    /// Texels per row.
    pub width: u32,
    /// Rows.
    pub height: u32,
    /// Linear RGB texels, row-major, first row at the zenith.
    pub texels: &'a [Vec3],
    /// World from the map's frame.
    pub to_world: DMat3,
    /// Its inverse.
    pub from_world: DMat3,
    /// Cumulative row weights.
    pub rows: &'a [f64],
    /// Cumulative patch weights, row after row.
    pub columns: &'a [f64],
    /// Patch densities in `(u, t)`, row after row.
    pub density: &'a [f64],
}

/// The first index whose cumulative value exceeds `x` (the last one for `x` ≥ all).
fn search(cdf: &[f64], x: f64) -> usize {
    cdf.partition_point(|&c| c <= x).min(cdf.len() - 1)
}

impl Environment {
    /// The environment of emitter `emitter`, a constant one or with `map`; the light's
    /// `mean` should be [`EnvironmentMap::mean`] for a map and 1 otherwise.
    pub fn new(emitter: usize, light: EnvironmentLight, map: Option<&EnvironmentMap>) -> Result<Self, EnvironmentError> {
        Ok(Self { emitter, light, map: map.map(MapTables::new).transpose()? })
    }

    /// The map's texels and tables; `None` for a constant environment.
    pub fn map_view(&self) -> Option<MapView<'_>> {
        self.map.as_ref().map(|m| MapView {
            width: m.width,
            height: m.height,
            texels: &m.texels,
            to_world: m.to_world,
            from_world: m.from_world,
            rows: &m.rows,
            columns: &m.columns,
            density: &m.density,
        })
    }

    /// Radiance (W/(m²·sr), RGB) arriving from world direction `d` (unit, towards the
    /// environment).
    pub fn radiance(&self, d: DVec3) -> DVec3 {
        match &self.map {
            None => self.light.radiance,
            Some(m) => {
                let uv = m.uv(d);
                self.light.radiance * m.eval_uv(uv.x, uv.y)
            }
        }
    }

    /// A direction towards the environment drawn by its radiance from the unit-square
    /// sample `s`, and its density (1/sr).
    pub fn sample(&self, s: DVec2) -> (DVec3, f64) {
        match &self.map {
            None => (uniform_sphere(s), 1.0 / (4.0 * PI)),
            Some(m) => m.sample(s),
        }
    }

    /// The density (1/sr) of [`Environment::sample`] drawing `d`.
    pub fn pdf(&self, d: DVec3) -> f64 {
        match &self.map {
            None => 1.0 / (4.0 * PI),
            Some(m) => m.pdf(d),
        }
    }

    /// A photon's direction from its draw `s`, and its flux factor `m(ω)/(4π p(ω) mean)`
    /// ([`crate::emit::emission::PreparedLight::emit_environment_in`]).
    pub fn photon_direction(&self, s: DVec2) -> (DVec3, DVec3) {
        match &self.map {
            None => (uniform_sphere(s), DVec3::ONE),
            Some(m) => {
                let (d, pdf) = m.sample(s);
                let uv = m.uv(d);
                let value = m.eval_uv(uv.x, uv.y);
                let factor = if pdf > 0.0 { value / (4.0 * PI * pdf * self.light.mean) } else { DVec3::ZERO };
                (d, DVec3::select(factor.is_finite_mask(), factor, DVec3::ZERO))
            }
        }
    }

    /// Irradiance (W/m², RGB) from the environment at a diffuse point, from one
    /// cosine-weighted draw `cosine` about the oriented shading normal `n` and, for a map,
    /// one draw `light` from [`Environment::sample`], combined by the balance heuristic. A
    /// constant environment takes the cosine draw alone (`πL` times the visibility where
    /// the shading and geometric normals agree: no noise under an open sky); the caller
    /// draws both samples either way. `cosine_of` gives the receiving cosine of a direction
    /// (0 where it gives nothing) and `visible` whether the environment is unoccluded along
    /// it.
    pub fn irradiance(&self, n: DVec3, cosine: DVec2, light: DVec2, cosine_of: impl Fn(DVec3) -> f64, mut visible: impl FnMut(DVec3) -> bool) -> DVec3 {
        let frame = Frame::from_normal(n);
        let by_cosine = crate::base::frame::unit_or(frame.to_world(cosine_hemisphere(cosine)), n);
        if self.map.is_none() {
            let cos = cosine_of(by_cosine);
            let pdf = by_cosine.dot(n).max(0.0) / PI;
            return if cos > 0.0 && pdf > 0.0 && visible(by_cosine) { self.light.radiance * (cos / pdf) } else { DVec3::ZERO };
        }
        let (by_light, _) = self.sample(light);
        let mut e = DVec3::ZERO;
        for d in [by_cosine, by_light] {
            let cos = cosine_of(d);
            if cos > 0.0 {
                let pdf = d.dot(n).max(0.0) / PI + self.pdf(d);
                if pdf > 0.0 && visible(d) {
                    e += self.radiance(d) * (cos / pdf);
                }
            }
        }
        e
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::base::rng::{Rng, StreamDomain};
    use crate::render::texture::{Texels, TextureFilter, TextureWrap, UvTransform};

    fn map(width: u32, height: u32, f: impl Fn(u32, u32) -> [f32; 3], to_world: DMat3) -> EnvironmentMap {
        let texels = (0..height).flat_map(|j| (0..width).map(move |i| (i, j))).map(|(i, j)| f(i, j)).collect();
        EnvironmentMap { bitmap: Bitmap { width, height, texels: Texels::Float(texels), filter: TextureFilter::Bilinear, wrap: TextureWrap::Repeat, to_uv: UvTransform::default() }, to_world }
    }

    fn environment(m: &EnvironmentMap) -> Environment {
        let light = EnvironmentLight { radiance: DVec3::ONE, mean: m.mean().unwrap() };
        Environment::new(0, light, Some(m)).unwrap()
    }

    /// `EnvironmentMap::check` (what scene validation runs) refuses exactly the maps the
    /// tables refuse, with the same error: a black map, one with a negative texel, a
    /// singular transform; a map lit by one texel of the last row passes both.
    #[test]
    fn check_agrees_with_the_tables() {
        let cases = [
            (map(4, 3, |_, _| [0.0; 3], DMat3::IDENTITY), Err(EnvironmentError::Black)),
            (map(4, 3, |i, j| if (i, j) == (3, 2) { [0.0, 0.0, -1.0] } else { [1.0; 3] }, DMat3::IDENTITY), Err(EnvironmentError::Negative)),
            (map(4, 3, |_, _| [1.0; 3], DMat3::from_cols(DVec3::X, DVec3::X, DVec3::Z)), Err(EnvironmentError::Transform)),
            (map(4, 3, |i, j| if (i, j) == (3, 2) { [0.0, 1e-3, 0.0] } else { [0.0; 3] }, DMat3::IDENTITY), Ok(())),
            (map(5, 1, |i, _| if i == 4 { [2.0, 0.0, 0.0] } else { [0.0; 3] }, DMat3::IDENTITY), Ok(())),
        ];
        for (k, (m, expected)) in cases.iter().enumerate() {
            assert_eq!(&m.check(), expected, "case {k}");
            assert_eq!(MapTables::new(m).map(|_| ()), *expected, "case {k}");
        }
    }

    /// The sampling density integrates to 1 over the sphere and matches the histogram of
    /// its draws; the mean equals a Monte Carlo estimate of the radiance over the sphere.
    #[test]
    fn map_sampling_is_a_density_of_its_draws() {
        let rot = DMat3::from_rotation_x(0.4) * DMat3::from_rotation_y(1.1);
        let m = map(16, 9, |i, j| [(1 + (i * 7 + j * 3) % 5) as f32 * if j == 2 && i == 5 { 40.0 } else { 1.0 }, 0.5, (j as f32) * 0.1], rot);
        let env = environment(&m);
        let mut rng = Rng::new(3, 0, 0, StreamDomain::User);
        let n = 400_000;
        let (mut pdf_mean, mut mean) = (0.0, DVec3::ZERO);
        let mut f_over_p = DVec3::ZERO;
        for _ in 0..n {
            let d = uniform_sphere(rng.next_2d());
            pdf_mean += env.pdf(d) * 4.0 * PI;
            mean += env.radiance(d);
            let (s, p) = env.sample(rng.next_2d());
            f_over_p += env.radiance(s) / p;
        }
        assert!((pdf_mean / n as f64 - 1.0).abs() < 0.01, "∫p dω = {}", pdf_mean / n as f64);
        let mc = mean / n as f64;
        let exact = env.light.mean;
        assert!(((mc - exact) / exact).abs().max_element() < 0.01, "{mc} vs {exact}");
        // Importance-sampled: ∫ L dω / 4π again.
        let is = f_over_p / n as f64 / (4.0 * PI);
        assert!(((is - exact) / exact).abs().max_element() < 0.01, "{is} vs {exact}");
    }

    /// The map's directions follow Mitsuba's convention: the first row is `+y` of the
    /// map's frame, the middle column of the middle row faces `+z` ... checked by the
    /// round trip `(u, t) → ω → (u, t)` and two fixed directions.
    #[test]
    fn map_directions_follow_mitsuba() {
        let m = map(8, 5, |i, _| [i as f32, 0.0, 0.0], DMat3::IDENTITY);
        let t = MapTables::new(&m).unwrap();
        for (u, v) in [(0.1, 0.3), (0.75, 0.5), (0.999, 0.9)] {
            let uv = t.uv(t.direction(u, v));
            assert!((uv - DVec2::new(u, v)).abs().max_element() < 1e-12, "{uv:?}");
        }
        // u = 0 looks along −z, u = 1/4 along +x; t = 0 is +y.
        assert!((t.direction(0.0, 0.5) - DVec3::new(0.0, 0.0, -1.0)).length() < 1e-12);
        assert!((t.direction(0.25, 0.5) - DVec3::X).length() < 1e-12);
        assert!((t.direction(0.3, 0.0) - DVec3::Y).length() < 1e-12);
        // Column i's centre sits at u = (i + ½)/W: the value there is i.
        assert!((t.eval_uv(3.5 / 8.0, 0.4).x - 3.0).abs() < 1e-6);
    }

    /// A constant environment's irradiance on an unoccluded plane is πL (exactly, by its
    /// cosine draw); a map's, a tilted bright patch, matches an estimate with many more
    /// uniform draws (the balance heuristic is unbiased).
    #[test]
    fn constant_irradiance_is_pi_l() {
        let env = Environment::new(0, EnvironmentLight { radiance: DVec3::new(0.5, 1.0, 2.0), mean: DVec3::ONE }, None).unwrap();
        let n = DVec3::new(0.2, 0.3, 0.9).normalize();
        let mut rng = Rng::new(9, 0, 0, StreamDomain::User);
        let mut e = DVec3::ZERO;
        let count = 200_000;
        for _ in 0..count {
            e += env.irradiance(n, rng.next_2d(), rng.next_2d(), |d| d.dot(n).max(0.0), |_| true);
        }
        let e = e / count as f64;
        let exact = DVec3::new(0.5, 1.0, 2.0) * PI;
        assert!(((e - exact) / exact).abs().max_element() < 1e-9, "{e} vs {exact}");
        let m = map(12, 7, |i, j| if (i, j) == (3, 2) { [50.0, 20.0, 5.0] } else { [0.3, 0.4, 0.5] }, DMat3::from_rotation_z(0.3));
        let env = environment(&m);
        let (mut mis, mut uniform) = (DVec3::ZERO, DVec3::ZERO);
        for _ in 0..count {
            mis += env.irradiance(n, rng.next_2d(), rng.next_2d(), |d| d.dot(n).max(0.0), |_| true);
            for _ in 0..8 {
                let d = uniform_sphere(rng.next_2d());
                uniform += env.radiance(d) * d.dot(n).max(0.0) * 4.0 * PI;
            }
        }
        let (mis, uniform) = (mis / count as f64, uniform / (8 * count) as f64);
        assert!(((mis - uniform) / uniform).abs().max_element() < 0.02, "{mis} vs {uniform}");
    }
}
