//! The loader's state and its access to an element's properties: typed values with
//! the checks every plugin shares, the warnings for what was not read, and the errors
//! naming the file and line.

use super::super::error::{SceneFileError, Warning};
use super::super::loaded::FovAxis;
use super::super::mesh::MeshReader;
use super::super::spectrum::{self, SpectrumUse};
use super::super::transform::{self, numbers, parse_transform};
use super::super::xml::Node;
use arpa_core::emit::emission::Light;
use arpa_core::render::scene::{Camera, Material, MaterialId, MaterialMaps, TriangleMesh};
use arpa_core::render::texture::{Texture, TextureId};
use glam::{DMat4, DVec3};
use std::cell::{Cell, RefCell};
use std::collections::HashMap;
use std::path::{Path, PathBuf};

/// `v` for messages: plain for ordinary magnitudes, scientific for absurd ones (so that
/// `1e-300` does not print 300 digits).
pub(super) fn num(v: f64) -> String {
    if v == 0.0 || !v.is_finite() || (1e-4..1e6).contains(&v.abs()) { format!("{v}") } else { format!("{v:e}") }
}

/// Tags that carry a named property value.
const PROPERTY_TAGS: &[&str] = &["float", "integer", "boolean", "string", "rgb", "spectrum", "point", "vector", "transform", "texture", "ref"];

/// A bsdf as loaded: the material it maps to.
#[derive(Clone)]
pub(super) struct Bsdf {
    /// The material.
    pub(super) material: Material,
    /// The textures it reads (colour, opacity).
    pub(super) maps: MaterialMaps,
}

/// Named properties of one element; remembers which were read so the rest can be
/// reported as ignored.
pub(super) struct Props<'n> {
    pub(super) node: &'n Node,
    pub(super) used: Vec<Cell<bool>>,
}

/// The state of one scene load: where files are, what was read so far, and the
/// warnings.
pub(super) struct Loader<'a> {
    pub(super) path: &'a Path,
    pub(super) read_mesh: MeshReader<'a>,
    pub(super) base: PathBuf,
    /// Approximations and ignored elements, in the order met (a cell: property readers
    /// that only borrow the loader warn too).
    pub(super) warnings: RefCell<Vec<Warning>>,
    /// Directories relative file names are looked up in, in order: the `<path>` entries
    /// (the last one first), then the scene file's directory (Mitsuba's order).
    pub(super) search: Vec<PathBuf>,
    pub(super) bsdfs: HashMap<String, (Bsdf, Option<MaterialId>)>,
    pub(super) default_material: Option<MaterialId>,
    pub(super) materials: Vec<Material>,
    /// Per material (aligned with `materials`), the textures it reads.
    pub(super) maps: Vec<MaterialMaps>,
    /// The scene's textures.
    pub(super) textures: Vec<Texture>,
    /// Per mesh (aligned with `meshes`), the texture of its area emitter's radiance.
    pub(super) emission_textures: Vec<Option<TextureId>>,
    /// Top-level textures by id.
    pub(super) texture_ids: HashMap<String, TextureId>,
    pub(super) meshes: Vec<TriangleMesh>,
    /// `shapegroup`s by id: their meshes (in the group's space), placed by each `instance`
    /// (a copy in `meshes`), and their prototype in `instancing` once one is placed.
    pub(super) shapegroups: HashMap<String, (Vec<TriangleMesh>, Option<u32>)>,
    /// The groups placed and where (the scene's [`arpa_core::render::scene::Instancing`]).
    pub(super) instancing: arpa_core::render::scene::Instancing,
    pub(super) lights: Vec<Light>,
    /// The `envmap` emitter's map.
    pub(super) environment: Option<arpa_core::render::environment::EnvironmentMap>,
    pub(super) camera: Option<(Camera, f64, FovAxis)>,
    pub(super) max_depth: Option<u32>,
    pub(super) sample_count: Option<u32>,
}

/// A loader result.
pub(super) type R<T> = Result<T, SceneFileError>;

impl<'a> Loader<'a> {
    pub(super) fn invalid(&self, line: usize, message: impl Into<String>) -> SceneFileError {
        SceneFileError::Invalid { path: self.path.to_path_buf(), line, message: message.into() }
    }

    pub(super) fn unsupported(&self, n: &Node, message: impl Into<String>) -> SceneFileError {
        SceneFileError::Unsupported { path: self.path.to_path_buf(), line: n.line, element: n.describe(), message: message.into() }
    }

    pub(super) fn warn(&self, line: usize, message: impl Into<String>) {
        self.warnings.borrow_mut().push(Warning { path: self.path.to_path_buf(), line, message: message.into() });
    }

    pub(super) fn props<'n>(&self, node: &'n Node) -> Props<'n> {
        Props { node, used: node.children.iter().map(|_| Cell::new(false)).collect() }
    }

    /// Warns about every property of `p` that was not read.
    pub(super) fn finish(&self, p: &Props<'_>) {
        for (c, used) in p.node.children.iter().zip(&p.used) {
            if !used.get() {
                let what = c.attr("name").map(|n| format!("<{} name=\"{n}\">", c.tag)).unwrap_or_else(|| c.describe());
                self.warn(c.line, format!("{what} in {} (line {}) is not supported and was ignored", p.node.describe(), p.node.line));
            }
        }
    }

    // ---- property access -------------------------------------------------------------

    pub(super) fn find<'n>(&self, p: &Props<'n>, name: &str) -> Option<&'n Node> {
        let i = p.node.children.iter().position(|c| PROPERTY_TAGS.contains(&c.tag.as_str()) && c.attr("name") == Some(name))?;
        p.used[i].set(true);
        Some(&p.node.children[i])
    }

    pub(super) fn value<'n>(&self, n: &'n Node) -> R<&'n str> {
        n.attr("value").ok_or_else(|| self.invalid(n.line, format!("<{}> lacks the attribute 'value'", n.tag)))
    }

    pub(super) fn float(&self, p: &Props<'_>, name: &str) -> R<Option<f64>> {
        let Some(n) = self.find(p, name) else { return Ok(None) };
        if !matches!(n.tag.as_str(), "float" | "integer") {
            return Err(self.invalid(n.line, format!("'{name}' must be a <float>, found <{}>", n.tag)));
        }
        let v = transform::number(self.value(n)?).map_err(|e| self.invalid(n.line, format!("'{name}': {e}")))?;
        if !v.is_finite() {
            return Err(self.invalid(n.line, format!("'{name}' is {v}: not a finite number")));
        }
        Ok(Some(v))
    }

    pub(super) fn integer(&self, p: &Props<'_>, name: &str) -> R<Option<i64>> {
        let Some(n) = self.find(p, name) else { return Ok(None) };
        let s = self.value(n)?;
        s.trim().parse::<i64>().map(Some).map_err(|_| self.invalid(n.line, format!("'{name}' must be an integer, found '{s}'")))
    }

    pub(super) fn boolean(&self, p: &Props<'_>, name: &str) -> R<Option<bool>> {
        let Some(n) = self.find(p, name) else { return Ok(None) };
        match self.value(n)?.trim() {
            "true" | "1" => Ok(Some(true)),
            "false" | "0" => Ok(Some(false)),
            s => Err(self.invalid(n.line, format!("'{name}' must be true or false, found '{s}'"))),
        }
    }

    pub(super) fn string(&self, p: &Props<'_>, name: &str) -> R<Option<String>> {
        let Some(n) = self.find(p, name) else { return Ok(None) };
        Ok(Some(self.value(n)?.to_string()))
    }

    /// A colour from `<rgb value="r, g, b">` (or one value), `<float>`, or a `<spectrum>`
    /// (a constant, a `λ:v` list or an `.spd` file) converted to linear sRGB as Mitsuba's
    /// RGB variants convert it for `usage` ([`super::super::spectrum`]; a colour Mitsuba
    /// clamps is clamped and warned about).
    pub(super) fn rgb(&self, p: &Props<'_>, name: &str, usage: SpectrumUse) -> R<Option<DVec3>> {
        let Some(n) = self.find(p, name) else { return Ok(None) };
        let v = match n.tag.as_str() {
            "rgb" | "float" => {
                let s = self.value(n)?;
                let v = numbers(s).map_err(|e| self.invalid(n.line, format!("'{name}': {e}")))?;
                match v.as_slice() {
                    [x] => DVec3::splat(*x),
                    [r, g, b] if n.tag == "rgb" => DVec3::new(*r, *g, *b),
                    _ => return Err(self.invalid(n.line, format!("'{name}' needs 1 or 3 numbers, found '{s}'"))),
                }
            }
            "spectrum" => {
                let parsed = match (n.attr("value"), n.attr("filename")) {
                    (Some(text), None) => spectrum::parse_value(text).map_err(|e| self.invalid(n.line, format!("'{name}': {e}")))?,
                    (None, Some(file)) => {
                        let (path, bytes) = self.read_file(file)?;
                        spectrum::parse_spd(&bytes).map_err(|e| self.invalid(n.line, format!("'{name}': spectrum file '{}': {e}", path.display())))?
                    }
                    _ => return Err(self.invalid(n.line, format!("<spectrum name=\"{name}\"> needs either 'value' or 'filename'"))),
                };
                let c = spectrum::convert(&parsed, usage);
                if let Some(before) = c.clamped_from {
                    self.warn(n.line, format!("'{name}': the spectrum's colour ({:.4}, {:.4}, {:.4}) is clamped to ({:.4}, {:.4}, {:.4}) as Mitsuba clamps it", before.x, before.y, before.z, c.rgb.x, c.rgb.y, c.rgb.z));
                }
                c.rgb
            }
            "texture" | "ref" => return Err(self.unsupported(n, format!("a texture for '{name}' is not supported (give a constant)"))),
            t => return Err(self.invalid(n.line, format!("'{name}' must be an <rgb>, <float> or <spectrum>, found <{t}>"))),
        };
        if !v.is_finite() {
            return Err(self.invalid(n.line, format!("'{name}' ({}, {}, {}) is not finite", v.x, v.y, v.z)));
        }
        Ok(Some(v))
    }

    /// Reads the file `name` a scene names (a mesh, texture or spectrum file): an absolute
    /// name as is, a relative one from the first of [`Loader::search`] that has it. The
    /// error names the file relative to the scene's directory when no directory has it.
    pub(super) fn read_file(&self, name: &str) -> R<(PathBuf, Vec<u8>)> {
        let direct = Path::new(name);
        if direct.is_absolute() {
            return (self.read_mesh)(direct).map(|b| (direct.to_path_buf(), b)).map_err(|source| SceneFileError::Io { path: direct.to_path_buf(), source });
        }
        for dir in &self.search {
            let c = dir.join(name);
            match (self.read_mesh)(&c) {
                Ok(bytes) => return Ok((c, bytes)),
                Err(e) if e.kind() == std::io::ErrorKind::NotFound => {}
                Err(source) => return Err(SceneFileError::Io { path: c, source }),
            }
        }
        let path = self.base.join(name);
        let source = (self.read_mesh)(&path).err().unwrap_or_else(|| std::io::Error::new(std::io::ErrorKind::NotFound, "not found"));
        Err(SceneFileError::Io { path, source })
    }

    pub(super) fn point(&self, p: &Props<'_>, name: &str) -> R<Option<DVec3>> {
        let Some(n) = self.find(p, name) else { return Ok(None) };
        if !matches!(n.tag.as_str(), "point" | "vector") {
            return Err(self.invalid(n.line, format!("'{name}' must be a <point> or <vector>, found <{}>", n.tag)));
        }
        let v = transform::vector3(n, 0.0, false).map_err(|e| self.invalid(n.line, format!("'{name}': {e}")))?;
        if !v.is_finite() {
            return Err(self.invalid(n.line, format!("'{name}' ({}, {}, {}) is not finite", v.x, v.y, v.z)));
        }
        Ok(Some(v))
    }

    pub(super) fn transform(&self, p: &Props<'_>, name: &str) -> R<Option<DMat4>> {
        let Some(n) = self.find(p, name) else { return Ok(None) };
        if n.tag != "transform" {
            return Err(self.invalid(n.line, format!("'{name}' must be a <transform>, found <{}>", n.tag)));
        }
        parse_transform(n).map(Some).map_err(|(line, m)| self.invalid(line, format!("<transform name=\"{name}\">: {m}")))
    }

    /// A non-negative emission colour (`radiance`, `intensity`, `irradiance`) that is
    /// finite in single precision (the renderer's), or `default`.
    pub(super) fn emission(&self, p: &Props<'_>, name: &str, default: Option<DVec3>) -> R<Option<DVec3>> {
        let line = self.line_of(p, name);
        let Some(v) = self.rgb(p, name, SpectrumUse::Emission)?.or(default) else { return Ok(None) };
        if v.min_element() < 0.0 {
            return Err(self.invalid(line, format!("'{name}' ({}, {}, {}) is negative", v.x, v.y, v.z)));
        }
        if !v.as_vec3().is_finite() {
            return Err(self.invalid(line, format!("'{name}' ({:e}, {:e}, {:e}) is too large (not finite in single precision)", v.x, v.y, v.z)));
        }
        Ok(Some(v))
    }

    /// A reflectance or transmittance colour in `[0, 1]` (energy is conserved), or `default`.
    pub(super) fn fraction(&self, p: &Props<'_>, name: &str, default: DVec3) -> R<DVec3> {
        let line = self.line_of(p, name);
        let v = self.rgb(p, name, SpectrumUse::Reflectance)?.unwrap_or(default);
        if !(v.min_element() >= 0.0 && v.max_element() <= 1.0) {
            return Err(self.invalid(line, format!("'{name}' ({}, {}, {}) is outside [0, 1]", v.x, v.y, v.z)));
        }
        Ok(v)
    }

    /// A reflectance-like parameter that may be a texture: a constant in `[0, 1]` (or
    /// `default`) with no texture, or factor 1 and the texture (a nested `<texture>` or a
    /// `<ref>` to a top-level one), whose values multiply the material's colour at every hit.
    pub(super) fn fraction_or_texture(&mut self, p: &Props<'_>, name: &str, default: DVec3) -> R<(DVec3, Option<TextureId>)> {
        match self.texture_of(p, name)? {
            Some(id) => Ok((DVec3::ONE, Some(id))),
            None => Ok((self.fraction(p, name, default)?, None)),
        }
    }

    /// The texture the property `name` of `p` names, if it is a `<texture>` or a `<ref>`
    /// (to a top-level texture); `None` for a constant or an absent property.
    pub(super) fn texture_of(&mut self, p: &Props<'_>, name: &str) -> R<Option<TextureId>> {
        let Some(i) = p.node.children.iter().position(|c| matches!(c.tag.as_str(), "texture" | "ref") && c.attr("name") == Some(name)) else { return Ok(None) };
        p.used[i].set(true);
        let n = &p.node.children[i];
        if n.tag == "texture" {
            return self.texture(n).map(Some);
        }
        let id = n.attr("id").ok_or_else(|| self.invalid(n.line, "<ref> lacks 'id'"))?;
        match self.texture_ids.get(id) {
            Some(&t) => Ok(Some(t)),
            None if self.bsdfs.contains_key(id) => Err(self.invalid(n.line, format!("<ref name=\"{name}\" id=\"{id}\"> names a bsdf, not a texture"))),
            None => Err(self.invalid(n.line, format!("<ref name=\"{name}\" id=\"{id}\"> names no <texture> defined before it"))),
        }
    }

    /// Line of the property `name` of `p`, or of `p`'s element if it is absent.
    pub(super) fn line_of(&self, p: &Props<'_>, name: &str) -> usize {
        p.node.children.iter().find(|c| PROPERTY_TAGS.contains(&c.tag.as_str()) && c.attr("name") == Some(name)).map_or(p.node.line, |c| c.line)
    }

    /// Child objects (non-property elements) of `p` with tag `tag`, marked as read.
    pub(super) fn objects<'n>(&self, p: &Props<'n>, tags: &[&str]) -> Vec<&'n Node> {
        p.node
            .children
            .iter()
            .enumerate()
            .filter(|(_, c)| tags.contains(&c.tag.as_str()) && !(c.tag == "texture" && c.attr("name").is_some()))
            .map(|(i, c)| {
                p.used[i].set(true);
                c
            })
            .collect()
    }

    /// Marks every child as read (elements whose content does not matter to arpa).
    pub(super) fn consume_all(&self, p: &Props<'_>) {
        p.used.iter().for_each(|u| u.set(true));
    }
}
