//! Progressive (PPM) photons: the fallback for footprints the heuristics reject, and the
//! only photon kind of the RTPM baseline. A progressive photon is a disc of the map's
//! current progressive radius `r_i` with the constant kernel `1/(π r_i²)` (Knaus & Zwicker;
//! RTPM's sphere test `|q − x_p|² < r_i²`).

use crate::store::footprint::PhotonMap;
use glam::{DVec3, Vec3};

/// A progressive photon in double precision.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ProgressivePhoton {
    /// Hit position (metres).
    pub position: DVec3,
    /// Unit surface normal oriented towards the side the photon arrived from.
    pub normal: DVec3,
    /// Flux (W, RGB).
    pub flux: DVec3,
    /// Map it belongs to.
    pub map: PhotonMap,
}

impl ProgressivePhoton {
    /// The progressive photon a rejected footprint becomes: at its centre, with its
    /// normal, flux and map (what [`crate::store::decision::store_footprint`] stores for it).
    pub fn from_footprint(fp: &crate::store::footprint::Footprint) -> Self {
        Self { position: fp.center, normal: fp.normal, flux: fp.flux, map: fp.map }
    }

    /// Irradiance (W/m², RGB) at `q` (metres) with unit normal `query_normal` for
    /// progressive radius `radius` (metres), in `f64`: `Φ/(π r²)` inside the sphere
    /// `|q − x_p|² < r²` and on the lit side, else 0 (also 0 when not finite). The `f64`
    /// twin of [`PackedPhoton::irradiance`].
    pub fn irradiance(&self, q: DVec3, query_normal: DVec3, radius: f64) -> DVec3 {
        let inside = (q - self.position).length_squared() < radius * radius;
        if !inside || !(self.normal.dot(query_normal) > 0.0) {
            return DVec3::ZERO;
        }
        let e = self.flux * (core::f64::consts::FRAC_1_PI / (radius * radius));
        if e.is_finite() { e } else { DVec3::ZERO }
    }

    /// The 48-byte `f32` record (see [`PackedPhoton`]).
    pub fn pack(&self) -> PackedPhoton {
        PackedPhoton {
            position: self.position.as_vec3().to_array(),
            map: self.map as u32,
            normal: self.normal.as_vec3().to_array(),
            _pad0: 0,
            flux: self.flux.as_vec3().to_array(),
            _pad1: 0,
        }
    }
}

/// The 48-byte `f32` progressive-photon record, three `vec4`-sized groups.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
pub struct PackedPhoton {
    /// Hit position (metres).
    pub position: [f32; 3],
    /// [`PhotonMap`] as `u32`.
    pub map: u32,
    /// Unit normal towards the arrival side (flipped where the photon arrived from below
    /// the shading plane, see [`crate::propagate::lambertian`]).
    pub normal: [f32; 3],
    /// Padding (zero).
    pub _pad0: u32,
    /// Flux (W, RGB).
    pub flux: [f32; 3],
    /// Padding (zero).
    pub _pad1: u32,
}

impl PackedPhoton {
    /// Sphere test `|q − x_p|² < radius²`.
    #[inline]
    pub fn contains(&self, q: Vec3, radius: f32) -> bool {
        (q - Vec3::from_array(self.position)).length_squared() < radius * radius
    }

    /// Irradiance (W/m², RGB) at `q` with normal `query_normal` for progressive radius
    /// `radius` (metres): `Φ/(π r²)` inside the sphere and on the lit side, else 0 (also 0 when the
    /// result would not be finite, e.g. for a zero or subnormal radius).
    #[inline]
    pub fn irradiance(&self, q: Vec3, query_normal: Vec3, radius: f32) -> Vec3 {
        let density = core::f32::consts::FRAC_1_PI / (radius * radius);
        if density.is_finite() && self.contains(q, radius) && Vec3::from_array(self.normal).dot(query_normal) > 0.0 {
            let e = Vec3::from_array(self.flux) * density;
            if e.is_finite() { e } else { Vec3::ZERO }
        } else {
            Vec3::ZERO
        }
    }

    /// [`PackedPhoton::irradiance`] at every scale of the bandwidth ladder
    /// ([`crate::gather::scales`]): scale `k` has radius `r 2^{−k/2}`, tested as
    /// `|q − x_p|² 2^k < r²`, and density `2^k/(π r²)` (exact scalings in `f32`). Scale 0
    /// equals [`PackedPhoton::irradiance`] bit for bit.
    #[inline]
    pub fn irradiance_scales(&self, q: Vec3, query_normal: Vec3, radius: f32) -> [Vec3; crate::gather::scales::SCALES] {
        let density = core::f32::consts::FRAC_1_PI / (radius * radius);
        let d2 = (q - Vec3::from_array(self.position)).length_squared();
        if density.is_finite() && Vec3::from_array(self.normal).dot(query_normal) > 0.0 {
            let mut e = [Vec3::ZERO; crate::gather::scales::SCALES];
            for (k, e) in e.iter_mut().enumerate() {
                let f = crate::gather::scales::inv_scale2(k);
                // The spheres are nested: once q is outside one, it is outside the smaller.
                if !(d2 * f < radius * radius) {
                    break;
                }
                let v = Vec3::from_array(self.flux) * (density * f);
                *e = if v.is_finite() { v } else { Vec3::ZERO };
            }
            e
        } else {
            [Vec3::ZERO; crate::gather::scales::SCALES]
        }
    }

    /// Map of this photon.
    #[inline]
    pub fn photon_map(&self) -> PhotonMap {
        PhotonMap::from_index(self.map)
    }
}
