//! Exact geometric optics of the suite's specular scenes, written here independently of
//! `arpa-core`'s camera and photon paths: the pinhole projection, the image of a point in
//! a plane mirror, the chains through a parallel glass slab and the Fresnel reflectance.
//! All in `f64`, metres and radians.

use arpa_core::glam::DVec3;
use arpa_core::render::scene::Camera;

/// The pinhole of [`Camera`] as documented there: `forward = target − position`, `right =
/// forward × up`, `up' = right × forward`, vertical field of view, film position `(0, 0)`
/// at the top-left corner, `x` to the right and `y` down, in pixels.
#[derive(Clone, Copy, Debug)]
pub struct Pinhole {
    /// Eye (m).
    pub eye: DVec3,
    forward: DVec3,
    right: DVec3,
    up: DVec3,
    tan_half: f64,
    aspect: f64,
    /// Image width (px).
    pub width: u32,
    /// Image height (px).
    pub height: u32,
}

impl Pinhole {
    /// The pinhole of `camera`.
    pub fn new(camera: &Camera) -> Self {
        let eye = camera.position.as_dvec3();
        let forward = (camera.target.as_dvec3() - eye).normalize();
        let right = forward.cross(camera.up.as_dvec3()).normalize();
        let up = right.cross(forward);
        Self {
            eye,
            forward,
            right,
            up,
            tan_half: (0.5 * camera.vertical_fov as f64).tan(),
            aspect: camera.width as f64 / camera.height as f64,
            width: camera.width,
            height: camera.height,
        }
    }

    /// Film position (px) of the ray leaving the eye along `d`; `None` behind the eye.
    pub fn film(&self, d: DVec3) -> Option<(f64, f64)> {
        let f = d.dot(self.forward);
        if f <= 0.0 {
            return None;
        }
        let sx = d.dot(self.right) / f / (self.tan_half * self.aspect);
        let sy = d.dot(self.up) / f / self.tan_half;
        Some((
            (sx + 1.0) * 0.5 * self.width as f64,
            (1.0 - sy) * 0.5 * self.height as f64,
        ))
    }

    /// Unit direction through film position `(x, y)` (px).
    pub fn direction(&self, x: f64, y: f64) -> DVec3 {
        let sx = (2.0 * x / self.width as f64 - 1.0) * self.tan_half * self.aspect;
        let sy = (1.0 - 2.0 * y / self.height as f64) * self.tan_half;
        (self.forward + self.right * sx + self.up * sy).normalize()
    }

    /// How far (px, 0 inside) film position `(x, y)` lies outside pixel `pixel` (row-major).
    pub fn outside_pixel(&self, (x, y): (f64, f64), pixel: u32) -> f64 {
        let (px, py) = ((pixel % self.width) as f64, (pixel / self.width) as f64);
        let dx = (px - x).max(x - (px + 1.0)).max(0.0);
        let dy = (py - y).max(y - (py + 1.0)).max(0.0);
        dx.max(dy)
    }

    /// The centre and four corners of pixel `pixel` as ray directions.
    pub fn pixel_probes(&self, pixel: u32) -> [DVec3; 5] {
        let (px, py) = ((pixel % self.width) as f64, (pixel / self.width) as f64);
        [
            self.direction(px + 0.5, py + 0.5),
            self.direction(px, py),
            self.direction(px + 1.0, py),
            self.direction(px, py + 1.0),
            self.direction(px + 1.0, py + 1.0),
        ]
    }
}

/// Unpolarised Fresnel reflectance of a smooth interface between indices `n1` (incident
/// side) and `n2` at incidence angle `theta_i` (1 under total internal reflection).
pub fn fresnel(n1: f64, n2: f64, theta_i: f64) -> f64 {
    let sin_t = n1 / n2 * theta_i.sin();
    if sin_t >= 1.0 {
        return 1.0;
    }
    let (ci, ct) = (theta_i.cos(), (1.0 - sin_t * sin_t).sqrt());
    let rs = (n1 * ci - n2 * ct) / (n1 * ci + n2 * ct);
    let rp = (n2 * ci - n1 * ct) / (n2 * ci + n1 * ct);
    0.5 * (rs * rs + rp * rp)
}

/// Horizontal distance travelled from a point at height `air` above a parallel slab of
/// thickness `t` and index `n` (plus `below` from the slab to the floor) to the floor,
/// entering at angle `theta` from the normal and crossing the slab `crossings` times
/// (1 + 2 per pair of internal reflections).
pub fn slab_offset(theta: f64, air: f64, below: f64, t: f64, n: f64, crossings: u32) -> f64 {
    let theta_t = (theta.sin() / n).asin();
    (air + below) * theta.tan() + crossings as f64 * t * theta_t.tan()
}

/// `d slab_offset / dθ` (m/rad).
pub fn slab_offset_derivative(
    theta: f64,
    air: f64,
    below: f64,
    t: f64,
    n: f64,
    crossings: u32,
) -> f64 {
    let theta_t = (theta.sin() / n).asin();
    let c = theta.cos();
    let ct = theta_t.cos();
    (air + below) / (c * c) + crossings as f64 * t / (ct * ct) * (c / (n * ct))
}

/// The entry angle `θ ∈ [0, π/2)` whose [`slab_offset`] is `rho` (bisection; the offset
/// grows monotonically with θ).
pub fn slab_entry_angle(rho: f64, air: f64, below: f64, t: f64, n: f64, crossings: u32) -> f64 {
    let (mut lo, mut hi) = (0.0f64, std::f64::consts::FRAC_PI_2 - 1e-9);
    for _ in 0..80 {
        let mid = 0.5 * (lo + hi);
        if slab_offset(mid, air, below, t, n, crossings) < rho {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    0.5 * (lo + hi)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fresnel_known_values() {
        // Normal incidence ((n−1)/(n+1))² and symmetry of the two sides of one pair of angles.
        assert!((fresnel(1.0, 1.5, 0.0) - 0.04).abs() < 1e-12);
        let ti = 0.6f64;
        let tt = (ti.sin() / 1.5).asin();
        assert!((fresnel(1.0, 1.5, ti) - fresnel(1.5, 1.0, tt)).abs() < 1e-12);
        assert_eq!(fresnel(1.5, 1.0, 1.2), 1.0);
    }

    #[test]
    fn slab_inversion_and_derivative() {
        for rho in [0.0, 0.3, 1.7] {
            let th = slab_entry_angle(rho, 2.0, 0.5, 1.0, 1.5, 3);
            assert!((slab_offset(th, 2.0, 0.5, 1.0, 1.5, 3) - rho).abs() < 1e-9);
        }
        let (th, h) = (0.4, 1e-6);
        let fd = (slab_offset(th + h, 1.0, 0.5, 1.0, 1.5, 1)
            - slab_offset(th - h, 1.0, 0.5, 1.0, 1.5, 1))
            / (2.0 * h);
        assert!((fd / slab_offset_derivative(th, 1.0, 0.5, 1.0, 1.5, 1) - 1.0).abs() < 1e-7);
    }

    #[test]
    fn pinhole_round_trip() {
        let cam = crate::scenes::camera(
            arpa_core::glam::Vec3::new(0.0, 1.0, 2.0),
            arpa_core::glam::Vec3::ZERO,
            arpa_core::glam::Vec3::Y,
            40.0,
            20,
        );
        let p = Pinhole::new(&cam);
        let (x, y) = p.film(p.direction(3.25, 17.5)).unwrap();
        assert!((x - 3.25).abs() < 1e-9 && (y - 17.5).abs() < 1e-9);
        // Top-left is up and to the left.
        let d = p.direction(0.0, 0.0);
        assert!(d.y > p.direction(10.0, 10.0).y && d.x < 0.0);
        assert_eq!(p.outside_pixel((3.5, 17.5), 17 * 20 + 3), 0.0);
        assert!((p.outside_pixel((4.5, 17.5), 17 * 20 + 3) - 0.5).abs() < 1e-12);
    }
}
