//! The `perspective` sensor with its film and sampler.

use super::loader::{num, Loader, R};
use super::super::loaded::{vertical_fov, FovAxis};
use super::super::xml::Node;
use arpa_core::render::scene::Camera;
use glam::{DMat3, DMat4, DVec3};

impl Loader<'_> {
    pub(super) fn sensor(&mut self, n: &Node) -> R<()> {
        if self.camera.is_some() {
            self.warn(n.line, "only the first <sensor> is used; this one is ignored");
            return Ok(());
        }
        if n.attr("type") != Some("perspective") {
            return Err(self.unsupported(n, "only the 'perspective' sensor is supported"));
        }
        let p = self.props(n);
        if self.find(&p, "focal_length").is_some() {
            return Err(self.unsupported(n, "'focal_length' is not supported; give 'fov' and 'fov_axis'"));
        }
        let fov = self.float(&p, "fov")?.unwrap_or(90.0);
        let axis_line = p.node.children.iter().find(|c| c.attr("name") == Some("fov_axis")).map_or(n.line, |c| c.line);
        let axis = match self.string(&p, "fov_axis")?.as_deref().unwrap_or("x") {
            "x" => FovAxis::X,
            "y" => FovAxis::Y,
            "diagonal" => FovAxis::Diagonal,
            "smaller" => FovAxis::Smaller,
            "larger" => FovAxis::Larger,
            other => return Err(self.invalid(axis_line, format!("fov_axis '{other}' is not one of x, y, diagonal, smaller, larger"))),
        };
        if !(fov > 0.0 && fov < 180.0) {
            return Err(self.invalid(n.line, format!("fov {} is outside (0, 180) degrees", num(fov))));
        }
        let to_world = self.transform(&p, "to_world")?.unwrap_or(DMat4::IDENTITY);
        // Clipping planes do not change a photon mapper's image of the scene.
        let _ = (self.float(&p, "near_clip")?, self.float(&p, "far_clip")?);
        let (mut width, mut height) = (768u32, 576u32);
        for s in self.objects(&p, &["sampler"]) {
            let sp = self.props(s);
            if let Some(c) = self.integer(&sp, "sample_count")? {
                self.sample_count = u32::try_from(c).ok();
            }
            self.consume_all(&sp);
        }
        let films = self.objects(&p, &["film"]);
        if films.len() > 1 {
            return Err(self.invalid(films[1].line, "a sensor can have only one <film>"));
        }
        if let Some(f) = films.first() {
            let fp = self.props(f);
            let size = |v: Option<i64>, what: &str, d: u32| -> R<u32> {
                match v {
                    None => Ok(d),
                    Some(v) if (1..=16384).contains(&v) => Ok(v as u32),
                    Some(v) => Err(self.invalid(f.line, format!("film {what} {v} is outside 1..=16384"))),
                }
            };
            width = size(self.integer(&fp, "width")?, "width", width)?;
            height = size(self.integer(&fp, "height")?, "height", height)?;
            for key in ["pixel_format", "component_format", "file_format", "banner", "high_quality_edges", "sample_border"] {
                let _ = self.find(&fp, key);
            }
            for r in self.objects(&fp, &["rfilter"]) {
                if r.attr("type") != Some("box") {
                    self.warn(r.line, format!("{}: not supported; the box pixel filter is used", r.describe()));
                }
                let rp = self.props(r);
                self.consume_all(&rp);
            }
            self.finish(&fp);
        }
        self.objects(&p, &["medium"]).iter().try_for_each(|m| Err(self.unsupported(m, "participating media are not supported")))?;
        self.finish(&p);

        // Mitsuba's camera frame: +z forward, +y up, +x left.
        let m3 = DMat3::from_mat4(to_world);
        let origin = to_world.transform_point3(DVec3::ZERO);
        let forward = m3.z_axis.normalize_or_zero();
        let up = m3.y_axis.normalize_or_zero();
        let left = m3.x_axis.normalize_or_zero();
        if forward == DVec3::ZERO || up == DVec3::ZERO || left == DVec3::ZERO || !origin.is_finite() {
            return Err(self.invalid(n.line, "the sensor's to_world is degenerate"));
        }
        if up.cross(forward).dot(left) < 0.0 {
            return Err(self.unsupported(n, "the sensor's to_world mirrors the image (its +x axis points right, not left); arpa cannot render mirrored cameras"));
        }
        if forward.dot(up).abs() > 1e-3 || forward.dot(left).abs() > 1e-3 || up.dot(left).abs() > 1e-3 {
            self.warn(n.line, "the sensor's to_world is not orthogonal; arpa uses its forward (+z) and up (+y) axes only");
        }
        let vfov = vertical_fov(fov, axis, width, height);
        if !(vfov > 0.0 && vfov < std::f32::consts::PI) {
            return Err(self.invalid(n.line, format!("fov {} along fov_axis {axis:?} on a {width}x{height} film gives a vertical field of view of {vfov} radians, outside (0, 180) degrees", num(fov))));
        }
        let camera = Camera {
            position: origin.as_vec3(),
            target: (origin + forward).as_vec3(),
            up: up.as_vec3(),
            vertical_fov: vfov,
            width,
            height,
        };
        self.camera = Some((camera, fov, axis));
        Ok(())
    }
}
