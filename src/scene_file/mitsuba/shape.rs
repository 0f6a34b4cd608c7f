//! Shape plugins: mesh files and Mitsuba's analytic shapes, placed in the world with
//! their material and area emitter.

use super::loader::{num, Bsdf, Loader, R};
use super::super::error::SceneFileError;
use super::super::mesh::RawMesh;
use super::super::xml::Node;
use super::super::{obj, ply, serialized, shapes};
use arpa_core::render::scene::{Instance, Material, MaterialId, TriangleMesh};
use arpa_core::render::shapes::angle_weighted_normals;
use glam::{DAffine3, DMat3, DMat4, DVec3, Vec3};

impl Loader<'_> {
    pub(super) fn shape(&mut self, n: &Node) -> R<()> {
        let ty = n.attr("type").unwrap_or("");
        match ty {
            "shapegroup" => return self.shapegroup(n),
            "instance" => return self.instance(n),
            _ => {}
        }
        let p = self.props(n);
        let to_world = self.transform(&p, "to_world")?.unwrap_or(DMat4::IDENTITY);
        let face_normals = self.boolean(&p, "face_normals")?;
        let flip_normals = self.boolean(&p, "flip_normals")?.unwrap_or(false);
        let (raw, label, to_world) = match ty {
            "ply" | "obj" | "serialized" => {
                let file = self.string(&p, "filename")?.ok_or_else(|| self.invalid(n.line, format!("{} lacks <string name=\"filename\">", n.describe())))?;
                let (path, bytes) = self.read_file(&file)?;
                let raw = match ty {
                    "ply" => ply::parse(&bytes, &path)?,
                    "obj" => obj::parse(&bytes, &path)?,
                    _ => {
                        let line = self.line_of(&p, "shape_index");
                        let index = self.integer(&p, "shape_index")?.unwrap_or(0);
                        let index = u32::try_from(index).map_err(|_| self.invalid(line, format!("shape_index {index} is negative or too large")))?;
                        serialized::parse(&bytes, &path, index)?
                    }
                };
                (raw, file, to_world)
            }
            "rectangle" => (shapes::rectangle(), "rectangle".to_string(), to_world),
            "cube" => (shapes::cube(), "cube".to_string(), to_world),
            "disk" => (shapes::disk(), "disk".to_string(), to_world),
            "sphere" => {
                let center = self.point(&p, "center")?.unwrap_or(DVec3::ZERO);
                let radius = self.float(&p, "radius")?.unwrap_or(1.0);
                if !(radius > 0.0 && (radius as f32).is_normal()) {
                    return Err(self.invalid(self.line_of(&p, "radius"), format!("sphere radius {} must be positive and finite in single precision", num(radius))));
                }
                let m = to_world * DMat4::from_translation(center) * DMat4::from_scale(DVec3::splat(radius));
                (shapes::sphere(), "sphere".to_string(), m)
            }
            "cylinder" => {
                let p0 = self.point(&p, "p0")?.unwrap_or(DVec3::ZERO);
                let p1 = self.point(&p, "p1")?.unwrap_or(DVec3::Z);
                let radius = self.float(&p, "radius")?.unwrap_or(1.0);
                if !(radius > 0.0 && (radius as f32).is_normal()) {
                    return Err(self.invalid(self.line_of(&p, "radius"), format!("cylinder radius {} must be positive and finite in single precision", num(radius))));
                }
                let d = p1 - p0;
                let length = d.length();
                if !(length > 0.0 && (length as f32).is_normal()) {
                    return Err(self.invalid(n.line, "cylinder p0 and p1 coincide (or are too far apart for single precision)"));
                }
                let m = to_world * DMat4::from_translation(p0) * cylinder_frame(d / length) * DMat4::from_scale(DVec3::new(radius, radius, length));
                (shapes::cylinder(), "cylinder".to_string(), m)
            }
            _ => return Err(self.unsupported(n, "supported shapes: ply, obj, serialized, rectangle, cube, sphere, cylinder, disk")),
        };
        // Material: one nested <bsdf> or <ref>; none gives Mitsuba's default diffuse 0.5.
        let mats = self.objects(&p, &["bsdf", "ref"]);
        if mats.len() > 1 {
            return Err(self.invalid(mats[1].line, "a shape can have only one <bsdf> or <ref>"));
        }
        let material = match mats.first() {
            Some(r) if r.tag == "ref" => {
                let id = r.attr("id").ok_or_else(|| self.invalid(r.line, "<ref> lacks 'id'"))?;
                self.material_of(id, r.line)?
            }
            Some(b) => {
                let b = self.bsdf(b)?;
                self.push_material(&b)
            }
            None => match self.default_material {
                Some(m) => m,
                None => {
                    let m = self.push_material(&Bsdf { material: Material::Diffuse { albedo: Vec3::splat(0.5) }, maps: Default::default() });
                    self.default_material = Some(m);
                    m
                }
            },
        };
        let emitters = self.objects(&p, &["emitter"]);
        if emitters.len() > 1 {
            return Err(self.invalid(emitters[1].line, "a shape can have only one <emitter>"));
        }
        let mut emission = None;
        let mut emission_texture = None;
        if let Some(e) = emitters.first() {
            if e.attr("type") != Some("area") {
                return Err(self.unsupported(e, "only 'area' emitters can be attached to shapes"));
            }
            let ep = self.props(e);
            // A textured radiance: the texture's values are the radiance (factor 1).
            emission_texture = self.texture_of(&ep, "radiance")?;
            let radiance = match emission_texture {
                Some(_) => DVec3::ONE,
                None => self.emission(&ep, "radiance", None)?.ok_or_else(|| self.invalid(e.line, "area emitter lacks 'radiance'"))?,
            };
            self.finish(&ep);
            emission = Some(radiance);
        }
        self.objects(&p, &["medium", "texture", "sensor", "shape"]).iter().try_for_each(|m| Err(self.unsupported(m, "not supported inside a <shape>")))?;
        self.finish(&p);

        // Mitsuba's mesh plugins give a mesh without stored normals smooth vertex normals
        // unless face normals are asked for; its analytic shapes have their own.
        let face_normals = face_normals.unwrap_or(raw.face_normals);
        let normals = match ty {
            "ply" | "obj" | "serialized" if !face_normals => MissingNormals::Smooth,
            _ => MissingNormals::Face,
        };
        let mesh = self.build_mesh(n, raw, &label, to_world, face_normals, normals, flip_normals, material, emission)?;
        self.meshes.push(mesh);
        self.emission_textures.push(emission_texture);
        Ok(())
    }

    #[allow(clippy::too_many_arguments)]
    /// A `shapegroup`: its shapes are loaded but not placed in the scene; each `instance`
    /// of it places a copy ([`Loader::instance`]). Emitters, nested groups and instances
    /// inside a group are errors (Mitsuba instances neither).
    fn shapegroup(&mut self, n: &Node) -> R<()> {
        let id = n.attr("id").ok_or_else(|| self.invalid(n.line, "a shapegroup needs an 'id' for its instances to name"))?.to_string();
        if self.shapegroups.contains_key(&id) || self.bsdfs.contains_key(&id) || self.texture_ids.contains_key(&id) {
            return Err(self.invalid(n.line, format!("duplicate id '{id}'")));
        }
        let p = self.props(n);
        let first = self.meshes.len();
        for c in self.objects(&p, &["shape"]) {
            if matches!(c.attr("type"), Some("shapegroup" | "instance")) {
                return Err(self.unsupported(c, "not supported inside a shapegroup (Mitsuba nests neither)"));
            }
            self.shape(c)?;
            if self.meshes.last().is_some_and(|m| m.emission.is_some()) {
                return Err(self.invalid(c.line, "an area emitter inside a shapegroup: emitters cannot be instanced (as in Mitsuba); place the shape directly"));
            }
        }
        self.finish(&p);
        let meshes = self.meshes.split_off(first);
        self.emission_textures.truncate(first);
        if meshes.is_empty() {
            self.warn(n.line, format!("shapegroup '{id}' has no shapes"));
        }
        self.shapegroups.insert(id, (meshes, None));
        Ok(())
    }

    /// An `instance`: a copy of the meshes of the `shapegroup` its `<ref>` names (defined
    /// before it), placed by its `to_world` (positions transformed, normals by the inverse
    /// transpose, in `f64`). The copies are the scene's meshes (what shading reads); the
    /// group and the transform are recorded in the scene's instancing, so that backends
    /// that can instance the group in their acceleration structures do.
    fn instance(&mut self, n: &Node) -> R<()> {
        let p = self.props(n);
        let to_world = self.transform(&p, "to_world")?.unwrap_or(DMat4::IDENTITY);
        let refs = self.objects(&p, &["ref"]);
        self.objects(&p, &["bsdf", "emitter", "shape", "texture", "medium"]).iter().try_for_each(|c| Err(self.unsupported(c, "not supported inside an instance")))?;
        let [r] = refs[..] else {
            return Err(self.invalid(n.line, format!("an instance needs exactly one <ref id> to a shapegroup; it has {}", refs.len())));
        };
        let id = r.attr("id").ok_or_else(|| self.invalid(r.line, "<ref> lacks 'id'"))?;
        let Some((group, _)) = self.shapegroups.get(id) else {
            return Err(self.invalid(r.line, format!("<ref id=\"{id}\"> names no shapegroup defined before this instance")));
        };
        let normal_matrix = DMat3::from_mat4(to_world).inverse().transpose();
        let name = n.attr("id").unwrap_or(id).to_string();
        let mut placed = Vec::with_capacity(group.len());
        for m in group {
            let positions: Vec<Vec3> = m.positions.iter().map(|v| to_world.transform_point3(v.as_dvec3()).as_vec3()).collect();
            if let Some(v) = positions.iter().position(|v| !v.is_finite()) {
                return Err(SceneFileError::Mesh { path: self.path.to_path_buf(), line: n.line, mesh: m.name.clone(), message: format!("vertex {v} is not finite after the instance's to_world") });
            }
            let normals = m.normals.as_ref().map(|ns| ns.iter().map(|v| (normal_matrix * v.as_dvec3()).normalize_or(DVec3::Y).as_vec3()).collect());
            placed.push(TriangleMesh {
                positions,
                normals,
                name: format!("{name}: {}", m.name),
                uvs: m.uvs.clone(),
                indices: m.indices.clone(),
                material: m.material,
                emission: m.emission,
            });
        }
        self.finish(&p);
        let prototype = match self.shapegroups.get_mut(id) {
            Some((group, Some(p))) if !group.is_empty() => Some(*p),
            Some((group, slot)) if !group.is_empty() => Some(*slot.insert(self.instancing.add_prototype(id, group))),
            _ => None,
        };
        let first = self.meshes.len() as u32;
        if let Some(prototype) = prototype {
            let meshes = (first..first + placed.len() as u32).collect();
            self.instancing.instances.push(Instance { prototype, to_world: DAffine3::from_mat4(to_world), meshes });
        }
        self.emission_textures.extend(placed.iter().map(|_| None));
        self.meshes.extend(placed);
        Ok(())
    }

    #[allow(clippy::too_many_arguments)]
    pub(super) fn build_mesh(&mut self, n: &Node, raw: RawMesh, file: &str, to_world: DMat4, face_normals: bool, missing: MissingNormals, flip: bool, material: MaterialId, emission: Option<DVec3>) -> R<TriangleMesh> {
        let err = |message: String| SceneFileError::Mesh { path: self.path.to_path_buf(), line: n.line, mesh: file.to_string(), message };
        let label = format!("{file} (line {})", n.line);
        if raw.indices.is_empty() {
            return Err(err("has no triangles".into()));
        }
        if let Some(v) = raw.positions.iter().position(|p| !p.is_finite()) {
            return Err(err(format!("vertex {v} has a non-finite position {:?}", raw.positions[v].to_array())));
        }
        if let Some((t, i)) = raw.indices.iter().enumerate().find_map(|(t, tri)| tri.iter().find(|&&i| i as usize >= raw.positions.len()).map(|&i| (t, i))) {
            return Err(err(format!("triangle {t} refers to vertex {i}, but there are {} vertices", raw.positions.len())));
        }
        let positions: Vec<DVec3> = raw.positions.iter().map(|&p| to_world.transform_point3(p)).collect();
        if let Some(v) = positions.iter().position(|p| !p.is_finite() || !p.as_vec3().is_finite()) {
            return Err(err(format!("vertex {v} is not finite after the shape's to_world")));
        }
        let mut normals = match (&raw.normals, face_normals) {
            (Some(ns), false) => {
                if let Some(v) = ns.iter().position(|p| !p.is_finite()) {
                    return Err(err(format!("vertex {v} has a non-finite normal")));
                }
                let nm = DMat3::from_mat4(to_world).inverse().transpose();
                let mut out: Vec<DVec3> = ns.iter().map(|&v| (nm * v).normalize_or_zero()).collect();
                let bad: Vec<usize> = (0..out.len()).filter(|&i| out[i] == DVec3::ZERO || !out[i].is_finite()).collect();
                if bad.is_empty() {
                    Some(out)
                } else {
                    // Replace each zero-length normal by the area-weighted normal of its faces.
                    let mut sum = vec![DVec3::ZERO; out.len()];
                    for t in &raw.indices {
                        let p = t.map(|i| positions[i as usize]);
                        let g = (p[1] - p[0]).cross(p[2] - p[0]);
                        t.iter().for_each(|&i| sum[i as usize] += g);
                    }
                    let mut fixed = true;
                    for &i in &bad {
                        out[i] = sum[i].normalize_or_zero();
                        fixed &= out[i] != DVec3::ZERO && out[i].is_finite();
                    }
                    if fixed {
                        self.warn(n.line, format!("mesh '{file}': {} vertices have zero-length normals; replaced by the normals of their faces", bad.len()));
                        Some(out)
                    } else {
                        self.warn(n.line, format!("mesh '{file}': {} vertices have zero-length normals; the mesh is shaded with face normals", bad.len()));
                        None
                    }
                }
            }
            (None, false) if missing == MissingNormals::Smooth => Some(angle_weighted_normals(&positions, &raw.indices)),
            _ => None,
        };
        let stored_normals = raw.normals.is_some() && !face_normals;
        if let (true, Some(ns), Some(Material::Diffuse { .. })) = (stored_normals, &normals, self.materials.get(material as usize)) {
            let off = tilted_normal_area_fraction(&positions, ns, &raw.indices);
            if off > TILTED_NORMAL_WARN_FRACTION {
                self.warn(
                    n.line,
                    format!(
                        "mesh '{file}': {:.1} % of its area has vertex normals more than {TILTED_NORMAL_DEGREES}° from the face normal; both arpa and Mitsuba shade diffuse surfaces with them (the interpolated normal decides the cosine and which side is lit), so such a mesh looks different from its face-normal rendering",
                        100.0 * off
                    ),
                );
            }
        }
        let uvs = match raw.uvs {
            Some(uvs) => {
                if let Some(v) = uvs.iter().position(|t| !t.is_finite() || !t.as_vec2().is_finite()) {
                    return Err(err(format!("vertex {v} has a non-finite texture coordinate")));
                }
                Some(uvs.iter().map(|t| t.as_vec2()).collect())
            }
            None => None,
        };
        let mut indices = raw.indices;
        if flip {
            indices.iter_mut().for_each(|t| t.swap(1, 2));
            if let Some(ns) = normals.as_mut() {
                ns.iter_mut().for_each(|v| *v = -*v);
            }
        }
        if let Some(e) = emission {
            let area: f64 = indices.iter().map(|t| {
                let p = t.map(|i| positions[i as usize]);
                0.5 * (p[1] - p[0]).cross(p[2] - p[0]).length()
            }).sum();
            if (area.is_nan() || area <= 0.0) && e.max_element() > 0.0 {
                return Err(err("is an area emitter with zero total area".into()));
            }
            if let (true, Some(ns)) = (stored_normals, &normals) {
                let against = indices
                    .iter()
                    .filter(|t| {
                        let p = t.map(|i| positions[i as usize]);
                        let g = (p[1] - p[0]).cross(p[2] - p[0]);
                        g.dot(ns[t[0] as usize] + ns[t[1] as usize] + ns[t[2] as usize]) < 0.0
                    })
                    .count();
                if 2 * against > indices.len() {
                    self.warn(n.line, format!("area emitter '{file}': the stored vertex normals point against the winding; arpa emits on the winding side (cross(p1-p0, p2-p0))"));
                }
            }
        }
        Ok(TriangleMesh {
            uvs,
            name: label,
            positions: positions.iter().map(|p| p.as_vec3()).collect(),
            normals: normals.map(|ns| ns.iter().map(|v| v.as_vec3()).collect()),
            indices,
            material,
            emission: emission.map(|e| e.as_vec3()),
        })
    }
}

/// What a mesh without stored vertex normals is shaded with.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum MissingNormals {
    /// Smooth normals ([`angle_weighted_normals`]): Mitsuba's mesh plugins.
    Smooth,
    /// Face normals: analytic shapes, and meshes with `face_normals`.
    Face,
}

/// Angle (degrees) beyond which a vertex normal counts as tilted away from its face.
pub const TILTED_NORMAL_DEGREES: f64 = 60.0;

/// Fraction of a diffuse mesh's area with tilted vertex normals above which the loader
/// warns (both arpa and Mitsuba shade diffuse surfaces with such normals; likely a broken export).
pub const TILTED_NORMAL_WARN_FRACTION: f64 = 0.01;

/// Fraction of the total area of `indices` whose triangles have at least one vertex
/// normal more than [`TILTED_NORMAL_DEGREES`] from the face normal (either orientation:
/// diffuse surfaces are two-sided). Degenerate triangles have no area and do not count.
pub(crate) fn tilted_normal_area_fraction(positions: &[DVec3], normals: &[DVec3], indices: &[[u32; 3]]) -> f64 {
    let cos_max = TILTED_NORMAL_DEGREES.to_radians().cos();
    let (mut tilted, mut total) = (0.0, 0.0);
    for t in indices {
        let p = t.map(|i| positions[i as usize]);
        let g = (p[1] - p[0]).cross(p[2] - p[0]);
        let area = 0.5 * g.length();
        if !(area > 0.0 && area.is_finite()) {
            continue;
        }
        let face = g.normalize();
        total += area;
        if t.iter().any(|&i| face.dot(normals[i as usize]).abs() < cos_max) {
            tilted += area;
        }
    }
    if total > 0.0 { tilted / total } else { 0.0 }
}


/// The rotation Mitsuba's cylinder takes its local frame to (`Frame3f(d)` of unit axis
/// `d`: Duff et al.'s orthonormal basis, local x and y its two tangents, z the axis), so
/// the texture coordinate `u` starts where Mitsuba's does.
fn cylinder_frame(d: DVec3) -> DMat4 {
    let sign = 1.0f64.copysign(d.z);
    let a = -1.0 / (sign + d.z);
    let b = d.x * d.y * a;
    let s = DVec3::new(1.0 + sign * d.x * d.x * a, sign * b, -sign * d.x);
    let t = DVec3::new(b, sign + d.y * d.y * a, -d.y);
    DMat4::from_cols(s.extend(0.0), t.extend(0.0), d.extend(0.0), glam::DVec4::W)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Mitsuba 3.9's frame for a cylinder along +x: local x is −z, local y is +y.
    #[test]
    fn cylinder_frame_is_mitsubas() {
        let m = cylinder_frame(DVec3::X);
        assert!((m.transform_vector3(DVec3::X) - DVec3::new(0.0, 0.0, -1.0)).length() < 1e-15);
        assert!((m.transform_vector3(DVec3::Y) - DVec3::Y).length() < 1e-15);
        assert!((m.transform_vector3(DVec3::Z) - DVec3::X).length() < 1e-15);
        for d in [DVec3::Z, -DVec3::Z, DVec3::new(0.3, -0.4, 0.5).normalize()] {
            let m = cylinder_frame(d);
            let (x, y, z) = (m.transform_vector3(DVec3::X), m.transform_vector3(DVec3::Y), m.transform_vector3(DVec3::Z));
            assert!((x.cross(y) - z).length() < 1e-12 && x.dot(y).abs() < 1e-12, "{d}");
        }
    }
}
