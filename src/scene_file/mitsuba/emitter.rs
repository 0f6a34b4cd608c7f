//! Emitter plugins: point, spot and directional lights (area emitters are read with
//! their shape).

use super::loader::{num, Loader, Props, R};
use super::super::xml::Node;
use arpa_core::emit::emission::{DirectionalLight, Light, PointLight, SpotFalloff, SpotLight};
use glam::{DMat4, DVec3};

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
            "area" => return Err(self.unsupported(n, "an area emitter must be nested in a <shape>")),
            _ => return Err(self.unsupported(n, "supported emitters: point, spot, directional, and area inside a shape")),
        };
        // What the per-field checks above cannot see (a position that overflows under
        // to_world, ...); the scene radius matters only to directional lights' bounds.
        light.validate(1.0).map_err(|e| self.invalid(n.line, format!("{}: {e}", n.describe())))?;
        self.finish(&p);
        self.lights.push(light);
        Ok(())
    }
}
