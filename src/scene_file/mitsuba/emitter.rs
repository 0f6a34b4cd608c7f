//! Emitter plugins: point, spot and directional lights, and the environment (`constant`,
//! `envmap`); area emitters are read with their shape.

use super::loader::{num, Loader, Props, R};
use super::super::xml::Node;
use super::super::bitmap;
use arpa_core::emit::emission::{DirectionalLight, EnvironmentLight, Light, PointLight, SpotFalloff, SpotLight};
use arpa_core::render::environment::EnvironmentMap;
use arpa_core::render::texture::{Bitmap, TextureFilter, TextureWrap, UvTransform};
use glam::{DMat3, DMat4, DVec3};

impl Loader<'_> {
    /// The emission colour `name` of an analytic light (default 1): non-negative, finite
    /// in single precision and not zero (a light must emit).
    pub(super) fn emitted(&self, p: &Props<'_>, name: &str) -> R<DVec3> {
        let v = self.emission(p, name, Some(DVec3::ONE))?.unwrap_or(DVec3::ONE);
        if v.max_element() <= 0.0 {
            return Err(self.invalid(self.line_of(p, name), format!("'{name}' is zero: the light emits no power")));
        }
        Ok(v)
    }

    pub(super) fn emitter(&mut self, n: &Node) -> R<()> {
        let ty = n.attr("type").unwrap_or("");
        let p = self.props(n);
        let light = match ty {
            "point" => {
                let intensity = self.emitted(&p, "intensity")?;
                let pos = self.point(&p, "position")?;
                let m = self.transform(&p, "to_world")?.unwrap_or(DMat4::IDENTITY);
                let position = m.transform_point3(pos.unwrap_or(DVec3::ZERO));
                if !position.as_vec3().is_finite() {
                    return Err(self.invalid(self.line_of(&p, "position"), "the point light's 'position' is not finite (in single precision) after its to_world"));
                }
                Light::Point(PointLight { position, intensity })
            }
            "spot" => {
                let intensity = self.emitted(&p, "intensity")?;
                let m = self.transform(&p, "to_world")?.unwrap_or(DMat4::IDENTITY);
                let cutoff = self.float(&p, "cutoff_angle")?.unwrap_or(20.0);
                let beam = self.float(&p, "beam_width")?.unwrap_or(cutoff * 0.75);
                if !(cutoff > 0.0 && cutoff <= 90.0) {
                    return Err(self.invalid(n.line, format!("spot cutoff_angle {} is outside (0, 90] degrees", num(cutoff))));
                }
                if !(beam >= 0.0 && beam <= cutoff) {
                    return Err(self.invalid(n.line, format!("spot beam_width {} is outside [0, cutoff_angle = {}] degrees", num(beam), num(cutoff))));
                }
                let direction = m.transform_vector3(DVec3::Z).normalize_or_zero();
                if direction == DVec3::ZERO {
                    return Err(self.invalid(n.line, "spot light to_world maps +z to zero"));
                }
                self.objects(&p, &["texture"]).iter().try_for_each(|t| Err(self.unsupported(t, "spot light textures are not supported")))?;
                Light::Spot(SpotLight {
                    position: m.transform_point3(DVec3::ZERO),
                    direction,
                    intensity,
                    cutoff: cutoff.to_radians(),
                    beam_width: beam.to_radians(),
                    falloff: SpotFalloff::LinearAngle,
                })
            }
            "directional" => {
                let irradiance = self.emitted(&p, "irradiance")?;
                let d = self.point(&p, "direction")?;
                let m = self.transform(&p, "to_world")?;
                let direction = match (d, m) {
                    (Some(d), _) => d,
                    (None, Some(m)) => m.transform_vector3(DVec3::Z),
                    (None, None) => DVec3::Z,
                }
                .normalize_or_zero();
                if direction == DVec3::ZERO {
                    return Err(self.invalid(n.line, "directional light direction is zero"));
                }
                Light::Directional(DirectionalLight { direction, irradiance })
            }
            "constant" | "envmap" if self.lights.iter().any(|l| matches!(l, Light::Environment(_))) => {
                return Err(self.invalid(n.line, format!("{}: a scene has at most one environment emitter (constant or envmap)", n.describe())));
            }
            "constant" => Light::Environment(EnvironmentLight { radiance: self.emitted(&p, "radiance")?, mean: DVec3::ONE }),
            "envmap" => self.envmap(n, &p)?,
            "area" => return Err(self.unsupported(n, "an area emitter must be nested in a <shape>")),
            _ => return Err(self.unsupported(n, "supported emitters: point, spot, directional, constant, envmap, and area inside a shape")),
        };
        // What the per-field checks above cannot see (a position that overflows under
        // to_world, ...); the scene radius matters only to directional lights' bounds.
        light.validate(1.0).map_err(|e| self.invalid(n.line, format!("{}: {e}", n.describe())))?;
        self.finish(&p);
        self.lights.push(light);
        Ok(())
    }

    /// Mitsuba's `envmap`: an equirectangular image (`filename`: EXR, HDR, PNG, JPEG; 8-bit
    /// images are sRGB), `scale`, and `to_world` (its linear part orients the map).
    fn envmap(&mut self, n: &Node, p: &Props<'_>) -> R<Light> {
        let file = self.string(p, "filename")?.ok_or_else(|| self.invalid(n.line, format!("{} lacks <string name=\"filename\">", n.describe())))?;
        let scale = self.float(p, "scale")?.unwrap_or(1.0);
        if scale <= 0.0 || !(scale as f32).is_finite() {
            return Err(self.invalid(self.line_of(p, "scale"), format!("envmap scale {} is not a finite positive number", super::loader::num(scale))));
        }
        let m = self.transform(p, "to_world")?.unwrap_or(DMat4::IDENTITY);
        let to_world = DMat3::from_mat4(m);
        let det = to_world.determinant().abs();
        if det.is_nan() || det <= 1e-12 {
            return Err(self.invalid(self.line_of(p, "to_world"), "the envmap's to_world is singular"));
        }
        // Importance-sampling resolution and mipmapping: nothing for a photon mapper.
        let _ = self.string(p, "filter_type")?;
        let (path, bytes) = self.read_file(&file)?;
        let d = bitmap::decode(&bytes, &path, false)?;
        let map = EnvironmentMap { bitmap: Bitmap { width: d.width, height: d.height, texels: d.texels, filter: TextureFilter::Bilinear, wrap: TextureWrap::Repeat, to_uv: UvTransform::default() }, to_world };
        let mean = map.mean().map_err(|e| self.invalid(n.line, format!("{}: {e}", path.display())))?;
        self.environment = Some(map);
        Ok(Light::Environment(EnvironmentLight { radiance: DVec3::splat(scale), mean }))
    }
}
